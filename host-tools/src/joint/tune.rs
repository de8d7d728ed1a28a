//! `softjoint tune`: controller gains searched against an identified plant,
//! robust over the identification's uncertainty.
//!
//! - **Plants**: plant 0 is the identified plant; plants 1.. draw every
//!   identified parameter from its 1σ (normal; log-normal for the scale
//!   parameters), seeded ([`plant_common::rng::IDENTIFY_SAMPLE`]). A draw
//!   the plant refuses (e.g. A_f below A_s) is drawn again.
//! - **Candidates**: candidate 0 is the paper's gains (K_P = 2 V/° on
//!   every coil, no integral action); the others draw K_P per coil
//!   log-uniform in 0.3–6 V/°, and with probability ½ an integral gain
//!   log-uniform in 0.02–1 V/(°·s) with a limit uniform in 0.1–1.5 V,
//!   seeded ([`plant_common::rng::IDENTIFY_SEARCH`]). v_offset stays the
//!   paper's 1.7 V unless `--search-v-offset` draws it too, uniform in
//!   1.2–2.2 V (the paper's ± 0.5 V) from its own stream
//!   ([`plant_common::rng::IDENTIFY_V_OFFSET`]), so the other gains are
//!   the same draws as without it. The board takes it in `SetGains`.
//! - **Test**: the joint (wire feedback, the paper's estimation laws, 1 kHz)
//!   steps 0 → +8° (1 s) → −6° (9 s) → 0 (17 s), 25 s, every plane alike.
//! - **Cost** of one run: mean settling time (s; to within ±0.5° for good,
//!   the segment's length if never) + overshoot (largest, °) + 2 × steady-
//!   state error (largest, °) + 0.1 × (peak coil temperature − 100 °C)⁺ +
//!   5 × (20 K − thermal-budget margin)⁺ / 20 K + 50 if any supervisor
//!   fault. The margin is the firmware's own modelled coil rise kept
//!   below its trip rise.
//! - **Robust cost** of a candidate: mean + standard deviation over the
//!   plants. Candidates are scored in parallel (rayon); the result does
//!   not depend on the number of threads.
//! - **Held out** (issue 28): the winner and the paper's gains are scored
//!   again on manoeuvres the search never saw ([`Manoeuvre`]: a step
//!   pattern of other sizes with the other direction first; in 3D the
//!   planes moving in opposite directions; a 20 g load hung and cut) and
//!   on as many plants drawn anew from the uncertainty (another seed of
//!   the same stream). The winner beats or ties the paper's gains on a
//!   manoeuvre when its robust cost is at most the paper's plus
//!   [`HELDOUT_TIE`]; `softjoint tune` refuses to recommend it unless it
//!   does so on every one.
//! - **Stopping and resuming**: a signal stops the search between
//!   candidates; the candidates scored so far and the best of them are a
//!   [`SearchState`], from which a resumed search scores only the others
//!   (its result is the one the search would have given unbroken: each
//!   candidate's score depends only on its gains, the plants and the seed).
//! - **Work units** (issue 33): a search is a [`TuneSweep`] cut into
//!   [`TuneUnit`]s of [`UNIT_CANDIDATES`] consecutive candidates. A unit
//!   is a pure function of the sweep (plant file, counts, seed) and its
//!   index: the sweep draws the seeded candidate sequence and the plants
//!   once (wherever it is set up: each Ray worker does it for itself),
//!   and the unit scores its own slice of the candidates on the plants. The reduction
//!   ([`TuneSweep::reduce`]) ranks the scored candidates by index and
//!   scores the winner on the held-out steps. `softjoint tune` runs the
//!   units on this machine's threads, the Python package's Ray driver on
//!   a cluster's workers: the same units, so the same result.

use std::sync::OnceLock;

use anyhow::{bail, Context};
use hal_sim::{ClosedLoop, CoreController, Plant, Sample};
use plant_joint::identify::{Param, PlaneModel, Scale};
use plant_joint::{Joint2dParams, Joint3dParams, PlaneParams, WireSensorParams};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;

use crate::files::gains::{
    paper_v_offset, Gains, GainsFile, HeldOut, ManoeuvreScore, RunCost, Score, Tuning,
};
use crate::files::plant::{PlantFile, PlantParams, Uncertainty};
use crate::files::scenario::{Disturbance, EstimatorMethod, FeedbackKind, Scenario, TargetStep};
use crate::files::JointKind;
use crate::resume::fnv1a_hex;
use crate::run::joint::{CoreLoopTask, SimJoint};
use crate::run::record::Trace;
use crate::run::schedule::RunSchedule;
use crate::run::spec::RunSpec;
use crate::stop::{Stop, StopSignal};
use serde::{Deserialize, Serialize};

/// The range `--search-v-offset` draws v_offset from (V): the paper's
/// 1.7 V ± 0.5 V.
pub const V_OFFSET_SEARCH_V: (f64, f64) = (1.2, 2.2);

/// Settling band (°).
pub const SETTLING_BAND_DEG: f64 = 0.5;

/// The steps of the search's test: (time s, target °).
pub const TEST_STEPS: [(f64, f64); 4] = [(0.0, 0.0), (1.0, 8.0), (9.0, -6.0), (17.0, 0.0)];

/// The held-out steps (issue 28): other sizes, the other direction first,
/// steps that do not return to 0, inside the test's ±8° range. 25 s like
/// the test.
pub const HELDOUT_STEPS: [(f64, f64); 5] = [
    (0.0, 0.0),
    (1.0, -4.0),
    (7.0, 6.0),
    (14.0, 2.0),
    (20.0, -5.0),
];

/// Relative slack within which the tuned gains' held-out robust cost
/// ties the paper's (1 %).
pub const HELDOUT_TIE: f64 = 0.01;

/// The held-out load (g): a weight hung on the link by a thread, 40 % of
/// the paper's 50 g, which deflects the unpowered link by 12° (SPEC,
/// seed 000: so ≈ 5°, inside the test's ±8° range).
pub const HELDOUT_LOAD_G: f64 = 20.0;

/// When the held-out load hangs (s): hung during the −4° hold of
/// [`HELDOUT_STEPS`], carried through the step to +6° and cut while
/// holding it, so the gains must hold against it, lift it and take its
/// release.
pub const HELDOUT_LOAD_S: (f64, f64) = (3.0, 11.0);

/// A held-out manoeuvre (issue 28): the tuned gains and the paper's are
/// scored on each, on plants drawn anew, and `tune` recommends the tuned
/// gains only if they beat or tie the paper's on every one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Manoeuvre {
    /// [`HELDOUT_STEPS`], every plane alike: other sizes, the other
    /// direction first.
    Steps,
    /// 3D only: α follows [`HELDOUT_STEPS`], β the same steps mirrored,
    /// so the planes move in opposite directions (the search's test moves
    /// them alike).
    OppositePlanes,
    /// [`HELDOUT_STEPS`] with a [`HELDOUT_LOAD_G`] g weight on the link
    /// (α's plane, thread towards −θ) during [`HELDOUT_LOAD_S`].
    Load,
}

impl Manoeuvre {
    /// The held-out manoeuvres of a joint kind, [`Manoeuvre::Steps`] first.
    pub fn all(joint: JointKind) -> &'static [Manoeuvre] {
        match joint {
            JointKind::TwoD => &[Manoeuvre::Steps, Manoeuvre::Load],
            JointKind::ThreeD => &[Manoeuvre::Steps, Manoeuvre::OppositePlanes, Manoeuvre::Load],
        }
    }

    /// Its name in the output and the gains file.
    pub fn name(self) -> &'static str {
        match self {
            Manoeuvre::Steps => "steps",
            Manoeuvre::OppositePlanes => "opposite planes",
            Manoeuvre::Load => "load",
        }
    }

    /// The scenario of this manoeuvre with `gains` on `params`.
    pub fn scenario(
        self,
        joint: JointKind,
        gains: &Gains,
        params: PlantParams,
        seed: u64,
    ) -> Scenario {
        let mut s = step_scenario(joint, gains, params, seed, &HELDOUT_STEPS);
        match self {
            Manoeuvre::Steps => {}
            Manoeuvre::OppositePlanes => {
                for t in &mut s.targets {
                    if let Some(beta) = t.deg.get_mut(1) {
                        *beta = -*beta;
                    }
                }
            }
            Manoeuvre::Load => s.disturbances.push(Disturbance::Weight {
                mass_g: HELDOUT_LOAD_G,
                plane: None,
                direction: None,
                from_s: HELDOUT_LOAD_S.0,
                to_s: HELDOUT_LOAD_S.1,
            }),
        }
        s
    }
}

