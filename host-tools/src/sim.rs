//! Running a scenario: the firmware core in closed loop with the simulated
//! joint (through `hal-sim`), and the summary a user reads.

use std::time::Instant;

use anyhow::{bail, Context};
use firmware::control::PairGains;
use firmware::estimate::PlaneLaw;
use firmware::joint::{JointConfig, JointController};
use firmware::supervisor::Faults;
use hal_sim::{ClosedLoop, FeedbackSource, Plant};
use plant_models::joint::{
    Joint2d, Joint2dParams, Joint3d, Joint3dParams, LoadId, Plane, PointLoad,
};
use serde::Serialize;

use crate::calibrate::{self, CalibrationFile, SweepRow};
use crate::scenario::{
    ControlMode, Disturbance, EstimatorMethod, FeedbackKind, JointKind, Scenario, TargetTracker,
};

/// One row of the time series. Fixed-size so recording a step does not
/// allocate: a 2D joint uses index 0 of the angle arrays and coils 0–1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Row {
    /// Time (s).
    pub t_s: f64,
    /// True angles (deg).
    pub true_deg: [f64; 2],
    /// Estimated angles (deg).
    pub estimate_deg: [f64; 2],
    /// Desired angles (deg).
    pub desired_deg: [f64; 2],
    /// Driver input voltages, paper numbering (V).
    pub coil_volts: [f64; 4],
    /// Fault bits.
    pub faults: u16,
}

/// The time series of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Angles per row that are used (1 or 2).
    pub planes: usize,
    /// One row per control period.
    pub rows: Vec<Row>,
}

fn pad<const N: usize, const M: usize>(v: [f64; N]) -> [f64; M] {
    core::array::from_fn(|i| v.get(i).copied().unwrap_or(f64::NAN))
}

/// Steady-state error of one target segment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Segment {
    /// Segment start (s).
    pub from_s: f64,
    /// Segment end (s).
    pub to_s: f64,
    /// Desired angles (deg).
    pub desired_deg: Vec<f64>,
    /// |mean true angle − desired| over the last 20 % of the segment (deg).
    pub steady_state_error_deg: Vec<f64>,
    /// Largest excursion beyond the target in the direction of travel (deg).
    pub overshoot_deg: Vec<f64>,
}

/// The summary of a run (also the `--json` output).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// "2d" or "3d".
    pub joint: String,
    /// Names of the controlled angles.
    pub angles: Vec<String>,
    /// Worst steady-state error over the target segments, per angle (deg).
    pub steady_state_error_deg: Vec<f64>,
    /// Largest |estimate − true| over the run, per angle (deg).
    pub max_estimation_error_deg: Vec<f64>,
    /// Per-segment details.
    pub segments: Vec<Segment>,
    /// Simulated seconds.
    pub sim_seconds: f64,
    /// Wall-clock seconds of the closed loop.
    pub wall_seconds: f64,
    /// sim_seconds / wall_seconds.
    pub realtime_factor: f64,
    /// Control steps.
    pub steps: u64,
    /// Every fault seen during the run.
    pub faults_seen: Vec<String>,
    /// Estimation method and its source.
    pub estimator: String,
    /// Peak modelled coil temperature (°C), per coil.
    pub peak_coil_temperature_c: Vec<f64>,
}

/// Names of the set bits of a fault word.
pub fn fault_names(bits: u16) -> Vec<String> {
    Faults::NAMED
        .iter()
        .filter(|(f, _)| Faults::from_bits(bits).contains(*f))
        .map(|(_, n)| (*n).to_string())
        .collect()
}

fn gains(s: &Scenario, pair: usize) -> anyhow::Result<PairGains> {
    let kp = &s.controller.kp_v_per_deg;
    let k = |coil: usize| kp.get(coil).or(kp.first()).copied().unwrap_or(2.0) as f32;
    // Pair p's agonist is coil p+1, its antagonist coil p+1+planes.
    let planes = s.planes();
    PairGains::new(
        k(pair),
        k(pair + planes),
        s.controller.ki_v_per_deg_s as f32,
        s.controller.integral_limit_v as f32,
    )
    .map_err(|e| anyhow::anyhow!("controller gains: {e:?}"))
}

