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
//! along them are not determined). That form assumes independent residuals
//! of one variance and a right model. [`block_robust_std`] drops both
//! assumptions for residuals grouped in blocks (log segments): the
//! cluster-robust "sandwich" `(JᵀJ)⁺ (Σ_b J_bᵀ r_b r_bᵀ J_b) (JᵀJ)⁺`, which
//! is what the spread of the estimate over resampled segments would be to
//! first order; residuals correlated within a block, or a block the model
//! fits badly, widen it.

use nalgebra::{DMatrix, DVector};
use std::sync::atomic::{AtomicUsize, Ordering};

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
    /// Secant (Broyden) updates of the Jacobian between two
    /// forward-difference ones (0: differences at every iteration, the
    /// textbook method); see [`minimise`]. An iteration whose steps from
    /// an updated Jacobian all fail, and which differences it anew
    /// instead of moving, counts against `max_iterations`.
    pub secant_updates: usize,
    /// A flag the caller sets (non-zero) to end the fit: read before
    /// each iteration and each Jacobian, it ends the minimiser with
    /// [`IdentifyError::Stopped`] (a program's Ctrl-C).
    pub stop: Option<StopFlag>,
}

impl Default for LmOptions {
    fn default() -> Self {
        Self {
            max_iterations: 100,
            ftol: 1e-4,
            step: 1e-3,
            secant_updates: 0,
            stop: None,
        }
    }
}

/// A flag that asks a fit to stop when it holds a non-zero value (e.g.
/// the number of the signal that asked); two flags are equal when they
/// are the same flag.
#[derive(Clone, Copy, Debug)]
pub struct StopFlag(pub &'static AtomicUsize);

impl PartialEq for StopFlag {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.0, other.0)
    }
}

impl LmOptions {
    /// `f` that first checks whether the caller asked the fit to stop
    /// (then [`IdentifyError::Stopped`], `f` not run): a stop ends a fit
    /// within one evaluation, however many a Jacobian or a step needs.
    pub(crate) fn stoppable<'a, F>(
        &'a self,
        f: &'a F,
    ) -> impl Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync + 'a
    where
        F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
    {
        move |x| {
            self.check_stop()?;
            f(x)
        }
    }

    /// An error if the caller asked the fit to stop.
    fn check_stop(&self) -> Result<(), IdentifyError> {
        match self.stop {
            Some(StopFlag(flag)) if flag.load(Ordering::Relaxed) != 0 => {
                Err(IdentifyError::Stopped)
            }
            _ => Ok(()),
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
    /// Jacobians from a replay carrying derivatives ([`JacobianCost`]),
    /// not counted in `evaluations`.
    pub derivative_replays: usize,
    /// Standard deviation of each coordinate (∞ where undetermined).
    pub std: Vec<f64>,
    /// Correlation matrix (row-major n×n; NaN where a variance is ∞).
    pub correlation: Vec<f64>,
    /// Residuals at `x`.
    pub residuals: Vec<f64>,
    /// The Jacobian at `x`, one column (m values) per coordinate.
    pub jacobian: Vec<Vec<f64>>,
}

fn sq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Minimises `‖f(x)‖²` from `x0`.
pub fn levenberg_marquardt<F>(f: F, x0: &[f64], opts: LmOptions) -> Result<LmResult, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    minimise(&f, x0, opts)?.finish(&f, opts)
}

/// Where the minimiser stopped, before the Jacobian there that the
/// covariance needs ([`Minimum::finish`]): a caller with several starting
/// points computes it only for the one it keeps.
#[derive(Clone, Debug)]
pub struct Minimum {
    /// The minimiser.
    pub x: Vec<f64>,
    /// `‖r‖²` there.
    pub cost: f64,
    /// Residuals at `x`.
    pub residuals: Vec<f64>,
    /// Iterations taken.
    pub iterations: usize,
    /// Residual evaluations so far.
    pub evaluations: usize,
    /// Jacobians from a replay carrying derivatives so far.
    pub derivative_replays: usize,
    /// Ran out of iterations (see [`LmResult::stopped_by_budget`]).
    pub stopped_by_budget: bool,
    /// The Jacobian at `x` where the minimiser already has it (it stopped
    /// on a rejected step or on its budget, not just after a step).
    jacobian: Option<Vec<Vec<f64>>>,
    /// A minimum found elsewhere whose minimiser had the Jacobian at `x`
    /// ([`Minimum::from_unit`]): [`Minimum::finish`] recomputes it without
    /// counting it, as the minimiser's own was counted there.
    jacobian_elsewhere: bool,
}

