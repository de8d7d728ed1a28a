//! A static solve checks its own answer before it calls it converged
//! (issue 29): the constraints hold, the point is stationary (the KKT
//! residual), it is a minimum and not a saddle (the Hessian of the
//! Lagrangian on the tangent space of the active constraints has no
//! negative eigenvalue), a wire stays out of itself, and a solve on a
//! second discretisation (twice as fine for a wire and a Ritz belt, half
//! as fine for a segment belt) does not move the answer by more than a
//! stated tolerance. Wires ([`super::linear`]) and belts ([`super::belt`])
//! share these checks; a belt has no self-contact model, so its
//! self-overlap is not reported rather than reported as zero.
//!
//! Every check is a number with the tolerance it is held to, so a report
//! can say how far from converged an answer is; [`Checks::failures`] names
//! the checks that do not hold, and an answer is verified when none fails.
//!
//! The Hessian is taken by central differences of the analytic gradient
//! (step 1e-6 in the problem's units); the stability check therefore
//! accepts eigenvalues down to −1e-6 of the largest one (rounding, and the
//! exact zero modes of an isotropic wire: a planar shape between two
//! clamps on one axis can be turned about that axis at no cost).
use nalgebra::{DMatrix, SymmetricEigen};
use serde::Serialize;

use super::optimize::{Kind, Problem, Solution};

/// Largest KKT residual accepted: ‖∇U + ∇P + Σλ∇c‖∞ and the largest
/// |λ·c| of an inequality, relative to max(1, ‖∇U‖∞).
pub const KKT_TOLERANCE: f64 = 1e-5;
/// Smallest reduced-Hessian eigenvalue accepted, relative to the largest.
pub const STABILITY_TOLERANCE: f64 = 1e-6;
/// Largest change of the energy (relative) or of any point (in units of the
/// length) accepted between the asked discretisation and the second one
/// (twice as fine; half as fine for a segment belt).
pub const DISCRETISATION_TOLERANCE: f64 = 1e-2;
/// Deepest self-overlap accepted, as a share of the wire's diameter 2r.
pub const SELF_CONTACT_TOLERANCE: f64 = 0.05;

/// The evidence of one static solve, each number with its tolerance.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Checks {
    /// Largest constraint violation (problem units: lengths in units of L).
    pub violation: f64,
    pub violation_tolerance: f64,
    /// KKT residual (see [`KKT_TOLERANCE`]).
    pub kkt_residual: f64,
    pub kkt_tolerance: f64,
    /// Smallest eigenvalue of the reduced Hessian over the largest |one|;
    /// negative beyond the tolerance: a saddle, not an equilibrium a wire
    /// rests in.
    pub min_curvature: f64,
    pub stability_tolerance: f64,
    /// Deepest self-overlap as a share of 2r (0 when there is none or the
    /// wire is not kept out of itself); `None` for a belt, which has no
    /// self-contact model (nothing is checked, so nothing is reported).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub self_overlap: Option<f64>,
    pub self_overlap_tolerance: f64,
    /// Relative energy change to the second discretisation (twice as fine;
    /// N/2 segments for a segment belt), and the
    /// largest change of a point there (units of the length). A wire's
    /// points are compared by their distances to either end, blind to the
    /// rigid turns that leave its problem unchanged; a belt, clamped in
    /// position and orientation at both ends, has no such turn, and its
    /// spine and edge points are compared directly. `None` when that solve
    /// was not made (a sequence step) or failed its own checks
    /// (`fine_solve_failed`).
    pub discretisation_energy: Option<f64>,
    pub discretisation_position: Option<f64>,
    pub discretisation_tolerance: f64,
    /// The solve on the second discretisation did not pass its own checks
    /// (the name is the wire's, where it is twice as fine), so the
    /// discretisation error is unknown (a failure).
    pub fine_solve_failed: bool,
}

