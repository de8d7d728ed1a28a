//! A rope run checks its own answer before it is reported as verified
//! (issue 29). Each check is a number with the tolerance it is held to:
//!
//! * `overlap`: the deepest overlap 2r − s of two non-neighbouring
//!   segments after any step's collision handling, against the scenario's
//!   stated bound ([`RopeScenario::penetration_tolerance_m`], 0.3 r);
//! * `force_balance`: the largest |Σ internal forces| sampled over the run
//!   (every term of Eq. 5–16 acts in equal and opposite pairs, so the sum
//!   is zero up to rounding), against [`FORCE_BALANCE_TOLERANCE`] times
//!   the largest Σ|f_i| of the same samples;
//! * `stability`: the run reached its end: the step's own checks
//!   (`Rope::step`) stop it at a non-finite value, a point beyond 1 km or
//!   a segment beyond 10 rest lengths. The figure is the longest segment
//!   of the run in rest lengths, against the step's own limit
//!   ([`STABILITY_RATIO_TOLERANCE`]), so a report shows how close a run
//!   came to it;
//! * `rest` (scenarios with `kinetic_damping` only, whose answer is a rest
//!   state): the largest force left on a free point by the end positions
//!   with every point at rest (gravity, internal forces, desk and tool
//!   couplings; not the collision impulses),
//!   against [`REST_TOLERANCE`] of a point's weight under standard gravity;
//! * `time_step` (asked for: `softjoint dlo rope --check-step`): the same
//!   scenario run again at dt/2; the largest distance between a node of
//!   the two runs at the topology checks' times and at the end, against
//!   [`TIME_STEP_TOLERANCE`] radii, and the same crossings and knot
//!   determinant at every topology check. The step is first-order
//!   (semi-implicit Euler), so the error at dt is about twice the change
//!   to dt/2 while the trajectory is smooth in dt.
//!
//! A run is verified when every check it carries holds.
use serde::Serialize;

use super::forces::V3;
use super::params::GRAVITY_N_PER_KG;
use super::script::{RopeScenario, RunResult};
use crate::error::Result;

/// Largest |Σ internal forces| accepted, relative to Σ|f_i| at the same
/// sample: the sum of N ≤ 2000 terms rounds to about N·2.2e-16 of Σ|f_i|
/// (4.4e-13 at most), and a missing or unbalanced term shows at the
/// order of the term itself.
pub const FORCE_BALANCE_TOLERANCE: f64 = 1e-10;
/// Longest segment accepted, in rest lengths: the limit at which
/// `Rope::step` stops a run as unstable (sim.rs, `check`).
pub const STABILITY_RATIO_TOLERANCE: f64 = 10.0;
/// Largest force left on a free point of a rest state, as a share of a
/// point's weight under standard gravity (m·9.8 N/kg). For a hanging chain
/// this bounds the error of the total stretch to about the same share.
pub const REST_TOLERANCE: f64 = 1e-3;
/// Largest distance accepted between the run at dt and at dt/2, in rope
/// radii r: the two shapes are the same to within the rope's thickness.
pub const TIME_STEP_TOLERANCE: f64 = 1.0;

/// One self-check: a figure, the tolerance it is held to, and whether it
/// holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Check {
    pub value: f64,
    pub tolerance: f64,
    /// Unit of `value` and `tolerance`.
    pub unit: &'static str,
    pub passed: bool,
    /// What else decided the check (why the run stopped, which topology
    /// check disagreed).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

impl Check {
    /// `value ≤ tolerance` (a NaN fails), unless `broken` says why not.
    fn at_most(value: f64, tolerance: f64, unit: &'static str, broken: Option<String>) -> Self {
        Self {
            passed: value <= tolerance && broken.is_none(),
            // A non-finite figure is reported as the largest number (JSON
            // has no NaN); the check fails either way.
            value: if value.is_finite() { value } else { f64::MAX },
            tolerance,
            unit,
            note: broken,
        }
    }
}

/// The checks of one rope run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RopeChecks {
    pub overlap: Check,
    pub force_balance: Check,
    pub stability: Check,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rest: Option<Check>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_step: Option<Check>,
}

impl RopeChecks {
    /// The checks of `result`, a run of `scenario`; `half_step` is the
    /// same scenario run at dt/2 (see [`RopeScenario::run_half_step`]) when
    /// the time-step check is asked for.
    pub fn of(scenario: &RopeScenario, result: &RunResult, half_step: Option<&RunResult>) -> Self {
        let overlap = Check::at_most(
            result.max_penetration_m,
            scenario.penetration_tolerance_m(),
            "m",
            None,
        );
        let force_balance = Check::at_most(
            result.max_internal_force_sum_n,
            FORCE_BALANCE_TOLERANCE * result.internal_force_scale_n,
            "N",
            None,
        );
        let mut stability = Check::at_most(
            result.max_segment_ratio,
            STABILITY_RATIO_TOLERANCE,
            "rest lengths",
            result
                .unstable
                .as_ref()
                .map(|why| format!("the run stopped: {why}")),
        );
        if stability.note.is_none() && result.max_segment_ratio > 1.0 {
            stability.note = Some(format!(
                "longest: segment {} at {:.2} s",
                result.max_segment_index, result.max_segment_ratio_time_s
            ));
        }
        let rest = scenario.kinetic_damping.then(|| {
            Check::at_most(
                result.rest_force_n,
                REST_TOLERANCE * scenario.rope.node_mass_kg * GRAVITY_N_PER_KG,
                "N",
                None,
            )
        });
        let time_step = half_step.map(|h| step_check(scenario, result, h));
        Self {
            overlap,
            force_balance,
            stability,
            rest,
            time_step,
        }
    }

