//! The multiplier method with BFGS (Wakamatsu et al., L800 and L809): the
//! constrained minimisation of the potential energy becomes a sequence of
//! unconstrained minimisations of the augmented Lagrangian
//!
//!   L(a) = U(a) + P(a) + Σ_eq (λ c + ρ c²/2) + Σ_ineq (max(0, μ + ρ g)² − μ²)/(2ρ),
//!
//! each solved by BFGS (dense inverse-Hessian update, backtracking line
//! search with the Armijo condition, the update skipped when the
//! curvature condition sᵀy > 0 fails), after which λ ← λ + ρc and
//! μ ← max(0, μ + ρg); ρ grows tenfold whenever the largest violation did
//! not fall to a quarter. P is an optional exterior penalty (self-contact,
//! Eq. 15), weighted with ρ. The multipliers are the reaction forces of
//! the constraints (L803).
//!
//! Why not argmin's BFGS: its Moré–Thuente search stops the whole run with
//! an error when a direction is not a descent direction (which rounding
//! produces near a minimum), and the iterate is lost with it; here such a
//! step resets the inverse Hessian and the search goes on.

use crate::error::{DloError, Result};

/// Equality or inequality (g ≤ 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Equality,
    Inequality,
}

/// A constrained minimisation problem over a vector of variables.
pub trait Problem: Sync {
    /// Number of variables.
    fn vars(&self) -> usize;
    /// Energy U and its gradient (added into `grad`).
    fn energy(&self, x: &[f64], grad: &mut [f64]) -> f64;
    /// The kinds of the constraints, in a fixed order.
    fn kinds(&self) -> &[Kind];
    /// Constraint values (in the order of `kinds`) and their gradients
    /// (one dense row each).
    fn constraints(&self, x: &[f64], values: &mut [f64], jacobian: &mut [Vec<f64>]);
    /// An exterior penalty and its gradient (added), scaled by `weight`.
    fn penalty(&self, _x: &[f64], _weight: f64, _grad: &mut [f64]) -> f64 {
        0.0
    }
}

/// Settings of the multiplier method.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// Outer (multiplier) iterations at most.
    pub max_outer: usize,
    /// BFGS iterations per outer iteration at most.
    pub max_inner: u64,
    /// Largest constraint violation accepted (in the problem's units).
    pub tolerance: f64,
    /// Initial ρ.
    pub rho0: f64,
    /// Largest ρ.
    pub rho_max: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            max_outer: 40,
            max_inner: 400,
            tolerance: 1e-7,
            rho0: 10.0,
            rho_max: 1e9,
        }
    }
}

/// The outcome of a solve.
#[derive(Debug, Clone, PartialEq)]
pub struct Solution {
    /// The variables.
    pub x: Vec<f64>,
    /// Energy U at the solution (without penalty and multiplier terms).
    pub energy: f64,
    /// Largest constraint violation.
    pub max_violation: f64,
    /// Penalty P at the solution (unweighted).
    pub penalty: f64,
    /// Multipliers (reaction forces), in the order of the constraints.
    pub multipliers: Vec<f64>,
    /// Penalty weight ρ at the end.
    pub rho: f64,
    pub outer_iterations: usize,
    pub inner_iterations: u64,
    /// Whether the violation tolerance was met.
    pub converged: bool,
}

struct Augmented<'a, P: Problem> {
    problem: &'a P,
    multipliers: &'a [f64],
    rho: f64,
}

impl<P: Problem> Augmented<'_, P> {
    fn eval(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        grad.iter_mut().for_each(|g| *g = 0.0);
        let mut total = self.problem.energy(x, grad);
        total += self.problem.penalty(x, self.rho, grad);
        let kinds = self.problem.kinds();
        let m = kinds.len();
        let mut c = vec![0.0; m];
        let mut jac = vec![vec![0.0; x.len()]; m];
        self.problem.constraints(x, &mut c, &mut jac);
        for j in 0..m {
            let lam = self.multipliers[j];
            let factor = match kinds[j] {
                Kind::Equality => {
                    total += lam * c[j] + 0.5 * self.rho * c[j] * c[j];
                    lam + self.rho * c[j]
                }
                Kind::Inequality => {
                    let t = (lam + self.rho * c[j]).max(0.0);
                    total += (t * t - lam * lam) / (2.0 * self.rho);
                    t
                }
            };
            if factor != 0.0 {
                for (g, d) in grad.iter_mut().zip(&jac[j]) {
                    *g += factor * d;
                }
            }
        }
        total
    }
}

