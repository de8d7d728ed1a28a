//! Fujioka & Kano's spline machinery against closed forms and against
//! itself: the bases (Eq. 1–4), the two solvers of Eq. 27, periodicity at
//! the seam, the area functional, GCV and bad input.
use plant_contour::basis::{b3, b_spline, basis_elements, rem_period, Axis};
use plant_contour::curve::{curve_problem, fit_curve, ClosedCurve, SplineCurve};
use plant_contour::fit::Solver;
use plant_contour::gramian::gauss4;
use plant_contour::identify::gcv::{factor_with, gcv_score, Lambda};
use plant_contour::identify::tracked::{
    fit_closed_curve, fit_signature, ContourOptions, Signature,
};
use plant_contour::surface::{fit_surface, SplineSurface};
use plant_contour::ContourError;
use std::f64::consts::{PI, TAU};

/// A deterministic pseudo-random value in [−1, 1] (no RNG needed here).
fn jitter(k: usize) -> f64 {
    ((k as f64 * 12.9898).sin() * 43_758.545_3).rem_euclid(1.0) * 2.0 - 1.0
}

#[test]
fn partition_of_unity_and_unit_integral_of_the_basis() {
    // Σ_j N_{j,k}(t) = 1 on [0, 1] and Σ_i B_k(t − i) = 1, for k = 0..6;
    // ∫ B_k = 1 (paper, after Eq. 3).
    for k in 0..=6 {
        for q in 0..=50 {
            let t = q as f64 / 50.0;
            let s: f64 = basis_elements(k, t).iter().sum();
            assert!((s - 1.0).abs() < 1e-14, "k {k} t {t}: Σ N = {s}");
            let x = 3.3 + 0.97 * t;
            let total: f64 = (-10..10).map(|i| b_spline(k, x - i as f64)).sum();
            assert!((total - 1.0).abs() < 1e-14, "k {k} x {x}: Σ B = {total}");
        }
        // Gauss on each unit piece is exact for degree ≤ 7.
        let integral: f64 = (0..=k)
            .flat_map(|j| {
                gauss4()
                    .iter()
                    .map(move |&(x, w)| w * b_spline(k, j as f64 + x))
            })
            .sum();
        if k <= 7 {
            assert!((integral - 1.0).abs() < 1e-14, "k {k}: ∫B = {integral}");
        }
    }
    // Eq. 4 values at the knots: 0, 1/6, 4/6, 1/6.
    for (t, v) in [
        (0.0, 0.0),
        (1.0, 1.0 / 6.0),
        (2.0, 4.0 / 6.0),
        (3.0, 1.0 / 6.0),
    ] {
        assert!((b3(t) - v).abs() < 1e-15);
    }
    // On an axis: the M basis functions sum to 1 everywhere in the domain,
    // and ∫ b(s) ds over the domain is the domain's length.
    let axis = Axis::over(-2.0, 5.0, 9, false).unwrap();
    for q in 0..=70 {
        let s = -2.0 + 0.1 * q as f64;
        let sum: f64 = axis.basis_vector(s, 0).iter().sum();
        assert!((sum - 1.0).abs() < 1e-14);
        let d1: f64 = axis.basis_vector(s, 1).iter().sum();
        assert!(d1.abs() < 1e-12);
    }
}

/// Noisy samples of a smooth periodic function on [0, m).
fn periodic_data(m: usize, n: usize) -> (Vec<f64>, Vec<f64>) {
    let u: Vec<f64> = (0..n).map(|k| m as f64 * k as f64 / n as f64).collect();
    let d: Vec<f64> = u
        .iter()
        .enumerate()
        .map(|(k, &s)| 2.0 + (TAU * s / m as f64).sin() + 0.3 * jitter(k))
        .collect();
    (u, d)
}

