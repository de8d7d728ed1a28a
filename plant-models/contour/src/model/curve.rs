//! Spline curves: a scalar spline `x(s)` on one axis (a contour's signature
//! r(θ) when the axis is periodic, a centroid coordinate over time when it
//! is not), and a closed parametric curve `(x(t), y(t))` with its area.
//!
//! Fitting (the one-variable Eq. 8, `λ∫x″² + Σ w (x − d)²`) goes through
//! [`Fitter`](crate::model::fit::Fitter); λ may be chosen by
//! generalised cross-validation ([`crate::identify::gcv`]).
use crate::error::{ContourError, Result};
use crate::model::basis::{local_cubic, Axis};
use crate::model::fit::{FitProblem, Fitter, Solver};
use crate::model::gramian::{gauss4, gramian};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// `x(s) = Σ τ_i B₃(α(s − s_i))` on one axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SplineCurve {
    /// The knot axis.
    pub axis: Axis,
    /// `τ_{−3} … τ_{m−1}` (M values).
    pub coef: Vec<f64>,
}

impl SplineCurve {
    /// A curve from its coefficients (checked against the axis).
    pub fn new(axis: Axis, coef: Vec<f64>) -> Result<Self> {
        axis.validate()?;
        if coef.len() != axis.coefficients() {
            return Err(ContourError::LengthMismatch {
                what: "coefficients",
                got: coef.len(),
                expected: axis.coefficients(),
            });
        }
        Ok(Self { axis, coef })
    }

    /// The `order`-th derivative of x at s (0 = the value).
    pub fn derivative(&self, s: f64, order: usize) -> f64 {
        let (first, b) = self.axis.basis(s, order);
        b.iter()
            .zip(&self.coef[first..first + 4])
            .map(|(b, c)| b * c)
            .sum()
    }

    /// x(s).
    pub fn value(&self, s: f64) -> f64 {
        self.derivative(s, 0)
    }

    /// The value and the first `D` derivatives at s, `[x, x', …]`, with the
    /// interval located once: each entry is bit-identical to
    /// [`SplineCurve::derivative`] of its order (the same operations).
    pub fn derivatives<const D: usize>(&self, s: f64) -> [f64; D] {
        let (first, x) = self.axis.locate(s);
        let c = &self.coef[first..first + 4];
        std::array::from_fn(|order| {
            let scale = self.axis.alpha.powi(order as i32);
            local_cubic(x, order)
                .iter()
                .zip(c)
                .map(|(b, c)| (b * scale) * c)
                .sum()
        })
    }

    /// `∫ x(s)² ds` over the domain (`τᵀ Q⁽⁰⁰⁾ τ`).
    pub fn integral_of_square(&self) -> f64 {
        quadratic_form(&gramian(&self.axis, 0, 0), &self.coef)
    }

    /// `∫ x″(s)² ds` over the domain (`τᵀ Q⁽²²⁾ τ`), the roughness the fit
    /// penalises.
    pub fn roughness(&self) -> f64 {
        quadratic_form(&gramian(&self.axis, 2, 2), &self.coef)
    }

    /// Area enclosed by the curve read as a signature r(θ) with θ running
    /// once round over the periodic domain: `½∫r² dθ = (π/L)∫x² ds`
    /// (Eq. 40 for one frame).
    pub fn signature_area(&self) -> f64 {
        std::f64::consts::PI / self.axis.length() * self.integral_of_square()
    }

    /// The paper's smoothness (Eq. 41) of the curve read as a signature
    /// r(θ), θ = 2π(s − s₀)/L, in the angle's units so that it does not
    /// depend on the knot count: `C = ∫₀^{2π} (d²r/dθ²)² dθ
    /// = (L/2π)³ ∫ x″(s)² ds`, in (length unit)²/rad³. A circle has 0.
    pub fn signature_smoothness(&self) -> f64 {
        let k = self.axis.length() / std::f64::consts::TAU;
        k * k * k * self.roughness()
    }

