//! The global volume condition (issue 14 must-show): a full plate squeezes
//! the block to 70 % of its height; with the Pascal pressure p = −k_vol(V −
//! V0) − c_vol·V̇ (L2176) the volume stays close to V0, without it the
//! lattice (a central-force lattice has Poisson's ratio ¼) loses volume.
use plant_models::rheology::lattice::VolumeMode;
use plant_models::rheology::scenario::{run_scenario, Scenario};

/// Largest |V/V0 − 1| over the run, and V/V0 at the end of the hold.
fn squeeze(volume: VolumeMode) -> (f64, f64) {
    let mut sc = Scenario::default();
    sc.model.volume = volume;
    sc.plate.footprint_cm = [30.0, 30.0]; // a full plate
    sc.plate.depth_mm = Some(vec![[0.0, 0.0], [1.0, 18.0], [2.0, 18.0]]); // 6 cm → 4.2 cm
    sc.plate.end_s = 2.0;
    sc.measure.frame_times_s = vec![2.0];
    let r = run_scenario(&sc, None).unwrap();
    assert!(r.instability.is_none(), "{:?}", r.instability);
    let worst = r
        .volume_m3
        .iter()
        .map(|v| (v / r.volume0_m3 - 1.0).abs())
        .fold(0.0, f64::max);
    // The top really is at 70 %.
    let top = r.frames[0]
        .positions_m
        .iter()
        .map(|p| p.y)
        .fold(f64::NEG_INFINITY, f64::max);
    assert!((top - 0.042).abs() < 2e-4, "top at {top} m");
    (worst, r.volume_m3.last().unwrap() / r.volume0_m3)
}

#[test]
fn the_global_volume_condition_holds_the_volume_under_a_squeeze_to_70_percent() {
    let (with_worst, with_end) = squeeze(VolumeMode::Global);
    let (without_worst, without_end) = squeeze(VolumeMode::None);
    eprintln!("global: worst {with_worst:.4}, end {with_end:.4}; none: worst {without_worst:.4}, end {without_end:.4}");
    assert!(with_worst < 0.02, "with the condition: {with_worst}");
    assert!(without_worst > 0.10, "without it: {without_worst}");
}