impl Checks {
    /// The checks of `sol` that can be made on `problem` at its own
    /// discretisation: the constraints (`violation` against `tolerance`),
    /// stationarity and stability. Self-contact is not checked and the
    /// discretisation not yet estimated; the caller adds them.
    pub fn at<P: Problem>(problem: &P, sol: &Solution, violation: f64, tolerance: f64) -> Self {
        let (kkt, curvature) = first_and_second_order(problem, sol, tolerance);
        Checks {
            violation,
            violation_tolerance: tolerance,
            kkt_residual: kkt,
            kkt_tolerance: KKT_TOLERANCE,
            min_curvature: curvature,
            stability_tolerance: STABILITY_TOLERANCE,
            self_overlap: None,
            self_overlap_tolerance: SELF_CONTACT_TOLERANCE,
            discretisation_energy: None,
            discretisation_position: None,
            discretisation_tolerance: DISCRETISATION_TOLERANCE,
            fine_solve_failed: false,
        }
    }

    /// The names of the checks that fail; empty when the answer is verified.
    pub fn failures(&self) -> Vec<&'static str> {
        let mut f = Vec::new();
        // A NaN fails: `within` is true only for ordered, small values.
        let within = |v: f64, tol: f64| v.partial_cmp(&tol).is_some_and(|o| o.is_le());
        if !within(self.violation, self.violation_tolerance) {
            f.push("constraints");
        }
        if !within(self.kkt_residual, self.kkt_tolerance) {
            f.push("stationarity (KKT)");
        }
        if !within(-self.min_curvature, self.stability_tolerance) {
            f.push("stability (saddle)");
        }
        if !self
            .self_overlap
            .is_none_or(|v| within(v, self.self_overlap_tolerance))
        {
            f.push("self-contact");
        }
        let fine = |v: Option<f64>| v.is_none_or(|v| within(v, self.discretisation_tolerance));
        if self.fine_solve_failed
            || !fine(self.discretisation_energy)
            || !fine(self.discretisation_position)
        {
            f.push("discretisation");
        }
        f
    }

    /// Whether every check holds.
    pub fn verified(&self) -> bool {
        self.failures().is_empty()
    }
}

/// A problem with its exterior penalty folded into the energy at a fixed
/// weight (the multiplier method's last ρ): the function the solver
/// minimised, so that its stationarity and curvature can be checked and a
/// Newton polish can be run on it.
pub struct Penalised<'a, P: Problem> {
    pub problem: &'a P,
    pub weight: f64,
}

impl<P: Problem> Problem for Penalised<'_, P> {
    fn vars(&self) -> usize {
        self.problem.vars()
    }
    fn energy(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        self.problem.energy(x, grad) + self.problem.penalty(x, self.weight, grad)
    }
    fn kinds(&self) -> &[Kind] {
        self.problem.kinds()
    }
    fn constraints(&self, x: &[f64], values: &mut [f64], jacobian: &mut [Vec<f64>]) {
        self.problem.constraints(x, values, jacobian)
    }
}

/// Stationarity and curvature of `sol` on `problem` (penalty included by
/// the caller through [`Penalised`]): (KKT residual, min curvature).
pub fn first_and_second_order<P: Problem>(
    problem: &P,
    sol: &Solution,
    tolerance: f64,
) -> (f64, f64) {
    let n = problem.vars();
    let kinds = problem.kinds();
    let m = kinds.len();
    let lam = &sol.multipliers;
    let (mut c, mut jac) = (vec![0.0; m], vec![vec![0.0; n]; m]);
    let lagrangian_gradient = |x: &[f64], c: &mut Vec<f64>, jac: &mut Vec<Vec<f64>>| {
        let mut gu = vec![0.0; n];
        problem.energy(x, &mut gu);
        let mut gl = gu.clone();
        problem.constraints(x, c, jac);
        for r in 0..m {
            for i in 0..n {
                gl[i] += lam[r] * jac[r][i];
            }
        }
        (gl, gu)
    };
    let (gl, gu) = lagrangian_gradient(&sol.x, &mut c, &mut jac);
    let (c0, j0) = (c.clone(), jac.clone());
    let scale = gu.iter().fold(1.0f64, |a, v| a.max(v.abs()));
    let mut residual = gl.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for r in 0..m {
        if kinds[r] == Kind::Inequality {
            // Complementarity and dual feasibility: λ ≥ 0, λ·g = 0.
            residual = residual.max((lam[r] * c0[r]).abs()).max(-lam[r]);
        }
    }
    let residual = residual / scale;
    // Hessian of the Lagrangian by central differences of its gradient.
    let step = 1e-6;
    let mut h = DMatrix::<f64>::zeros(n, n);
    let mut probe = sol.x.clone();
    for i in 0..n {
        probe[i] = sol.x[i] + step;
        let (gp, _) = lagrangian_gradient(&probe, &mut c, &mut jac);
        probe[i] = sol.x[i] - step;
        let (gm, _) = lagrangian_gradient(&probe, &mut c, &mut jac);
        probe[i] = sol.x[i];
        for r in 0..n {
            h[(r, i)] = (gp[r] - gm[r]) / (2.0 * step);
        }
    }
    let h = 0.5 * (&h + h.transpose());
    // Tangent space of the equalities and the active inequalities.
    let active: Vec<usize> = (0..m)
        .filter(|&r| kinds[r] == Kind::Equality || c0[r] > -10.0 * tolerance || lam[r] > 0.0)
        .collect();
    let z = null_space(
        &active.iter().map(|&r| j0[r].clone()).collect::<Vec<_>>(),
        n,
    );
    if z.ncols() == 0 {
        return (residual, 0.0);
    }
    let reduced = z.transpose() * h * &z;
    let eig = SymmetricEigen::new(reduced).eigenvalues;
    let largest = eig.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let smallest = eig.iter().fold(f64::INFINITY, |a, &v| a.min(v));
    let curvature = if largest > 0.0 {
        smallest / largest
    } else {
        0.0
    };
    (residual, curvature)
}

