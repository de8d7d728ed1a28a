//! The three experiments of `softjoint push` as library calls: run the
//! model on one push and score it every way ([`run_model`], then
//! [`assess`]), learn its parameters from a training push ([`calibrate`],
//! Algorithm 5) and decide which calibrated material explains a push best
//! ([`classify`], §VIII-E). Each takes a prepared push and its settings
//! and returns a report whose `Serialize` form is the command's `--json`
//! summary (field for field); files, pictures, progress bars and the
//! command line's words are the caller's.
//!
//! Besides the seed's pixel F-score every experiment measures the contour
//! distance in the finger's reach ([`contour_score`](crate::contour_score))
//! against the tracked contour of the push ([`Tracking`]), and the
//! undeformed block's scores as the baseline a model must beat.
//!
//! Left out: reading and recording pushes (the caller hands over a
//! [`PreparedVideo`]), and any bound that exists for the command line's
//! sake (how many generations a person may ask for).
use serde::Serialize;

use crate::classify::{self as material, MaterialModel, Tally};
use crate::contour_score::{
    classify_by_contour, score_contour_run, skill, still_block_contour_score, still_config,
    track_video, ContourScore, ContourTarget, ReachZone, TrackingOptions,
};
use crate::error::{PushError, Result};
use crate::evaluate::{score_run, score_run_observed, simulate_frames, PreparedVideo};
use crate::evolution::{self, CalibrationResult, EvolutionSettings, GenerationReport};
use crate::force_regression::{ForcePredictor, DEFAULT_ERROR_THRESHOLD};
use crate::forces::MaterialParams;
use crate::sim::SimConfig;
use crate::V2;

/// Spacing of the resampled contours the contour distance compares, px.
pub const CONTOUR_SPACING_PX: f64 = 2.0;

/// Frames kept as snapshots: start, mid-push, deepest, mid-retrieval, end.
pub const SNAPSHOT_FRAMES: [usize; 5] = [0, 25, 50, 75, 99];

/// Mesh positions at the snapshot frames, with their frame index.
pub type Snapshots = Vec<(usize, Vec<V2>)>;

/// Whether frame `f` of `n` is one of the [`SNAPSHOT_FRAMES`] (the last
/// frame stands in for those beyond a short push).
pub fn is_snapshot_frame(f: usize, n: usize) -> bool {
    SNAPSHOT_FRAMES.iter().any(|&s| s.min(n - 1) == f)
}

/// The per-frame score a calibration maximises or a classification
/// decides by.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ScoreKind {
    /// Pixel F-score over the whole block, μ(F) (the seed's, Eq. 16–19).
    F,
    /// Mean distance (px) between the model's outline and the tracked
    /// contour within the finger's reach.
    Contour,
}

impl ScoreKind {
    /// The name on the command line and in summaries.
    pub fn name(self) -> &'static str {
        match self {
            ScoreKind::F => "f",
            ScoreKind::Contour => "contour",
        }
    }

    /// A fitness of the search in the score's own terms: μ(F) as it is,
    /// the contour distance in px (the search maximised its negative).
    pub fn in_own_terms(self, fitness: f64) -> f64 {
        let sign = if self == ScoreKind::Contour {
            -1.0
        } else {
            1.0
        };
        sign * fitness
    }
}

/// The tracked contour of a push as splines, its reach zone, and (once a
/// model was run) the model's and the undeformed block's contour
/// distances.
#[derive(Debug, Clone)]
pub struct Tracking {
    /// Each frame's spline resampled densely (closed polygon), px.
    pub contours_px: Vec<Vec<V2>>,
    pub zone: ReachZone,
    pub target: ContourTarget,
    /// The model's distances, when a model was run.
    pub model: Option<ContourScore>,
    /// The undeformed block's distances.
    pub still: ContourScore,
}

impl Tracking {
    /// Tracks the push's contours and scores the undeformed block.
    pub fn of(prep: &PreparedVideo) -> Result<Self> {
        let tracked = track_video(&prep.video, &TrackingOptions::default())?;
        let zone = ReachZone::default_of(&prep.video.scenario)?;
        let target = ContourTarget::new(&tracked, zone, CONTOUR_SPACING_PX)?;
        let still = still_block_contour_score(prep, &target);
        Ok(Self {
            contours_px: tracked.contours_px,
            zone,
            target,
            model: None,
            still,
        })
    }

