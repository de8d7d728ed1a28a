//! Running a scenario: the firmware core in closed loop with the simulated
//! joint (through `hal-sim`), and the summary a user reads.

use std::time::Instant;

use anyhow::{bail, Context};
use firmware::control::PairGains;
use firmware::estimate::PlaneLaw;
use firmware::joint::{JointConfig, JointController};
use firmware::supervisor::Faults;
use hal_sim::{ClosedLoop, Controller, CoreController, FeedbackSource, LoopError, Plant, Schedule};
use plant_joint::{Joint2d, Joint2dParams, Joint3d, Joint3dParams};
use serde::Serialize;

use crate::files::calibration::CalibrationFile;
use crate::files::plant::PlantParams;
use crate::files::scenario::{
    ControlMode, EstimatorMethod, FeedbackKind, JointKind, Scenario, ScenarioSchedule,
};
use crate::files::sweep::SweepRow;
use crate::joint::calibrate;
use crate::run::trace::{NoRows, RowSink, TraceFileReport};
use crate::stop::{Stop, StopSignal};

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
    /// Whether the run reached the segment's end. For a segment it did
    /// not (a run cut short), `steady_state_error_deg` is the error at its
    /// last row when no row of its last 20 % ran, and the summary's
    /// worst-case figures leave it out.
    pub complete: bool,
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
    /// Control steps the scenario asked for (`steps` is fewer when the run
    /// was cut short).
    pub planned_steps: u64,
    /// Where and why the run ended early; absent when it ran to the end.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cut_short: Option<CutShort>,
    /// The streamed CSV trace, if one was written: its rows and whether
    /// they are the whole run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace: Option<TraceFileReport>,
}

/// Why a run ended before its last step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CutCause {
    /// The plant refused a step (instability, a load it cannot take).
    Plant,
    /// The controller failed: for `hil` the board, its link or its
    /// emulator.
    Controller,
    /// A trace file could not be written.
    Output,
    /// SIGINT or SIGTERM.
    Signal,
}

/// Where and why a run ended early.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CutShort {
    /// The step that did not complete (= steps completed; 0-based).
    pub at_step: u64,
    /// Its time (s).
    pub at_t_s: f64,
    /// What kind of reason.
    pub cause: CutCause,
    /// The reason, for a person.
    pub reason: String,
    /// The signal, when one stopped the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub signal: Option<StopSignal>,
}

impl std::fmt::Display for CutShort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "run cut short at step {} (t = {:.3} s): {}",
            self.at_step, self.at_t_s, self.reason
        )
    }
}

/// A run that ended early, as an error: the summary and trace are written
/// first; the program then exits with [`RunCutShort::exit_code`].
#[derive(Clone, Debug, thiserror::Error)]
#[error("{0}")]
pub struct RunCutShort(pub CutShort);

