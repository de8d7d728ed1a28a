//! Normalised uniform B-splines (Fujioka & Kano Eq. 1–4) and the uniform
//! knot axis a spline lives on.
//!
//! `B_k(t)` is the degree-k B-spline with integer knots 0, 1, …, k+1; it is
//! built by the recursion of Eq. 3 for any k, and for k = 3 (the only degree
//! the fits use, as in the paper §II) also by the closed form of Eq. 4 and
//! its derivatives. A spline on an [`Axis`] with `m` intervals of length
//! 1/α is `x(s) = Σ_{i=-3}^{m-1} τ_i B_3(α(s − s_i))`; at any s only four
//! basis functions are nonzero.
use crate::error::{check_finite, check_positive, ContourError, Result};
use serde::{Deserialize, Serialize};

/// `N_{j,k}(t)` for `j = 0..=k` at `t ∈ [0, 1]`, by the recursion of
/// Eq. 3 (`N_{0,0} ≡ 1`).
pub fn basis_elements(k: usize, t: f64) -> Vec<f64> {
    let mut n = vec![1.0];
    for i in 1..=k {
        let fi = i as f64;
        let mut next = vec![0.0; i + 1];
        next[0] = (1.0 - t) / fi * n[0];
        for j in 1..i {
            let fj = j as f64;
            next[j] = (fi - fj + t) / fi * n[j - 1] + (1.0 + fj - t) / fi * n[j];
        }
        next[i] = t / fi * n[i - 1];
        n = next;
    }
    n
}

/// `B_k(t)` by Eq. 2 from the elements of Eq. 3: on `[j, j+1)` it is
/// `N_{k−j,k}(t − j)`, zero outside `[0, k+1)`.
pub fn b_spline(k: usize, t: f64) -> f64 {
    if !(0.0..(k + 1) as f64).contains(&t) {
        return 0.0;
    }
    let j = t.floor() as usize;
    basis_elements(k, t - j as f64)[k - j]
}

/// The cubic `B_3(t)` of Eq. 4.
pub fn b3(t: f64) -> f64 {
    b3_derivative(t, 0)
}

/// The `order`-th derivative (0–3) of `B_3` (Eq. 4 differentiated); 0 for
/// higher orders and outside `[0, 4)`.
pub fn b3_derivative(t: f64, order: usize) -> f64 {
    if !(0.0..4.0).contains(&t) {
        return 0.0;
    }
    let piece = t.floor() as usize;
    let coeffs = B3_PIECES[piece];
    poly_derivative(&coeffs, t, order) / 6.0
}

/// Coefficients (constant first) of 6·B_3 on each unit piece, Eq. 4.
const B3_PIECES: [[f64; 4]; 4] = [
    [0.0, 0.0, 0.0, 1.0],
    [4.0, -12.0, 12.0, -3.0],
    [-44.0, 60.0, -24.0, 3.0],
    [64.0, -48.0, 12.0, -1.0],
];

/// The `order`-th derivative of the cubic `Σ c_i t^i` at t.
fn poly_derivative(c: &[f64; 4], t: f64, order: usize) -> f64 {
    match order {
        0 => c[0] + t * (c[1] + t * (c[2] + t * c[3])),
        1 => c[1] + t * (2.0 * c[2] + t * 3.0 * c[3]),
        2 => 2.0 * c[2] + 6.0 * c[3] * t,
        3 => 6.0 * c[3],
        _ => 0.0,
    }
}

/// The four cubic B-spline values (or derivatives, in units of the local
/// coordinate) on one knot interval at local coordinate `x ∈ [0, 1]`,
/// ordered from the function that started 3 intervals earlier to the one
/// starting at this interval's left knot: `B_3(x+3), B_3(x+2), B_3(x+1),
/// B_3(x)`.
pub fn local_cubic(x: f64, order: usize) -> [f64; 4] {
    let (u, x2, x3) = (1.0 - x, x * x, x * x * x);
    match order {
        0 => [
            u * u * u / 6.0,
            (3.0 * x3 - 6.0 * x2 + 4.0) / 6.0,
            (-3.0 * x3 + 3.0 * x2 + 3.0 * x + 1.0) / 6.0,
            x3 / 6.0,
        ],
        1 => [
            -u * u / 2.0,
            (3.0 * x2 - 4.0 * x) / 2.0,
            (-3.0 * x2 + 2.0 * x + 1.0) / 2.0,
            x2 / 2.0,
        ],
        2 => [u, 3.0 * x - 2.0, -3.0 * x + 1.0, x],
        3 => [-1.0, 3.0, -3.0, 1.0],
        _ => [0.0; 4],
    }
}

