//! `softjoint`: simulation, hardware-in-the-loop, board console, calibration
//! and model fitting for SMA-driven soft joints and deformable objects.
use clap::{Parser, Subcommand};

mod viscoelastic;

#[derive(Parser)]
#[command(name = "softjoint", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Print what the portable control core computes for one 3D step.
    Info,
    /// Viscoelastic solids (seed 002): 3-element model on your data, fits,
    /// and the measured DGFM object.
    Viscoelastic(viscoelastic::ViscoArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::Info => {
            println!("softjoint {}", env!("CARGO_PKG_VERSION"));
            Ok(())
        }
        Command::Viscoelastic(args) => viscoelastic::run(args),
    }
}