/// The test scenario for a joint kind (see the module docs).
pub fn test_scenario(joint: JointKind, gains: &Gains, params: PlantParams, seed: u64) -> Scenario {
    step_scenario(joint, gains, params, seed, &TEST_STEPS)
}

fn step_scenario(
    joint: JointKind,
    gains: &Gains,
    params: PlantParams,
    seed: u64,
    steps: &[(f64, f64)],
) -> Scenario {
    let planes = if joint == JointKind::TwoD { 1 } else { 2 };
    let mut s = Scenario {
        name: "tuning step test".into(),
        joint,
        duration_s: 25.0,
        seed,
        feedback: FeedbackKind::Wire,
        targets: steps
            .iter()
            .map(|&(t_s, d)| TargetStep {
                t_s,
                deg: vec![d; planes],
            })
            .collect(),
        ..Scenario::default()
    };
    s.estimator.method = EstimatorMethod::Paper;
    s.controller.kp_v_per_deg = gains.kp_v_per_deg.clone();
    s.controller.ki_v_per_deg_s = gains.ki_v_per_deg_s;
    s.controller.integral_limit_v = gains.integral_limit_v;
    s.controller.v_offset_v = gains.v_offset_v;
    s.plant.params = Some(params);
    s
}

/// Accumulates a run's metrics from its samples.
struct Meter {
    planes: usize,
    /// Segment starts (s) and each plane's target there (°).
    targets: Vec<(f64, [f64; 2])>,
    /// Per segment and plane: last time outside the band, overshoot, tail
    /// sum and count.
    last_out: Vec<[f64; 2]>,
    over: Vec<[f64; 2]>,
    tail: Vec<[(f64, usize); 2]>,
    start_deg: [f64; 2],
    peak_c: f64,
    fault: bool,
}

impl Meter {
    fn new(spec: &RunSpec, planes: usize) -> Self {
        let targets: Vec<(f64, [f64; 2])> = spec
            .targets
            .iter()
            .map(|t| (t.t_s, [t.deg[0], t.deg.get(1).copied().unwrap_or(t.deg[0])]))
            .collect();
        let n = targets.len();
        Self {
            planes,
            targets,
            last_out: vec![[f64::NAN; 2]; n],
            over: vec![[0.0; 2]; n],
            tail: vec![[(0.0, 0); 2]; n],
            start_deg: [0.0; 2],
            peak_c: f64::NEG_INFINITY,
            fault: false,
        }
    }

    fn push_sample<const P: usize, const S: usize, const C: usize>(
        &mut self,
        x: &Sample<P, S, C>,
        end_s: f64,
    ) {
        for t in x.coil_temperatures_c {
            self.peak_c = self.peak_c.max(t);
        }
        self.push(x.t_s, &x.true_deg, x.faults, end_s);
    }

    fn push(&mut self, t_s: f64, true_deg: &[f64], faults: u16, end_s: f64) {
        self.fault |= faults != 0;
        let Some(seg) = self.targets.iter().rposition(|(t, _)| t_s >= *t) else {
            return;
        };
        let (from, targets) = self.targets[seg];
        let to = self.targets.get(seg + 1).map(|t| t.0).unwrap_or(end_s);
        for (p, &th) in true_deg.iter().enumerate().take(self.planes) {
            let target = targets[p];
            let prev = if seg == 0 {
                None
            } else {
                Some(self.targets[seg - 1].1[p])
            };
            if seg == 0 && t_s == 0.0 {
                self.start_deg[p] = th;
            }
            let e = th - target;
            if e.abs() > SETTLING_BAND_DEG {
                self.last_out[seg][p] = t_s;
            }
            let dir = (target - prev.unwrap_or(self.start_deg[p])).signum();
            self.over[seg][p] = self.over[seg][p].max(dir * e);
            if t_s >= to - 0.2 * (to - from) {
                self.tail[seg][p].0 += th;
                self.tail[seg][p].1 += 1;
            }
        }
    }

    fn finish(&self, end_s: f64, margin_k: f64) -> RunCost {
        let mut settle = Vec::new();
        let (mut over, mut sse) = (0.0f64, 0.0f64);
        for (seg, (from, targets)) in self.targets.iter().enumerate() {
            let to = self.targets.get(seg + 1).map(|t| t.0).unwrap_or(end_s);
            for (p, target) in targets.iter().enumerate().take(self.planes) {
                let lo = self.last_out[seg][p];
                settle.push(if lo.is_nan() {
                    0.0
                } else {
                    (lo - from + 1e-3).min(to - from)
                });
                if seg > 0 {
                    over = over.max(self.over[seg][p]);
                }
                let (sum, n) = self.tail[seg][p];
                if n > 0 {
                    sse = sse.max((sum / n as f64 - target).abs());
                }
            }
        }
        let settling_s = settle.iter().sum::<f64>() / settle.len().max(1) as f64;
        let cost = settling_s
            + over
            + 2.0 * sse
            + 0.1 * (self.peak_c - 100.0).max(0.0)
            + 5.0 * (20.0 - margin_k).max(0.0) / 20.0
            + if self.fault { 50.0 } else { 0.0 };
        RunCost {
            settling_s,
            overshoot_deg: over,
            steady_state_error_deg: sse,
            peak_coil_c: self.peak_c,
            budget_margin_k: margin_k,
            fault: self.fault,
            cost,
        }
    }
}

/// Runs a test scenario's closed loop and meters it.
struct Metered<'a> {
    spec: &'a RunSpec,
}

impl CoreLoopTask for Metered<'_> {
    type Output = RunCost;

    fn run<Pl, const P: usize, const S: usize, const C: usize>(
        self,
        cl: &mut ClosedLoop<Pl, CoreController<P, S>, P, S, C>,
    ) -> anyhow::Result<RunCost>
    where
        Pl: Plant<P, S, C> + SimJoint,
    {
        let spec = self.spec;
        let mut meter = Meter::new(spec, P);
        let mut schedule = RunSchedule::new(spec);
        let trip = cl
            .controller
            .joint()
            .supervisor()
            .config()
            .thermal
            .trip_rise_k;
        let mut margin = f64::from(trip);
        for _ in 0..spec.steps() {
            cl.run(1, &mut schedule, |x| -> anyhow::Result<()> {
                meter.push_sample(x, spec.duration_s);
                Ok(())
            })?;
            let sup = cl.controller.joint().supervisor();
            for pair in 0..P {
                for coil in 0..2 {
                    if let Some(r) = sup.coil_rise_k(pair, coil) {
                        margin = margin.min(f64::from(trip - r));
                    }
                }
            }
        }
        Ok(meter.finish(spec.duration_s, margin))
    }
}

/// The cost of a recorded run of a test scenario (a `sim` or `hil` trace
/// of the run `spec`, with its peak coil temperature); the thermal-budget
/// margin is given (a board's own budget is not in its trace).
pub fn cost_of_trace(spec: &RunSpec, trace: &Trace, peak_coil_c: f64, margin_k: f64) -> RunCost {
    let mut meter = Meter::new(spec, trace.planes);
    meter.peak_c = peak_coil_c;
    for r in &trace.rows {
        meter.push(
            r.t_s,
            &r.true_deg[..trace.planes],
            r.faults,
            spec.duration_s,
        );
    }
    meter.finish(spec.duration_s, margin_k)
}

/// Runs a test scenario (resolved into `spec`) and measures it.
pub fn evaluate(spec: &RunSpec) -> anyhow::Result<RunCost> {
    spec.core_loop(Metered { spec })
}

