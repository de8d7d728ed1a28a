//! The randomised campaign of hanging ropes (issue 29): random ropes
//! (nodes, length, segment length against the diameter 2r, k_l, point
//! mass; model 4, Table I's other constants; the time step [`time_step_s`]
//! a user would take from the axial stability limit) hang from their
//! first point and relax to rest as a `softjoint dlo rope` scenario with
//! `kinetic_damping = true`, every check on (`--check-step` included).
//! Each end state is compared with the closed form of the discrete chain
//! written here from its statics: segment k from the bottom (k = 1..N−1)
//! carries the k points below it, k·m·g; model 4's spring k_l·ε makes its
//! strain k·m·g/k_l, so the total stretch is
//! Σ_k l_r·k·m·g/k_l = l_r·m·g·N(N−1)/(2k_l) = l·m·g·N/(2k_l).
//! A case is right when the stretch is within [`STRETCH_TOLERANCE`] of it
//! (relative). The campaign counts the cases solved (right and verified),
//! the wrong answers called verified (goal 0) and the cases reported
//! unverified.
//!
//! The short form runs in CI (`rope_campaign::`); the full form is
//! `cargo run --profile ci-opt -p plant-dlo --example rope_campaign -- 300`
//! (`examples/rope_campaign.rs` includes this file).
use plant_dlo::rope::script::RopeScenario;
use plant_dlo::rope::verify::RopeChecks;
use plant_dlo::rope::RopeParams;

/// Largest relative error of the stretch counted as right. The `rest`
/// check holds the force left on a point to 1e-3 of its weight, which
/// bounds the stretch's relative error to about the same (verify.rs).
pub const STRETCH_TOLERANCE: f64 = 1e-3;
/// Simulated time each case has to come to rest, s.
pub const DURATION_S: f64 = 20.0;

/// One random hanging rope.
#[derive(Debug, Clone)]
pub struct Case {
    pub nodes: usize,
    pub length_m: f64,
    /// Rest length of a segment over the diameter, l_r/(2r).
    pub segment_over_diameter: f64,
    pub linear_stiffness_n: f64,
    pub node_mass_kg: f64,
}

/// What the run made of a case.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub stretch_m: f64,
    pub closed_form_m: f64,
    pub relative_error: f64,
    pub right: bool,
    /// Every check passed (the time-step check included).
    pub verified: bool,
    /// Every check but the time-step one passed (the verdict without
    /// `--check-step`).
    pub verified_without_step: bool,
    pub failures: Vec<&'static str>,
    /// The `rest` check's figure: the largest force left on a point over
    /// its tolerance.
    pub rest_ratio: f64,
}

use crate::splitmix::next;

/// Case `index` of the campaign seeded by `seed`: N in 8..=60, l in
/// [0.5, 6] m, l_r/(2r) in [0.5, 2] (segments shorter than the diameter
/// in a third of the cases), m log-uniform in [0.01, 0.2] kg, and k_l set
/// from a top-segment strain (N−1)·m·g/k_l log-uniform in [1e-3, 0.2].
pub fn case(seed: u64, index: u64) -> Case {
    let mut s = seed.wrapping_mul(1_000_003).wrapping_add(index);
    let mut u = || next(&mut s);
    let nodes = 8 + (u() * 53.0) as usize;
    let length_m = 0.5 + 5.5 * u();
    let segment_over_diameter = 0.5 + 1.5 * u();
    let node_mass_kg = 0.01 * 20f64.powf(u());
    let top_strain = 1e-3 * 200f64.powf(u());
    let linear_stiffness_n = (nodes - 1) as f64 * node_mass_kg * 9.8 / top_strain;
    Case {
        nodes,
        length_m,
        segment_over_diameter,
        linear_stiffness_n,
        node_mass_kg,
    }
}

