//! The optimal smoothing spline for given sites, weights and λ: the
//! minimiser of Eq. 8, `J(τ) = λ τᵀQτ + (Bᵀτ − d)ᵀ W (Bᵀτ − d)` (Eq. 15),
//! subject to the periodicity ties `Ḡ τ = 0` (Eq. 21–24).
//!
//! Two solvers give the same τ:
//! * [`Solver::Kkt`] — the paper's route: the saddle-point system of Eq. 27,
//!   `[λQ + BWBᵀ, Ḡᵀ; Ḡ, 0] [τ; μ/2] = [BWd; 0]`, assembled densely and
//!   solved by SVD for its minimum-norm solution, as the paper prescribes
//!   when the matrix is singular (always so for a closed surface, whose
//!   corner ties repeat each other). O((n + 3M)³); for small problems and
//!   as the reference.
//! * [`Solver::Reduced`] — the ties say `τ_{−3+l} = τ_{m−3+l}`, so τ = P z
//!   with z the `m` distinct coefficients of each periodic axis. Then
//!   `(Pᵀ(λQ + BWBᵀ)P) z = Pᵀ B W d`, symmetric positive definite as soon
//!   as the data pin down Q's null space (a + b·s on an open axis),
//!   banded, and solved by the shared skyline Cholesky with the periodic
//!   axis innermost (bandwidth ≈ 4 × its coefficients). If that matrix is
//!   not positive definite the fit falls back to the KKT minimum-norm
//!   solution when it is small enough, or says why it cannot.
//!
//! The fitted values are linear in d: `x̂ = H d`. `tr H` (the effective
//! degrees of freedom) comes from the entries of `A⁻¹` inside the band
//! (selected inversion), for generalised cross-validation.
use crate::error::{check_positive, ContourError, Result};
use crate::model::basis::{Axis, AxisKey};
use crate::model::gramian::{surface_entry, AxisGramians};
use nalgebra::{DMatrix, DVector};
use plant_common::linalg::SkylineCholesky;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Which linear solver computes τ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum Solver {
    /// Periodic ties eliminated, banded Cholesky (fast; default).
    #[default]
    Reduced,
    /// The dense KKT system of Eq. 27, minimum-norm solution by SVD.
    Kkt,
}

impl Solver {
    /// Lower-case name for files and command lines.
    pub fn name(self) -> &'static str {
        match self {
            Solver::Reduced => "reduced",
            Solver::Kkt => "kkt",
        }
    }
}

/// Largest KKT system (equations) the dense solver takes: its SVD holds
/// three dense matrices of this size (≈ 55 MB at 1,500).
pub const KKT_MAX_EQUATIONS: usize = 1500;

/// The quadratic problem of Eq. 15 with its ties, independent of d.
#[derive(Debug, Clone)]
pub struct FitProblem {
    /// Stored coefficients (M or M₁M₂).
    stored: usize,
    /// Independent coefficients after the ties.
    free: usize,
    /// Free index of each stored coefficient.
    free_of: Vec<usize>,
    /// Ties τ_a = τ_b (stored indices), the rows of Ḡ.
    ties: Vec<(usize, usize)>,
    /// Q's entries over stored indices (both triangles).
    penalty: Vec<(usize, usize, f64)>,
    /// Nonzero basis values per sample.
    stride: usize,
    /// Stored index of each nonzero, `stride` per sample.
    index: Vec<usize>,
    /// Basis value of each nonzero.
    value: Vec<f64>,
    /// Weight w of each sample.
    weight: Vec<f64>,
}

/// A Gramian's entries (row, column, value) over stored indices.
type Entries = Vec<(usize, usize, f64)>;

thread_local! {
    /// The last axis a curve problem was built on, with its Q⁽²²⁾ entries:
    /// the frames of a contour fit (and their halves) share one axis.
    static CURVE_PENALTY: std::cell::RefCell<Option<(AxisKey, Entries)>> =
        const { std::cell::RefCell::new(None) };
}

/// Q⁽²²⁾'s entries on `axis`, from [`CURVE_PENALTY`] when the axis is the
/// last one's (the same entries to the bit: the Gramian is a function of
/// the axis alone).
fn curve_penalty(axis: &Axis) -> Entries {
    let key = axis.key();
    CURVE_PENALTY.with(|cache| {
        let mut cache = cache.borrow_mut();
        match &*cache {
            Some((k, entries)) if *k == key => entries.clone(),
            _ => {
                let entries: Vec<_> = crate::model::gramian::gramian(axis, 2, 2)
                    .entries()
                    .collect();
                *cache = Some((key, entries.clone()));
                entries
            }
        }
    })
}