/// Draws a plane's identified parameters from their 1σ.
fn perturb_plane(
    plane: &PlaneParams,
    wires: &[WireSensorParams],
    name: &str,
    unc: &[Uncertainty],
    rng: &mut ChaCha8Rng,
) -> (PlaneParams, Vec<WireSensorParams>) {
    let mut m = PlaneModel {
        plane: plane.clone(),
        wires: wires.to_vec(),
        settle_s: 1.0,
        substep_s: 1e-3,
    };
    for u in unc.iter().filter(|u| u.plane == name && u.std.is_finite()) {
        let Some(p) = Param::from_field(&u.field) else {
            continue;
        };
        let z: f64 = StandardNormal.sample(rng);
        let v = match p.scale() {
            Scale::Log { .. } if u.value > 0.0 => u.value * (z * u.std / u.value).exp(),
            _ => (u.value + z * u.std).max(0.0),
        };
        p.set(&mut m, v);
    }
    (m.plane, m.wires)
}

/// `n` plants: the file's, then `n − 1` drawn from its uncertainty.
pub fn sample_plants(file: &PlantFile, n: usize, seed: u64) -> anyhow::Result<Vec<PlantParams>> {
    let base = file.params()?;
    let mut rng = plant_common::rng::stream(seed, plant_common::rng::IDENTIFY_SAMPLE);
    let mut out = vec![base.clone()];
    let mut tries = 0;
    while out.len() < n {
        tries += 1;
        if tries > 100 * n {
            bail!("the plant file's uncertainties give no valid plant in {tries} draws");
        }
        let u = &file.uncertainty;
        let drawn = match &base {
            PlantParams::TwoD(p) => {
                let (plane, w) = perturb_plane(
                    &p.plane,
                    std::slice::from_ref(&p.wire),
                    "theta",
                    u,
                    &mut rng,
                );
                let mut q: Joint2dParams = p.clone();
                q.plane = plane;
                q.wire = w[0].clone();
                q.validate().is_ok().then_some(PlantParams::TwoD(q))
            }
            PlantParams::ThreeD(p) => {
                let mut q: Joint3dParams = p.clone();
                let (a, wa) = perturb_plane(
                    &p.alpha,
                    &[p.wires[0].clone(), p.wires[2].clone()],
                    "alpha",
                    u,
                    &mut rng,
                );
                let (b, wb) = perturb_plane(
                    &p.beta,
                    &[p.wires[1].clone(), p.wires[3].clone()],
                    "beta",
                    u,
                    &mut rng,
                );
                q.alpha = a;
                q.beta = b;
                q.wires = [wa[0].clone(), wb[0].clone(), wa[1].clone(), wb[1].clone()];
                q.validate().is_ok().then_some(PlantParams::ThreeD(q))
            }
        };
        out.extend(drawn);
    }
    Ok(out)
}

/// Candidate gains: the paper's first, then `n − 1` seeded draws; with
/// `search_v_offset` each draw's v_offset too (see the module docs).
pub fn candidates(coils: usize, n: usize, seed: u64, search_v_offset: bool) -> Vec<Gains> {
    let mut rng = plant_common::rng::stream(seed, plant_common::rng::IDENTIFY_SEARCH);
    let mut rng_offset = plant_common::rng::stream(seed, plant_common::rng::IDENTIFY_V_OFFSET);
    let (lo, hi) = V_OFFSET_SEARCH_V;
    let mut out = vec![Gains::paper(coils)];
    let log_uniform = |rng: &mut ChaCha8Rng, lo: f64, hi: f64| {
        (lo.ln() + rng.gen::<f64>() * (hi.ln() - lo.ln())).exp()
    };
    while out.len() < n {
        let kp = (0..coils)
            .map(|_| log_uniform(&mut rng, 0.3, 6.0))
            .collect();
        let integral = rng.gen::<bool>();
        let ki = log_uniform(&mut rng, 0.02, 1.0);
        let ilim = 0.1 + 1.4 * rng.gen::<f64>();
        out.push(Gains {
            kp_v_per_deg: kp,
            ki_v_per_deg_s: if integral { ki } else { 0.0 },
            integral_limit_v: if integral { ilim } else { 1.0 },
            v_offset_v: if search_v_offset {
                lo + (hi - lo) * rng_offset.gen::<f64>()
            } else {
                paper_v_offset()
            },
        });
    }
    out
}

/// Scores `gains` on every plant.
pub fn score(
    joint: JointKind,
    gains: &Gains,
    plants: &[PlantParams],
    seed: u64,
) -> anyhow::Result<Score> {
    score_on(joint, gains, plants, seed, &TEST_STEPS)
}

/// A candidate scored with a bound on the cost that matters.
enum Bounded {
    /// Every plant run.
    Scored(Score),
    /// Stopped after this many plants: the runs so far prove its robust
    /// cost above the bound.
    Rejected(usize),
}

/// The least robust cost (mean + population sd over `n` plants) a
/// candidate can still reach when the costs `known` of its first plants
/// are known and the others may be any cost ≥ 0 (every run's cost is).
///
/// Mean + sd is a convex function of the cost vector (the mean is linear,
/// the sd a norm of the centred vector), and symmetric in the unknown
/// costs, so its least value over them is reached with all of them equal
/// to one cost u ≥ 0 (averaging any minimiser over their permutations
/// does not raise it). Along u it is convex: its least value is at u = 0,
/// at a kink (sd = 0: every known cost equal, u that cost), or where its
/// derivative vanishes, which is where sd = mean − u, a quadratic in u
/// (coefficients below, with a = (n − k)/n and the known costs' sum S1
/// and sum of squares S2). The function is evaluated at each of those
/// points and the least value returned: exact but for rounding, which
/// [`REJECT_MARGIN`] covers.
pub fn robust_lower_bound(known: &[f64], n: usize) -> f64 {
    let (k, nf) = (known.len(), n as f64);
    if k == 0 || n < k {
        return 0.0;
    }
    let r = (n - k) as f64;
    let s1: f64 = known.iter().sum();
    let s2: f64 = known.iter().map(|c| c * c).sum();
    let robust_at = |u: f64| {
        let mean = (s1 + r * u) / nf;
        let second = (s2 + r * u * u) / nf;
        mean + (second - mean * mean).max(0.0).sqrt()
    };
    let a = r / nf;
    let qa = (2.0 * a - 1.0) * (1.0 - a);
    let qb = 2.0 * s1 / nf * (1.0 - 2.0 * a);
    let qc = s2 / nf - 2.0 * s1 * s1 / (nf * nf);
    let mut points = vec![0.0, s1 / k as f64];
    if qa.abs() > 1e-12 {
        let disc = qb * qb - 4.0 * qa * qc;
        if disc >= 0.0 {
            let root = disc.sqrt();
            points.push((-qb + root) / (2.0 * qa));
            points.push((-qb - root) / (2.0 * qa));
        }
    } else if qb.abs() > 1e-300 {
        points.push(-qc / qb);
    }
    points
        .into_iter()
        .filter(|u| u.is_finite() && *u >= 0.0)
        .map(robust_at)
        .fold(f64::INFINITY, f64::min)
}

/// [`score`], but stopped once the candidate provably cannot reach
/// `bound` (the paper's robust cost): after each plant, the least robust
/// cost its remaining plants could still give it
/// ([`robust_lower_bound`]) is compared with `bound`; once it exceeds it
/// (by [`REJECT_MARGIN`]) the candidate would lose to the paper's gains
/// whatever the other plants gave, so it cannot win and the rest of its
/// runs are skipped. A candidate run to the end gets exactly [`score`]'s
/// score.
fn score_bounded(
    joint: JointKind,
    gains: &Gains,
    plants: &[PlantParams],
    seed: u64,
    bound: Option<f64>,
) -> anyhow::Result<Bounded> {
    let mut runs: Vec<RunCost> = Vec::with_capacity(plants.len());
    let mut costs = Vec::with_capacity(plants.len());
    for p in plants {
        let run = evaluate(&RunSpec::resolve(&step_scenario(
            joint,
            gains,
            p.clone(),
            seed,
            &TEST_STEPS,
        ))?)?;
        debug_assert!(run.cost >= 0.0, "a run's cost is ≥ 0: {run:?}");
        costs.push(run.cost);
        runs.push(run);
        if let Some(b) = bound {
            if runs.len() < plants.len()
                && robust_lower_bound(&costs, plants.len()) > b * (1.0 + REJECT_MARGIN)
            {
                return Ok(Bounded::Rejected(runs.len()));
            }
        }
    }
    Ok(Bounded::Scored(summarise(runs)))
}

