//! Closed loop under visual feedback (seed 000, last paper, §III): the 2D
//! joint, the 30 frames/s camera as the only sensor, the firmware's Eq. 1
//! law (one actuator; coil 2 unpowered, a bias spring), run through
//! `host_tools::run::sim::run` exactly as `softjoint sim` runs a scenario.
//!
//! Must show (issue 3): convergence at Kp = 0.05 and 2.0 (Fig. 7), the
//! steady-state error at Kp = 2.0 (§III-B), the coil-2 disturbance (Fig. 9),
//! the rigid bearing oscillating more (Fig. 7 vs Fig. 11), integral action
//! removing the P law's steady-state error under the supervisor.
//!
//! All runs are seeded; every number below was measured with the seed given.

use crate::common;

use common::{camera_p, coil_disturbance, err_stats, peak_to_peak, reversals, run};
use firmware::supervisor::ThermalConfig;
use plant_joint::Joint2dParams;

const SEED: u64 = 3;
/// θd of the paper's Fig. 7 (deg).
const FIG7_TARGET_DEG: f64 = 20.0;

/// Paper §III-B, Fig. 7: θd = 20°, Kp = 0.05 and 2.0 V/deg; "the angle
/// reaches a steady value, albeit there is some fluctuation", with a
/// steady-state error that depends on Kp.
///
/// Measured (seed 3, 40 s): Kp = 2.0 stays within −0.21…+0.27° of θd over
/// 10–40 s (the SMA's hysteresis: a small overshoot is held while the
/// unpowered coil cools through the hysteresis band, then the coil is
/// reheated), mean −0.063° over 20–40 s. Kp = 0.05 settles smoothly at
/// 16.31° (error −3.69° over 30–40 s, 0.05° peak to peak): the lower gain
/// leaves the larger P offset, as the paper's mass–spring argument (Fig. 8)
/// predicts.
#[test]
fn camera_p_control_converges_at_both_gains_of_fig7() {
    let high = run(&camera_p(2.0, FIG7_TARGET_DEG, 40.0, SEED)).trace;
    let low = run(&camera_p(0.05, FIG7_TARGET_DEG, 40.0, SEED)).trace;

    // Kp = 2.0 converges: after 10 s the angle never leaves a ±1° band
    // around θd, and it does not drift (the means of two consecutive 10 s
    // windows agree within 0.2°).
    let band = err_stats(&high, 0, 10.0, 40.0);
    println!("Kp = 2.0, 10–40 s: {band:?}");
    assert!(
        band.max_abs < 1.0,
        "Kp = 2.0 leaves the ±1° band after 10 s: {band:?}"
    );
    let (a, b) = (
        err_stats(&high, 0, 20.0, 30.0).mean,
        err_stats(&high, 0, 30.0, 40.0).mean,
    );
    assert!(
        (a - b).abs() < 0.2,
        "Kp = 2.0 drifts: mean error {a:.3}° (20–30 s) vs {b:.3}° (30–40 s)"
    );

    // Kp = 0.05 converges to a steady value: over the last 10 s the (true,
    // noise-free) angle moves by less than 0.1° peak to peak.
    let ptp = peak_to_peak(&low, 0, 30.0, 40.0);
    assert!(
        ptp < 0.1,
        "Kp = 0.05 still moving: {ptp:.3}° peak to peak over 30–40 s"
    );
    // ... with the larger steady-state error: below θd by more than 1°, and
    // at least 5 times the Kp = 2.0 offset.
    let low_err = err_stats(&low, 0, 30.0, 40.0).mean;
    let high_err = err_stats(&high, 0, 20.0, 40.0).mean;
    println!("mean error: Kp = 0.05 {low_err:+.3}° (30–40 s, {ptp:.3}° p-p), Kp = 2.0 {high_err:+.3}° (20–40 s)");
    assert!(
        low_err < -1.0,
        "Kp = 0.05 offset {low_err:.3}°: expected the P law's droop below θd"
    );
    assert!(
        low_err.abs() > 5.0 * high_err.abs(),
        "offsets: Kp = 0.05 {low_err:.3}°, Kp = 2.0 {high_err:.3}°"
    );
}