    /// The model's mean contour distance at frame `f` (NaN before a run).
    pub fn model_mean_px(&self, f: usize) -> f64 {
        self.model
            .as_ref()
            .and_then(|m| m.mean_px_per_frame.get(f).copied())
            .unwrap_or(f64::NAN)
    }
}

/// How to run the model on one push.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulateSpec {
    pub params: MaterialParams,
    pub sim: SimConfig,
    /// Drive the model with the force predictor (§V) learned on the push
    /// instead of the sensed forces.
    pub predicted_forces: bool,
}

/// The model's run on a push, scored by F: what drove it, its scores and
/// its snapshot positions.
#[derive(Debug, Clone)]
pub struct ModelRun {
    /// The force per frame that drove the model, N.
    pub forces_n: Vec<f64>,
    pub score: crate::evaluate::RunScore,
    pub snapshots: Snapshots,
    /// Where and why the run became unstable, in words.
    pub instability: Option<String>,
}

/// Runs the model through the push, scoring each frame by F and keeping
/// the snapshot positions in the same pass; `on_frame` hears how many
/// frames are done after each.
pub fn run_model(
    prep: &PreparedVideo,
    spec: &SimulateSpec,
    on_frame: &mut dyn FnMut(usize),
) -> Result<ModelRun> {
    let forces_n = if spec.predicted_forces {
        ForcePredictor::fit(
            &prep.video.scenario,
            &prep.video.forces_n,
            DEFAULT_ERROR_THRESHOLD,
        )?
        .predict_series(&prep.video.scenario)
    } else {
        prep.video.forces_n.clone()
    };
    let n = prep.frame_count();
    let mut snapshots = Vec::new();
    let score = score_run_observed(prep, &forces_n, &spec.params, &spec.sim, |f, pos| {
        if is_snapshot_frame(f, n) {
            snapshots.push((f, pos.to_vec()));
        }
        on_frame(f + 1);
    })?;
    let instability = score.unstable_from_frame.map(|f| {
        let why = score
            .instability
            .map(|i| i.to_string())
            .unwrap_or_else(|| "unknown cause".into());
        format!(
            "the mass-spring model ({} integrator) became unstable at frame {f} of {n} ({why})",
            spec.sim.integrator.name(),
        )
    });
    Ok(ModelRun {
        forces_n,
        score,
        snapshots,
        instability,
    })
}

/// One push simulated and scored every way; the `Serialize` form is the
/// summary of `softjoint push simulate --json`.
#[derive(Debug, Clone, Serialize)]
pub struct SimulateReport {
    pub material: String,
    pub site: &'static str,
    pub integrator: &'static str,
    pub mode: &'static str,
    pub params: MaterialParams,
    /// μ(F) of the model, and of the undeformed block.
    pub mean_f: f64,
    pub still_mean_f: f64,
    /// The model's contour distance in the finger's reach: mean over
    /// frames of the per-frame mean and largest distance, and the largest
    /// of any frame, px.
    pub contour_mean_px: f64,
    pub contour_max_px: f64,
    pub contour_worst_px: f64,
    /// The undeformed block's, px.
    pub still_contour_mean_px: f64,
    pub still_contour_max_px: f64,
    /// The fraction of the undeformed block's contour mismatch the model
    /// removes.
    pub contour_skill: f64,
    pub contour_mean_px_per_frame: Vec<f64>,
    pub unstable_from_frame: Option<usize>,
    pub instability: Option<String>,
    pub f_per_frame: Vec<f64>,
    /// The force per frame that drove the model, N.
    #[serde(skip)]
    pub forces_n: Vec<f64>,
    #[serde(skip)]
    pub snapshots: Snapshots,
    #[serde(skip)]
    pub contour: ContourScore,
    /// The tracked contour, with the model's distances.
    #[serde(skip)]
    pub tracking: Tracking,
}

