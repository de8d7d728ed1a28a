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
use crate::viscoelastic::error::{Result, VeError};
use crate::viscoelastic::three_element::{Element, ExactStep, StepLength};
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
                || evaluations >= budget_end
            {
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
}

/// Weighted squared force error of parameters `(k1, k2, b)`; allocation-free.
fn cost(k1: f64, k2: f64, b: f64, time_s: &[f64], u: &[f64], f: &[f64], w: &[f64]) -> f64 {
    let Ok(m) = Element::new(k1, k2, b) else {
        return f64::INFINITY;
    };
    let mut total = 0.0;
    let run = series(&m, Drive::Displacement, time_s, u, |k, model_f| {
        let r = model_f - f[k];
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
    let objective = |x: &[f64; 3]| {
        cost(
            x[0].exp(),
            x[1].exp(),
            x[2].exp(),
            time_s,
            displacement_m,
            force_n,
            &w,
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
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / n as f64)
        .sqrt();
    Ok(TrialFit {
        k1_n_per_m: k1,
        k2_n_per_m: k2,
        b_n_s_per_m: b,
        rms_residual_n: rms,
        weighted_cost_n2: res.cost,
        evaluations: res.evaluations,
    })
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
