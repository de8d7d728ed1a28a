//! Issue 29: the fit checks its own answer. GCV no longer collapses on a
//! sparse noisy contour, a collapsed or self-crossing fit is flagged
//! `unverified`, smoothness does not depend on the knots, absurd λ and
//! negative radii are refused, and the random campaign's short form
//! reports no wrong answer as verified. References: closed forms (πab,
//! Ramanujan's perimeter, 2π/R) and quadratures of the true shapes' own
//! formulas, never the splines.
use plant_contour::fit::Solver;
use plant_contour::identify::campaign::{self, TrueShape};
use plant_contour::identify::checks::{gap_caps, DenseContour, Flag, Status, GAP_AREA_LIMIT};
use plant_contour::identify::contours::{fit_contours, ContourFitSpec, ContourModel};
use plant_contour::identify::data::{ContourData, FrameData};
use plant_contour::identify::gcv::Lambda;
use plant_contour::identify::tracked::{Point, Signature};
use plant_contour::ContourError;
use std::f64::consts::{PI, TAU};

/// 23 noisy points of an ellipse (a = 81.985, b = 53.842, σ ≈ 1.5) at
/// random angles: today's main chose λ = 2.5e-12 by GCV on them and
/// reported area 74,174 (5.3× the truth) and perimeter 51,527 (120×),
/// exit 0 — the collapse of issue 29.
const SPARSE_ELLIPSE: &str = "1.134,-152.733 -5.550,-135.156 -51.590,-108.155 -53.174,-107.246 -108.542,-110.551 -112.555,-106.467 -122.773,-114.126 -123.709,-113.389 -137.854,-123.608 -151.844,-135.715 -161.920,-154.940 -161.284,-157.442 -160.035,-164.440 -158.318,-173.043 -156.349,-182.331 -152.141,-182.230 -140.255,-199.337 -100.136,-213.372 -36.463,-206.963 -30.871,-201.127 -11.067,-185.987 -4.193,-178.545 3.119,-162.926";
const SPARSE_A: f64 = 81.98488673794117;
const SPARSE_B: f64 = 53.84164107337456;

fn sparse_points() -> Vec<Point> {
    SPARSE_ELLIPSE
        .split_whitespace()
        .map(|p| {
            let (x, y) = p.split_once(',').unwrap();
            (x.parse().unwrap(), y.parse().unwrap())
        })
        .collect()
}

/// Ramanujan's second approximation of an ellipse's perimeter (relative
/// error below 10⁻⁹ at b/a ≥ 0.4).
fn ellipse_perimeter(a: f64, b: f64) -> f64 {
    let h = ((a - b) / (a + b)).powi(2);
    PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()))
}

fn spec(model: ContourModel, knots: Option<usize>, lambda: Lambda) -> ContourFitSpec {
    ContourFitSpec {
        model: Some(model),
        knots,
        time_knots: None,
        lambda,
        solver: Solver::Reduced,
        samples: 64,
        signed_radii: false,
    }
}

fn one_frame(frame: FrameData) -> ContourData {
    ContourData {
        file: "test".into(),
        frames: vec![(0.0, frame)],
    }
}

#[test]
fn gcv_does_not_collapse_on_a_sparse_noisy_ellipse() {
    let data = one_frame(FrameData::Points(sparse_points()));
    let fit = fit_contours(&data, &spec(ContourModel::Curve, None, Lambda::Gcv)).unwrap();
    let r = &fit.frames[0].result;
    let (area, perimeter) = (
        PI * SPARSE_A * SPARSE_B,
        ellipse_perimeter(SPARSE_A, SPARSE_B),
    );
    println!(
        "area {:.1} (truth {area:.1}), perimeter {:.2} (truth {perimeter:.2}), λ {:.3e}, tr H {:.2} of 23, {:?}",
        r.area,
        r.perimeter,
        r.lambda.unwrap(),
        r.trace_hat.unwrap(),
        r.checks
    );
    assert!((r.area / area - 1.0).abs() < 0.05, "area {}", r.area);
    assert!(
        (r.perimeter / perimeter - 1.0).abs() < 0.05,
        "perimeter {}",
        r.perimeter
    );
    assert_eq!(r.checks.status, Status::Verified, "{:?}", r.checks);
    // The bound at work: tr H stays below N/γ.
    assert!(r.trace_hat.unwrap() < 23.0 / 1.4);
}

