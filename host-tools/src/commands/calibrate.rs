//! `softjoint calibrate wire`: the wire-sensor laws fitted to a sweep.
use std::path::PathBuf;

use clap::Subcommand;
use host_tools::joint::calibrate;
use host_tools::{out, outln, output};

#[derive(Subcommand)]
pub enum CalibrateCommand {
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

/// Runs `calibrate wire`.
pub fn run(cmd: CalibrateCommand) -> anyhow::Result<()> {
    let CalibrateCommand::Wire {
        sweep,
        output,
        json,
    } = cmd;
    let rows = host_tools::files::sweep::read_sweep(&sweep)?;
    // The output path is checked (its temporary file made) before
    // the fit; the file is replaced only once it is complete.
    let pending = host_tools::output::AtomicFile::create(&output)?;
    let fits = calibrate::fit(&rows).map_err(|e| anyhow::anyhow!("{}: {e}", sweep.display()))?;
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