/// Scores a run of the model against the tracked contour and the
/// undeformed block.
pub fn assess(prep: &PreparedVideo, spec: &SimulateSpec, run: ModelRun) -> Result<SimulateReport> {
    let still_f = score_run(
        prep,
        &vec![0.0; prep.frame_count()],
        &spec.params,
        &still_config(&spec.sim),
    )?
    .mean_f;
    let mut tracking = Tracking::of(prep)?;
    let contour = score_contour_run(
        prep,
        &tracking.target,
        &run.forces_n,
        &spec.params,
        &spec.sim,
    )?;
    let contour_skill = skill(contour.mean_px, tracking.still.mean_px);
    tracking.model = Some(contour.clone());
    Ok(SimulateReport {
        material: prep.video.material.clone(),
        site: prep.video.scenario.site.name(),
        integrator: spec.sim.integrator.name(),
        mode: spec.sim.mode.name(),
        params: spec.params,
        mean_f: run.score.mean_f,
        still_mean_f: still_f,
        contour_mean_px: contour.mean_px,
        contour_max_px: contour.max_px,
        contour_worst_px: contour.worst_px,
        still_contour_mean_px: tracking.still.mean_px,
        still_contour_max_px: tracking.still.max_px,
        contour_skill,
        contour_mean_px_per_frame: contour.mean_px_per_frame.clone(),
        unstable_from_frame: run.score.unstable_from_frame,
        instability: run.instability,
        f_per_frame: run.score.f_per_frame,
        forces_n: run.forces_n,
        snapshots: run.snapshots,
        contour,
        tracking,
    })
}

/// Mesh positions of the model at the snapshot frames.
pub fn snapshot_positions(
    prep: &PreparedVideo,
    forces_n: &[f64],
    params: &MaterialParams,
    sim: &SimConfig,
) -> Result<Snapshots> {
    let n = prep.frame_count();
    let mut out = Vec::new();
    simulate_frames(
        &prep.mesh,
        &prep.video.scenario,
        forces_n,
        params,
        sim,
        |f, pos, _| {
            if is_snapshot_frame(f, n) {
                out.push((f, pos.to_vec()));
            }
        },
    )?;
    Ok(out)
}

/// The fitness Algorithm 5 maximises for parameters `p` on the push's
/// sensed forces: μ(F) (`ScoreKind::F`), or minus the mean contour
/// distance in the finger's reach against `target` (px); NaN when the
/// run could not be scored (the search counts it failed).
pub fn fitness(
    prep: &PreparedVideo,
    target: &ContourTarget,
    score: ScoreKind,
    sim: &SimConfig,
    p: &MaterialParams,
) -> f64 {
    let forces = &prep.video.forces_n;
    match score {
        ScoreKind::F => score_run(prep, forces, p, sim)
            .map(|s| s.mean_f)
            .unwrap_or(f64::NAN),
        ScoreKind::Contour => score_contour_run(prep, target, forces, p, sim)
            .map(|s| -s.mean_px)
            .unwrap_or(f64::NAN),
    }
}

/// How to calibrate: Table III's search with `generations` and `seed`,
/// maximising `score`, the model run as `sim` says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrateSpec {
    pub generations: usize,
    pub seed: u64,
    pub score: ScoreKind,
    pub sim: SimConfig,
}

/// A calibration and its best model scored every way; the `Serialize`
/// form is the summary of `softjoint push calibrate --json`.
#[derive(Debug, Clone, Serialize)]
pub struct CalibrateReport {
    pub material: String,
    pub site: &'static str,
    pub integrator: &'static str,
    pub mode: &'static str,
    pub score: ScoreKind,
    pub best_params: MaterialParams,
    /// μ(F) of the best model, and of the undeformed block.
    pub best_mean_f: f64,
    pub still_mean_f: f64,
    /// The best model's contour distance (mean and largest per frame,
    /// averaged over frames), and the undeformed block's mean, px.
    pub best_contour_mean_px: f64,
    pub best_contour_max_px: f64,
    pub still_contour_mean_px: f64,
    pub contour_skill: f64,
    /// Simulations run.
    pub evaluations: usize,
    /// Each generation's best, in the score's own terms
    /// ([`ScoreKind::in_own_terms`]).
    pub best_per_generation: Vec<f64>,
    /// The search's outcome (`params.json`).
    #[serde(skip)]
    pub result: CalibrationResult,
    /// The best model's F per frame.
    #[serde(skip)]
    pub f_per_frame: Vec<f64>,
    #[serde(skip)]
    pub snapshots: Snapshots,
    /// The tracked contour, with the best model's distances.
    #[serde(skip)]
    pub tracking: Tracking,
}