    /// Length of the contour of the signature r(θ):
    /// `∫ √(r² + r_θ²) dθ` (Gauss quadrature, [`QUADRATURE_SUB`]
    /// sub-intervals per knot interval).
    pub fn signature_perimeter(&self) -> f64 {
        let k = self.axis.length() / std::f64::consts::TAU;
        integrate::<2>(&self.axis, QUADRATURE_SUB, |j, b| {
            let [r, r1] = self.combine(j, b);
            speed(r, k * r1) / k
        })
    }

    /// Bending energy of the contour of the signature r(θ), `∫ κ² dl`, in
    /// 1/(length unit): the curvature of a polar curve is
    /// `(r² + 2r_θ² − r r_θθ)/(r² + r_θ²)^{3/2}` and `dl = √(r² + r_θ²) dθ`.
    /// A circle of radius R has 2π/R.
    pub fn signature_bending_energy(&self) -> f64 {
        let k = self.axis.length() / std::f64::consts::TAU;
        integrate::<3>(&self.axis, QUADRATURE_SUB, |j, b| {
            let [r, r1, r2] = self.combine(j, b);
            let (r1, r2) = (k * r1, k * k * r2);
            let v2 = r * r + r1 * r1;
            let num = r * r + 2.0 * r1 * r1 - r * r2;
            num * num / (v2 * v2 * v2.sqrt()) / k
        })
    }

    /// The value and derivatives in knot interval `j` from the basis
    /// values `b` of a point there (as [`integrate`] gives them): the
    /// operations of [`SplineCurve::derivatives`] at that point.
    fn combine<const D: usize>(&self, j: usize, b: &[[f64; 4]; D]) -> [f64; D] {
        let c = &self.coef[j..j + 4];
        std::array::from_fn(|order| b[order].iter().zip(c).map(|(b, c)| b * c).sum())
    }

    /// Curvature of the contour of the signature r(θ) at s, 1/length.
    pub fn signature_curvature(&self, s: f64) -> f64 {
        self.signature_radius_and_curvature(s).1
    }

    /// r(s) (bit-identical to [`SplineCurve::value`]) and the curvature
    /// of [`SplineCurve::signature_curvature`] at s, the interval located
    /// once for both.
    pub fn signature_radius_and_curvature(&self, s: f64) -> (f64, f64) {
        let k = self.axis.length() / std::f64::consts::TAU;
        let [r, r1, r2] = self.derivatives::<3>(s);
        let (r1, r2) = (k * r1, k * k * r2);
        let v2 = r * r + r1 * r1;
        (r, (r * r + 2.0 * r1 * r1 - r * r2) / (v2 * v2.sqrt()))
    }

    /// `n` values at equally spaced s over the domain (the end excluded on
    /// a periodic axis, included otherwise).
    pub fn sample(&self, n: usize) -> Vec<(f64, f64)> {
        sample_sites(&self.axis, n)
            .into_iter()
            .map(|s| (s, self.value(s)))
            .collect()
    }
}

/// `√(a² + b²)` by the square root (about a fifth of libm's `hypot` in
/// the perimeter's quadrature, issue 34; within an ulp or two of it),
/// falling back to `hypot` where the squares overflow or underflow.
fn speed(a: f64, b: f64) -> f64 {
    let s2 = a * a + b * b;
    if s2.is_normal() {
        s2.sqrt()
    } else {
        a.hypot(b)
    }
}

/// Sub-intervals per knot interval of the quadratures whose integrand is
/// not a polynomial (length, bending energy): 4-point Gauss on each.
pub const QUADRATURE_SUB: usize = 8;

