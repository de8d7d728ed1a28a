//! `softjoint rheology`: the rheology lattice of seed 000 (Noborio).
//!
//! * `simulate` — push the lattice (or the reference block that stands in
//!   for the paper's recordings) as a scenario file says; write forces,
//!   surface points, cross-sections and force charts, and score S against
//!   a measured push if one is given;
//! * `calibrate` — learn the lattice's parameters from a measured push (a
//!   directory of CSV files, or a push of the reference block generated on
//!   the spot) by the paper's GA or RA, with a progress bar, and check the
//!   result on a push the calibration did not see; stopped by a signal it
//!   keeps its best and its scores so far, and `--resume` goes on from
//!   them (host_tools::resume); with `--ray ADDRESS` each batch of the
//!   search is scored on a Ray cluster (`ray`: the search, its progress
//!   and its files stay here).
//!
//! The physics lives in `plant_rheology`; this is argument
//! handling, files, pictures and reports.
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use host_tools::files::rheology::ScenarioFile;
use host_tools::output::{self, JsonObject};
use host_tools::plot::{self, Anchor, Chart, Series, Stroke, Svg};
use host_tools::resume::{best_of, fnv1a_hex, Scored, Scores};
use host_tools::stop::{Stop, StopSignal, Stopped};
use host_tools::{out, outln, progress};
use indicatif::ProgressBar;
use plant_rheology::identify::calibrate::{CalibrationSettings, Problem};
use plant_rheology::identify::experiment::{
    self, CalibrationReport, CalibrationSpec, Event, LatticePush, ReferencePush, ScoreSummary,
    UnseenPush,
};
use plant_rheology::identify::measurement::Measurement;
use plant_rheology::identify::reference::ReferenceConfig;
use plant_rheology::identify::search::{BatchObjective, Budget, HistoryRow, Method};
use plant_rheology::lattice::{mid_section, surface_nodes, V3};
use plant_rheology::params::{LatticeParams, ParamSet};
use plant_rheology::scenario::{push_schedule_mm, Frame, ParamsSpec, Run, Scenario};
use plant_rheology::RheologyError;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

mod ray;

/// Arguments of `softjoint rheology`.
#[derive(Args)]
pub struct RheologyArgs {
    #[command(subcommand)]
    command: RheologyCommand,
}

#[derive(Subcommand)]
enum RheologyCommand {
    /// Push the lattice (or the reference block) as the scenario says.
    Simulate(SimulateArgs),
    /// Learn the lattice's parameters from a measured push (GA or RA).
    ///
    /// Ctrl-C, SIGTERM or SIGHUP stops the search between simulations
    /// (exit 130, 143, 129): no result file is written, but the best
    /// candidate so far and every candidate simulated are kept in
    /// OUT/params.search.toml, from which --resume goes on to the result
    /// of the search never stopped.
    Calibrate(CalibrateArgs),
}

#[derive(Clone, Copy, ValueEnum)]
enum ModelArg {
    /// The rheology lattice (the model being calibrated).
    Lattice,
    /// The continuum reference block (the ground truth); writes a
    /// measured push that `calibrate --measured` reads.
    Reference,
}

#[derive(Clone, Copy, ValueEnum)]
enum MethodArg {
    /// The paper's genetic algorithm.
    Ga,
    /// The paper's randomized algorithm (descent and random walks).
    Ra,
    /// Uniform random sampling (a baseline).
    Uniform,
}

impl From<MethodArg> for Method {
    fn from(m: MethodArg) -> Self {
        match m {
            MethodArg::Ga => Method::Ga,
            MethodArg::Ra => Method::Ra,
            MethodArg::Uniform => Method::Uniform,
        }
    }
}

#[derive(Args)]
struct SimulateArgs {
    /// Scenario file (TOML); without it the paper's push of the default
    /// block runs. `--print-default` shows the format.
    scenario: Option<PathBuf>,
    /// What to push.
    #[arg(long, value_enum, default_value = "lattice")]
    model: ModelArg,
    /// Element parameters (TOML with `all`, `surface_on`, `surface_in`,
    /// `core_on`, `core_in` tables, as `calibrate` writes them); they
    /// replace the scenario's `[model.params]`.
    #[arg(long, value_name = "PARAMS.toml")]
    params: Option<PathBuf>,
    /// A measured push to score the lattice against (a directory with
    /// `surface_points.csv` and `forces.csv`).
    #[arg(long, value_name = "DIR")]
    measured: Option<PathBuf>,
    /// Times of the cross-sections (s), comma-separated. Default: 0, the
    /// scenario's frame times.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    section_times: Option<Vec<f64>>,
    /// Output directory.
    #[arg(long, default_value = "rheology-out")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
    /// Print the built-in default scenario as TOML and exit.
    #[arg(long)]
    print_default: bool,
}