/// Scores `gains` on every plant with the steps `steps`.
fn score_on(
    joint: JointKind,
    gains: &Gains,
    plants: &[PlantParams],
    seed: u64,
    steps: &[(f64, f64)],
) -> anyhow::Result<Score> {
    score_scenarios(plants, |p| step_scenario(joint, gains, p, seed, steps))
}

/// Scores the scenarios `make` gives for each plant.
fn score_scenarios(
    plants: &[PlantParams],
    make: impl Fn(PlantParams) -> Scenario,
) -> anyhow::Result<Score> {
    let runs = plants
        .iter()
        .map(|p| evaluate(&RunSpec::resolve(&make(p.clone()))?))
        .collect::<anyhow::Result<Vec<_>>>()?;
    Ok(summarise(runs))
}

/// The score of a candidate's runs, one per plant (plant 0 first).
fn summarise(runs: Vec<RunCost>) -> Score {
    let n = runs.len() as f64;
    let mean = runs.iter().map(|r| r.cost).sum::<f64>() / n;
    let std = (runs.iter().map(|r| (r.cost - mean).powi(2)).sum::<f64>() / n).sqrt();
    Score {
        mean,
        std,
        robust: mean + std,
        nominal: runs[0].clone(),
    }
}

/// The result of a search.
#[derive(Debug)]
pub struct TuneResult {
    /// The best candidate.
    pub best: Gains,
    /// Its score.
    pub score: Score,
    /// The paper's gains' score.
    pub paper: Score,
    /// Candidates whose runs failed (plant instability), by index.
    pub failed: usize,
    /// Candidates rejected early: their first plants' runs already cost
    /// more than the paper's gains' robust cost.
    pub rejected: usize,
    /// The best and the paper's gains on the held-out steps and plants.
    pub heldout: HeldOut,
}

/// Scores `best` and the paper's gains on every held-out manoeuvre
/// ([`Manoeuvre::all`]) and on `n_plants` plants drawn anew from `file`'s
/// uncertainty (seed `seed + 1` of the plant stream; plant 0 is the
/// identified one, as in the search). The tuned gains beat or tie the
/// paper's only if they do so on every manoeuvre.
pub fn heldout(
    file: &PlantFile,
    best: &Gains,
    n_plants: usize,
    seed: u64,
) -> anyhow::Result<HeldOut> {
    let coils = match file.params()? {
        PlantParams::TwoD(_) => 2,
        PlantParams::ThreeD(_) => 4,
    };
    let paper_gains = Gains::paper(coils);
    Ok(heldout_of(heldout_scores(
        file,
        &[best, &paper_gains],
        n_plants,
        seed,
    )?))
}

/// The held-out verdict from the tuned (first) and the paper's (second)
/// gains' scores on each manoeuvre, [`Manoeuvre::Steps`] first.
fn heldout_of(scores: Vec<(Manoeuvre, Vec<Score>)>) -> HeldOut {
    let mut manoeuvres = Vec::new();
    for (m, pair) in scores {
        let [tuned, paper] = <[Score; 2]>::try_from(pair).expect("two gains scored");
        manoeuvres.push(ManoeuvreScore {
            name: m.name().to_string(),
            beats_or_ties_paper: tuned.robust <= paper.robust * (1.0 + HELDOUT_TIE),
            tuned,
            paper,
        });
    }
    // The steps first: its scores stay where files before the other
    // manoeuvres kept them.
    let steps = manoeuvres.remove(0);
    HeldOut {
        beats_or_ties_paper: steps.beats_or_ties_paper
            && manoeuvres.iter().all(|m| m.beats_or_ties_paper),
        score: steps.tuned,
        paper: steps.paper,
        manoeuvres,
    }
}

/// One held-out manoeuvre's score of `gains` on `plants` (seeded as the
/// search's runs): a unit of the held-out check, here or on a Ray worker.
fn heldout_score(
    joint: JointKind,
    m: Manoeuvre,
    gains: &Gains,
    plants: &[PlantParams],
    seed: u64,
) -> anyhow::Result<Score> {
    score_scenarios(plants, |p| m.scenario(joint, gains, p, seed))
}

/// Each of `gains` scored on every held-out manoeuvre of `file`'s joint
/// on the held-out plants ([`heldout`]), by manoeuvre and then in the
/// order of `gains` (run in parallel; the result does not depend on the
/// threads).
pub fn heldout_scores(
    file: &PlantFile,
    gains: &[&Gains],
    n_plants: usize,
    seed: u64,
) -> anyhow::Result<Vec<(Manoeuvre, Vec<Score>)>> {
    let joint = match file.params()? {
        PlantParams::TwoD(_) => JointKind::TwoD,
        PlantParams::ThreeD(_) => JointKind::ThreeD,
    };
    let plants = sample_plants(file, n_plants.max(1), seed.wrapping_add(1))?;
    let jobs: Vec<(Manoeuvre, usize)> = Manoeuvre::all(joint)
        .iter()
        .flat_map(|&m| (0..gains.len()).map(move |g| (m, g)))
        .collect();
    let scored = jobs
        .par_iter()
        .map(|&(m, g)| {
            heldout_score(joint, m, gains[g], &plants, seed)
                .with_context(|| format!("gains {} on the held-out {}", g, m.name()))
        })
        .collect::<anyhow::Result<Vec<Score>>>()?;
    let mut out: Vec<(Manoeuvre, Vec<Score>)> = Vec::new();
    for ((m, _), score) in jobs.into_iter().zip(scored) {
        match out.last_mut() {
            Some((last, v)) if *last == m => v.push(score),
            _ => out.push((m, vec![score])),
        }
    }
    Ok(out)
}

/// What a search is asked: its counts, seed and whether v_offset is
/// searched.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TuneRequest {
    /// Candidate gain sets (the first is the paper's).
    pub candidates: usize,
    /// Plants per candidate.
    pub plants: usize,
    /// Seed of the candidates and the plant draws.
    pub seed: u64,
    /// Search v_offset too.
    pub search_v_offset: bool,
}

/// One candidate scored: its index in the seeded sequence and its score
/// (`None`: its runs failed, a plant went unstable).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scored {
    /// Index in the candidate sequence (0: the paper's gains).
    pub index: usize,
    /// Its score; absent if its runs failed or it was rejected early.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub score: Option<Score>,
    /// Rejected after this many plants: its runs so far already cost more
    /// than the paper's gains' robust cost ([`TuneSweep::run_unit`]), so
    /// it cannot be the search's winner.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rejected_after_plants: Option<usize>,
}

/// The relative margin by which a candidate's lower bound must exceed the
/// paper's robust cost before it is rejected: rounding in the two sums
/// (≈ 1e-16 relative) cannot then turn a tie into a rejection.
pub const REJECT_MARGIN: f64 = 1e-9;

/// How a search ended.
pub enum TuneOutcome {
    /// Every candidate scored.
    Done(Box<TuneResult>),
    /// Stopped by a signal at a clean point (between candidates): the
    /// candidates scored so far, those given to resume from included, in
    /// index order.
    Stopped(StopSignal, Vec<Scored>),
}

/// Candidates per work unit. One candidate is `plants` closed-loop runs
/// of 25 s: 21 ms a run in the release build (issue 33: 1,000 × 20 in
/// ≈ 7 CPU-minutes), 0.19 s in the Python wheel's `ci-opt` build, so
/// 0.8–8 s for a unit of two candidates of 20 plants, against 0.7–0.9 ms
/// a Ray task costs (5.7 ms under heavy load; docs/benchmarks.md, "Sweeps
/// on Ray"): under 1 % of overhead, 500 units for 1,000 candidates to spread over workers, and
/// a stop or a lost worker costs at most two candidates' work.
pub const UNIT_CANDIDATES: usize = 2;

