//! Tensor-product spline surfaces `x(s, t) = Σ τ_ij B₃(α(s − s_i))
//! B₃(β(t − t_j))` (Eq. 5), periodic in t (a contour signature over time:
//! the deforming object, the red-blood-cell surface of Eq. 38), or in both
//! variables (the paper's closed surface), with the area and smoothness
//! functionals of Eq. 40–41 and the polar read-out of Eq. 39.
use crate::error::{ContourError, Result};
use crate::model::basis::Axis;
use crate::model::curve::{checked_weights, quadratic_form, SplineCurve};
use crate::model::fit::{FitProblem, Fitter, Solver};
use crate::model::gramian::gramian;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// A spline surface on `s_axis × t_axis`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplineSurface {
    /// First variable (time, for a deforming contour).
    pub s_axis: Axis,
    /// Second variable (the contour's angle parameter).
    pub t_axis: Axis,
    /// `vec τ`: `τ_{i,j}` at `i + M₁ j` (Eq. 13).
    pub coef: Vec<f64>,
}

impl SplineSurface {
    /// A surface from its coefficients (checked against the axes).
    pub fn new(s_axis: Axis, t_axis: Axis, coef: Vec<f64>) -> Result<Self> {
        s_axis.validate()?;
        t_axis.validate()?;
        let n = s_axis.coefficients() * t_axis.coefficients();
        if coef.len() != n {
            return Err(ContourError::LengthMismatch {
                what: "coefficients",
                got: coef.len(),
                expected: n,
            });
        }
        Ok(Self {
            s_axis,
            t_axis,
            coef,
        })
    }

    /// `∂^{i+j} x / ∂sⁱ ∂tʲ` at (s, t).
    pub fn partial(&self, s: f64, t: f64, i: usize, j: usize) -> f64 {
        let m1 = self.s_axis.coefficients();
        let (f1, b1) = self.s_axis.basis(s, i);
        let (f2, b2) = self.t_axis.basis(t, j);
        let mut v = 0.0;
        for (l, v2) in b2.iter().enumerate() {
            for (k, v1) in b1.iter().enumerate() {
                v += v1 * v2 * self.coef[f1 + k + m1 * (f2 + l)];
            }
        }
        v
    }

    /// x(s, t).
    pub fn value(&self, s: f64, t: f64) -> f64 {
        self.partial(s, t, 0, 0)
    }

    /// The curve `t ↦ x(s, t)` at fixed s (its coefficients are
    /// `Σ_i τ_ij B₃(α(s − s_i))`, i.e. `τᵀ b₁(s)`).
    pub fn curve_at(&self, s: f64) -> SplineCurve {
        let m1 = self.s_axis.coefficients();
        let (f1, b1) = self.s_axis.basis(s, 0);
        let coef = (0..self.t_axis.coefficients())
            .map(|j| {
                b1.iter()
                    .enumerate()
                    .map(|(k, v)| v * self.coef[f1 + k + m1 * j])
                    .sum()
            })
            .collect();
        SplineCurve {
            axis: self.t_axis,
            coef,
        }
    }

    /// Area of the contour at s read as a signature over one turn of t,
    /// Eq. 40: `S(s) = (π/L_t) ∫ x(s,t)² dt = (π/L_t) τ̂ᵀ(Q₂⁽⁰⁰⁾ ⊗ B_c(s))τ̂`.
    pub fn area(&self, s: f64) -> f64 {
        self.curve_at(s).signature_area()
    }

    /// Smoothness of the contour at s, Eq. 41:
    /// `C(s) = ∫ (∂²x/∂t²)² dt = τ̂ᵀ(Q₂⁽²²⁾ ⊗ B_c(s))τ̂`.
    pub fn smoothness(&self, s: f64) -> f64 {
        let c = self.curve_at(s);
        quadratic_form(&gramian(&self.t_axis, 2, 2), &c.coef)
    }

    /// The polar read-out of Eq. 39 at s: `(x cos θ(t), x sin θ(t))` for
    /// `n` equally spaced t over one turn, θ(t) = 2π(t − t₀)/L_t.
    pub fn polar_contour(&self, s: f64, n: usize) -> Vec<(f64, f64)> {
        let c = self.curve_at(s);
        let l = self.t_axis.length();
        (0..n)
            .map(|k| {
                let t = self.t_axis.start + l * k as f64 / n as f64;
                let th = std::f64::consts::TAU * (t - self.t_axis.start) / l;
                let r = c.value(t);
                (r * th.cos(), r * th.sin())
            })
            .collect()
    }
}

/// The smoothing problem of a surface observed at `sites` (s, t), with
/// weights (default 1/N, Eq. 29); checked like
/// [`curve_problem`](crate::model::curve::curve_problem).
pub fn surface_problem(
    s_axis: &Axis,
    t_axis: &Axis,
    sites: &[(f64, f64)],
    weights: Option<&[f64]>,
) -> Result<Arc<FitProblem>> {
    s_axis.validate()?;
    t_axis.validate()?;
    let w = checked_weights(weights, sites.len())?;
    for (k, &(s, t)) in sites.iter().enumerate() {
        for (name, v, axis) in [("s", s, s_axis), ("t", t, t_axis)] {
            if !v.is_finite() {
                return Err(ContourError::NonFinite {
                    location: format!("sample {k}"),
                    what: name,
                    value: v,
                });
            }
            if !axis.contains(v) {
                return Err(ContourError::OutsideDomain {
                    location: format!("sample {k}"),
                    axis: name,
                    value: v,
                    start: axis.start,
                    end: axis.end(),
                });
            }
        }
    }
    Ok(Arc::new(FitProblem::surface(s_axis, t_axis, sites, &w)))
}

/// Fits a surface to `(sites, d)` for a fixed λ.
pub fn fit_surface(
    s_axis: &Axis,
    t_axis: &Axis,
    sites: &[(f64, f64)],
    d: &[f64],
    weights: Option<&[f64]>,
    lambda: f64,
    solver: Solver,
) -> Result<(SplineSurface, Fitter)> {
    let fitter = surface_problem(s_axis, t_axis, sites, weights)?.fitter(lambda, solver)?;
    let tau = fitter.solve(d)?;
    Ok((SplineSurface::new(*s_axis, *t_axis, tau)?, fitter))
}
