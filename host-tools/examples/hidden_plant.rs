//! Writes the twin tests' hidden joint (`plant_joint::identify::
//! hidden`: the defaults moved 20–50 %, a Clausius–Clapeyron slope, more
//! camera noise, jamming) as a plant file, so the whole pipeline can be run
//! from the command line against a joint whose truth is known:
//! `cargo run --release -p host-tools --example hidden_plant -- 3d hidden.toml [SEED]`;
//! `campaign3d` instead of `3d` writes twin SEED of the identification
//! campaign (`hidden::campaign_joint_3d`).
use plant_joint::identify::hidden;

use host_tools::files::plant::{PlantFile, PlantParams};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let (Some(kind), Some(path)) = (args.get(1), args.get(2)) else {
        anyhow::bail!("usage: hidden_plant 2d|3d|campaign3d OUT.toml [SEED]");
    };
    let seed: u64 = args.get(3).map(|s| s.parse()).transpose()?.unwrap_or(7);
    let params = match kind.as_str() {
        "2d" => PlantParams::TwoD(hidden::joint_2d(seed)),
        "3d" => PlantParams::ThreeD(hidden::joint_3d(seed)),
        "campaign3d" => PlantParams::ThreeD(hidden::campaign_joint_3d(seed)),
        other => anyhow::bail!("joint must be 2d, 3d or campaign3d, got {other}"),
    };
    PlantFile::new(params, vec![]).save(
        std::path::Path::new(path),
        "# The twin tests' hidden joint (plant_joint::identify::hidden).\n",
    )?;
    println!("hidden {kind} joint written to {path}");
    Ok(())
}
