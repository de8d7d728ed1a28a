//! Wire sensors on the assembled joints: the paper's calibrated laws (Eq. 2,
//! Eq. 3) against the true angles on a quasi-static sweep, and jamming on
//! the pushing side only.
//!
//! The sweep holds the link at each target with the paper's antagonistic P
//! law on the *true* angle (Kp = 2 V/°), 4 s per 1° step — a stand-in for a
//! camera-referenced calibration, not the controller under test.

use plant_joint::wire_sensor::{paper_eq2_deg, paper_eq3_deg};
use plant_joint::{JamParams, Joint2d, Joint2dParams, Joint3d, Joint3dParams};

const DT: f64 = 1e-3;

fn p_law(angle: f64, target: f64) -> [f64; 2] {
    let e = angle - target;
    // Raising coil when below the target, lowering coil when above (the
    // sign that pulls back, see SPEC §1).
    if e < 0.0 {
        [1.7 - 2.0 * e, 0.0]
    } else {
        [0.0, 1.7 + 2.0 * e]
    }
}

/// Targets 0 → ±20° in 1° steps from rest, for each side separately.
fn targets(sign: f64) -> impl Iterator<Item = f64> {
    (0..=20).map(move |k| sign * k as f64)
}

#[test]
fn eq2_holds_on_the_quasi_static_path_without_jamming() {
    let mut worst: f64 = 0.0;
    for sign in [1.0, -1.0] {
        let mut p = Joint2dParams::default();
        p.wire.jam = JamParams::none();
        let mut j = Joint2d::new(p).unwrap();
        for t in targets(sign) {
            for _ in 0..4000 {
                j.step(DT, &p_law(j.angle_deg(), t)).unwrap();
            }
            let err = paper_eq2_deg(j.wire_insertion_mm()) - j.angle_deg();
            worst = worst.max(err.abs());
        }
    }
    println!("Eq. 2 on the simulated 2D joint, no jamming: worst {worst:.2}°");
    assert!(worst < 2.5, "Eq. 2 off by {worst:.2}°");
}

#[test]
fn eq3_holds_on_the_quasi_static_path_without_jamming() {
    let mut worst = [0.0f64; 2];
    for sign in [1.0, -1.0] {
        let mut p = Joint3dParams::default();
        for w in p.wires.iter_mut() {
            w.jam = JamParams::none();
        }
        let mut j = Joint3d::new(p).unwrap();
        for t in targets(sign) {
            // α to t, β to −t/2: both planes move, in opposite directions.
            for _ in 0..4000 {
                let [a, b] = j.angles_deg();
                let va = p_law(a, t);
                let vb = p_law(b, -0.5 * t);
                j.step(DT, &[va[0], vb[0], va[1], vb[1]]).unwrap();
            }
            let (ae, be) = paper_eq3_deg(j.wire_insertions_mm());
            let [a, b] = j.angles_deg();
            worst[0] = worst[0].max((ae - a).abs());
            worst[1] = worst[1].max((be - b).abs());
        }
    }
    println!(
        "Eq. 3 on the simulated 3D joint, no jamming: worst α {:.2}°, β {:.2}°",
        worst[0], worst[1]
    );
    assert!(worst[0] < 1.0 && worst[1] < 1.0, "Eq. 3 off by {worst:?}°");
}

/// Angle error (deg) of the single-sensor reading: the jamming lag through
/// Eq. 2's local slope.
fn eq2_error(j: &Joint2d) -> f64 {
    paper_eq2_deg(j.wire_insertion_mm()) - paper_eq2_deg(j.wire().ideal_insertion_mm())
}

#[test]
fn jamming_errs_when_pushing_and_not_when_pulling() {
    let mut j = Joint2d::new(Joint2dParams::default()).unwrap();
    // Pulling side first (θ rises: the 2D wire comes out of its tube).
    let mut worst_pull: f64 = 0.0;
    for t in targets(1.0) {
        for _ in 0..2000 {
            j.step(DT, &p_law(j.angle_deg(), t)).unwrap();
            worst_pull = worst_pull.max(eq2_error(&j).abs());
        }
    }
    // Then all the way down to −20° (pushed in).
    let mut worst_push: f64 = 0.0;
    for t in (-20..=20).rev().map(f64::from) {
        for _ in 0..2000 {
            j.step(DT, &p_law(j.angle_deg(), t)).unwrap();
            worst_push = worst_push.max(eq2_error(&j).abs());
        }
    }
    println!("2D jamming: single-sensor error pulling {worst_pull:.3}°, pushing {worst_push:.3}°");
    // Pulling: only the quantisation (0.01 mm ≈ 0.06°) remains. Pushing:
    // an order of magnitude more (Eq. 2 flattens at deep insertion, so the
    // 2D error in degrees is smaller than the 3D single-sensor one).
    assert!(worst_pull < 0.1, "error while pulling {worst_pull}");
    assert!(
        worst_push > 0.5 && worst_push > 10.0 * worst_pull,
        "jamming error while pushing only {worst_push}"
    );
}

