//! Estimation on synthetic probe trials generated with known parameters on
//! the shipped object (seed 002 §4): per-trial weighted fits, weighted vs
//! uniform on the contact-area artefact (Fig. 8), damping tensor by DSVD,
//! Rayleigh coefficient (Eq. 13), stiffness ratio, column spreading;
//! parallel = serial, bit-identical reruns.
use plant_viscoelastic::dgfm::Dgfm;
use plant_viscoelastic::estimate::*;
use plant_viscoelastic::fit::*;
use plant_viscoelastic::measure::*;
use plant_viscoelastic::{ColumnParams, Mat3, TractionModel, Vec3, ViscoObject};
use std::sync::OnceLock;

fn object_dgfm() -> &'static Dgfm {
    static D: OnceLock<Dgfm> = OnceLock::new();
    D.get_or_init(|| Dgfm::default_object().expect("default object builds"))
}

// Truth from the seed's Fig. 8 weighted fit (k1 = 1.81, k2 = 0.528,
// b = 0.137): r = k2/k1 ≈ 0.29, Rayleigh b = b/(k1 k2/(k1+k2)) ≈ 0.33 s.
const RATIO: f64 = 0.29;
const RAYLEIGH_B_S: f64 = 0.33;

fn truths() -> Vec<VertexTruth> {
    let d = object_dgfm();
    [10usize, 80]
        .iter()
        .map(|&v| VertexTruth::from_dgfm(d, v, RATIO, RAYLEIGH_B_S).unwrap())
        .collect()
}

fn rel_errors(t: &Trial, f: &TrialFit, truths: &[VertexTruth]) -> [f64; 3] {
    let tr = truths.iter().find(|x| x.vertex == t.vertex).unwrap();
    let (k1, k2, b) = tr.trial_scalars(t.direction);
    [
        (f.k1_n_per_m / k1 - 1.0).abs(),
        (f.k2_n_per_m / k2 - 1.0).abs(),
        (f.b_n_s_per_m / b - 1.0).abs(),
    ]
}

fn worst(e: [f64; 3]) -> f64 {
    e.into_iter().fold(0.0, f64::max)
}

#[test]
fn weighted_fit_recovers_k1_k2_b_within_5_percent_on_noisy_trials() {
    let truths = truths();
    // Sensor noise on, contact-area artefact off: 2 vertices × 5 directions × 2 speeds.
    let protocol = ProbeProtocol {
        contact_growth_fraction: 0.0,
        ..ProbeProtocol::default()
    };
    let trials = simulate_campaign(object_dgfm(), &truths, &protocol, 11).unwrap();
    assert_eq!(trials.len(), 20);
    let fits = fit_trials(&trials, Weighting::Seed, NelderMeadOptions::default());
    for (t, f) in trials.iter().zip(&fits) {
        let e = rel_errors(t, f.as_ref().unwrap(), &truths);
        assert!(
            worst(e) < 0.05,
            "vertex {} speed {} dir {:?}: relative errors k1,k2,b = {e:?}",
            t.vertex,
            t.speed_m_per_s,
            t.direction
        );
    }
}

#[test]
fn on_the_contact_area_artefact_the_weighted_fit_beats_the_uniform_one() {
    let truths = truths();
    let trials = simulate_campaign(object_dgfm(), &truths, &ProbeProtocol::default(), 12).unwrap();
    let weighted = fit_trials(&trials, Weighting::Seed, NelderMeadOptions::default());
    let uniform = fit_trials(&trials, Weighting::Uniform, NelderMeadOptions::default());
    for ((t, w), u) in trials.iter().zip(&weighted).zip(&uniform) {
        let (ew, eu) = (
            rel_errors(t, w.as_ref().unwrap(), &truths),
            rel_errors(t, u.as_ref().unwrap(), &truths),
        );
        // The seed's Fig. 8: uniform weighting bends b (and k1) to fit the
        // front, the weighted fit keeps to the peak and tail.
        assert!(
            worst(ew) < worst(eu),
            "speed {}: weighted {ew:?} vs uniform {eu:?}",
            t.speed_m_per_s
        );
        assert!(
            worst(eu) > 0.1,
            "the artefact should spoil the uniform fit: {eu:?}"
        );
        // At the high speed the weighted fit still meets 5 %; at the low
        // speed the peak overshoot is small and the artefact still biases it
        // (measured, seed 12: k1 +17…+25 %, b +30…+43 %; fast trials within
        // 2.4 %): reported, not asserted.
        if t.speed_m_per_s > 0.01 {
            assert!(worst(ew) < 0.05, "fast trial, weighted: {ew:?}");
        }
    }
}