/// Builds the estimation laws for the scenario: the paper's, a calibration
/// file's, or a fit to a simulated calibration sweep of the same joint.
pub fn laws_for(s: &Scenario) -> anyhow::Result<(Option<Vec<PlaneLaw>>, String)> {
    if s.estimator.method == EstimatorMethod::Paper || s.feedback == FeedbackKind::Camera {
        return Ok((None, "paper (Eq. 2 / Eq. 3, published constants)".into()));
    }
    let (fits_cal, source) = match &s.estimator.calibration {
        Some(path) => (
            CalibrationFile::load(path)?,
            format!("calibration file {}", path.display()),
        ),
        None => {
            let rows = calibration_sweep(s)?;
            let fits = calibrate::fit(&rows)?;
            // `switching` is what `calibrate wire` writes: Eq. 4 with the
            // threshold its search finds, kept only where a second branch
            // pays (otherwise the differential branch alone, Eq. 5's form).
            // `single` and `differential` force that method.
            let cal = match s.estimator.method {
                EstimatorMethod::Single => calibrate::calibration_with(&fits, "single")?,
                EstimatorMethod::Differential => {
                    calibrate::calibration_with(&fits, "differential")?
                }
                _ => calibrate::calibration_of(&fits)?,
            };
            (
                cal,
                format!("fitted to a simulated sweep ({} rows)", rows.len()),
            )
        }
    };
    let laws = fits_cal.laws()?;
    if laws.len() != s.planes() {
        bail!(
            "calibration has {} angle(s), the scenario's joint has {}",
            laws.len(),
            s.planes()
        );
    }
    let method = match laws[0] {
        PlaneLaw::Single { .. } => "single-sensor quadratic",
        PlaneLaw::Differential { .. } => "differential linear",
        PlaneLaw::Switching { .. } => "threshold switching",
    };
    Ok((Some(laws), format!("{method}, {source}")))
}

/// What one run produced.
pub struct RunOutput {
    /// The summary.
    pub summary: Summary,
    /// The time series.
    pub trace: Trace,
}

/// Runs a scenario to completion, keeping the time series.
pub fn run(s: &Scenario) -> anyhow::Result<RunOutput> {
    run_with(s, true)
}

/// Runs a scenario to completion; the time series is kept only with
/// `keep_trace` (otherwise `trace.rows` is empty). The summary is the same
/// either way: it is accumulated row by row ([`SummaryBuilder`]). A 600 s
/// run's series is 58 MB, which costs page faults and memory traffic when
/// nobody asked for `--csv` or `--plot`.
pub fn run_with(s: &Scenario, keep_trace: bool) -> anyhow::Result<RunOutput> {
    s.validate()?;
    let (laws, estimator) = laws_for(s)?;
    match s.joint {
        JointKind::ThreeD => {
            let plant = plant_3d(s)?;
            let mut cfg = JointConfig::paper_3d();
            for p in 0..2 {
                cfg.gains[p] = gains(s, p)?;
            }
            if let Some(l) = &laws {
                cfg.laws = [l[0], l[1]];
            }
            if s.controller.mode == ControlMode::Single {
                cfg.modes = [firmware::control::PairMode::SingleAgonist; 2];
            }
            let ctl =
                JointController::new(cfg).map_err(|e| anyhow::anyhow!("controller: {e:?}"))?;
            let cl: ClosedLoop<Joint3d, 2, 4, 4> =
                ClosedLoop::new(plant, ctl, feedback(s), s.control_period_us, s.seed)?;
            run_loop(s, cl, keep_trace, estimator, &["alpha", "beta"], load_3d)
        }
        JointKind::TwoD => {
            let mut params = Joint2dParams::default();
            params.sim.seed = s.seed;
            if s.plant.rigid_bearing {
                params = params.rigid_bearing();
            }
            let plant = Joint2d::new(params).context("building the 2D plant")?;
            let mut cfg = JointConfig::paper_2d_wire();
            cfg.gains[0] = gains(s, 0)?;
            if let Some(l) = &laws {
                cfg.laws = [l[0]];
            }
            if s.controller.mode == ControlMode::Single {
                cfg.modes = [firmware::control::PairMode::SingleAgonist];
            }
            let ctl =
                JointController::new(cfg).map_err(|e| anyhow::anyhow!("controller: {e:?}"))?;
            let cl: ClosedLoop<Joint2d, 1, 1, 2> =
                ClosedLoop::new(plant, ctl, feedback(s), s.control_period_us, s.seed)?;
            run_loop(
                s,
                cl,
                keep_trace,
                estimator,
                &["theta"],
                |plant, load, on| match load {
                    LoadAction::Weight { load, .. } => {
                        if let Some(id) = on {
                            plant.remove_load(id);
                            Ok(None)
                        } else {
                            Ok(Some(plant.add_load(load)?))
                        }
                    }
                },
            )
        }
    }
}

