//! `softjoint`: simulation, hardware-in-the-loop, board console, calibration
//! and model fitting for SMA-driven soft joints and deformable objects.
use std::io::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use host_tools::{calibrate, out, outln, output, report, scenario::Scenario, sim};

mod serial_cmds;

mod contour;
mod dlo;
mod identify_cmd;
mod push;
mod rheology;
mod tetmsd;
mod tissue;
mod viscoelastic;

#[derive(Parser)]
#[command(name = "softjoint", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate the joint under the firmware controller (default: the 3D
    /// joint, threshold switching, targets (0,0) → (5,5) → (10,10)).
    Sim(SimArgs),
    /// Calibrate from measured data.
    #[command(subcommand)]
    Calibrate(CalibrateCommand),
    /// Hardware-in-the-loop: the firmware image under QEMU (or a board on
    /// --port) runs the controller in lockstep with the simulated joint.
    Hil(serial_cmds::HilArgs),
    /// Send commands to a board and stream its telemetry.
    Console(serial_cmds::ConsoleArgs),
    /// Viscoelastic solids (seed 002): 3-element model on your data, fits,
    /// and the measured DGFM object.
    Viscoelastic(viscoelastic::ViscoArgs),
    /// Deformable blocks under robotic pushing (seed 001): simulate,
    /// calibrate (Algorithm 5), classify.
    Push(push::PushArgs),
    /// A tetrahedral Voigt cube deformed by two haptic users at two sites
    /// over a network (seed 000, Yamaguchi): simulate, pair.
    Tetmsd(tetmsd::TetArgs),
    /// Periodic and closed smoothing spline contours (seed 000, Fujioka &
    /// Kano): fit tracked contours and deforming contours over time, or
    /// write the paper's test cases.
    Contour(contour::ContourArgs),
    /// The joint's plant fitted to your own excitation log, and the plans
    /// to record one.
    #[command(subcommand)]
    Identify(identify_cmd::IdentifyCommand),
    /// Search controller gains on an identified plant, robust over its
    /// uncertainty; writes a gains file the console and scenarios load.
    Tune(identify_cmd::TuneArgs),
    /// Deformable linear objects (seed 000): the knotting rope of Shi &
    /// Payandeh, the static wires and belts of Wakamatsu et al.
    Dlo(dlo::DloArgs),
    /// Inner deformation of soft tissue (seed 000): deformation fields from
    /// volume images (Zhang) and breast compression between plates (Kita).
    Tissue(tissue::TissueArgs),
    /// Rheology lattice of a dough-like block (seed 000, Noborio):
    /// simulate a push, calibrate by the paper's GA or RA.
    Rheology(rheology::RheologyArgs),
}

#[derive(Args)]
struct SimArgs {
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
    ) -> anyhow::Result<Option<plant_models::joint::identify::ExcitationPlan>> {
        self.excite
            .as_ref()
            .map(|p| host_tools::excite::load_plan(p, scenario.planes()))
            .transpose()
    }

    /// Writes the log and prints what the session saw.
    pub fn finish(
        &self,
        log: &plant_models::joint::identify::ExcitationLog,
        summary: &host_tools::excite::SessionSummary,
    ) -> anyhow::Result<()> {
        let path = self
            .log
            .as_ref()
            .ok_or_else(|| anyhow::anyhow!("--excite needs --log"))?;
        host_tools::excite::write_log(path, log)?;
        outln!(
            "{}: {} rows ({} s) written to {}; peak coil {:.1} °C, budget peak rise {:.0} K, faults seen: [{}]",
            summary.plan,
            summary.rows,
            summary.duration_s,
            path.display(),
            summary.peak_coil_temperature_c,
            summary.budget_peak_rise_k,
            summary.faults_seen.join(",")
        );
        Ok(())
    }
}

#[derive(Subcommand)]
enum CalibrateCommand {
    /// Fit the wire-sensor laws (Eq. 2–5) to a sweep CSV
    /// (`d1_mm,d2_mm,d3_mm,d4_mm,alpha_deg,beta_deg` or `d_mm,theta_deg`).
    Wire {
        /// The sweep.
        sweep: PathBuf,
        /// Write the calibration file (TOML) here.
        #[arg(short, long, default_value = "calibration.toml")]
        output: PathBuf,
        /// Print a machine-readable result.
        #[arg(long)]
        json: bool,
    },
}