#[test]
fn periodic_curves_are_continuous_to_the_second_derivative_at_the_seam() {
    let m = 10;
    let axis = Axis::over(0.0, m as f64, m, true).unwrap();
    let (u, d) = periodic_data(m, 37);
    for solver in [Solver::Reduced, Solver::Kkt] {
        let (c, _) = fit_curve(&axis, &u, &d, None, 1e-3, solver).unwrap();
        for order in 0..=2 {
            // x^(l)(s₀) from the first interval and x^(l)(s_m) from the last.
            let end = evaluate_at_end(&c, order);
            let start = c.derivative(0.0, order);
            assert!(
                (end - start).abs() < 1e-12,
                "{solver:?} order {order}: {start} vs {end}"
            );
        }
    }
}

/// The `order`-th derivative at the domain's end, from the last interval's
/// polynomial (not wrapped).
fn evaluate_at_end(c: &SplineCurve, order: usize) -> f64 {
    let m = c.axis.intervals;
    let scale = c.axis.alpha.powi(order as i32);
    let b = plant_contour::basis::local_cubic(1.0, order);
    b.iter()
        .zip(&c.coef[m - 1..m + 3])
        .map(|(b, t)| scale * b * t)
        .sum()
}

#[test]
fn periodic_and_closed_surfaces_are_continuous_at_their_seams() {
    let (m1, m2) = (6, 8);
    for closed in [false, true] {
        let sa = Axis::over(0.0, m1 as f64, m1, closed).unwrap();
        let ta = Axis::over(0.0, m2 as f64, m2, true).unwrap();
        let mut sites = Vec::new();
        let mut d = Vec::new();
        for i in 0..13 {
            for j in 0..11 {
                let (s, t) = (m1 as f64 * i as f64 / 13.0, m2 as f64 * j as f64 / 11.0);
                sites.push((s, t));
                d.push(
                    1.0 + 0.4 * (TAU * t / m2 as f64).cos() * (1.0 + 0.2 * s)
                        + 0.1 * jitter(sites.len()),
                );
            }
        }
        for solver in [Solver::Reduced, Solver::Kkt] {
            let (x, _) = fit_surface(&sa, &ta, &sites, &d, None, 1e-3, solver).unwrap();
            for q in 0..=12 {
                let v = m1 as f64 * q as f64 / 12.0;
                for l in 0..=2 {
                    // Across t = t₀ ≡ t_m: from the first and last intervals.
                    let (a, b) = surface_seam(&x, v, l, false);
                    assert!(
                        (a - b).abs() < 1e-12,
                        "closed {closed} {solver:?} t-seam l {l}: {a} vs {b}"
                    );
                    if closed {
                        let (a, b) = surface_seam(&x, v * m2 as f64 / m1 as f64, l, true);
                        assert!((a - b).abs() < 1e-12, "{solver:?} s-seam l {l}: {a} vs {b}");
                    }
                }
            }
        }
    }
}

/// ∂ˡ/∂tˡ x(v, t₀) and x(v, t_m) (or along s when `along_s`), evaluated from
/// the coefficients of the first and of the last knot interval.
fn surface_seam(x: &SplineSurface, v: f64, l: usize, along_s: bool) -> (f64, f64) {
    let (m1, m2) = (x.s_axis.coefficients(), x.t_axis.coefficients());
    let at = |first: usize, local: f64| -> f64 {
        let bl = plant_contour::basis::local_cubic(local, l);
        if along_s {
            let (f2, b2) = x.t_axis.basis(v, 0);
            let mut sum = 0.0;
            for (p, bp) in bl.iter().enumerate() {
                for (q, bq) in b2.iter().enumerate() {
                    sum += bp * bq * x.coef[first + p + m1 * (f2 + q)];
                }
            }
            sum
        } else {
            let (f1, b1) = x.s_axis.basis(v, 0);
            let mut sum = 0.0;
            for (q, bq) in bl.iter().enumerate() {
                for (p, bp) in b1.iter().enumerate() {
                    sum += bp * bq * x.coef[f1 + p + m1 * (first + q)];
                }
            }
            sum
        }
    };
    let last = if along_s { m1 - 4 } else { m2 - 4 };
    (at(0, 0.0), at(last, 1.0))
}

