//! Fixed-size 3-vectors and 3×3 matrices for the tensor forms of the
//! viscoelastic model (seed 002 §3: "scalars become 3×3 tensors").
//!
//! Deliberately tiny: row-major arrays, no allocation, no panicking index.
//! The host crates use nalgebra; the core keeps to this so the firmware image
//! carries no linear-algebra dependency.

use crate::real::Real;
use core::ops::{Add, Mul, Neg, Sub};

/// A 3-vector (force, traction or displacement at one vertex).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Vec3<T>(pub [T; 3]);

/// A 3×3 matrix, row-major: `m.0[row][col]`.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Mat3<T>(pub [[T; 3]; 3]);

impl<T: Real> Vec3<T> {
    /// The zero vector.
    pub fn zero() -> Self {
        Vec3([T::zero(); 3])
    }

    /// Builds a vector from components.
    pub fn new(x: T, y: T, z: T) -> Self {
        Vec3([x, y, z])
    }

    /// Multiplies every component by `s`.
    pub fn scale(self, s: T) -> Self {
        let [x, y, z] = self.0;
        Vec3([x * s, y * s, z * s])
    }

    /// Largest absolute component (the ∞-norm; needs no square root).
    pub fn max_abs(self) -> T {
        let [x, y, z] = self.0;
        x.abs().max(y.abs()).max(z.abs())
    }

    /// Euclidean norm.
    pub fn norm(self) -> T {
        let [x, y, z] = self.0;
        (x * x + y * y + z * z).sqrt()
    }

    /// True when every component is finite.
    pub fn is_finite(self) -> bool {
        self.0.iter().all(|c| c.is_finite())
    }

    /// True when every component is exactly zero.
    pub fn is_zero(self) -> bool {
        self.0.iter().all(|c| *c == T::zero())
    }
}

impl<T: Real> Add for Vec3<T> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        let ([a, b, c], [d, e, f]) = (self.0, o.0);
        Vec3([a + d, b + e, c + f])
    }
}

impl<T: Real> Sub for Vec3<T> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        let ([a, b, c], [d, e, f]) = (self.0, o.0);
        Vec3([a - d, b - e, c - f])
    }
}

impl<T: Real> Neg for Vec3<T> {
    type Output = Self;
    fn neg(self) -> Self {
        self.scale(-T::one())
    }
}

impl<T: Real> Mat3<T> {
    /// The zero matrix.
    pub fn zero() -> Self {
        Mat3([[T::zero(); 3]; 3])
    }

    /// The identity.
    pub fn identity() -> Self {
        Self::diagonal(T::one(), T::one(), T::one())
    }

    /// A diagonal matrix.
    pub fn diagonal(a: T, b: T, c: T) -> Self {
        let z = T::zero();
        Mat3([[a, z, z], [z, b, z], [z, z, c]])
    }

    /// Multiplies every entry by `s`.
    pub fn scale(self, s: T) -> Self {
        let mut out = self;
        for row in out.0.iter_mut() {
            for v in row.iter_mut() {
                *v = *v * s;
            }
        }
        out
    }

    /// Matrix–vector product.
    pub fn mul_vec(&self, v: Vec3<T>) -> Vec3<T> {
        let m = &self.0;
        let [x, y, z] = v.0;
        Vec3([
            m[0][0] * x + m[0][1] * y + m[0][2] * z,
            m[1][0] * x + m[1][1] * y + m[1][2] * z,
            m[2][0] * x + m[2][1] * y + m[2][2] * z,
        ])
    }

    /// The transpose.
    pub fn transpose(&self) -> Self {
        let m = &self.0;
        Mat3([
            [m[0][0], m[1][0], m[2][0]],
            [m[0][1], m[1][1], m[2][1]],
            [m[0][2], m[1][2], m[2][2]],
        ])
    }

    /// Determinant.
    pub fn determinant(&self) -> T {
        let m = &self.0;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }

    /// Largest absolute entry.
    pub fn max_abs(&self) -> T {
        self.0
            .iter()
            .flat_map(|r| r.iter())
            .fold(T::zero(), |acc, v| acc.max(v.abs()))
    }