/// Paper §III-B: "even when the gain Kp [is] 2.0, the steady-state error is
/// acceptable, being less than 0.15 deg".
///
/// The steady-state error is the time mean of θ − θd over 10–60 s, worst
/// over seeds 1–5 (each seed a different camera-noise and jamming stream).
/// The joint does not rest exactly: each reheat overshoots θd a little and
/// the overshoot is held while the unpowered coil cools through its
/// hysteresis band (the paper's "albeit there is some fluctuation").
///
/// History: this failed at +0.12…+0.22° until the SMA coil's latent heat
/// was settled together with the phase (plant `sma.rs`,
/// `settle_latent_heat`). The old split step squeezed the A_s–A_f
/// transformation into ≈ 2.5 K, so a saturated reheat moved the link faster
/// than the 30 frames/s camera could report it.
#[test]
fn camera_p_steady_state_error_below_0_15_deg_at_kp_2() {
    let mut worst: f64 = 0.0;
    for seed in 1..=5 {
        let t = run(&camera_p(2.0, FIG7_TARGET_DEG, 60.0, seed)).trace;
        let e = err_stats(&t, 0, 10.0, 60.0).mean;
        println!("seed {seed}: mean error over 10–60 s {e:+.3}°");
        worst = worst.max(e.abs());
    }
    assert!(
        worst < 0.15,
        "steady-state error up to {worst:.3}° (paper: < 0.15°)"
    );
}

/// Paper §III-C, Fig. 9: Kp = 2.0, θd = 5°, coil 2 driven at 5 V from 4 s
/// to 6 s (≈ 150 g of pull, as large as coil 1's own moment); "the angle
/// converges to a stable location after v2 breaks contact".
///
/// Measured (seed 3): pushed down to −5.1° (error −10.1°) during the
/// disturbance; over 14–20 s the error stays within −0.16…+0.13°, mean
/// −0.02°. Tolerance: ±0.75° and a mean within 0.3° (set when the P law
/// still limit-cycled at −0.4…+0.5°; kept, not tightened to the new run).
#[test]
fn coil_2_disturbance_pushes_the_angle_away_and_it_returns() {
    let target = 5.0;
    let mut s = camera_p(2.0, target, 20.0, SEED);
    s.disturbances = vec![coil_disturbance(2, 5.0, 4.0, 6.0)];
    let t = run(&s).trace;

    // Coil 2 lowers θ: during the disturbance (and the 0.5 s the coil needs
    // to let go) the angle is pushed clearly below θd.
    let during = err_stats(&t, 0, 4.0, 6.5);
    println!("during 4–6.5 s: {during:?}");
    assert!(
        during.min < -1.0,
        "coil 2 at 5 V did not push the angle away: {during:?}"
    );

    // Returns: 8 s after the disturbance ends the angle is back at θd.
    let after = err_stats(&t, 0, 14.0, 20.0);
    println!("after 14–20 s: {after:?}");
    assert!(
        after.max_abs < 0.75,
        "not back within ±0.75° of θd = {target}° over 14–20 s: {after:?}"
    );
    assert!(
        after.mean.abs() < 0.3,
        "mean offset {:.3}° over 14–20 s",
        after.mean
    );
}

/// Paper §III-D, Fig. 7 vs Fig. 11: the same Eq. 1 law on a rigid bearing
/// (coil 2 the bias spring) oscillates; "the viscoelastic object reduces the
/// oscillation in the angle".
///
/// Measured (seed 3, first 10 s of a θd = 20° step at Kp = 2.0): overshoot
/// 2.68° (rigid) vs 1.42° (cartilage); direction reversals larger than 0.2°:
/// 67 (rigid: it rings at ≈ 3 Hz whenever the coil is switched) vs 3
/// (cartilage: only the slow hysteresis cycle). The reversal count is the
/// oscillation; the overshoot margin (1.5×) only checks that the rigid
/// joint's first swing is also the larger one. (Before the latent-heat fix
/// in the SMA coil the cartilage overshot 0.74°, the rigid joint 2.62°,
/// with 102 vs 4 reversals.)
#[test]
fn rigid_bearing_oscillates_more_than_the_cartilage_joint() {
    let cartilage = run(&camera_p(2.0, FIG7_TARGET_DEG, 10.0, SEED)).trace;
    let mut rigid_s = camera_p(2.0, FIG7_TARGET_DEG, 10.0, SEED);
    rigid_s.plant.rigid_bearing = true;
    let rigid = run(&rigid_s).trace;

    let overshoot = |t| err_stats(t, 0, 0.0, 10.0).max;
    let (o_c, o_r) = (overshoot(&cartilage), overshoot(&rigid));
    println!("overshoot: cartilage {o_c:.2}°, rigid {o_r:.2}°");
    assert!(
        o_r > 1.5 * o_c,
        "overshoot: rigid {o_r:.2}° vs cartilage {o_c:.2}°"
    );

    let (n_c, n_r) = (
        reversals(&cartilage, 0, 0.2, 0.0, 10.0),
        reversals(&rigid, 0, 0.2, 0.0, 10.0),
    );
    println!("reversals > 0.2° in 10 s: cartilage {n_c}, rigid {n_r}");
    assert!(
        n_r >= 10 && n_r >= 5 * n_c,
        "reversals > 0.2° in 10 s: rigid {n_r} vs cartilage {n_c}"
    );
}

