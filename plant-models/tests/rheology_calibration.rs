//! Calibration of the rheology lattice against the reference block (issue
//! 14's identification must-shows).
//!
//! The tests that run in CI are short forms on small blocks; the paper-
//! sized experiments are `#[ignore]`d and print the figures the README
//! reports:
//!
//! ```sh
//! cargo test --release -p plant-models --test rheology_calibration -- --ignored --nocapture --test-threads 1
//! ```
use plant_models::rheology::identify::calibrate::{calibrate, CalibrationSettings, Problem};
use plant_models::rheology::identify::measurement::Measurement;
use plant_models::rheology::identify::reference::{record_push, ReferenceConfig};
use plant_models::rheology::identify::search::{Budget, Method};
use plant_models::rheology::lattice::VolumeMode;
use plant_models::rheology::params::{LatticeParams, ParamSet};
use plant_models::rheology::scenario::{push_schedule_mm, Scenario};

/// A small, quick version of the paper's push: a 6 × 4 × 6 cm block,
/// 0–0.5 s push of 8 mm, hold to 1.5 s, release by 2 s.
fn small_scenario(grid: [usize; 3], depth_mm: f64, push_s: f64) -> Scenario {
    let mut sc = Scenario::default();
    sc.block.size_cm = [6.0, 4.0, 6.0];
    sc.block.mass_g = 6.0 * 4.0 * 6.0 * 1.2;
    sc.block.grid = grid;
    sc.model.dt_ms = 20.0;
    sc.plate.footprint_cm = [3.0, 3.0];
    sc.plate.depth_mm = Some(push_schedule_mm(depth_mm, push_s));
    sc.plate.end_s = 4.0 * push_s;
    sc.measure.frame_times_s = vec![push_s, 2.0 * push_s, 3.0 * push_s, 4.0 * push_s];
    sc.measure.force_window_s = [push_s, 3.0 * push_s];
    sc
}

fn small_reference(seed: u64) -> ReferenceConfig {
    ReferenceConfig {
        cells: [3, 2, 3],
        dt_ms: 10.0,
        points_per_frame: 150,
        seed,
        ..ReferenceConfig::default()
    }
}

fn measured(sc: &Scenario, cfg: &ReferenceConfig) -> Measurement {
    record_push(sc, cfg).unwrap().measurement
}

#[test]
fn calibrated_parameters_predict_an_unseen_push_better_than_the_defaults() {
    // Train on an 8 mm push over 0.5 s; test on a 5 mm push over 0.35 s
    // (another depth and speed) that the calibration never saw.
    let train = small_scenario([3, 3, 3], 8.0, 0.5);
    let test = small_scenario([3, 3, 3], 5.0, 0.35);
    let problem = Problem::new(
        train.clone(),
        ParamSet::Four,
        measured(&train, &small_reference(1)),
    )
    .unwrap();
    let cal = calibrate(
        &problem,
        &CalibrationSettings::new(Method::Ga, Budget::evaluations(150), 1),
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(cal.search.evaluations, 150);
    let unseen = Problem::new(
        test.clone(),
        ParamSet::Four,
        measured(&test, &small_reference(2)),
    )
    .unwrap();
    let defaults = LatticeParams::paper_default();
    let (d_train, _) = problem.score(&defaults).unwrap();
    let (d, _) = unseen.score(&defaults).unwrap();
    let (c, _) = unseen.score(&cal.best_params).unwrap();
    eprintln!(
        "training S: defaults {:.2}, calibrated {:.2}; unseen push S: defaults {:.2} ({:.3} mm/point), calibrated {:.2} ({:.3} mm/point)",
        d_train.s,
        cal.search.best_s,
        d.s,
        d.mean_distance_mm(),
        c.s,
        c.mean_distance_mm()
    );
    assert!(cal.search.best_s < d_train.s);
    assert!(
        c.s < 0.8 * d.s,
        "unseen push: calibrated {} vs defaults {}",
        c.s,
        d.s
    );
}