/// Runs Algorithm 5 on the push, maximising μ(F) or minus the contour
/// distance in the finger's reach; `on_generation` hears each generation.
pub fn calibrate(
    prep: &PreparedVideo,
    spec: &CalibrateSpec,
    on_generation: &mut dyn FnMut(&GenerationReport),
) -> Result<CalibrateReport> {
    let report = calibrate_until(prep, spec, &|p, run| Some(run(p)), on_generation)?;
    report.ok_or(PushError::InvalidParameter {
        name: "generations",
        value: 0.0,
        reason: "the search stopped without being asked to",
    })
}

/// A fitness as the caller wraps it: given a candidate and the fitness
/// that simulates it, its score, or `None` to stop the search (a caller
/// may take a score kept from a stopped search instead of simulating).
pub type FitnessLayer<'a> =
    dyn Fn(&MaterialParams, &dyn Fn(&MaterialParams) -> f64) -> Option<f64> + Sync + 'a;

/// [`calibrate`] with each candidate scored through `layer`: `Ok(None)`
/// when it stopped the search (nothing after the search is run).
pub fn calibrate_until(
    prep: &PreparedVideo,
    spec: &CalibrateSpec,
    layer: &FitnessLayer,
    on_generation: &mut dyn FnMut(&GenerationReport),
) -> Result<Option<CalibrateReport>> {
    let tracking = Tracking::of(prep)?;
    let settings = settings_of(spec);
    let fitness = |p: &MaterialParams| fitness(prep, &tracking.target, spec.score, &spec.sim, p);
    let found = evolution::calibrate_until(
        &settings,
        &evolution::TABLE_III_RANGES,
        |p| layer(p, &fitness),
        |g| on_generation(g),
    )?;
    match found {
        Some(result) => Ok(Some(assess_calibration(prep, spec, tracking, result)?)),
        None => Ok(None),
    }
}

/// A generation's candidates not scored yet, as gene vectors in the order
/// of [`MaterialParams::to_array`], scored elsewhere (a Ray cluster):
/// their fitness ([`fitness`] on the push's [`Tracking::of`]) in the same
/// order, or `None` to stop the search.
pub type BatchScorer<'a> = dyn FnMut(&[Vec<f64>]) -> Option<Vec<f64>> + 'a;

/// [`calibrate_until`] with each generation's new candidates scored at
/// once by `batch` ([`evolution::calibrate_batches`]): the same search,
/// draws and report for the same scores, wherever `batch` runs them.
pub fn calibrate_batches(
    prep: &PreparedVideo,
    spec: &CalibrateSpec,
    batch: &mut BatchScorer,
    on_generation: &mut dyn FnMut(&GenerationReport),
) -> Result<Option<CalibrateReport>> {
    let tracking = Tracking::of(prep)?;
    let found = evolution::calibrate_batches(
        &settings_of(spec),
        &evolution::TABLE_III_RANGES,
        |genes| batch(genes),
        |g| on_generation(g),
    )?;
    match found {
        Some(result) => Ok(Some(assess_calibration(prep, spec, tracking, result)?)),
        None => Ok(None),
    }
}

/// Table III's settings with `spec`'s generations and seed.
fn settings_of(spec: &CalibrateSpec) -> EvolutionSettings {
    let mut settings = EvolutionSettings::table_iii(spec.seed);
    settings.generations = spec.generations;
    settings
}