/// The scored candidates of a sweep's units as a file: what the Python
/// package's Ray driver hands back to `softjoint tune --ray` for the
/// reduction (TOML: Rust's float text reads back as the same bits).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ScoredFile {
    /// The candidates scored, in any order.
    #[serde(default)]
    pub scored: Vec<Scored>,
    /// The held-out check's units, where the driver ran them (any order;
    /// [`TuneSweep::heldout_units`]); without them the program runs the
    /// check itself.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub heldout: Vec<HeldOutScored>,
}

/// A unit of the held-out check (the Monte Carlo over plants drawn anew
/// from the plant file's uncertainty, [`heldout`]): the tuned gains
/// (`gains` 0) or the paper's (1) on manoeuvre `manoeuvre` (its index in
/// [`Manoeuvre::all`]), on every held-out plant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldOutUnit {
    /// Index in [`Manoeuvre::all`] of the sweep's joint.
    pub manoeuvre: usize,
    /// 0: the tuned gains, 1: the paper's.
    pub gains: usize,
}

/// A held-out unit's score, and the search's winner it was run for.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldOutScored {
    /// The winning candidate's index (the tuned gains).
    pub best: usize,
    /// The unit.
    pub unit: HeldOutUnit,
    /// Its score.
    pub score: Score,
}

/// A work unit of a search: candidates `start..end` of the seeded
/// sequence (unit `index` of [`TuneSweep::units`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TuneUnit {
    /// The unit's index.
    pub index: usize,
    /// Its first candidate.
    pub start: usize,
    /// One past its last candidate.
    pub end: usize,
}

/// A search as data: what every unit needs (the plant file, the request,
/// the plants drawn from the file's uncertainty), the units, and the
/// reduction.
pub struct TuneSweep {
    file: PlantFile,
    req: TuneRequest,
    joint: JointKind,
    plants: Vec<PlantParams>,
    /// The seeded candidate sequence, drawn once.
    cands: Vec<Gains>,
    /// Candidate 0's (the paper's gains') result, made once per sweep
    /// (per process: a Ray worker makes its own, the same): the bound
    /// every other candidate is checked against.
    paper: OnceLock<Option<Score>>,
    /// The held-out plants (seed + 1 of the plant stream), drawn on first
    /// use.
    heldout_plants: OnceLock<Vec<PlantParams>>,
}

impl TuneSweep {
    /// The sweep of `req` on `file` (its plants drawn, seeded by
    /// `req.seed`).
    pub fn new(file: &PlantFile, req: TuneRequest) -> anyhow::Result<Self> {
        let (joint, coils) = match file.params()? {
            PlantParams::TwoD(_) => (JointKind::TwoD, 2),
            PlantParams::ThreeD(_) => (JointKind::ThreeD, 4),
        };
        let plants = sample_plants(file, req.plants.max(1), req.seed)?;
        let cands = candidates(coils, req.candidates.max(1), req.seed, req.search_v_offset);
        Ok(Self {
            file: file.clone(),
            req,
            joint,
            plants,
            cands,
            paper: OnceLock::new(),
            heldout_plants: OnceLock::new(),
        })
    }

    /// The paper's gains' score on the sweep's plants (`None`: they
    /// failed), made on first use.
    fn paper(&self) -> &Option<Score> {
        self.paper
            .get_or_init(|| score(self.joint, &self.cands[0], &self.plants, self.req.seed).ok())
    }

    /// The request.
    pub fn request(&self) -> TuneRequest {
        self.req
    }

    /// The joint's kind.
    pub fn joint(&self) -> JointKind {
        self.joint
    }

    /// The units of `size` candidates (the last may be shorter), in order.
    pub fn units(&self, size: usize) -> Vec<TuneUnit> {
        let (n, size) = (self.req.candidates.max(1), size.max(1));
        (0..n.div_ceil(size))
            .map(|index| TuneUnit {
                index,
                start: index * size,
                end: ((index + 1) * size).min(n),
            })
            .collect()
    }

    /// Scores the unit's candidates in order, except those `skip` names
    /// (scored already: a resumed search); `stop` is read before each
    /// candidate and, once asked, the rest are left out. A candidate
    /// whose runs fail (a plant gone unstable) has no score. A candidate
    /// whose first plants already prove it worse than the paper's gains
    /// is rejected there ([`score_bounded`]): it could not have won, so
    /// the search's winner, its score and every file are those of the
    /// search without the rejections.
    pub fn run_unit(
        &self,
        unit: TuneUnit,
        skip: &dyn Fn(usize) -> bool,
        stop: &Stop,
    ) -> Vec<Scored> {
        let end = unit.end.min(self.cands.len());
        let mut out = Vec::new();
        for (index, gains) in self.cands.iter().enumerate().take(end).skip(unit.start) {
            if skip(index) {
                continue;
            }
            if stop.requested().is_some() {
                break;
            }
            let (score, rejected_after_plants) = if index == 0 {
                (self.paper().clone(), None)
            } else {
                let bound = self.paper().as_ref().map(|p| p.robust);
                match score_bounded(self.joint, gains, &self.plants, self.req.seed, bound) {
                    Ok(Bounded::Scored(s)) => (Some(s), None),
                    Ok(Bounded::Rejected(k)) => (None, Some(k)),
                    Err(_) => (None, None),
                }
            };
            out.push(Scored {
                index,
                score,
                rejected_after_plants,
            });
        }
        out
    }

    /// The reduction: every candidate's score (by index, in any order;
    /// one per candidate) to the best of them, the paper's, the failures
    /// and the held-out check (run here, on this process's threads). The
    /// result depends only on the scores, not on where or in which order
    /// they were made.
    pub fn reduce(&self, scored: &[Scored]) -> anyhow::Result<TuneResult> {
        self.reduce_with(scored, None)
    }

    /// The search's winner among `scored` (what [`Self::reduce`] keeps):
    /// its index, its score, the paper's and the counts of failed and
    /// rejected candidates.
    fn winner(&self, scored: &[Scored]) -> anyhow::Result<(usize, Score, Score, usize, usize)> {
        let n = self.req.candidates.max(1);
        let mut scores: Vec<Option<&Option<Score>>> = vec![None; n];
        let mut rejected = 0;
        for s in scored {
            rejected += usize::from(s.rejected_after_plants.is_some());
            match scores.get_mut(s.index) {
                Some(slot @ None) => *slot = Some(&s.score),
                Some(Some(_)) => bail!("candidate {} was scored twice", s.index),
                None => bail!("candidate {} is not one of the {n} searched", s.index),
            }
        }
        if let Some(missing) = scores.iter().position(Option::is_none) {
            bail!("candidate {missing} was not scored");
        }
        let scores: Vec<Option<&Score>> = scores
            .into_iter()
            .map(|s| s.and_then(Option::as_ref))
            .collect();
        let failed = scores.iter().filter(|s| s.is_none()).count() - rejected;
        let paper = scores[0]
            .cloned()
            .context("the paper's gains failed on the identified plant")?;
        let (i, best) = best_of(
            scores
                .iter()
                .enumerate()
                .filter_map(|(i, s)| s.map(|s| (i, s))),
        )
        .context("no candidate could be scored")?;
        Ok((i, best.clone(), paper, failed, rejected))
    }

    /// The index of the search's winner among `scored`: the tuned gains
    /// the held-out units are run for.
    pub fn best_index(&self, scored: &[Scored]) -> anyhow::Result<usize> {
        Ok(self.winner(scored)?.0)
    }

    /// The held-out check's units: each manoeuvre of the joint, the tuned
    /// gains and then the paper's.
    pub fn heldout_units(&self) -> Vec<HeldOutUnit> {
        (0..Manoeuvre::all(self.joint).len())
            .flat_map(|manoeuvre| (0..2).map(move |gains| HeldOutUnit { manoeuvre, gains }))
            .collect()
    }

