//! One-dimensional 3-element fits of force-vs-time trials (seed 002 §4.1):
//! Nelder–Mead [NM65] on (ln k1, ln k2, ln b) of a weighted least-squares
//! cost, with the seed's weighting (the tail ×100 and the three points
//! around the peak ×1000, Fig. 8) or uniform weighting.
//!
//! The model is the plant's 3-element [`Element`], integrated exactly
//! between samples with the input taken linear between them (steps may be
//! uneven). Before the first sample the model is at rest with zero
//! displacement, so the first sample is an instantaneous step response.
//!
//! Nelder–Mead is hand-written (standard coefficients 1, 2, ½, ½; tested on
//! the Rosenbrock function) so that it is deterministic and dependency-free.
//! Fits of many trials run in parallel with rayon; each fit is independent,
//! so the parallel result is identical to the serial one.
//!
//! Left out: fitting several speeds together (the seed fits them
//! separately), confidence intervals.
use crate::error::{Result, VeError};
use plant_common::three_element::{Element, ExactStep, StepLength};
use rayon::prelude::*;

/// Options of the Nelder–Mead minimiser.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NelderMeadOptions {
    /// Maximum number of cost evaluations per run.
    pub max_evaluations: usize,
    /// Stop when the simplex's cost spread is below this (relative to |best|).
    pub cost_tolerance_rel: f64,
    /// Stop when the simplex's extent (max |x_i − x_best|) is below this.
    pub x_tolerance: f64,
    /// Number of restarts from the best point with a fresh simplex (guards
    /// against the premature collapse NM is known for).
    pub restarts: usize,
}

impl Default for NelderMeadOptions {
    fn default() -> Self {
        // In ln-parameter space x_tolerance 1e-4 is 0.01 % relative, far
        // below the fits' noise-driven error; one restart. Measured on the
        // recovery trials: same worst error as (1e-7, 1e-10, 2 restarts)
        // with about half the evaluations (364 vs 700 per trial).
        NelderMeadOptions {
            max_evaluations: 2000,
            cost_tolerance_rel: 1e-7,
            x_tolerance: 1e-4,
            restarts: 1,
        }
    }
}

/// Result of a minimisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NelderMeadResult<const N: usize> {
    /// Best point.
    pub x: [f64; N],
    /// Cost at the best point.
    pub cost: f64,
    /// Cost evaluations used (all runs).
    pub evaluations: usize,
    /// False when the last run stopped at its evaluation budget rather
    /// than at its tolerances.
    pub converged: bool,
}