#[derive(Args)]
struct CalibrateArgs {
    /// Scenario file (TOML): lattice, push, objective, reference block and
    /// search settings. Default: the paper's push of the default block.
    scenario: Option<PathBuf>,
    /// The measured push (a directory with `surface_points.csv` and
    /// `forces.csv`); without it the reference block is pushed as the
    /// scenario says and its recording is used.
    #[arg(long, value_name = "DIR")]
    measured: Option<PathBuf>,
    /// The search.
    #[arg(long, value_enum, default_value = "ga")]
    method: MethodArg,
    /// Parameters to calibrate: 4 (all elements), 8 (surface/core) or 16
    /// (surface/core × in/on voxel).
    #[arg(long, default_value_t = 4, allow_negative_numbers = true)]
    params: usize,
    /// Budget in simulations (default 1000 when no --seconds is given).
    #[arg(long, allow_negative_numbers = true)]
    evaluations: Option<usize>,
    /// Budget in wall-clock seconds (the paper ran 168 h).
    #[arg(long, allow_negative_numbers = true)]
    seconds: Option<f64>,
    /// Seed of the search.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    seed: u64,
    /// Check the result on a generated push to this depth (mm) that the
    /// calibration did not see.
    #[arg(long, allow_negative_numbers = true)]
    validate_depth_mm: Option<f64>,
    /// … pushed over this time (s) instead of the scenario's 1 s.
    #[arg(long, allow_negative_numbers = true)]
    validate_push_s: Option<f64>,
    /// Output directory.
    #[arg(long, default_value = "rheology-out")]
    out: PathBuf,
    /// Print a machine-readable summary (and no progress bar).
    #[arg(long)]
    json: bool,
    /// Go on with a calibration stopped by a signal (Ctrl-C, SIGTERM,
    /// SIGHUP) from the search state it wrote (OUT/params.search.toml):
    /// the candidates it simulated are not simulated again, and the search
    /// ends where it would have ended unbroken (the same params.toml, and
    /// generations.csv but for its wall-time column). Same
    /// scenario, --measured, --method, --params and --seed; the budget may
    /// be larger (a --seconds budget counts the stopped runs' time). A
    /// calibration stopped again writes its state back to this file.
    #[arg(long, value_name = "STATE")]
    resume: Option<PathBuf>,
    /// Score each batch of the search (a GA generation, RA's probes) on
    /// the Ray cluster at this address, one task per candidate, through
    /// the Python package's driver (`python3 -m softjoint.ray_sweep
    /// rheology-serve`; $SOFTJOINT_PYTHON names another Python). The
    /// search, its progress, a stop's search state and every file are
    /// this program's: the files are those of the same calibration
    /// without --ray, and --resume goes on with or without it. A stop
    /// loses the batch in flight.
    #[arg(long, value_name = "ADDRESS")]
    ray: Option<String>,
}

pub fn run(args: RheologyArgs) -> Result<()> {
    match args.command {
        RheologyCommand::Simulate(a) => simulate_cmd(a),
        RheologyCommand::Calibrate(a) => calibrate_cmd(a),
    }
}

fn simulate_cmd(a: SimulateArgs) -> Result<()> {
    if a.print_default {
        return print_default();
    }
    let mut file = ScenarioFile::load(a.scenario.as_deref())?;
    if let Some(p) = &a.params {
        file.model.params = params_spec(&load_params(p)?);
    }
    let sc = file.scenario();
    sc.validate()?;
    let sections = a.section_times.clone().unwrap_or_else(|| {
        let mut t = vec![0.0];
        t.extend(&sc.measure.frame_times_s);
        t
    });
    check_times("--section-times", &sections, sc.plate.end_s)?;
    if sections.is_empty() || sections.len() > 12 {
        bail!("--section-times: give 1 to 12 times");
    }
    // The folder is checked now and made only when there is something to
    // write in it: a refused scenario leaves no empty folder behind.
    output::check_dir(&a.out)?;
    match a.model {
        ModelArg::Reference => {
            if a.measured.is_some() || a.params.is_some() {
                bail!("--measured and --params apply to the lattice, not to --model reference");
            }
            simulate_reference(&a, &sc, &file.reference, &sections)
        }
        ModelArg::Lattice => simulate_lattice(&a, &sc, &sections),
    }
}

/// `simulate --print-default`: the built-in scenario with the paper's
/// push and parameters written out.
fn print_default() -> Result<()> {
    let mut d = ScenarioFile::default();
    d.plate.depth_mm = Some(push_schedule_mm(15.0, 1.0));
    d.model.params.all = Some(plant_rheology::params::ElementParams::PAPER_DEFAULT);
    out!("{}", toml::to_string(&d)?);
    Ok(())
}

fn simulate_reference(
    a: &SimulateArgs,
    sc: &Scenario,
    cfg: &ReferenceConfig,
    sections: &[f64],
) -> Result<()> {
    let push = experiment::push_reference(sc, cfg, sections)?;
    write_reference(&a.out, sc, &push, sections)?;
    if a.json {
        return JsonObject::of(&push)?.field("out", &a.out)?.print();
    }
    outln!(
        "reference block {}×{}×{} cubes: {} steps, peak force {:.1} N, {} surface points in {} frames",
        push.cells[0],
        push.cells[1],
        push.cells[2],
        push.steps,
        push.peak_force_n,
        push.measurement.point_count(),
        push.measurement.frames.len()
    );
    outln!(
        "wrote forces.csv, surface_points.csv (a measured push for `calibrate --measured`), sections.svg, force.svg to {}",
        a.out.display()
    );
    Ok(())
}

fn simulate_lattice(a: &SimulateArgs, sc: &Scenario, sections: &[f64]) -> Result<()> {
    let measured = a.measured.as_deref().map(load_measurement).transpose()?;
    if let Some(m) = &measured {
        check_times("measured frame", &m.frame_times_s(), sc.plate.end_s)?;
    }
    let push = experiment::push_lattice(sc, measured.as_ref(), sections)
        .map_err(|e| in_scenario(a.scenario.as_deref(), e))?;
    let nodes = push.lattice.nodes;
    let title = format!(
        "lattice {}×{}×{}, model {} ({} volume condition)",
        nodes[0],
        nodes[1],
        nodes[2],
        sc.model.volume.model_number(),
        sc.model.volume.name()
    );
    write_lattice(&a.out, sc, &push, measured.as_ref(), sections, &title)?;
    if a.json {
        JsonObject::of(&push)?.field("out", &a.out)?.print()?;
    } else {
        outln!("{title}: {} steps in {:.2} s", push.steps, push.wall_s);
        if let Some(e) = &push.instability {
            outln!("UNSTABLE: {e}; the files stop there");
        }
        outln!(
            "peak force {:.1} N, volume at the end {:.2} % of rest",
            push.peak_force_n,
            100.0 * push.final_volume_ratio.unwrap_or(f64::NAN)
        );
        if let Some(s) = &push.score {
            outln!("{}", score_text(s));
        }
        outln!(
            "wrote forces.csv, surface_points.csv, sections.svg, force.svg to {}",
            a.out.display()
        );
    }
    if let Some(e) = &push.run.instability {
        return Err(anyhow::anyhow!("the lattice became {e}"));
    }
    Ok(())
}