/// `x.rem_euclid(period)`, bit for bit, without the division when x is
/// already in `[0, period)` (where `rem_euclid` returns x itself): most
/// sites a curve is evaluated at already lie in its domain, and `fmod` was
/// a tenth of a contour frame's checks (issue 34).
pub fn rem_period(x: f64, period: f64) -> f64 {
    if (0.0..period).contains(&x) {
        x
    } else {
        x.rem_euclid(period)
    }
}

/// A uniform knot axis: knots `s_i = start + i/α`, `i = −3, …, m + 3`,
/// domain `[s_0, s_m]`, `m` intervals and `M = m + 3` coefficients
/// `τ_{−3} … τ_{m−1}` (stored at indices 0 … M−1). A periodic axis ties
/// `τ_{−3}, τ_{−2}, τ_{−1}` to `τ_{m−3}, τ_{m−2}, τ_{m−1}` (paper, after
/// Eq. 20), so x, x′ and x″ agree at the two ends.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Axis {
    /// `s_0`.
    pub start: f64,
    /// `m`, the number of knot intervals in the domain.
    pub intervals: usize,
    /// Knots per unit, α (knot spacing 1/α).
    pub alpha: f64,
    /// Whether the spline is periodic on this axis (closed).
    pub periodic: bool,
}

/// Fewest knot intervals of an axis (the paper's m > 2).
pub const MIN_INTERVALS: usize = 3;
/// Most knot intervals of an axis (a guard against absurd requests).
pub const MAX_INTERVALS: usize = 100_000;

/// Every field of an [`Axis`], to the bit ([`Axis::key`]): equal keys,
/// equal axes.
pub(crate) type AxisKey = (u64, usize, u64, bool);

impl Axis {
    /// The axis as a key for tables computed from it alone.
    pub(crate) fn key(&self) -> AxisKey {
        // Destructured: a field added to `Axis` must join the key.
        let Axis {
            start,
            intervals,
            alpha,
            periodic,
        } = *self;
        (start.to_bits(), intervals, alpha.to_bits(), periodic)
    }

    /// The axis over `[start, end]` with `intervals` knot intervals.
    pub fn over(start: f64, end: f64, intervals: usize, periodic: bool) -> Result<Self> {
        check_finite("start", start)?;
        check_finite("end", end)?;
        if end <= start {
            return Err(ContourError::InvalidParameter {
                name: "end",
                value: end,
                reason: "the domain's end must be above its start",
            });
        }
        let a = Self {
            start,
            intervals,
            alpha: intervals as f64 / (end - start),
            periodic,
        };
        a.validate()?;
        Ok(a)
    }

    /// Checks the fields.
    pub fn validate(&self) -> Result<()> {
        check_finite("start", self.start)?;
        check_positive("alpha", self.alpha)?;
        if !(MIN_INTERVALS..=MAX_INTERVALS).contains(&self.intervals) {
            return Err(ContourError::InvalidParameter {
                name: "intervals",
                value: self.intervals as f64,
                reason: "an axis needs between 3 (the paper's m > 2) and 100000 knot intervals",
            });
        }
        if !self.end().is_finite() {
            return Err(ContourError::InvalidParameter {
                name: "alpha",
                value: self.alpha,
                reason: "the domain's end is not finite",
            });
        }
        Ok(())
    }

    /// `s_m`, the end of the domain.
    pub fn end(&self) -> f64 {
        self.start + self.intervals as f64 / self.alpha
    }

    /// Length of the domain.
    pub fn length(&self) -> f64 {
        self.intervals as f64 / self.alpha
    }

    /// `M = m + 3`, coefficients stored.
    pub fn coefficients(&self) -> usize {
        self.intervals + 3
    }

    /// Independent coefficients: `m` on a periodic axis, `M` otherwise.
    pub fn free_coefficients(&self) -> usize {
        if self.periodic {
            self.intervals
        } else {
            self.coefficients()
        }
    }

    /// Knot `s_i`.
    pub fn knot(&self, i: i64) -> f64 {
        self.start + i as f64 / self.alpha
    }

    /// `s` moved into the domain: wrapped on a periodic axis, unchanged
    /// otherwise.
    pub fn wrap(&self, s: f64) -> f64 {
        if self.periodic {
            let l = self.length();
            let mut r = rem_period(s - self.start, l);
            if r >= l {
                r = 0.0;
            }
            self.start + r
        } else {
            s
        }
    }

    /// Whether `s` lies in the closed domain (any finite s on a periodic
    /// axis).
    pub fn contains(&self, s: f64) -> bool {
        s.is_finite() && (self.periodic || (s >= self.start && s <= self.end()))
    }