/// Minimises `f` from `x0` with initial simplex steps `step` (Nelder–Mead
/// with reflection 1, expansion 2, contraction ½, shrink ½). Non-finite
/// costs are treated as +∞.
pub fn nelder_mead<const N: usize>(
    mut f: impl FnMut(&[f64; N]) -> f64,
    x0: [f64; N],
    step: [f64; N],
    opts: NelderMeadOptions,
) -> NelderMeadResult<N> {
    let mut eval = |x: &[f64; N], count: &mut usize| {
        *count += 1;
        let c = f(x);
        if c.is_finite() {
            c
        } else {
            f64::INFINITY
        }
    };
    let mut evaluations = 0;
    let mut best = x0;
    let mut best_cost = eval(&x0, &mut evaluations);
    let mut converged = false;
    for _run in 0..=opts.restarts {
        let mut simplex: Vec<([f64; N], f64)> = Vec::with_capacity(N + 1);
        simplex.push((best, best_cost));
        for i in 0..N {
            let mut x = best;
            x[i] += step[i];
            let c = eval(&x, &mut evaluations);
            simplex.push((x, c));
        }
        let budget_end = evaluations + opts.max_evaluations;
        loop {
            simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
            let (lo, hi) = (simplex[0].1, simplex[N].1);
            let spread = simplex
                .iter()
                .flat_map(|(x, _)| {
                    x.iter()
                        .zip(simplex[0].0.iter())
                        .map(|(a, b)| (a - b).abs())
                })
                .fold(0.0, f64::max);
            if (hi - lo).abs() <= opts.cost_tolerance_rel * lo.abs().max(f64::MIN_POSITIVE)
                && spread <= opts.x_tolerance
                || spread <= opts.x_tolerance * 1e-3
            {
                converged = true;
                break;
            }
            if evaluations >= budget_end {
                converged = false;
                break;
            }
            let mut centroid = [0.0; N];
            for (x, _) in &simplex[..N] {
                for k in 0..N {
                    centroid[k] += x[k] / N as f64;
                }
            }
            let along = |t: f64| {
                let mut p = [0.0; N];
                for k in 0..N {
                    p[k] = centroid[k] + t * (simplex[N].0[k] - centroid[k]);
                }
                p
            };
            let xr = along(-1.0);
            let cr = eval(&xr, &mut evaluations);
            if cr < simplex[0].1 {
                let xe = along(-2.0);
                let ce = eval(&xe, &mut evaluations);
                simplex[N] = if ce < cr { (xe, ce) } else { (xr, cr) };
            } else if cr < simplex[N - 1].1 {
                simplex[N] = (xr, cr);
            } else {
                let (xc, cc) = if cr < simplex[N].1 {
                    let xc = along(-0.5);
                    (xc, eval(&xc, &mut evaluations))
                } else {
                    let xc = along(0.5);
                    (xc, eval(&xc, &mut evaluations))
                };
                if cc < simplex[N].1.min(cr) {
                    simplex[N] = (xc, cc);
                } else {
                    let x0 = simplex[0].0;
                    for v in simplex.iter_mut().skip(1) {
                        for (vk, x0k) in v.0.iter_mut().zip(x0.iter()) {
                            *vk = x0k + 0.5 * (*vk - x0k);
                        }
                        v.1 = eval(&v.0, &mut evaluations);
                    }
                }
            }
        }
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        if simplex[0].1 <= best_cost {
            best = simplex[0].0;
            best_cost = simplex[0].1;
        }
    }
    NelderMeadResult {
        x: best,
        cost: best_cost,
        evaluations,
        converged,
    }
}

/// How the residuals of a trial are weighted.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Weighting {
    /// The seed's (§4.1): front ×1, tail (after the peak) ×100, the three
    /// points around the peak ×1000.
    Seed,
    /// Every sample ×1.
    Uniform,
}

/// Tail weight of the seed's weighting (§4.1: "the tail 100 times more").
pub const SEED_TAIL_WEIGHT: f64 = 100.0;
/// Peak weight of the seed's weighting (§4.1: "the 3 points around the
/// peak 1000 times more").
pub const SEED_PEAK_WEIGHT: f64 = 1000.0;

/// Per-sample weights for a force series.
pub fn weights(force_n: &[f64], weighting: Weighting) -> Vec<f64> {
    match weighting {
        Weighting::Uniform => vec![1.0; force_n.len()],
        Weighting::Seed => {
            let peak = force_n
                .iter()
                .enumerate()
                .fold((0, f64::NEG_INFINITY), |(bi, bv), (i, &v)| {
                    if v > bv {
                        (i, v)
                    } else {
                        (bi, bv)
                    }
                })
                .0;
            (0..force_n.len())
                .map(|i| {
                    if i + 1 >= peak && i <= peak + 1 {
                        SEED_PEAK_WEIGHT
                    } else if i > peak {
                        SEED_TAIL_WEIGHT
                    } else {
                        1.0
                    }
                })
                .collect()
        }
    }
}

/// A time series that has passed the checks every model run needs.
fn check_series(time_s: &[f64], other: &[f64], what: &'static str) -> Result<()> {
    if time_s.len() != other.len() {
        return Err(VeError::LengthMismatch {
            what,
            got: other.len(),
            expected: time_s.len(),
        });
    }
    if time_s.len() < 2 {
        return Err(VeError::InvalidParameter {
            name: "samples",
            value: time_s.len() as f64,
            reason: "need at least 2 samples",
        });
    }
    for w in time_s.windows(2) {
        if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) {
            return Err(VeError::InvalidParameter {
                name: "time_s",
                value: w[1],
                reason: "must be strictly increasing",
            });
        }
    }
    if time_s.iter().chain(other).any(|v| !v.is_finite()) {
        return Err(VeError::InvalidParameter {
            name: what,
            value: f64::NAN,
            reason: "must be finite",
        });
    }
    Ok(())
}