impl RunCutShort {
    /// 128 + the signal for a stop by signal (130 for SIGINT), else 1.
    pub fn exit_code(&self) -> u8 {
        self.0.signal.map_or(1, StopSignal::exit_code)
    }
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
    .and_then(|g| g.with_v_offset(s.controller.v_offset_v as f32))
    .map_err(|e| anyhow::anyhow!("controller gains: {e}"))
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
                EstimatorMethod::Single => {
                    calibrate::calibration_with(&fits, calibrate::Method::Single)?
                }
                EstimatorMethod::Differential => {
                    calibrate::calibration_with(&fits, calibrate::Method::Differential)?
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
        let tables = if laws.len() == 1 {
            "[alpha] only: a 2D calibration"
        } else {
            "[alpha] and [beta]: a 3D calibration"
        };
        bail!(
            "{source} has {} angle(s) ({tables}), but the scenario's `joint = \"{}\"` has {}",
            laws.len(),
            if s.planes() == 1 { "2d" } else { "3d" },
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

/// Runs a scenario to completion with the firmware core in process; the
/// time series is kept only with `keep_trace` (otherwise `trace.rows` is
/// empty). The summary is the same either way: it is accumulated row by row
/// ([`SummaryBuilder`]). A run that ends early is an error here
/// ([`RunCutShort`]); [`run_into`] returns its summary instead.
pub fn run_with(s: &Scenario, keep_trace: bool) -> anyhow::Result<RunOutput> {
    let mut rows = Vec::new();
    let summary = if keep_trace {
        run_into(
            s,
            &mut rows,
            &Stop::never(),
            &indicatif::ProgressBar::hidden(),
        )?
    } else {
        run_into(
            s,
            &mut NoRows,
            &Stop::never(),
            &indicatif::ProgressBar::hidden(),
        )?
    };
    if let Some(cut) = summary.cut_short {
        return Err(RunCutShort(cut).into());
    }
    Ok(RunOutput {
        trace: Trace {
            planes: s.planes(),
            rows,
        },
        summary,
    })
}

/// Runs a scenario with the firmware core in process, every row to `sink`,
/// until its end, a failure or `stop`. Errors are what prevents the run
/// from starting; a run that ends early returns its summary with
/// [`Summary::cut_short`] set.
pub fn run_into(
    s: &Scenario,
    sink: &mut impl RowSink,
    stop: &Stop,
    progress: &indicatif::ProgressBar,
) -> anyhow::Result<Summary> {
    s.validate()?;
    let (laws, estimator) = laws_for(s)?;
    let ctx = RunContext { stop, progress };
    match s.joint {
        JointKind::ThreeD => {
            let mut cl = core_loop_3d(s, laws.as_deref())?;
            Ok(run_scenario(
                s,
                &mut cl,
                sink,
                &ctx,
                estimator,
                &["alpha", "beta"],
            ))
        }
        JointKind::TwoD => {
            let mut cl = core_loop_2d(s, laws.as_deref())?;
            Ok(run_scenario(s, &mut cl, sink, &ctx, estimator, &["theta"]))
        }
    }
}

/// The 3D joint of scenario `s` under the firmware core in process, with
/// the scenario's gains, mode and estimation `laws` (the paper's if none).
pub fn core_loop_3d(
    s: &Scenario,
    laws: Option<&[PlaneLaw]>,
) -> anyhow::Result<ClosedLoop<Joint3d, CoreController<2, 4>, 2, 4, 4>> {
    let plant = plant_3d(s)?;
    let mut cfg = JointConfig::paper_3d();
    for p in 0..2 {
        cfg.gains[p] = gains(s, p)?;
    }
    if let Some(l) = laws {
        cfg.laws = [l[0], l[1]];
    }
    if s.controller.mode == ControlMode::Single {
        cfg.modes = [firmware::control::PairMode::SingleAgonist; 2];
    }
    let ctl = JointController::new(cfg).context("controller")?;
    let core = CoreController::new(
        ctl,
        feedback(s),
        s.control_period_us,
        plant.mm_per_count(),
        s.seed,
    );
    Ok(ClosedLoop::new(plant, core, s.control_period_us)?)
}

/// The 2D joint of scenario `s` under the firmware core in process (see
/// [`core_loop_3d`]).
pub fn core_loop_2d(
    s: &Scenario,
    laws: Option<&[PlaneLaw]>,
) -> anyhow::Result<ClosedLoop<Joint2d, CoreController<1, 1>, 1, 1, 2>> {
    let plant = plant_2d(s)?;
    let mut cfg = JointConfig::paper_2d_wire();
    cfg.gains[0] = gains(s, 0)?;
    if let Some(l) = laws {
        cfg.laws = [l[0]];
    }
    if s.controller.mode == ControlMode::Single {
        cfg.modes = [firmware::control::PairMode::SingleAgonist];
    }
    let ctl = JointController::new(cfg).context("controller")?;
    let core = CoreController::new(
        ctl,
        feedback(s),
        s.control_period_us,
        plant.mm_per_count(),
        s.seed,
    );
    Ok(ClosedLoop::new(plant, core, s.control_period_us)?)
}

/// Names of a scenario's angles, as the summary and the CSV call them.
pub fn angle_names(s: &Scenario) -> Vec<String> {
    let names: &[&str] = match s.joint {
        JointKind::ThreeD => &["alpha", "beta"],
        JointKind::TwoD => &["theta"],
    };
    names.iter().map(|n| n.to_string()).collect()
}

/// What a run reads besides its scenario: the stop flag and the progress
/// bar (hidden unless a person watches).
pub struct RunContext<'a> {
    /// Set by SIGINT/SIGTERM (or a caller).
    pub stop: &'a Stop,
    /// Advanced every few thousand steps.
    pub progress: &'a indicatif::ProgressBar,
}

/// Why [`ClosedLoop::run`] stopped before its last step.
enum Cut<E: std::error::Error + 'static> {
    Loop(LoopError<E>),
    Sink(anyhow::Error),
    Stop(StopSignal),
}

impl<E: std::error::Error + 'static> From<LoopError<E>> for Cut<E> {
    fn from(e: LoopError<E>) -> Self {
        Cut::Loop(e)
    }
}

/// Steps between progress-bar updates.
const PROGRESS_EVERY: u64 = 4096;

