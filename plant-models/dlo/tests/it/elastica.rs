//! The clamped wire against the elastica (issue 29): the paper's wire with
//! both ends clamped on the z axis and brought to 0.7 L and 0.9 L, solved as
//! `softjoint dlo solve` solves a problem file, must give the closed form
//! of `elastica_ref` or say that it is unverified.
use plant_dlo::wire::problem::{StaticProblem, StaticSolution};
use plant_dlo::wire::WireShape;

use crate::elastica_ref::clamped;

/// The paper's wire (L817–819), both ends clamped in the natural
/// orientation, the far end at `l_fraction` L on the axis; the file's
/// defaults otherwise (4 harmonics, 160 intervals, self-contact on).
pub fn clamped_toml(length_m: f64, rf: f64, rt: f64, l_fraction: f64, extra: &str) -> String {
    format!(
        r#"model = "wire"
[problem]
wire = {{ length_m = {length_m}, flexural_rigidity_n_m2 = {rf}, torsional_rigidity_n_m2 = {rt}, radius_m = 1e-3 }}
constraints = [
  {{ kind = "orientation", s_m = 0.0, euler_rad = [0.0, 0.0, 0.0] }},
  {{ kind = "position", s_a_m = 0.0, s_b_m = {length_m}, l_m = [0.0, 0.0, {}] }},
  {{ kind = "orientation", s_m = {length_m}, euler_rad = [0.0, 0.0, 0.0] }},
]
{extra}
"#,
        l_fraction * length_m
    )
}

pub fn solve(text: &str) -> WireShape {
    let p: StaticProblem = toml::from_str(text).expect("a valid problem");
    match p.solve().expect("a solve") {
        StaticSolution::Wire { shape, .. } => shape,
        _ => unreachable!("a wire problem"),
    }
}

/// Deflection from the axis at mid-length, m.
pub fn mid_deflection(shape: &WireShape) -> f64 {
    let p = shape.x_m[shape.x_m.len() / 2];
    p.x.hypot(p.y)
}

fn check(l_fraction: f64) {
    let (length, rf) = (0.871, 6.6e-4);
    let shape = solve(&clamped_toml(length, rf, 2.3e-4, l_fraction, ""));
    let reference = clamped(length, rf, l_fraction);
    let energy_error = (shape.energy_j - reference.energy_j).abs() / reference.energy_j;
    let deflection_error = (mid_deflection(&shape) - reference.mid_deflection_m).abs() / length;
    eprintln!(
        "l = {l_fraction} L: U = {:.6e} J (elastica {:.6e}, {energy_error:.2e} off), mid deflection {:.5} m (elastica {:.5}), checks {:?}",
        shape.energy_j,
        reference.energy_j,
        mid_deflection(&shape),
        reference.mid_deflection_m,
        shape.checks
    );
    // The answer is the elastica's: energy to 0.1 %, shape to 0.1 % of L
    // (4 harmonics and 160 trapezoid intervals; the discretisation check
    // states the change to 8 harmonics and 320 intervals).
    assert!(
        energy_error < 1e-3,
        "energy {energy_error:.2e} off the elastica"
    );
    assert!(
        deflection_error < 1e-3,
        "mid deflection {deflection_error:.2e} L off"
    );
    assert!(shape.verified(), "{:?}", shape.checks.failures());
}

#[test]
#[ignore = "seconds optimised, minutes in a debug build: CI runs it in ci-opt"]
fn clamped_wire_at_0_7_l_is_the_elastica() {
    check(0.7);
}

#[test]
#[ignore = "seconds optimised, minutes in a debug build: CI runs it in ci-opt"]
fn clamped_wire_at_0_9_l_is_the_elastica() {
    check(0.9);
}

/// The single direct start that today's main reports (from the straight
/// wire, no continuation) lands far from the elastica at 0.7 L and 0.9 L;
/// its own checks must say so, or its energy must be above the robust
/// answer's so that the robust solve cannot keep it.
#[test]
#[ignore = "seconds optimised, minutes in a debug build: CI runs it in ci-opt"]
fn a_direct_start_that_misses_the_elastica_is_not_called_converged() {
    for l_fraction in [0.7, 0.9] {
        let text = clamped_toml(0.871, 6.6e-4, 2.3e-4, l_fraction, "");
        let p: StaticProblem = toml::from_str(&text).unwrap();
        let StaticProblem::Wire { problem } = p else {
            unreachable!()
        };
        let direct = problem
            .solve(&plant_dlo::wire::optimize::Settings::default(), None)
            .unwrap();
        let reference = clamped(0.871, 6.6e-4, l_fraction);
        let wrong = (direct.energy_j - reference.energy_j).abs() > 1e-3 * reference.energy_j;
        eprintln!(
            "direct start at {l_fraction} L: U = {:.4e} J (elastica {:.4e}), failures {:?}",
            direct.energy_j,
            reference.energy_j,
            direct.checks.failures()
        );
        assert!(
            !wrong || !direct.verified(),
            "a wrong answer passed its checks"
        );
    }
}