/// Which way a series drives the element.
#[derive(Clone, Copy)]
enum Drive {
    /// Displacement in, force out.
    Displacement,
    /// Force in, displacement out.
    Force,
}

/// Runs the 1D model over a series: the first sample is the instantaneous
/// response, each later one the exact step from the previous sample. The
/// step is recomputed only when the sample spacing changes.
fn run_series(m: &Element, drive: Drive, time_s: &[f64], input: &[f64]) -> Result<Vec<f64>> {
    let mut out = Vec::with_capacity(time_s.len());
    series(m, drive, time_s, input, |_, y| {
        out.push(y);
        Ok(())
    })?;
    Ok(out)
}

/// The model's output at every sample, passed to `each(k, output)`.
fn series(
    m: &Element,
    drive: Drive,
    time_s: &[f64],
    input: &[f64],
    mut each: impl FnMut(usize, f64) -> Result<()>,
) -> Result<()> {
    let (Some(&t0), Some(&first)) = (time_s.first(), input.first()) else {
        return Ok(());
    };
    each(
        0,
        match drive {
            Drive::Displacement => m.k2() * first,
            Drive::Force => first / m.k2(),
        },
    )?;
    let mut x = 0.0;
    let mut cached: Option<(f64, ExactStep)> = None;
    let (mut t_prev, mut v_prev) = (t0, first);
    for (k, (&t, &v)) in time_s.iter().zip(input).enumerate().skip(1) {
        let h = t - t_prev;
        let step = match cached {
            Some((hc, s)) if hc == h => s,
            _ => {
                let len = StepLength::new(h).map_err(|_| VeError::InvalidParameter {
                    name: "time_s",
                    value: t,
                    reason: "the step from the previous sample is not finite and > 0",
                })?;
                let s = match drive {
                    Drive::Displacement => m.relaxation_step(len),
                    Drive::Force => m.creep_step(len),
                };
                cached = Some((h, s));
                s
            }
        };
        each(
            k,
            match drive {
                Drive::Displacement => step.force(&mut x, v_prev, v),
                Drive::Force => step.displacement(&mut x, v_prev, v),
            },
        )?;
        (t_prev, v_prev) = (t, v);
    }
    Ok(())
}

/// Force (N) of the 1D model for a displacement series (m) at times (s).
pub fn simulate_force(
    k1_n_per_m: f64,
    k2_n_per_m: f64,
    b_n_s_per_m: f64,
    time_s: &[f64],
    displacement_m: &[f64],
) -> Result<Vec<f64>> {
    check_series(time_s, displacement_m, "displacement")?;
    let m = Element::new(k1_n_per_m, k2_n_per_m, b_n_s_per_m)?;
    run_series(&m, Drive::Displacement, time_s, displacement_m)
}

/// Displacement (m) of the 1D model for a force series (N) at times (s).
pub fn simulate_displacement(
    k1_n_per_m: f64,
    k2_n_per_m: f64,
    b_n_s_per_m: f64,
    time_s: &[f64],
    force_n: &[f64],
) -> Result<Vec<f64>> {
    check_series(time_s, force_n, "force")?;
    let m = Element::new(k1_n_per_m, k2_n_per_m, b_n_s_per_m)?;
    run_series(&m, Drive::Force, time_s, force_n)
}

/// Fitted 1D parameters of one trial.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrialFit {
    /// Delayed spring k1 (N/m).
    pub k1_n_per_m: f64,
    /// Series spring k2 (N/m).
    pub k2_n_per_m: f64,
    /// Dashpot b (N·s/m).
    pub b_n_s_per_m: f64,
    /// Unweighted RMS force residual (N).
    pub rms_residual_n: f64,
    /// Final weighted cost (N², normalised by the weight sum).
    pub weighted_cost_n2: f64,
    /// Cost evaluations used.
    pub evaluations: usize,
    /// Whether the minimiser stopped at its tolerances (not its budget).
    pub converged: bool,
    /// How well the trial determines each parameter, in ln units, for
    /// (k1, k2, b): how far ln θ may move (the others re-adjusting) before
    /// the weighted rms model force changes by the fit's own rms residual
    /// or by [`FORCE_RESOLUTION_REL`] of the largest force, whichever is
    /// larger. From the Gauss–Newton Hessian at the optimum; +∞ where it is
    /// singular. 0.1 is ±10 %; ln 10 is a factor of ten either way.
    pub ln_uncertainty: [f64; 3],
}