/// An orthonormal basis (columns) of {d : J d = 0}, rows of J given; rank
/// by singular values above 1e-6 of the largest (redundant rows allowed).
fn null_space(rows: &[Vec<f64>], n: usize) -> DMatrix<f64> {
    if rows.is_empty() {
        return DMatrix::identity(n, n);
    }
    // Square J^T J so that the SVD gives all n right singular vectors.
    let j = DMatrix::from_fn(rows.len(), n, |r, i| rows[r][i]);
    let jtj = j.transpose() * &j;
    let eig = SymmetricEigen::new(jtj);
    let largest = eig.eigenvalues.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let keep: Vec<usize> = (0..n)
        .filter(|&k| eig.eigenvalues[k].abs() <= 1e-12 * largest || largest == 0.0)
        .collect();
    DMatrix::from_fn(n, keep.len(), |r, c| eig.eigenvectors[(r, keep[c])])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// min/max of x² − y² on the line x + y = 0: the point (0, 0) is a
    /// stationary point with zero curvature along the line (x² − x² = 0);
    /// on x = 0 it is a maximum in y (a saddle of the constrained problem).
    struct Saddle(bool);
    impl Problem for Saddle {
        fn vars(&self) -> usize {
            2
        }
        fn energy(&self, x: &[f64], g: &mut [f64]) -> f64 {
            g[0] += 2.0 * x[0];
            g[1] -= 2.0 * x[1];
            x[0] * x[0] - x[1] * x[1]
        }
        fn kinds(&self) -> &[Kind] {
            &[Kind::Equality]
        }
        fn constraints(&self, x: &[f64], v: &mut [f64], j: &mut [Vec<f64>]) {
            if self.0 {
                v[0] = x[0];
                j[0] = vec![1.0, 0.0];
            } else {
                v[0] = x[1];
                j[0] = vec![0.0, 1.0];
            }
        }
    }

    fn at_origin() -> Solution {
        Solution {
            x: vec![0.0, 0.0],
            energy: 0.0,
            max_violation: 0.0,
            penalty: 0.0,
            multipliers: vec![0.0],
            rho: 10.0,
            outer_iterations: 1,
            inner_iterations: 1,
            converged: true,
        }
    }

    #[test]
    fn a_constrained_saddle_is_caught_and_a_minimum_passes() {
        // On x = 0 the energy is −y²: a maximum, curvature −1 relative.
        let (r, c) = first_and_second_order(&Saddle(true), &at_origin(), 1e-9);
        assert!(r < 1e-12 && (c + 1.0).abs() < 1e-6, "{r} {c}");
        // On y = 0 it is x²: a minimum.
        let (r, c) = first_and_second_order(&Saddle(false), &at_origin(), 1e-9);
        assert!(r < 1e-12 && (c - 1.0).abs() < 1e-6, "{r} {c}");
        // Away from the origin on y = 0 the point is not stationary.
        let mut s = at_origin();
        s.x = vec![0.5, 0.0];
        let (r, _) = first_and_second_order(&Saddle(false), &s, 1e-9);
        assert!(r > 0.9, "{r}");
    }
}
