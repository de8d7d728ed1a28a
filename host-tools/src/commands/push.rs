//! `softjoint push`: deformable blocks under robotic pushing (seed 001).
//!
//! * `simulate` — record a push of the ground-truth block (or read one from
//!   CSV), run the mass-spring model on it and score every frame;
//! * `calibrate` — Algorithm 5 on a training push, with a progress bar;
//!   stopped by a signal it keeps its best and its scores so far, and
//!   `--resume` goes on from them (host_tools::resume);
//! * `classify` — which of several calibrated models predicts a push best.
//!
//! Every command writes CSV and SVG pictures into `--out` and prints either
//! a short text report or, with `--json`, a machine-readable summary.
use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use host_tools::output::{self, JsonObject};
use host_tools::plot::{self, Anchor, Chart, Series, Stroke, Svg};
use host_tools::push::Material;
use host_tools::push::{self, ModelGrid, PushSource};
use host_tools::resume::{best_of, fnv1a_hex, Scored, Scores};
use host_tools::stop::{Stop, StopSignal, Stopped};
use host_tools::{outln, progress};
use plant_pushing::classify::MaterialModel;
use plant_pushing::contour_score::ReachZone;
use plant_pushing::evaluate::PreparedVideo;
use plant_pushing::experiment::{
    self, CalibrateReport, CalibrateSpec, ClassifyReport, ScoreKind, SimulateReport, SimulateSpec,
    Tracking,
};
use plant_pushing::forces::MaterialParams;
use plant_pushing::scenario::PushSite;
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};
use plant_pushing::video_csv::write_video_csv;
use plant_pushing::V2;
use serde::{Deserialize, Serialize};

#[derive(Args)]
pub struct PushArgs {
    #[command(subcommand)]
    command: PushCommand,
}