/// Hangs (no id) or cuts (with id) a weight on the 3D plant.
pub fn load_3d(
    plant: &mut Joint3d,
    action: LoadAction,
    id: Option<LoadId>,
) -> Result<Option<LoadId>, plant_models::joint::PlantError> {
    let LoadAction::Weight { plane, load } = action;
    let which = if plane == 1 {
        Plane::Beta
    } else {
        Plane::Alpha
    };
    match id {
        Some(id) => {
            plant.remove_load(which, id);
            Ok(None)
        }
        None => Ok(Some(plant.add_load(which, load)?)),
    }
}

/// The 3D plant of a scenario.
pub fn plant_3d(s: &Scenario) -> anyhow::Result<Joint3d> {
    let mut params = Joint3dParams::default();
    params.sim.seed = s.seed;
    if s.plant.rigid_bearing {
        params.alpha = params.alpha.rigid_bearing();
        params.beta = params.beta.rigid_bearing();
    }
    Joint3d::new(params).context("building the 3D plant")
}

/// Pair gains of a scenario (public for `hil`).
pub fn pair_gains(s: &Scenario, pair: usize) -> anyhow::Result<PairGains> {
    gains(s, pair)
}

fn feedback(s: &Scenario) -> FeedbackSource {
    match s.feedback {
        FeedbackKind::Wire => FeedbackSource::Wire,
        FeedbackKind::Camera => FeedbackSource::Camera,
    }
}

/// A load to attach or remove.
#[derive(Clone, Copy, Debug)]
pub enum LoadAction {
    /// A point load on a plane.
    Weight {
        /// Plane index.
        plane: usize,
        /// The load.
        load: PointLoad,
    },
}

/// Link end distance from the joint origin (m), for hanging weights: the
/// paper's 27 mm (seed 000, last paper, §II-B).
const LINK_END_M: f64 = 0.027;
/// Standard gravity (m/s²).
const G_M_S2: f64 = 9.80665;

fn run_loop<Pl, const P: usize, const S: usize, const C: usize>(
    s: &Scenario,
    mut cl: ClosedLoop<Pl, P, S, C>,
    keep_trace: bool,
    estimator: String,
    names: &[&str],
    mut apply_load: impl FnMut(
        &mut Pl,
        LoadAction,
        Option<LoadId>,
    ) -> Result<Option<LoadId>, plant_models::joint::PlantError>,
) -> anyhow::Result<RunOutput>
where
    Pl: Plant<C, S, P>,
{
    let (period, steps) = (s.period_s(), s.steps());
    let mut rows = Vec::with_capacity(if keep_trace { steps as usize } else { 0 });
    let mut stats = SummaryBuilder::new(s, P);
    let mut disturber = Disturber::new(s);
    let mut faults_seen = 0u16;
    let mut peak_temp = [f64::NEG_INFINITY; C];
    let mut targets = TargetTracker::default();
    let started = Instant::now();
    for k in 0..steps {
        let t = k as f64 * period;
        if let Some(target) = targets.changed(s, t) {
            for (p, d) in target.iter().enumerate() {
                cl.controller
                    .set_target(p, *d as f32)
                    .map_err(|e| anyhow::anyhow!("target: {e:?}"))?;
            }
        }
        cl.overrides = [None; C];
        disturber.apply(s, t, &mut cl.overrides, |action, id| {
            apply_load(&mut cl.plant, action, id)
        })?;
        let sample = cl.tick().with_context(|| format!("at t = {t:.3} s"))?;
        faults_seen |= sample.faults;
        for (p, c) in peak_temp.iter_mut().zip(cl.plant.coil_temperatures_c()) {
            *p = p.max(c);
        }
        let row = Row {
            t_s: sample.t_s,
            true_deg: pad(sample.true_deg),
            estimate_deg: pad(sample.estimate_deg),
            desired_deg: pad(sample.desired_deg),
            coil_volts: pad(sample.coil_volts),
            faults: sample.faults,
        };
        stats.push(&row);
        if keep_trace {
            rows.push(row);
        }
    }
    let wall = started.elapsed().as_secs_f64();
    let summary = stats.finish(s, names, wall, estimator, faults_seen, peak_temp.to_vec());
    Ok(RunOutput {
        summary,
        trace: Trace { planes: P, rows },
    })
}