impl Minimum {
    /// Whether the minimiser had the Jacobian at `x` when it stopped.
    pub fn jacobian_known(&self) -> bool {
        self.jacobian.is_some()
    }

    /// A minimum a fit found elsewhere (a work unit, [`super::units`]),
    /// taken only if it reproduces here: the residuals of `f` at its
    /// minimiser must give its cost to the last bit (another log, prior
    /// or build where it ran is an error, not a different minimum). Its
    /// Jacobian, where its minimiser had one, is recomputed by
    /// [`Minimum::finish`], uncounted (the fit counted it).
    pub fn from_unit<F>(
        fit: &super::units::StartFit,
        f: &F,
        opts: LmOptions,
    ) -> Result<Self, IdentifyError>
    where
        F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
    {
        let x = fit.x();
        let cost = f64::from_bits(fit.cost);
        let residuals = opts.stoppable(f)(&x)?;
        let here = sq(&residuals);
        if here.to_bits() != cost.to_bits() {
            return Err(IdentifyError::Remote(format!(
                "a fit run elsewhere does not reproduce here: its cost {cost:e} at its minimiser is {here:e} here (another log, prior or build where it ran?)"
            )));
        }
        Ok(Self {
            x,
            cost,
            residuals,
            iterations: fit.iterations,
            evaluations: fit.evaluations,
            derivative_replays: fit.derivative_replays,
            stopped_by_budget: fit.stopped_by_budget,
            jacobian: None,
            jacobian_elsewhere: fit.jacobian_known,
        })
    }

    /// The result with the Jacobian at the minimiser and the covariance
    /// from it (the Jacobian costs `n` evaluations unless known).
    pub fn finish<F>(self, f: &F, opts: LmOptions) -> Result<LmResult, IdentifyError>
    where
        F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
    {
        let f = opts.stoppable(f);
        let jac = differences(&f, opts.step);
        self.finish_with(&jac, opts)
    }

    /// [`Minimum::finish`] with the Jacobian from `jac` ([`minimise_with`]).
    pub fn finish_with<J>(mut self, jac: &J, opts: LmOptions) -> Result<LmResult, IdentifyError>
    where
        J: Fn(&[f64], &[f64]) -> Result<Costed, IdentifyError> + Sync,
    {
        if self.jacobian_elsewhere {
            opts.check_stop()?;
            self.jacobian = Some(jac(&self.x, &self.residuals)?.0);
        }
        let m = self.residuals.len();
        let mut evaluations = self.evaluations;
        let mut derivative_replays = self.derivative_replays;
        let jac = match self.jacobian {
            Some(jac) => jac,
            None => {
                opts.check_stop()?;
                let (j, cost) = jac(&self.x, &self.residuals)?;
                cost.count(&mut evaluations, &mut derivative_replays);
                j
            }
        };
        let (std, correlation) = covariance(&jac, self.cost, m);
        Ok(LmResult {
            x: self.x,
            cost: self.cost,
            m,
            iterations: self.iterations,
            stopped_by_budget: self.stopped_by_budget,
            evaluations,
            derivative_replays,
            std,
            correlation,
            residuals: self.residuals,
            jacobian: jac,
        })
    }
}

/// A Jacobian's columns (one per coordinate) and what it cost.
pub type Costed = (Vec<Vec<f64>>, JacobianCost);

/// What a Jacobian for [`minimise_with`] cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum JacobianCost {
    /// Residual evaluations (forward differences: one per coordinate).
    Evaluations(usize),
    /// One replay carrying the derivatives (counted apart: it costs
    /// several plain ones, docs/benchmarks.md).
    DerivativeReplay,
}