/// `∫ f ds` over the axis's domain by 4-point Gauss on `sub` sub-intervals
/// of each knot interval. `f` gets the knot interval j of a point and the
/// basis values there of the derivative orders 0 … D − 1 (in s, as
/// [`Axis::basis`] gives them; the coefficients `j … j + 3` are the
/// nonzero ones). On a uniform axis a point's basis values are the same in
/// every interval, so they are computed once for the `4·sub` points of
/// one interval, not located and evaluated anew at each of the
/// `4·sub·m` points (issue 34: locating and evaluating were most of a
/// contour frame's perimeter). A point's local coordinate is
/// `(q + x_g)/sub` in sub-interval q; it equals `α(s − s_j)` of its s in
/// real arithmetic (the two may differ in the last bit).
pub(crate) fn integrate<const D: usize>(
    axis: &Axis,
    sub: usize,
    mut f: impl FnMut(usize, &[[f64; 4]; D]) -> f64,
) -> f64 {
    let sub = sub.max(1);
    let h = 1.0 / (axis.alpha * sub as f64);
    let rule: Vec<(f64, [[f64; 4]; D])> = (0..sub)
        .flat_map(|q| {
            gauss4().iter().map(move |&(xg, w)| {
                let x = (q as f64 + xg) / sub as f64;
                let b = std::array::from_fn(|order| {
                    let scale = axis.alpha.powi(order as i32);
                    local_cubic(x, order).map(|b| b * scale)
                });
                (w * h, b)
            })
        })
        .collect();
    let mut total = 0.0;
    for j in 0..axis.intervals {
        for (wh, b) in &rule {
            total += wh * f(j, b);
        }
    }
    total
}

/// [`integrate`] for an integrand of s (a curve whose two coordinates
/// have different axes: not one this crate fits, which share one).
fn integrate_sites(axis: &Axis, sub: usize, f: impl Fn(f64) -> f64) -> f64 {
    let sub = sub.max(1);
    let h = 1.0 / (axis.alpha * sub as f64);
    let mut total = 0.0;
    for j in 0..axis.intervals * sub {
        for &(x, w) in gauss4() {
            total += w * h * f(axis.start + (j as f64 + x) * h);
        }
    }
    total
}

/// `τᵀ Q τ` for a band matrix.
pub(crate) fn quadratic_form(q: &crate::model::gramian::Band7, tau: &[f64]) -> f64 {
    q.entries().map(|(p, r, v)| tau[p] * v * tau[r]).sum()
}

/// `n` equally spaced sites over the axis's domain (end excluded when
/// periodic).
pub fn sample_sites(axis: &Axis, n: usize) -> Vec<f64> {
    let l = axis.length();
    let den = if axis.periodic {
        n.max(1) as f64
    } else {
        (n.max(2) - 1) as f64
    };
    (0..n).map(|k| axis.start + l * k as f64 / den).collect()
}

/// A closed parametric curve `(x(t), y(t))`: two periodic splines on one
/// axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClosedCurve {
    /// x(t).
    pub x: SplineCurve,
    /// y(t).
    pub y: SplineCurve,
}

impl ClosedCurve {
    /// The point at parameter t.
    pub fn point(&self, t: f64) -> (f64, f64) {
        (self.x.value(t), self.y.value(t))
    }

    /// The `order`-th derivative at t.
    pub fn derivative(&self, t: f64, order: usize) -> (f64, f64) {
        (self.x.derivative(t, order), self.y.derivative(t, order))
    }

    /// Signed enclosed area by Green's theorem, `½∮(x y′ − y x′) dt`
    /// (positive counter-clockwise), integrated exactly (4-point Gauss per
    /// knot interval; the integrand is a degree-5 polynomial there).
    pub fn signed_area(&self) -> f64 {
        let axis = &self.x.axis;
        let h = 1.0 / axis.alpha;
        let mut a = 0.0;
        for j in 0..axis.intervals {
            for &(x, w) in gauss4() {
                let t = axis.knot(j as i64) + x * h;
                let (px, py) = self.point(t);
                let (dx, dy) = self.derivative(t, 1);
                a += w * h * (px * dy - py * dx);
            }
        }
        0.5 * a
    }

    /// Length of the curve (Gauss quadrature, 4 points per knot interval
    /// and `sub` sub-intervals; the speed is not a polynomial).
    pub fn length(&self, sub: usize) -> f64 {
        if self.x.axis != self.y.axis {
            return integrate_sites(&self.x.axis, sub, |t| {
                let (dx, dy) = self.derivative(t, 1);
                dx.hypot(dy)
            });
        }
        integrate::<2>(&self.x.axis, sub, |j, b| {
            let [_, dx] = self.x.combine(j, b);
            let [_, dy] = self.y.combine(j, b);
            dx.hypot(dy)
        })
    }