    /// Runs a held-out unit for the winner `best` (its candidate index):
    /// the same score [`Self::reduce`] computes for it on this process.
    pub fn run_heldout_unit(
        &self,
        best: usize,
        unit: HeldOutUnit,
    ) -> anyhow::Result<HeldOutScored> {
        let m = *Manoeuvre::all(self.joint)
            .get(unit.manoeuvre)
            .with_context(|| {
                format!(
                    "held-out manoeuvre {} of {}",
                    unit.manoeuvre,
                    Manoeuvre::all(self.joint).len()
                )
            })?;
        let coils = match self.joint {
            JointKind::TwoD => 2,
            JointKind::ThreeD => 4,
        };
        let paper = Gains::paper(coils);
        let gains = match unit.gains {
            0 => self
                .cands
                .get(best)
                .with_context(|| format!("candidate {best} is not one of the sweep's"))?,
            1 => &paper,
            g => bail!("held-out gains {g}: 0 (tuned) or 1 (paper)"),
        };
        let plants = match self.heldout_plants.get() {
            Some(p) => p,
            None => {
                let drawn = sample_plants(
                    &self.file,
                    self.req.plants.max(1),
                    self.req.seed.wrapping_add(1),
                )?;
                self.heldout_plants.get_or_init(|| drawn)
            }
        };
        let score = heldout_score(self.joint, m, gains, plants, self.req.seed)
            .with_context(|| format!("gains {} on the held-out {}", unit.gains, m.name()))?;
        Ok(HeldOutScored { best, unit, score })
    }

    /// [`Self::reduce`] with the held-out check's units run elsewhere
    /// (`elsewhere`: every unit of [`Self::heldout_units`] once, for this
    /// search's winner, in any order); `None` runs them here. The result
    /// is the same either way.
    pub fn reduce_with(
        &self,
        scored: &[Scored],
        elsewhere: Option<&[HeldOutScored]>,
    ) -> anyhow::Result<TuneResult> {
        let (i, best, paper, failed, rejected) = self.winner(scored)?;
        let gains = self.cands[i].clone();
        let held = match elsewhere {
            None => heldout(&self.file, &gains, self.req.plants, self.req.seed)?,
            Some(units) => {
                let all = Manoeuvre::all(self.joint);
                let mut slots: Vec<Option<Score>> = vec![None; 2 * all.len()];
                for h in units {
                    if h.best != i {
                        bail!(
                            "a held-out unit was run for candidate {}, the search's winner is {i}",
                            h.best
                        );
                    }
                    let k = 2 * h.unit.manoeuvre + h.unit.gains;
                    match slots.get_mut(k).filter(|_| h.unit.gains < 2) {
                        Some(slot @ None) => *slot = Some(h.score.clone()),
                        Some(Some(_)) => bail!("held-out unit {:?} was run twice", h.unit),
                        None => bail!("held-out unit {:?} is not one of the check's", h.unit),
                    }
                }
                let mut scores = Vec::new();
                for (j, m) in all.iter().enumerate() {
                    let pair = [slots[2 * j].take(), slots[2 * j + 1].take()];
                    match pair {
                        [Some(t), Some(p)] => scores.push((*m, vec![t, p])),
                        _ => bail!("the held-out {} was not run for both gains", m.name()),
                    }
                }
                heldout_of(scores)
            }
        };
        Ok(TuneResult {
            best: gains,
            score: best,
            paper,
            failed,
            rejected,
            heldout: held,
        })
    }
}

/// Searches `req.candidates` gains on `req.plants` plants of `file`, in
/// parallel, skipping the candidates already scored in `done` (a search
/// resumed: the candidates are the same seeded sequence, so their scores
/// hold). The search is a [`TuneSweep`]: its units run on this process's
/// threads (rayon), then its reduction. `stop` is read before each
/// candidate: once asked, no new candidate starts and the search returns
/// what it scored. `progress` shows a bar on standard error.
pub fn tune(
    file: &PlantFile,
    req: TuneRequest,
    progress: bool,
    stop: &Stop,
    done: &[Scored],
) -> anyhow::Result<TuneOutcome> {
    let sweep = TuneSweep::new(file, req)?;
    let n = req.candidates.max(1);
    let mut known: Vec<Option<Scored>> = vec![None; n];
    for d in done.iter().filter(|d| d.index < n) {
        known[d.index] = Some(d.clone());
    }
    let todo = known.iter().filter(|k| k.is_none()).count();
    let bar = crate::progress::counter("tune", "candidates", Some(todo as u64), !progress);
    let skip = |i: usize| known[i].is_some();
    let fresh: Vec<Scored> = sweep
        .units(UNIT_CANDIDATES)
        .into_par_iter()
        .flat_map_iter(|u| {
            let s = sweep.run_unit(u, &skip, stop);
            bar.inc(s.len() as u64);
            s
        })
        .collect();
    bar.finish_and_clear();
    let mut scored: Vec<Scored> = known.into_iter().flatten().collect();
    scored.extend(fresh);
    scored.sort_by_key(|s| s.index);
    if let Some(signal) = stop.requested() {
        if scored.len() < n {
            return Ok(TuneOutcome::Stopped(signal, scored));
        }
    }
    Ok(TuneOutcome::Done(Box::new(sweep.reduce(&scored)?)))
}

impl TuneResult {
    /// The gains file of this result of `req` on the plant file named
    /// `plant_file` (what `softjoint tune` writes, and the Python
    /// package's sweeps return).
    pub fn gains_file(&self, plant_file: &str, joint: JointKind, req: TuneRequest) -> GainsFile {
        GainsFile {
            joint,
            controller: self.best.clone(),
            tuning: Some(Tuning {
                plant_file: plant_file.to_string(),
                candidates: req.candidates,
                plants: req.plants,
                seed: req.seed,
                score: self.score.clone(),
                paper: self.paper.clone(),
                v_offset_searched: req.search_v_offset,
                heldout: Some(self.heldout.clone()),
            }),
        }
    }
}

/// The lowest robust cost (the lower index on a tie).
fn best_of<'a>(scores: impl Iterator<Item = (usize, &'a Score)>) -> Option<(usize, &'a Score)> {
    scores.min_by(|a, b| a.1.robust.total_cmp(&b.1.robust).then(a.0.cmp(&b.0)))
}

/// The comment lines a search state file starts with.
pub const STATE_HEADER: &str = "# Written by `softjoint tune` when stopped: the candidates scored so far.\n# `softjoint tune PLANT --resume THIS_FILE` goes on from here.\n";

/// A search stopped by a signal, written so that `softjoint tune
/// --resume` goes on from it: what it was asked (the plant file, by name
/// and by a hash of its text, the plants, seed and v_offset switch), the
/// candidates scored, and the best so far with its gains (for a person;
/// the resumed search ranks them again).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SearchState {
    /// The plant file searched on.
    pub plant_file: String,
    /// FNV-1a (64 bits, hex) of the plant file's bytes: a resumed search
    /// must be on the same plant.
    pub plant_fnv1a: String,
    /// Candidates the stopped search was asked for.
    pub candidates: usize,
    /// Plants per candidate.
    pub plants: usize,
    /// Seed.
    pub seed: u64,
    /// Whether v_offset was searched.
    pub search_v_offset: bool,
    /// The best candidate so far (absent if none was scored).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub best: Option<BestSoFar>,
    /// The candidates scored, in index order.
    #[serde(default)]
    pub scored: Vec<Scored>,
}

/// The best candidate of a stopped search.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BestSoFar {
    /// Its index in the candidate sequence.
    pub index: usize,
    /// Its gains.
    pub gains: Gains,
    /// Its robust cost.
    pub robust_cost: f64,
}