/// The files `calibrate` writes in its output directory.
const CALIBRATION_FILES: [&str; 5] = [
    "params.toml",
    "generations.csv",
    "s_per_generation.svg",
    "force.svg",
    "sections.svg",
];

/// Where a stopped calibration writes its search state, in its output
/// directory (`params.toml` → `params.search.toml`, as `tune` does).
const STATE_FILE: &str = "params.search.toml";

fn calibrate_cmd(a: CalibrateArgs) -> Result<()> {
    // A signal stops the search at its next simulation (one that comes
    // while the measurement is made stops it before the first).
    let stop = Stop::on_signals()?;
    // Every file the calibration writes, and the search state a stop
    // writes, can be written: checked before the search, not after it.
    output::check_files_in(&a.out, &CALIBRATION_FILES)?;
    let state_path = a.state_path();
    if a.resume.is_some() || a.out.is_dir() {
        output::check_file(&state_path)?;
    }
    let file = ScenarioFile::load(a.scenario.as_deref())?;
    let scenario = file.scenario();
    let set = ParamSet::from_count(a.params).map_err(|e| anyhow::anyhow!("--params: {e}"))?;
    let mut budget = budget(&a)?;
    let unseen = unseen_push(&a, &scenario)?;
    let measured = a.measured.as_deref().map(load_measurement).transpose()?;
    let fingerprint = problem_fingerprint(&a, &file)?;
    let Resumed {
        scored: resumed,
        seconds_spent: seconds_before,
        evaluations: evaluations_before,
    } = a.resumed(&fingerprint)?;
    if let Some(s) = &mut budget.max_seconds {
        // The wall-time budget is the whole search's, stopped runs too.
        *s = (*s - seconds_before).max(1e-9);
    }
    let mut settings = CalibrationSettings::new(a.method.into(), budget, a.seed);
    settings.ga = file.ga;
    settings.ra = file.ra;
    let spec = CalibrationSpec {
        scenario,
        reference: file.reference,
        measured,
        set,
        settings,
        unseen,
    };
    let mut watch = Watch {
        prefix: format!("{} ({} params)", settings.method.name(), set.len()),
        simulations: budget.max_evaluations.map(|n| n as u64),
        json: a.json,
        counter: None,
    };
    let scores = Scores::new(stop.clone(), resumed);
    // Started before the problem is built: it joins the cluster meanwhile.
    let driver = a.ray.as_deref().map(|address| {
        let (cmd, who) = ray::driver_command(&ray::Problem {
            scenario: a.scenario.as_deref(),
            measured: a.measured.as_deref(),
            params: a.params,
            address,
        });
        // The search counts any non-finite S as +∞.
        ray::Driver::start(cmd, who, stop.clone(), f64::INFINITY)
    });
    let driver = driver.transpose()?;
    let problem = experiment::calibration_problem(&spec, &mut |e| watch.event(e))
        .map_err(|e| in_scenario(a.scenario.as_deref(), e))?;
    let started = std::time::Instant::now();
    let result = search(&spec, &problem, &scores, driver, &mut watch);
    let report = match (result, stop.requested()) {
        (Ok(report), _) => report,
        (Err(_), Some(signal)) => {
            let state = CalibrationState {
                scenario: scenario_name(&a),
                problem_fnv1a: fingerprint,
                method: settings.method,
                params: set.len(),
                seed: a.seed,
                seconds_spent: seconds_before + started.elapsed().as_secs_f64(),
                // A resumed search stopped while retracing is no
                // further on than the search it resumed.
                evaluations: scores.answered().max(evaluations_before),
                best: None,
                scored: scores.into_scored(),
            }
            .with_best(set)?;
            return Err(stopped(&a, signal, &state_path, &state));
        }
        (Err(e), None) => return Err(e.into()),
    };
    write_calibration(&a.out, &spec, &report)?;
    if a.json {
        let mut j = JsonObject::of(&report)?.field("out", &a.out)?;
        if let Some(r) = &a.resume {
            #[derive(Serialize)]
            struct Resumed<'a> {
                from: &'a Path,
                candidates_taken: usize,
                simulated: usize,
            }
            j = j.field(
                "resumed",
                &Resumed {
                    from: r,
                    candidates_taken: scores.replayed(),
                    simulated: scores.simulated(),
                },
            )?;
        }
        j.print()?;
    } else {
        calibration_text(&a, set, &report, &scores)?;
    }
    // The search had ended when a signal came: its files are whole.
    host_tools::resume::finished_or_stopped(&stop, &a.out)
}

/// The search on `problem`, each batch scored on this process's threads,
/// or by `driver` on a Ray cluster; the scores kept in `scores` either way.
fn search(
    spec: &CalibrationSpec,
    problem: &Problem,
    scores: &Scores,
    driver: Option<ray::Driver>,
    watch: &mut Watch,
) -> plant_rheology::Result<CalibrationReport> {
    let f = |g: &[f64]| problem.s_of_genes(g);
    let mut local;
    let mut on_ray;
    let objective: &mut dyn BatchObjective = match driver {
        Some(driver) => {
            on_ray = ray::OnRay { driver, scores };
            &mut on_ray
        }
        None => {
            local = Resumable { f: &f, scores };
            &mut local
        }
    };
    let result =
        experiment::calibrate_problem(spec, problem.clone(), objective, &mut |e| watch.event(e));
    watch.finish();
    result
}

