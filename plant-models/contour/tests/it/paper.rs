//! The paper's studies (Fujioka & Kano §IV): Eq. 38 with σ = 0.3 and
//! λ = 10⁻³ from N = 5 to N = 40 (Theorem 1), the closed red-blood-cell
//! surface, and the held-out frames of a deforming contour movie.
//!
//! The paper prints no error figures (Fig. 1–2 and 6 are pictures), so the
//! assertions are the properties the paper claims: the fit approaches f as
//! N grows, the Monte-Carlo mean of the noisy fits is the noise-free fit
//! (Theorem 1(ii)), τ^ε_N → τ_c in mean square, and the model's contour at
//! frames it never saw is close to the truth (here: closer than linear
//! interpolation in time).
use plant_common::rng;
use plant_contour::fit::Solver;
use plant_contour::identify::gcv::Lambda;
use plant_contour::identify::movie::{
    held_out_study, HeldOutRow, PulsatingContour, PAPER_HELD_OUT,
};
use plant_contour::identify::paper::{
    axes, continuous_limit, grid_sites, rbc_closed_surface, rbc_surface, rms_error, theorem1_study,
    LAMBDA, SIGMA,
};
use plant_contour::identify::tracked::MovieOptions;
use plant_contour::surface::fit_surface;

/// Seed of the studies (any fixed value).
const SEED: u64 = 38;

#[test]
fn eq38_error_falls_from_n5_to_n40_and_the_monte_carlo_mean_is_the_noise_free_fit() {
    let ns = [5, 10, 20, 40];
    let reps = 100;
    let mut r = rng::stream(SEED, rng::CONTOUR_MONTE_CARLO);
    let (rows, tau_c) = theorem1_study(&ns, SIGMA, LAMBDA, reps, &mut r).unwrap();
    println!(
        "τ_c: RMS error to f = {:.4}",
        rms_error(&tau_c, rbc_surface)
    );
    println!("  N | RMS x_N−f | mean RMS x^ε−f | RMS MC mean−f | ‖τ_N−τ_c‖ | E‖τ^ε−τ_c‖² | ‖mean τ^ε−τ_N‖ (s.e.) | RMS mean−x_N (spread/√R)");
    for r in &rows {
        println!(
            "{:3} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} ({:.4}) | {:.4} ({:.4})",
            r.n,
            r.rms_noise_free,
            r.rms_noisy_mean,
            r.rms_mc_mean,
            r.tau_n_to_tau_c,
            r.mean_square_tau_eps_to_tau_c,
            r.mc_mean_to_tau_n,
            r.mc_standard_error,
            r.rms_mc_mean_to_noise_free,
            r.rms_spread / (r.replicates as f64).sqrt()
        );
    }
    for w in rows.windows(2) {
        // The noisy fit's error to the true surface falls with N …
        assert!(
            w[1].rms_noisy_mean < w[0].rms_noisy_mean,
            "N {} → {}: {} → {}",
            w[0].n,
            w[1].n,
            w[0].rms_noisy_mean,
            w[1].rms_noisy_mean
        );
        // … and τ^ε_N approaches τ_c in mean square (Theorem 1(ii)).
        assert!(w[1].mean_square_tau_eps_to_tau_c < w[0].mean_square_tau_eps_to_tau_c);
    }
    let (first, last) = (&rows[0], &rows[rows.len() - 1]);
    assert!(last.rms_noisy_mean < 0.5 * first.rms_noisy_mean);
    // Theorem 1(i): τ_N → τ_c.
    assert!(last.tau_n_to_tau_c < 0.25 * first.tau_n_to_tau_c);
    for r in &rows {
        // Theorem 1(ii), E τ^ε_N = τ_N: the Monte-Carlo mean is within 4
        // standard errors of τ_N …
        assert!(
            r.mc_mean_to_tau_n < 4.0 * r.mc_standard_error,
            "N {}: {} vs s.e. {}",
            r.n,
            r.mc_mean_to_tau_n,
            r.mc_standard_error
        );
        // … and as a surface: E‖mean − x_N‖² = E‖x^ε − x_N‖²/R exactly for
        // a linear smoother, so the ratio below is about 1.
        let ratio = r.rms_mc_mean_to_noise_free / (r.rms_spread / (r.replicates as f64).sqrt());
        assert!(
            ratio < 1.5,
            "N {}: MC mean is {ratio}× its expected distance from x_N",
            r.n
        );
    }
    // … and approaches it as replicates accumulate: with 4× the replicates
    // the distance falls by about half (here: to below 0.7×).
    let mut r2 = rng::stream(SEED + 1, rng::CONTOUR_MONTE_CARLO);
    let (few, _) = theorem1_study(&[10], SIGMA, LAMBDA, 25, &mut r2).unwrap();
    let (many, _) = theorem1_study(&[10], SIGMA, LAMBDA, 400, &mut r2).unwrap();
    println!(
        "N = 10: ‖mean τ^ε − τ_N‖ = {:.4} (R = 25), {:.4} (R = 400)",
        few[0].mc_mean_to_tau_n, many[0].mc_mean_to_tau_n
    );
    assert!(many[0].mc_mean_to_tau_n < 0.7 * few[0].mc_mean_to_tau_n);
}

