//! The paper's numerical study (§IV-A): the red-blood-cell surface of
//! Eq. 38, sampled on an N × N grid with noise, fitted as a surface
//! periodic in t; the continuous limit τ_c of Eq. 36; Theorem 1 by Monte
//! Carlo; and the closed red-blood-cell surface of Fig. 3.
//!
//! Choices the paper leaves open (stated here and in the README):
//! * Sample sites: t (periodic) at `v_j = 10 (j − 1)/N₂`, s (open) at
//!   `u_i = 10 (i − 1)/(N₁ − 1)` (both ends); the closed case spaces both
//!   like t.
//! * Assumption 1 as printed equates `(1/N₁N₂)Σ g` with `∫∫ g`; over the
//!   10 × 10 domain the sample mean tends to `(1/100)∫∫ g`. τ_c here is the
//!   limit of the discrete problem actually solved (weights 1/(N₁N₂)), i.e.
//!   Eq. 32/36 with the data term divided by the domain's area.
//! * Eq. 38 is used as printed (θ(t), not 2θ(t) as in a Cassini oval).
use crate::error::Result;
use crate::model::basis::Axis;
use crate::model::fit::Solver;
use crate::model::gramian::gauss4;
use crate::model::surface::{surface_problem, SplineSurface};
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// θ(t) = 36π/180·t (§IV-A): one turn over t ∈ [0, 10].
pub fn theta(t: f64) -> f64 {
    36.0 * std::f64::consts::PI / 180.0 * t
}

/// The red-blood-cell surface of Eq. 38:
/// `f(s,t) = √(cos θ(t) + √(b⁴(s) − sin²θ(t)))`, `b(s) = 1.1 + 0.4|sin(1.256 s)|`.
pub fn rbc_surface(s: f64, t: f64) -> f64 {
    let b = 1.1 + 0.4 * (1.256 * s).sin().abs();
    let th = theta(t);
    (th.cos() + (b.powi(4) - th.sin().powi(2)).sqrt()).sqrt()
}

/// The closed red-blood-cell surface of Fig. 3: `√(h₁² + h₂² + h₃²)` with
/// θ = θ(s), φ = θ(t) and the paper's h₁, h₂, h₃ (as printed).
pub fn rbc_closed_surface(s: f64, t: f64) -> f64 {
    let (th, ph) = (theta(s), theta(t));
    let h1 = 0.1147 + 1.1103 * th.sin().powi(2) - 1.123 * th.sin().powi(4) * th.cos();
    let h2 = 1.1087 * th.sin() * ph.sin() + 0.5;
    let h3 = 1.1087 * th.sin() * ph.cos() + 0.5;
    (h1 * h1 + h2 * h2 + h3 * h3).sqrt()
}

/// The paper's domain: s, t ∈ [0, 10].
pub const DOMAIN: f64 = 10.0;
/// m₁ = m₂ = 10 knot intervals (§IV-A).
pub const KNOTS: usize = 10;
/// σ = 0.3 (§IV-A).
pub const SIGMA: f64 = 0.3;
/// λ = 10⁻³ (§IV-A).
pub const LAMBDA: f64 = 1e-3;

/// Sites of an N₁ × N₂ grid on the paper's domain (s fastest, as `vec`).
pub fn grid_sites(n1: usize, n2: usize, s_periodic: bool) -> Vec<(f64, f64)> {
    let u = |i: usize| {
        if s_periodic {
            DOMAIN * i as f64 / n1 as f64
        } else {
            DOMAIN * i as f64 / (n1.max(2) - 1) as f64
        }
    };
    (0..n2)
        .flat_map(|j| (0..n1).map(move |i| (u(i), DOMAIN * j as f64 / n2 as f64)))
        .collect()
}