/// The time step of a case: Table I's 1 ms, or less where the axial
/// springs need it. Semi-implicit Euler is stable while ω·dt < 2; the
/// fastest axial mode of a free chain of springs k_l/l_r and masses m has
/// ω = 2·√(k_l/(l_r·m)); the step keeps ω·dt ≤ 0.5, a quarter of the
/// limit. (With ω·dt ≤ 1, 8 of seed 29's first 30 cases did not come to
/// rest in 20 s and were reported unverified by the `rest` check; case 9
/// rests at dt = 0.3 ms and not at 0.4 ms, ω·dt = 0.75 and 1.)
pub fn time_step_s(c: &Case) -> f64 {
    let l_r = c.length_m / (c.nodes - 1) as f64;
    let omega = 2.0 * (c.linear_stiffness_n / (l_r * c.node_mass_kg)).sqrt();
    (0.5 / omega).min(1e-3)
}

/// The scenario of a case: the rope hanging straight down from its first
/// point, pinned there, relaxing for [`DURATION_S`] at the time step
/// [`time_step_s`] (or Table I's 1 ms for every case, `table_step`: a
/// stiff case then goes unstable or does not come to rest, and its checks
/// must say so).
pub fn scenario(c: &Case, table_step: bool) -> RopeScenario {
    let l_r = c.length_m / (c.nodes - 1) as f64;
    let text = format!(
        r#"name = "hanging"
start_m = [0.0, 0.0, 10.0]
direction = [0.0, 0.0, -1.0]
pins = [0]
duration_s = {DURATION_S}
frame_interval_s = 1.0
kinetic_damping = true

[rope]
nodes = {}
length_m = {}
radius_m = {}
linear_stiffness_n = {}
node_mass_kg = {}
model = "swivel"
dt_s = {}
"#,
        c.nodes,
        c.length_m,
        l_r / (2.0 * c.segment_over_diameter),
        c.linear_stiffness_n,
        c.node_mass_kg,
        if table_step { 1e-3 } else { time_step_s(c) }
    );
    toml::from_str(&text).expect("a valid scenario")
}

/// The closed form of the stretch (module doc), summed segment by segment.
pub fn closed_form_stretch_m(p: &RopeParams) -> f64 {
    let l_r = p.length_m / (p.nodes - 1) as f64;
    (1..p.nodes)
        .map(|k| l_r * k as f64 * p.node_mass_kg * p.gravity_n_per_kg / p.linear_stiffness_n)
        .sum()
}

/// Runs `c` as `softjoint dlo rope --check-step` does and compares.
pub fn run(c: &Case, table_step: bool) -> Outcome {
    let s = scenario(c, table_step);
    let result = s.run(|_| {}).expect("the scenario runs");
    let half = s.run_half_step().expect("the scenario runs at dt/2");
    let checks = RopeChecks::of(&s, &result, Some(&half));
    let base = RopeChecks::of(&s, &result, None);
    let x = &result.final_x;
    let stretch_m = (x[x.len() - 1] - x[0]).norm() - s.rope.length_m;
    let closed_form_m = closed_form_stretch_m(&s.rope);
    let relative_error = ((stretch_m - closed_form_m) / closed_form_m).abs();
    Outcome {
        stretch_m,
        closed_form_m,
        relative_error,
        // A NaN (a run that stopped) is not right.
        right: relative_error <= STRETCH_TOLERANCE,
        verified: checks.verified(),
        verified_without_step: base.verified(),
        failures: checks.failures(),
        rest_ratio: checks
            .rest
            .as_ref()
            .map_or(f64::NAN, |r| r.value / r.tolerance),
    }
}

/// The short form: three cases of seed 29; none wrong and called
/// verified (with or without the time-step check), each solved.
#[test]
#[ignore = "a second optimised, a minute in a debug build: CI runs it in ci-opt"]
fn random_hanging_ropes_short_form() {
    for i in 0..3 {
        let c = case(29, i);
        let o = run(&c, false);
        eprintln!("{c:?} -> {o:?}");
        assert!(
            o.right || !o.verified_without_step,
            "case {i}: wrong and called verified"
        );
        assert!(
            o.right && o.verified,
            "case {i} not solved: stretch {} m against {} m ({:.1e} off), fails {:?}, rest force {:.1e} of its tolerance",
            o.stretch_m,
            o.closed_form_m,
            o.relative_error,
            o.failures,
            o.rest_ratio
        );
    }
}