#[test]
fn only_the_pushed_wire_of_a_pair_jams() {
    let mut j = Joint3d::new(Joint3dParams::default()).unwrap();
    let (mut single, mut diff) = (0.0f64, 0.0f64);
    let lags = |j: &Joint3d| {
        let w = j.wires();
        (
            w[0].ideal_insertion_mm() - w[0].insertion_mm(),
            w[2].ideal_insertion_mm() - w[2].insertion_mm(),
        )
    };
    let mut at_top = (0.0, 0.0);
    let mut at_bottom = (0.0, 0.0);
    let sweep = (0..=20)
        .chain((-20..20).rev())
        .chain(-20..=0)
        .map(f64::from);
    for (k, t) in sweep.enumerate() {
        for _ in 0..2000 {
            let [a, _] = j.angles_deg();
            let va = p_law(a, t);
            j.step(DT, &[va[0], 0.0, va[1], 0.0]).unwrap();
            let (lag1, lag3) = lags(&j);
            // Single sensor: each wire carries half of Eq. 3's 2.727 °/mm.
            single = single
                .max(2.0 * 2.727 * lag1.abs())
                .max(2.0 * 2.727 * lag3.abs());
            // Differential law: what the jam does to Eq. 3's α.
            diff = diff.max((2.727 * (lag3 - lag1)).abs());
        }
        if k == 20 {
            at_top = lags(&j);
        }
        if k == 60 {
            at_bottom = lags(&j);
        }
    }
    println!("3D α jamming: single-sensor error up to {single:.3}°, differential up to {diff:.3}°");
    println!("lags (wire 1, wire 3) at +20°: {at_top:.3?} mm, at −20°: {at_bottom:.3?} mm");
    assert!(single > 1.0, "single-sensor jamming error only {single}");
    // At +20° wire 3 was pushed in and lags; wire 1 was pulled out and has
    // shed its lag. At −20° the other way round.
    assert!(
        at_top.1 > 0.1 && at_top.0 < at_top.1 / 3.0,
        "at +20°: {at_top:?}"
    );
    assert!(
        at_bottom.0 > 0.1 && at_bottom.1 < at_bottom.0 / 3.0,
        "at −20°: {at_bottom:?}"
    );
    assert!(
        diff < 0.6 * single,
        "differential error {diff} vs single {single}"
    );
}

/// Least-squares fit of `y ≈ Σ c_k f_k(x)`; returns the coefficients.
fn lstsq<const N: usize>(rows: &[([f64; N], f64)]) -> [f64; N] {
    let a = nalgebra::DMatrix::from_fn(rows.len(), N, |i, k| rows[i].0[k]);
    let b = nalgebra::DVector::from_iterator(rows.len(), rows.iter().map(|r| r.1));
    let c = a.svd(true, true).solve(&b, 1e-12).expect("least squares");
    core::array::from_fn(|k| c[k])
}

fn eval<const N: usize>(c: &[f64; N], f: [f64; N]) -> f64 {
    c.iter().zip(f).map(|(c, f)| c * f).sum()
}

/// The paper calibrated against camera images of a *held* joint. A stepped
/// sweep (2° steps over ±20°, up, down and up again, 8 s dwell so the
/// antagonist coil is cold again at each sample) of the simulated 3D joint
/// with jamming: a single-sensor quadratic cannot follow the link's sink
/// (V-shaped in α) nor the jamming, while the paper's threshold switching
/// (Eq. 4: differential above α_th, the pulled wire's quadratic below)
/// fitted on the same data stays under 1° in both planes.
///
/// Independent of host-tools' calibrator on purpose (SVD least squares
/// here), so it checks the plant, not that tool.
#[test]
fn stepped_sweep_supports_threshold_switching() {
    let mut j = Joint3d::new(Joint3dParams::default()).unwrap();
    let mut targets: Vec<f64> = (0..=20).step_by(2).map(f64::from).collect();
    targets.extend((-20..20).rev().step_by(2).map(f64::from));
    targets.extend((-20..=20).step_by(2).map(f64::from));
    let mut samples = Vec::new(); // (d1..d4, α, β)
    for t in targets {
        for _ in 0..8000 {
            let [a, b] = j.angles_deg();
            let va = p_law(a, t);
            let vb = p_law(b, -0.8 * t);
            j.step(DT, &[va[0], vb[0], va[1], vb[1]]).unwrap();
        }
        samples.push((j.wire_insertions_mm(), j.angles_deg()));
    }
    for (plane, minus, plus) in [(0usize, 0usize, 2usize), (1, 1, 3)] {
        let data: Vec<(f64, f64, f64)> = samples
            .iter()
            .map(|(d, a)| (d[minus], d[plus], a[plane]))
            .collect();
        let single_c = lstsq(
            &data
                .iter()
                .map(|&(_, p, a)| ([p * p, p, 1.0], a))
                .collect::<Vec<_>>(),
        );
        let single = data
            .iter()
            .map(|&(_, p, a)| (eval(&single_c, [p * p, p, 1.0]) - a).abs())
            .fold(0.0, f64::max);
        let mut best = (f64::MAX, 0.0);
        for th in (-150..=150).step_by(5).map(|k| k as f64 / 10.0) {
            let hi: Vec<_> = data
                .iter()
                .filter(|s| s.2 >= th)
                .map(|&(m, p, a)| ([p - m, 1.0], a))
                .collect();
            let lo: Vec<_> = data
                .iter()
                .filter(|s| s.2 < th)
                .map(|&(_, p, a)| ([p * p, p, 1.0], a))
                .collect();
            if hi.len() < 4 || lo.len() < 4 {
                continue;
            }
            let (c0, c1) = (lstsq(&hi), lstsq(&lo));
            let worst = data
                .iter()
                .map(|&(m, p, a)| {
                    let diff = eval(&c0, [p - m, 1.0]);
                    let est = if diff >= th {
                        diff
                    } else {
                        eval(&c1, [p * p, p, 1.0])
                    };
                    (est - a).abs()
                })
                .fold(0.0, f64::max);
            if worst < best.0 {
                best = (worst, th);
            }
        }
        println!("plane {plane}: single-sensor quadratic max error {single:.2}°, threshold switching {:.2}° at θ_th = {:.1}°", best.0, best.1);
        assert!(single > 1.0, "plane {plane}: single sensor only {single}°");
        assert!(
            best.0 < 1.0,
            "plane {plane}: threshold switching {}°",
            best.0
        );
    }
}