/// Paper §III-B, Fig. 8: P control leaves a steady-state error, I action
/// would remove it ("we have not verified it experimentally", future work).
/// Eq. 1 at Kp = 0.5 V/° droops by ≈ 0.35° (the coil needs ≈ 0.18 V above
/// the offset to hold 20°); ki = 0.05 V/(deg·s) — integral time Kp/ki =
/// 10 s, about two coil cooling time constants (≈ 5 s, plant README), so it
/// trims the offset without driving the hysteresis — limited to 1 V (the
/// scenario default). (At Kp = 2.0 the P offset is already below 0.1°,
/// nothing to remove; at Kp = 0.05 it is 3.7°.)
///
/// Measured (`softjoint sim`, 40–60 s mean, seeds 1–5): P −0.351…−0.339°,
/// P + I −0.008…−0.004°, no fault (the test runs seed 3).
#[test]
fn integral_action_removes_the_p_offset_without_supervisor_faults() {
    let (kp, ki) = (0.5, 0.05);
    let p_only = run(&camera_p(kp, FIG7_TARGET_DEG, 60.0, SEED));
    let mut s = camera_p(kp, FIG7_TARGET_DEG, 60.0, SEED);
    s.controller.ki_v_per_deg_s = ki;
    s.controller.integral_limit_v = 1.0;
    let pi = run(&s);

    let e_p = err_stats(&p_only.trace, 0, 40.0, 60.0).mean;
    let e_pi = err_stats(&pi.trace, 0, 40.0, 60.0).mean;
    println!(
        "mean error 40–60 s: P {e_p:+.3}°, P + I {e_pi:+.3}°; peak coil °C {:?}",
        pi.summary.peak_coil_temperature_c
    );
    assert!(e_p < -0.2, "the P law alone should droop: {e_p:.3}°");
    assert!(e_pi.abs() < 0.05, "P + I leaves a {e_pi:.3}° offset");
    assert!(
        e_pi.abs() < 0.2 * e_p.abs(),
        "P + I offset {e_pi:.3}° vs P {e_p:.3}°: not removed"
    );
    // It settles: within ±0.15° of θd over the last 30 s.
    let band = err_stats(&pi.trace, 0, 30.0, 60.0);
    assert!(
        band.max_abs < 0.15,
        "P + I leaves the ±0.15° band after 30 s: {band:?}"
    );

    // The supervisor never had to step in: no thermal cut-off, no latched
    // fault, at any step.
    assert!(
        pi.summary.faults_seen.is_empty(),
        "faults: {:?}",
        pi.summary.faults_seen
    );
    assert!(
        pi.trace.rows.iter().all(|r| r.faults == 0),
        "a step reported faults"
    );
    // Coil temperatures stay bounded: below the supervisor's trip level
    // (ambient + trip rise), both coils.
    let trip_c = Joint2dParams::default().plane.coil.ambient_c
        + f64::from(ThermalConfig::default().trip_rise_k);
    for (i, t) in pi.summary.peak_coil_temperature_c.iter().enumerate() {
        assert!(
            t.is_finite() && *t < trip_c,
            "coil {} peaked at {t:.1} °C (trip {trip_c:.0} °C)",
            i + 1
        );
    }
}