impl JacobianCost {
    /// Adds itself to the counters.
    fn count(self, evaluations: &mut usize, derivative_replays: &mut usize) {
        match self {
            JacobianCost::Evaluations(n) => *evaluations += n,
            JacobianCost::DerivativeReplay => *derivative_replays += 1,
        }
    }
}

/// The forward-difference Jacobian of `f` with steps `step`, as a
/// Jacobian for [`minimise_with`] (`n` evaluations).
pub fn differences<F>(
    f: &F,
    step: f64,
) -> impl Fn(&[f64], &[f64]) -> Result<Costed, IdentifyError> + Sync + '_
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    move |x: &[f64], r0: &[f64]| {
        Ok((
            jacobian(f, x, r0, step)?,
            JacobianCost::Evaluations(x.len()),
        ))
    }
}

/// The minimiser of [`levenberg_marquardt`], without the final Jacobian.
///
/// The Jacobian is taken by forward differences (`n` evaluations) at the
/// start; with `opts.secant_updates = k > 0` the next `k` accepted steps
/// update it by Broyden's secant formula (the least change that maps the
/// step to the change of the residuals along it; no evaluation) before it
/// is differenced again. A step from an updated Jacobian that lowers the
/// cost by less than `ftol`, or that finds no lower cost in
/// [`SECANT_TRIALS`] trials, sends the minimiser back to forward
/// differences where it is, so it stops only where a step from a
/// differenced Jacobian gains less than `ftol`: the same test as with
/// `k = 0`. The minimum is then a minimum of the same kind, reached by
/// another path (and so not the same to the last digit).
pub fn minimise<F>(f: &F, x0: &[f64], opts: LmOptions) -> Result<Minimum, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    // The differences evaluate the stoppable residuals, as minimise_with's
    // own evaluations do.
    let stoppable = opts.stoppable(f);
    let jac = differences(&stoppable, opts.step);
    minimise_with(f, &jac, x0, opts)
}

/// [`minimise`] with the Jacobian, wherever the textbook method takes
/// one, from `jac`: given a point and the residuals there, the Jacobian's
/// columns and what it cost in evaluations (forward differences,
/// [`differences`]: `n`; a replay carrying derivatives: 1).
pub fn minimise_with<F, J>(
    f: &F,
    jac_at: &J,
    x0: &[f64],
    opts: LmOptions,
) -> Result<Minimum, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
    J: Fn(&[f64], &[f64]) -> Result<Costed, IdentifyError> + Sync,
{
    let f = &opts.stoppable(f);
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
    opts.check_stop()?;
    let mut derivative_replays = 0;
    let (mut jac, cost_j) = jac_at(&x, &r)?;
    cost_j.count(&mut evaluations, &mut derivative_replays);
    // Secant updates applied to `jac` since it was differenced at a point
    // (0: it is the forward-difference Jacobian at `x`).
    let mut updates = 0;
    let stop =
        |x, r, cost, (iterations, evaluations, derivative_replays), budget, jacobian| Minimum {
            x,
            cost,
            residuals: r,
            iterations,
            evaluations,
            derivative_replays,
            stopped_by_budget: budget,
            jacobian,
            jacobian_elsewhere: false,
        };
    while iterations < opts.max_iterations {
        opts.check_stop()?;
        iterations += 1;
        let trials = if updates == 0 { 8 } else { SECANT_TRIALS };
        let lambda_before = lambda;
        let Some((trial, rt, new_cost)) =
            lm_step(f, &x, &r, cost, &jac, &mut lambda, &mut evaluations, trials)?
        else {
            if updates == 0 {
                // No step lowers the cost: a (local) optimum, where the
                // Jacobian is the one just used.
                return Ok(stop(
                    x,
                    r,
                    cost,
                    (iterations, evaluations, derivative_replays),
                    false,
                    Some(jac),
                ));
            }
            // The updated Jacobian found no lower cost: difference anew,
            // with the damping the failed trials started from (their
            // rejections judged the updated Jacobian, not the point).
            lambda = lambda_before;
            opts.check_stop()?;
            let (j, cost_j) = jac_at(&x, &r)?;
            jac = j;
            cost_j.count(&mut evaluations, &mut derivative_replays);
            updates = 0;
            continue;
        };
        let decrease = (cost - new_cost) / cost.max(1e-300);
        let converged = decrease < opts.ftol;
        let difference = converged || updates >= opts.secant_updates;
        if !difference {
            // Carried along the step, from where it was taken.
            let dx: Vec<f64> = trial.iter().zip(&x).map(|(a, b)| a - b).collect();
            let dr: Vec<f64> = rt.iter().zip(&r).map(|(a, b)| a - b).collect();
            broyden_update(&mut jac, &dx, &dr);
        }
        x = trial;
        r = rt;
        cost = new_cost;
        if converged && updates == 0 {
            return Ok(stop(
                x,
                r,
                cost,
                (iterations, evaluations, derivative_replays),
                false,
                None,
            ));
        }
        opts.check_stop()?;
        if difference {
            let (j, cost_j) = jac_at(&x, &r)?;
            jac = j;
            cost_j.count(&mut evaluations, &mut derivative_replays);
            updates = 0;
        } else {
            updates += 1;
        }
    }
    let known = (updates == 0).then_some(jac);
    Ok(stop(
        x,
        r,
        cost,
        (iterations, evaluations, derivative_replays),
        true,
        known,
    ))
}