impl FitProblem {
    /// A curve on `axis` observed at `sites` with `weights` (Eq. 8 in one
    /// variable: Q = Q⁽²²⁾).
    pub(crate) fn curve(axis: &Axis, sites: &[f64], weights: &[f64]) -> Self {
        let stored = axis.coefficients();
        let free_of: Vec<usize> = (0..stored).map(|i| axis.free_index(i)).collect();
        let penalty = curve_penalty(axis);
        let mut index = Vec::with_capacity(4 * sites.len());
        let mut value = Vec::with_capacity(4 * sites.len());
        for &s in sites {
            let (first, b) = axis.basis(s, 0);
            for (k, v) in b.iter().enumerate() {
                index.push(first + k);
                value.push(*v);
            }
        }
        Self {
            stored,
            free: axis.free_coefficients(),
            free_of,
            ties: axis.ties(),
            penalty,
            stride: 4,
            index,
            value,
            weight: weights.to_vec(),
        }
    }

    /// Stored coefficients (M, or M₁M₂ for a surface).
    pub(crate) fn coefficients(&self) -> usize {
        self.stored
    }

    /// The same problem at samples `keep` of this one (in that order),
    /// each weighted 1/`keep.len()`: what [`FitProblem::curve`] builds at
    /// those samples' sites with the default weights, without evaluating
    /// their basis again (a sample's basis values are a function of its
    /// site alone). `None` when an index is out of range or `keep` is
    /// empty.
    pub(crate) fn samples_at(&self, keep: &[usize]) -> Option<Self> {
        if keep.is_empty() || keep.iter().any(|&k| k >= self.samples()) {
            return None;
        }
        let w = self.stride;
        let mut index = Vec::with_capacity(w * keep.len());
        let mut value = Vec::with_capacity(w * keep.len());
        for &k in keep {
            index.extend_from_slice(&self.index[k * w..(k + 1) * w]);
            value.extend_from_slice(&self.value[k * w..(k + 1) * w]);
        }
        Some(Self {
            stored: self.stored,
            free: self.free,
            free_of: self.free_of.clone(),
            ties: self.ties.clone(),
            penalty: self.penalty.clone(),
            stride: w,
            index,
            value,
            weight: vec![1.0 / keep.len() as f64; keep.len()],
        })
    }

    /// A surface on `s_axis × t_axis` observed at `sites` (s, t) with
    /// `weights` (Eq. 14–18; stored index `i + M₁ j`, vec τ).
    pub(crate) fn surface(
        s_axis: &Axis,
        t_axis: &Axis,
        sites: &[(f64, f64)],
        weights: &[f64],
    ) -> Self {
        let (m1, m2) = (s_axis.coefficients(), t_axis.coefficients());
        let stored = m1 * m2;
        let (n1, n2) = (s_axis.free_coefficients(), t_axis.free_coefficients());
        // The periodic axis (or else the shorter one) varies fastest in the
        // free numbering, which keeps the band narrow.
        let t_inner = match (s_axis.periodic, t_axis.periodic) {
            (false, true) => true,
            (true, false) => false,
            _ => n2 <= n1,
        };
        let free_of: Vec<usize> = (0..stored)
            .map(|k| {
                let (f1, f2) = (s_axis.free_index(k % m1), t_axis.free_index(k / m1));
                if t_inner {
                    f2 + n2 * f1
                } else {
                    f1 + n1 * f2
                }
            })
            .collect();
        let mut ties = Vec::new();
        // Ḡ₁ (Eq. 21–22): periodic in t, whole columns of τ tied.
        for (a, b) in t_axis.ties() {
            for i in 0..m1 {
                ties.push((i + m1 * a, i + m1 * b));
            }
        }
        // Ḡ₂ = G₂E (Eq. 23): periodic in s, whole rows of τ tied.
        for (a, b) in s_axis.ties() {
            for j in 0..m2 {
                ties.push((a + m1 * j, b + m1 * j));
            }
        }
        let (g1, g2) = (AxisGramians::of(s_axis), AxisGramians::of(t_axis));
        let mut penalty = Vec::with_capacity(49 * stored);
        for p2 in 0..m2 {
            for q2 in p2.saturating_sub(3)..(p2 + 4).min(m2) {
                for p1 in 0..m1 {
                    for q1 in p1.saturating_sub(3)..(p1 + 4).min(m1) {
                        let v = surface_entry(&g1, &g2, (p1, p2), (q1, q2));
                        if v != 0.0 {
                            penalty.push((p1 + m1 * p2, q1 + m1 * q2, v));
                        }
                    }
                }
            }
        }
        let mut index = Vec::with_capacity(16 * sites.len());
        let mut value = Vec::with_capacity(16 * sites.len());
        for &(s, t) in sites {
            let (f1, b1) = s_axis.basis(s, 0);
            let (f2, b2) = t_axis.basis(t, 0);
            for (l, v2) in b2.iter().enumerate() {
                for (k, v1) in b1.iter().enumerate() {
                    index.push(f1 + k + m1 * (f2 + l));
                    value.push(v1 * v2);
                }
            }
        }
        Self {
            stored,
            free: n1 * n2,
            free_of,
            ties,
            penalty,
            stride: 16,
            index,
            value,
            weight: weights.to_vec(),
        }
    }