#[test]
fn damping_tensor_rayleigh_and_stiffness_ratio_recover_the_generating_values() {
    let d = object_dgfm();
    let truths = truths();
    let protocol = ProbeProtocol {
        contact_growth_fraction: 0.0,
        ..ProbeProtocol::default()
    };
    let trials = simulate_campaign(d, &truths, &protocol, 13).unwrap();
    let fits = fit_trials(&trials, Weighting::Seed, NelderMeadOptions::default());
    let est = estimate_all(d, &trials, &fits).unwrap();
    assert_eq!(est.len(), 4, "2 vertices × 2 speeds");
    let frob = |m: Mat3| m.norm();
    for e in &est {
        let tr = truths.iter().find(|t| t.vertex == e.vertex).unwrap();
        let b_true = tr.damping_tensor_n_s_per_m();
        let b_est = e
            .damping_tensor_n_s_per_m
            .expect("five directions: not singular");
        let diff = b_est + b_true.scale(-1.0);
        assert!(
            frob(diff) < 0.05 * frob(b_true),
            "vertex {}: tensor error {}",
            e.vertex,
            frob(diff) / frob(b_true)
        );
        assert!(
            (e.rayleigh_b_s / RAYLEIGH_B_S - 1.0).abs() < 0.05,
            "Rayleigh b {}",
            e.rayleigh_b_s
        );
        assert!((e.ratio / RATIO - 1.0).abs() < 0.05, "ratio {}", e.ratio);
        let (k1, k2) = tr.multipliers();
        assert!(
            (e.k1 / k1 - 1.0).abs() < 0.05 && (e.k2 / k2 - 1.0).abs() < 0.05,
            "k1 {} k2 {}",
            e.k1,
            e.k2
        );
    }
    // Column spreading: measured columns carry their estimate, others none.
    let fast: Vec<VertexEstimate> = est
        .iter()
        .copied()
        .filter(|e| e.speed_m_per_s > 0.01)
        .collect();
    let params = spread_columns(d.len(), &fast, 1.0, false).unwrap();
    let ColumnParams::Rayleigh(p) = &params else {
        panic!("asked for Rayleigh")
    };
    assert!(
        (p[10].b_s() / RAYLEIGH_B_S - 1.0).abs() < 0.05
            && (p[80].ratio() / RATIO - 1.0).abs() < 0.05
    );
    assert_eq!(p[11].b_s(), 0.0);
    let mags = params.damping_magnitude_n_s_per_m(d);
    assert!(mags[10] > 0.0 && mags[11] == 0.0);
    // The spread parameters drive the object.
    let mut obj = ViscoObject::new(d.clone(), params, 1e-3).unwrap();
    obj.set_traction(10, Vec3::new(0.0, 0.0, -1e3)).unwrap();
    let mut u = vec![Vec3::zeros(); d.len()];
    obj.step(1e-3, &mut u).unwrap();
    assert!(u[10].norm() > 0.0);
    let tensor = spread_columns(d.len(), &fast, 1.0, true).unwrap();
    assert!(matches!(tensor, ColumnParams::Tensor { .. }));
}