#[derive(Subcommand)]
enum PushCommand {
    /// Run the mass-spring model on one push and score it frame by frame.
    Simulate(SimulateArgs),
    /// Learn the model's parameters from a training push (Algorithm 5).
    ///
    /// Ctrl-C, SIGTERM or SIGHUP stops the search between simulations
    /// (exit 130, 143, 129): no result file is written, but the best
    /// candidate so far and every candidate simulated are kept in
    /// OUT/params.search.toml, from which --resume goes on to the result
    /// of the search never stopped.
    Calibrate(CalibrateArgs),
    /// Decide which calibrated material model explains a push best.
    Classify(ClassifyArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum MaterialArg {
    Sponge,
    Plasticine,
}

impl From<MaterialArg> for Material {
    fn from(m: MaterialArg) -> Self {
        match m {
            MaterialArg::Sponge => Material::Sponge,
            MaterialArg::Plasticine => Material::Plasticine,
        }
    }
}

impl MaterialArg {
    fn label(self) -> &'static str {
        Material::from(self).label()
    }
    fn seed_params(self) -> MaterialParams {
        Material::from(self).seed_params()
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum SiteArg {
    /// Middle of the long side (the seed's training push).
    MiddleLong,
    /// Near the corner of the long side.
    Corner,
    /// Middle of the short side.
    MiddleShort,
}

impl From<SiteArg> for PushSite {
    fn from(s: SiteArg) -> Self {
        match s {
            SiteArg::MiddleLong => PushSite::MiddleLongSide,
            SiteArg::Corner => PushSite::NearCorner,
            SiteArg::MiddleShort => PushSite::MiddleShortSide,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum IntegratorArg {
    /// The seed's first-order scheme, Eq. 15 as printed (all forces at p(t)).
    Customised,
    /// Explicit Euler on Newton's law.
    Euler,
    /// Position Verlet on Newton's law.
    Verlet,
    /// Eq. 15 spring by spring (Gauss–Seidel); the seed's Fig. 14
    /// parameters are stable only under this one.
    CustomisedSeq,
}

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    /// Finger as an obstacle only.
    Collision,
    /// Sensed forces on the vertices under the finger only.
    Forces,
    /// Both (the default, as in the seed's calibration).
    Both,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum ScoreArg {
    /// Pixel F-score over the whole block, μ(F) (the seed's, Eq. 16–19).
    F,
    /// Mean distance (px) between the model's outline and the tracked
    /// contour (a periodic smoothing spline) within the finger's reach.
    Contour,
}

impl From<ScoreArg> for ScoreKind {
    fn from(s: ScoreArg) -> Self {
        match s {
            ScoreArg::F => ScoreKind::F,
            ScoreArg::Contour => ScoreKind::Contour,
        }
    }
}

/// Which push to use.
#[derive(Args, Clone)]
struct VideoArgs {
    /// Material of the block (chooses the generated ground truth and the
    /// camera scale, §VIII-A).
    #[arg(long, value_enum, default_value = "sponge")]
    material: MaterialArg,
    /// Where the finger pushes.
    #[arg(long, value_enum, default_value = "middle-long")]
    site: SiteArg,
    /// Read the tracked contours and forces from this CSV
    /// (`frame,force_n,x_px,y_px`) instead of generating them (the
    /// generator's --ref-element-px and --noise-seed then have no use).
    #[arg(long, value_name = "CSV", conflicts_with_all = ["ref_element_px", "noise_seed"])]
    video: Option<PathBuf>,
    /// Element size of the finite-element ground truth, px.
    #[arg(allow_negative_numbers = true, long, default_value_t = 8.0)]
    ref_element_px: f64,
    /// Seed of the ground truth's contour and force noise.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    noise_seed: u64,
}

/// How to run the mass-spring model.
#[derive(Args, Clone)]
struct ModelArgs {
    #[arg(long, value_enum, default_value = "customised")]
    integrator: IntegratorArg,
    #[arg(long, value_enum, default_value = "both")]
    mode: ModeArg,
    /// Squares along the block's long side.
    #[arg(allow_negative_numbers = true, long, default_value_t = 20)]
    nx: usize,
    /// Squares along the block's short side.
    #[arg(allow_negative_numbers = true, long, default_value_t = 10)]
    ny: usize,
    /// Raster cell size for the F-score, px (1 = camera pixels).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.0)]
    cell_px: f64,
    /// Turn off the repair of reversed and flat triangles (§VI-E).
    #[arg(long)]
    no_repair: bool,
}

#[derive(Args)]
struct SimulateArgs {
    #[command(flatten)]
    video: VideoArgs,
    #[command(flatten)]
    model: ModelArgs,
    /// Model parameters: a JSON file with the eight parameters, or the
    /// output of `calibrate`. Default: the seed's Fig. 14 (sponge) or
    /// Fig. 15 (plasticine) values.
    #[arg(long, value_name = "JSON")]
    params: Option<PathBuf>,
    /// Drive the model with the force predictor (§V) learned on this push
    /// instead of the sensed forces.
    #[arg(long)]
    predicted_forces: bool,
    /// Output directory.
    #[arg(long, default_value = "push-out")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
    /// Write the results even when the model becomes unstable, from its
    /// first frames or later (frames from the instability on score 0, a
    /// warning on stderr); without it an unstable run exits 1, names the
    /// frame and cause on stderr, and writes nothing.
    #[arg(long)]
    allow_unstable: bool,
}

#[derive(Args)]
struct CalibrateArgs {
    #[command(flatten)]
    video: VideoArgs,
    #[command(flatten)]
    model: ModelArgs,
    /// Generations M (Table III: 30).
    #[arg(allow_negative_numbers = true, long, default_value_t = 30)]
    generations: usize,
    /// Seed of the evolutionary search.
    #[arg(allow_negative_numbers = true, long, default_value_t = 7)]
    seed: u64,
    /// What the search maximises: μ(F), or minus the contour distance in
    /// the finger's reach.
    #[arg(long, value_enum, default_value = "f")]
    score: ScoreArg,
    /// Output directory.
    #[arg(long, default_value = "push-out")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
    /// Go on with a calibration stopped by a signal (Ctrl-C, SIGTERM,
    /// SIGHUP) from the search state it wrote (OUT/params.search.toml):
    /// the candidates it simulated are not simulated again, and the search
    /// ends where it would have ended unbroken (same params.json). Same
    /// push, model options, --score, --generations and --seed. A
    /// calibration stopped again writes its state back to this file.
    #[arg(long, value_name = "STATE")]
    resume: Option<PathBuf>,
    /// Score each generation's new candidates on the Ray cluster at this
    /// address, through the Python package's driver (`python3 -m
    /// softjoint.ray_sweep push-serve`; $SOFTJOINT_PYTHON names another
    /// Python). The draws and the selection stay here: the files are
    /// those of the same calibration without --ray, and --resume goes on
    /// with or without it.
    #[arg(long, value_name = "ADDRESS")]
    ray: Option<String>,
}

#[derive(Args)]
struct ClassifyArgs {
    #[command(flatten)]
    video: VideoArgs,
    #[command(flatten)]
    model: ModelArgs,
    /// A calibrated model as LABEL=PARAMS.json; give at least two.
    #[arg(long = "model", value_name = "LABEL=JSON", required = true)]
    models: Vec<String>,
    /// Per-frame score that decides: F-score, or contour distance in the
    /// finger's reach.
    #[arg(long, value_enum, default_value = "f")]
    score: ScoreArg,
    /// Output directory.
    #[arg(long, default_value = "push-out")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
}

pub fn run(args: PushArgs) -> Result<()> {
    match args.command {
        PushCommand::Simulate(a) => simulate_cmd(a),
        PushCommand::Calibrate(a) => calibrate_cmd(a),
        PushCommand::Classify(a) => classify_cmd(a),
    }
}

fn simulate_cmd(a: SimulateArgs) -> Result<()> {
    // The output directory and the parameters first: an unwritable path
    // or a bad file is refused before the ground truth (seconds of finite
    // elements) is generated.
    check_out_dir(&a.out)?;
    let params = match &a.params {
        Some(p) => load_params(p)?,
        None => a.video.material.seed_params(),
    };
    let prep = prepare(&a.video, &a.model, a.json)?;
    let spec = SimulateSpec {
        params,
        sim: sim_config(&a.model),
        predicted_forces: a.predicted_forces,
    };
    let bar = progress::bar("frames", a.json);
    bar.set_length(prep.frame_count() as u64);
    let run = experiment::run_model(&prep, &spec, &mut |done| bar.set_position(done as u64))?;
    bar.finish_and_clear();
    // An unstable model is a failed run — from its first frames (a stiff
    // mesh at the seed's step: its pictures would only show the blow-up)
    // or later — unless the user asked for its results anyway, with every
    // frame from the instability on scored 0. Nothing non-finite is
    // written either way.
    if let Some(what) = &run.instability {
        if !a.allow_unstable {
            bail!(
                "{what}; nothing was written: try smaller stiffnesses or another --integrator, or give --allow-unstable to write the results with every frame from there on scored 0"
            );
        }
        let _ = writeln!(
            std::io::stderr(),
            "warning: {what}; frames from there on score 0 (--allow-unstable)"
        );
    }
    let report = experiment::assess(&prep, &spec, run)?;
    out_dir(&a.out)?;
    let title = format!(
        "{} pushed at {}: μ(F) = {:.4}",
        report.material, report.site, report.mean_f
    );
    write_simulation(&a.out, &prep, (a.model.nx, a.model.ny), &report, &title)?;
    if a.json {
        return JsonObject::of(&report)?.field("out", &a.out)?.print();
    }
    outln!("{title} (undeformed block: {:.4})", report.still_mean_f);
    outln!(
        "contour distance in the finger's reach: {:.2} px mean, {:.2} px max (undeformed block {:.2} / {:.2} px): skill {:.2}",
        report.contour_mean_px,
        report.contour_max_px,
        report.still_contour_mean_px,
        report.still_contour_max_px,
        report.contour_skill
    );
    if let Some(what) = &report.instability {
        outln!("{what}: scored 0 from there");
    }
    outln!(
        "wrote frames.csv, video.csv, snapshots.svg, f_per_frame.svg to {}",
        a.out.display()
    );
    Ok(())
}

/// Most generations `calibrate` runs: the history of every generation is
/// allocated up front, and at Table III's 30 simulations per generation this
/// is already hours of work.
const MAX_GENERATIONS: usize = 10_000;

/// The files `calibrate` writes in its output directory.
const CALIBRATION_FILES: [&str; 4] = [
    "params.json",
    "generations.csv",
    "mu_per_generation.svg",
    "snapshots.svg",
];

/// Where a stopped calibration writes its search state, in its output
/// directory (`params.json` → `params.search.toml`, as `tune` does).
const STATE_FILE: &str = "params.search.toml";

fn calibrate_cmd(a: CalibrateArgs) -> Result<()> {
    // A signal stops the search at its next simulation (one that comes
    // while the push is prepared stops it before the first).
    let stop = Stop::on_signals()?;
    if !(1..=MAX_GENERATIONS).contains(&a.generations) {
        bail!(
            "--generations must be 1..={MAX_GENERATIONS} (Table III: 30), got {}",
            a.generations
        );
    }
    // Every file the calibration writes, and the search state a stop
    // writes, can be written: checked before the search, not after it.
    host_tools::output::check_files_in(&a.out, &CALIBRATION_FILES)?;
    let state_path = a.state_path();
    if a.resume.is_some() || a.out.is_dir() {
        output::check_file(&state_path)?;
    }
    // Started before the push is prepared: it joins the cluster meanwhile.
    // It answers `null` for a fitness that is not finite, read as NaN,
    // which the search ranks last, as it ranks a local one.
    let driver = a
        .ray
        .as_deref()
        .map(|address| {
            let (cmd, who) = push_driver_command(&a, address);
            host_tools::ray::Driver::start(cmd, who, stop.clone(), f64::NAN)
        })
        .transpose()?;
    let prep = prepare(&a.video, &a.model, a.json)?;
    let spec = CalibrateSpec {
        generations: a.generations,
        seed: a.seed,
        score: a.score.into(),
        sim: sim_config(&a.model),
    };
    let fingerprint = push_fingerprint(&a, &prep, &spec);
    let (resumed, evaluations_before) = a.resumed(&fingerprint)?;
    let scores = Scores::new(stop.clone(), resumed);
    let bar = progress::counter(
        "calibrating",
        "generations",
        Some(a.generations as u64),
        a.json,
    );
    let layer = |p: &MaterialParams, run: &dyn Fn(&MaterialParams) -> f64| {
        scores.score(&p.to_array(), |_| run(p))
    };
    let mut on_generation = |g: &plant_pushing::evolution::GenerationReport| {
        bar.set_message(match spec.score {
            ScoreKind::F => format!("best μ(F) {:.4}", g.best),
            ScoreKind::Contour => format!("best contour distance {:.2} px", -g.best),
        });
        bar.inc(1);
    };
    let found = match driver {
        None => experiment::calibrate_until(&prep, &spec, &layer, &mut on_generation),
        Some(mut driver) => {
            // The driver's failure, which stops the search.
            let mut failed = None;
            let found = experiment::calibrate_batches(
                &prep,
                &spec,
                &mut |genes| match scores.score_batch(genes, |todo| driver.scores(todo)) {
                    Ok(kept) => kept,
                    Err(e) => {
                        failed = Some(e);
                        None
                    }
                },
                &mut on_generation,
            );
            if let (Some(e), None) = (failed, stop.requested()) {
                bail!("{e}");
            }
            found
        }
    };
    let report = match (found, stop.requested()) {
        (Ok(Some(report)), _) => report,
        (Ok(None) | Err(_), Some(signal)) => {
            bar.finish_and_clear();
            let mut state = PushSearchState::new(&a, fingerprint, spec.score, &scores);
            // A resumed search stopped while retracing is no further on
            // than the search it resumed.
            state.evaluations = state.evaluations.max(evaluations_before);
            return Err(push_stopped(&a, signal, &state_path, &state, spec.score));
        }
        (Ok(None), None) => bail!("the search stopped though no signal asked it to"),
        (Err(e), None) => return Err(e.into()),
    };
    bar.finish_and_clear();
    out_dir(&a.out)?;
    write_calibration(&a.out, &prep, (a.model.nx, a.model.ny), &report)?;
    if a.json {
        return JsonObject::of(&report)?.field("out", &a.out)?.print();
    }
    outln!(
        "calibrated by {}: μ(F) {:.4} (undeformed block {:.4}), contour distance {:.2} px (undeformed block {:.2} px, skill {:.2}) after {} generations ({} simulations)",
        report.score.name(),
        report.best_mean_f,
        report.still_mean_f,
        report.best_contour_mean_px,
        report.still_contour_mean_px,
        report.contour_skill,
        report.result.history.len(),
        report.evaluations
    );
    outln!("{}", report.best_params);
    if let Some(r) = &a.resume {
        outln!("{}", scores.resumed_line(r));
    }
    outln!(
        "wrote params.json, generations.csv, mu_per_generation.svg, snapshots.svg to {}",
        a.out.display()
    );
    // The search had ended when a signal came: its files are whole.
    host_tools::resume::finished_or_stopped(&stop, &a.out)
}

/// The Ray driver of `a`'s calibration (`push-serve` with the push and
/// model flags of `a`, as the Python package's `PushProblem` takes them),
/// and its name in errors.
fn push_driver_command(a: &CalibrateArgs, address: &str) -> (std::process::Command, String) {
    let (mut cmd, who) = host_tools::ray::serve_command("push-serve", address);
    let name = |v: Option<clap::builder::PossibleValue>| {
        v.map(|v| v.get_name().to_string()).unwrap_or_default()
    };
    let (v, m) = (&a.video, &a.model);
    cmd.args(["--material", &name(v.material.to_possible_value())]);
    cmd.args(["--site", &name(v.site.to_possible_value())]);
    if let Some(path) = &v.video {
        cmd.arg("--video").arg(path);
    }
    cmd.args(["--ref-element-px", &format!("{:?}", v.ref_element_px)]);
    cmd.args(["--noise-seed", &v.noise_seed.to_string()]);
    cmd.args(["--integrator", &name(m.integrator.to_possible_value())]);
    cmd.args(["--mode", &name(m.mode.to_possible_value())]);
    cmd.args(["--nx", &m.nx.to_string(), "--ny", &m.ny.to_string()]);
    cmd.args(["--cell-px", &format!("{:?}", m.cell_px)]);
    if m.no_repair {
        cmd.arg("--no-repair");
    }
    cmd.args(["--score", &name(a.score.to_possible_value())]);
    (cmd, who)
}

/// A `push calibrate` stopped by a signal: what it had simulated, to
/// resume from (`--resume`), and the best candidate so far.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PushSearchState {
    /// FNV-1a of the problem: the push (its tracked contours and forces),
    /// the material, site, grid, raster and simulator settings, the score.
    problem_fnv1a: String,
    /// --generations (σ falls over them: another count is another search).
    generations: usize,
    seed: u64,
    /// Candidates the search had been given scores for (one asked twice
    /// counts twice, is simulated once).
    evaluations: usize,
    /// The best candidate so far (absent if none scored).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    best: Option<PushBest>,
    /// Every candidate simulated, in the order they came in: genes are
    /// k_length, k_damping, k_area, k_angle, max_force, yield_strain,
    /// creep, max_alpha; the score is the search's fitness (μ(F), or minus
    /// the contour distance in px), absent when not finite.
    #[serde(default)]
    scored: Vec<Scored>,
}

/// The best candidate of a stopped `push calibrate`.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PushBest {
    /// Its score in the score's own terms: μ(F), or the contour distance
    /// in px.
    score: f64,
    /// Its parameters, as params.json names them.
    params: MaterialParams,
}

impl PushSearchState {
    fn new(a: &CalibrateArgs, problem_fnv1a: String, kind: ScoreKind, scores: &Scores) -> Self {
        let evaluations = scores.answered();
        let scored = scores.snapshot();
        let best = best_of(&scored, |x, y| x > y).and_then(|b| {
            let genes = <[f64; 8]>::try_from(b.genes.as_slice()).ok()?;
            Some(PushBest {
                score: kind.in_own_terms(b.score?),
                params: MaterialParams::from_array(genes),
            })
        });
        Self {
            problem_fnv1a,
            generations: a.generations,
            seed: a.seed,
            evaluations,
            best,
            scored,
        }
    }
}

impl CalibrateArgs {
    /// Where a stopped calibration writes its state: the file it resumed
    /// from, or [`STATE_FILE`] in the output directory.
    fn state_path(&self) -> PathBuf {
        match &self.resume {
            Some(p) => p.clone(),
            None => self.out.join(STATE_FILE),
        }
    }

    /// The candidates scored by the calibration resumed and its
    /// evaluations, checked against this one.
    fn resumed(&self, fingerprint: &str) -> Result<(Vec<Scored>, usize)> {
        let Some(path) = &self.resume else {
            return Ok((Vec::new(), 0));
        };
        let text = fs::read_to_string(path)
            .with_context(|| format!("cannot read --resume {}", path.display()))?;
        let st: PushSearchState = host_tools::input::from_toml(&text, &path.display().to_string())?;
        let refuse = |why: String| anyhow::anyhow!("--resume {}: {why}", path.display());
        if st.problem_fnv1a != fingerprint {
            return Err(refuse(
                "it is a calibration of another problem (the push, the model options or --score differ, or the --video file changed since)".into(),
            ));
        }
        if st.generations != self.generations {
            return Err(refuse(format!(
                "it is a calibration with --generations {}, this one asks {} (σ falls over the generations: another count is another search)",
                st.generations, self.generations
            )));
        }
        if st.seed != self.seed {
            return Err(refuse(format!(
                "it is a calibration with --seed {}, this one asks {}",
                st.seed, self.seed
            )));
        }
        if st.scored.iter().any(|s| s.genes.len() != 8) {
            return Err(refuse("every `scored` entry needs the eight genes".into()));
        }
        Ok((st.scored, st.evaluations))
    }
}

/// FNV-1a of what the search's scores depend on: the push, the material,
/// site, grid, raster and simulator settings and the score.
fn push_fingerprint(a: &CalibrateArgs, prep: &PreparedVideo, spec: &CalibrateSpec) -> String {
    let mut text = write_video_csv(&prep.video);
    let _ = write!(
        text,
        "\nmaterial {} site {} nx {} ny {} cell_px {:?} sim {:?} score {}",
        a.video.material.label(),
        PushSite::from(a.video.site).name(),
        a.model.nx,
        a.model.ny,
        a.model.cell_px,
        spec.sim,
        spec.score.name()
    );
    fnv1a_hex(text.as_bytes())
}

/// Writes a stopped calibration's state and says what it kept, as the
/// error the program exits with (130, 143, 129); no result file is
/// written (the search did not finish).
fn push_stopped(
    a: &CalibrateArgs,
    signal: StopSignal,
    path: &Path,
    state: &PushSearchState,
    kind: ScoreKind,
) -> anyhow::Error {
    if let Err(e) = out_dir(&a.out).and_then(|()| {
        output::write_toml(
            path,
            "# Written by `softjoint push calibrate` when stopped: the candidates simulated so far\n# and the best of them. `softjoint push calibrate … --resume THIS_FILE` goes on from here.\n",
            state,
        )
    }) {
        return e.context(format!(
            "stopped by {}; the search state was lost",
            signal.name()
        ));
    }
    let best = match (&state.best, kind) {
        (Some(b), ScoreKind::F) => format!("best so far μ(F) {:.4}", b.score),
        (Some(b), ScoreKind::Contour) => {
            format!("best so far contour distance {:.2} px", b.score)
        }
        (None, _) => "none scored yet".into(),
    };
    Stopped {
        signal,
        what: format!(
            "{} evaluations ({} candidates simulated), {best}; search state in {} (`softjoint push calibrate … --resume {}` with the same options goes on from there); params.json and the other result files not written",
            state.evaluations,
            state.scored.len(),
            path.display(),
            path.display(),
        ),
    }
    .into()
}

fn classify_cmd(a: ClassifyArgs) -> Result<()> {
    let models = parse_models(&a.models)?;
    check_out_dir(&a.out)?;
    let prep = prepare(&a.video, &a.model, a.json)?;
    let score = ScoreKind::from(a.score);
    let report = experiment::classify(&prep, &models, score, &sim_config(&a.model))?;
    out_dir(&a.out)?;
    write(
        &a.out.join("classification.csv"),
        &classification_csv(&report),
    )?;
    write(
        &a.out.join("classification.svg"),
        &classification_chart(&report),
    )?;
    if a.json {
        return JsonObject::of(&report)?.field("out", &a.out)?.print();
    }
    outln!("global vote by {}: {}", score.name(), report.verdict());
    let unit = if score == ScoreKind::Contour {
        " px"
    } else {
        ""
    };
    for (k, l) in report.labels.iter().enumerate() {
        outln!(
            "  {l:>12}: {} frames won, weighted vote {:+.4}{unit}",
            report.frames_won[k],
            report.vote[k],
        );
    }
    outln!(
        "wrote classification.csv, classification.svg to {}",
        a.out.display()
    );
    Ok(())
}

fn sim_config(m: &ModelArgs) -> SimConfig {
    push::sim_config(
        match m.integrator {
            IntegratorArg::Customised => Integrator::Customised,
            IntegratorArg::Euler => Integrator::Euler,
            IntegratorArg::Verlet => Integrator::Verlet,
            IntegratorArg::CustomisedSeq => Integrator::CustomisedSequential,
        },
        match m.mode {
            ModeArg::Collision => DrivingMode::CollisionOnly,
            ModeArg::Forces => DrivingMode::ForcesOnVertices,
            ModeArg::Both => DrivingMode::CollisionAndForces,
        },
        !m.no_repair,
    )
}

/// A setting's flag: `--ref-element-px` for `ref_element_px`.
fn flag(name: &str) -> String {
    format!("--{}", name.replace('_', "-"))
}

/// The push the flags name, loaded (the tests read a written video back).
#[cfg(test)]
fn load_video(v: &VideoArgs, json: bool) -> Result<plant_pushing::reference::Video> {
    let text = read_video(v)?;
    push::load_video(&source(v, text.as_ref()), &flag, json)
}

/// The --video file's text and name, if one is given.
fn read_video(v: &VideoArgs) -> Result<Option<(String, String)>> {
    v.video
        .as_ref()
        .map(|path| {
            let text =
                fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            Ok((text, path.display().to_string()))
        })
        .transpose()
}

/// The push the flags name (`text`: the --video file's text and name).
fn source<'a>(v: &VideoArgs, text: Option<&'a (String, String)>) -> PushSource<'a> {
    PushSource {
        material: v.material.into(),
        site: v.site.into(),
        video: text.map(|(t, n)| (t.as_str(), n.as_str())),
        ref_element_px: v.ref_element_px,
        noise_seed: v.noise_seed,
    }
}

fn prepare(v: &VideoArgs, m: &ModelArgs, json: bool) -> Result<PreparedVideo> {
    let grid = ModelGrid {
        nx: m.nx,
        ny: m.ny,
        cell_px: m.cell_px,
    };
    push::check_grid(&grid, &flag)?;
    let text = read_video(v)?;
    push::prepare(&source(v, text.as_ref()), &grid, &flag, json)
}

/// Reads parameters from a bare parameter object or from `calibrate`'s
/// `params.json` (which holds them under `best_params`).
fn load_params(path: &Path) -> Result<MaterialParams> {
    let text = fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    push::params_from_json(&text, &path.display().to_string())
}

fn parse_model(spec: &str) -> Result<MaterialModel> {
    let Some((label, path)) = spec.split_once('=') else {
        bail!("--model `{spec}`: expected LABEL=PARAMS.json");
    };
    if label.trim().is_empty() {
        bail!("--model `{spec}`: the label is empty");
    }
    // The label becomes a CSV column name (`f_LABEL`) and a legend entry.
    if label.contains([',', '"', '\n', '\r']) {
        bail!("--model `{spec}`: the label may not contain a comma, a quote or a line break");
    }
    Ok(MaterialModel {
        label: label.trim().to_string(),
        params: load_params(Path::new(path.trim()))?,
    })
}

/// The `--model LABEL=PARAMS.json` flags: at least two, no label twice.
fn parse_models(specs: &[String]) -> Result<Vec<MaterialModel>> {
    let models: Vec<MaterialModel> = specs
        .iter()
        .map(|s| parse_model(s))
        .collect::<Result<_>>()?;
    if models.len() < 2 {
        bail!("classification needs at least two --model LABEL=PARAMS.json");
    }
    for (k, m) in models.iter().enumerate() {
        if models[..k].iter().any(|o| o.label == m.label) {
            bail!(
                "--model: the label `{}` is given twice; the results could not be told apart",
                m.label
            );
        }
    }
    Ok(models)
}

/// Creates the output directory.
fn out_dir(dir: &Path) -> Result<()> {
    host_tools::output::create_dir(dir)
}

/// Checks the output directory can be written, before the simulation
/// rather than after it.
fn check_out_dir(dir: &Path) -> Result<()> {
    host_tools::output::check_dir(dir)
}

/// Writes a result file atomically (a failed write leaves the old file).
fn write(path: &Path, text: &str) -> Result<()> {
    if path.extension().is_some_and(|e| e == "svg") {
        output::write_svg(path, text)
    } else {
        output::write_csv(path, text)
    }
}

/// `simulate`'s files: frames.csv, video.csv, snapshots.svg, f_per_frame.svg.
fn write_simulation(
    out: &Path,
    prep: &PreparedVideo,
    grid: (usize, usize),
    report: &SimulateReport,
    title: &str,
) -> Result<()> {
    write(&out.join("frames.csv"), &frames_csv(prep, report))?;
    write(&out.join("video.csv"), &write_video_csv(&prep.video))?;
    let panels = Panels {
        prep,
        grid,
        f_per_frame: &report.f_per_frame,
        tracking: &report.tracking,
    };
    write(
        &out.join("snapshots.svg"),
        &snapshots_svg(&panels, &report.snapshots, title),
    )?;
    write(
        &out.join("f_per_frame.svg"),
        &f_per_frame_chart(prep, report),
    )
}

/// `calibrate`'s files: params.json, generations.csv,
/// mu_per_generation.svg, snapshots.svg.
fn write_calibration(
    out: &Path,
    prep: &PreparedVideo,
    grid: (usize, usize),
    report: &CalibrateReport,
) -> Result<()> {
    output::write_json(&out.join("params.json"), &report.result)?;
    write(&out.join("generations.csv"), &generations_csv(report))?;
    write(
        &out.join("mu_per_generation.svg"),
        &generations_chart(report),
    )?;
    let title = format!(
        "{} model calibrated by {} on its training push: μ(F) = {:.4}, contour distance {:.2} px",
        report.material,
        report.score.name(),
        report.best_mean_f,
        report.best_contour_mean_px
    );
    let panels = Panels {
        prep,
        grid,
        f_per_frame: &report.f_per_frame,
        tracking: &report.tracking,
    };
    write(
        &out.join("snapshots.svg"),
        &snapshots_svg(&panels, &report.snapshots, &title),
    )
}

/// Most grid lines drawn per direction in a snapshot panel: a 2000 × 2000
/// mesh drawn edge by edge made a 1.44 GB SVG no viewer opens.
const MAX_DRAWN_GRID_LINES: usize = 50;

/// The mesh of a snapshot as line segments: every edge of a mesh of at
/// most [`MAX_DRAWN_GRID_LINES`] squares per side, else every k-th grid
/// line of the `nx × ny` grid (through every k-th vertex along it), which
/// still shows how the block deforms. Returns the segments and k.
fn mesh_segments(
    mesh: &plant_pushing::mesh::Mesh,
    nx: usize,
    ny: usize,
    pos: &[V2],
) -> (Vec<(V2, V2)>, usize) {
    let k = nx.max(ny).div_ceil(MAX_DRAWN_GRID_LINES).max(1);
    if k == 1 || pos.len() != (nx + 1) * (ny + 1) {
        let all = mesh.edges.iter().map(|e| (pos[e[0]], pos[e[1]])).collect();
        return (all, 1);
    }
    let at = |i: usize, j: usize| pos[j * (nx + 1) + i];
    // Every k-th index, and the last one (the block's far sides).
    let picks = |n: usize| -> Vec<usize> {
        let mut v: Vec<usize> = (0..=n).step_by(k).collect();
        if v.last() != Some(&n) {
            v.push(n);
        }
        v
    };
    let (is, js) = (picks(nx), picks(ny));
    let mut out = Vec::new();
    for &j in &js {
        out.extend(is.windows(2).map(|w| (at(w[0], j), at(w[1], j))));
    }
    for &i in &is {
        out.extend(js.windows(2).map(|w| (at(i, w[0]), at(i, w[1]))));
    }
    (out, k)
}

/// What every snapshot panel draws from: the push, the `nx × ny` mesh
/// size asked for, the model's F per frame and the tracked contour.
struct Panels<'a> {
    prep: &'a PreparedVideo,
    grid: (usize, usize),
    f_per_frame: &'a [f64],
    tracking: &'a Tracking,
}

/// Where a snapshot panel lies on the page: its left edge and top, its
/// width and height, and the scale from pixels of the image.
#[derive(Clone, Copy)]
struct Panel {
    left: f64,
    top: f64,
    width: f64,
    height: f64,
    scale: f64,
    /// The image region shown (lowest and highest corner, px).
    lo: V2,
    hi: V2,
}

impl Panel {
    /// Page coordinates of an image point (y up in the image, down on the
    /// page).
    fn at(&self, p: V2) -> (f64, f64) {
        (
            self.left + (p.x - self.lo.x) * self.scale,
            self.top + (self.hi.y - p.y) * self.scale,
        )
    }
}

/// Mesh snapshots over frames: ground-truth outline (grey fill), the model
/// mesh (blue), the finger (red).
fn snapshots_svg(panels: &Panels, shots: &[(usize, Vec<V2>)], title: &str) -> String {
    let grid = &panels.prep.grid;
    let lo = grid.origin_px;
    let hi = V2::new(
        lo.x + grid.nx as f64 * grid.cell_px,
        lo.y + grid.ny as f64 * grid.cell_px,
    );
    let panel_w = 300.0;
    let scale = panel_w / (hi.x - lo.x);
    let panel_h = (hi.y - lo.y) * scale;
    let top = 40.0;
    let width = panel_w * shots.len() as f64 + 10.0 * (shots.len() as f64 + 1.0);
    let height = panel_h + top + 40.0;
    let mut svg = Svg::new(width, height);
    svg.text(10.0, 20.0, 14.0, Anchor::Start, title);
    for (k, (f, pos)) in shots.iter().enumerate() {
        let frame = Panel {
            left: 10.0 + k as f64 * (panel_w + 10.0),
            top,
            width: panel_w,
            height: panel_h,
            scale,
            lo,
            hi,
        };
        snapshot_panel(&mut svg, panels, &frame, *f, pos, k == 0);
    }
    svg.text_styled(
        10.0,
        height - 6.0,
        12.0,
        Anchor::Start,
        r##"fill="#555""##,
        "grey: tracked contour points · green: their periodic smoothing spline · dashed orange: the finger's reach · blue: mass-spring mesh · red: finger · brown: table",
    );
    svg.finish()
}

/// One snapshot panel: frame `f` with the mesh at `pos`; the first panel
/// also says when only every k-th grid line is drawn.
fn snapshot_panel(
    svg: &mut Svg,
    panels: &Panels,
    frame: &Panel,
    f: usize,
    pos: &[V2],
    first: bool,
) {
    let (prep, tracked) = (panels.prep, panels.tracking);
    let (ox, top, lo, hi) = (frame.left, frame.top, frame.lo, frame.hi);
    let tx = |p: V2| frame.at(p);
    svg.rect(
        ox,
        top,
        frame.width,
        frame.height,
        "none",
        Some(Stroke::solid("#ccc", 1.0)),
    );
    // The table.
    let table = tx(V2::new(lo.x, 0.0));
    svg.line(
        table,
        (ox + frame.width, table.1),
        Stroke::solid("#964", 2.0),
    );
    let contour: Vec<(f64, f64)> = prep.video.contours_px[f].iter().map(|p| tx(*p)).collect();
    svg.polygon(&contour, "#ddd", Stroke::solid("#777", 1.0));
    let mut spline: Vec<(f64, f64)> = tracked.contours_px[f].iter().map(|p| tx(*p)).collect();
    if let Some(&first) = spline.first() {
        spline.push(first);
    }
    svg.polyline(spline, Stroke::solid("#2a2", 1.2));
    // The zone's outline, kept inside the panel.
    let mut zone: Vec<(f64, f64)> = zone_outline(&tracked.zone)
        .into_iter()
        .map(|p| tx(V2::new(p.x.clamp(lo.x, hi.x), p.y.clamp(lo.y, hi.y))))
        .collect();
    if let Some(&first) = zone.first() {
        zone.push(first);
    }
    svg.polyline(zone, Stroke::dashed("#e80", 1.0));
    let (nx, ny) = panels.grid;
    let (segments, every) = mesh_segments(&prep.mesh, nx, ny, pos);
    svg.segments(
        segments.into_iter().map(|(a, b)| (tx(a), tx(b))),
        Stroke::solid("#1f5fbf", 0.7),
    );
    if every > 1 && first {
        svg.text(
            10.0,
            34.0,
            11.0,
            Anchor::Start,
            &format!("{nx} × {ny} mesh: one grid line in {every} drawn"),
        );
    }
    let sc = &prep.video.scenario;
    let finger = sc.finger_at(sc.frame_time_s(f));
    svg.circle(
        tx(finger.centre_px),
        finger.radius_px * frame.scale,
        Stroke::solid("#d22", 1.5),
    );
    let fscore = panels.f_per_frame.get(f).copied().unwrap_or(f64::NAN);
    let phase = if sc.is_push_frame(f) {
        "push"
    } else {
        "retrieval"
    };
    svg.text(
        ox,
        top + frame.height + 18.0,
        12.0,
        Anchor::Start,
        &format!(
            "frame {f} ({phase}), F = {fscore:.3}, d = {:.1} px",
            tracked.model_mean_px(f)
        ),
    );
}

/// The outline of the reach zone: the finger path's capsule.
fn zone_outline(z: &ReachZone) -> Vec<V2> {
    let d = z.path_end_px - z.path_start_px;
    let u = if d.norm() > 0.0 {
        d.normalize()
    } else {
        V2::new(0.0, -1.0)
    };
    let n = V2::new(-u.y, u.x);
    let mut out = Vec::with_capacity(74);
    for k in 0..=36 {
        let a = std::f64::consts::PI * (k as f64 / 36.0 - 0.5);
        out.push(z.path_end_px + (u * a.cos() + n * a.sin()) * z.radius_px);
    }
    for k in 0..=36 {
        let a = std::f64::consts::PI * (k as f64 / 36.0 + 0.5);
        out.push(z.path_start_px + (u * a.cos() + n * a.sin()) * z.radius_px);
    }
    out
}

/// `frames.csv`: per frame the finger, the forces, F and the contour
/// distances of the model and the undeformed block
/// ([`push::frame_table`]'s columns).
fn frames_csv(prep: &PreparedVideo, report: &SimulateReport) -> String {
    let table = push::frame_table(prep, report);
    // Decimals of each numeric column, in the table's order.
    const DIGITS: [usize; 10] = [3, 3, 4, 4, 5, 5, 3, 3, 3, 3];
    let mut s = String::from("frame");
    for (k, (name, _)) in table.columns.iter().enumerate() {
        let _ = write!(s, ",{name}");
        if k == 0 {
            s.push_str(",phase");
        }
    }
    s.push('\n');
    for (f, phase) in table.phase.iter().enumerate() {
        let _ = write!(s, "{f}");
        for (k, ((_, col), digits)) in table.columns.iter().zip(DIGITS).enumerate() {
            let _ = write!(s, ",{:.digits$}", col[f]);
            if k == 0 {
                let _ = write!(s, ",{phase}");
            }
        }
        s.push('\n');
    }
    s
}

/// `f_per_frame.svg`: F and μ(F), the contour distances, and the forces
/// per frame.
fn f_per_frame_chart(prep: &PreparedVideo, report: &SimulateReport) -> String {
    let t: Vec<f64> = (0..prep.frame_count()).map(|f| f as f64).collect();
    let (contour, still) = (&report.contour, &report.tracking.still);
    plot::line_charts(&[
        Chart {
            title: "F-score per frame".into(),
            x_label: "frame".into(),
            y_label: "F-score".into(),
            series: vec![
                Series::over("F", "#1f5fbf", false, &t, &report.f_per_frame),
                Series::over(
                    "μ(F)",
                    "#d22",
                    true,
                    &t,
                    &plant_pushing::raster::running_mean(&report.f_per_frame),
                ),
            ],
        },
        Chart {
            title: "Contour distance within the finger's reach (tracked spline vs model outline)"
                .into(),
            x_label: "frame".into(),
            y_label: "distance (px)".into(),
            series: vec![
                Series::over(
                    "model, mean",
                    "#1f5fbf",
                    false,
                    &t,
                    &contour.mean_px_per_frame,
                ),
                Series::over("model, max", "#1f5fbf", true, &t, &contour.max_px_per_frame),
                Series::over(
                    "undeformed block, mean",
                    "#555",
                    false,
                    &t,
                    &still.mean_px_per_frame,
                ),
                Series::over(
                    "undeformed block, max",
                    "#555",
                    true,
                    &t,
                    &still.max_px_per_frame,
                ),
            ],
        },
        Chart {
            title: "Finger force".into(),
            x_label: "frame".into(),
            y_label: "force (N)".into(),
            series: vec![
                Series::over("sensed", "#555", false, &t, &prep.video.forces_n),
                Series::over("driving the model", "#e80", true, &t, &report.forces_n),
            ],
        },
    ])
    .finish()
}

/// `generations.csv`: each generation's scores in the score's own terms
/// (μ(F), or the contour distance in px) and σ.
fn generations_csv(report: &CalibrateReport) -> String {
    let score = report.score;
    let mut csv = String::from(match score {
        ScoreKind::F => "generation,best_mean_f,population_mean_f,worst_mean_f,sigma\n",
        ScoreKind::Contour => {
            "generation,best_contour_px,population_mean_contour_px,worst_contour_px,sigma\n"
        }
    });
    for g in &report.result.history {
        let _ = writeln!(
            csv,
            "{},{:.6},{:.6},{:.6},{:.2}",
            g.generation,
            score.in_own_terms(g.best),
            score.in_own_terms(g.mean),
            score.in_own_terms(g.worst),
            g.sigma
        );
    }
    csv
}

/// `mu_per_generation.svg`: the best and the population's mean per
/// generation.
fn generations_chart(report: &CalibrateReport) -> String {
    let history = &report.result.history;
    let t: Vec<f64> = history.iter().map(|g| g.generation as f64).collect();
    let mean: Vec<f64> = history
        .iter()
        .map(|g| report.score.in_own_terms(g.mean))
        .collect();
    let what = match report.score {
        ScoreKind::F => "μ(F)",
        ScoreKind::Contour => "contour distance (px)",
    };
    plot::line_charts(&[Chart {
        title: format!(
            "{what} per generation, {} at {}",
            report.material, report.site
        ),
        x_label: "generation".into(),
        y_label: what.into(),
        series: vec![
            Series::over("best", "#1f5fbf", false, &t, &report.best_per_generation),
            Series::over("population mean", "#e80", true, &t, &mean),
        ],
    }])
    .finish()
}

/// `classification.csv`: each model's value per frame and the frame's
/// winner.
fn classification_csv(report: &ClassifyReport) -> String {
    let (prefix, digits) = match report.score {
        ScoreKind::F => ("f", 5),
        ScoreKind::Contour => ("d_px", 3),
    };
    let mut csv = String::from("frame");
    for label in &report.labels {
        let _ = write!(csv, ",{prefix}_{label}");
    }
    csv.push_str(",winner\n");
    for (f, winner) in report.frame_winner.iter().enumerate() {
        let _ = write!(csv, "{f}");
        for values in &report.per_frame {
            let _ = write!(csv, ",{:.digits$}", values[f]);
        }
        let _ = writeln!(
            csv,
            ",{}",
            winner.map(|k| report.labels[k].as_str()).unwrap_or("tie")
        );
    }
    csv
}

/// `classification.svg`: each model's value per frame.
fn classification_chart(report: &ClassifyReport) -> String {
    const COLOURS: [&str; 6] = ["#1f5fbf", "#d22", "#2a2", "#e80", "#808", "#555"];
    let y_label = match report.score {
        ScoreKind::F => "F-score",
        ScoreKind::Contour => "mean contour distance in the finger's reach (px)",
    };
    let t: Vec<f64> = (0..report.frame_winner.len()).map(|f| f as f64).collect();
    plot::line_charts(&[Chart {
        title: format!(
            "{y_label} per frame of each model — global vote: {}",
            report.verdict()
        ),
        x_label: "frame".into(),
        y_label: y_label.into(),
        series: report
            .labels
            .iter()
            .enumerate()
            .map(|(k, label)| {
                Series::over(
                    label.clone(),
                    COLOURS[k % COLOURS.len()],
                    k % 2 == 1,
                    &t,
                    &report.per_frame[k],
                )
            })
            .collect(),
    }])
    .finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratch directory deleted when the test ends.
    fn tmp(name: &str) -> tempfile::TempDir {
        tempfile::Builder::new()
            .prefix(&format!("softjoint-push-{name}-"))
            .tempdir()
            .unwrap()
    }

    fn small_video(material: MaterialArg) -> VideoArgs {
        VideoArgs {
            material,
            site: SiteArg::MiddleLong,
            video: None,
            ref_element_px: 30.0,
            noise_seed: 1,
        }
    }

    fn small_model() -> ModelArgs {
        ModelArgs {
            integrator: IntegratorArg::Customised,
            mode: ModeArg::Both,
            nx: 3,
            ny: 2,
            cell_px: 8.0,
            no_repair: false,
        }
    }

    #[test]
    fn snapshots_of_large_meshes_draw_a_bounded_number_of_lines() {
        use plant_pushing::mesh::Mesh;
        let small = Mesh::grid(V2::new(0.0, 0.0), 100.0, 50.0, 20, 10).unwrap();
        let (all, k) = mesh_segments(&small, 20, 10, &small.rest_positions_px);
        assert_eq!((all.len(), k), (small.edges.len(), 1));
        // 2000 × 2000 squares (the CLI's largest): 12 million edges drawn
        // one by one were a 1.44 GB SVG. Rest positions of the grid stand in
        // for a deformed mesh (only the positions are read).
        let (nx, ny) = (2000, 2000);
        let pos: Vec<V2> = (0..=ny)
            .flat_map(|j| (0..=nx).map(move |i| V2::new(i as f64, j as f64)))
            .collect();
        let (drawn, k) = mesh_segments(&small, nx, ny, &pos);
        assert_eq!(k, 40);
        // 51 lines each way, 50 segments each.
        assert_eq!(drawn.len(), 2 * 51 * 50);
        // The outline is complete: the four corners are on drawn lines.
        for corner in [(0.0, 0.0), (2000.0, 0.0), (0.0, 2000.0), (2000.0, 2000.0)] {
            assert!(drawn
                .iter()
                .any(|(a, b)| (a.x, a.y) == corner || (b.x, b.y) == corner));
        }
    }

    #[test]
    fn every_integrator_name_on_the_command_line_reaches_the_simulator() {
        use clap::Parser;
        #[derive(Parser)]
        struct Cli {
            #[command(flatten)]
            model: ModelArgs,
        }
        for integ in Integrator::WITH_VARIANTS {
            let cli = Cli::try_parse_from(["t", "--integrator", integ.name()]).unwrap();
            assert_eq!(sim_config(&cli.model).integrator, integ);
        }
        assert!(Cli::try_parse_from(["t", "--integrator", "rk4"]).is_err());
    }

    #[test]
    fn bad_model_specs_and_parameter_files_are_refused_clearly() {
        let scratch = tmp("bad");
        let dir = scratch.path();
        assert!(parse_model("sponge")
            .unwrap_err()
            .to_string()
            .contains("expected LABEL=PARAMS.json"));
        assert!(parse_model(" =x.json")
            .unwrap_err()
            .to_string()
            .contains("label is empty"));
        assert!(
            format!("{:#}", parse_model("a=/nonexistent/p.json").unwrap_err())
                .contains("reading /nonexistent/p.json")
        );
        let p = dir.join("notjson.json");
        fs::write(&p, "k_length = 3").unwrap();
        let e = format!("{:#}", load_params(&p).unwrap_err());
        assert!(
            e.contains("notjson.json:1:1") && e.contains("expected value"),
            "{e}"
        );
        let p = dir.join("missing.json");
        fs::write(&p, r#"{"k_length": 1.0}"#).unwrap();
        assert!(format!("{:#}", load_params(&p).unwrap_err())
            .contains("expected the eight model parameters"));
        let p = dir.join("negative.json");
        let mut bad = serde_json::to_value(MaterialParams::SEED_FIG14_SPONGE).unwrap();
        bad["k_area"] = serde_json::json!(-1.0);
        fs::write(&p, bad.to_string()).unwrap();
        assert!(format!("{:#}", load_params(&p).unwrap_err()).contains("k_area"));
    }

    #[test]
    fn simulate_calibrate_and_classify_write_their_files() {
        let scratch = tmp("run");
        let dir = scratch.path();
        let sim_out = dir.join("sim");
        simulate_cmd(SimulateArgs {
            video: small_video(MaterialArg::Sponge),
            model: small_model(),
            params: None,
            predicted_forces: true,
            out: sim_out.clone(),
            json: true,
            allow_unstable: false,
        })
        .unwrap();
        let frames = fs::read_to_string(sim_out.join("frames.csv")).unwrap();
        assert_eq!(frames.lines().count(), 101);
        assert!(frames.lines().next().unwrap().ends_with(
            "contour_mean_px,contour_max_px,still_contour_mean_px,still_contour_max_px"
        ));
        assert!(!frames.contains("NaN"));
        assert!(fs::read_to_string(sim_out.join("snapshots.svg"))
            .unwrap()
            .starts_with("<svg"));
        // The written video reads back through --video.
        let mut v = small_video(MaterialArg::Sponge);
        v.video = Some(sim_out.join("video.csv"));
        let again = load_video(&v, true).unwrap();
        assert_eq!(again.contours_px.len(), 100);

        for (mat, name) in [(MaterialArg::Sponge, "s"), (MaterialArg::Plasticine, "p")] {
            calibrate_cmd(CalibrateArgs {
                video: small_video(mat),
                model: small_model(),
                generations: 2,
                seed: 3,
                score: if name == "s" {
                    ScoreArg::F
                } else {
                    ScoreArg::Contour
                },
                out: dir.join(name),
                json: true,
                resume: None,
                ray: None,
            })
            .unwrap();
            let p = load_params(&dir.join(name).join("params.json")).unwrap();
            p.validate().unwrap();
            assert_eq!(
                fs::read_to_string(dir.join(name).join("generations.csv"))
                    .unwrap()
                    .lines()
                    .count(),
                3
            );
        }
        let models = vec![
            format!("sponge={}", dir.join("s/params.json").display()),
            format!("plasticine={}", dir.join("p/params.json").display()),
        ];
        classify_cmd(ClassifyArgs {
            video: small_video(MaterialArg::Plasticine),
            model: small_model(),
            models: models.clone(),
            score: ScoreArg::F,
            out: dir.join("c"),
            json: true,
        })
        .unwrap();
        assert_eq!(
            fs::read_to_string(dir.join("c/classification.csv"))
                .unwrap()
                .lines()
                .count(),
            101
        );
        // By contour distance: the CSV holds distances per model.
        classify_cmd(ClassifyArgs {
            video: small_video(MaterialArg::Plasticine),
            model: small_model(),
            models,
            score: ScoreArg::Contour,
            out: dir.join("cc"),
            json: true,
        })
        .unwrap();
        let cc = fs::read_to_string(dir.join("cc/classification.csv")).unwrap();
        assert!(cc.starts_with("frame,d_px_sponge,d_px_plasticine,winner"));
        assert_eq!(cc.lines().count(), 101);
        let one = vec![format!("sponge={}", dir.join("s/params.json").display())];
        assert!(classify_cmd(ClassifyArgs {
            video: small_video(MaterialArg::Plasticine),
            model: small_model(),
            models: one,
            score: ScoreArg::F,
            out: dir.join("c"),
            json: true
        })
        .is_err());
        assert!(calibrate_cmd(CalibrateArgs {
            video: small_video(MaterialArg::Sponge),
            model: small_model(),
            generations: 0,
            seed: 3,
            score: ScoreArg::F,
            out: dir.join("z"),
            json: true,
            resume: None,
            ray: None,
        })
        .is_err());
    }
}