/// Eq. 38 data as contour frames: frame i at s = 10 i/(N − 1), with N
/// points at θ(t_j), t_j = 10 j/N, radius `f(s, t_j) + σ ε`; returns per
/// frame its s and the (θ, radius) pairs.
pub fn rbc_frames(n: usize, sigma: f64, rng: &mut impl Rng) -> Vec<(f64, Vec<(f64, f64)>)> {
    (0..n)
        .map(|i| {
            let s = DOMAIN * i as f64 / (n.max(2) - 1) as f64;
            let pts = (0..n)
                .map(|j| {
                    let t = DOMAIN * j as f64 / n as f64;
                    let e: f64 = StandardNormal.sample(rng);
                    (theta(t), rbc_surface(s, t) + sigma * e)
                })
                .collect();
            (s, pts)
        })
        .collect()
}

/// The paper's axes: s open (periodic for the closed surface), t periodic.
pub fn axes(closed: bool) -> Result<(Axis, Axis)> {
    Ok((
        Axis::over(0.0, DOMAIN, KNOTS, closed)?,
        Axis::over(0.0, DOMAIN, KNOTS, true)?,
    ))
}

/// Grid intervals per direction of [`rms_error`] (4 per knot interval).
pub const ERROR_GRID: usize = 40;

/// RMS of `x − f` over a 41 × 40 grid of the domain (s with both ends,
/// t periodic).
pub fn rms_error(x: &SplineSurface, f: impl Fn(f64, f64) -> f64) -> f64 {
    let g = ERROR_GRID;
    let mut sum = 0.0;
    let mut n = 0.0;
    for i in 0..=g {
        for j in 0..g {
            let (s, t) = (DOMAIN * i as f64 / g as f64, DOMAIN * j as f64 / g as f64);
            sum += (x.value(s, t) - f(s, t)).powi(2);
            n += 1.0;
        }
    }
    (sum / n).sqrt()
}

/// Euclidean distance between two coefficient vectors.
pub fn coef_distance(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The continuous-limit surface τ_c (Eq. 32, 36) of `f` for λ: the data
/// term `(1/A)∫∫(x − f)²` is integrated by composite 4-point Gauss rules
/// with `sub` sub-intervals per knot interval, exact for its `BBᵀ` part
/// (piecewise polynomials) and converging for `φ` of Eq. 37.
pub fn continuous_limit(
    f: impl Fn(f64, f64) -> f64,
    closed: bool,
    lambda: f64,
    sub: usize,
) -> Result<SplineSurface> {
    let (sa, ta) = axes(closed)?;
    let pts = composite_gauss(DOMAIN, KNOTS * sub.max(1));
    let area = DOMAIN * DOMAIN;
    let mut sites = Vec::with_capacity(pts.len() * pts.len());
    let mut w = Vec::with_capacity(pts.len() * pts.len());
    let mut d = Vec::with_capacity(pts.len() * pts.len());
    for &(t, wt) in &pts {
        for &(s, ws) in &pts {
            sites.push((s, t));
            w.push(ws * wt / area);
            d.push(f(s, t));
        }
    }
    let fitter = surface_problem(&sa, &ta, &sites, Some(&w))?.fitter(lambda, Solver::Reduced)?;
    SplineSurface::new(sa, ta, fitter.solve(&d)?)
}

/// Composite 4-point Gauss nodes and weights on [0, L] with `pieces` pieces.
fn composite_gauss(l: f64, pieces: usize) -> Vec<(f64, f64)> {
    let h = l / pieces as f64;
    (0..pieces)
        .flat_map(|p| {
            gauss4()
                .iter()
                .map(move |&(x, w)| ((p as f64 + x) * h, w * h))
        })
        .collect()
}

/// One row of the Theorem 1 study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Theorem1Row {
    /// N₁ = N₂ = N.
    pub n: usize,
    /// RMS error to f of the noise-free fit x_N.
    pub rms_noise_free: f64,
    /// Mean over replicates of the RMS error to f of the noisy fit x^ε_N.
    pub rms_noisy_mean: f64,
    /// RMS error to f of the first replicate (one realisation, as Fig. 1).
    pub rms_noisy_first: f64,
    /// RMS error to f of the Monte-Carlo mean surface.
    pub rms_mc_mean: f64,
    /// ‖τ_N − τ_c‖.
    pub tau_n_to_tau_c: f64,
    /// Mean over replicates of ‖τ^ε_N − τ_c‖² (mean-square convergence).
    pub mean_square_tau_eps_to_tau_c: f64,
    /// ‖mean τ^ε_N − τ_N‖ (Theorem 1(ii): 0 in expectation).
    pub mc_mean_to_tau_n: f64,
    /// The Monte-Carlo standard error of that mean: `√(tr Cov/R)`.
    pub mc_standard_error: f64,
    /// RMS over the domain of the Monte-Carlo mean surface minus x_N.
    pub rms_mc_mean_to_noise_free: f64,
    /// `√(mean over replicates of RMS(x^ε_N − x_N)²)`: the spread of one
    /// noisy fit about the noise-free one; the Monte-Carlo mean's distance
    /// to x_N is expected to be this over √R.
    pub rms_spread: f64,
    /// Replicates R.
    pub replicates: usize,
}