/// Applies a scenario's disturbances as time passes (shared by `sim` and
/// `hil`): coil-voltage overrides, and weights hung and cut.
pub struct Disturber {
    loads: Vec<Option<LoadId>>,
}

impl Disturber {
    /// Nothing applied yet.
    pub fn new(s: &Scenario) -> Self {
        Self {
            loads: vec![None; s.disturbances.len()],
        }
    }

    /// Sets the coil overrides active at `t_s` (coil index = paper number
    /// − 1) and hangs or cuts weights through `load` (attach when given no
    /// id, remove when given one).
    pub fn apply<const C: usize>(
        &mut self,
        s: &Scenario,
        t_s: f64,
        overrides: &mut [Option<f64>; C],
        mut load: impl FnMut(
            LoadAction,
            Option<LoadId>,
        ) -> Result<Option<LoadId>, plant_models::joint::PlantError>,
    ) -> anyhow::Result<()> {
        for (i, d) in s.disturbances.iter().enumerate() {
            match d {
                Disturbance::CoilVoltage {
                    coil,
                    volts,
                    from_s,
                    to_s,
                } => {
                    if t_s >= *from_s && t_s < *to_s {
                        if let Some(o) = overrides.get_mut(coil.saturating_sub(1)) {
                            *o = Some(*volts);
                        }
                    }
                }
                Disturbance::Weight {
                    mass_g,
                    plane,
                    direction,
                    from_s,
                    to_s,
                } => {
                    let active = t_s >= *from_s && t_s < *to_s;
                    // Hung and not to be, or the reverse: build the load
                    // only then, not on every step.
                    if active == self.loads[i].is_some() {
                        continue;
                    }
                    let plane = usize::from(plane.as_deref() == Some("beta"));
                    let dir = direction.unwrap_or([-1.0, 0.0]);
                    let w = PointLoad::weight(mass_g * 1e-3, G_M_S2, [0.0, LINK_END_M], dir);
                    let action = LoadAction::Weight { plane, load: w };
                    if active {
                        self.loads[i] = load(action, None)?;
                    } else {
                        load(action, self.loads[i].take())?;
                    }
                }
            }
        }
        Ok(())
    }
}

/// The summary of a finished run (shared by `sim` and `hil`).
pub fn summarize(
    s: &Scenario,
    trace: &Trace,
    names: &[&str],
    wall_seconds: f64,
    estimator: String,
    faults_seen: u16,
    peak_coil_temperature_c: Vec<f64>,
) -> Summary {
    let mut b = SummaryBuilder::new(s, trace.planes);
    for r in &trace.rows {
        b.push(r);
    }
    b.finish(
        s,
        names,
        wall_seconds,
        estimator,
        faults_seen,
        peak_coil_temperature_c,
    )
}

/// Splits the run at target changes and measures each segment.
pub fn segments(s: &Scenario, trace: &Trace) -> Vec<Segment> {
    let mut b = SummaryBuilder::new(s, trace.planes);
    for r in &trace.rows {
        b.push(r);
    }
    b.segments()
}

/// The neutral element of `Iterator::sum` for `f64` (−0.0 in current Rust,
/// +0.0 in older), so running sums match a `sum()` over the same values.
fn sum_start() -> f64 {
    core::iter::empty::<f64>().sum()
}

/// Running statistics of one target segment (see [`SummaryBuilder`]).
#[derive(Clone, Debug)]
struct SegmentStats {
    from_s: f64,
    to_s: f64,
    /// Start of the last 20 % of the segment.
    tail_from_s: f64,
    desired_deg: Vec<f64>,
    rows: u64,
    first_true_deg: [f64; 2],
    tail_sum_deg: [f64; 2],
    tail_rows: usize,
    /// Running max (from 0) of `true − desired`: the overshoot if the
    /// segment moves upwards.
    above_deg: [f64; 2],
    /// Running max (from 0) of `−(true − desired)`: the overshoot if it
    /// moves downwards.
    below_deg: [f64; 2],
}

