//! The experiments of `softjoint rheology` as library calls: a push of
//! the lattice, scored against a measured push if there is one
//! ([`push_lattice`]); a push of the reference block recorded as a
//! measurement ([`push_reference`]); and a calibration from a measured
//! push with its check on a push it did not see ([`calibrate_push`]).
//! Each returns a report whose `Serialize` form is the command's `--json`
//! summary, field for field (a number that is not finite is `null` where
//! the summary allows it); files, pictures, progress bars and the command
//! line's words are the caller's.
//!
//! Left out: reading scenarios and measurements (the caller hands them
//! over, checked), and any bound that exists for the command line's sake.
use std::collections::BTreeMap;
use std::time::Instant;

use serde::{Serialize, Serializer};

use crate::error::Result;
use crate::identify::calibrate::{calibrate_with, Calibration, CalibrationSettings, Problem};
use crate::identify::measurement::Measurement;
use crate::identify::objective::{check_weights, score, Score};
use crate::identify::reference::{record_push, ReferenceConfig, ReferenceRun};
use crate::identify::search::{
    BatchObjective, Local, Method, Progress, SearchResult, UNIT_CANDIDATES,
};
use crate::model::lattice::Lattice;
use crate::model::params::{LatticeParams, ParamSet};
use crate::model::scenario::{lattice_sim, push_schedule_mm, run, Run, Scenario};

/// `v` when it is finite.
fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// A number that is `null` in a summary when it is not finite.
fn finite_or_null<S: Serializer>(v: &f64, s: S) -> core::result::Result<S::Ok, S::Error> {
    finite(*v).serialize(s)
}

/// An optional number that is `null` in a summary when it is not finite.
fn finite_opt_or_null<S: Serializer>(
    v: &Option<f64>,
    s: S,
) -> core::result::Result<S::Ok, S::Error> {
    v.and_then(finite).serialize(s)
}

/// Sorted, distinct times.
fn merge_times(a: &[f64], b: &[f64]) -> Vec<f64> {
    let mut t: Vec<f64> = a.iter().chain(b).copied().collect();
    t.sort_by(f64::total_cmp);
    t.dedup();
    t
}

/// S and its parts as a summary reports them (S `null` when the run was
/// unstable).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ScoreSummary {
    pub s: Option<f64>,
    pub shape_cm: f64,
    pub force_n: f64,
    pub points: usize,
    pub force_samples: usize,
    pub mean_distance_mm: f64,
    pub mean_force_error_n: f64,
}

impl From<Score> for ScoreSummary {
    fn from(s: Score) -> Self {
        Self {
            s: finite(s.s),
            shape_cm: s.shape_cm,
            force_n: s.force_n,
            points: s.points,
            force_samples: s.samples,
            mean_distance_mm: s.mean_distance_mm(),
            mean_force_error_n: s.mean_force_error_n(),
        }
    }
}

/// The lattice pushed as a scenario says; the `Serialize` form is the
/// summary of `softjoint rheology simulate --json`.
#[derive(Clone, Debug, Serialize)]
pub struct LatticePush {
    /// "lattice".
    pub model: &'static str,
    /// Masses per axis.
    pub grid: [usize; 3],
    pub masses: usize,
    pub elements: usize,
    pub volume_condition: &'static str,
    pub integrator: &'static str,
    pub dt_ms: f64,
    pub steps: usize,
    pub solver_iterations: usize,
    /// Wall-clock time of the run (s).
    pub wall_s: f64,
    /// Largest plate force (N; −∞ for a run without a step).
    #[serde(serialize_with = "finite_or_null")]
    pub peak_force_n: f64,
    /// Enclosed volume at the end over the rest volume.
    #[serde(serialize_with = "finite_opt_or_null")]
    pub final_volume_ratio: Option<f64>,
    /// Why the run stopped early, in words.
    pub instability: Option<String>,
    /// S against the measured push, when one was given.
    pub score: Option<ScoreSummary>,
    /// Enclosed volume over the rest volume per step.
    #[serde(skip)]
    pub volume_ratio: Vec<f64>,
    #[serde(skip)]
    pub run: Run,
    #[serde(skip)]
    pub lattice: Lattice,
}