/// The calibration's report for a person.
fn calibration_text(
    a: &CalibrateArgs,
    set: ParamSet,
    report: &CalibrationReport,
    scores: &Scores,
) -> Result<()> {
    outln!(
        "{} on {} parameters: {} simulations in {:.1} s ({} unstable), stopped by {}",
        report.method.name(),
        report.params,
        report.evaluations,
        report.elapsed_s,
        report.unstable,
        report.stopped_by
    );
    if let Some(r) = &a.resume {
        outln!("{}", scores.resumed_line(r));
    }
    outln!("defaults:   {}", score_text(&report.default));
    outln!("calibrated: {}", score_text(&report.calibrated));
    for (r, g) in set.ranges().iter().zip(&report.search.best_genes) {
        outln!("  {:<28} {:>12.4}   (range {}–{})", r.name, g, r.min, r.max);
    }
    if let Some(v) = &report.validation {
        outln!("unseen push ({} mm over {} s):", v.depth_mm, v.push_s);
        outln!("  defaults:   {}", score_text(&v.default));
        outln!("  calibrated: {}", score_text(&v.calibrated));
    }
    outln!(
        "wrote params.toml, generations.csv, s_per_generation.svg, force.svg, sections.svg to {}",
        a.out.display()
    );
    Ok(())
}

/// The search's objective with its scores kept ([`Scores`]): a candidate
/// scored before (a resumed search) is not simulated again, and none is
/// simulated once a signal asks the search to stop (the batch then fails,
/// which ends the search).
struct Resumable<'a, F> {
    f: &'a F,
    scores: &'a Scores,
}

impl<F: Fn(&[f64]) -> f64 + Sync> BatchObjective for Resumable<'_, F> {
    fn scores(&mut self, batch: &[Vec<f64>]) -> std::result::Result<Vec<f64>, String> {
        let f = self.f;
        let got: Vec<Option<f64>> = batch.par_iter().map(|g| self.scores.score(g, f)).collect();
        got.into_iter()
            .collect::<Option<Vec<f64>>>()
            .ok_or_else(|| "stopped by a signal".into())
    }
}

/// A calibration stopped by a signal: what it had simulated, to resume
/// from (`--resume`), and the best candidate so far.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CalibrationState {
    /// The scenario file searched on (or the built-in scenario).
    scenario: String,
    /// FNV-1a of the problem: the scenario as read (its defaults filled
    /// in), the measured push's files, the parameter count.
    problem_fnv1a: String,
    method: Method,
    params: usize,
    seed: u64,
    /// Wall time the stopped runs spent (s), for a --seconds budget.
    seconds_spent: f64,
    /// Candidates the search had been given scores for (one asked twice
    /// counts twice, is simulated once): its evaluations so far.
    evaluations: usize,
    /// The best candidate so far (absent if none was stable).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    best: Option<BestSoFar>,
    /// Every candidate simulated, in the order they came in (genes in the
    /// units of the parameter ranges; score S absent when unstable).
    #[serde(default)]
    scored: Vec<Scored>,
}

/// The best candidate of a stopped calibration.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct BestSoFar {
    /// Its S.
    s: f64,
    /// Its parameters, as `params.toml` holds them.
    params: ParamsSpec,
}

