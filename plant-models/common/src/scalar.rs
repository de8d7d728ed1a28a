//! Numbers a model can be stepped with: `f64`, and [`Dual`], a value with
//! the derivatives of it with respect to `N` chosen parameters (forward
//! mode). A model written once over [`Scalar`] gives, with `f64`, exactly
//! the operations it was written with — the same bits — and with a dual
//! its sensitivities along the same run, instead of a run per parameter
//! moved a little (finite differences).
//!
//! Branches decide on the value ([`Scalar::val`]): a dual takes the branch
//! its value takes, and its derivatives are those of that branch (the
//! one-sided derivative at a kink). Constants enter with [`Scalar::cst`]
//! (no derivative).

use core::fmt::Debug;
use core::ops::{Add, Div, Mul, Neg, Sub};

/// A number a model can be stepped with.
pub trait Scalar:
    Copy
    + Debug
    + PartialEq
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// Whether the number carries derivatives: code may skip work whose
    /// value would not change only where this is false (a derivative can
    /// move where its value does not).
    const TANGENTS: bool;
    /// A constant.
    fn cst(v: f64) -> Self;
    /// The value.
    fn val(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Cosine.
    fn cos(self) -> Self;
    /// Sine and cosine.
    fn sin_cos(self) -> (Self, Self);
    /// eˣ.
    fn exp(self) -> Self;
    /// eˣ − 1.
    fn exp_m1(self) -> Self;
    /// The value of `self` with its derivatives plus `k` times those of
    /// `other` (the chain rule through a quantity solved for implicitly);
    /// `self` itself for a number without derivatives.
    fn plus_tangents_of(self, k: f64, other: Self) -> Self;
    /// `value` with the derivatives of `self` (a quantity found on the
    /// values, e.g. by a root search, whose derivatives are `self`'s).
    fn with_value(self, value: f64) -> Self;
    /// The smaller by value, as `f64::min` (a dual: the first on a tie).
    #[inline(always)]
    fn min_of(self, o: Self) -> Self {
        if o.val() < self.val() {
            o
        } else {
            self
        }
    }
    /// The larger by value, as `f64::max` (a dual: the first on a tie).
    #[inline(always)]
    fn max_of(self, o: Self) -> Self {
        if o.val() > self.val() {
            o
        } else {
            self
        }
    }
    /// Clamped to [`lo`, `hi`] by value, as `f64::clamp` (`lo ≤ hi`).
    #[inline(always)]
    fn clamp_to(self, lo: Self, hi: Self) -> Self {
        if self.val() < lo.val() {
            lo
        } else if self.val() > hi.val() {
            hi
        } else {
            self
        }
    }
}

impl Scalar for f64 {
    const TANGENTS: bool = false;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn val(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        f64::cos(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        f64::sin_cos(self)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline(always)]
    fn exp_m1(self) -> Self {
        f64::exp_m1(self)
    }
    #[inline(always)]
    fn plus_tangents_of(self, _k: f64, _other: Self) -> Self {
        self
    }
    #[inline(always)]
    fn with_value(self, value: f64) -> Self {
        value
    }
    #[inline(always)]
    fn min_of(self, o: Self) -> Self {
        f64::min(self, o)
    }
    #[inline(always)]
    fn max_of(self, o: Self) -> Self {
        f64::max(self, o)
    }
    #[inline(always)]
    fn clamp_to(self, lo: Self, hi: Self) -> Self {
        f64::clamp(self, lo, hi)
    }
}

/// A value and its derivatives with respect to `N` parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    /// The value.
    pub v: f64,
    /// ∂value/∂pₖ.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// Parameter `k` at `v` (derivative 1 along itself).
    pub fn var(v: f64, k: usize) -> Self {
        let mut d = [0.0; N];
        if let Some(x) = d.get_mut(k) {
            *x = 1.0;
        }
        Self { v, d }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self {
            v: self.v + o.v,
            d: core::array::from_fn(|i| self.d[i] + o.d[i]),
        }
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self {
            v: self.v - o.v,
            d: core::array::from_fn(|i| self.d[i] - o.d[i]),
        }
    }
}

// The product and quotient rules add inside `*` and `/`.
#[allow(clippy::suspicious_arithmetic_impl)]
impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self {
            v: self.v * o.v,
            d: core::array::from_fn(|i| self.d[i] * o.v + self.v * o.d[i]),
        }
    }
}

