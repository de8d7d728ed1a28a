//! Levenberg–Marquardt for residual vectors, with the Gauss–Newton
//! covariance of the result.
//!
//! Minimises `½‖r(x)‖²` over `x ∈ ℝⁿ` (the caller chooses a scaling in
//! which a unit step is comparable for every parameter: log parameters,
//! temperatures in kelvin). The Jacobian is by forward differences of
//! `step` per coordinate, its columns evaluated in parallel (rayon; each is
//! an independent simulation, so the result does not depend on the number
//! of threads). Marquardt's scaling `λ·diag(JᵀJ)` with λ ×10 / ÷10 on
//! rejection / acceptance; stops when the relative decrease of the cost is
//! below `ftol` or after `max_iterations`.
//!
//! Covariance: `σ² (JᵀJ)⁺` with `σ² = ‖r‖²/(m − n)`, the pseudo-inverse
//! from the SVD (singular values below 1e-12 of the largest are dropped,
//! their directions get an infinite variance: the parameters that move
//! along them are not determined).

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::IdentifyError;

/// Settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LmOptions {
    /// Iterations at most.
    pub max_iterations: usize,
    /// Stop when the cost falls by less than this fraction in an accepted
    /// step.
    pub ftol: f64,
    /// Forward-difference step per coordinate.
    pub step: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            ftol: 1e-4,
            step: 1e-3,
        }
    }
}

/// The result of a fit.
#[derive(Clone, Debug, PartialEq)]
pub struct LmResult {
    /// The minimiser.
    pub x: Vec<f64>,
    /// `‖r‖²` there.
    pub cost: f64,
    /// Residuals.
    pub m: usize,
    /// Iterations taken.
    pub iterations: usize,
    /// Whether the minimiser stopped because it ran out of iterations
    /// (`max_iterations`) rather than because the cost stopped falling:
    /// `x` may then not be the optimum.
    pub stopped_by_budget: bool,
    /// Residual evaluations.
    pub evaluations: usize,
    /// Standard deviation of each coordinate (∞ where undetermined).
    pub std: Vec<f64>,
    /// Correlation matrix (row-major n×n; NaN where a variance is ∞).
    pub correlation: Vec<f64>,
}

fn sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Minimises `‖f(x)‖²` from `x0`.
pub fn levenberg_marquardt<F>(f: F, x0: &[f64], opts: LmOptions) -> Result<LmResult, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    let n = x0.len();
    let mut x = x0.to_vec();
    let mut r = f(&x)?;
    let m = r.len();
    if m <= n {
        return Err(IdentifyError::TooFewData {
            residuals: m,
            parameters: n,
        });
    }
    let mut cost = sq(&r);
    let mut evaluations = 1;
    let mut lambda = 1e-2;
    let mut iterations = 0;
    let mut jac = jacobian(&f, &x, &r, opts.step)?;
    evaluations += n;
    while iterations < opts.max_iterations {
        iterations += 1;
        let jm = DMatrix::from_fn(m, n, |i, j| jac[j][i]);
        let rv = DVector::from_column_slice(&r);
        let jtj = jm.transpose() * &jm;
        let g = jm.transpose() * rv;
        let mut accepted = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            for k in 0..n {
                a[(k, k)] += lambda * jtj[(k, k)].max(1e-12);
            }
            let Some(chol) = a.cholesky() else {
                lambda *= 10.0;
                continue;
            };
            let dx = chol.solve(&(-&g));
            let trial: Vec<f64> = x.iter().zip(dx.iter()).map(|(a, b)| a + b).collect();
            evaluations += 1;
            match f(&trial) {
                Ok(rt) if sq(&rt).is_finite() && sq(&rt) < cost => {
                    let new_cost = sq(&rt);
                    let decrease = (cost - new_cost) / cost.max(1e-300);
                    x = trial;
                    r = rt;
                    cost = new_cost;
                    lambda = (lambda / 10.0).max(1e-9);
                    accepted = true;
                    if decrease < opts.ftol {
                        return finish(&f, x, r, cost, m, iterations, evaluations, false, opts);
                    }
                    break;
                }
                // A trial the plant refuses (unstable) counts as worse.
                _ => lambda *= 10.0,
            }
        }
        if !accepted {
            // No step lowers the cost: a (local) optimum.
            return finish(&f, x, r, cost, m, iterations, evaluations, false, opts);
        }
        jac = jacobian(&f, &x, &r, opts.step)?;
        evaluations += n;
    }
    finish(&f, x, r, cost, m, iterations, evaluations, true, opts)
}

#[allow(clippy::too_many_arguments)]
fn finish<F>(
    f: &F,
    x: Vec<f64>,
    r: Vec<f64>,
    cost: f64,
    m: usize,
    iterations: usize,
    evaluations: usize,
    stopped_by_budget: bool,
    opts: LmOptions,
) -> Result<LmResult, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    let n = x.len();
    let jac = jacobian(f, &x, &r, opts.step)?;
    let (std, correlation) = covariance(&jac, cost, m);
    Ok(LmResult {
        x,
        cost,
        m,
        iterations,
        stopped_by_budget,
        evaluations: evaluations + n,
        std,
        correlation,
    })
}