impl CalibrationState {
    /// The state with its best candidate filled in.
    fn with_best(mut self, set: ParamSet) -> Result<Self> {
        self.best = match best_of(&self.scored, |a, b| a < b) {
            Some(b) => Some(BestSoFar {
                s: b.score.unwrap_or(f64::INFINITY),
                params: params_spec(&set.to_lattice(&b.genes)?),
            }),
            None => None,
        };
        Ok(self)
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

    /// What the calibration resumed kept, checked against this one.
    fn resumed(&self, fingerprint: &str) -> Result<Resumed> {
        let Some(path) = &self.resume else {
            return Ok(Resumed {
                scored: Vec::new(),
                seconds_spent: 0.0,
                evaluations: 0,
            });
        };
        let text = fs::read_to_string(path)
            .with_context(|| format!("cannot read --resume {}", path.display()))?;
        let st: CalibrationState =
            host_tools::input::from_toml(&text, &path.display().to_string())?;
        let refuse = |why: String| anyhow::anyhow!("--resume {}: {why}", path.display());
        if st.problem_fnv1a != fingerprint {
            return Err(refuse(format!(
                "it is a calibration of another problem (scenario, --measured or --params differ from {}'s, or a file changed since)",
                st.scenario
            )));
        }
        let method: Method = self.method.into();
        if st.method != method {
            return Err(refuse(format!(
                "it is a calibration with --method {}, this one asks {}",
                st.method.name(),
                method.name()
            )));
        }
        if st.seed != self.seed {
            return Err(refuse(format!(
                "it is a calibration with --seed {}, this one asks {}",
                st.seed, self.seed
            )));
        }
        if !(st.seconds_spent.is_finite() && st.seconds_spent >= 0.0) {
            return Err(refuse("`seconds_spent` must be a time ≥ 0".into()));
        }
        Ok(Resumed {
            scored: st.scored,
            seconds_spent: st.seconds_spent,
            evaluations: st.evaluations,
        })
    }
}

/// What a resumed calibration takes from the state it resumes.
struct Resumed {
    scored: Vec<Scored>,
    seconds_spent: f64,
    evaluations: usize,
}

/// An error of the rheology model, with the scenario file named in front
/// when it is about one of its `[objective]` weights (refused only once
/// the measured push is known, after the file was read).
fn in_scenario(scenario: Option<&Path>, e: RheologyError) -> anyhow::Error {
    let objective = matches!(
        &e,
        RheologyError::InvalidParameter { name, .. } | RheologyError::InvalidSetting { name, .. }
            if name.starts_with("objective")
    );
    match scenario {
        Some(p) if objective => anyhow::Error::new(e).context(p.display().to_string()),
        _ => e.into(),
    }
}

/// The scenario's name for the state file.
fn scenario_name(a: &CalibrateArgs) -> String {
    match &a.scenario {
        Some(p) => p.display().to_string(),
        None => "(the built-in scenario)".into(),
    }
}

/// FNV-1a of what the search's scores depend on: the scenario as read
/// (defaults filled in), the measured push's files and the parameter
/// count.
fn problem_fingerprint(a: &CalibrateArgs, file: &ScenarioFile) -> Result<String> {
    let mut bytes = toml::to_string(file)?.into_bytes();
    bytes.extend(format!("\nparams = {}\n", a.params).as_bytes());
    if let Some(dir) = &a.measured {
        for name in ["surface_points.csv", "forces.csv"] {
            let p = dir.join(name);
            bytes.extend(fs::read(&p).with_context(|| format!("cannot read {}", p.display()))?);
        }
    }
    Ok(fnv1a_hex(&bytes))
}

/// Writes a stopped calibration's state and says what it kept, as the
/// error the program exits with (130, 143, 129); no result file is
/// written (the search did not finish).
fn stopped(
    a: &CalibrateArgs,
    signal: StopSignal,
    path: &Path,
    state: &CalibrationState,
) -> anyhow::Error {
    if let Err(e) = output::create_dir(&a.out).and_then(|()| {
        output::write_toml(
            path,
            "# Written by `softjoint rheology calibrate` when stopped: the candidates simulated so far\n# and the best of them. `softjoint rheology calibrate … --resume THIS_FILE` goes on from here.\n",
            state,
        )
    }) {
        return e.context(format!(
            "stopped by {}; the search state was lost",
            signal.name()
        ));
    }
    let best = match &state.best {
        Some(b) => format!("best so far S = {:.3}", b.s),
        None => "no stable candidate yet".into(),
    };
    let scenario = a
        .scenario
        .as_ref()
        .map(|p| format!(" {}", p.display()))
        .unwrap_or_default();
    Stopped {
        signal,
        what: format!(
            "{} evaluations ({} candidates simulated), {best}; search state in {} (`softjoint rheology calibrate{scenario} … --resume {}` with the same options goes on from there); params.toml and the other result files not written",
            state.evaluations,
            state.scored.len(),
            path.display(),
            path.display(),
        ),
    }
    .into()
}

/// The search's budget from `--evaluations` and `--seconds` (1000
/// simulations when neither is given).
fn budget(a: &CalibrateArgs) -> Result<Budget> {
    if let Some(n) = a.evaluations {
        if n == 0 || n > 10_000_000 {
            bail!("--evaluations must be 1..=10000000, got {n}");
        }
    }
    if let Some(s) = a.seconds {
        if !(s.is_finite() && s > 0.0) {
            bail!("--seconds must be a number of seconds > 0, got {s}");
        }
    }
    Ok(Budget {
        max_evaluations: a.evaluations.or(if a.seconds.is_none() {
            Some(1000)
        } else {
            None
        }),
        max_seconds: a.seconds,
    })
}

/// The push to check the result on, from `--validate-depth-mm` and
/// `--validate-push-s` (15 mm over 1 s for the one not given).
fn unseen_push(a: &CalibrateArgs, sc: &Scenario) -> Result<Option<UnseenPush>> {
    if a.measured.is_some() && (a.validate_depth_mm.is_some() || a.validate_push_s.is_some()) {
        bail!("--validate-depth-mm/--validate-push-s push the reference block; they need a generated measurement (no --measured)");
    }
    if a.validate_depth_mm.is_none() && a.validate_push_s.is_none() {
        return Ok(None);
    }
    let depth = a.validate_depth_mm.unwrap_or(15.0);
    let push = a.validate_push_s.unwrap_or(1.0);
    if !(depth > 0.0 && depth < sc.block.size_cm[1] * 10.0) {
        bail!("--validate-depth-mm must be between 0 and the block's height, got {depth}");
    }
    if !(push > 0.0 && 4.0 * push <= sc.plate.end_s) {
        bail!(
            "--validate-push-s must be > 0 with the push, hold and release (4× it) inside plate.end_s = {} s, got {push}",
            sc.plate.end_s
        );
    }
    Ok(Some(UnseenPush {
        depth_mm: depth,
        push_s: push,
    }))
}

/// The calibration's progress on stderr: a note for each push of the
/// reference block, a counter of simulations during the search.
struct Watch {
    prefix: String,
    /// The budget in simulations, if it has one.
    simulations: Option<u64>,
    json: bool,
    counter: Option<ProgressBar>,
}

impl Watch {
    fn event(&mut self, e: Event) {
        match e {
            Event::Phase(what) => {
                self.finish();
                progress::note(what, self.json);
            }
            Event::Search(p) => {
                let counter = self.counter.get_or_insert_with(|| {
                    progress::counter(&self.prefix, "simulations", self.simulations, self.json)
                });
                counter.set_position(p.evaluations as u64);
                counter.set_message(format!("best S {:.2}", p.best_s));
            }
        }
    }