/// The run summary accumulated one row at a time, so a run need not keep
/// its time series to be summarised. Each statistic sees the same values
/// in the same order as a pass over the stored rows would (sums start from
/// `sum()`'s neutral element, maxima from 0), so the figures are identical.
#[derive(Clone, Debug)]
pub struct SummaryBuilder {
    planes: usize,
    rows: u64,
    max_estimation_error_deg: [f64; 2],
    segments: Vec<SegmentStats>,
    /// First segment that has not ended at the last row's time: targets are
    /// validated in time order, so segments are ordered and disjoint and
    /// each row belongs to this one or to none.
    cursor: usize,
}

impl SummaryBuilder {
    /// Nothing seen yet, for a run of `s` with `planes` angles.
    pub fn new(s: &Scenario, planes: usize) -> Self {
        let end = s.duration_s;
        let segments = s
            .targets
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let from = t.t_s;
                let to = s.targets.get(i + 1).map(|n| n.t_s).unwrap_or(end).min(end);
                (to > from).then(|| SegmentStats {
                    from_s: from,
                    to_s: to,
                    tail_from_s: to - 0.2 * (to - from),
                    desired_deg: t.deg.clone(),
                    rows: 0,
                    first_true_deg: [0.0; 2],
                    tail_sum_deg: [sum_start(); 2],
                    tail_rows: 0,
                    above_deg: [0.0; 2],
                    below_deg: [0.0; 2],
                })
            })
            .collect();
        Self {
            planes,
            rows: 0,
            max_estimation_error_deg: [0.0; 2],
            segments,
            cursor: 0,
        }
    }

    /// Adds one control period's row; rows come in time order.
    #[inline]
    pub fn push(&mut self, r: &Row) {
        self.rows += 1;
        for (p, m) in self
            .max_estimation_error_deg
            .iter_mut()
            .enumerate()
            .take(self.planes)
        {
            let e = (r.estimate_deg[p] - r.true_deg[p]).abs();
            if e.is_finite() {
                *m = m.max(e);
            }
        }
        while self
            .segments
            .get(self.cursor)
            .is_some_and(|g| r.t_s >= g.to_s)
        {
            self.cursor += 1;
        }
        if let Some(g) = self.segments.get_mut(self.cursor) {
            if r.t_s < g.from_s {
                return;
            }
            if g.rows == 0 {
                g.first_true_deg = r.true_deg;
            }
            g.rows += 1;
            let tail = r.t_s >= g.tail_from_s;
            if tail {
                g.tail_rows += 1;
            }
            for (p, d) in g.desired_deg.iter().enumerate() {
                let x = r.true_deg[p];
                if tail {
                    g.tail_sum_deg[p] += x;
                }
                let e = x - d;
                g.above_deg[p] = g.above_deg[p].max(e);
                g.below_deg[p] = g.below_deg[p].max(-e);
            }
        }
    }

    /// The target segments that saw rows, measured: steady-state error over
    /// the last 20 %, overshoot in the direction of travel from the previous
    /// segment's target (the first from its first true angle).
    pub fn segments(&self) -> Vec<Segment> {
        let mut out = Vec::new();
        let mut prev_target: Option<&[f64]> = None;
        for g in self.segments.iter().filter(|g| g.rows > 0) {
            let planes = g.desired_deg.len();
            let sse = (0..planes)
                .map(|p| {
                    let mean = g.tail_sum_deg[p] / g.tail_rows.max(1) as f64;
                    (mean - g.desired_deg[p]).abs()
                })
                .collect();
            let overshoot = (0..planes)
                .map(|p| {
                    let start = prev_target.map(|v| v[p]).unwrap_or(g.first_true_deg[p]);
                    let dir = (g.desired_deg[p] - start).signum();
                    if dir == 1.0 {
                        g.above_deg[p]
                    } else if dir == -1.0 {
                        g.below_deg[p]
                    } else {
                        // 0 or NaN: no direction of travel.
                        0.0
                    }
                })
                .collect();
            out.push(Segment {
                from_s: g.from_s,
                to_s: g.to_s,
                desired_deg: g.desired_deg.clone(),
                steady_state_error_deg: sse,
                overshoot_deg: overshoot,
            });
            prev_target = Some(&g.desired_deg);
        }
        out
    }

    /// The summary (`wall_seconds` and the rest as for [`summarize`]).
    pub fn finish(
        &self,
        s: &Scenario,
        names: &[&str],
        wall_seconds: f64,
        estimator: String,
        faults_seen: u16,
        peak_coil_temperature_c: Vec<f64>,
    ) -> Summary {
        let planes = self.planes;
        let segments = self.segments();
        let sse: Vec<f64> = (0..planes)
            .map(|p| {
                segments
                    .iter()
                    .map(|g| g.steady_state_error_deg[p])
                    .fold(0.0, f64::max)
            })
            .collect();
        let period = f64::from(s.control_period_us) * 1e-6;
        let sim_seconds = self.rows as f64 * period;
        Summary {
            scenario: s.name.clone(),
            joint: if planes == 1 {
                "2d".into()
            } else {
                "3d".into()
            },
            angles: names.iter().map(|n| n.to_string()).collect(),
            steady_state_error_deg: sse,
            max_estimation_error_deg: self.max_estimation_error_deg[..planes].to_vec(),
            segments,
            sim_seconds,
            wall_seconds,
            realtime_factor: if wall_seconds > 0.0 {
                sim_seconds / wall_seconds
            } else {
                f64::INFINITY
            },
            steps: self.rows,
            faults_seen: fault_names(faults_seen),
            estimator,
            peak_coil_temperature_c,
        }
    }
}

