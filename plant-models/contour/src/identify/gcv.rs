//! The smoothing parameter λ: given by the user, or chosen by generalised
//! cross-validation (Craven & Wahba 1979; the paper fixes λ by hand).
//!
//! For a linear smoother `x̂ = H(λ) d` with weights w,
//! `V(λ) = (Σ w (x̂ − d)² / Σ w) / (1 − γ tr H / N)²`, averaged over the data
//! channels (x and y of a parametric curve share one λ). With γ = 1 this is
//! Craven & Wahba's score; plain GCV undersmooths now and then, and when
//! the knots allow interpolation (tr H → N) its score tends to a finite
//! limit, so it can pick λ → 0 and return the noise, or wild excursions
//! between sparse points (issue 29: one contour in 60, area 7× the truth).
//! We use γ = [`GCV_GAMMA`] = 1.4 (Kim & Gu 2004, J. R. Statist. Soc. B
//! 66:337; the default of Wood's `mgcv`): V is infinite once `γ tr H ≥ N`,
//! which is the lower bound on λ from the data's degrees of freedom — at
//! least 1 − 1/γ ≈ 29 % of the data are left to estimate the noise. A
//! minimum against that bound ([`LambdaReport::at_dof_bound`]) or at an end
//! of the scan means the data did not determine λ; the caller flags it.
//!
//! V is scanned on a
//! grid of λ = λ₀·10^k, k = −9 … 3 in half decades, around the problem's
//! natural unit λ₀ ([`FitProblem::lambda_scale`]), and the best grid point
//! is refined by golden-section search on log λ to 0.01 decade. GCV can
//! have several local minima; the grid keeps the search from the nearest
//! one. `tr H` comes from selected inversion (no dense inverse).
use crate::error::{check_positive, ContourError, Result};
use crate::model::fit::{FitProblem, Fitter, Solver};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// γ of the modified GCV score (Kim & Gu 2004): each effective parameter
/// counts 1.4 times in the denominator.
pub const GCV_GAMMA: f64 = 1.4;

/// Largest λ a fit takes. The natural unit λ₀ (the scan's centre,
/// [`FitProblem::lambda_scale`]) is below 0.2 for every knot count, so
/// 10⁶ is ≥ 5·10⁶ λ₀: far past the point where the spline is its
/// least-squares line or constant, while `λQ + BWBᵀ` stays factorable.
/// (Beyond it, λ = 10³⁰⁸ overflowed the matrix and the SVD never returned:
/// issue 31, item 4.)
pub const MAX_LAMBDA: f64 = 1e6;

/// Checks a given λ: finite, > 0 and ≤ [`MAX_LAMBDA`].
pub fn check_lambda(lambda: f64) -> Result<f64> {
    check_positive("lambda", lambda)?;
    if lambda > MAX_LAMBDA {
        return Err(ContourError::InvalidParameter {
            name: "lambda",
            value: lambda,
            reason: "must be at most 1e6 (λ ≥ 10⁶ already smooths any contour to its mean; the scan's unit λ₀ is below 0.2)",
        });
    }
    Ok(lambda)
}

/// How λ is set.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Lambda {
    /// A given value.
    Fixed(f64),
    /// The minimiser of the GCV score.
    Gcv,
}

/// What the λ selection found.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LambdaReport {
    /// λ used.
    pub lambda: f64,
    /// `V(λ)`, the GCV score at λ (None past the degrees-of-freedom bound,
    /// `γ tr H ≥ N`, which only a given λ can be).
    pub gcv: Option<f64>,
    /// `tr H`, the effective number of parameters.
    pub trace_hat: f64,
    /// Whether λ was chosen by GCV.
    pub by_gcv: bool,
    /// GCV's minimum sits at an end of the scanned range (λ₀·10⁻⁹ or
    /// λ₀·10³): typically too few data for the knots (N ≤ free
    /// coefficients) so that GCV heads for interpolation, or data with no
    /// detectable signal.
    pub at_scan_edge: bool,
    /// GCV's minimum sits against the degrees-of-freedom bound
    /// (`γ tr H → N`, see the module): the score would keep falling
    /// towards interpolation, so the data show no noise to smooth
    /// (noise-free, or too few points for the knots) and λ is not
    /// determined by them.
    #[serde(default)]
    pub at_dof_bound: bool,
    /// The scanned (λ, V) pairs that have a score (empty for a fixed λ;
    /// λ past the degrees-of-freedom bound have none).
    pub scanned: Vec<(f64, f64)>,
}