#[test]
fn closed_red_blood_cell_surface_is_fitted_from_21_by_21_points() {
    // Fig. 3: N₁ = N₂ = 21, λ = 10⁻³, m₁ = m₂ = 10, noise-free data.
    let (sa, ta) = axes(true).unwrap();
    let sites = grid_sites(21, 21, true);
    let d: Vec<f64> = sites
        .iter()
        .map(|&(s, t)| rbc_closed_surface(s, t))
        .collect();
    let (x, f) = fit_surface(&sa, &ta, &sites, &d, None, LAMBDA, Solver::Reduced).unwrap();
    let (xk, _) = fit_surface(&sa, &ta, &sites, &d, None, LAMBDA, Solver::Kkt).unwrap();
    let diff = x
        .coef
        .iter()
        .zip(&xk.coef)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    let err = rms_error(&x, rbc_closed_surface);
    let range = (0..=100)
        .flat_map(|i| (0..100).map(move |j| rbc_closed_surface(i as f64 / 10.0, j as f64 / 10.0)))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    println!(
        "closed surface: RMS error {err:.4} (f spans {:.3}…{:.3}); KKT vs reduced {diff:.1e}; tr H = {:.1}",
        range.0,
        range.1,
        f.trace_hat()
    );
    assert!(diff < 1e-9);
    // The continuous limit of the closed problem (Eq. 36, unique) is what
    // the 21 × 21 fit approaches: they differ by far less than either
    // differs from f. At λ = 10⁻³ both are smoothed by ≈ 6 % of f's range
    // (the penalty, not the knots: at λ = 10⁻⁵ the error is 0.018).
    let c = continuous_limit(rbc_closed_surface, true, LAMBDA, 2).unwrap();
    let to_c = rms_error(&x, |s, t| c.value(s, t));
    let c_err = rms_error(&c, rbc_closed_surface);
    println!("  τ_c: RMS error {c_err:.4}; 21×21 fit to τ_c {to_c:.2e}");
    assert!(to_c < 0.01 * err, "fit to τ_c {to_c} vs error {err}");
    assert!(err < 0.07 * (range.1 - range.0), "RMS error {err}");
    let (x5, _) = fit_surface(&sa, &ta, &sites, &d, None, 1e-5, Solver::Reduced).unwrap();
    assert!(rms_error(&x5, rbc_closed_surface) < 0.01 * (range.1 - range.0));
}

/// Mean over the held-out rows of one column.
fn mean_of(rows: &[HeldOutRow], f: fn(&HeldOutRow) -> f64) -> f64 {
    rows.iter().map(f).sum::<f64>() / rows.len() as f64
}

fn print_rows(label: &str, rows: &[HeldOutRow]) {
    println!("{label}: frame | data angles spline / linear (mean, max) | dense spline / linear | centroid spline / linear (px)");
    for r in rows {
        println!(
            "  {:3} | {:.2} / {:.2} ({:.2} / {:.2}) | {:.2} / {:.2} | {:.2} / {:.2}",
            r.frame + 1,
            r.spline_mean_px,
            r.linear_mean_px,
            r.spline_max_px,
            r.linear_max_px,
            r.spline_dense_mean_px,
            r.linear_dense_mean_px,
            r.spline_centre_px,
            r.linear_centre_px
        );
    }
}

#[test]
fn held_out_frames_fitted_versus_linear_interpolation_in_time() {
    // The paper's protocol: 101 frames, every 10th used (11 frames), 10
    // angles per frame, w = 1/(N₁N₂), m₁ = m₂ = 10; frames 26/46/66/86
    // (1-based) held out. Noise-free tracking and 1 px tracking noise.
    let movie = PulsatingContour::default();
    let paper = MovieOptions {
        time_knots: 10,
        angle_knots: 10,
        lambda: Lambda::Fixed(5e-4),
        centre_lambda: Lambda::Fixed(5e-4),
        solver: Solver::Reduced,
    };
    let gcv = MovieOptions {
        lambda: Lambda::Gcv,
        centre_lambda: Lambda::Gcv,
        ..paper
    };
    for sigma in [0.0, 1.0] {
        for (label, opts) in [("paper λ = 5e-4", &paper), ("λ by GCV", &gcv)] {
            let mut r = rng::stream(SEED, rng::CONTOUR_MOVIE_NOISE);
            let (fit, rows) =
                held_out_study(&movie, 10, 10, &PAPER_HELD_OUT, sigma, opts, &mut r).unwrap();
            print_rows(
                &format!("σ = {sigma} px, {label} (λ = {:.1e})", fit.lambda.lambda),
                &rows,
            );
            assert_eq!(rows.len(), 4);
            let (s, l) = (
                mean_of(&rows, |r| r.spline_mean_px),
                mean_of(&rows, |r| r.linear_mean_px),
            );
            let (sd, ld) = (
                mean_of(&rows, |r| r.spline_dense_mean_px),
                mean_of(&rows, |r| r.linear_dense_mean_px),
            );
            let (sc, lc) = (
                mean_of(&rows, |r| r.spline_centre_px),
                mean_of(&rows, |r| r.linear_centre_px),
            );
            println!("  mean: data angles {s:.2} vs {l:.2}; dense {sd:.2} vs {ld:.2}; centroid {sc:.2} vs {lc:.2}");
            println!(
                "  GCV against its degrees-of-freedom bound: surface {}, centroid {}",
                fit.lambda.at_dof_bound, fit.centre_lambda.at_dof_bound
            );
            if opts.lambda == Lambda::Gcv {
                // 110 data for 130 surface coefficients, 11 centroids for
                // 13: plain GCV went to interpolation (λ 7e-12), which won
                // here; guarded GCV (γ = 1.4, issue 29) may not, and
                // smooths more. Its figures are reported, not asserted
                // (README).
                continue;
            }
            // The paper's λ: the whole contour (dense) and the centroid
            // path beat linear interpolation in time.
            assert!(
                sd < ld,
                "{label} σ {sigma}: dense spline {sd} vs linear {ld}"
            );
            assert!(sc < 0.5 * lc, "{label} σ {sigma}: centroid {sc} vs {lc}");
            // At the data angles the paper's λ smooths the 3-lobed shape by
            // ≈ 1 px and loses to linear interpolation of the raw radii
            // (reported, see README).
        }
    }
}