    fn finish(&mut self) {
        if let Some(counter) = self.counter.take() {
            counter.finish_and_clear();
        }
    }
}

/// Writes a CSV or SVG result through the checked writer (no non-finite
/// number, atomic).
fn write(path: &Path, text: &str) -> Result<()> {
    if path.extension().is_some_and(|e| e == "csv") {
        output::write_csv(path, text)
    } else {
        output::write_svg(path, text)
    }
}

fn load_params(path: &Path) -> Result<LatticeParams> {
    let text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let spec: ParamsSpec = toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().trim_end()))?;
    spec.resolve()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

fn params_spec(p: &LatticeParams) -> ParamsSpec {
    ParamsSpec {
        all: None,
        surface_on: Some(p.surface_on),
        surface_in: Some(p.surface_in),
        core_on: Some(p.core_on),
        core_in: Some(p.core_in),
    }
}

fn load_measurement(dir: &Path) -> Result<Measurement> {
    let (p, f) = (dir.join("surface_points.csv"), dir.join("forces.csv"));
    let pt = fs::read_to_string(&p).with_context(|| format!("cannot read {}", p.display()))?;
    let ft = fs::read_to_string(&f).with_context(|| format!("cannot read {}", f.display()))?;
    Ok(Measurement::from_csv(
        &pt,
        &p.display().to_string(),
        &ft,
        &f.display().to_string(),
    )?)
}

fn check_times(name: &str, times: &[f64], end_s: f64) -> Result<()> {
    for t in times {
        if !(t.is_finite() && *t >= 0.0 && *t <= end_s) {
            bail!("{name}: {t} s is outside the run (0–{end_s} s)");
        }
    }
    Ok(())
}

/// The reference push's files: forces.csv, surface_points.csv,
/// sections.svg, force.svg.
fn write_reference(
    out: &Path,
    sc: &Scenario,
    push: &ReferencePush,
    sections: &[f64],
) -> Result<()> {
    output::create_dir(out)?;
    let r = &push.run;
    write(
        &out.join("forces.csv"),
        &forces_csv(&r.t_s, &push.depth_m, &push.force_n, &r.volume_m3),
    )?;
    write(
        &out.join("surface_points.csv"),
        &push.measurement.points_csv(),
    )?;
    let shots = section_shots(&r.frames, r.nodes, Some(sections));
    let svg = sections_svg(
        sc,
        r.nodes,
        &shots,
        Some(&r.measurement),
        "reference block (continuum FEM, hidden material)",
    );
    write(&out.join("sections.svg"), &svg)?;
    let volume: Vec<f64> = r.volume_m3.iter().map(|v| v / r.volume0_m3).collect();
    let chart = force_chart(
        "Reference block: plate force (as measured, with sensor noise)",
        &[("reference, measured", "#555", false, &r.t_s, &push.force_n)],
        &[("reference", "#555", &r.t_s, &volume)],
    );
    write(&out.join("force.svg"), &chart)
}

/// The lattice push's files: forces.csv, surface_points.csv,
/// sections.svg, force.svg.
fn write_lattice(
    out: &Path,
    sc: &Scenario,
    push: &LatticePush,
    measured: Option<&Measurement>,
    sections: &[f64],
    title: &str,
) -> Result<()> {
    output::create_dir(out)?;
    let r = &push.run;
    write(
        &out.join("forces.csv"),
        &forces_csv(&r.t_s, &r.plate_depth_m, &r.plate_force_n, &r.volume_m3),
    )?;
    write(
        &out.join("surface_points.csv"),
        &lattice_points_csv(sc, push),
    )?;
    let nodes = push.lattice.nodes;
    let shots = section_shots(&r.frames, nodes, Some(sections));
    write(
        &out.join("sections.svg"),
        &sections_svg(sc, nodes, &shots, measured, title),
    )?;
    let mt: Vec<f64>;
    let mf: Vec<f64>;
    let mut series: Vec<ForceSeries> =
        vec![("lattice", "#1f5fbf", false, &r.t_s, &r.plate_force_n)];
    if let Some(m) = measured {
        mt = m.forces.iter().map(|f| f.t_s).collect();
        mf = m.forces.iter().map(|f| f.force_n).collect();
        series.insert(0, ("measured", "#555", false, &mt, &mf));
    }
    write(
        &out.join("force.svg"),
        &force_chart(
            &format!("Plate force: {title}"),
            &series,
            &[("lattice", "#1f5fbf", &r.t_s, &push.volume_ratio)],
        ),
    )
}

/// The lattice's own surface masses at the scenario's frames, in the
/// measurement format (a twin experiment can calibrate against them).
fn lattice_points_csv(sc: &Scenario, push: &LatticePush) -> String {
    let nodes = surface_nodes(&push.lattice.surface);
    let mut pts = String::from("frame,time_s,x_cm,y_cm,z_cm\n");
    let mut k = 0;
    for f in &push.run.frames {
        if sc.measure.frame_times_s.contains(&f.t_s) {
            for &n in &nodes {
                let p = f.positions_m[n] * 100.0;
                let _ = writeln!(pts, "{k},{},{:.5},{:.5},{:.5}", f.t_s, p.x, p.y, p.z);
            }
            k += 1;
        }
    }
    pts
}