/// The smallest force change a trial is taken to resolve, relative to its
/// largest force (estimate: a load cell's 0.1 % of range). It floors the
/// misfit in [`TrialFit::ln_uncertainty`], so an exactly fitted trial is
/// not credited with infinite precision.
pub const FORCE_RESOLUTION_REL: f64 = 1e-3;

/// Largest [`TrialFit::ln_uncertainty`] of a parameter the trial
/// determines: ln 100, a factor of a hundred either way. The measure is
/// conservative (it allows the fit to change by its whole misfit, not by
/// a standard error), so the threshold separates orders of magnitude: on a
/// simulated campaign (`fits_of_the_probe_campaign_are_refused_exactly_when_they_are_wrong`)
/// the fits it accepts have factors up to 8.3 and errors up to 47 %, the
/// ones it refuses factors beyond 4·10⁵ and errors beyond 3000 %; a
/// constant or purely elastic force leaves k1 and b free entirely.
pub const MAX_LN_UNCERTAINTY: f64 = 4.605_170_185_988_092; // ln 100

/// Names of the fitted parameters, in [`TrialFit::ln_uncertainty`] order.
pub const FIT_PARAMETERS: [&str; 3] = ["k1", "k2", "b"];

impl TrialFit {
    /// How far each of (k1, k2, b) could move before the fit changes by
    /// its own misfit, as a factor (1.05 is ±5 %): `exp` of
    /// [`TrialFit::ln_uncertainty`].
    pub fn uncertainty_factor(&self) -> [f64; 3] {
        self.ln_uncertainty.map(f64::exp)
    }