#[test]
fn a_collapsed_or_self_crossing_fit_is_flagged_unverified() {
    // λ forced to 10⁻¹² with a knot per point: the fit main's GCV chose.
    let data = one_frame(FrameData::Points(sparse_points()));
    let fit = fit_contours(
        &data,
        &spec(ContourModel::Curve, Some(23), Lambda::Fixed(1e-12)),
    )
    .unwrap();
    let r = &fit.frames[0].result;
    assert!(r.area > 2.0 * PI * SPARSE_A * SPARSE_B, "area {}", r.area);
    assert_eq!(r.checks.status, Status::Unverified);
    assert!(
        r.checks.flags.contains(&Flag::AreaDisagreesWithData)
            && r.checks.flags.contains(&Flag::PerimeterDisagreesWithData),
        "{:?}",
        r.checks.flags
    );
    // A figure eight (Gerono's lemniscate) as a closed curve crosses
    // itself; a signature through its centre (r(θ) = cos 2θ + 0.2 dips
    // below 0) does too.
    let eight: Vec<Point> = (0..48)
        .map(|k| {
            let t = TAU * k as f64 / 48.0;
            (10.0 * t.cos(), 10.0 * t.sin() * t.cos())
        })
        .collect();
    let fit = fit_contours(
        &one_frame(FrameData::Points(eight)),
        &spec(ContourModel::Curve, None, Lambda::Fixed(1e-6)),
    )
    .unwrap();
    assert!(
        fit.frames[0]
            .result
            .checks
            .flags
            .contains(&Flag::SelfIntersection),
        "{:?}",
        fit.frames[0].result.checks
    );
    let angles: Vec<f64> = (0..40).map(|k| TAU * k as f64 / 40.0).collect();
    let radii: Vec<f64> = angles.iter().map(|t| (2.0 * t).cos() + 0.2).collect();
    let sig = Signature::new("s", (0.0, 0.0), &angles, &radii).unwrap();
    let mut signed = spec(ContourModel::Signature, Some(20), Lambda::Fixed(1e-6));
    signed.signed_radii = true;
    let fit = fit_contours(&one_frame(FrameData::Signature(sig)), &signed).unwrap();
    assert!(fit.frames[0]
        .result
        .checks
        .flags
        .contains(&Flag::SelfIntersection));
}