/// BFGS on `f` from `x`; returns the iterations used.
fn bfgs(f: &dyn Fn(&[f64], &mut [f64]) -> f64, x: &mut Vec<f64>, max_iter: u64) -> u64 {
    let n = x.len();
    let mut h = identity(n);
    let mut g = vec![0.0; n];
    let mut fx = f(x, &mut g);
    let mut g_new = vec![0.0; n];
    let mut x_new = vec![0.0; n];
    let mut it = 0;
    while it < max_iter {
        it += 1;
        let gnorm = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        if gnorm < 1e-11 {
            break;
        }
        let mut d: Vec<f64> = (0..n).map(|i| -dot(&h[i], &g)).collect();
        let mut slope = dot(&d, &g);
        if slope >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            h = identity(n);
            d = g.iter().map(|v| -v).collect();
            slope = -gnorm * gnorm;
        }
        // No step longer than 0.5 in the variables (radians of a Ritz
        // coefficient, lengths in units of L): an early step along a large
        // multiplier gradient would otherwise jump to a far, wild minimum.
        let dnorm = dot(&d, &d).sqrt();
        let mut step = if dnorm > 0.5 { 0.5 / dnorm } else { 1.0 };
        let mut accepted = false;
        let mut f_new = fx;
        for _ in 0..50 {
            for i in 0..n {
                x_new[i] = x[i] + step * d[i];
            }
            f_new = f(&x_new, &mut g_new);
            if f_new.is_finite() && f_new <= fx + 1e-4 * step * slope {
                accepted = true;
                break;
            }
            step *= 0.5;
        }
        if !accepted {
            break;
        }
        let s: Vec<f64> = (0..n).map(|i| x_new[i] - x[i]).collect();
        let y: Vec<f64> = (0..n).map(|i| g_new[i] - g[i]).collect();
        let sy = dot(&s, &y);
        let converged = (fx - f_new).abs() <= 1e-15 * (1.0 + fx.abs());
        std::mem::swap(x, &mut x_new);
        std::mem::swap(&mut g, &mut g_new);
        fx = f_new;
        if converged {
            break;
        }
        if sy > 1e-300 {
            // H ← (I − ρ s yᵀ) H (I − ρ y sᵀ) + ρ s sᵀ.
            let rho = 1.0 / sy;
            let hy: Vec<f64> = (0..n).map(|i| dot(&h[i], &y)).collect();
            let yhy = dot(&y, &hy);
            for i in 0..n {
                for j in 0..n {
                    h[i][j] +=
                        rho * ((1.0 + rho * yhy) * s[i] * s[j] - hy[i] * s[j] - s[i] * hy[j]);
                }
            }
        }
    }
    it
}