/// A calibration sweep of the scenario's joint: the link follows a slow
/// triangle 0 → +20° → −20° → 0 at 1°/s, and every camera frame gives one
/// row of wire insertions and the camera's angles (with its noise and its
/// one-frame latency, ≈ 0.03° at this rate). The camera is the reference
/// only: the joint is moved by the firmware's P law on the wires with the
/// paper's published Eq. 2 / Eq. 3, because P control on 30 frames/s camera
/// feedback limit-cycles between the coils and overheats them (the thermal
/// budget then cuts them for much of the sweep). Frames taken while any
/// fault is active are skipped.
///
/// Why moving rather than held: a staircase with 8 s dwells (the paper's
/// static images) was tried. Laws fitted to it read held angles to 0.2–0.4°
/// but moving ones to 1.0–1.2°, because a moving wire lags in its tube; the
/// slow sweep covers both and its laws stay below 1° on independent runs.
pub fn calibration_sweep(s: &Scenario) -> anyhow::Result<Vec<SweepRow>> {
    const AMPLITUDE_DEG: f64 = 20.0;
    const RATE_DEG_S: f64 = 1.0;
    let period_us = 1000u32;
    let quarter = AMPLITUDE_DEG / RATE_DEG_S;
    let target = |t: f64| {
        if t < quarter {
            t * RATE_DEG_S
        } else if t < 3.0 * quarter {
            AMPLITUDE_DEG - (t - quarter) * RATE_DEG_S
        } else {
            -AMPLITUDE_DEG + (t - 3.0 * quarter) * RATE_DEG_S
        }
    };
    let duration = 4.0 * quarter;
    let steps = (duration / (f64::from(period_us) * 1e-6)).round() as u64;
    let seed = s.seed ^ 0xCA1B;
    match s.joint {
        JointKind::ThreeD => {
            let mut params = Joint3dParams::default();
            params.sim.seed = seed;
            let ctl = JointController::new(JointConfig::paper_3d())
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let cl: ClosedLoop<Joint3d, 2, 4, 4> = ClosedLoop::new(
                Joint3d::new(params)?,
                ctl,
                FeedbackSource::Wire,
                period_us,
                s.seed,
            )?;
            sweep_rows(cl, steps, target)
        }
        JointKind::TwoD => {
            let mut params = Joint2dParams::default();
            params.sim.seed = seed;
            let ctl = JointController::new(JointConfig::paper_2d_wire())
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
            let cl: ClosedLoop<Joint2d, 1, 1, 2> = ClosedLoop::new(
                Joint2d::new(params)?,
                ctl,
                FeedbackSource::Wire,
                period_us,
                s.seed,
            )?;
            sweep_rows(cl, steps, target)
        }
    }
}