    /// The names of the checks that do not hold.
    pub fn failures(&self) -> Vec<&'static str> {
        let mut f = Vec::new();
        for (name, c) in [
            ("overlap", Some(&self.overlap)),
            ("force_balance", Some(&self.force_balance)),
            ("stability", Some(&self.stability)),
            ("rest", self.rest.as_ref()),
            ("time_step", self.time_step.as_ref()),
        ] {
            if c.is_some_and(|c| !c.passed) {
                f.push(name);
            }
        }
        f
    }

    /// Whether every check holds.
    pub fn verified(&self) -> bool {
        self.failures().is_empty()
    }

    /// `"verified"` or `"UNVERIFIED"`.
    pub fn status(&self) -> &'static str {
        if self.verified() {
            "verified"
        } else {
            "UNVERIFIED"
        }
    }
}

/// The largest distance between corresponding nodes of two shapes, m.
fn max_distance(a: &[V3], b: &[V3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max)
}

/// The time-step check: `result` (dt) against `half` (dt/2).
fn step_check(scenario: &RopeScenario, result: &RunResult, half: &RunResult) -> Check {
    let mut worst = max_distance(&result.final_x, &half.final_x);
    let mut notes = Vec::new();
    for (run, at) in [(result, "dt"), (half, "dt/2")] {
        if let Some(why) = &run.unstable {
            notes.push(format!("the run at {at} stopped ({why})"));
        }
    }
    if result.topology.len() != half.topology.len() {
        notes.push("the two runs made different topology checks".to_string());
    }
    for (a, b) in result.topology.iter().zip(&half.topology) {
        worst = worst.max(max_distance(&a.x, &b.x));
        if (a.crossings, a.determinant) != (b.crossings, b.determinant) {
            notes.push(format!(
                "`{}`: {} crossings, determinant {:?} at dt; {}, {:?} at dt/2",
                a.label, a.crossings, a.determinant, b.crossings, b.determinant
            ));
        }
    }
    let note = (!notes.is_empty()).then(|| notes.join("; "));
    Check::at_most(
        worst,
        TIME_STEP_TOLERANCE * scenario.rope.radius_m,
        "m",
        note,
    )
}