    /// Number of samples.
    pub fn samples(&self) -> usize {
        self.weight.len()
    }

    /// Factors the problem for `lambda` with `solver`.
    pub fn fitter(self: &Arc<Self>, lambda: f64, solver: Solver) -> Result<Fitter> {
        Fitter::new(Arc::clone(self), lambda, solver)
    }

    /// A natural unit for λ: `tr(BWBᵀ) / tr(Q)` over the free coefficients,
    /// the λ at which penalty and data weigh about the same. GCV scans
    /// around it, which makes the scan independent of the knot spacing and
    /// of the weights' scale.
    pub fn lambda_scale(&self) -> f64 {
        let data: f64 = (0..self.samples())
            .map(|k| {
                self.weight[k]
                    * self.value[k * self.stride..(k + 1) * self.stride]
                        .iter()
                        .map(|v| v * v)
                        .sum::<f64>()
            })
            .sum();
        let pen: f64 = self
            .penalty
            .iter()
            .filter(|e| e.0 == e.1)
            .map(|e| e.2)
            .sum();
        if data > 0.0 && pen > 0.0 {
            data / pen
        } else {
            1.0
        }
    }

    /// `B W d` over stored indices.
    fn bwd(&self, d: &[f64]) -> Vec<f64> {
        let mut r = vec![0.0; self.stored];
        for (k, (&dk, &wk)) in d.iter().zip(&self.weight).enumerate() {
            for e in k * self.stride..(k + 1) * self.stride {
                r[self.index[e]] += wk * dk * self.value[e];
            }
        }
        r
    }

    /// Fitted values `Bᵀ τ` at the samples.
    pub(crate) fn fitted(&self, tau: &[f64]) -> Vec<f64> {
        (0..self.samples())
            .map(|k| {
                (k * self.stride..(k + 1) * self.stride)
                    .map(|e| self.value[e] * tau[self.index[e]])
                    .sum()
            })
            .collect()
    }

    /// The reduced matrix `Pᵀ(λQ + BWBᵀ)P` in skyline storage.
    fn reduced_matrix(&self, lambda: f64) -> SkylineCholesky {
        let mut first: Vec<usize> = (0..self.free).collect();
        for &(p, q, _) in &self.penalty {
            let (a, b) = (self.free_of[p], self.free_of[q]);
            let (hi, lo) = if a > b { (a, b) } else { (b, a) };
            first[hi] = first[hi].min(lo);
        }
        let free_at = self.free_at();
        // A sample couples every pair of its coefficients: each one's
        // profile reaches down to the sample's lowest (first[a] ≤ a).
        for row in free_at.chunks(self.stride) {
            let lo = row.iter().copied().min().unwrap_or(0);
            for &a in row {
                first[a] = first[a].min(lo);
            }
        }
        let mut m = SkylineCholesky::with_profile(first);
        for &(p, q, v) in &self.penalty {
            let (a, b) = (self.free_of[p], self.free_of[q]);
            if a >= b {
                m.add(a, b, lambda * v);
            }
        }
        for k in 0..self.samples() {
            let w = self.weight[k];
            let r = k * self.stride..(k + 1) * self.stride;
            for e in r.clone() {
                for f in r.clone() {
                    let (a, b) = (free_at[e], free_at[f]);
                    if a >= b {
                        m.add(a, b, w * self.value[e] * self.value[f]);
                    }
                }
            }
        }
        m
    }

    /// The free index of each nonzero (`free_of[index[e]]`), looked up
    /// once for the passes over the samples.
    fn free_at(&self) -> Vec<usize> {
        self.index.iter().map(|&i| self.free_of[i]).collect()
    }