    /// Signed curvature at t, 1/length.
    pub fn curvature(&self, t: f64) -> f64 {
        let (dx, dy) = self.derivative(t, 1);
        let (ddx, ddy) = self.derivative(t, 2);
        let v2 = dx * dx + dy * dy;
        (dx * ddy - dy * ddx) / (v2 * v2.sqrt())
    }

    /// Bending energy `∫ κ² dl = ∫ (x′y″ − y′x″)² / |c′|⁵ dt`, in
    /// 1/(length unit): independent of the parameter and of the knot
    /// count. A circle of radius R has 2π/R.
    pub fn bending_energy(&self) -> f64 {
        let energy = |dx: f64, dy: f64, ddx: f64, ddy: f64| {
            let cross = dx * ddy - dy * ddx;
            let v2 = dx * dx + dy * dy;
            cross * cross / (v2 * v2 * v2.sqrt())
        };
        if self.x.axis != self.y.axis {
            return integrate_sites(&self.x.axis, QUADRATURE_SUB, |t| {
                let (dx, dy) = self.derivative(t, 1);
                let (ddx, ddy) = self.derivative(t, 2);
                energy(dx, dy, ddx, ddy)
            });
        }
        integrate::<3>(&self.x.axis, QUADRATURE_SUB, |j, b| {
            let [_, dx, ddx] = self.x.combine(j, b);
            let [_, dy, ddy] = self.y.combine(j, b);
            energy(dx, dy, ddx, ddy)
        })
    }

    /// `n` points at equally spaced parameters (the closing point not
    /// repeated).
    pub fn sample(&self, n: usize) -> Vec<(f64, f64)> {
        sample_sites(&self.x.axis, n)
            .into_iter()
            .map(|t| self.point(t))
            .collect()
    }
}

/// Fits a scalar spline on `axis` to `(sites, d)` with weights (default
/// 1/N, the paper's Eq. 29) for a fixed λ.
pub fn fit_curve(
    axis: &Axis,
    sites: &[f64],
    d: &[f64],
    weights: Option<&[f64]>,
    lambda: f64,
    solver: Solver,
) -> Result<(SplineCurve, Fitter)> {
    let fitter = curve_problem(axis, sites, weights)?.fitter(lambda, solver)?;
    let tau = fitter.solve(d)?;
    Ok((SplineCurve::new(*axis, tau)?, fitter))
}

/// The smoothing problem of a curve on `axis` observed at `sites`, with
/// weights (default 1/N); checked: finite sites inside the domain, one
/// finite weight ≥ 0 per site.
pub fn curve_problem(
    axis: &Axis,
    sites: &[f64],
    weights: Option<&[f64]>,
) -> Result<Arc<FitProblem>> {
    axis.validate()?;
    let w = checked_weights(weights, sites.len())?;
    for (k, &s) in sites.iter().enumerate() {
        if !s.is_finite() {
            return Err(ContourError::NonFinite {
                location: format!("sample {k}"),
                what: "site",
                value: s,
            });
        }
        if !axis.contains(s) {
            return Err(ContourError::OutsideDomain {
                location: format!("sample {k}"),
                axis: "s",
                value: s,
                start: axis.start,
                end: axis.end(),
            });
        }
    }
    Ok(Arc::new(FitProblem::curve(axis, sites, &w)))
}

/// The weights: given ones checked (finite, ≥ 0, one per sample, not all
/// zero), or 1/N each.
pub(crate) fn checked_weights(weights: Option<&[f64]>, n: usize) -> Result<Vec<f64>> {
    match weights {
        None => Ok(vec![1.0 / n.max(1) as f64; n]),
        Some(w) => {
            if w.len() != n {
                return Err(ContourError::LengthMismatch {
                    what: "weights",
                    got: w.len(),
                    expected: n,
                });
            }
            if let Some(k) = w.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(ContourError::InvalidParameter {
                    name: "weight",
                    value: w[k],
                    reason: "weights must be finite and ≥ 0",
                });
            }
            if w.iter().all(|v| *v == 0.0) {
                return Err(ContourError::InvalidParameter {
                    name: "weight",
                    value: 0.0,
                    reason: "at least one weight must be > 0",
                });
            }
            Ok(w.to_vec())
        }
    }
}