/// The calibration's files: params.toml, generations.csv,
/// s_per_generation.svg, force.svg, sections.svg.
fn write_calibration(out: &Path, spec: &CalibrationSpec, report: &CalibrationReport) -> Result<()> {
    output::create_dir(out)?;
    output::write_toml(
        &out.join("params.toml"),
        "# Calibrated rheology parameters (softjoint rheology calibrate); `simulate --params` reads them.\n",
        &params_spec(&report.best_params),
    )?;
    write(
        &out.join("generations.csv"),
        &generations_csv(&report.search.history),
    )?;
    write(
        &out.join("s_per_generation.svg"),
        &s_chart(
            &report.search.history,
            &format!(
                "S per generation: {} on {} parameters ({} simulations)",
                report.method.name(),
                report.params,
                report.evaluations
            ),
        ),
    )?;
    write(&out.join("force.svg"), &calibration_force_chart(report))?;
    let problem = &report.problem;
    let shots = section_shots(&report.calibrated_run.frames, problem.lattice().nodes, None);
    write(
        &out.join("sections.svg"),
        &sections_svg(
            &spec.scenario,
            problem.lattice().nodes,
            &shots,
            Some(&problem.measurement),
            "calibrated lattice and the measured points",
        ),
    )
}

/// `generations.csv`: one row per generation (or RA cycle).
fn generations_csv(history: &[HistoryRow]) -> String {
    let mut csv =
        String::from("generation,evaluations,best_s,batch_best_s,batch_mean_s,elapsed_s\n");
    for h in history {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{:.3}",
            h.generation,
            h.evaluations,
            csv_number(h.best_s),
            csv_number(h.batch_best_s),
            csv_number(h.batch_mean_s),
            h.elapsed_s
        );
    }
    csv
}

/// The calibration's `force.svg`: the measured force, the lattice with
/// the defaults and calibrated.
fn calibration_force_chart(report: &CalibrationReport) -> String {
    let forces = &report.problem.measurement.forces;
    let mt: Vec<f64> = forces.iter().map(|f| f.t_s).collect();
    let mf: Vec<f64> = forces.iter().map(|f| f.force_n).collect();
    let (dr, br) = (&report.default_run, &report.calibrated_run);
    let vol = |r: &Run| -> Vec<f64> { r.volume_m3.iter().map(|v| v / r.volume0_m3).collect() };
    let (vd, vb) = (vol(dr), vol(br));
    force_chart(
        "Plate force: measured, lattice with the defaults, calibrated lattice",
        &[
            ("measured", "#555", false, &mt, &mf),
            ("defaults", "#e80", true, &dr.t_s, &dr.plate_force_n),
            ("calibrated", "#1f5fbf", false, &br.t_s, &br.plate_force_n),
        ],
        &[
            ("defaults", "#e80", &dr.t_s, &vd),
            ("calibrated", "#1f5fbf", &br.t_s, &vb),
        ],
    )
}

/// `forces.csv`: one row per step.
fn forces_csv(t: &[f64], depth_m: &[f64], force_n: &[f64], volume_m3: &[f64]) -> String {
    let mut s = String::from("time_s,depth_mm,force_n,volume_cm3\n");
    for k in 0..t.len() {
        let _ = writeln!(
            s,
            "{:.6},{:.4},{:.4},{:.4}",
            t[k],
            depth_m[k] * 1e3,
            force_n[k],
            volume_m3[k] * 1e6
        );
    }
    s
}

fn score_text(s: &ScoreSummary) -> String {
    let Some(total) = s.s else {
        return "S = ∞ (the run was unstable)".into();
    };
    let mut t = format!("S = {total:.2}");
    if s.points > 0 {
        let _ = write!(
            t,
            "; shape: {:.2} cm over {} points ({:.3} mm each)",
            s.shape_cm, s.points, s.mean_distance_mm
        );
    }
    if s.force_samples > 0 {
        let _ = write!(
            t,
            "; force: {:.1} N over {} samples ({:.2} N each)",
            s.force_n, s.force_samples, s.mean_force_error_n
        );
    }
    t
}

/// A force curve: label, colour, dashed, times (s), forces (N).
type ForceSeries<'a> = (&'a str, &'static str, bool, &'a [f64], &'a [f64]);