    /// Dense `λQ + BWBᵀ` over stored indices.
    fn dense_matrix(&self, lambda: f64) -> DMatrix<f64> {
        let mut a = DMatrix::zeros(self.stored, self.stored);
        for &(p, q, v) in &self.penalty {
            a[(p, q)] += lambda * v;
        }
        for k in 0..self.samples() {
            let w = self.weight[k];
            let r = k * self.stride..(k + 1) * self.stride;
            for e in r.clone() {
                for f in r.clone() {
                    a[(self.index[e], self.index[f])] += w * self.value[e] * self.value[f];
                }
            }
        }
        a
    }

    /// The KKT matrix of Eq. 27.
    pub(crate) fn kkt_matrix(&self, lambda: f64) -> DMatrix<f64> {
        let n = self.stored;
        let c = self.ties.len();
        let mut k = DMatrix::zeros(n + c, n + c);
        k.view_mut((0, 0), (n, n))
            .copy_from(&self.dense_matrix(lambda));
        for (r, &(a, b)) in self.ties.iter().enumerate() {
            k[(n + r, a)] = 1.0;
            k[(n + r, b)] = -1.0;
            k[(a, n + r)] = 1.0;
            k[(b, n + r)] = -1.0;
        }
        k
    }
}

/// How a [`Fitter`] solves.
#[derive(Debug, Clone)]
enum Method {
    Reduced(SkylineCholesky),
    /// The τ-block of the KKT matrix's pseudo-inverse.
    Kkt(DMatrix<f64>),
}

/// A smoothing problem with fixed sites, weights and λ, factored once:
/// each data vector is then one back-substitution (movies, Monte Carlo,
/// x and y of a parametric curve).
#[derive(Debug, Clone)]
pub struct Fitter {
    problem: Arc<FitProblem>,
    lambda: f64,
    method: Method,
}

impl Fitter {
    /// Factors the problem with `solver` (the reduced one falls back to the
    /// KKT system when its matrix is not positive definite and the KKT
    /// system is small enough).
    pub(crate) fn new(problem: Arc<FitProblem>, lambda: f64, solver: Solver) -> Result<Self> {
        check_positive("lambda", lambda)?;
        if problem.samples() == 0 {
            return Err(ContourError::TooFewPoints {
                location: "fit".into(),
                got: 0,
                needed: 1,
                why: "a smoothing spline needs data",
            });
        }
        let method = match solver {
            Solver::Reduced => {
                let mut m = problem.reduced_matrix(lambda);
                match m.factor() {
                    Ok(()) => Method::Reduced(m),
                    Err(e) => {
                        let size = problem.stored + problem.ties.len();
                        if size > KKT_MAX_EQUATIONS {
                            return Err(ContourError::Unsolvable(format!(
                                "the reduced normal equations are singular ({e}): the data do not determine the spline (too few distinct sites for the knots, or all weights zero); add points, use fewer knot intervals or a larger λ"
                            )));
                        }
                        Method::Kkt(kkt_pseudo_inverse(&problem, lambda)?)
                    }
                }
            }
            Solver::Kkt => Method::Kkt(kkt_pseudo_inverse(&problem, lambda)?),
        };
        Ok(Self {
            problem,
            lambda,
            method,
        })
    }

    /// The solver that was used in the end.
    pub fn solver(&self) -> Solver {
        match self.method {
            Method::Reduced(_) => Solver::Reduced,
            Method::Kkt(_) => Solver::Kkt,
        }
    }

    /// λ.
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// Number of samples.
    pub fn samples(&self) -> usize {
        self.problem.samples()
    }

    /// Stored coefficients τ (vec τ for a surface) for data `d`.
    pub fn solve(&self, d: &[f64]) -> Result<Vec<f64>> {
        if d.len() != self.problem.samples() {
            return Err(ContourError::LengthMismatch {
                what: "data",
                got: d.len(),
                expected: self.problem.samples(),
            });
        }
        let bwd = self.problem.bwd(d);
        let tau = match &self.method {
            Method::Reduced(chol) => {
                let mut z = vec![0.0; self.problem.free];
                for (i, v) in bwd.iter().enumerate() {
                    z[self.problem.free_of[i]] += v;
                }
                chol.solve_in_place(&mut z);
                self.problem.free_of.iter().map(|&f| z[f]).collect()
            }
            Method::Kkt(pinv) => (pinv * DVector::from_vec(bwd)).as_slice().to_vec(),
        };
        if let Some(i) = tau.iter().position(|v| !v.is_finite()) {
            return Err(ContourError::Unsolvable(format!(
                "coefficient {i} came out non-finite"
            )));
        }
        Ok(tau)
    }