/// Forward-difference Jacobian, one column per coordinate, in parallel.
fn jacobian<F>(f: &F, x: &[f64], r0: &[f64], step: f64) -> Result<Vec<Vec<f64>>, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    (0..x.len())
        .into_par_iter()
        .map(|j| {
            let mut xp = x.to_vec();
            xp[j] += step;
            // A step the plant refuses is taken backwards.
            let (rp, h) = match f(&xp) {
                Ok(rp) => (rp, step),
                Err(_) => {
                    xp[j] = x[j] - step;
                    (f(&xp)?, -step)
                }
            };
            Ok(rp.iter().zip(r0).map(|(a, b)| (a - b) / h).collect())
        })
        .collect()
}

/// Standard deviations and correlations from the Jacobian (columns) at the
/// optimum.
pub fn covariance(jac: &[Vec<f64>], cost: f64, m: usize) -> (Vec<f64>, Vec<f64>) {
    let n = jac.len();
    let jm = DMatrix::from_fn(m, n, |i, j| jac[j][i]);
    let jtj = jm.transpose() * &jm;
    let sigma2 = cost / (m.saturating_sub(n)).max(1) as f64;
    let svd = jtj.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let mut cov = DMatrix::zeros(n, n);
    let mut undetermined = vec![false; n];
    if let (Some(u), Some(vt)) = (&svd.u, &svd.v_t) {
        for k in 0..n {
            let s = svd.singular_values[k];
            if s > 1e-12 * smax && s > 0.0 {
                let uk = u.column(k);
                let vk = vt.row(k);
                cov += (uk * vk) / s;
            } else {
                for (j, flag) in undetermined.iter_mut().enumerate() {
                    if vt[(k, j)].abs() > 1e-3 {
                        *flag = true;
                    }
                }
            }
        }
    }
    let std: Vec<f64> = (0..n)
        .map(|j| {
            if undetermined[j] {
                f64::INFINITY
            } else {
                (sigma2 * cov[(j, j)].max(0.0)).sqrt()
            }
        })
        .collect();
    let mut corr = vec![f64::NAN; n * n];
    for i in 0..n {
        for j in 0..n {
            let d = (cov[(i, i)] * cov[(j, j)]).sqrt();
            if !undetermined[i] && !undetermined[j] && d > 0.0 {
                corr[i * n + j] = cov[(i, j)] / d;
            }
        }
    }
    (std, corr)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential_and_its_uncertainty_matches_the_closed_form() {
        // y = a·exp(−b t) + noise-free; then a linear model whose
        // covariance is known in closed form.
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let f = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            Ok(t.iter()
                .zip(&y)
                .map(|(t, y)| x[0] * (-x[1] * t).exp() - y)
                .collect())
        };
        let r = levenberg_marquardt(
            f,
            &[1.0, 0.2],
            LmOptions {
                ftol: 1e-12,
                step: 1e-7,
                ..Default::default()
            },
        )
        .unwrap();
        assert!(
            (r.x[0] - 2.0).abs() < 1e-5 && (r.x[1] - 0.7).abs() < 1e-5,
            "{:?}",
            r.x
        );
        // Straight line y = c0 + c1 t with residuals ±e alternating: the
        // covariance is σ²(XᵀX)⁻¹ exactly.
        let e = 0.1;
        let yl: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, t)| 1.0 + 0.5 * t + if k % 2 == 0 { e } else { -e })
            .collect();
        let fl = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            Ok(t.iter()
                .zip(&yl)
                .map(|(t, y)| x[0] + x[1] * t - y)
                .collect())
        };
        let r = levenberg_marquardt(
            fl,
            &[0.0, 0.0],
            LmOptions {
                ftol: 1e-14,
                step: 1e-6,
                ..Default::default()
            },
        )
        .unwrap();
        let m = t.len() as f64;
        let (st, stt) = (t.iter().sum::<f64>(), t.iter().map(|v| v * v).sum::<f64>());
        let det = m * stt - st * st;
        let sigma2 = r.cost / (m - 2.0);
        let sd1 = (sigma2 * m / det).sqrt();
        assert!((r.std[1] - sd1).abs() < 1e-3 * sd1, "{} vs {sd1}", r.std[1]);
        // A parameter the residuals do not depend on is undetermined.
        let fu = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            Ok(t.iter()
                .zip(&yl)
                .map(|(t, y)| x[0] + x[1] * t - y + 0.0 * x[2])
                .collect())
        };
        let r = levenberg_marquardt(fu, &[0.0, 0.0, 1.0], LmOptions::default()).unwrap();
        assert!(
            r.std[2].is_infinite() && r.std[0].is_finite(),
            "{:?}",
            r.std
        );
    }

    #[test]
    fn a_fit_cut_short_by_its_budget_says_so() {
        let t: Vec<f64> = (0..50).map(|k| k as f64 * 0.1).collect();
        let f = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            Ok(t.iter()
                .map(|t| x[0] * (-x[1] * t).exp() - 2.0 * (-0.7 * t).exp())
                .collect())
        };
        let opts = |max_iterations| LmOptions {
            max_iterations,
            ftol: 1e-12,
            step: 1e-7,
        };
        let short = levenberg_marquardt(f, &[1.0, 0.2], opts(2)).unwrap();
        assert!(short.stopped_by_budget && short.iterations == 2);
        assert!((short.x[1] - 0.7).abs() > 1e-3, "{:?}", short.x);
        let full = levenberg_marquardt(f, &[1.0, 0.2], opts(200)).unwrap();
        assert!(!full.stopped_by_budget, "{} iterations", full.iterations);
    }
}
