//! The paper's dense-versus-sparse comparison for Model 2′ (local volume
//! condition, 16 parameters; L1998–2001: S 1506 dense against 1831
//! sparse): the paper's 10 × 6 × 10 cm block on 6 × 4 × 6 and 11 × 7 × 11
//! lattices, calibrated by the GA at equal evaluations (seed 1) against the
//! same measured push (the paper's depth, scaled to 0.5 s of pushing to
//! keep runs short) of the default 12 × 7 × 12-cube reference block.
//!
//! ```sh
//! cargo run --release -p plant-rheology --example dense_against_sparse -- [EVALUATIONS]
//! ```
//!
//! `EVALUATIONS` per lattice, default 300 (the README's figures, ≈ 12 min
//! on 2 cores). Prints the defaults' and the GA's S per lattice, then
//! whether the dense lattice's is the lower; exits 1 when it is not.
use std::process::ExitCode;

use plant_rheology::identify::calibrate::{calibrate, CalibrationSettings, Problem};
use plant_rheology::identify::reference::{record_push, ReferenceConfig};
use plant_rheology::identify::search::{Budget, Method};
use plant_rheology::lattice::VolumeMode;
use plant_rheology::params::{LatticeParams, ParamSet};
use plant_rheology::scenario::{push_schedule_mm, Scenario};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The paper's block on a `grid` lattice with the local volume condition:
/// 15 mm over 0.5 s, frames every 0.5 s to 2 s.
fn scenario(grid: [usize; 3]) -> Scenario {
    let mut sc = Scenario::default();
    sc.block.grid = grid;
    sc.model.volume = VolumeMode::Local;
    sc.model.dt_ms = 10.0;
    sc.plate.depth_mm = Some(push_schedule_mm(15.0, 0.5));
    sc.plate.end_s = 2.0;
    sc.measure.frame_times_s = vec![0.5, 1.0, 1.5, 2.0];
    sc.measure.force_window_s = [0.5, 1.5];
    sc
}

fn run() -> Result<ExitCode> {
    let evaluations: usize = match std::env::args().nth(1) {
        Some(e) => e
            .parse()
            .map_err(|_| format!("EVALUATIONS must be a whole number, got `{e}`"))?,
        None => 300,
    };
    let sparse = scenario([6, 4, 6]);
    let dense = scenario([11, 7, 11]);
    let reference = ReferenceConfig {
        dt_ms: 10.0,
        points_per_frame: 400,
        ..ReferenceConfig::default()
    };
    let m = record_push(&sparse, &reference)?.measurement;
    let mut s = [0.0; 2];
    for (k, sc) in [sparse, dense].into_iter().enumerate() {
        let problem = Problem::new(sc.clone(), ParamSet::Sixteen, m.clone())?;
        let (d, _) = problem.score(&LatticeParams::paper_default())?;
        let cal = calibrate(
            &problem,
            &CalibrationSettings::new(Method::Ga, Budget::evaluations(evaluations), 1),
            &mut |_| {},
        )?;
        s[k] = cal.search.best_s;
        eprintln!(
            "{:?}: defaults S {:.2}, GA S {:.2} ({:.3} mm/point) after {} evaluations in {:.1} s",
            sc.block.grid,
            d.s,
            cal.search.best_s,
            10.0 * cal.search.best_s / d.points.max(1) as f64,
            cal.search.evaluations,
            cal.search.elapsed_s
        );
    }
    let holds = s[1] < s[0];
    eprintln!(
        "dense S below sparse S (the paper's claim): {} (ratio {:.3})",
        if holds { "yes" } else { "no" },
        s[1] / s[0]
    );
    Ok(if holds {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn main() -> ExitCode {
    run().unwrap_or_else(|e| {
        eprintln!("dense_against_sparse: {e}");
        ExitCode::from(2)
    })
}