/// Trials (λ raised tenfold after each) a step from an updated Jacobian
/// gets before the minimiser takes forward differences instead (from a
/// differenced one: 8).
pub const SECANT_TRIALS: usize = 2;

/// Broyden's rank-one update of `jac` (columns) for a step `dx` that
/// changed the residuals by `dr`: the least change of the Jacobian that
/// maps `dx` to `dr`.
fn broyden_update(jac: &mut [Vec<f64>], dx: &[f64], dr: &[f64]) {
    let dxdx: f64 = dx.iter().map(|v| v * v).sum();
    if dxdx.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return;
    }
    let mut u = dr.to_vec();
    for (col, d) in jac.iter().zip(dx) {
        for (ui, c) in u.iter_mut().zip(col) {
            *ui -= c * d;
        }
    }
    for (col, d) in jac.iter_mut().zip(dx) {
        let w = d / dxdx;
        for (c, ui) in col.iter_mut().zip(&u) {
            *c += ui * w;
        }
    }
}

/// One Levenberg–Marquardt step from `x` with the Jacobian `jac`: λ grows
/// tenfold per rejected trial (at most `trials`) and falls tenfold on
/// acceptance; the accepted trial point, its residuals and cost.
#[allow(clippy::type_complexity, clippy::too_many_arguments)] // (x, r, cost)
fn lm_step<F>(
    f: &F,
    x: &[f64],
    r: &[f64],
    cost: f64,
    jac: &[Vec<f64>],
    lambda: &mut f64,
    evaluations: &mut usize,
    trials: usize,
) -> Result<Option<(Vec<f64>, Vec<f64>, f64)>, IdentifyError>
where
    F: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    let (m, n) = (r.len(), x.len());
    let jm = DMatrix::from_fn(m, n, |i, j| jac[j][i]);
    let rv = DVector::from_column_slice(r);
    let jtj = jm.transpose() * &jm;
    let g = jm.transpose() * rv;
    for _ in 0..trials {
        let mut a = jtj.clone();
        for k in 0..n {
            a[(k, k)] += *lambda * jtj[(k, k)].max(1e-12);
        }
        let Some(chol) = a.cholesky() else {
            *lambda *= 10.0;
            continue;
        };
        let dx = chol.solve(&(-&g));
        let trial: Vec<f64> = x.iter().zip(dx.iter()).map(|(a, b)| a + b).collect();
        *evaluations += 1;
        match f(&trial) {
            Ok(rt) if sq(&rt).is_finite() && sq(&rt) < cost => {
                let new_cost = sq(&rt);
                *lambda = (*lambda / 10.0).max(1e-9);
                return Ok(Some((trial, rt, new_cost)));
            }
            // The caller stopped the fit: no step is taken.
            Err(IdentifyError::Stopped) => return Err(IdentifyError::Stopped),
            // A trial the plant refuses (unstable) counts as worse.
            _ => *lambda *= 10.0,
        }
    }
    Ok(None)
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