/// The report of a finished search: its best candidate run through the
/// push and scored.
fn assess_calibration(
    prep: &PreparedVideo,
    spec: &CalibrateSpec,
    mut tracking: Tracking,
    result: CalibrationResult,
) -> Result<CalibrateReport> {
    let forces = &prep.video.forces_n;
    let best = &result.best_params;
    let score = score_run(prep, forces, best, &spec.sim)?;
    let contour = score_contour_run(prep, &tracking.target, forces, best, &spec.sim)?;
    let still_f = score_run(
        prep,
        &vec![0.0; prep.frame_count()],
        best,
        &still_config(&spec.sim),
    )?
    .mean_f;
    let contour_skill = skill(contour.mean_px, tracking.still.mean_px);
    let snapshots = snapshot_positions(prep, forces, best, &spec.sim)?;
    let report = CalibrateReport {
        material: prep.video.material.clone(),
        site: prep.video.scenario.site.name(),
        integrator: spec.sim.integrator.name(),
        mode: spec.sim.mode.name(),
        score: spec.score,
        best_params: result.best_params,
        best_mean_f: score.mean_f,
        still_mean_f: still_f,
        best_contour_mean_px: contour.mean_px,
        best_contour_max_px: contour.max_px,
        still_contour_mean_px: tracking.still.mean_px,
        contour_skill,
        evaluations: result.evaluations,
        best_per_generation: result
            .history
            .iter()
            .map(|g| spec.score.in_own_terms(g.best))
            .collect(),
        f_per_frame: score.f_per_frame,
        snapshots,
        result,
        tracking: {
            tracking.model = Some(contour);
            tracking
        },
    };
    Ok(report)
}

/// Which material model explains a push best; the `Serialize` form is
/// the summary of `softjoint push classify --json`.
#[derive(Debug, Clone, Serialize)]
pub struct ClassifyReport {
    pub video_material: String,
    pub site: &'static str,
    pub score: ScoreKind,
    /// The global winner's label; none on a tie.
    pub winner: Option<String>,
    pub tie: bool,
    /// The labels whose votes tie for first place (the winner alone when
    /// there is one).
    pub leaders: Vec<String>,
    pub labels: Vec<String>,
    pub frames_won: Vec<usize>,
    pub vote: Vec<f64>,
    /// Each model's value per frame (outer: model): F, or the mean
    /// contour distance in px.
    #[serde(skip)]
    pub per_frame: Vec<Vec<f64>>,
    /// Each frame's winner (index into `labels`); none on a tie.
    #[serde(skip)]
    pub frame_winner: Vec<Option<usize>>,
}

impl ClassifyReport {
    /// The verdict in words: the winner's label, or `tie between a and b`.
    pub fn verdict(&self) -> String {
        match &self.winner {
            Some(label) => label.clone(),
            None => format!("tie between {}", self.leaders.join(" and ")),
        }
    }
}

/// Classifies the push among `models` (at least two) by `score`, each
/// model driven by the sensed forces.
pub fn classify(
    prep: &PreparedVideo,
    models: &[MaterialModel],
    score: ScoreKind,
    sim: &SimConfig,
) -> Result<ClassifyReport> {
    let forces = &prep.video.forces_n;
    let (per_frame, tally, labels) = match score {
        ScoreKind::F => {
            let c = material::classify(prep, forces, models, sim)?;
            let tally = Tally {
                frame_winner: c.frame_winner,
                frames_won: c.frames_won,
                vote: c.vote,
                winner: c.winner,
                leaders: c.leaders,
            };
            (c.f_per_frame, tally, c.labels)
        }
        ScoreKind::Contour => {
            let tracking = Tracking::of(prep)?;
            let c = classify_by_contour(prep, &tracking.target, forces, models, sim)?;
            (c.mean_px_per_frame, c.tally, c.labels)
        }
    };
    let winner = tally.winner.map(|k| labels[k].clone());
    Ok(ClassifyReport {
        video_material: prep.video.material.clone(),
        site: prep.video.scenario.site.name(),
        score,
        tie: winner.is_none(),
        winner,
        leaders: tally.leaders.iter().map(|&k| labels[k].clone()).collect(),
        frames_won: tally.frames_won,
        vote: tally.vote,
        per_frame,
        frame_winner: tally.frame_winner,
        labels,
    })
}
