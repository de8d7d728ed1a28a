//! `softjoint`: simulation, hardware-in-the-loop, board console, calibration
//! and model fitting for SMA-driven soft joints and deformable objects.
use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand};
use host_tools::{calibrate, report, scenario::Scenario, sim};

mod serial_cmds;

mod push;
mod rheology;
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
    /// joint (slow ±20° sweep, camera reference) to this CSV.
    #[arg(long, value_name = "PATH")]
    calibration_sweep: Option<PathBuf>,
    /// Print the built-in default scenario as TOML and exit.
    #[arg(long)]
    print_default: bool,
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

/// A reader that goes away early (`softjoint sim --json | head -1`) makes
/// the next `println!` fail with EPIPE, which std turns into a panic. End
/// quietly instead, with the status a shell gives a process killed by
/// SIGPIPE (128 + 13), as other command-line tools do; any other panic
/// still reports as usual.
fn exit_quietly_on_broken_pipe() {
    let report = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let message = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to std") && message.contains("Broken pipe") {
            std::process::exit(141);
        }
        report(info)
    }));
}

fn main() -> ExitCode {
    exit_quietly_on_broken_pipe();
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
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
        Command::Rheology(args) => rheology::run_command(args),
        Command::Calibrate(CalibrateCommand::Wire {
            sweep,
            output,
            json,
        }) => {
            let rows = calibrate::read_sweep(&sweep)?;
            let fits =
                calibrate::fit(&rows).map_err(|e| anyhow::anyhow!("{}: {e}", sweep.display()))?;
            calibrate::calibration_of(&fits)?.save(&output)?;
            if json {
                let out: Vec<serde_json::Value> = fits
                    .iter()
                    .map(|f| {
                        serde_json::json!({
                            "angle": f.angle,
                            "chosen": f.chosen,
                            "threshold_deg": f.chosen.threshold_deg(),
                            "max_error_deg": f.chosen_errors.max_error_deg,
                            "rms_error_deg": f.chosen_errors.rms_error_deg,
                            "methods": {
                                "single": f.single.1,
                                "differential": f.differential.as_ref().map(|d| d.1),
                                "switching": f.switching.as_ref().map(|d| d.1),
                            },
                        })
                    })
                    .collect();
                println!(
                    "{}",
                    serde_json::to_string_pretty(
                        &serde_json::json!({ "rows": rows.len(), "angles": out, "calibration": output })
                    )?
                );
            } else {
                print!("{}", calibrate::table(&fits));
                println!(
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
        print!("{}", toml::to_string_pretty(&Scenario::default())?);
        return Ok(());
    }
    if let Some(path) = &args.calibration_sweep {
        let rows = sim::calibration_sweep(&scenario)?;
        calibrate::write_sweep(path, &rows)?;
        println!("{} sweep rows written to {}", rows.len(), path.display());
        return Ok(());
    }
    let out = sim::run_with(&scenario, args.output.wants_trace())?;
    args.output
        .write_files(&scenario.name, &out.summary, &out.trace)?;
    if args.output.json {
        println!("{}", serde_json::to_string_pretty(&out.summary)?);
    } else {
        print!("{}", report::table(&out.summary));
    }
    Ok(())
}