    /// True when every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().flat_map(|r| r.iter()).all(|v| v.is_finite())
    }

    /// The inverse by the adjugate, or `None` when the matrix is singular
    /// relative to its own scale (|det| ≤ 1e-12·max|m|³ in f64, 1e-6 in f32
    /// terms of machine epsilon) or not finite.
    pub fn inverse(&self) -> Option<Self> {
        if !self.is_finite() {
            return None;
        }
        let scale = self.max_abs();
        let det = self.determinant();
        // Relative singularity test: det compared with the cube of the
        // entry scale, using a tolerance of ~1e4 machine epsilons.
        let tol = T::epsilon() * T::lit(1.0e4) * scale * scale * scale;
        if scale == T::zero() || det.abs() <= tol || !det.is_finite() {
            return None;
        }
        let m = &self.0;
        let inv_det = T::one() / det;
        let c = |a: T, b: T, c: T, d: T| (a * d - b * c) * inv_det;
        Some(Mat3([
            [
                c(m[1][1], m[1][2], m[2][1], m[2][2]),
                c(m[0][2], m[0][1], m[2][2], m[2][1]),
                c(m[0][1], m[0][2], m[1][1], m[1][2]),
            ],
            [
                c(m[1][2], m[1][0], m[2][2], m[2][0]),
                c(m[0][0], m[0][2], m[2][0], m[2][2]),
                c(m[0][2], m[0][0], m[1][2], m[1][0]),
            ],
            [
                c(m[1][0], m[1][1], m[2][0], m[2][1]),
                c(m[0][1], m[0][0], m[2][1], m[2][0]),
                c(m[0][0], m[0][1], m[1][0], m[1][1]),
            ],
        ]))
    }
}

impl<T: Real> Add for Mat3<T> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        let mut out = self;
        for (ro, ri) in out.0.iter_mut().zip(o.0.iter()) {
            for (a, b) in ro.iter_mut().zip(ri.iter()) {
                *a = *a + *b;
            }
        }
        out
    }
}

impl<T: Real> Mul for Mat3<T> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let [o0, o1, o2] = o.0;
        // Row r of the product: self[r][0]·o[0] + self[r][1]·o[1] +
        // self[r][2]·o[2], summed in that order.
        Mat3(self.0.map(|[x, y, z]| {
            let mut row = [T::zero(); 3];
            for (((v, a), b), c) in row.iter_mut().zip(o0).zip(o1).zip(o2) {
                *v = x * a + y * b + z * c;
            }
            row
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_times_matrix_is_identity() {
        let m: Mat3<f64> = Mat3([[4.0, 1.0, 0.5], [1.0, 3.0, -0.2], [0.5, -0.2, 2.0]]);
        let inv = m.inverse().expect("well-conditioned");
        let p = m * inv;
        for r in 0..3 {
            for c in 0..3 {
                let want = if r == c { 1.0 } else { 0.0 };
                assert!(
                    (p.0[r][c] - want).abs() < 1e-14,
                    "entry ({r},{c}) = {}",
                    p.0[r][c]
                );
            }
        }
    }

    #[test]
    fn singular_and_non_finite_matrices_have_no_inverse() {
        let singular: Mat3<f64> = Mat3([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]]);
        assert!(singular.inverse().is_none());
        assert!(Mat3::<f64>::zero().inverse().is_none());
        let nan = Mat3([[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
        assert!(nan.inverse().is_none());
        // Scale-independent: a tiny but well-conditioned matrix inverts.
        assert!(Mat3::diagonal(1e-9_f64, 2e-9, 3e-9).inverse().is_some());
    }

    #[test]
    fn determinant_and_transpose_agree_with_hand_values() {
        let m = Mat3([[2.0_f64, 0.0, 1.0], [1.0, 3.0, 2.0], [1.0, 1.0, 1.0]]);
        // 2(3-2) - 0 + 1(1-3) = 0
        assert_eq!(m.determinant(), 0.0);
        assert_eq!(m.transpose().0[0][2], 1.0);
        assert_eq!(m.transpose().0[2][0], 1.0);
        assert_eq!(m.transpose().0[1][0], 0.0);
    }
}