/// Pushes the lattice as `scenario` says with frames at its frame times,
/// at `sections_s` and at the measured push's frames, and scores it
/// against `measured` if given (its frames must lie within the run).
pub fn push_lattice(
    scenario: &Scenario,
    measured: Option<&Measurement>,
    sections_s: &[f64],
) -> Result<LatticePush> {
    let lattice = scenario.lattice()?;
    let params = scenario.model.params.resolve()?;
    let mut frame_times = merge_times(&scenario.measure.frame_times_s, sections_s);
    if let Some(m) = measured {
        check_weights(&lattice, m, &scenario.objective)?;
        frame_times = merge_times(&frame_times, &m.frame_times_s());
    }
    let mut sim = lattice_sim(scenario, &lattice, &params)?;
    let started = Instant::now();
    let r = run(&mut sim, scenario.plate.end_s, &frame_times);
    let wall_s = started.elapsed().as_secs_f64();
    let score = measured
        .map(|m| {
            score(
                &lattice.surface,
                &r,
                m,
                &scenario.objective,
                scenario.measure.force_window_s,
            )
        })
        .transpose()?;
    let peak = r
        .plate_force_n
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let volume_ratio: Vec<f64> = r.volume_m3.iter().map(|v| v / r.volume0_m3).collect();
    Ok(LatticePush {
        model: "lattice",
        grid: lattice.nodes,
        masses: lattice.masses(),
        elements: lattice.elements.len(),
        volume_condition: scenario.model.volume.name(),
        integrator: scenario.model.integrator.name(),
        dt_ms: scenario.model.dt_ms,
        steps: r.t_s.len(),
        solver_iterations: r.iterations,
        wall_s,
        peak_force_n: peak,
        final_volume_ratio: volume_ratio.last().copied(),
        instability: r.instability.as_ref().map(|e| e.to_string()),
        score: score.map(ScoreSummary::from),
        volume_ratio,
        run: r,
        lattice,
    })
}

/// A frame of a measured push in a summary.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FrameSummary {
    pub time_s: f64,
    pub points: usize,
}

/// The reference block pushed and recorded; the `Serialize` form is the
/// summary of `softjoint rheology simulate --model reference --json`.
#[derive(Clone, Debug, Serialize)]
pub struct ReferencePush {
    /// "reference".
    pub model: &'static str,
    /// Cubes per axis.
    pub cells: [usize; 3],
    pub steps: usize,
    /// Largest measured plate force (N).
    pub peak_force_n: f64,
    /// Enclosed volume at the end over the rest volume.
    pub final_volume_ratio: Option<f64>,
    /// The measurement's frames.
    pub frames: Vec<FrameSummary>,
    /// The run, with node positions at the scenario's frame times and at
    /// the sections' (its measurement holds points at all of them).
    #[serde(skip)]
    pub run: ReferenceRun,
    /// The measurement at the scenario's frame times only.
    #[serde(skip)]
    pub measurement: Measurement,
    /// The plate's depth below the rest top per step (m).
    #[serde(skip)]
    pub depth_m: Vec<f64>,
    /// The measured plate force per step (N, with sensor noise).
    #[serde(skip)]
    pub force_n: Vec<f64>,
}

