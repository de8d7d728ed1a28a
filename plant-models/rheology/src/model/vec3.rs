//! Small 3-vectors and 3×3 matrices for the lattice's and the reference
//! block's inner loops.
//!
//! Plain structs rather than nalgebra's `Vector3`/`Matrix3`: the release
//! code is the same, but in the unoptimised builds that run the test suite
//! nalgebra's generic operators cost about 13× more per operation
//! (measured: 1e6 differences, norms and scalings, 683 ms against 52 ms),
//! and the lattice's tests step thousands of times.
use core::ops::{Add, AddAssign, Div, Index, IndexMut, Mul, MulAssign, Neg, Sub, SubAssign};

/// A 3-vector (m, m/s or N by context).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct V3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl V3 {
    #[inline]
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Self { x, y, z }
    }
    #[inline]
    pub const fn zeros() -> Self {
        Self::new(0.0, 0.0, 0.0)
    }
    #[inline]
    pub const fn repeat(v: f64) -> Self {
        Self::new(v, v, v)
    }
    #[inline]
    pub fn dot(&self, o: &V3) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    #[inline]
    pub fn cross(&self, o: &V3) -> V3 {
        V3::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }
    #[inline]
    pub fn norm_squared(&self) -> f64 {
        self.dot(self)
    }
    #[inline]
    pub fn norm(&self) -> f64 {
        self.norm_squared().sqrt()
    }
    #[inline]
    pub fn component_mul(&self, o: &V3) -> V3 {
        V3::new(self.x * o.x, self.y * o.y, self.z * o.z)
    }
    /// Component-wise minimum.
    pub fn inf(&self, o: &V3) -> V3 {
        V3::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }
    /// Component-wise maximum.
    pub fn sup(&self, o: &V3) -> V3 {
        V3::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }
    /// Whether every component is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
    /// The outer product `self·oᵀ`.
    #[inline]
    pub fn outer(&self, o: &V3) -> M3 {
        M3 {
            m: [
                [self.x * o.x, self.x * o.y, self.x * o.z],
                [self.y * o.x, self.y * o.y, self.y * o.z],
                [self.z * o.x, self.z * o.y, self.z * o.z],
            ],
        }
    }
}

impl Index<usize> for V3 {
    type Output = f64;
    #[inline]
    fn index(&self, i: usize) -> &f64 {
        match i {
            0 => &self.x,
            1 => &self.y,
            _ => &self.z,
        }
    }
}

impl IndexMut<usize> for V3 {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut f64 {
        match i {
            0 => &mut self.x,
            1 => &mut self.y,
            _ => &mut self.z,
        }
    }
}