#[test]
fn kkt_and_reduced_solvers_give_the_same_spline() {
    // Curve.
    let axis = Axis::over(0.0, 12.0, 12, true).unwrap();
    let (u, d) = periodic_data(12, 29);
    let (a, _) = fit_curve(&axis, &u, &d, None, 1e-3, Solver::Kkt).unwrap();
    let (b, _) = fit_curve(&axis, &u, &d, None, 1e-3, Solver::Reduced).unwrap();
    let diff = a
        .coef
        .iter()
        .zip(&b.coef)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(diff < 1e-10, "curve: {diff}");
    // Surfaces: periodic in t; closed (the KKT matrix is singular there:
    // the corner ties repeat, and the minimum-norm solution is used).
    for closed in [false, true] {
        let sa = Axis::over(0.0, 5.0, 5, closed).unwrap();
        let ta = Axis::over(0.0, 7.0, 7, true).unwrap();
        let sites: Vec<(f64, f64)> = (0..80)
            .map(|k| (5.0 * (k % 8) as f64 / 8.0, 7.0 * (k / 8) as f64 / 10.0))
            .collect();
        let d: Vec<f64> = sites
            .iter()
            .enumerate()
            .map(|(k, &(s, t))| s.sin() + t.cos() + 0.1 * jitter(k))
            .collect();
        let (a, fa) = fit_surface(&sa, &ta, &sites, &d, None, 1e-3, Solver::Kkt).unwrap();
        let (b, fb) = fit_surface(&sa, &ta, &sites, &d, None, 1e-3, Solver::Reduced).unwrap();
        assert_eq!(fa.solver(), Solver::Kkt);
        assert_eq!(fb.solver(), Solver::Reduced);
        let diff = a
            .coef
            .iter()
            .zip(&b.coef)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(diff < 1e-9, "closed {closed}: {diff}");
        // The KKT solution satisfies every tie of Ḡ.
        for &(p, q) in fa.ties() {
            assert!((a.coef[p] - a.coef[q]).abs() < 1e-12);
        }
        // Same effective degrees of freedom.
        assert!((fa.trace_hat() - fb.trace_hat()).abs() < 1e-8);
    }
}

#[test]
fn a_circle_has_area_pi_r_squared() {
    let r = 3.7;
    // Signature of a circle: r(θ) = r is reproduced exactly (a constant
    // has no roughness), so Eq. 40 gives πr² to rounding.
    let angles: Vec<f64> = (0..23).map(|k| TAU * k as f64 / 23.0 + 0.01).collect();
    let sig = Signature::new("circle", (1.0, -2.0), &angles, &[r; 23]).unwrap();
    let fit = fit_signature(
        "circle",
        &sig,
        &ContourOptions {
            knots: 10,
            lambda: Lambda::Fixed(1e-3),
            solver: Solver::Reduced,
        },
    )
    .unwrap();
    let rel = (fit.area() / (PI * r * r) - 1.0).abs();
    assert!(rel < 1e-13, "signature area off by {rel}");
    // As a closed parametric curve (x(t), y(t)): a cubic spline only
    // approximates a circle; with 24 knots and 48 points the area is within
    // 1e-5 of πr² (spline error O(h⁴)), and with 48 knots within 1e-6.
    for (knots, tol) in [(24, 1e-5), (48, 1e-6)] {
        let pts: Vec<(f64, f64)> = (0..2 * knots)
            .map(|k| {
                let a = TAU * k as f64 / (2 * knots) as f64;
                (5.0 + r * a.cos(), r * a.sin())
            })
            .collect();
        let c = fit_closed_curve(
            "circle",
            &pts,
            &ContourOptions {
                knots,
                lambda: Lambda::Fixed(1e-9),
                solver: Solver::Reduced,
            },
        )
        .unwrap();
        let rel = (c.curve.signed_area() / (PI * r * r) - 1.0).abs();
        assert!(rel < tol, "{knots} knots: area off by {rel}");
        let len_rel = (c.curve.length(4) / (TAU * r) - 1.0).abs();
        assert!(
            len_rel < 10.0 * tol,
            "{knots} knots: length off by {len_rel}"
        );
    }
    // Clockwise points give a negative signed area.
    let cw: Vec<(f64, f64)> = (0..30)
        .map(|k| {
            let a = -TAU * k as f64 / 30.0;
            (r * a.cos(), r * a.sin())
        })
        .collect();
    let c = fit_closed_curve(
        "cw",
        &cw,
        &ContourOptions {
            knots: 15,
            lambda: Lambda::Fixed(1e-9),
            solver: Solver::Reduced,
        },
    )
    .unwrap();
    assert!(c.curve.signed_area() < 0.0);
    let _: &ClosedCurve = &c.curve;
}