/// `(JᵀJ)⁺` of a Jacobian and which coordinates move along a direction
/// it leaves undetermined: what [`systematic_shift_with`] and
/// [`block_robust_std_with`] share, computed once for several of them.
#[derive(Clone, Debug)]
pub struct NormalInverse {
    pinv: DMatrix<f64>,
    undetermined: Vec<bool>,
}

impl NormalInverse {
    /// Of the Jacobian `jac` (columns of `m` values).
    pub fn new(jac: &[Vec<f64>], m: usize) -> Self {
        let (pinv, undetermined) = normal_pinv(jac, m);
        Self { pinv, undetermined }
    }
}

/// `(JᵀJ)⁺` from the SVD and which coordinates move along a dropped
/// (undetermined) direction.
fn normal_pinv(jac: &[Vec<f64>], m: usize) -> (DMatrix<f64>, Vec<bool>) {
    let n = jac.len();
    let jm = DMatrix::from_fn(m, n, |i, j| jac[j][i]);
    let jtj = jm.transpose() * &jm;
    let svd = jtj.svd(true, true);
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
    (cov, undetermined)
}

/// Standard deviations and correlations from the Jacobian (columns) at the
/// optimum.
pub fn covariance(jac: &[Vec<f64>], cost: f64, m: usize) -> (Vec<f64>, Vec<f64>) {
    let n = jac.len();
    let sigma2 = cost / (m.saturating_sub(n)).max(1) as f64;
    let (cov, undetermined) = normal_pinv(jac, m);
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

/// How far (1σ, per coordinate) a systematic change `shift` of the
/// residuals moves the least-squares estimate, to first order:
/// `(JᵀJ)⁺ Jᵀ shift`. For an error the data cannot average out, such as a
/// reading offset common to the whole log (`shift` = its 1σ's effect on
/// every residual), which neither the white-noise nor the block-robust
/// 1σ sees.
pub fn systematic_shift(jac: &[Vec<f64>], shift: &[f64]) -> Vec<f64> {
    systematic_shift_with(&NormalInverse::new(jac, shift.len()), jac, shift)
}

/// [`systematic_shift`] with `(JᵀJ)⁺` of `jac` given.
pub fn systematic_shift_with(inverse: &NormalInverse, jac: &[Vec<f64>], shift: &[f64]) -> Vec<f64> {
    let n = jac.len();
    let (bread, undetermined) = (&inverse.pinv, &inverse.undetermined);
    let g = DVector::from_iterator(
        n,
        jac.iter()
            .map(|col| col.iter().zip(shift).map(|(a, b)| a * b).sum::<f64>()),
    );
    let dx = bread * g;
    (0..n)
        .map(|j| {
            if undetermined[j] {
                f64::INFINITY
            } else {
                dx[j].abs()
            }
        })
        .collect()
}

/// Cluster-robust standard deviations of the coordinates (module docs):
/// residual `i` belongs to block `block[i]`. With `B` blocks the sandwich
/// is scaled by `B/(B − 1) · (m − 1)/(m − n)` (the usual small-sample
/// factor). ∞ where the Jacobian leaves a coordinate undetermined, or with
/// fewer than two blocks.
pub fn block_robust_std(jac: &[Vec<f64>], r: &[f64], block: &[usize]) -> Vec<f64> {
    block_robust_std_with(&NormalInverse::new(jac, r.len()), jac, r, block)
}

/// [`block_robust_std`] with `(JᵀJ)⁺` of `jac` given.
pub fn block_robust_std_with(
    inverse: &NormalInverse,
    jac: &[Vec<f64>],
    r: &[f64],
    block: &[usize],
) -> Vec<f64> {
    let n = jac.len();
    let m = r.len();
    assert_eq!(block.len(), m, "one block index per residual");
    let blocks = block.iter().max().map_or(0, |b| b + 1);
    let mut score = vec![vec![0.0; n]; blocks];
    for (i, (&b, &ri)) in block.iter().zip(r).enumerate() {
        for (j, col) in jac.iter().enumerate() {
            score[b][j] += col[i] * ri;
        }
    }
    let used = score.iter().filter(|g| g.iter().any(|v| *v != 0.0)).count();
    if used < 2 || m <= n {
        return vec![f64::INFINITY; n];
    }
    let mut meat = DMatrix::<f64>::zeros(n, n);
    for g in &score {
        let gv = DVector::from_column_slice(g);
        meat += &gv * gv.transpose();
    }
    let (bread, undetermined) = (&inverse.pinv, &inverse.undetermined);
    let factor = used as f64 / (used - 1) as f64 * (m - 1) as f64 / (m - n) as f64;
    let cov = bread * meat * bread * factor;
    (0..n)
        .map(|j| {
            if undetermined[j] {
                f64::INFINITY
            } else {
                cov[(j, j)].max(0.0).sqrt()
            }
        })
        .collect()
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
            secant_updates: 0,
            stop: None,
            ftol: 1e-12,
            step: 1e-7,
        };
        let short = levenberg_marquardt(f, &[1.0, 0.2], opts(2)).unwrap();
        assert!(short.stopped_by_budget && short.iterations == 2);
        assert!((short.x[1] - 0.7).abs() > 1e-3, "{:?}", short.x);
        let full = levenberg_marquardt(f, &[1.0, 0.2], opts(200)).unwrap();
        assert!(!full.stopped_by_budget, "{} iterations", full.iterations);
    }

    /// Secant updates between differenced Jacobians: on a nonlinear fit
    /// of nine parameters (three peaks and noise, from a start off in
    /// every one) they reach the textbook method's minimum — the same cost
    /// to 1e-9 and coordinates within 1e-3 of their 1σ — and every
    /// evaluation is counted. (Whether they save evaluations depends on
    /// the problem; on the identification's own fits it is measured by
    /// `identify::secant_updates_save_mechanics_replays_on_the_compact_twin`
    /// and docs/benchmarks.md.)
    #[test]
    fn secant_updates_reach_the_textbook_minimum() {
        let t: Vec<f64> = (0..600).map(|k| k as f64 * 0.02).collect();
        let noise = |k: usize| ((k as f64 * 12.9898).sin() * 43_758.545_3).fract() - 0.5;
        let peaks = |x: &[f64], t: f64| -> f64 {
            x.chunks(3)
                .map(|p| p[0] * (-((t - p[1]) / p[2]).powi(2)).exp())
                .sum()
        };
        let truth = [2.0, 3.0, 0.8, 1.0, 6.0, 1.2, 1.5, 9.0, 0.6];
        let y: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, &t)| peaks(&truth, t) + 0.02 * noise(k))
            .collect();
        let calls = AtomicUsize::new(0);
        let f = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            calls.fetch_add(1, Ordering::Relaxed);
            Ok(t.iter().zip(&y).map(|(&t, y)| peaks(x, t) - y).collect())
        };
        let x0 = [1.0, 3.8, 1.3, 1.8, 5.2, 0.7, 0.9, 9.8, 1.1];
        let fit = |secant_updates| {
            calls.store(0, Ordering::Relaxed);
            let opts = LmOptions {
                ftol: 1e-8,
                step: 1e-7,
                secant_updates,
                ..LmOptions::default()
            };
            let r = levenberg_marquardt(f, &x0, opts).unwrap();
            assert_eq!(
                r.evaluations,
                calls.load(Ordering::Relaxed),
                "evaluations counted"
            );
            r
        };
        let plain = fit(0);
        let secant = fit(2);
        assert!(!plain.stopped_by_budget && !secant.stopped_by_budget);
        assert!(
            (secant.cost / plain.cost - 1.0).abs() < 1e-9,
            "{} vs {}",
            secant.cost,
            plain.cost
        );
        for j in 0..x0.len() {
            let z = (secant.x[j] - plain.x[j]) / plain.std[j];
            assert!(
                z.abs() < 1e-3,
                "x[{j}]: {} vs {} ({z} σ)",
                secant.x[j],
                plain.x[j]
            );
        }
    }

    /// Broyden's update maps the step to the residuals' change along it
    /// and leaves the Jacobian unchanged in every direction orthogonal to
    /// the step (the least change that does so).
    #[test]
    fn the_broyden_update_maps_the_step_and_changes_nothing_across_it() {
        let mut jac = vec![
            vec![1.0, 2.0, 3.0, -1.0],
            vec![0.5, -0.25, 4.0, 2.0],
            vec![-3.0, 1.0, 0.0, 1.5],
        ];
        let before = jac.clone();
        let apply = |j: &[Vec<f64>], v: &[f64]| -> Vec<f64> {
            (0..4)
                .map(|i| j.iter().zip(v).map(|(c, vk)| c[i] * vk).sum())
                .collect()
        };
        let dx = [0.3, -0.2, 0.1];
        let dr = [1.0, -2.0, 0.5, 0.25];
        broyden_update(&mut jac, &dx, &dr);
        for (a, b) in apply(&jac, &dx).iter().zip(&dr) {
            assert!((a - b).abs() < 1e-12, "J·dx = {a}, dr = {b}");
        }
        // Orthogonal to dx: (0.2, 0.3, 0) and (1, 0, −3).
        for v in [[0.2, 0.3, 0.0], [1.0, 0.0, -3.0]] {
            for (a, b) in apply(&jac, &v).iter().zip(apply(&before, &v)) {
                assert!((a - b).abs() < 1e-12, "J·v = {a} was {b}");
            }
        }
        // A zero step changes nothing.
        let kept = jac.clone();
        broyden_update(&mut jac, &[0.0; 3], &dr);
        assert_eq!(jac, kept);
    }

    /// Which evaluations a fit makes: every point is the start, a trial
    /// step, or a forward difference at the last accepted point. With
    /// `k` secant updates at most `k + 1` accepted steps (one from the
    /// differenced Jacobian, `k` from updates of it) come between two
    /// differenced Jacobians, and with 0 a differenced Jacobian follows
    /// every accepted step that does not end the fit (the textbook
    /// method); with 2 the updates are used.
    #[test]
    fn between_two_differenced_jacobians_come_at_most_k_accepted_steps() {
        use std::sync::Mutex;
        let t: Vec<f64> = (0..300).map(|k| k as f64 * 0.02).collect();
        let y: Vec<f64> = t
            .iter()
            .map(|t| 2.0 * (-0.9 * t).exp() + 0.5 * (3.0 * t).sin())
            .collect();
        let model = |x: &[f64], t: f64| x[0] * (-x[1] * t).exp() + x[2] * (x[3] * t).sin();
        let seen = Mutex::new(Vec::<Vec<f64>>::new());
        let f = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            seen.lock().unwrap().push(x.to_vec());
            Ok(t.iter().zip(&y).map(|(&t, y)| model(x, t) - y).collect())
        };
        let cost = |x: &[f64]| sq(&f(x).unwrap());
        let step = 1e-6;
        for k in [0, 2] {
            seen.lock().unwrap().clear();
            let opts = LmOptions {
                ftol: 1e-12,
                step,
                secant_updates: k,
                ..LmOptions::default()
            };
            let x0 = [1.0, 0.5, 0.8, 2.7];
            let r = minimise(&f, &x0, opts).unwrap();
            let points = std::mem::take(&mut *seen.lock().unwrap());
            assert_eq!(points.len(), r.evaluations);
            assert_eq!(points[0], x0);
            let (mut at, mut at_cost) = (x0.to_vec(), cost(&x0));
            let (mut columns, mut accepted_since, mut most) = (0, 0, 0);
            for p in &points[1..] {
                let differs: Vec<usize> = (0..4)
                    .filter(|&j| p[j].to_bits() != at[j].to_bits())
                    .collect();
                if differs.len() == 1
                    && p[differs[0]].to_bits() == (at[differs[0]] + step).to_bits()
                {
                    columns += 1;
                    if columns == 4 {
                        (columns, accepted_since) = (0, 0);
                    }
                    continue;
                }
                assert_eq!(columns, 0, "a trial inside a Jacobian (k = {k})");
                let c = cost(p);
                if c < at_cost {
                    (at, at_cost) = (p.clone(), c);
                    accepted_since += 1;
                    most = most.max(accepted_since);
                    assert!(
                        accepted_since <= k + 1,
                        "{accepted_since} accepted steps without differences (k = {k})"
                    );
                }
            }
            assert_eq!(at, r.x, "the fit ends at its last accepted point");
            assert!(
                r.iterations > 4,
                "a fit of {} iterations shows little",
                r.iterations
            );
            assert_eq!(most, k + 1, "k = {k}");
        }
    }

    /// A straight line through residuals that come in runs (a slow wave
    /// the model lacks): the white-noise 1σ of the slope is far too small,
    /// the block-robust one covers the spread of the slope over
    /// realisations of the wave; with independent residuals both agree.
    #[test]
    fn block_robust_std_widens_for_correlated_residuals_only() {
        let t: Vec<f64> = (0..2000).map(|k| k as f64 * 0.01).collect();
        let blocks: Vec<usize> = (0..t.len()).map(|k| k / 100).collect();
        let fit = |y: &[f64]| {
            let f = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
                Ok(t.iter().zip(y).map(|(t, y)| x[0] + x[1] * t - y).collect())
            };
            let opts = LmOptions {
                ftol: 1e-14,
                step: 1e-6,
                ..Default::default()
            };
            let r = levenberg_marquardt(f, &[0.0, 0.0], opts).unwrap();
            let robust = block_robust_std(&r.jacobian, &r.residuals, &blocks);
            (r.x[1], r.std[1], robust[1])
        };
        // Deterministic pseudo-noise: a hash of the index, uniform ±0.5.
        let noise = |k: usize, seed: u64| {
            let mut z = (k as u64 ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15))
                .wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z ^= z >> 31;
            z = z.wrapping_mul(0x94D0_49BB_1331_11EB);
            (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let (mut slopes, mut white, mut robust) = (Vec::new(), Vec::new(), Vec::new());
        for seed in 0..40 {
            // Runs: one level per 100 samples (a block), plus white noise.
            let y: Vec<f64> = (0..t.len())
                .map(|k| 1.0 + 0.5 * t[k] + noise(k / 100, seed + 1000) + 0.1 * noise(k, seed))
                .collect();
            let (s, w, r) = fit(&y);
            slopes.push(s);
            white.push(w);
            robust.push(r);
        }
        let mean = slopes.iter().sum::<f64>() / 40.0;
        let spread = (slopes.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 39.0).sqrt();
        let avg = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        assert!(
            avg(&white) < 0.3 * spread,
            "white {} vs spread {spread}",
            avg(&white)
        );
        assert!(
            (avg(&robust) / spread - 1.0).abs() < 0.35,
            "robust {} vs spread {spread}",
            avg(&robust)
        );
        // Independent residuals: the two agree.
        let y: Vec<f64> = (0..t.len())
            .map(|k| 1.0 + 0.5 * t[k] + 0.1 * noise(k, 7))
            .collect();
        let (_, w, r) = fit(&y);
        assert!((r / w - 1.0).abs() < 0.35, "robust {r} vs white {w}");
    }

    #[test]
    fn a_stop_ends_the_fit_within_one_evaluation() {
        use std::sync::atomic::AtomicUsize;
        // A fit that would take several iterations; the flag is set during
        // the 4th evaluation (the first step's trial, after the start and
        // the two Jacobian columns), and no evaluation may start after it.
        let flag: &'static AtomicUsize = Box::leak(Box::new(AtomicUsize::new(0)));
        let calls = AtomicUsize::new(0);
        let t: Vec<f64> = (0..20).map(f64::from).collect();
        let f = |x: &[f64]| -> Result<Vec<f64>, IdentifyError> {
            if calls.fetch_add(1, Ordering::SeqCst) + 1 == 4 {
                flag.store(15, Ordering::SeqCst);
            }
            Ok(t.iter().map(|t| (x[0] * t).sin() + x[1] - 0.3).collect())
        };
        let opts = LmOptions {
            stop: Some(StopFlag(flag)),
            ..LmOptions::default()
        };
        let e = levenberg_marquardt(f, &[0.9, 0.0], opts).unwrap_err();
        assert!(matches!(e, IdentifyError::Stopped), "{e}");
        assert_eq!(calls.load(Ordering::SeqCst), 4);
        // Unset, the same fit runs on.
        flag.store(0, Ordering::SeqCst);
        assert!(levenberg_marquardt(f, &[0.9, 0.0], opts).is_ok());
    }
}
