//! `softjoint sim`: the joint under the firmware core in process, an
//! excitation session on it, or a calibration sweep of it.
use std::path::PathBuf;

use clap::Args;
use host_tools::files::scenario::Scenario;
use host_tools::joint::excite::{self, LogFile, SessionSummary};
use host_tools::run::joint::JointSpec;
use host_tools::run::spec::RunSpec;
use host_tools::run::summary::RunCutShort;
use host_tools::run::sweep::calibration_sweep;
use host_tools::run::{report, sim};
use host_tools::stop::{Stop, Stopped};
use host_tools::{out, outln, output};

#[derive(Args)]
pub struct SimArgs {
    /// Scenario file (TOML); without it the built-in default runs.
    scenario: Option<PathBuf>,
    #[command(flatten)]
    output: report::OutputArgs,
    /// Instead of a control run, write a calibration sweep of the simulated
    /// joint (slow ±20° sweep, camera reference) to this CSV. There is no
    /// control run, so --csv, --plot and --json cannot go with it.
    #[arg(long, value_name = "PATH", conflicts_with_all = ["csv", "plot", "json", "excite"])]
    calibration_sweep: Option<PathBuf>,
    /// Print the built-in default scenario as TOML and exit (nothing else
    /// runs, so it takes no other argument).
    #[arg(long, conflicts_with_all = ["scenario", "csv", "plot", "json", "calibration_sweep", "excite"])]
    print_default: bool,
    #[command(flatten)]
    excite: ExciteArgs,
}

/// An excitation session instead of the scenario's targets (`sim`, `hil`).
#[derive(Args)]
pub struct ExciteArgs {
    /// Run this excitation plan (TOML; `softjoint identify plan` prints
    /// one) on the scenario's joint and write its log to --log. There is
    /// no control run, so --csv, --plot and --json cannot go with it.
    #[arg(long, value_name = "PLAN", requires = "log", conflicts_with_all = ["csv", "plot", "json"])]
    pub excite: Option<PathBuf>,
    /// Where --excite writes its log (CSV), for `softjoint identify joint`.
    #[arg(long, value_name = "PATH", requires = "excite")]
    pub log: Option<PathBuf>,
    /// Log no coil currents and resistances (a lab without a current
    /// sense): identification then fits the thermal parameters from the
    /// angle alone.
    #[arg(long, requires = "excite")]
    pub no_electrical: bool,
}

impl ExciteArgs {
    /// Loads the plan for a scenario's joint.
    pub fn plan(
        &self,
        scenario: &Scenario,
    ) -> anyhow::Result<Option<plant_joint::identify::ExcitationPlan>> {
        self.excite
            .as_ref()
            .map(|p| host_tools::joint::excite::load_plan(p, scenario.planes()))
            .transpose()
    }

    /// Creates the log file (`planes` angles) before the session, so a
    /// path that cannot be written is refused before any work.
    pub fn open_log(&self, planes: usize) -> anyhow::Result<LogFile> {
        let path = self
            .log
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("--excite needs --log"))?;
        LogFile::create(path, planes, !self.no_electrical)
    }

    /// Ends the session's log: writes its last rows and prints what the
    /// session saw; a session stopped by a signal (its rows up to there in
    /// the log) or one that failed (the rows before the failure kept) is
    /// an error that says how many rows the log holds.
    pub fn finish(
        &self,
        log: LogFile,
        session: anyhow::Result<SessionSummary>,
    ) -> anyhow::Result<()> {
        let path = log.path().to_path_buf();
        let written = log.finish();
        let summary = match session {
            Ok(s) => s,
            Err(e) => {
                let kept = match written {
                    Ok(rows) => format!("the log {} holds its first {rows} rows", path.display()),
                    Err(w) => format!("{w:#}"),
                };
                return Err(e.context(kept));
            }
        };
        let rows = written?;
        if let Some(signal) = summary.stopped_by {
            return Err(Stopped {
                signal,
                what: format!(
                    "{} stopped at t = {:.2} s of {} s; the log {} holds its {rows} rows up to there",
                    summary.plan,
                    summary.duration_s,
                    plant_common::short_number(summary.planned_s),
                    path.display()
                ),
            }
            .into());
        }
        outln!(
            "{}: {} rows ({} s) written to {}; peak coil {:.1} °C, budget peak rise {:.0} K, faults seen: [{}]",
            summary.plan,
            rows,
            summary.duration_s,
            path.display(),
            summary.peak_coil_temperature_c,
            summary.budget_peak_rise_k,
            summary.faults_seen.join(",")
        );
        Ok(())
    }
}

/// Runs `sim`.
pub fn run(args: SimArgs) -> anyhow::Result<()> {
    let scenario = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    if args.print_default {
        output::print_toml("", &Scenario::default())?;
        return Ok(());
    }
    let in_scenario = |e: anyhow::Error| match &args.scenario {
        Some(p) => e.context(format!("scenario {}", p.display())),
        None => e,
    };
    if let Some(plan) = args.excite.plan(&scenario)? {
        let stop = Stop::on_signals()?;
        let spec = RunSpec::resolve(&scenario).map_err(in_scenario)?;
        let mut log = args.excite.open_log(scenario.planes())?;
        let electrical = !args.excite.no_electrical;
        let session = excite::run_sim(&plan, &spec, electrical, &mut log, &stop);
        return args.excite.finish(log, session);
    }
    let joint = JointSpec::of(&scenario);
    if let Some(path) = &args.calibration_sweep {
        let pending = host_tools::output::AtomicFile::create(path)?;
        let rows = calibration_sweep(&joint)?;
        drop(pending);
        host_tools::files::sweep::write_sweep(path, &rows)?;
        outln!("{} sweep rows written to {}", rows.len(), path.display());
        return Ok(());
    }
    let stop = Stop::on_signals()?;
    // Output paths are checked (the CSV created) before the run and before
    // any fitted law's sweep.
    let mut files = args.output.open_trace(joint.angle_names())?;
    let spec = RunSpec::resolve(&scenario).map_err(in_scenario)?;
    let progress = args.output.progress("steps");
    let mut summary = sim::run_into(&spec, &mut files, &stop, &progress).map_err(in_scenario)?;
    progress.finish_and_clear();
    args.output
        .finish_trace(files, &scenario.name, &mut summary)?;
    if args.output.json {
        output::print_json(&summary)?;
    } else {
        out!("{}", report::table(&summary));
    }
    match summary.cut_short {
        Some(cut) => Err(RunCutShort(cut).into()),
        None => Ok(()),
    }
}