/// Pushes the reference block as `scenario` says (`cfg` its material and
/// mesh) and records the push at the scenario's frame times, keeping its
/// node positions at `sections_s` too.
pub fn push_reference(
    scenario: &Scenario,
    cfg: &ReferenceConfig,
    sections_s: &[f64],
) -> Result<ReferencePush> {
    let mut with_sections = scenario.clone();
    with_sections.measure.frame_times_s = merge_times(&scenario.measure.frame_times_s, sections_s);
    let r = record_push(&with_sections, cfg)?;
    // The measurement keeps only the scenario's frames.
    let mut m = r.measurement.clone();
    m.frames
        .retain(|f| scenario.measure.frame_times_s.contains(&f.t_s));
    let top = scenario.size_m()[1];
    let plate = scenario.plate()?;
    let depth_m: Vec<f64> = r
        .t_s
        .iter()
        .map(|&t| plate.face_y_m(t).map(|f| top - f).unwrap_or(0.0))
        .collect();
    let force_n: Vec<f64> = m.forces.iter().map(|f| f.force_n).collect();
    let peak = force_n.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    Ok(ReferencePush {
        model: "reference",
        cells: cfg.cells,
        steps: r.t_s.len(),
        peak_force_n: peak,
        final_volume_ratio: r.volume_m3.last().map(|v| v / r.volume0_m3),
        frames: m
            .frames
            .iter()
            .map(|f| FrameSummary {
                time_s: f.t_s,
                points: f.points_m.len(),
            })
            .collect(),
        run: r,
        measurement: m,
        depth_m,
        force_n,
    })
}

/// A push the calibration does not see: the scenario's plate pushed to
/// `depth_mm` over `push_s` (then held and released,
/// [`push_schedule_mm`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UnseenPush {
    pub depth_mm: f64,
    pub push_s: f64,
}

/// What to calibrate, against what, how, and what to check it on.
#[derive(Clone, Debug)]
pub struct CalibrationSpec {
    /// The lattice, model variant, rig and push.
    pub scenario: Scenario,
    /// The reference block that stands in for measurements.
    pub reference: ReferenceConfig,
    /// The measured push; without one the reference block is pushed as
    /// the scenario says and its recording is used.
    pub measured: Option<Measurement>,
    pub set: ParamSet,
    pub settings: CalibrationSettings,
    /// A push of the reference block to check the result on (only with a
    /// generated measurement).
    pub unseen: Option<UnseenPush>,
}

/// What [`calibrate_push`] tells its caller while it works.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event<'a> {
    /// A phase without a count begins (a push of the reference block).
    Phase(&'a str),
    /// The search finished a batch.
    Search(&'a Progress),
}

/// The check on a push the calibration did not see.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Validation {
    pub depth_mm: f64,
    pub push_s: f64,
    /// S of the default and of the calibrated parameters on it.
    pub default: ScoreSummary,
    pub calibrated: ScoreSummary,
}

/// A calibration, the default and calibrated lattices scored, and the
/// check on an unseen push; the `Serialize` form is the summary of
/// `softjoint rheology calibrate --json`.
#[derive(Clone, Debug, Serialize)]
pub struct CalibrationReport {
    pub method: Method,
    /// Parameters searched.
    pub params: usize,
    pub seed: u64,
    pub evaluations: usize,
    /// Candidates whose simulation was unstable.
    pub unstable: usize,
    pub stopped_by: &'static str,
    pub elapsed_s: f64,
    /// S of the scenario's parameters and of the calibrated ones.
    pub default: ScoreSummary,
    pub calibrated: ScoreSummary,
    pub best_params: LatticeParams,
    /// The best genes by parameter name.
    pub best_genes: BTreeMap<String, f64>,
    /// Best S so far after each generation (`null` while none was stable).
    pub best_s_per_generation: Vec<Option<f64>>,
    pub validation: Option<Validation>,
    /// The search's record.
    #[serde(skip)]
    pub search: SearchResult,
    /// The problem calibrated (its measurement and lattice).
    #[serde(skip)]
    pub problem: Problem,
    /// The lattice's runs with the scenario's and the calibrated
    /// parameters.
    #[serde(skip)]
    pub default_run: Run,
    #[serde(skip)]
    pub calibrated_run: Run,
}