impl SearchState {
    /// The state of a search of `req` on `plant_file` (whose bytes are
    /// `plant_bytes`) that scored `scored`.
    pub fn new(
        plant_file: &str,
        plant_bytes: &[u8],
        req: TuneRequest,
        coils: usize,
        scored: Vec<Scored>,
    ) -> Self {
        let best = best_of(
            scored
                .iter()
                .filter_map(|s| s.score.as_ref().map(|sc| (s.index, sc))),
        )
        .map(|(index, sc)| BestSoFar {
            index,
            gains: candidates(coils, index + 1, req.seed, req.search_v_offset)[index].clone(),
            robust_cost: sc.robust,
        });
        Self {
            plant_file: plant_file.to_string(),
            plant_fnv1a: fnv1a_hex(plant_bytes),
            candidates: req.candidates,
            plants: req.plants,
            seed: req.seed,
            search_v_offset: req.search_v_offset,
            best,
            scored,
        }
    }

    /// Checks that `req` on a plant file with bytes `plant_bytes` goes on
    /// with this search (the candidate count may differ: the candidates
    /// are one seeded sequence, so a longer search extends a shorter one);
    /// the error names what differs.
    pub fn check_resumes(&self, plant_bytes: &[u8], req: TuneRequest) -> Result<(), String> {
        if self.plant_fnv1a != fnv1a_hex(plant_bytes) {
            return Err(format!(
                "it is a search on another plant file (or {} has changed since)",
                self.plant_file
            ));
        }
        let differs = |flag: &str, was: String, now: String| {
            Err(format!(
                "it is a search with {flag} {was}, this one asks {now}: scores would not compare"
            ))
        };
        if self.plants != req.plants {
            return differs("--plants", self.plants.to_string(), req.plants.to_string());
        }
        if self.seed != req.seed {
            return differs("--seed", self.seed.to_string(), req.seed.to_string());
        }
        if self.search_v_offset != req.search_v_offset {
            let with = |b: bool| if b { "with" } else { "without" };
            return Err(format!(
                "it is a search {} --search-v-offset, this one is {} it: its candidates are other gains",
                with(self.search_v_offset),
                with(req.search_v_offset)
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::record::Row;

    /// The held-out verdict can fail: gains with a tenth of the paper's
    /// K_P (slow, never settling within the band in time) lose to the
    /// paper's on the held-out steps; the paper's own gains tie.
    #[test]
    fn heldout_refuses_gains_that_lose_to_the_papers() {
        let file = PlantFile::new(PlantParams::ThreeD(Joint3dParams::default()), vec![]);
        let mut weak = Gains::paper(4);
        weak.kp_v_per_deg = vec![0.2; 4];
        let h = heldout(&file, &weak, 1, 1).unwrap();
        assert!(!h.beats_or_ties_paper, "{h:?}");
        assert!(h.score.robust > h.paper.robust, "{h:?}");
        let h = heldout(&file, &Gains::paper(4), 1, 1).unwrap();
        assert!(h.beats_or_ties_paper, "{h:?}");
    }

    /// Each plane is metered against its own targets: a joint that
    /// follows the opposite-planes manoeuvre exactly (each plane reaching
    /// its own target 0.3 s after each step, no overshoot) costs the same
    /// as one following the steps alike, and a β that followed α's
    /// targets instead is charged for it. (The meter read only the first
    /// plane's targets before the manoeuvre: β's mirrored steps were
    /// scored as errors of up to 12°.)
    #[test]
    fn each_plane_is_metered_against_its_own_targets() {
        let file = PlantFile::new(PlantParams::ThreeD(Joint3dParams::default()), vec![]);
        let params = file.params().unwrap();
        let cost = |m: Manoeuvre, follow: &dyn Fn(&Scenario, f64, usize) -> f64| {
            let sc = m.scenario(JointKind::ThreeD, &Gains::paper(4), params.clone(), 1);
            let spec = RunSpec::resolve(&sc).unwrap();
            let target = |t: f64, p: usize| {
                sc.targets
                    .iter()
                    .rev()
                    .find(|s| t >= s.t_s)
                    .map_or(0.0, |s| s.deg[p])
            };
            let rows = (0..25_000)
                .map(|i| {
                    let t = i as f64 * 1e-3;
                    let th = [follow(&sc, t, 0), follow(&sc, t, 1)];
                    Row {
                        t_s: t,
                        true_deg: th,
                        estimate_deg: th,
                        desired_deg: [target(t, 0), target(t, 1)],
                        coil_volts: [0.0; 4],
                        faults: 0,
                    }
                })
                .collect();
            let trace = Trace { planes: 2, rows };
            cost_of_trace(&spec, &trace, 60.0, 20.0)
        };
        // Each plane holds its previous target for 0.3 s after a step,
        // then its new one.
        let own = |sc: &Scenario, t: f64, p: usize| {
            let lagged = (t - 0.3).max(0.0);
            sc.targets
                .iter()
                .rev()
                .find(|s| lagged >= s.t_s)
                .map_or(0.0, |s| s.deg[p])
        };
        let alike = cost(Manoeuvre::Steps, &own);
        let opposite = cost(Manoeuvre::OppositePlanes, &own);
        assert!(
            alike.overshoot_deg == 0.0
                && alike.steady_state_error_deg == 0.0
                && alike.settling_s > 0.2
                && alike.settling_s < 0.31,
            "{alike:?}"
        );
        assert_eq!(opposite, alike);
        // β following α's steps on the opposite-planes manoeuvre is off
        // by up to 12° (+6 against −6).
        let wrong = cost(Manoeuvre::OppositePlanes, &|sc, t, _| own(sc, t, 0));
        assert!(wrong.steady_state_error_deg > 11.9, "{wrong:?}");
    }

    /// The robust cost's lower bound is one: no way of filling the plants
    /// not yet run (costs ≥ 0, seeded draws of several shapes) gives a
    /// robust cost below it, the best equal filling meets it (a fine scan
    /// of u), and it is tighter than the plain √(Σc²/n) bound it replaced.
    #[test]
    fn the_robust_lower_bound_is_never_above_a_reachable_cost_and_is_reached() {
        use rand::SeedableRng;
        let robust = |c: &[f64]| {
            let n = c.len() as f64;
            let m = c.iter().sum::<f64>() / n;
            m + (c.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt()
        };
        let mut rng = ChaCha8Rng::seed_from_u64(28);
        let mut tighter = 0;
        for case in 0..400 {
            let n = rng.gen_range(2..25usize);
            let k = rng.gen_range(1..n);
            let known: Vec<f64> = (0..k)
                .map(|_| match case % 4 {
                    0 => rng.gen_range(0.0..10.0),
                    1 => 3.0,
                    2 => rng.gen_range(0.0..1.0f64).powi(4) * 60.0,
                    _ => {
                        if rng.gen_bool(0.5) {
                            0.0
                        } else {
                            50.0 + rng.gen_range(0.0..5.0)
                        }
                    }
                })
                .collect();
            let lb = robust_lower_bound(&known, n);
            for _ in 0..50 {
                let mut c = known.clone();
                let scale = rng.gen_range(0.0..20.0);
                c.extend((k..n).map(|_| rng.gen_range(0.0..1.0f64) * scale));
                assert!(
                    robust(&c) >= lb * (1.0 - 1e-12),
                    "{known:?} n {n}: {} < {lb}",
                    robust(&c)
                );
            }
            let top = known.iter().cloned().fold(0.0, f64::max);
            let scan = (0..=20_000)
                .map(|i| {
                    let mut c = known.clone();
                    c.extend(std::iter::repeat_n(top * i as f64 / 20_000.0, n - k));
                    robust(&c)
                })
                .fold(f64::INFINITY, f64::min);
            assert!(
                lb <= scan * (1.0 + 1e-12),
                "{known:?} n {n}: bound {lb} above the scan's {scan}"
            );
            assert!(
                scan - lb <= 1e-3 * scan.max(1.0),
                "{known:?} n {n}: bound {lb}, scan {scan}"
            );
            let rms = (known.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
            assert!(
                lb >= rms * (1.0 - 1e-12),
                "{known:?} n {n}: {lb} < rms {rms}"
            );
            tighter += usize::from(lb > rms * 1.01);
        }
        assert!(
            tighter > 200,
            "tighter than the rms bound in only {tighter} of 400"
        );
    }

    /// Rejection changes nothing a search reports but its counts: a 3D
    /// search of 8 candidates on 4 plants drawn from the committed
    /// identified plant's 1σ rejects some early, and every candidate it
    /// ran to the end has the score the unbounded scoring gives; the
    /// winner is the unbounded search's.
    #[test]
    fn rejected_candidates_could_not_have_won_and_the_rest_score_as_before() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .parent()
            .unwrap();
        let file = PlantFile::load(&root.join("scenarios/identify/plant.toml")).unwrap();
        let req = TuneRequest {
            candidates: 8,
            plants: 4,
            seed: 3,
            search_v_offset: false,
        };
        let sweep = TuneSweep::new(&file, req).unwrap();
        let bounded: Vec<Scored> = sweep
            .units(UNIT_CANDIDATES)
            .into_iter()
            .flat_map(|u| sweep.run_unit(u, &|_| false, &Stop::never()))
            .collect();
        let rejected = bounded
            .iter()
            .filter(|s| s.rejected_after_plants.is_some())
            .count();
        assert!(rejected > 0, "nothing rejected: the test shows nothing");
        let paper = bounded[0].score.clone().unwrap();
        let mut best_unbounded = (0, paper.robust);
        for (s, g) in bounded.iter().zip(&sweep.cands) {
            let full = score(sweep.joint, g, &sweep.plants, req.seed).ok();
            match (&s.score, s.rejected_after_plants) {
                (Some(sc), None) => assert_eq!(Some(sc), full.as_ref(), "candidate {}", s.index),
                (None, Some(k)) => {
                    assert!(k < req.plants);
                    let f = full.as_ref().expect("a rejected candidate ran in full");
                    assert!(
                        f.robust > paper.robust,
                        "candidate {} rejected at {k} plants but robust {} ≤ paper {}",
                        s.index,
                        f.robust,
                        paper.robust
                    );
                }
                (None, None) => assert!(full.is_none()),
                (Some(_), Some(_)) => panic!("scored and rejected"),
            }
            if let Some(f) = &full {
                if f.robust < best_unbounded.1 {
                    best_unbounded = (s.index, f.robust);
                }
            }
        }
        let (i, _) = best_of(
            bounded
                .iter()
                .filter_map(|s| s.score.as_ref().map(|sc| (s.index, sc))),
        )
        .unwrap();
        assert_eq!(i, best_unbounded.0);
    }

    /// A sweep's units, of any size and reduced in any order, give what
    /// the search gives, and each unit's scores are the candidates'
    /// scores made one by one with [`score`] (the search before the
    /// units).
    #[test]
    fn units_of_any_size_in_any_order_reduce_to_the_search() {
        let file = PlantFile::new(PlantParams::TwoD(Joint2dParams::default()), vec![]);
        let req = TuneRequest {
            candidates: 3,
            plants: 1,
            seed: 9,
            search_v_offset: true,
        };
        let sweep = TuneSweep::new(&file, req).unwrap();
        let plants = sample_plants(&file, 1, 9).unwrap();
        let one_by_one: Vec<Scored> = candidates(2, 3, 9, true)
            .iter()
            .enumerate()
            .map(|(index, g)| Scored {
                index,
                score: score(JointKind::TwoD, g, &plants, 9).ok(),
                rejected_after_plants: None,
            })
            .collect();
        let mut by_units: Vec<Scored> = sweep
            .units(2)
            .into_iter()
            .rev()
            .flat_map(|u| sweep.run_unit(u, &|_| false, &Stop::never()))
            .collect();
        assert_eq!(sweep.units(2).len(), 2);
        by_units.sort_by_key(|s| s.index);
        assert_eq!(by_units, one_by_one);
        let mut reversed = one_by_one.clone();
        reversed.reverse();
        let reduced = sweep.reduce(&reversed).unwrap();
        let TuneOutcome::Done(searched) = tune(&file, req, false, &Stop::never(), &[]).unwrap()
        else {
            panic!("not stopped")
        };
        let name = "p.toml";
        assert_eq!(
            reduced.gains_file(name, JointKind::TwoD, req),
            searched.gains_file(name, JointKind::TwoD, req)
        );
        assert_eq!(reduced.failed, searched.failed);
    }

    #[test]
    fn heldout_units_run_one_by_one_give_the_reductions_check_and_misfits_are_refused() {
        let file = PlantFile::new(PlantParams::TwoD(Joint2dParams::default()), vec![]);
        let req = TuneRequest {
            candidates: 3,
            plants: 2,
            seed: 4,
            search_v_offset: false,
        };
        let sweep = TuneSweep::new(&file, req).unwrap();
        let scored: Vec<Scored> = sweep
            .units(3)
            .into_iter()
            .flat_map(|u| sweep.run_unit(u, &|_| false, &Stop::never()))
            .collect();
        let here = sweep.reduce(&scored).unwrap();
        let best = sweep.best_index(&scored).unwrap();
        let units = sweep.heldout_units();
        // 2D: steps and load, each for the tuned and the paper's gains.
        assert_eq!(units.len(), 4);
        let mut there: Vec<HeldOutScored> = units
            .iter()
            .rev()
            .map(|&u| sweep.run_heldout_unit(best, u).unwrap())
            .collect();
        let elsewhere = sweep.reduce_with(&scored, Some(&there)).unwrap();
        assert_eq!(elsewhere.heldout, here.heldout);
        let name = "p.toml";
        assert_eq!(
            elsewhere.gains_file(name, JointKind::TwoD, req),
            here.gains_file(name, JointKind::TwoD, req)
        );
        // A unit missing, one twice, one run for another candidate.
        let missing = &there[1..];
        let e = sweep.reduce_with(&scored, Some(missing)).unwrap_err();
        assert!(format!("{e}").contains("was not run for both gains"), "{e}");
        let mut twice = there.clone();
        twice.push(there[0].clone());
        let e = sweep.reduce_with(&scored, Some(&twice)).unwrap_err();
        assert!(format!("{e}").contains("was run twice"), "{e}");
        there[2].best = (best + 1) % 3;
        let e = sweep.reduce_with(&scored, Some(&there)).unwrap_err();
        assert!(format!("{e}").contains("the search's winner is"), "{e}");
        let e = sweep
            .run_heldout_unit(
                best,
                HeldOutUnit {
                    manoeuvre: 2,
                    gains: 0,
                },
            )
            .unwrap_err();
        assert!(format!("{e}").contains("held-out manoeuvre 2 of 2"), "{e}");
    }

    /// FNV-1a against the published test vectors (the FNV authors' list:
    /// "" → cbf29ce484222325, "a" → af63dc4c8601ec8c, "foobar" →
    /// 85944171f73967e8).
    #[test]
    fn the_plant_fingerprint_is_fnv1a() {
        assert_eq!(fnv1a_hex(b""), "cbf29ce484222325");
        assert_eq!(fnv1a_hex(b"a"), "af63dc4c8601ec8c");
        assert_eq!(fnv1a_hex(b"foobar"), "85944171f73967e8");
    }

    /// `--search-v-offset` adds v_offset to the draws without changing the
    /// other gains (its own stream), keeps the paper's candidate first and
    /// stays in its range; without it every candidate has 1.7 V.
    #[test]
    fn v_offset_is_searched_on_its_own_stream() {
        let plain = candidates(4, 50, 3, false);
        let searched = candidates(4, 50, 3, true);
        assert_eq!(searched[0], Gains::paper(4));
        let (lo, hi) = V_OFFSET_SEARCH_V;
        let mut distinct = std::collections::BTreeSet::new();
        for (p, s) in plain.iter().zip(&searched).skip(1) {
            assert_eq!(p.kp_v_per_deg, s.kp_v_per_deg);
            assert_eq!(p.ki_v_per_deg_s, s.ki_v_per_deg_s);
            assert_eq!(p.integral_limit_v, s.integral_limit_v);
            assert_eq!(p.v_offset_v, paper_v_offset());
            assert!((lo..=hi).contains(&s.v_offset_v), "{}", s.v_offset_v);
            distinct.insert((s.v_offset_v * 1e6) as i64);
        }
        assert_eq!(distinct.len(), 49, "every draw its own v_offset");
    }
}