    /// Fitted values at the samples for coefficients `tau`.
    pub fn fitted(&self, tau: &[f64]) -> Vec<f64> {
        self.problem.fitted(tau)
    }

    /// `tr H`, the effective number of parameters of the smoother
    /// (`x̂ = H d`).
    pub fn trace_hat(&self) -> f64 {
        let p = &self.problem;
        match &self.method {
            Method::Reduced(chol) => {
                let z = chol.inverse_in_profile();
                let free_at = p.free_at();
                let mut tr = 0.0;
                for k in 0..p.samples() {
                    let r = k * p.stride..(k + 1) * p.stride;
                    let mut s = 0.0;
                    for e in r.clone() {
                        for f in r.clone() {
                            s += p.value[e] * p.value[f] * z.get(free_at[e], free_at[f]);
                        }
                    }
                    tr += p.weight[k] * s;
                }
                tr
            }
            Method::Kkt(pinv) => {
                let mut tr = 0.0;
                for k in 0..p.samples() {
                    let r = k * p.stride..(k + 1) * p.stride;
                    let mut s = 0.0;
                    for e in r.clone() {
                        for f in r.clone() {
                            s += p.value[e] * p.value[f] * pinv[(p.index[e], p.index[f])];
                        }
                    }
                    tr += p.weight[k] * s;
                }
                tr
            }
        }
    }

    /// Weighted residual sum `Σ w (x̂ − d)²` of `tau` against `d`.
    pub fn weighted_rss(&self, tau: &[f64], d: &[f64]) -> f64 {
        self.fitted(tau)
            .iter()
            .zip(d)
            .zip(&self.problem.weight)
            .map(|((x, d), w)| w * (x - d) * (x - d))
            .sum()
    }

    /// The problem this fitter solves.
    pub fn problem(&self) -> &Arc<FitProblem> {
        &self.problem
    }

    /// The sample weights.
    pub fn weights(&self) -> &[f64] {
        &self.problem.weight
    }

    /// The ties τ_a = τ_b (rows of Ḡ), stored indices.
    pub fn ties(&self) -> &[(usize, usize)] {
        &self.problem.ties
    }
}

/// The τ-block of the pseudo-inverse of the Eq. 27 matrix (its
/// minimum-norm solution operator).
fn kkt_pseudo_inverse(problem: &FitProblem, lambda: f64) -> Result<DMatrix<f64>> {
    let size = problem.stored + problem.ties.len();
    if size > KKT_MAX_EQUATIONS {
        return Err(ContourError::TooLargeForKkt {
            size,
            limit: KKT_MAX_EQUATIONS,
        });
    }
    let k = problem.kkt_matrix(lambda);
    // An SVD of a matrix with an infinite or NaN entry need not return.
    if k.iter().any(|v| !v.is_finite()) {
        return Err(ContourError::Unsolvable(format!(
            "the KKT matrix of Eq. 27 overflows at λ = {}",
            plant_common::short_number(lambda)
        )));
    }
    let svd = k.svd(true, true);
    let smax = svd.singular_values.max();
    if !(smax.is_finite() && smax > 0.0) {
        return Err(ContourError::Unsolvable(
            "the KKT matrix of Eq. 27 is zero or not finite".into(),
        ));
    }
    // Relative cut-off as in LAPACK/numpy least squares: singular values
    // below n·ε·σ_max are treated as zero (minimum-norm solution).
    let eps = size as f64 * f64::EPSILON * smax;
    let pinv = svd
        .pseudo_inverse(eps)
        .map_err(|e| ContourError::Unsolvable(e.to_string()))?;
    let n = problem.stored;
    Ok(pinv.view((0, 0), (n, n)).into_owned())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cached penalty is the Gramian of the axis asked for, however
    /// axes alternate on one thread (knots, start, length, periodic).
    #[test]
    fn the_cached_penalty_follows_the_axis() {
        let axes = [
            Axis::over(0.0, 16.0, 16, true).unwrap(),
            Axis::over(0.0, 16.0, 16, false).unwrap(),
            Axis::over(0.0, 8.0, 8, true).unwrap(),
            Axis::over(1.0, 17.0, 16, true).unwrap(),
            Axis::over(0.0, 32.0, 16, true).unwrap(),
        ];
        for round in 0..3 {
            for (k, axis) in axes.iter().enumerate() {
                let want: Vec<_> = crate::model::gramian::gramian(axis, 2, 2)
                    .entries()
                    .collect();
                let got = curve_penalty(axis);
                assert_eq!(
                    format!("{got:?}"),
                    format!("{want:?}"),
                    "round {round}, axis {k}"
                );
            }
        }
    }
}