/// `∫₀^{2π} f` by the composite Simpson rule on `n` (even) intervals.
fn simpson(f: impl Fn(f64) -> f64, n: usize) -> f64 {
    let h = TAU / n as f64;
    (0..=n)
        .map(|k| {
            let w = if k == 0 || k == n {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * f(h * k as f64)
        })
        .sum::<f64>()
        * h
        / 3.0
}

#[test]
fn smoothness_and_bending_energy_do_not_depend_on_the_knots() {
    // An ellipse a = 3, b = 2 about its centre, 200 exact radii.
    let (a, b) = (3.0_f64, 2.0_f64);
    let r = |t: f64| a * b / ((b * t.cos()).powi(2) + (a * t.sin()).powi(2)).sqrt();
    // References from the closed form: r_θθ by central differences of
    // r(θ), the bending energy of the parametric ellipse
    // ∫ a²b² / (a² sin²t + b² cos²t)^{5/2} dt.
    let h = 1e-4;
    let c_ref = simpson(
        |t| ((r(t + h) - 2.0 * r(t) + r(t - h)) / (h * h)).powi(2),
        4000,
    );
    let e_ref = simpson(
        |t| a * a * b * b / ((a * t.sin()).powi(2) + (b * t.cos()).powi(2)).powf(2.5),
        4000,
    );
    let n = 200;
    let angles: Vec<f64> = (0..n).map(|k| TAU * k as f64 / n as f64).collect();
    let radii: Vec<f64> = angles.iter().map(|&t| r(t)).collect();
    let sig = Signature::new("e", (0.0, 0.0), &angles, &radii).unwrap();
    let pts: Vec<Point> = angles.iter().map(|&t| (a * t.cos(), b * t.sin())).collect();
    for knots in [24, 48, 96] {
        let fit = fit_contours(
            &one_frame(FrameData::Signature(sig.clone())),
            &spec(ContourModel::Signature, Some(knots), Lambda::Fixed(1e-9)),
        )
        .unwrap();
        let res = &fit.frames[0].result;
        let c = res.smoothness.unwrap();
        println!("knots {knots}: C = {c:.5} (reference {c_ref:.5}), ∫κ²dl = {:.5} (reference {e_ref:.5})", res.bending_energy);
        assert!(
            (c / c_ref - 1.0).abs() < 0.01,
            "knots {knots}: C {c} vs {c_ref}"
        );
        assert!((res.bending_energy / e_ref - 1.0).abs() < 0.01);
        assert!((res.perimeter / ellipse_perimeter(a, b) - 1.0).abs() < 1e-4);
        let fit = fit_contours(
            &one_frame(FrameData::Points(pts.clone())),
            &spec(ContourModel::Curve, Some(knots), Lambda::Fixed(1e-9)),
        )
        .unwrap();
        let e = fit.frames[0].result.bending_energy;
        assert!(
            (e / e_ref - 1.0).abs() < 0.02,
            "curve, knots {knots}: {e} vs {e_ref}"
        );
    }
    // A circle of radius 5: C = 0, ∫κ² dl = 2π/5.
    let circle = Signature::new("c", (1.0, 2.0), &angles, &vec![5.0; n]).unwrap();
    let fit = fit_contours(
        &one_frame(FrameData::Signature(circle)),
        &spec(ContourModel::Signature, Some(30), Lambda::Fixed(1e-3)),
    )
    .unwrap();
    let res = &fit.frames[0].result;
    assert!(res.smoothness.unwrap().abs() < 1e-8, "{:?}", res.smoothness);
    assert!((res.bending_energy - TAU / 5.0).abs() < 1e-9);
    assert!((res.perimeter - TAU * 5.0).abs() < 1e-9);
}

#[test]
fn absurd_lambda_and_negative_radii_are_refused_by_name() {
    let data = one_frame(FrameData::Points(sparse_points()));
    for lam in [1e308, 1e7] {
        let e =
            fit_contours(&data, &spec(ContourModel::Curve, None, Lambda::Fixed(lam))).unwrap_err();
        assert!(
            matches!(e, ContourError::InvalidParameter { name: "lambda", .. }),
            "{e}"
        );
    }
    let sig = Signature::new("s", (0.0, 0.0), &[0.0, 2.0, 4.0], &[1.0, -0.5, 1.0]).unwrap();
    let data = one_frame(FrameData::Signature(sig));
    let e = fit_contours(
        &data,
        &spec(ContourModel::Signature, Some(4), Lambda::Fixed(1e-3)),
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("point 1") && e.to_string().contains("negative"),
        "{e}"
    );
}

#[test]
fn campaign_truth_is_the_closed_form_and_no_wrong_answer_is_verified() {
    // The truth of the campaign against the closed form: πab and
    // Ramanujan's perimeter.
    let e = TrueShape::Ellipse {
        a: 7.0,
        b: 3.0,
        turn_rad: 0.3,
    };
    let (area, perimeter) = e.area_and_perimeter();
    assert!((area / (PI * 21.0) - 1.0).abs() < 1e-6, "{area}");
    assert!((perimeter / ellipse_perimeter(7.0, 3.0) - 1.0).abs() < 1e-6);
    // The short form: the first 40 cases of the full campaign (seed 29;
    // the full 500 are the example `contour_campaign`).
    let (summary, outcomes) = campaign::run(29, 40);
    println!("{summary:?}");
    for o in outcomes.iter().filter(|o| o.wrong()) {
        println!("wrong: {o:?}");
    }
    assert_eq!(summary.wrong, 0);
    assert!(summary.solved >= 36, "solved {} of 40", summary.solved);
}

#[test]
fn a_sparse_ellipse_whose_gap_the_fit_bridges_is_verified() {
    // Case 168 of the campaign's reported seed 2026: an ellipse 39.7 × 29.8
    // from 37 noisy points at random angles (σ = 2.5 % of the size), whose
    // largest gap spans a chord of 36.9. The fit is within 1.7 % of the
    // truth (a 20,000-gon of the formula), but the chord cap of the fit's
    // largest curvature, κ_max g³/12, is 6.1 % of the area, and so it was
    // left unverified. Against the fit's own bridge, with the ends held by
    // the data on either side, the gap hides at most ≈ 5 %.
    let o = campaign::run_case(2026, 168);
    let (local, global) = o.gap_bounds.unwrap();
    println!("{o:?}");
    assert!(o.right(), "{:?} {:?}", o.area_error, o.perimeter_error);
    assert!(global > GAP_AREA_LIMIT, "the chord cap {global}");
    assert!(local <= GAP_AREA_LIMIT, "the bridge bound {local}");
    assert!(o.verified, "{:?}", o.flags);
}

/// A circle of radius `radius` with a bulge `radius·height·exp(−((θ − θ₀)/w)²)`
/// at θ₀ = π, sampled at `n` equal angles outside the gap |θ − π| < `half_gap`,
/// with the noise `sigma` on x and y (seeded).
fn bulge_in_gap(
    radius: f64,
    height: f64,
    w: f64,
    half_gap: f64,
    n: usize,
    sigma: f64,
) -> Vec<Point> {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand::rngs::StdRng::seed_from_u64(29);
    let noise = Normal::new(0.0, sigma).unwrap();
    let r = |t: f64| radius * (1.0 + height * (-((t - PI) / w).powi(2)).exp());
    (0..n)
        .map(|k| PI + half_gap + (TAU - 2.0 * half_gap) * k as f64 / (n - 1) as f64)
        .map(|t| {
            (
                r(t) * t.cos() + noise.sample(&mut rng),
                r(t) * t.sin() + noise.sample(&mut rng),
            )
        })
        .collect()
}

#[test]
fn a_bulge_hidden_in_a_gap_stays_unverified() {
    // A circle (R = 50) with a bulge of 8.1 % of its area (height 0.57 R,
    // width 0.25 rad) entirely inside a 90° gap of its 48 points: the fit
    // sees a circle and misses the bulge, and the gap check says that
    // the gap could hide it — under either bound. The bulge's area
    // ∫½(r² − R²)dθ is the reference, by Simpson on the formula.
    let (radius, height, w) = (50.0, 0.57, 0.25);
    let bulge = simpson(
        |t| {
            let r = radius * (1.0 + height * (-((t - PI) / w).powi(2)).exp());
            0.5 * (r * r - radius * radius)
        },
        2000,
    );
    let area = PI * radius * radius + bulge;
    assert!(bulge / area > 0.07, "bulge {:.3}", bulge / area);
    for model in [ContourModel::Curve, ContourModel::Signature] {
        let pts = bulge_in_gap(radius, height, w, PI / 4.0, 48, 0.25);
        let fit = fit_contours(
            &one_frame(FrameData::Points(pts)),
            &spec(model, None, Lambda::Gcv),
        )
        .unwrap();
        let r = &fit.frames[0].result;
        println!(
            "{model:?}: area {:.1} (truth {area:.1}), {:?}",
            r.area, r.checks
        );
        assert!(
            r.area / area - 1.0 < -0.05,
            "the fit misses the bulge: {}",
            r.area
        );
        assert!(r.checks.flags.contains(&Flag::DataGap), "{:?}", r.checks);
        assert_eq!(r.checks.status, Status::Unverified);
    }
}

#[test]
fn the_gap_bound_of_a_circle_is_its_closed_form() {
    // A circle of radius R sampled finely as the fit, and data at equal
    // angles 0.1 rad apart but for one gap of φ = 1.2 rad, no noise: the
    // largest gap's bound is (κ_max + F) ℓ³/32 with κ_max = F = 1/R and
    // ℓ = Rφ; the chord cap is g³/12R with g = 2R sin(φ/2).
    let radius = 20.0;
    let m = 4000;
    let t: Vec<f64> = (0..m).map(|k| TAU * k as f64 / m as f64).collect();
    let dense = DenseContour {
        period: TAU,
        points: t
            .iter()
            .map(|&a| (radius * a.cos(), radius * a.sin()))
            .collect(),
        kappa: vec![1.0 / radius; m],
        t,
    };
    let phi = 1.2;
    let mut angles = vec![0.0];
    while angles.last().unwrap() + 0.1 < TAU - phi - 1e-9 {
        angles.push(angles.last().unwrap() + 0.1);
    }
    let last = *angles.last().unwrap();
    let gap = TAU - last;
    let data: Vec<Point> = angles
        .iter()
        .map(|&a| (radius * a.cos(), radius * a.sin()))
        .collect();
    let caps = gap_caps(&data, &angles, &dense, 0.0).unwrap();
    let bridge = 2.0 / radius * (radius * gap).powi(3) / 32.0;
    let chord = 2.0 * radius * (gap / 2.0).sin();
    assert!(
        (caps.local / bridge - 1.0).abs() < 1e-3,
        "{} vs {bridge}",
        caps.local
    );
    assert!((caps.largest_gap / chord - 1.0).abs() < 1e-12);
    assert!((caps.global / (chord.powi(3) / (12.0 * radius)) - 1.0).abs() < 1e-12);
    // The ends' directions add σ√12/(b√c) each, times ℓ²/12.
    let noisy = gap_caps(&data, &angles, &dense, 0.1).unwrap();
    assert!(noisy.local > caps.local);
}