fn main() -> ExitCode {
    if let Err(e) = host_tools::stop::file_size_limit_is_an_error() {
        let _ = writeln!(std::io::stderr(), "warning: {e}");
    }
    let result = run(Cli::parse()).and_then(|()| Ok(host_tools::output::flush_stdout()?));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A reader that went away early (`softjoint sim --json | head -1`)
            // ends the program quietly with the status a shell gives a
            // process killed by SIGPIPE (128 + 13), as other command-line
            // tools do. Any other failed output is an error like the rest.
            if e.downcast_ref::<host_tools::output::StdoutError>()
                .is_some_and(|s| s.is_broken_pipe())
            {
                return ExitCode::from(141);
            }
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            // A run cut short by a signal exits as the signal would (130
            // for SIGINT), after its trace and summary were written.
            match e.downcast_ref::<sim::RunCutShort>() {
                Some(cut) => ExitCode::from(cut.exit_code()),
                None => ExitCode::FAILURE,
            }
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Sim(args) => sim_command(args),
        Command::Hil(args) => serial_cmds::hil(args),
        Command::Console(args) => serial_cmds::console(args),
        Command::Viscoelastic(args) => viscoelastic::run(args),
        Command::Push(args) => push::run(args),
        Command::Tetmsd(args) => tetmsd::run(args),
        Command::Contour(args) => contour::run(args),
        Command::Identify(cmd) => identify_cmd::run(cmd),
        Command::Tune(args) => identify_cmd::tune_command(args),
        Command::Dlo(args) => dlo::run(args),
        Command::Tissue(args) => tissue::run(args),
        Command::Rheology(args) => rheology::run_command(args),
        Command::Calibrate(CalibrateCommand::Wire {
            sweep,
            output,
            json,
        }) => {
            let rows = calibrate::read_sweep(&sweep)?;
            // The output path is checked (its temporary file made) before
            // the fit; the file is replaced only once it is complete.
            let pending = host_tools::output::AtomicFile::create(&output)?;
            let fits =
                calibrate::fit(&rows).map_err(|e| anyhow::anyhow!("{}: {e}", sweep.display()))?;
            calibrate::calibration_of(&fits)?.save_to(pending)?;
            if json {
                let out = fits
                    .iter()
                    .map(|f| {
                        output::JsonObject::new()
                            .field("angle", &f.angle)?
                            .field("chosen", &f.chosen)?
                            .field("threshold_deg", &f.chosen.threshold_deg())?
                            .field("max_error_deg", &f.chosen_errors.max_error_deg)?
                            .field("rms_error_deg", &f.chosen_errors.rms_error_deg)?
                            .field(
                                "methods",
                                &output::JsonObject::new()
                                    .field("single", &f.single.1)?
                                    .field("differential", &f.differential.as_ref().map(|d| d.1))?
                                    .field("switching", &f.switching.as_ref().map(|d| d.1))?,
                            )
                    })
                    .collect::<anyhow::Result<Vec<_>>>()?;
                output::JsonObject::new()
                    .field("rows", &rows.len())?
                    .field("angles", &out)?
                    .field("calibration", &output)?
                    .print()?;
            } else {
                out!("{}", calibrate::table(&fits));
                outln!(
                    "{} rows; calibration written to {}",
                    rows.len(),
                    output.display()
                );
            }
            Ok(())
        }
    }
}

fn sim_command(args: SimArgs) -> anyhow::Result<()> {
    let scenario = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    if args.print_default {
        crate::output::print_toml("", &Scenario::default())?;
        return Ok(());
    }
    if let Some(plan) = args.excite.plan(&scenario)? {
        let (log, summary) =
            host_tools::excite::run_sim(&plan, &scenario, !args.excite.no_electrical)?;
        return args.excite.finish(&log, &summary);
    }
    if let Some(path) = &args.calibration_sweep {
        let pending = host_tools::output::AtomicFile::create(path)?;
        let rows = sim::calibration_sweep(&scenario)?;
        drop(pending);
        calibrate::write_sweep(path, &rows)?;
        outln!("{} sweep rows written to {}", rows.len(), path.display());
        return Ok(());
    }
    let stop = host_tools::stop::Stop::on_signals()?;
    // Output paths are checked (the CSV created) before the run.
    let mut files = args.output.open_trace(&sim::angle_names(&scenario))?;
    let progress = args.output.progress("steps");
    let mut summary = sim::run_into(&scenario, &mut files, &stop, &progress).map_err(|e| {
        match &args.scenario {
            Some(p) => e.context(format!("scenario {}", p.display())),
            None => e,
        }
    })?;
    progress.finish_and_clear();
    args.output
        .finish_trace(files, &scenario.name, &mut summary)?;
    if args.output.json {
        output::print_json(&summary)?;
    } else {
        out!("{}", report::table(&summary));
    }
    match summary.cut_short {
        Some(cut) => Err(sim::RunCutShort(cut).into()),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::builder::ValueParser;
    use clap::CommandFactory;

    /// Every option and positional argument that takes a number, in every
    /// subcommand.
    fn numeric_args(cmd: &clap::Command, path: &str, out: &mut Vec<(String, bool)>) {
        let numeric = [
            ValueParser::from(clap::value_parser!(f64)).type_id(),
            ValueParser::from(clap::value_parser!(u64)).type_id(),
            ValueParser::from(clap::value_parser!(u32)).type_id(),
            ValueParser::from(clap::value_parser!(u16)).type_id(),
            ValueParser::from(clap::value_parser!(usize)).type_id(),
        ];
        for a in cmd.get_arguments() {
            if numeric.contains(&a.get_value_parser().type_id()) {
                out.push((
                    format!("{path} --{}", a.get_id()),
                    a.is_allow_negative_numbers_set() || a.is_allow_hyphen_values_set(),
                ));
            }
        }
        for sub in cmd.get_subcommands() {
            numeric_args(sub, &format!("{path} {}", sub.get_name()), out);
        }
    }

    /// `--k1 -1` was `unexpected argument '-1'`: clap took the value for a
    /// flag. Every numeric option takes a negative number as its value,
    /// so the range check that follows can name the flag and the range.
    #[test]
    fn every_numeric_option_accepts_a_negative_value() {
        let mut args = Vec::new();
        numeric_args(&Cli::command(), "softjoint", &mut args);
        assert!(args.len() >= 15, "{args:?}");
        let refused: Vec<&String> = args.iter().filter(|(_, ok)| !ok).map(|(n, _)| n).collect();
        assert!(refused.is_empty(), "read as flags: {refused:?}");
        let e = Cli::try_parse_from(["softjoint", "push", "simulate", "--nx", "-3"])
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("--nx") && e.contains("-3"), "{e}");
    }
}