/// Theorem 1 on Eq. 38: for each N, the noise-free fit τ_N, `replicates`
/// noisy fits τ^ε_N (σ, λ as given; noise from `rng`), and τ_c.
pub fn theorem1_study(
    ns: &[usize],
    sigma: f64,
    lambda: f64,
    replicates: usize,
    rng: &mut impl Rng,
) -> Result<(Vec<Theorem1Row>, SplineSurface)> {
    let tau_c = continuous_limit(rbc_surface, false, lambda, 4)?;
    let (sa, ta) = axes(false)?;
    let mut rows = Vec::new();
    for &n in ns {
        let sites = grid_sites(n, n, false);
        let f: Vec<f64> = sites.iter().map(|&(s, t)| rbc_surface(s, t)).collect();
        let fitter = surface_problem(&sa, &ta, &sites, None)?.fitter(lambda, Solver::Reduced)?;
        let tau_n = fitter.solve(&f)?;
        let x_n = SplineSurface::new(sa, ta, tau_n.clone())?;
        let mut sum = vec![0.0; tau_n.len()];
        let mut sumsq = vec![0.0; tau_n.len()];
        let (mut rms_sum, mut ms_c, mut spread2) = (0.0, 0.0, 0.0);
        let mut first = f64::NAN;
        for r in 0..replicates.max(1) {
            let d: Vec<f64> = f
                .iter()
                .map(|v| {
                    let e: f64 = StandardNormal.sample(rng);
                    v + sigma * e
                })
                .collect();
            let tau = fitter.solve(&d)?;
            for (k, v) in tau.iter().enumerate() {
                sum[k] += v;
                sumsq[k] += v * v;
            }
            let x = SplineSurface::new(sa, ta, tau.clone())?;
            let e = rms_error(&x, rbc_surface);
            spread2 += rms_error(&x, |s, t| x_n.value(s, t)).powi(2);
            if r == 0 {
                first = e;
            }
            rms_sum += e;
            ms_c += coef_distance(&tau, &tau_c.coef).powi(2);
        }
        let rn = replicates.max(1) as f64;
        let mean: Vec<f64> = sum.iter().map(|v| v / rn).collect();
        let var_total: f64 = sumsq
            .iter()
            .zip(&mean)
            .map(|(s2, m)| (s2 / rn - m * m).max(0.0))
            .sum::<f64>()
            * rn
            / (rn - 1.0).max(1.0);
        let mc = SplineSurface::new(sa, ta, mean.clone())?;
        rows.push(Theorem1Row {
            n,
            rms_noise_free: rms_error(&x_n, rbc_surface),
            rms_noisy_mean: rms_sum / rn,
            rms_noisy_first: first,
            rms_mc_mean: rms_error(&mc, rbc_surface),
            tau_n_to_tau_c: coef_distance(&tau_n, &tau_c.coef),
            mean_square_tau_eps_to_tau_c: ms_c / rn,
            mc_mean_to_tau_n: coef_distance(&mean, &tau_n),
            mc_standard_error: (var_total / rn).sqrt(),
            rms_mc_mean_to_noise_free: rms_error(&mc, |s, t| x_n.value(s, t)),
            rms_spread: (spread2 / rn).sqrt(),
            replicates: replicates.max(1),
        });
    }
    Ok((rows, tau_c))
}