    /// Refuses a fit whose parameters the trial does not determine: the
    /// minimiser ran out of evaluations, a parameter left f64 (0 or ∞
    /// after `exp`), or a parameter could change by more than a factor
    /// [`MAX_LN_UNCERTAINTY`].exp() without the fit changing by more than
    /// its own misfit.
    pub fn check_determined(&self) -> Result<()> {
        let values = [self.k1_n_per_m, self.k2_n_per_m, self.b_n_s_per_m];
        let free: Vec<usize> = (0..3)
            .filter(|&k| !(values[k].is_normal() && self.ln_uncertainty[k] <= MAX_LN_UNCERTAINTY))
            .collect();
        if free.is_empty() && self.converged {
            return Ok(());
        }
        let factor = |k: usize| {
            let u = self.ln_uncertainty[k];
            if u.is_finite() && u < 700.0 {
                let x = u.exp();
                if x < 1e6 {
                    format!("a factor of {x:.2}")
                } else {
                    format!("a factor of {}", plant_common::short_number(x))
                }
            } else {
                "any factor".into()
            }
        };
        let reason = if free.is_empty() {
            format!(
                "the fit did not settle within its {} evaluations (an ill-conditioned trial)",
                self.evaluations
            )
        } else {
            format!(
                "the trial does not determine {}: the fit stays as good with {}",
                free.iter()
                    .map(|&k| FIT_PARAMETERS[k])
                    .collect::<Vec<_>>()
                    .join(" and "),
                free.iter()
                    .map(|&k| format!("{} changed by {}", FIT_PARAMETERS[k], factor(k)))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        Err(VeError::NotDetermined { reason })
    }
}

/// Weighted squared force error of parameters `(k1, k2, b)`; allocation-free.
/// Residuals are multiplied by `scale` (a power of two, so exactly)
/// before squaring: forces of 1e150 N would overflow their squares.
#[allow(clippy::too_many_arguments)]
fn cost(
    k1: f64,
    k2: f64,
    b: f64,
    time_s: &[f64],
    u: &[f64],
    f: &[f64],
    w: &[f64],
    scale: f64,
) -> f64 {
    let Ok(m) = Element::new(k1, k2, b) else {
        return f64::INFINITY;
    };
    let mut total = 0.0;
    let run = series(&m, Drive::Displacement, time_s, u, |k, model_f| {
        let r = (model_f - f[k]) * scale;
        total += w[k] * r * r;
        Ok(())
    });
    if run.is_err() {
        return f64::INFINITY;
    }
    total
}

/// Fits (k1, k2, b) to a force-vs-time trial with the given weighting.
pub fn fit_trial(
    time_s: &[f64],
    displacement_m: &[f64],
    force_n: &[f64],
    weighting: Weighting,
    opts: NelderMeadOptions,
) -> Result<TrialFit> {
    check_series(time_s, displacement_m, "displacement")?;
    check_series(time_s, force_n, "force")?;
    let n = time_s.len();
    // Fewer samples than parameters: infinitely many (k1, k2, b) fit them
    // exactly, and the minimiser would return whichever it met first.
    if n < 3 {
        return Err(VeError::TooFewSamples {
            parameters: "k1, k2 and b",
            needed: 3,
            got: n,
        });
    }
    let (peak_i, peak_f) =
        force_n
            .iter()
            .enumerate()
            .fold((0, f64::NEG_INFINITY), |(bi, bv), (i, &v)| {
                if v > bv {
                    (i, v)
                } else {
                    (bi, bv)
                }
            });
    let (u_peak, u_end, f_end) = (
        displacement_m[peak_i],
        displacement_m[n - 1],
        force_n[n - 1],
    );
    if !(u_peak > 0.0 && u_end > 0.0 && peak_f > 0.0 && f_end > 0.0) {
        return Err(VeError::InvalidParameter {
            name: "trial",
            value: peak_f,
            reason:
                "needs positive displacement and force at the peak and at the end (a loading trial)",
        });
    }
    // Initial guess from the data: relaxed stiffness from the end, the
    // instantaneous one above the peak secant, relaxation time ~ 1/10 of
    // the record (only a starting point; the restarts move it).
    let k_relaxed = f_end / u_end;
    let k2_0 = (1.5 * peak_f / u_peak).max(2.0 * k_relaxed);
    let k1_0 = k_relaxed * k2_0 / (k2_0 - k_relaxed);
    let tau_0 = 0.1 * (time_s[n - 1] - time_s[0]);
    let b_0 = tau_0 * (k1_0 + k2_0);
    let w = weights(force_n, weighting);
    let norm = w.iter().sum::<f64>();
    // Residuals in units of the largest force, rounded to a power of two
    // so that the scaling is exact: ordinary trials (forces of order 1 N)
    // fit bit for bit as before, and forces of 1e150 N no longer overflow
    // the cost (their fits went astray at 1e144 N rms with exit 0).
    let force_max = force_n.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let scale = 2f64.powi(-(force_max.log2().round() as i32));
    let objective = |x: &[f64; 3]| {
        cost(
            x[0].exp(),
            x[1].exp(),
            x[2].exp(),
            time_s,
            displacement_m,
            force_n,
            &w,
            scale,
        ) / norm
    };
    let ln2 = std::f64::consts::LN_2;
    let res = nelder_mead(
        objective,
        [k1_0.ln(), k2_0.ln(), b_0.ln()],
        [ln2, ln2, ln2],
        opts,
    );
    let [k1, k2, b] = res.x.map(f64::exp);
    let sim = simulate_force(k1, k2, b, time_s, displacement_m)?;
    let rms = (sim
        .iter()
        .zip(force_n)
        .map(|(a, b)| ((a - b) * scale).powi(2))
        .sum::<f64>()
        / n as f64)
        .sqrt()
        / scale;
    let misfit = (res.cost.max(0.0).sqrt()).max(FORCE_RESOLUTION_REL * force_max * scale);
    Ok(TrialFit {
        k1_n_per_m: k1,
        k2_n_per_m: k2,
        b_n_s_per_m: b,
        rms_residual_n: rms,
        weighted_cost_n2: res.cost / (scale * scale),
        evaluations: res.evaluations,
        converged: res.converged,
        ln_uncertainty: ln_uncertainty(res.x, time_s, displacement_m, &w, norm, scale, misfit),
    })
}

/// [`TrialFit::ln_uncertainty`] at `x` = (ln k1, ln k2, ln b): the
/// Gauss–Newton Hessian `A = Σ w J Jᵀ / Σ w` of the scaled model force
/// (J by central differences in ln units), and `misfit · √(A⁻¹)_kk`.
fn ln_uncertainty(
    x: [f64; 3],
    time_s: &[f64],
    u: &[f64],
    w: &[f64],
    norm: f64,
    scale: f64,
    misfit: f64,
) -> [f64; 3] {
    const H: f64 = 1e-4;
    let force = |x: [f64; 3]| {
        let [k1, k2, b] = x.map(f64::exp);
        simulate_force(k1, k2, b, time_s, u).ok()
    };
    let mut jac: Vec<Vec<f64>> = Vec::with_capacity(3);
    for k in 0..3 {
        let (mut up, mut down) = (x, x);
        up[k] += H;
        down[k] -= H;
        match (force(up), force(down)) {
            (Some(a), Some(b)) => jac.push(
                a.iter()
                    .zip(&b)
                    .map(|(p, m)| (p - m) * scale / (2.0 * H))
                    .collect(),
            ),
            _ => return [f64::INFINITY; 3],
        }
    }
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    for i in 0..time_s.len() {
        for r in 0..3 {
            for c in 0..3 {
                a[(r, c)] += w[i] * jac[r][i] * jac[c][i] / norm;
            }
        }
    }
    // Relative to the largest eigenvalue, anything below 1e-14 is rounding:
    // the Hessian is singular there and the parameters not determined.
    let eig = a.symmetric_eigen();
    let largest = eig.eigenvalues.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !(largest > 0.0 && largest.is_finite()) {
        return [f64::INFINITY; 3];
    }
    // inv = Σ v vᵀ / λ over the eigenpairs; a parameter that enters a
    // singular direction (component above 1e-6) is not determined at all.
    let mut out = [0.0f64; 3];
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(k);
        for (p, o) in out.iter_mut().enumerate() {
            if l > 1e-14 * largest {
                *o += v[p] * v[p] / l;
            } else if v[p].abs() > 1e-6 {
                *o = f64::INFINITY;
            }
        }
    }
    out.map(|d| misfit * d.sqrt())
}

/// Fits every trial in parallel (order preserved; identical to serial).
pub fn fit_trials(
    trials: &[super::measure::Trial],
    weighting: Weighting,
    opts: NelderMeadOptions,
) -> Vec<Result<TrialFit>> {
    trials
        .par_iter()
        .map(|t| fit_trial(&t.time_s, &t.displacement_m, &t.force_n, weighting, opts))
        .collect()
}

/// The same as [`fit_trials`] on one thread (for the equality test/bench).
pub fn fit_trials_serial(
    trials: &[super::measure::Trial],
    weighting: Weighting,
    opts: NelderMeadOptions,
) -> Vec<Result<TrialFit>> {
    trials
        .iter()
        .map(|t| fit_trial(&t.time_s, &t.displacement_m, &t.force_n, weighting, opts))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nelder_mead_finds_the_rosenbrock_minimum() {
        let rosen = |x: &[f64; 2]| (1.0 - x[0]).powi(2) + 100.0 * (x[1] - x[0] * x[0]).powi(2);
        let r = nelder_mead(rosen, [-1.2, 1.0], [0.5, 0.5], NelderMeadOptions::default());
        assert!(
            (r.x[0] - 1.0).abs() < 1e-4 && (r.x[1] - 1.0).abs() < 1e-4,
            "{:?}",
            r
        );
    }

    #[test]
    fn a_fit_needs_a_sample_per_parameter() {
        let e = fit_trial(
            &[0.0, 0.1],
            &[0.0, 1e-3],
            &[0.0, 1.0],
            Weighting::Seed,
            NelderMeadOptions::default(),
        )
        .unwrap_err();
        assert_eq!(
            e,
            VeError::TooFewSamples {
                parameters: "k1, k2 and b",
                needed: 3,
                got: 2
            }
        );
        assert!(e.to_string().contains("at least 3 samples"), "{e}");
    }

    #[test]
    fn seed_weights_mark_three_peak_points_and_the_tail() {
        let f = [0.0, 1.0, 2.0, 3.0, 2.5, 2.0, 1.9];
        let w = weights(&f, Weighting::Seed);
        assert_eq!(w, vec![1.0, 1.0, 1000.0, 1000.0, 1000.0, 100.0, 100.0]);
    }
}