/// GCV score `V` and `tr H` of `fitter` on data channels (each one value per
/// sample).
pub fn gcv_score(fitter: &Fitter, channels: &[&[f64]]) -> Result<(f64, f64)> {
    let n = fitter.samples() as f64;
    let tr = fitter.trace_hat();
    let wsum: f64 = fitter.weights().iter().sum();
    let mut v = 0.0;
    for d in channels {
        let tau = fitter.solve(d)?;
        v += fitter.weighted_rss(&tau, d) / wsum;
    }
    v /= channels.len().max(1) as f64;
    let free = 1.0 - GCV_GAMMA * tr / n;
    // Past the degrees-of-freedom bound the score is not defined.
    let score = if free > 1e-9 {
        v / (free * free)
    } else {
        f64::INFINITY
    };
    Ok((score, tr))
}

/// Grid of log10(λ/λ₀).
const GRID_LO: f64 = -9.0;
const GRID_HI: f64 = 3.0;
const GRID_STEP: f64 = 0.5;
/// Golden-section tolerance in decades.
const REFINE_TOL: f64 = 0.01;

/// Factors `problem` for the λ `lambda` asks for, scanning GCV on
/// `channels` when asked to.
pub fn factor_with(
    problem: &Arc<FitProblem>,
    lambda: Lambda,
    solver: Solver,
    channels: &[&[f64]],
) -> Result<(Fitter, LambdaReport)> {
    match lambda {
        Lambda::Fixed(l) => {
            check_lambda(l)?;
            let f = problem.fitter(l, solver)?;
            let (gcv, tr) = gcv_score(&f, channels)?;
            Ok((
                f,
                LambdaReport {
                    lambda: l,
                    gcv: Some(gcv).filter(|v| v.is_finite()),
                    trace_hat: tr,
                    by_gcv: false,
                    at_scan_edge: false,
                    at_dof_bound: false,
                    scanned: Vec::new(),
                },
            ))
        }
        Lambda::Gcv => choose_by_gcv(problem, solver, channels),
    }
}

fn choose_by_gcv(
    problem: &Arc<FitProblem>,
    solver: Solver,
    channels: &[&[f64]],
) -> Result<(Fitter, LambdaReport)> {
    let l0 = problem.lambda_scale();
    let mut scanned = Vec::new();
    let mut eval = |k: f64| -> f64 {
        let lam = l0 * 10f64.powf(k);
        let v = problem
            .fitter(lam, solver)
            .and_then(|f| gcv_score(&f, channels))
            .map(|(v, _)| v)
            .unwrap_or(f64::INFINITY);
        if v.is_finite() {
            scanned.push((lam, v));
            v
        } else {
            f64::INFINITY
        }
    };
    let steps = ((GRID_HI - GRID_LO) / GRID_STEP).round() as usize;
    let mut best = (f64::INFINITY, GRID_LO);
    let mut grid = Vec::with_capacity(steps + 1);
    for i in 0..=steps {
        let k = GRID_LO + GRID_STEP * i as f64;
        let v = eval(k);
        grid.push(v);
        if v < best.0 {
            best = (v, k);
        }
    }
    let best_i = ((best.1 - GRID_LO) / GRID_STEP).round() as usize;
    let below_has_no_score = best_i > 0 && !grid[best_i - 1].is_finite();
    if !best.0.is_finite() {
        return Err(ContourError::Unsolvable(
            "no λ gave a finite GCV score (N ≤ tr H everywhere: too few data points for the knots)"
                .into(),
        ));
    }
    // Golden-section search on [k − step, k + step].
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut a, mut b) = (best.1 - GRID_STEP, best.1 + GRID_STEP);
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (eval(c), eval(d));
    while b - a > REFINE_TOL {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = eval(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = eval(d);
        }
    }
    let (_, k) = [(fc, c), (fd, d), best]
        .into_iter()
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .unwrap_or(best);
    // Against the degrees-of-freedom bound: a little less smoothing has
    // no score at all.
    let at_dof_bound = below_has_no_score && !eval(k - 2.0 * REFINE_TOL).is_finite();
    let lam = l0 * 10f64.powf(k);
    let at_scan_edge = k <= GRID_LO + GRID_STEP || k >= GRID_HI - GRID_STEP;
    let f = problem.fitter(lam, solver)?;
    let (gcv, tr) = gcv_score(&f, channels)?;
    scanned.sort_by(|x, y| x.0.total_cmp(&y.0));
    Ok((
        f,
        LambdaReport {
            lambda: lam,
            gcv: Some(gcv).filter(|v| v.is_finite()),
            trace_hat: tr,
            by_gcv: true,
            at_scan_edge,
            at_dof_bound,
            scanned,
        },
    ))
}