/// Force (and volume) against time.
fn force_chart(
    title: &str,
    force: &[ForceSeries],
    volume: &[(&str, &'static str, &[f64], &[f64])],
) -> String {
    plot::line_charts(&[
        Chart {
            title: title.into(),
            x_label: "time (s)".into(),
            y_label: "plate force (N)".into(),
            series: force
                .iter()
                .map(|(l, c, d, t, f)| Series::over(*l, c, *d, t, f))
                .collect(),
        },
        Chart {
            title: "Volume (enclosed by the surface)".into(),
            x_label: "time (s)".into(),
            y_label: "V / V0".into(),
            series: volume
                .iter()
                .map(|(l, c, t, v)| Series::over(*l, c, false, t, v))
                .collect(),
        },
    ])
    .finish()
}

/// The mid-depth section of the block at every recorded frame, or at each
/// of `times` in their order (a time without a recorded frame is left
/// out).
fn section_shots(
    frames: &[Frame],
    nodes: [usize; 3],
    times: Option<&[f64]>,
) -> Vec<(f64, Vec<V3>)> {
    let shot = |f: &Frame| (f.t_s, mid_section(nodes, &f.positions_m));
    match times {
        Some(ts) => ts
            .iter()
            .filter_map(|&t| frames.iter().find(|f| f.t_s == t).map(shot))
            .collect(),
        None => frames.iter().map(shot).collect(),
    }
}

/// Cross-sections through the middle of the block (x–y plane at mid z):
/// the grid of the section (blue), the rest outline (dashed), measured
/// points within 5 mm of the plane (dots), the plate (red), the table.
fn sections_svg(
    sc: &Scenario,
    nodes: [usize; 3],
    shots: &[(f64, Vec<V3>)],
    measured: Option<&Measurement>,
    title: &str,
) -> String {
    let size = sc.size_m();
    let panel_w = 260.0;
    let margin_m = 0.2 * size[0];
    let scale = panel_w / (size[0] + 2.0 * margin_m);
    let panel_h = (size[1] * 1.35 + margin_m) * scale;
    let top = 44.0;
    let cols = shots.len().clamp(1, 4);
    let rows = shots.len().div_ceil(cols).max(1);
    let width = cols as f64 * (panel_w + 12.0) + 12.0;
    let height = top + rows as f64 * (panel_h + 34.0) + 24.0;
    let mut svg = Svg::new(width, height);
    svg.text_styled(
        12.0,
        20.0,
        14.0,
        Anchor::Start,
        r#"font-weight="bold""#,
        &format!("Cross-sections at mid-depth: {title}"),
    );
    let page = SectionPage {
        sc,
        plate: sc.plate().ok(),
        nodes,
        measured,
        panel_w,
        panel_h,
        margin_m,
        scale,
    };
    for (k, (t, sec)) in shots.iter().enumerate() {
        let ox = 12.0 + (k % cols) as f64 * (panel_w + 12.0);
        let oy = top + (k / cols) as f64 * (panel_h + 34.0);
        section_panel(&mut svg, &page, (ox, oy), *t, sec);
    }
    svg.text_styled(
        12.0,
        height - 8.0,
        11.0,
        Anchor::Start,
        r##"fill="#555""##,
        "blue: section of the block · dashed: at rest · dots: measured points within 5 mm of the plane · red: plate · brown: table",
    );
    svg.finish()
}

/// What every cross-section panel shares: the scenario and its plate, the
/// grid, the measured points, the panels' size (page units), the margin
/// beside the block (m) and the scale (page units per m).
struct SectionPage<'a> {
    sc: &'a Scenario,
    plate: Option<plant_rheology::contact::Plate>,
    nodes: [usize; 3],
    measured: Option<&'a Measurement>,
    panel_w: f64,
    panel_h: f64,
    margin_m: f64,
    scale: f64,
}

/// One cross-section panel at `(ox, oy)`: the section `sec` at time `t`.
fn section_panel(svg: &mut Svg, page: &SectionPage, (ox, oy): (f64, f64), t: f64, sec: &[V3]) {
    let size = page.sc.size_m();
    let (nx, ny) = (page.nodes[0], page.nodes[1]);
    let (panel_w, panel_h, scale) = (page.panel_w, page.panel_h, page.scale);
    let floor = oy + panel_h - 6.0;
    let tx = |p: V3| (ox + (p.x + page.margin_m) * scale, floor - p.y * scale);
    svg.rect(
        ox,
        oy,
        panel_w,
        panel_h,
        "none",
        Some(Stroke::solid("#ddd", 1.0)),
    );
    svg.line(
        (ox, floor),
        (ox + panel_w, floor),
        Stroke::solid("#964", 2.0),
    );
    // Rest outline.
    let rest = [
        V3::new(0.0, 0.0, 0.0),
        V3::new(size[0], 0.0, 0.0),
        V3::new(size[0], size[1], 0.0),
        V3::new(0.0, size[1], 0.0),
        V3::new(0.0, 0.0, 0.0),
    ];
    svg.polyline(rest.iter().map(|p| tx(*p)), Stroke::dashed("#999", 1.0));
    // The section's grid lines.
    let at = |i: usize, j: usize| tx(sec[i + nx * j]);
    let mut segs = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if i + 1 < nx {
                segs.push((at(i, j), at(i + 1, j)));
            }
            if j + 1 < ny {
                segs.push((at(i, j), at(i, j + 1)));
            }
        }
    }
    svg.segments(segs, Stroke::solid("#1f5fbf", 1.0));
    // Measured points near the plane at this time.
    let zmid = size[2] / 2.0;
    if let Some(m) = page.measured {
        if let Some(f) = m.frames.iter().find(|f| (f.t_s - t).abs() < 1e-9) {
            for p in f.points_m.iter().filter(|p| (p.z - zmid).abs() < 0.005) {
                let (x, y) = tx(*p);
                svg.rect(x - 1.5, y - 1.5, 3.0, 3.0, "#222", None);
            }
        }
    }
    // The plate.
    if let Some(pl) = &page.plate {
        if let Some(face) = pl.face_y_m(t) {
            let (x0, y0) = tx(V3::new(
                pl.centre_xz_m[0] - pl.footprint_m[0] / 2.0,
                face,
                0.0,
            ));
            let (x1, _) = tx(V3::new(
                pl.centre_xz_m[0] + pl.footprint_m[0] / 2.0,
                face,
                0.0,
            ));
            let (x0, x1) = (x0.max(ox), x1.min(ox + panel_w));
            svg.rect(
                x0,
                (y0 - 14.0).max(oy),
                x1 - x0,
                (y0 - oy).clamp(0.0, 14.0),
                "#f3c6c6",
                Some(Stroke::solid("#d22", 1.5)),
            );
        }
    }
    svg.text(
        ox + 4.0,
        oy + panel_h + 16.0,
        12.0,
        Anchor::Start,
        &format!("t = {t} s"),
    );
}

fn s_chart(rows: &[HistoryRow], title: &str) -> String {
    let e: Vec<f64> = rows.iter().map(|h| h.evaluations as f64).collect();
    let best: Vec<f64> = rows.iter().map(|h| h.best_s).collect();
    let batch: Vec<f64> = rows.iter().map(|h| h.batch_mean_s).collect();
    plot::line_charts(&[Chart {
        title: title.into(),
        x_label: "simulations run".into(),
        y_label: "S (cm)".into(),
        series: vec![
            Series::over("best so far", "#1f5fbf", false, &e, &best),
            Series::over("batch mean", "#e80", true, &e, &batch),
        ],
    }])
    .finish()
}

/// A number for a CSV cell; empty when not finite (no candidate of the
/// batch was stable).
fn csv_number(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.4}")
    } else {
        String::new()
    }
}