#[test]
fn gcv_picks_a_useful_lambda_and_its_trace_is_exact() {
    // Knots at every other sample: a tiny λ nearly interpolates the noise.
    let m = 60;
    let axis = Axis::over(0.0, m as f64, m, true).unwrap();
    let n = 120;
    let u: Vec<f64> = (0..n).map(|k| m as f64 * k as f64 / n as f64).collect();
    let truth = |s: f64| (TAU * s / m as f64).sin() + 0.5 * (2.0 * TAU * s / m as f64).cos();
    let d: Vec<f64> = u
        .iter()
        .enumerate()
        .map(|(k, &s)| truth(s) + 0.3 * jitter(k))
        .collect();
    let problem = curve_problem(&axis, &u, None).unwrap();
    let (f, rep) = factor_with(&problem, Lambda::Gcv, Solver::Reduced, &[&d]).unwrap();
    assert!(rep.by_gcv && rep.scanned.len() > 20);
    let err = |lam: f64| {
        let f = problem.fitter(lam, Solver::Reduced).unwrap();
        let c = SplineCurve::new(axis, f.solve(&d).unwrap()).unwrap();
        (0..400)
            .map(|k| {
                let s = m as f64 * k as f64 / 400.0;
                (c.value(s) - truth(s)).powi(2)
            })
            .sum::<f64>()
            / 400.0
    };
    let e_gcv = err(f.lambda());
    // Better than interpolating the noise, and better than flattening it.
    assert!(
        e_gcv < 0.5 * err(f.lambda() * 1e-5),
        "gcv {e_gcv} vs tiny λ {}",
        err(f.lambda() * 1e-5)
    );
    assert!(
        e_gcv < 0.5 * err(f.lambda() * 1e4),
        "gcv {e_gcv} vs huge λ {}",
        err(f.lambda() * 1e4)
    );
    // The GCV minimum is a minimum of the scanned curve.
    let min_scanned = rep
        .scanned
        .iter()
        .map(|p| p.1)
        .fold(f64::INFINITY, f64::min);
    assert!(rep.gcv.unwrap() <= min_scanned * (1.0 + 1e-12));
    // tr H by selected inversion equals tr H from the dense KKT inverse,
    // and equals the sum of the dense hat matrix's diagonal.
    let kkt = problem.fitter(f.lambda(), Solver::Kkt).unwrap();
    assert!((kkt.trace_hat() - f.trace_hat()).abs() < 1e-9);
    let mut diag = 0.0;
    for k in 0..n {
        let mut e = vec![0.0; n];
        e[k] = 1.0;
        diag += f.fitted(&f.solve(&e).unwrap())[k];
    }
    assert!(
        (diag - f.trace_hat()).abs() < 1e-9,
        "{diag} vs {}",
        f.trace_hat()
    );
    let (v, tr) = gcv_score(&f, &[&d]).unwrap();
    assert!((v - rep.gcv.unwrap()).abs() < 1e-12 && (tr - rep.trace_hat).abs() < 1e-12);
}