#[test]
fn dsvd_damping_tensor_solves_exact_data_and_abandons_singular_vertices() {
    // A general (non-Rayleigh, non-symmetric) tensor and directions within
    // 30° of a normal, as the probe uses.
    let b_true = Mat3::new(40.0, 5.0, -3.0, 2.0, 25.0, 4.0, -1.0, 6.0, 60.0);
    let protocol = ProbeProtocol::default();
    let dirs = protocol.directions([0.3, -0.2, 0.9]);
    let mut fdirs = Vec::new();
    let mut b_n = Vec::new();
    for d in &dirs {
        let q = b_true * Vec3::from(*d);
        b_n.push(q.norm());
        fdirs.push(q.normalize().into());
    }
    let b = damping_tensor(&dirs, &fdirs, &b_n, DSVD_DAMPING_REL)
        .unwrap()
        .unwrap();
    for r in 0..3 {
        for c in 0..3 {
            assert!(
                (b[(r, c)] - b_true[(r, c)]).abs() < 1e-3 * 60.0,
                "entry ({r},{c}): {} vs {}",
                b[(r, c)],
                b_true[(r, c)]
            );
        }
    }
    // One direction only (several trials along it): singular → abandoned.
    let same = vec![dirs[0]; 4];
    assert_eq!(
        damping_tensor(&same, &fdirs[..4], &b_n[..4], DSVD_DAMPING_REL).unwrap(),
        None
    );
    // Nearly coplanar directions: DSVD still returns a finite tensor.
    let mut flat = dirs.clone();
    for d in &mut flat {
        d[2] *= 1e-5;
    }
    let bt = damping_tensor(&flat, &fdirs, &b_n, DSVD_DAMPING_REL)
        .unwrap()
        .unwrap();
    assert!(bt.iter().all(|v| v.is_finite()));
    // Rayleigh Eq. 13 (least-squares form) recovers b from B = b K exactly.
    let k = Mat3::new(
        1300.0, -20.0, 50.0, -20.0, 1000.0, -110.0, 50.0, -110.0, 1800.0,
    );
    assert!((rayleigh_coefficient(&k, &(k * 0.27)) - 0.27).abs() < 1e-12);
}

#[test]
fn parallel_fits_equal_serial_fits_and_reruns_are_bit_identical() {
    let truths = truths();
    let protocol = ProbeProtocol {
        speeds_m_per_s: vec![0.02],
        tilted_directions: 2,
        ..ProbeProtocol::default()
    };
    let a = simulate_campaign(object_dgfm(), &truths, &protocol, 99).unwrap();
    let b = simulate_campaign(object_dgfm(), &truths, &protocol, 99).unwrap();
    assert_eq!(a, b);
    let c = simulate_campaign(object_dgfm(), &truths, &protocol, 100).unwrap();
    assert_ne!(a[0].force_n, c[0].force_n, "another seed gives other noise");
    let par = fit_trials(&a, Weighting::Seed, NelderMeadOptions::default());
    let ser = fit_trials_serial(&a, Weighting::Seed, NelderMeadOptions::default());
    assert_eq!(par, ser);
}

#[test]
fn fits_of_bad_series_are_errors() {
    let t = [0.0, 0.001, 0.001];
    let u = [0.0, 1e-3, 2e-3];
    let f = [0.0, 1.0, 2.0];
    assert!(fit_trial(&t, &u, &f, Weighting::Seed, NelderMeadOptions::default()).is_err());
    let t = [0.0, 0.001, 0.002];
    assert!(fit_trial(
        &t,
        &u,
        &[0.0, f64::NAN, 1.0],
        Weighting::Seed,
        NelderMeadOptions::default()
    )
    .is_err());
    assert!(fit_trial(
        &t,
        &u,
        &[0.0, 0.0, 0.0],
        Weighting::Seed,
        NelderMeadOptions::default()
    )
    .is_err());
    assert!(simulate_force(1.0, 2.0, 0.5, &t, &u[..2]).is_err());
}

