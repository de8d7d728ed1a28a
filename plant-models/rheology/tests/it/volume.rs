//! The global volume condition (issue 14 must-show): a full plate squeezes
//! the block to 70 % of its height; with the Pascal pressure p = −k_vol(V −
//! V0) − c_vol·V̇ (L2176) the volume stays close to V0, without it the
//! lattice (a central-force lattice has Poisson's ratio ¼) loses volume.
use plant_rheology::lattice::VolumeMode;
use plant_rheology::scenario::{run_scenario, Scenario};

/// Largest |V/V0 − 1| over the run, and V/V0 at the end of the hold
/// (the paper's 6 × 4 × 6 lattice, its defaults, 10 ms steps).
fn squeeze(volume: VolumeMode) -> (f64, f64) {
    let mut sc = Scenario::default();
    sc.model.volume = volume;
    sc.model.dt_ms = 10.0;
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
    // Measured: with the condition ≈ 2 % at worst (while squeezing) and
    // 0.15 % at the end of the hold; without it 24 %.
    assert!(with_worst < 0.03, "with the condition: {with_worst}");
    assert!(
        (with_end - 1.0).abs() < 0.005,
        "with the condition, held: {with_end}"
    );
    assert!(without_worst > 0.20, "without it: {without_worst}");
    assert!(without_end < 0.80, "without it, held: {without_end}");
}