impl RopeScenario {
    /// The same scenario at half the time step (frames at the same times).
    pub fn run_half_step(&self) -> Result<RunResult> {
        let mut half = self.clone();
        half.rope.dt_s *= 0.5;
        half.run(|_| {})
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `scenarios/dlo/drag_through.toml` (a hand drags the rope's free end
    /// across its pinned part at the same height) with `collision_passes`
    /// shift passes.
    fn drag(collision_passes: usize) -> RopeScenario {
        let text = include_str!("../../../../scenarios/dlo/drag_through.toml").replace(
            "collision_passes = 0",
            &format!("collision_passes = {collision_passes}"),
        );
        toml::from_str(&text).unwrap()
    }

    /// A rope of 12 nodes pinned at one end, released horizontal: it
    /// swings down for `duration_s`.
    fn swing(dt_s: f64, extra: &str) -> RopeScenario {
        let text = format!(
            r#"name = "swing"
start_m = [0.0, 0.0, 2.0]
direction = [1.0, 0.0, 0.0]
pins = [0]
duration_s = 1.0

[[checks]]
label = "end"
at_s = 1.0

[rope]
nodes = 12
length_m = 1.1
radius_m = 0.01
dt_s = {dt_s}
{extra}
"#
        );
        toml::from_str(&text).unwrap()
    }

    #[test]
    fn a_rope_dragged_through_itself_fails_the_overlap_check() {
        // Without the shift passes the hand's coupling (1200 N/m) drags the
        // end through the rope against the repulsion (100 N/m): the overlap
        // reaches about 2r. With Table I's 4 passes, none is left.
        let through = drag(0);
        let r = through.run(|_| {}).unwrap();
        let c = RopeChecks::of(&through, &r, None);
        assert!(r.max_penetration_m > 0.06, "{}", r.max_penetration_m);
        assert_eq!(c.failures(), vec!["overlap"]);
        assert_eq!(c.status(), "UNVERIFIED");
        let kept = drag(4);
        let r = kept.run(|_| {}).unwrap();
        assert!(r.contact_steps > 100, "no contact: {}", r.contact_steps);
        let c = RopeChecks::of(&kept, &r, None);
        assert!(c.verified(), "{c:?}");
        assert_eq!(c.status(), "verified");
    }

    #[test]
    fn a_run_the_step_stops_fails_the_stability_check() {
        // Soft springs (k_l = 20 N) whip at the end of the swing and the
        // step stops the run at 5 ms; at 1 ms it swings through.
        let soft = "linear_stiffness_n = 20.0\ntorsional_stiffness_n_m = 0.1";
        let s = swing(5e-3, soft);
        let r = s.run(|_| {}).unwrap();
        let why = r.unstable.clone().expect("the run stops");
        assert!(why.contains("rest lengths"), "{why}");
        assert!(r.frames.last().unwrap().time_s < 0.5);
        let c = RopeChecks::of(&s, &r, None);
        assert_eq!(c.failures(), vec!["stability"]);
        assert!(c.stability.note.as_ref().unwrap().contains("stopped"));
        let s = swing(1e-3, "");
        let r = s.run(|_| {}).unwrap();
        assert!(r.unstable.is_none());
        assert!(RopeChecks::of(&s, &r, None).verified());
    }

    #[test]
    fn the_time_step_check_shrinks_with_the_step_and_fails_on_a_stopped_run() {
        // A smooth swing: the change to dt/2 falls with dt as a first-order
        // step's error does (measured: 1.37e-4 m at 1 ms, 1.35e-5 m at
        // 0.1 ms), well inside one radius (0.01 m).
        let change = |dt: f64| {
            let s = swing(dt, "");
            let r = s.run(|_| {}).unwrap();
            let c = RopeChecks::of(&s, &r, Some(&s.run_half_step().unwrap()));
            assert!(c.verified(), "{c:?}");
            c.time_step.unwrap().value
        };
        let (coarse, fine) = (change(1e-3), change(1e-4));
        assert!(coarse > 1e-5 && coarse < 1e-3, "{coarse}");
        let ratio = coarse / fine;
        assert!((7.0..13.0).contains(&ratio), "ratio {ratio}");
        // The soft rope's runs stop at dt and at dt/2: the check fails and
        // says so.
        let s = swing(
            5e-3,
            "linear_stiffness_n = 20.0\ntorsional_stiffness_n_m = 0.1",
        );
        let r = s.run(|_| {}).unwrap();
        let c = RopeChecks::of(&s, &r, Some(&s.run_half_step().unwrap()));
        let step = c.time_step.as_ref().unwrap();
        assert!(!step.passed);
        assert!(step.note.as_ref().unwrap().contains("stopped"), "{step:?}");
        assert!(c.failures().contains(&"time_step"));
    }

    #[test]
    fn the_force_balance_check_fails_on_an_unbalanced_sum() {
        // The figure of a run is rounding (≈ 1e-14 N); an internal-force
        // sum the size of a term fails.
        let s = swing(1e-3, "");
        let mut r = s.run(|_| {}).unwrap();
        let c = RopeChecks::of(&s, &r, None);
        assert!(c.force_balance.passed, "{c:?}");
        assert!(c.force_balance.value < 1e-12, "{}", c.force_balance.value);
        r.max_internal_force_sum_n = 1e-6 * r.internal_force_scale_n;
        let c = RopeChecks::of(&s, &r, None);
        assert_eq!(c.failures(), vec!["force_balance"]);
    }

    #[test]
    fn a_relaxation_cut_short_fails_the_rest_check() {
        // A hanging rope relaxed by kinetic damping: at rest after 20 s
        // (the force left is far below 1e-3 of a point's weight), still
        // moving after 0.2 s.
        let hang = |duration_s: f64| -> RopeScenario {
            toml::from_str(&format!(
                "name = \"hang\"\nstart_m = [0.0, 0.0, 10.0]\ndirection = [0.0, 0.0, -1.0]\npins = [0]\nduration_s = {duration_s}\nframe_interval_s = 1.0\nkinetic_damping = true\n[rope]\nnodes = 20\n"
            ))
            .unwrap()
        };
        let s = hang(20.0);
        let c = RopeChecks::of(&s, &s.run(|_| {}).unwrap(), None);
        assert!(c.verified(), "{c:?}");
        let rest = c.rest.unwrap();
        assert!(rest.value < 1e-3 * rest.tolerance, "{rest:?}");
        let s = hang(0.2);
        let c = RopeChecks::of(&s, &s.run(|_| {}).unwrap(), None);
        assert_eq!(c.failures(), vec!["rest"]);
        // Without kinetic damping there is no rest check.
        let s = RopeScenario {
            kinetic_damping: false,
            ..s
        };
        assert!(RopeChecks::of(&s, &s.run(|_| {}).unwrap(), None)
            .rest
            .is_none());
    }
}