/// The refusal of undetermined fits on a simulated probe campaign (noise
/// and the contact-area artefact on, 5 and 20 mm/s, both weightings)
/// against the known truth: every fit it accepts is within 60 % of the
/// generating parameters (the seed-weighted slow trials carry the known
/// slow-trial bias, up to 47 % in b), and every fit it refuses is off by
/// more than 100 % (uniform weighting on the slow trials: b off by
/// ≈ 3300 %, k1 free by a factor of ~10⁹). Measured uncertainty factors:
/// seed weighting ≤ 1.3 (20 mm/s) and ≤ 8.3 (5 mm/s); uniform 5.3
/// (20 mm/s) and ≥ 4·10⁵ (5 mm/s), against the threshold of 100.
#[test]
fn fits_of_the_probe_campaign_are_refused_exactly_when_they_are_wrong() {
    let truths = truths();
    let trials = simulate_campaign(object_dgfm(), &truths, &ProbeProtocol::default(), 21).unwrap();
    let (mut accepted, mut refused) = (0, 0);
    for weighting in [Weighting::Seed, Weighting::Uniform] {
        let fits = fit_trials(&trials, weighting, NelderMeadOptions::default());
        for (t, f) in trials.iter().zip(&fits) {
            let f = f.as_ref().unwrap();
            let err = worst(rel_errors(t, f, &truths));
            let what = format!(
                "{weighting:?} vertex {} speed {}: error {err:.3}, uncertainty {:.3?}",
                t.vertex, t.speed_m_per_s, f.ln_uncertainty
            );
            match f.check_determined() {
                Ok(()) => {
                    accepted += 1;
                    assert!(err < 0.6, "accepted: {what}");
                }
                Err(_) => {
                    refused += 1;
                    assert!(err > 1.0, "refused: {what}");
                }
            }
        }
    }
    // Seed weighting at both speeds and uniform at 20 mm/s accepted,
    // uniform at 5 mm/s refused.
    assert_eq!((accepted, refused), (30, 10));
}

/// A trial that cannot determine the parameters is refused, not printed:
/// a constant force under a constant displacement (k1 = 2.3e17 and
/// b = 3e-10 came out, with no warning) and a purely elastic force (no
/// relaxation). And a trial's forces in any unit give the same fit, scaled:
/// forces of 1e150 N overflowed the cost (rms residual 1.3e144 N, exit 0).
#[test]
fn fits_the_data_do_not_determine_are_refused_and_scale_does_not_matter() {
    let t: Vec<f64> = (0..50).map(|k| f64::from(k) * 0.01).collect();
    let held = vec![1e-3; t.len()];
    let constant = vec![1.0; t.len()];
    let opts = NelderMeadOptions::default();
    let f = fit_trial(&t, &held, &constant, Weighting::Seed, opts).unwrap();
    let e = f.check_determined().unwrap_err().to_string();
    assert!(e.contains("does not determine k1 and b"), "{e}");
    let ramp: Vec<f64> = t
        .iter()
        .map(|&s| 1e-4 * (1.0 + (s / 0.1).min(1.0)))
        .collect();
    let elastic: Vec<f64> = ramp.iter().map(|u| 500.0 * u).collect();
    let f = fit_trial(&t[..], &ramp, &elastic, Weighting::Seed, opts).unwrap();
    assert!(f.check_determined().is_err(), "{f:?}");
    // A relaxing trial, in newtons and in units 1e150 times smaller.
    let relaxing = simulate_force(800.0, 400.0, 60.0, &t, &ramp).unwrap();
    let a = fit_trial(&t, &ramp, &relaxing, Weighting::Seed, opts).unwrap();
    a.check_determined().unwrap();
    assert!((a.k1_n_per_m / 800.0 - 1.0).abs() < 1e-3, "{a:?}");
    let huge: Vec<f64> = relaxing.iter().map(|f| f * 1e150).collect();
    let b = fit_trial(&t, &ramp, &huge, Weighting::Seed, opts).unwrap();
    b.check_determined().unwrap();
    for (x, y) in [
        (a.k1_n_per_m, b.k1_n_per_m),
        (a.k2_n_per_m, b.k2_n_per_m),
        (a.b_n_s_per_m, b.b_n_s_per_m),
    ] {
        assert!((y / (x * 1e150) - 1.0).abs() < 1e-6, "{x:e} vs {y:e}");
    }
}