#[test]
fn bad_input_is_refused_by_name() {
    let opts = ContourOptions {
        knots: 8,
        lambda: Lambda::Fixed(1e-3),
        solver: Solver::Reduced,
    };
    let e = Signature::new("frame 3", (0.0, 0.0), &[0.0, 1.0], &[1.0, 1.0]).unwrap_err();
    assert!(
        matches!(e, ContourError::TooFewPoints { got: 2, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("frame 3"));
    let e = Signature::new("frame 1", (0.0, 0.0), &[0.0, 1.0, 1.0, 2.0], &[1.0; 4]).unwrap_err();
    assert!(
        matches!(
            e,
            ContourError::DuplicateParameter {
                first: 1,
                second: 2,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("duplicate angle"), "{e}");
    // 0 and 2π are the same angle.
    let e = Signature::new("f", (0.0, 0.0), &[0.0, 1.0, TAU], &[1.0; 3]).unwrap_err();
    assert!(matches!(e, ContourError::DuplicateParameter { .. }), "{e}");
    let e = Signature::new("f", (0.0, 0.0), &[0.0, 1.0, 2.0], &[1.0, f64::NAN, 1.0]).unwrap_err();
    assert!(
        e.to_string().contains("radius") && e.to_string().contains("point 1"),
        "{e}"
    );
    let e = fit_closed_curve(
        "f",
        &[(0.0, 0.0), (1.0, 0.0), (1.0, 0.0), (0.0, 1.0)],
        &opts,
    )
    .unwrap_err();
    assert!(matches!(e, ContourError::DuplicateParameter { .. }), "{e}");
    let e = Signature::from_points("f", &[(0.0, 0.0), (1.0, 1.0), (2.0, 2.0)]).unwrap_err();
    assert!(e.to_string().contains("no area"), "{e}");
    // A U shape is not star-shaped about its centroid.
    let u_shape = [
        (0.0, 0.0),
        (3.0, 0.0),
        (3.0, 3.0),
        (2.0, 3.0),
        (2.0, 0.5),
        (1.0, 0.5),
        (1.0, 3.0),
        (0.0, 3.0),
    ];
    let e = Signature::from_points("u", &u_shape).unwrap_err();
    assert!(e.to_string().contains("not star-shaped"), "{e}");
    assert!(fit_closed_curve("u", &u_shape, &opts).is_ok());
    // Sites outside a non-periodic domain, bad λ, bad weights.
    let open = Axis::over(0.0, 4.0, 4, false).unwrap();
    let e = fit_curve(&open, &[0.0, 5.0], &[1.0, 2.0], None, 1e-3, Solver::Reduced).unwrap_err();
    assert!(matches!(e, ContourError::OutsideDomain { .. }), "{e}");
    let e = fit_curve(&open, &[0.0, 1.0], &[1.0, 2.0], None, -1.0, Solver::Reduced).unwrap_err();
    assert!(e.to_string().contains("lambda"), "{e}");
    let e = fit_curve(
        &open,
        &[0.0, 1.0],
        &[1.0, 2.0],
        Some(&[1.0, f64::NAN]),
        1e-3,
        Solver::Reduced,
    )
    .unwrap_err();
    assert!(e.to_string().contains("weight"), "{e}");
    // One site cannot pin a + b·s on an open axis: the reduced matrix is
    // singular, the KKT minimum-norm solution takes over.
    let (c, f) = fit_curve(&open, &[1.0], &[2.0], None, 1e-3, Solver::Reduced).unwrap();
    assert_eq!(f.solver(), Solver::Kkt);
    assert!((c.value(1.0) - 2.0).abs() < 1e-9);
}

#[test]
fn area_and_smoothness_are_the_kronecker_forms_of_eq_40_and_41() {
    use nalgebra::{DMatrix, DVector};
    use plant_contour::gramian::{gramian, kron};
    // A surface with arbitrary coefficients, periodic in t.
    let sa = Axis::over(0.0, 6.0, 6, false).unwrap();
    let ta = Axis::over(0.0, 10.0, 10, true).unwrap();
    let (m1, m2) = (sa.coefficients(), ta.coefficients());
    let mut coef: Vec<f64> = (0..m1 * m2).map(|k| 1.0 + 0.3 * jitter(k)).collect();
    for i in 0..m1 {
        for l in 0..3 {
            coef[i + m1 * (10 + l)] = coef[i + m1 * l];
        }
    }
    let x = SplineSurface::new(sa, ta, coef.clone()).unwrap();
    let tau = DVector::from_vec(coef);
    let q00 = gramian(&ta, 0, 0).to_dense();
    let q22 = gramian(&ta, 2, 2).to_dense();
    for s in [0.0, 1.3, 2.5, 5.99] {
        let b1 = DVector::from_vec(sa.basis_vector(s, 0));
        let bc: DMatrix<f64> = &b1 * b1.transpose();
        let area = PI / 10.0 * (tau.transpose() * kron(&q00, &bc) * &tau)[0];
        let c = (tau.transpose() * kron(&q22, &bc) * &tau)[0];
        assert!((x.area(s) - area).abs() < 1e-12 * area.abs(), "S({s})");
        assert!(
            (x.smoothness(s) - c).abs() < 1e-10 * c.abs().max(1.0),
            "C({s})"
        );
        // And S(s) = ½∫r² dθ by quadrature over the polar contour (Eq. 39).
        let n = 4000;
        let quad: f64 = (0..n)
            .map(|k| {
                let t = 10.0 * (k as f64 + 0.5) / n as f64;
                0.5 * x.value(s, t).powi(2) * TAU / n as f64
            })
            .sum();
        assert!((quad - area).abs() < 1e-6 * area, "S({s}) by quadrature");
    }
}

/// The perimeter's quadrature takes value and slope from one interval
/// search (`derivatives`, issue 34): each is bit-identical to
/// `derivative` of its order; the perimeter of a circle r = R stays
/// 2πR, also for radii whose squares overflow (the `hypot` fallback).
#[test]
fn derivatives_match_derivative_bit_for_bit_and_the_perimeter_survives_huge_radii() {
    let m = 12;
    let axis = Axis::over(0.0, m as f64, m, true).unwrap();
    let coef: Vec<f64> = (0..axis.coefficients())
        .map(|i| 3.0 + (i as f64 * 0.7).sin())
        .collect();
    let c = SplineCurve::new(axis, coef).unwrap();
    for k in 0..97 {
        let s = m as f64 * k as f64 / 97.0;
        let [v, d1, d2] = c.derivatives::<3>(s);
        assert_eq!(v.to_bits(), c.value(s).to_bits(), "value at {s}");
        assert_eq!(d1.to_bits(), c.derivative(s, 1).to_bits(), "slope at {s}");
        assert_eq!(
            d2.to_bits(),
            c.derivative(s, 2).to_bits(),
            "curvature term at {s}"
        );
    }
    for r in [1.0, 1e200] {
        let circle = SplineCurve::new(axis, vec![r; axis.coefficients()]).unwrap();
        let p = circle.signature_perimeter();
        assert!(
            ((p - TAU * r) / (TAU * r)).abs() < 1e-12,
            "r {r}: perimeter {p}"
        );
    }
}

/// `∫ f(s) ds` by 4-point Gauss on `sub` sub-intervals of each knot
/// interval, every point located from its s: the quadrature the crate ran
/// before it took each point's basis values from one interval's table.
fn gauss_by_sites(axis: &Axis, sub: usize, f: impl Fn(f64) -> f64) -> f64 {
    let h = 1.0 / (axis.alpha * sub as f64);
    let mut total = 0.0;
    for j in 0..axis.intervals * sub {
        for &(x, w) in gauss4() {
            total += w * h * f(axis.start + (j as f64 + x) * h);
        }
    }
    total
}

#[test]
fn the_tabled_quadratures_equal_quadrature_at_located_points() {
    // Perimeter, bending energy and length take the basis values of one
    // knot interval's Gauss points for every interval (issue 34); each
    // must be the quadrature of its integrand at the located points,
    // to rounding, on random periodic and open axes and knot counts.
    let k_sub = plant_contour::curve::QUADRATURE_SUB;
    for case in 0..40 {
        let m = 4 + case % 13;
        let start = 3.0 * jitter(7 * case + 1);
        let axis = Axis::over(
            start,
            start + 0.5 + 9.0 * jitter(7 * case + 2).abs(),
            m,
            true,
        )
        .unwrap();
        // Free coefficients `mean(i) + ½ jitter`, tied round the period:
        // a wavy signature about 4, and a wavy loop about a circle of
        // radius 4 (no cusps, where rounding in the speed would be
        // magnified without bound).
        let coef = |seed: usize, mean: &dyn Fn(f64) -> f64| -> Vec<f64> {
            let free: Vec<f64> = (0..m)
                .map(|i| mean(TAU * i as f64 / m as f64) + 0.5 * jitter(seed + 31 * i))
                .collect();
            (0..axis.coefficients())
                .map(|i| free[axis.free_index(i)])
                .collect()
        };
        let r = SplineCurve::new(axis, coef(100 * case, &|_| 4.0)).unwrap();
        let k = axis.length() / TAU;
        let want_p = gauss_by_sites(&axis, k_sub, |s| {
            let (r0, r1) = (r.value(s), k * r.derivative(s, 1));
            (r0 * r0 + r1 * r1).sqrt() / k
        });
        let want_e = gauss_by_sites(&axis, k_sub, |s| {
            let (r0, r1, r2) = (
                r.value(s),
                k * r.derivative(s, 1),
                k * k * r.derivative(s, 2),
            );
            let v2 = r0 * r0 + r1 * r1;
            let num = r0 * r0 + 2.0 * r1 * r1 - r0 * r2;
            num * num / (v2 * v2 * v2.sqrt()) / k
        });
        let close = |got: f64, want: f64, what: &str| {
            assert!(
                (got - want).abs() <= 1e-13 * want.abs(),
                "case {case} ({m} knots): {what} {got} against {want}"
            );
        };
        close(r.signature_perimeter(), want_p, "perimeter");
        close(r.signature_bending_energy(), want_e, "bending energy");
        let c = ClosedCurve {
            x: SplineCurve::new(axis, coef(100 * case + 50, &|a| 4.0 * a.cos())).unwrap(),
            y: SplineCurve::new(axis, coef(100 * case + 77, &|a| 4.0 * a.sin())).unwrap(),
        };
        for sub in [1, 4, k_sub] {
            let want = gauss_by_sites(&axis, sub, |t| {
                let (dx, dy) = c.derivative(t, 1);
                dx.hypot(dy)
            });
            close(c.length(sub), want, "length");
        }
        let want = gauss_by_sites(&axis, k_sub, |t| {
            let (dx, dy) = c.derivative(t, 1);
            let (ddx, ddy) = c.derivative(t, 2);
            let cross = dx * ddy - dy * ddx;
            let v2 = dx * dx + dy * dy;
            cross * cross / (v2 * v2 * v2.sqrt())
        });
        close(c.bending_energy(), want, "curve bending energy");
    }
    // A curve whose coordinates have different axes (none this crate
    // fits) is integrated at located points, not read out of range.
    let (a, b) = (
        Axis::over(0.0, 6.0, 6, true).unwrap(),
        Axis::over(0.0, 6.0, 3, true).unwrap(),
    );
    let c = ClosedCurve {
        x: SplineCurve::new(a, vec![1.0; a.coefficients()]).unwrap(),
        y: SplineCurve::new(b, (0..b.coefficients()).map(|i| (i % 3) as f64).collect()).unwrap(),
    };
    let want = gauss_by_sites(&a, 4, |t| {
        let (dx, dy) = c.derivative(t, 1);
        dx.hypot(dy)
    });
    assert_eq!(c.length(4), want);
}

#[test]
fn rem_period_is_rem_euclid_bit_for_bit() {
    for period in [TAU, 16.0, 0.7, 1e-3, 3e5] {
        let mut xs = vec![
            0.0,
            -0.0,
            period,
            -period,
            period * (1.0 - f64::EPSILON),
            f64::NAN,
            f64::INFINITY,
            1e300,
            -1e-300,
        ];
        xs.extend((0..2000).map(|k| 40.0 * period * jitter(k)));
        xs.extend((0..200).map(|k| period * k as f64 / 200.0));
        for x in xs {
            assert_eq!(
                rem_period(x, period).to_bits(),
                x.rem_euclid(period).to_bits(),
                "x = {x:e}, period {period}"
            );
        }
    }
}