#[allow(clippy::suspicious_arithmetic_impl)]
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let q = self.v / o.v;
        let inv = 1.0 / o.v;
        Self {
            v: q,
            d: core::array::from_fn(|i| (self.d[i] - q * o.d[i]) * inv),
        }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self {
            v: -self.v,
            d: self.d.map(|x| -x),
        }
    }
}

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: f64) -> Self {
        Self {
            v: self.v + o,
            d: self.d,
        }
    }
}

impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: f64) -> Self {
        Self {
            v: self.v - o,
            d: self.d,
        }
    }
}

impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Self {
            v: self.v * o,
            d: self.d.map(|x| x * o),
        }
    }
}

#[allow(clippy::suspicious_arithmetic_impl)]
impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: f64) -> Self {
        let inv = 1.0 / o;
        Self {
            v: self.v / o,
            d: self.d.map(|x| x * inv),
        }
    }
}

impl<const N: usize> Scalar for Dual<N> {
    const TANGENTS: bool = true;
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Self { v, d: [0.0; N] }
    }
    #[inline(always)]
    fn val(self) -> f64 {
        self.v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        let k = 0.5 / s;
        Self {
            v: s,
            d: self.d.map(|x| x * k),
        }
    }
    #[inline(always)]
    fn cos(self) -> Self {
        let (s, c) = self.v.sin_cos();
        Self {
            v: c,
            d: self.d.map(|x| -s * x),
        }
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = self.v.sin_cos();
        (
            Self {
                v: s,
                d: self.d.map(|x| c * x),
            },
            Self {
                v: c,
                d: self.d.map(|x| -s * x),
            },
        )
    }
    #[inline(always)]
    fn exp(self) -> Self {
        let e = self.v.exp();
        Self {
            v: e,
            d: self.d.map(|x| e * x),
        }
    }
    #[inline(always)]
    fn exp_m1(self) -> Self {
        let e = self.v.exp_m1();
        let de = self.v.exp();
        Self {
            v: e,
            d: self.d.map(|x| de * x),
        }
    }
    #[inline(always)]
    fn plus_tangents_of(self, k: f64, other: Self) -> Self {
        Self {
            v: self.v,
            d: core::array::from_fn(|i| self.d[i] + k * other.d[i]),
        }
    }
    #[inline(always)]
    fn with_value(self, value: f64) -> Self {
        Self {
            v: value,
            d: self.d,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each rule against a central difference of the f64 expression.
    #[test]
    fn dual_rules_match_central_differences() {
        let f = |x: f64, y: f64| -> f64 {
            let a = (x * y + 0.3).sqrt() / (x - 2.0 * y);
            let (s, c) = (x * 0.7).sin_cos();
            a * s - c.exp() + (-x * y).exp_m1() + (y * 3.0).cos() * x
        };
        let g = |x: Dual<2>, y: Dual<2>| -> Dual<2> {
            let a = (x * y + 0.3).sqrt() / (x - y * 2.0);
            let (s, c) = (x * 0.7).sin_cos();
            a * s - c.exp() + (-(x * y)).exp_m1() + (y * 3.0).cos() * x
        };
        for &(x0, y0) in &[(0.4, 0.5), (1.3, 0.2), (-0.7, -0.1)] {
            let r = g(Dual::var(x0, 0), Dual::var(y0, 1));
            assert_eq!(r.v.to_bits(), f(x0, y0).to_bits(), "value at ({x0}, {y0})");
            let h = 1e-6;
            let dx = (f(x0 + h, y0) - f(x0 - h, y0)) / (2.0 * h);
            let dy = (f(x0, y0 + h) - f(x0, y0 - h)) / (2.0 * h);
            assert!(
                (r.d[0] - dx).abs() < 1e-7 * (1.0 + dx.abs()),
                "∂x {} vs {dx}",
                r.d[0]
            );
            assert!(
                (r.d[1] - dy).abs() < 1e-7 * (1.0 + dy.abs()),
                "∂y {} vs {dy}",
                r.d[1]
            );
        }
    }

    /// A dual's min, max and clamp pick by value.
    #[test]
    fn choices_follow_the_value() {
        let (a, b) = (Dual::<1>::var(1.0, 0), Dual::<1>::cst(2.0));
        assert_eq!(a.min_of(b), a);
        assert_eq!(a.max_of(b), b);
        assert_eq!(a.clamp_to(Dual::cst(1.5), b).d, [0.0]);
        assert_eq!(a.clamp_to(Dual::cst(0.0), b), a);
        assert_eq!(b.min_of(a), a);
        assert_eq!(b.max_of(a), b);
    }
}
