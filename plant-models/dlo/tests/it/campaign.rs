//! The randomised campaign of wire end conditions (issue 29): random
//! clamped wires (length, rigidities, end distance, discretisation,
//! self-contact on or off) solved as `softjoint dlo solve` solves a file,
//! each compared with the elastica of `elastica_ref`. An answer is right
//! when its energy is within 0.1 % of the elastica's and its mid-length
//! deflection within 0.1 % of L. The campaign counts the wrong answers
//! reported as converged (must be 0) and the share of cases solved (right
//! and verified; goal ≥ 99 %).
//!
//! The short form runs in CI (`campaign::`); the full form, 500 cases, is
//! `cargo run --release -p plant-dlo --example wire_campaign -- 500`
//! (docs/experiments.md). `examples/wire_campaign.rs` includes this file.
use plant_dlo::wire::problem::{StaticProblem, StaticSolution};

use crate::elastica_ref::clamped;

/// One random case.
#[derive(Debug, Clone)]
pub struct Case {
    pub length_m: f64,
    pub rf_n_m2: f64,
    pub rt_n_m2: f64,
    pub l_fraction: f64,
    pub intervals: usize,
    pub self_contact: bool,
}

/// What the solver made of a case.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub right: bool,
    pub verified: bool,
    pub energy_error: f64,
    pub deflection_error: f64,
    pub failures: Vec<&'static str>,
    /// The elastica's modulus k = sin(θ_max/2) (NaN when the solve failed).
    pub modulus_k: f64,
}

use crate::splitmix::next;

/// Case `index` of the campaign seeded by `seed`: L in [0.2, 2] m, R_f
/// log-uniform in [1e-4, 1e-2] N·m², R_t/R_f in [0.3, 1.5], l/L in [0.3,
/// 0.97] (the lobes of the first mode stay apart), 64–192 intervals.
pub fn case(seed: u64, index: u64) -> Case {
    let mut s = seed.wrapping_mul(1_000_003).wrapping_add(index);
    let mut u = || next(&mut s);
    let length_m = 0.2 + 1.8 * u();
    let rf_n_m2 = 10f64.powf(-4.0 + 2.0 * u());
    let rt_n_m2 = rf_n_m2 * (0.3 + 1.2 * u());
    let l_fraction = 0.3 + 0.67 * u();
    let intervals = [64, 96, 128, 160, 192][(u() * 5.0) as usize % 5];
    let self_contact = u() < 0.5;
    Case {
        length_m,
        rf_n_m2,
        rt_n_m2,
        l_fraction,
        intervals,
        self_contact,
    }
}

/// Solves `c` from its problem file text and compares with the elastica.
pub fn run(c: &Case) -> Outcome {
    let text = format!(
        r#"model = "wire"
[problem]
wire = {{ length_m = {}, flexural_rigidity_n_m2 = {}, torsional_rigidity_n_m2 = {}, radius_m = 1e-3 }}
constraints = [
  {{ kind = "orientation", s_m = 0.0, euler_rad = [0.0, 0.0, 0.0] }},
  {{ kind = "position", s_a_m = 0.0, s_b_m = {}, l_m = [0.0, 0.0, {}] }},
  {{ kind = "orientation", s_m = {}, euler_rad = [0.0, 0.0, 0.0] }},
]
intervals = {}
self_contact = {}
"#,
        c.length_m,
        c.rf_n_m2,
        c.rt_n_m2,
        c.length_m,
        c.l_fraction * c.length_m,
        c.length_m,
        c.intervals,
        c.self_contact
    );
    let p: StaticProblem = toml::from_str(&text).expect("a valid problem");
    let shape = match p.solve() {
        Ok(StaticSolution::Wire { shape, .. }) => shape,
        Ok(_) => unreachable!("a wire problem"),
        Err(e) => {
            return Outcome {
                right: false,
                verified: false,
                energy_error: f64::NAN,
                deflection_error: f64::NAN,
                failures: vec![
                    if matches!(e, plant_dlo::error::DloError::NotConverged(_)) {
                        "solve error"
                    } else {
                        "refused"
                    },
                ],
                modulus_k: f64::NAN,
            }
        }
    };
    let reference = clamped(c.length_m, c.rf_n_m2, c.l_fraction);
    let mid = shape.x_m[shape.x_m.len() / 2];
    let energy_error = (shape.energy_j - reference.energy_j).abs() / reference.energy_j;
    let deflection_error = (mid.x.hypot(mid.y) - reference.mid_deflection_m).abs() / c.length_m;
    Outcome {
        right: energy_error < 1e-3 && deflection_error < 1e-3,
        verified: shape.verified(),
        energy_error,
        deflection_error,
        failures: shape.checks.failures(),
        modulus_k: reference.k,
    }
}

/// The short form: a few cases of seed 29; none wrong and called
/// converged, every one solved.
#[test]
#[ignore = "seconds optimised, minutes in a debug build: CI runs it in ci-opt"]
fn random_clamped_wires_short_form() {
    for i in 0..2 {
        let c = case(29, i);
        let o = run(&c);
        eprintln!("{c:?} -> {o:?}");
        assert!(
            o.right || !o.verified,
            "case {i}: a wrong answer called converged"
        );
        assert!(
            o.right && o.verified,
            "case {i} not solved: energy {:.1e} off, mid deflection {:.1e} L off, fails {:?} (k = {:.3})",
            o.energy_error,
            o.deflection_error,
            o.failures,
            o.modulus_k
        );
    }
}

/// Case 85 of seed 29 (L 1.905 m, l/L 0.486, 160 intervals, no
/// self-contact), one of the right answers the campaign at 48d3fb1 reported
/// unverified: the solve twice as fine stopped short of stationarity (KKT
/// residual 4e-4 against 1e-5), its Newton polish stalled on multipliers
/// drifted to |λ| 1.5e6 along the null space of the redundant orientation
/// rows. Now every check passes, the discretisation check included, on the
/// finer grid.
#[test]
#[ignore = "seconds optimised, minutes in a debug build: CI runs it in ci-opt"]
fn formerly_unverified_case_85_passes_every_check() {
    let c = case(29, 85);
    let o = run(&c);
    assert!(
        o.right && o.verified,
        "energy {:.1e} off, mid deflection {:.1e} L off, fails {:?}",
        o.energy_error,
        o.deflection_error,
        o.failures
    );
}
