//! One file per subcommand (as cargo's `src/bin/cargo/commands/`): its clap
//! arguments and a short `run` that calls library code.
use clap::{Parser, Subcommand};

pub mod calibrate;
pub mod conform;
pub mod console;
pub mod contour;
pub mod dlo;
pub mod hil;
pub mod identify;
pub mod push;
pub mod rheology;
pub mod sim;
pub mod tetmsd;
pub mod tissue;
pub mod tune;
pub mod viscoelastic;

#[derive(Parser)]
#[command(name = "softjoint", version, about)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Simulate the joint under the firmware controller (default: the 3D
    /// joint, threshold switching, targets (0,0) → (5,5) → (10,10)).
    Sim(sim::SimArgs),
    /// Calibrate from measured data.
    #[command(subcommand)]
    Calibrate(calibrate::CalibrateCommand),
    /// Hardware-in-the-loop: the firmware image under QEMU (or a board on
    /// --port) runs the controller in lockstep with the simulated joint.
    Hil(hil::HilArgs),
    /// Send commands to a board and stream its telemetry.
    Console(console::ConsoleArgs),
    /// Hold a board to docs/protocol.md: the conformance suite (a serial
    /// port, the images under QEMU, or the pty board), each check citing
    /// its section; text, JSON or JUnit XML, non-zero exit on a failure.
    Conform(conform::ConformArgs),
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
    Identify(identify::IdentifyCommand),
    /// Search controller gains on an identified plant, robust over its
    /// uncertainty; writes a gains file the console and scenarios load.
    Tune(tune::TuneArgs),
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

/// Runs the subcommand.
pub fn exec(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Sim(args) => sim::run(args),
        Command::Calibrate(cmd) => calibrate::run(cmd),
        Command::Hil(args) => hil::run(args),
        Command::Console(args) => console::run(args),
        Command::Conform(args) => conform::run(args),
        Command::Viscoelastic(args) => viscoelastic::run(args),
        Command::Push(args) => push::run(args),
        Command::Tetmsd(args) => tetmsd::run(args),
        Command::Contour(args) => contour::run(args),
        Command::Identify(cmd) => identify::run(cmd),
        Command::Tune(args) => tune::run(args),
        Command::Dlo(args) => dlo::run(args),
        Command::Tissue(args) => tissue::run(args),
        Command::Rheology(args) => rheology::run(args),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::builder::ValueParser;
    use clap::CommandFactory as _;

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