/// Calibrates the lattice against the measured push (or a recording of
/// the reference block made on the spot) by the chosen search, scores the
/// scenario's and the calibrated parameters, and checks both on the
/// unseen push if asked.
pub fn calibrate_push(
    spec: &CalibrationSpec,
    on_event: &mut dyn FnMut(Event),
) -> Result<CalibrationReport> {
    let problem = calibration_problem(spec, on_event)?;
    let f = |g: &[f64]| problem.s_of_genes(g);
    let mut local = Local {
        f: &f,
        unit: UNIT_CANDIDATES,
    };
    calibrate_problem(spec, problem.clone(), &mut local, on_event)
}

/// The problem a calibration of `spec` solves: the scenario against its
/// measured push, or against a recording of the reference block made now
/// (seeded: the same recording wherever it is made).
pub fn calibration_problem(
    spec: &CalibrationSpec,
    on_event: &mut dyn FnMut(Event),
) -> Result<Problem> {
    let sc = &spec.scenario;
    let measurement = match &spec.measured {
        Some(m) => m.clone(),
        None => {
            on_event(Event::Phase(
                "pushing the reference block for the measurement…",
            ));
            record_push(sc, &spec.reference)?.measurement
        }
    };
    Problem::new(sc.clone(), spec.set, measurement)
}

/// [`calibrate_push`] on `problem` (from [`calibration_problem`]) with the
/// search's batches scored by `objective`.
pub fn calibrate_problem(
    spec: &CalibrationSpec,
    problem: Problem,
    objective: &mut dyn BatchObjective,
    on_event: &mut dyn FnMut(Event),
) -> Result<CalibrationReport> {
    let sc = &spec.scenario;
    let defaults = sc.model.params.resolve()?;
    let (default_score, default_run) = problem.score(&defaults)?;
    let Calibration {
        search,
        best_params,
    } = calibrate_with(&problem, &spec.settings, objective, &mut |p| {
        on_event(Event::Search(p))
    })?;
    let (best_score, calibrated_run) = problem.score(&best_params)?;
    let validation = match spec.unseen {
        None => None,
        Some(push) => {
            on_event(Event::Phase(
                "pushing the reference block for the validation push…",
            ));
            Some(check_unseen(spec, push, &defaults, &best_params)?)
        }
    };
    Ok(CalibrationReport {
        method: spec.settings.method,
        params: spec.set.len(),
        seed: spec.settings.seed,
        evaluations: search.evaluations,
        unstable: search.unstable,
        stopped_by: search.stopped_by,
        elapsed_s: search.elapsed_s,
        default: default_score.into(),
        calibrated: best_score.into(),
        best_params,
        best_genes: spec
            .set
            .ranges()
            .iter()
            .zip(&search.best_genes)
            .map(|(r, g)| (r.name.clone(), *g))
            .collect(),
        best_s_per_generation: search.history.iter().map(|h| finite(h.best_s)).collect(),
        validation,
        search,
        problem,
        default_run,
        calibrated_run,
    })
}

/// Scores the scenario's and the calibrated parameters on a push of the
/// reference block the calibration did not see (its own sensor noise).
fn check_unseen(
    spec: &CalibrationSpec,
    push: UnseenPush,
    defaults: &LatticeParams,
    calibrated: &LatticeParams,
) -> Result<Validation> {
    let mut unseen = spec.scenario.clone();
    unseen.plate.depth_mm = Some(push_schedule_mm(push.depth_mm, push.push_s));
    unseen.plate.force_n = None;
    let mut cfg = spec.reference.clone();
    cfg.seed = cfg.seed.wrapping_add(1);
    let measurement = record_push(&unseen, &cfg)?.measurement;
    let problem = Problem::new(unseen, spec.set, measurement)?;
    let (d, _) = problem.score(defaults)?;
    let (c, _) = problem.score(calibrated)?;
    Ok(Validation {
        depth_mm: push.depth_mm,
        push_s: push.push_s,
        default: d.into(),
        calibrated: c.into(),
    })
}