fn identity(n: usize) -> Vec<Vec<f64>> {
    (0..n)
        .map(|i| (0..n).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

/// Largest violation: |c| for equalities, max(0, g) for inequalities.
fn violation(kinds: &[Kind], c: &[f64]) -> f64 {
    kinds
        .iter()
        .zip(c)
        .map(|(k, v)| match k {
            Kind::Equality => v.abs(),
            Kind::Inequality => v.max(0.0),
        })
        .fold(0.0, f64::max)
}

/// Minimises `problem` from `x0` by the multiplier method.
pub fn solve<P: Problem>(problem: &P, x0: Vec<f64>, s: &Settings) -> Result<Solution> {
    solve_warm(problem, x0, None, s)
}

/// As [`solve`], starting the multipliers and ρ from `warm` (a solution
/// of a neighbouring problem with the same constraints: continuation).
pub fn solve_warm<P: Problem>(
    problem: &P,
    x0: Vec<f64>,
    warm: Option<(&[f64], f64)>,
    s: &Settings,
) -> Result<Solution> {
    let n = problem.vars();
    if x0.len() != n {
        return Err(DloError::InvalidScenario(format!(
            "start vector has {} values, the problem {n}",
            x0.len()
        )));
    }
    let kinds = problem.kinds().to_vec();
    let m = kinds.len();
    let (mut lam, mut rho) = match warm {
        Some((l, r)) if l.len() == m => (l.to_vec(), r.clamp(s.rho0, s.rho_max)),
        _ => (vec![0.0; m], s.rho0),
    };
    let mut x = x0;
    let mut c = vec![0.0; m];
    let mut jac = vec![vec![0.0; n]; m];
    problem.constraints(&x, &mut c, &mut jac);
    let mut last_violation = violation(&kinds, &c);
    let mut inner_total = 0;
    let mut outer = 0;
    let mut converged = false;
    while outer < s.max_outer {
        outer += 1;
        let aug = Augmented {
            problem,
            multipliers: &lam,
            rho,
        };
        inner_total += bfgs(&|x, g| aug.eval(x, g), &mut x, s.max_inner);
        if !x.iter().all(|v| v.is_finite()) {
            return Err(DloError::NotConverged(
                "BFGS produced a non-finite iterate".into(),
            ));
        }
        problem.constraints(&x, &mut c, &mut jac);
        let v = violation(&kinds, &c);
        for j in 0..m {
            lam[j] = match kinds[j] {
                Kind::Equality => lam[j] + rho * c[j],
                Kind::Inequality => (lam[j] + rho * c[j]).max(0.0),
            };
        }
        if v < s.tolerance {
            converged = true;
            break;
        }
        if v > 0.25 * last_violation {
            rho = (rho * 10.0).min(s.rho_max);
        }
        last_violation = v;
    }
    let mut g = vec![0.0; n];
    let energy = problem.energy(&x, &mut g);
    let penalty = problem.penalty(&x, 1.0, &mut g);
    if !energy.is_finite() {
        return Err(DloError::NotConverged("energy is not finite".into()));
    }
    Ok(Solution {
        energy,
        max_violation: last_violation.min(violation(&kinds, &c)),
        penalty,
        multipliers: lam,
        rho,
        outer_iterations: outer,
        inner_iterations: inner_total,
        converged,
        x,
    })
}

/// Newton's method on the optimality (KKT) conditions from a solution of
/// the multiplier method: the equalities and the inequalities active there
/// (within 10·`tolerance` of the bound) are held as equalities, the Hessian of the Lagrangian is taken by central
/// differences of its analytic gradient, and each step solves
///
///   [H Jᵀ; J 0] [Δx; λ] = −[∇U; c]
///
/// by SVD (redundant rows, such as six conditions on an orientation, are
/// allowed). The multiplier method ends where the violation is small, but
/// in flat valleys of U its BFGS passes stall before the energy is at its
/// minimum; Newton converges there in a few steps.
///
/// The active set is updated between Newton solves (a held bound whose
/// multiplier turns negative is released, a violated one is held) until
/// it no longer changes. Returns `None`, and the caller keeps `sol`,
/// unless the result is such a KKT point with every constraint within
/// `tolerance` and an energy not above `sol`'s (allowing twice Σ|λc| at
/// `sol`, what its violations may have saved, and 1e-6 relative). The penalty term is not
/// included (problems with a penalty are not polished).
pub fn polish<P: Problem>(problem: &P, sol: &Solution, tolerance: f64) -> Option<Solution> {
    let n = problem.vars();
    let kinds = problem.kinds();
    let m = kinds.len();
    let (mut c, mut jac) = (vec![0.0; m], vec![vec![0.0; n]; m]);
    problem.constraints(&sol.x, &mut c, &mut jac);
    // Active by value: the multiplier method meets active bounds to about
    // its tolerance, and its multipliers of inactive rows need not be zero.
    let mut held: Vec<bool> = (0..m)
        .map(|r| kinds[r] == Kind::Equality || c[r] > -10.0 * tolerance)
        .collect();
    // How far `sol`'s energy may sit below the feasible optimum: to first
    // order, the multipliers times the violations.
    let slack: f64 = (0..m)
        .map(|r| {
            let v = match kinds[r] {
                Kind::Equality => c[r].abs(),
                Kind::Inequality => c[r].max(0.0),
            };
            (sol.multipliers[r] * v).abs()
        })
        .sum();
    let mut x = sol.x.clone();
    let mut lam = sol.multipliers.clone();
    for _round in 0..12 {
        let rows: Vec<usize> = (0..m).filter(|&r| held[r]).collect();
        let mut l: Vec<f64> = rows.iter().map(|&r| lam[r]).collect();
        if !newton_kkt(problem, &rows, &mut x, &mut l) {
            return None;
        }
        lam.iter_mut().for_each(|v| *v = 0.0);
        for (q, &r) in rows.iter().enumerate() {
            lam[r] = l[q];
        }
        problem.constraints(&x, &mut c, &mut jac);
        // Release held bounds that pull the wrong way, hold violated ones.
        let mut changed = false;
        for r in 0..m {
            if kinds[r] == Kind::Equality {
                continue;
            }
            if held[r] && lam[r] < -1e-8 {
                held[r] = false;
                lam[r] = 0.0;
                changed = true;
            } else if !held[r] && c[r] > tolerance {
                held[r] = true;
                changed = true;
            }
        }
        if !changed {
            let mut g = vec![0.0; n];
            let energy = problem.energy(&x, &mut g);
            let violation_end = violation(kinds, &c);
            if !energy.is_finite()
                || violation_end > tolerance
                || energy > sol.energy + 2.0 * slack + 1e-6 * (1.0 + sol.energy.abs())
            {
                return None;
            }
            return Some(Solution {
                x,
                energy,
                max_violation: violation_end,
                penalty: 0.0,
                multipliers: lam,
                converged: true,
                ..sol.clone()
            });
        }
    }
    None
}

/// Newton on ∇U + Σ λ∇c = 0, c = 0 over `rows`, from (x, λ); true when it
/// reached stationarity below 1e-9·(1 + ‖∇U‖) and |c| below 1e-12, or,
/// where no step lowers the residual any more, below 1e-7·(1 + ‖∇U‖) and
/// 1e-10.
fn newton_kkt<P: Problem>(problem: &P, rows: &[usize], x: &mut [f64], lam: &mut [f64]) -> bool {
    use nalgebra::{DMatrix, DVector};
    let start = x.to_vec();
    if newton_kkt_from(problem, rows, x, lam) {
        return true;
    }
    x.copy_from_slice(&start);
    // Stalled: again from the least-norm multipliers that best balance ∇U
    // (Jᵀλ = −∇U by SVD). Redundant rows (six conditions on an
    // orientation) leave λ free along the null space of Jᵀ, and the
    // multiplier method, its ρ grown to 1e9, can drift far along it (|λ|
    // 1.5e6 and 1.3e7 where the least-norm one is 55 and 63: campaign cases
    // 85 and 16 of seed 29, issue 29). That drift does not change
    // ∇U + Jᵀλ but does change Σλ∇²c in the Hessian, and with it each
    // Newton step; the steps then stop lowering the residual. Only a
    // stalled polish is retried, so a polish that converged is unchanged.
    let k = rows.len();
    if k == 0 {
        return false;
    }
    let n = problem.vars();
    let m = problem.kinds().len();
    let (mut c, mut jac) = (vec![0.0; m], vec![vec![0.0; n]; m]);
    let mut grad_u = vec![0.0; n];
    problem.energy(x, &mut grad_u);
    problem.constraints(x, &mut c, &mut jac);
    let jt = DMatrix::from_fn(n, k, |i, q| jac[rows[q]][i]);
    let rhs = DVector::from_fn(n, |i, _| -grad_u[i]);
    let svd = jt.svd(true, true);
    let Ok(l) = svd.solve(&rhs, 1e-10 * svd.singular_values.max()) else {
        return false;
    };
    lam.copy_from_slice(l.as_slice());
    newton_kkt_from(problem, rows, x, lam)
}

/// One Newton run of [`newton_kkt`] from (x, λ) as given.
fn newton_kkt_from<P: Problem>(
    problem: &P,
    rows: &[usize],
    x: &mut [f64],
    lam: &mut [f64],
) -> bool {
    use nalgebra::{DMatrix, DVector};
    let n = problem.vars();
    let m = problem.kinds().len();
    let k = rows.len();
    let (mut c, mut jac) = (vec![0.0; m], vec![vec![0.0; n]; m]);
    let lagrangian_gradient =
        |x: &[f64], lam: &[f64], c: &mut Vec<f64>, jac: &mut Vec<Vec<f64>>| {
            let mut g = vec![0.0; n];
            problem.energy(x, &mut g);
            problem.constraints(x, c, jac);
            for (q, &r) in rows.iter().enumerate() {
                for i in 0..n {
                    g[i] += lam[q] * jac[r][i];
                }
            }
            g
        };
    let step = 1e-6;
    for _ in 0..40 {
        let g = lagrangian_gradient(x, lam, &mut c, &mut jac);
        let (c0, j0) = (c.clone(), jac.clone());
        let stationary = g.iter().map(|v| v * v).sum::<f64>().sqrt();
        let violation_now = rows.iter().map(|&r| c0[r].abs()).fold(0.0, f64::max);
        if !stationary.is_finite() {
            return false;
        }
        // Stationary to 1e-9 of the energy gradient's size (rounding puts a
        // floor under the absolute residual of a stiff, finely resolved
        // problem).
        let mut grad_size = vec![0.0; n];
        problem.energy(x, &mut grad_size);
        let grad_size = grad_size.iter().map(|v| v * v).sum::<f64>().sqrt();
        if stationary < 1e-9 * (1.0 + grad_size) && violation_now < 1e-12 {
            return true;
        }
        let size = stationary + violation_now;
        let mut kkt = DMatrix::<f64>::zeros(n + k, n + k);
        let mut probe = x.to_vec();
        for i in 0..n {
            probe[i] = x[i] + step;
            let gp = lagrangian_gradient(&probe, lam, &mut c, &mut jac);
            probe[i] = x[i] - step;
            let gm = lagrangian_gradient(&probe, lam, &mut c, &mut jac);
            probe[i] = x[i];
            for row in 0..n {
                kkt[(row, i)] = (gp[row] - gm[row]) / (2.0 * step);
            }
        }
        for i in 0..n {
            for j in 0..i {
                let v = 0.5 * (kkt[(i, j)] + kkt[(j, i)]);
                kkt[(i, j)] = v;
                kkt[(j, i)] = v;
            }
        }
        let mut rhs = DVector::<f64>::zeros(n + k);
        let mut grad_u = vec![0.0; n];
        problem.energy(x, &mut grad_u);
        for i in 0..n {
            rhs[i] = -grad_u[i];
        }
        for (q, &r) in rows.iter().enumerate() {
            for i in 0..n {
                kkt[(n + q, i)] = j0[r][i];
                kkt[(i, n + q)] = j0[r][i];
            }
            rhs[n + q] = -c0[r];
        }
        // Singular values below 1e-10 of the largest count as zero: the
        // exact zero modes (a planar shape turned about its clamps' axis)
        // and the redundant rows then take no step.
        let svd = kkt.svd(true, true);
        let largest = svd.singular_values.max();
        let Ok(d) = svd.solve(&rhs, 1e-10 * largest) else {
            return false;
        };
        // Damped: the residual ‖∇L‖ + max|c| must fall (Armijo-like).
        let (x0, l0) = (x.to_vec(), lam.to_vec());
        let mut alpha = 1.0;
        let mut accepted = false;
        for _ in 0..30 {
            for i in 0..n {
                x[i] = x0[i] + alpha * d[i];
            }
            for q in 0..k {
                lam[q] = l0[q] + alpha * (d[n + q] - l0[q]);
            }
            let g = lagrangian_gradient(x, lam, &mut c, &mut jac);
            let s_new = g.iter().map(|v| v * v).sum::<f64>().sqrt()
                + rows.iter().map(|&r| c[r].abs()).fold(0.0, f64::max);
            if s_new.is_finite() && s_new < (1.0 - 1e-4 * alpha) * size {
                accepted = true;
                break;
            }
            alpha *= 0.5;
        }
        if !accepted {
            // No step lowers the residual: the rounding floor of the
            // finite-difference Hessian. The iterate is kept when it is
            // stationary to 1e-7 of the gradient's size there.
            x.copy_from_slice(&x0);
            lam.copy_from_slice(&l0);
            return stationary < 1e-7 * (1.0 + grad_size) && violation_now < 1e-10;
        }
    }
    false
}

/// Test support: the analytic gradient of the energy (plus the penalty at
/// `penalty_weight`, if given) and every constraint row of `problem` at `x`
/// agree with central differences of step `h` to 1e-5 relative.
#[cfg(test)]
pub(crate) fn assert_derivatives_match_differences(
    problem: &impl Problem,
    x: &[f64],
    h: f64,
    penalty_weight: Option<f64>,
) {
    let n = problem.vars();
    let f = |x: &[f64], g: &mut [f64]| {
        problem.energy(x, g) + penalty_weight.map_or(0.0, |w| problem.penalty(x, w, g))
    };
    let mut g = vec![0.0; n];
    f(x, &mut g);
    let m = problem.kinds().len();
    let (mut v, mut j) = (vec![0.0; m], vec![vec![0.0; n]; m]);
    problem.constraints(x, &mut v, &mut j);
    let (mut va, mut vb) = (vec![0.0; m], vec![0.0; m]);
    let (mut scratch, mut t) = (vec![vec![0.0; n]; m], vec![0.0; n]);
    for i in 0..n {
        let (mut a, mut b) = (x.to_vec(), x.to_vec());
        a[i] += h;
        b[i] -= h;
        let num = (f(&a, &mut t) - f(&b, &mut t)) / (2.0 * h);
        assert!(
            (num - g[i]).abs() < 1e-5 * (1.0 + num.abs()),
            "energy var {i}: {num} vs {}",
            g[i]
        );
        problem.constraints(&a, &mut va, &mut scratch);
        problem.constraints(&b, &mut vb, &mut scratch);
        for r in 0..m {
            let num = (va[r] - vb[r]) / (2.0 * h);
            assert!(
                (num - j[r][i]).abs() < 1e-5 * (1.0 + num.abs()),
                "constraint {r} var {i}: {num} vs {}",
                j[r][i]
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// min x² + 2y² s.t. x + y = 1, x ≥ 0.8: (0.8, 0.2), λ = −1.6+… .
    struct Toy;
    impl Problem for Toy {
        fn vars(&self) -> usize {
            2
        }
        fn energy(&self, x: &[f64], g: &mut [f64]) -> f64 {
            g[0] += 2.0 * x[0];
            g[1] += 4.0 * x[1];
            x[0] * x[0] + 2.0 * x[1] * x[1]
        }
        fn kinds(&self) -> &[Kind] {
            &[Kind::Equality, Kind::Inequality]
        }
        fn constraints(&self, x: &[f64], v: &mut [f64], j: &mut [Vec<f64>]) {
            v[0] = x[0] + x[1] - 1.0;
            j[0] = vec![1.0, 1.0];
            v[1] = 0.8 - x[0];
            j[1] = vec![-1.0, 0.0];
        }
    }

    #[test]
    fn multiplier_method_finds_the_constrained_minimum() {
        let sol = solve(&Toy, vec![0.0, 0.0], &Settings::default()).unwrap();
        assert!(sol.converged);
        assert!(
            (sol.x[0] - 0.8).abs() < 1e-6 && (sol.x[1] - 0.2).abs() < 1e-6,
            "{:?}",
            sol.x
        );
        // Unconstrained-by-the-bound optimum would be (2/3, 1/3): the
        // inequality is active, its multiplier positive.
        assert!(sol.multipliers[1] > 0.0);
    }

    #[test]
    fn polish_takes_a_loose_solution_to_the_kkt_point() {
        // A loose multiplier-method solve, then Newton on the KKT system with
        // the bound x ≥ 0.8 active: exact to rounding.
        let loose = Settings {
            tolerance: 1e-3,
            ..Settings::default()
        };
        let sol = solve(&Toy, vec![0.0, 0.0], &loose).unwrap();
        assert!((sol.x[0] - 0.8).abs() > 1e-9 || (sol.x[1] - 0.2).abs() > 1e-9);
        let p = polish(&Toy, &sol, 1e-9).expect("a KKT point");
        assert!(
            (p.x[0] - 0.8).abs() < 1e-10 && (p.x[1] - 0.2).abs() < 1e-10,
            "{:?}",
            p.x
        );
        // ∇U + λ∇c = 0: λ_eq = −0.8, μ = 0.8·2 − 0.8 = 0.8 on x ≥ 0.8.
        assert!((p.multipliers[0] + 0.8).abs() < 1e-8, "{:?}", p.multipliers);
        assert!((p.multipliers[1] - 0.8).abs() < 1e-8, "{:?}", p.multipliers);
    }
}