/// Runs scenario `s` through a closed loop — the firmware core in process,
/// or a board behind a link (`hil`): the one run of the joint. Targets and
/// disturbances come from the scenario ([`ScenarioSchedule`]); every period
/// gives one [`Row`] to the summary and to `sink`. The run ends at its last
/// step, or early when the loop fails (plant, controller), `sink` fails or
/// `ctx.stop` is set; the summary then says where and why
/// ([`Summary::cut_short`]), and `sink` holds every row up to there.
pub fn run_scenario<Pl, Ctl, const P: usize, const S: usize, const C: usize>(
    s: &Scenario,
    cl: &mut ClosedLoop<Pl, Ctl, P, S, C>,
    sink: &mut impl RowSink,
    ctx: &RunContext,
    estimator: String,
    names: &[&str],
) -> Summary
where
    Pl: Plant<P, S, C>,
    Ctl: Controller<P, S>,
{
    let steps = s.steps();
    let mut stats = SummaryBuilder::new(s, P);
    let mut faults_seen = 0u16;
    let mut peak_temp = [f64::NEG_INFINITY; C];
    let mut schedule = ScenarioSchedule::new(s);
    ctx.progress.set_length(steps);
    let started = Instant::now();
    let result = cl.run(
        steps,
        &mut schedule,
        |sample| -> Result<(), Cut<Ctl::Error>> {
            faults_seen |= sample.faults;
            for (p, c) in peak_temp.iter_mut().zip(sample.coil_temperatures_c) {
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
            sink.row(&row).map_err(Cut::Sink)?;
            let done = stats.rows;
            if done % PROGRESS_EVERY == 0 {
                ctx.progress.set_position(done);
            }
            match ctx.stop.requested() {
                Some(signal) if done < steps => Err(Cut::Stop(signal)),
                _ => Ok(()),
            }
        },
    );
    let wall = started.elapsed().as_secs_f64();
    ctx.progress.set_position(stats.rows);
    let at_step = stats.rows;
    let at_t_s = at_step as f64 * s.period_s();
    let cut_short = result.err().map(|cut| {
        let (cause, reason, signal) = match cut {
            Cut::Loop(LoopError::Plant { error, .. }) => {
                (CutCause::Plant, format!("plant: {error}"), None)
            }
            Cut::Loop(LoopError::Controller { error, .. }) => {
                (CutCause::Controller, format!("controller: {error}"), None)
            }
            Cut::Loop(e @ LoopError::Period(_)) => (CutCause::Controller, e.to_string(), None),
            Cut::Sink(e) => (CutCause::Output, format!("{e:#}"), None),
            Cut::Stop(sig) => (
                CutCause::Signal,
                format!("stopped by {}", sig.name()),
                Some(sig),
            ),
        };
        CutShort {
            at_step,
            at_t_s,
            cause,
            reason,
            signal,
        }
    });
    // A run cut short before its first row has no peak temperature (the
    // −∞ it starts from is no number a summary may carry).
    let peaks = if stats.rows == 0 {
        Vec::new()
    } else {
        peak_temp.to_vec()
    };
    let mut summary = stats.finish(s, names, wall, estimator, faults_seen, peaks);
    summary.cut_short = cut_short;
    summary
}

/// The 3D plant of a scenario.
pub fn plant_3d(s: &Scenario) -> anyhow::Result<Joint3d> {
    let mut params = params_3d(s);
    params.sim.seed = s.seed;
    if s.plant.rigid_bearing {
        params.alpha = params.alpha.rigid_bearing();
        params.beta = params.beta.rigid_bearing();
    }
    Joint3d::new(params).context("building the 3D plant")
}

/// The 2D plant of a scenario.
pub fn plant_2d(s: &Scenario) -> anyhow::Result<Joint2d> {
    let mut params = params_2d(s);
    params.sim.seed = s.seed;
    if s.plant.rigid_bearing {
        params = params.rigid_bearing();
    }
    Joint2d::new(params).context("building the 2D plant")
}

/// The scenario's 3D parameters: its plant file's, or the defaults.
pub fn params_3d(s: &Scenario) -> Joint3dParams {
    match &s.plant.params {
        Some(PlantParams::ThreeD(p)) => p.clone(),
        _ => Joint3dParams::default(),
    }
}

/// The scenario's 2D parameters: its plant file's, or the defaults.
pub fn params_2d(s: &Scenario) -> Joint2dParams {
    match &s.plant.params {
        Some(PlantParams::TwoD(p)) => p.clone(),
        _ => Joint2dParams::default(),
    }
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
    last_true_deg: [f64; 2],
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
    /// Time of the last row (s); −∞ before the first.
    last_t_s: f64,
    /// Control period (s).
    period_s: f64,
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
                    last_true_deg: [0.0; 2],
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
            last_t_s: f64::NEG_INFINITY,
            period_s: s.period_s(),
        }
    }

    /// Adds one control period's row; rows come in time order.
    #[inline]
    pub fn push(&mut self, r: &Row) {
        self.rows += 1;
        self.last_t_s = r.t_s;
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
            g.last_true_deg = r.true_deg;
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
            // Rows of a segment: those with from ≤ t < to, one per period.
            let complete = self.last_t_s + self.period_s >= g.to_s - 1e-9;
            let sse = (0..planes)
                .map(|p| {
                    let at = if g.tail_rows == 0 && !complete {
                        g.last_true_deg[p]
                    } else {
                        g.tail_sum_deg[p] / g.tail_rows.max(1) as f64
                    };
                    (at - g.desired_deg[p]).abs()
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
                complete,
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
                    .filter(|g| g.complete)
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
            // (No wall time means no step ran: 0, not ∞, which no result
            // may carry.)
            realtime_factor: if wall_seconds > 0.0 {
                sim_seconds / wall_seconds
            } else {
                0.0
            },
            steps: self.rows,
            faults_seen: fault_names(faults_seen),
            estimator,
            peak_coil_temperature_c,
            planned_steps: s.steps(),
            cut_short: None,
            trace: None,
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
    let period_us = 1000u32;
    let steps = (SweepTriangle::DURATION_S / (f64::from(period_us) * 1e-6)).round() as u64;
    let seed = s.seed ^ 0xCA1B;
    match s.joint {
        JointKind::ThreeD => {
            let mut params = params_3d(s);
            params.sim.seed = seed;
            let plant = Joint3d::new(params)?;
            let ctl = JointController::new(JointConfig::paper_3d()).context("controller")?;
            let core = CoreController::new(
                ctl,
                FeedbackSource::Wire,
                period_us,
                plant.mm_per_count(),
                s.seed,
            );
            sweep_rows(ClosedLoop::new(plant, core, period_us)?, steps)
        }
        JointKind::TwoD => {
            let mut params = params_2d(s);
            params.sim.seed = seed;
            let plant = Joint2d::new(params)?;
            let ctl = JointController::new(JointConfig::paper_2d_wire()).context("controller")?;
            let core = CoreController::new(
                ctl,
                FeedbackSource::Wire,
                period_us,
                plant.mm_per_count(),
                s.seed,
            );
            sweep_rows(ClosedLoop::new(plant, core, period_us)?, steps)
        }
    }
}

/// The sweep's targets: every plane follows 0 → +20° → −20° → 0 at 1°/s.
struct SweepTriangle;

impl SweepTriangle {
    const AMPLITUDE_DEG: f64 = 20.0;
    const RATE_DEG_S: f64 = 1.0;
    const QUARTER_S: f64 = Self::AMPLITUDE_DEG / Self::RATE_DEG_S;
    const DURATION_S: f64 = 4.0 * Self::QUARTER_S;

    fn at(t: f64) -> f64 {
        let (a, r, q) = (Self::AMPLITUDE_DEG, Self::RATE_DEG_S, Self::QUARTER_S);
        if t < q {
            t * r
        } else if t < 3.0 * q {
            a - (t - q) * r
        } else {
            -a + (t - 3.0 * q) * r
        }
    }
}

impl<Pl, const P: usize, const C: usize> Schedule<Pl, P, C> for SweepTriangle {
    fn targets(&mut self, t_s: f64) -> Option<[f32; P]> {
        Some([Self::at(t_s) as f32; P])
    }
    fn disturb(
        &mut self,
        _t_s: f64,
        _plant: &mut Pl,
        _overrides: &mut [Option<f64>; C],
    ) -> Result<(), plant_joint::PlantError> {
        Ok(())
    }
}

/// Runs a calibration sweep: each camera frame the controller is given
/// while its step reports no fault yields one row, with the wire
/// insertions read at the same instant. With wire feedback nothing else
/// consumes camera frames, so each is seen once. The camera's one-frame
/// latency makes each angle ~33 ms older than the insertions beside it: at
/// 1°/s that is 0.03°, well under the estimation errors being calibrated.
fn sweep_rows<Pl, const P: usize, const S: usize, const C: usize>(
    mut cl: ClosedLoop<Pl, CoreController<P, S>, P, S, C>,
    steps: u64,
) -> anyhow::Result<Vec<SweepRow>>
where
    Pl: Plant<P, S, C>,
{
    let mut rows = Vec::new();
    let res = cl.plant.mm_per_count();
    cl.run(steps, &mut SweepTriangle, |sample| -> anyhow::Result<()> {
        if let Some(angles) = sample.readings.camera {
            if sample.faults == 0 {
                rows.push(SweepRow {
                    d_mm: sample
                        .readings
                        .counts
                        .iter()
                        .zip(res)
                        .map(|(c, r)| *c as f64 * r)
                        .collect(),
                    angle_deg: angles.to_vec(),
                });
            }
        }
        Ok(())
    })?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::scenario::TargetStep;

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
                complete: true,
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