/// Runs a calibration sweep: every plane follows `target(t)`; each camera
/// frame that arrives while no fault is active gives one row. With wire
/// feedback nothing else consumes camera frames, so each is seen once. The
/// camera's one-frame latency makes each angle ~33 ms older than the
/// insertions beside it: at 1°/s that is 0.03°, well under the estimation
/// errors being calibrated.
fn sweep_rows<Pl, const P: usize, const S: usize, const C: usize>(
    mut cl: ClosedLoop<Pl, P, S, C>,
    steps: u64,
    target: impl Fn(f64) -> f64,
) -> anyhow::Result<Vec<SweepRow>>
where
    Pl: Plant<C, S, P>,
{
    let mut rows = Vec::new();
    let period = cl.period_s();
    for k in 0..steps {
        let d = target(k as f64 * period) as f32;
        for p in 0..P {
            cl.controller
                .set_target(p, d)
                .map_err(|e| anyhow::anyhow!("{e:?}"))?;
        }
        let faults = cl.control().faults;
        cl.advance()?;
        if let Some(angles) = cl.plant.take_camera() {
            if faults.is_empty() {
                let res = cl.plant.mm_per_count();
                let d_mm = cl
                    .plant
                    .counts()
                    .iter()
                    .zip(res)
                    .map(|(c, r)| *c as f64 * r)
                    .collect();
                rows.push(SweepRow {
                    d_mm,
                    angle_deg: angles.to_vec(),
                });
            }
        }
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::TargetStep;

    /// The segment statistics as a pass over the stored rows (the form the
    /// running [`SummaryBuilder`] replaced).
    fn segments_from_rows(s: &Scenario, trace: &Trace) -> Vec<Segment> {
        let end = s.duration_s;
        let mut out = Vec::new();
        let mut prev_target: Option<Vec<f64>> = None;
        for (i, t) in s.targets.iter().enumerate() {
            let from = t.t_s;
            let to = s.targets.get(i + 1).map(|n| n.t_s).unwrap_or(end).min(end);
            if to <= from {
                continue;
            }
            let rows: Vec<&Row> = trace
                .rows
                .iter()
                .filter(|r| r.t_s >= from && r.t_s < to)
                .collect();
            if rows.is_empty() {
                continue;
            }
            let tail_from = to - 0.2 * (to - from);
            let tail: Vec<&&Row> = rows.iter().filter(|r| r.t_s >= tail_from).collect();
            let planes = t.deg.len();
            let sse = (0..planes)
                .map(|p| {
                    let mean =
                        tail.iter().map(|r| r.true_deg[p]).sum::<f64>() / tail.len().max(1) as f64;
                    (mean - t.deg[p]).abs()
                })
                .collect();
            let overshoot = (0..planes)
                .map(|p| {
                    let start = prev_target
                        .as_ref()
                        .map(|v| v[p])
                        .unwrap_or(rows[0].true_deg[p]);
                    let dir = (t.deg[p] - start).signum();
                    if dir == 0.0 {
                        return 0.0;
                    }
                    rows.iter()
                        .map(|r| dir * (r.true_deg[p] - t.deg[p]))
                        .fold(0.0, f64::max)
                })
                .collect();
            out.push(Segment {
                from_s: from,
                to_s: to,
                desired_deg: t.deg.clone(),
                steady_state_error_deg: sse,
                overshoot_deg: overshoot,
            });
            prev_target = Some(t.deg.clone());
        }
        out
    }

    #[test]
    fn running_summary_equals_the_pass_over_the_rows() {
        let mut s = Scenario {
            duration_s: 6.0,
            ..Scenario::default()
        };
        s.estimator.method = EstimatorMethod::Paper;
        // Up, down (overshoot the other way), an empty segment past the end.
        s.targets = [(0.0, 0.0), (1.0, 6.0), (3.5, -4.0), (9.0, 1.0)]
            .map(|(t_s, d)| TargetStep {
                t_s,
                deg: vec![d, -d],
            })
            .to_vec();
        let kept = run(&s).unwrap();
        assert_eq!(kept.trace.rows.len(), 6000);
        let want = segments_from_rows(&s, &kept.trace);
        assert_eq!(want.len(), 3);
        assert_eq!(kept.summary.segments, want);
        assert_eq!(segments(&s, &kept.trace), want);
        let again = summarize(
            &s,
            &kept.trace,
            &["alpha", "beta"],
            1.0,
            "x".into(),
            0,
            vec![],
        );
        assert_eq!(again.segments, want);
        assert_eq!(
            again.max_estimation_error_deg,
            kept.summary.max_estimation_error_deg
        );
        // Without the trace: the same summary, no rows.
        let lean = run_with(&s, false).unwrap();
        assert!(lean.trace.rows.is_empty());
        let strip = |mut m: Summary| {
            m.wall_seconds = 0.0;
            m.realtime_factor = 0.0;
            m
        };
        assert_eq!(strip(lean.summary), strip(kept.summary));
    }
}