    /// The knot interval `j` holding `s` and the local coordinate
    /// `x = α(s − s_j) ∈ [0, 1]`. Outside the domain of a non-periodic axis
    /// the end interval is used (its polynomial extends the spline).
    pub fn locate(&self, s: f64) -> (usize, f64) {
        let u = self.alpha * (self.wrap(s) - self.start);
        let j = (u.floor().max(0.0) as usize).min(self.intervals - 1);
        (j, u - j as f64)
    }

    /// The four nonzero basis values `B_3(α(s − s_i))` (or their
    /// `order`-th derivatives with respect to s) at `s`, and the storage
    /// index of the first: indices `first .. first + 4` (`τ_{j−3} … τ_j`).
    pub fn basis(&self, s: f64, order: usize) -> (usize, [f64; 4]) {
        let (j, x) = self.locate(s);
        let scale = self.alpha.powi(order as i32);
        let mut v = local_cubic(x, order);
        v.iter_mut().for_each(|b| *b *= scale);
        (j, v)
    }

    /// The dense basis vector `b(s)` (Eq. 11), length M.
    pub fn basis_vector(&self, s: f64, order: usize) -> Vec<f64> {
        let mut b = vec![0.0; self.coefficients()];
        let (first, v) = self.basis(s, order);
        b[first..first + 4].copy_from_slice(&v);
        b
    }

    /// Index of the free coefficient that storage index `i` is tied to:
    /// `(i − 3) mod m` on a periodic axis (so `τ_{−3}` → `τ_{m−3}`), `i`
    /// otherwise.
    pub fn free_index(&self, i: usize) -> usize {
        if self.periodic {
            (i + self.intervals - 3) % self.intervals
        } else {
            i
        }
    }

    /// The storage indices tied by periodicity, as pairs `(a, b)` meaning
    /// `τ_a = τ_b` (`τ_{−3+l} = τ_{m−3+l}`, l = 0, 1, 2); none on a
    /// non-periodic axis.
    pub fn ties(&self) -> Vec<(usize, usize)> {
        if self.periodic {
            (0..3).map(|l| (l, self.intervals + l)).collect()
        } else {
            Vec::new()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recursion_of_eq_3_gives_eq_4() {
        for k in 0..200 {
            let t = 4.0 * k as f64 / 200.0 + 1e-3;
            assert!((b_spline(3, t) - b3(t)).abs() < 1e-14, "t = {t}");
        }
        // Degree 1 is the hat function.
        assert!((b_spline(1, 0.5) - 0.5).abs() < 1e-15);
        assert!((b_spline(1, 1.25) - 0.75).abs() < 1e-15);
        assert_eq!(b_spline(2, -0.1), 0.0);
        assert_eq!(b_spline(2, 3.0), 0.0);
    }

    #[test]
    fn local_cubic_is_b3_and_its_derivatives() {
        for k in 0..=20 {
            let x = k as f64 / 20.0 * 0.999;
            for order in 0..4 {
                let v = local_cubic(x, order);
                for (p, vi) in v.iter().enumerate() {
                    let want = b3_derivative(x + (3 - p) as f64, order);
                    assert!((vi - want).abs() < 1e-13, "x {x} order {order} p {p}");
                }
            }
        }
    }

    #[test]
    fn derivatives_match_finite_differences() {
        let h = 1e-6;
        for k in 1..40 {
            let t = 0.1 * k as f64 + 0.013;
            for order in 0..3 {
                let fd = (b3_derivative(t + h, order) - b3_derivative(t - h, order)) / (2.0 * h);
                assert!((fd - b3_derivative(t, order + 1)).abs() < 1e-6, "t {t}");
            }
        }
    }

    #[test]
    fn periodic_axis_wraps_and_ties_three_coefficients() {
        let a = Axis::over(0.0, 10.0, 10, true).unwrap();
        assert_eq!(a.coefficients(), 13);
        assert_eq!(a.free_coefficients(), 10);
        assert_eq!(a.ties(), vec![(0, 10), (1, 11), (2, 12)]);
        for (i, f) in [(0, 7), (1, 8), (2, 9), (3, 0), (12, 9)] {
            assert_eq!(a.free_index(i), f);
        }
        assert!((a.wrap(-0.5) - 9.5).abs() < 1e-12);
        assert!((a.wrap(10.0) - 0.0).abs() < 1e-12);
        assert_eq!(a.locate(10.0).0, 0);
        let b = Axis::over(0.0, 10.0, 10, false).unwrap();
        assert_eq!(b.locate(10.0), (9, 1.0));
        assert!(Axis::over(0.0, 1.0, 2, true).is_err());
        assert!(Axis::over(1.0, 1.0, 5, true).is_err());
        assert!(Axis::over(f64::NAN, 1.0, 5, true).is_err());
    }
}