impl Add for V3 {
    type Output = V3;
    #[inline]
    fn add(self, o: V3) -> V3 {
        V3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}
impl Sub for V3 {
    type Output = V3;
    #[inline]
    fn sub(self, o: V3) -> V3 {
        V3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}
impl Neg for V3 {
    type Output = V3;
    #[inline]
    fn neg(self) -> V3 {
        V3::new(-self.x, -self.y, -self.z)
    }
}
impl Mul<f64> for V3 {
    type Output = V3;
    #[inline]
    fn mul(self, s: f64) -> V3 {
        V3::new(self.x * s, self.y * s, self.z * s)
    }
}
impl Mul<V3> for f64 {
    type Output = V3;
    #[inline]
    fn mul(self, v: V3) -> V3 {
        v * self
    }
}
impl Div<f64> for V3 {
    type Output = V3;
    #[inline]
    fn div(self, s: f64) -> V3 {
        V3::new(self.x / s, self.y / s, self.z / s)
    }
}
impl AddAssign for V3 {
    #[inline]
    fn add_assign(&mut self, o: V3) {
        self.x += o.x;
        self.y += o.y;
        self.z += o.z;
    }
}
impl SubAssign for V3 {
    #[inline]
    fn sub_assign(&mut self, o: V3) {
        self.x -= o.x;
        self.y -= o.y;
        self.z -= o.z;
    }
}
impl MulAssign<f64> for V3 {
    #[inline]
    fn mul_assign(&mut self, s: f64) {
        self.x *= s;
        self.y *= s;
        self.z *= s;
    }
}

/// A 3×3 matrix, row-major.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct M3 {
    pub m: [[f64; 3]; 3],
}

impl M3 {
    pub const fn zeros() -> Self {
        Self { m: [[0.0; 3]; 3] }
    }
    pub const fn identity() -> Self {
        Self::from_diagonal(V3::repeat(1.0))
    }
    pub const fn from_diagonal(d: V3) -> Self {
        Self {
            m: [[d.x, 0.0, 0.0], [0.0, d.y, 0.0], [0.0, 0.0, d.z]],
        }
    }
    /// The matrix with columns `a`, `b`, `c`.
    pub fn from_columns(a: V3, b: V3, c: V3) -> Self {
        Self {
            m: [[a.x, b.x, c.x], [a.y, b.y, c.y], [a.z, b.z, c.z]],
        }
    }
    pub fn diagonal(&self) -> V3 {
        V3::new(self.m[0][0], self.m[1][1], self.m[2][2])
    }
    pub fn trace(&self) -> f64 {
        self.m[0][0] + self.m[1][1] + self.m[2][2]
    }
    pub fn transpose(&self) -> M3 {
        let m = &self.m;
        M3 {
            m: [
                [m[0][0], m[1][0], m[2][0]],
                [m[0][1], m[1][1], m[2][1]],
                [m[0][2], m[1][2], m[2][2]],
            ],
        }
    }
    pub fn determinant(&self) -> f64 {
        let m = &self.m;
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    }
    /// The inverse, or `None` when the determinant is zero or not finite.
    pub fn try_inverse(&self) -> Option<M3> {
        let det = self.determinant();
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let m = &self.m;
        let c = |r0: usize, c0: usize, r1: usize, c1: usize| {
            m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
        };
        let inv = [
            [c(1, 1, 2, 2), -c(0, 1, 2, 2), c(0, 1, 1, 2)],
            [-c(1, 0, 2, 2), c(0, 0, 2, 2), -c(0, 0, 1, 2)],
            [c(1, 0, 2, 1), -c(0, 0, 2, 1), c(0, 0, 1, 1)],
        ];
        Some(M3 { m: inv } * (1.0 / det))
    }
    /// The symmetric part.
    pub fn sym(&self) -> M3 {
        (*self + self.transpose()) * 0.5
    }
    /// Frobenius inner product.
    pub fn ddot(&self, o: &M3) -> f64 {
        (0..3)
            .map(|r| (0..3).map(|c| self.m[r][c] * o.m[r][c]).sum::<f64>())
            .sum()
    }
}

impl Add for M3 {
    type Output = M3;
    #[inline]
    fn add(self, o: M3) -> M3 {
        let mut r = self;
        r += o;
        r
    }
}
impl Sub for M3 {
    type Output = M3;
    #[inline]
    fn sub(self, o: M3) -> M3 {
        let mut r = self;
        for i in 0..3 {
            for j in 0..3 {
                r.m[i][j] -= o.m[i][j];
            }
        }
        r
    }
}
impl AddAssign for M3 {
    #[inline]
    fn add_assign(&mut self, o: M3) {
        for i in 0..3 {
            for j in 0..3 {
                self.m[i][j] += o.m[i][j];
            }
        }
    }
}
impl Mul<f64> for M3 {
    type Output = M3;
    #[inline]
    fn mul(self, s: f64) -> M3 {
        let mut r = self;
        for row in r.m.iter_mut() {
            for v in row.iter_mut() {
                *v *= s;
            }
        }
        r
    }
}
impl Mul<V3> for M3 {
    type Output = V3;
    #[inline]
    fn mul(self, v: V3) -> V3 {
        let m = &self.m;
        V3::new(
            m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
            m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
            m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
        )
    }
}
impl Mul<M3> for M3 {
    type Output = M3;
    fn mul(self, o: M3) -> M3 {
        let mut r = M3::zeros();
        for i in 0..3 {
            for j in 0..3 {
                r.m[i][j] = (0..3).map(|k| self.m[i][k] * o.m[k][j]).sum();
            }
        }
        r
    }
}
impl Index<(usize, usize)> for M3 {
    type Output = f64;
    #[inline]
    fn index(&self, (r, c): (usize, usize)) -> &f64 {
        &self.m[r][c]
    }
}
impl IndexMut<(usize, usize)> for M3 {
    #[inline]
    fn index_mut(&mut self, (r, c): (usize, usize)) -> &mut f64 {
        &mut self.m[r][c]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn products_and_inverse_agree_with_nalgebra() {
        let a = M3 {
            m: [[2.0, -1.0, 0.5], [0.3, 4.0, 1.0], [-0.7, 0.2, 3.0]],
        };
        let na =
            nalgebra::Matrix3::from_row_slice(&[2.0, -1.0, 0.5, 0.3, 4.0, 1.0, -0.7, 0.2, 3.0]);
        let inv = a.try_inverse().unwrap();
        let ninv = na.try_inverse().unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((inv[(r, c)] - ninv[(r, c)]).abs() < 1e-14);
            }
        }
        assert!((a.determinant() - na.determinant()).abs() < 1e-12);
        let v = V3::new(1.0, -2.0, 0.5);
        let nv = na * nalgebra::Vector3::new(1.0, -2.0, 0.5);
        let av = a * v;
        for k in 0..3 {
            assert!((av[k] - nv[k]).abs() < 1e-14);
        }
        let p = (a * a.transpose()) * inv;
        let np = (na * na.transpose()) * ninv;
        for r in 0..3 {
            for c in 0..3 {
                assert!((p[(r, c)] - np[(r, c)]).abs() < 1e-12);
            }
        }
        let w = V3::new(0.2, 0.1, -3.0);
        let nc =
            nalgebra::Vector3::new(1.0, -2.0, 0.5).cross(&nalgebra::Vector3::new(0.2, 0.1, -3.0));
        let c = v.cross(&w);
        for k in 0..3 {
            assert!((c[k] - nc[k]).abs() < 1e-14);
        }
        assert!(M3::zeros().try_inverse().is_none());
    }
}
