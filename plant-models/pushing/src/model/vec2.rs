//! A small 2D vector and 2×2 matrix for the pushing models. Plain `f64`
//! fields and inlined operators keep the hot loops fast in both debug and
//! release builds (the test suite runs unoptimised).
use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// 2D vector: a position in px, a velocity in px/s or a force, as named at
/// each use.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct V2 {
    pub x: f64,
    pub y: f64,
}

impl V2 {
    #[inline(always)]
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }
    #[inline(always)]
    pub const fn zeros() -> Self {
        Self { x: 0.0, y: 0.0 }
    }
    #[inline(always)]
    pub fn dot(&self, o: &V2) -> f64 {
        self.x * o.x + self.y * o.y
    }
    #[inline(always)]
    pub fn norm_squared(&self) -> f64 {
        self.x * self.x + self.y * self.y
    }
    #[inline(always)]
    pub fn norm(&self) -> f64 {
        self.norm_squared().sqrt()
    }
    /// Unit vector along `self` (NaN for the zero vector).
    #[inline(always)]
    pub fn normalize(&self) -> V2 {
        *self / self.norm()
    }
    /// Component-wise minimum.
    #[inline(always)]
    pub fn inf(&self, o: &V2) -> V2 {
        V2::new(self.x.min(o.x), self.y.min(o.y))
    }
    /// Component-wise maximum.
    #[inline(always)]
    pub fn sup(&self, o: &V2) -> V2 {
        V2::new(self.x.max(o.x), self.y.max(o.y))
    }
    #[inline(always)]
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite()
    }
}

impl Add for V2 {
    type Output = V2;
    #[inline(always)]
    fn add(self, o: V2) -> V2 {
        V2::new(self.x + o.x, self.y + o.y)
    }
}
impl Sub for V2 {
    type Output = V2;
    #[inline(always)]
    fn sub(self, o: V2) -> V2 {
        V2::new(self.x - o.x, self.y - o.y)
    }
}
impl Sub<V2> for &V2 {
    type Output = V2;
    #[inline(always)]
    fn sub(self, o: V2) -> V2 {
        V2::new(self.x - o.x, self.y - o.y)
    }
}
impl<'a> Add<&'a V2> for V2 {
    type Output = V2;
    #[inline(always)]
    fn add(self, o: &'a V2) -> V2 {
        V2::new(self.x + o.x, self.y + o.y)
    }
}
impl Neg for V2 {
    type Output = V2;
    #[inline(always)]
    fn neg(self) -> V2 {
        V2::new(-self.x, -self.y)
    }
}
impl Mul<f64> for V2 {
    type Output = V2;
    #[inline(always)]
    fn mul(self, s: f64) -> V2 {
        V2::new(self.x * s, self.y * s)
    }
}
impl Mul<f64> for &V2 {
    type Output = V2;
    #[inline(always)]
    fn mul(self, s: f64) -> V2 {
        V2::new(self.x * s, self.y * s)
    }
}
impl Mul<V2> for f64 {
    type Output = V2;
    #[inline(always)]
    fn mul(self, v: V2) -> V2 {
        V2::new(self * v.x, self * v.y)
    }
}
impl Div<f64> for V2 {
    type Output = V2;
    #[inline(always)]
    fn div(self, s: f64) -> V2 {
        V2::new(self.x / s, self.y / s)
    }
}
impl AddAssign for V2 {
    #[inline(always)]
    fn add_assign(&mut self, o: V2) {
        self.x += o.x;
        self.y += o.y;
    }
}
impl SubAssign for V2 {
    #[inline(always)]
    fn sub_assign(&mut self, o: V2) {
        self.x -= o.x;
        self.y -= o.y;
    }
}
impl MulAssign<f64> for V2 {
    #[inline(always)]
    fn mul_assign(&mut self, s: f64) {
        self.x *= s;
        self.y *= s;
    }
}

/// 2×2 matrix, row-major: [[a, b], [c, d]].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct M2 {
    pub a: f64,
    pub b: f64,
    pub c: f64,
    pub d: f64,
}

impl M2 {
    pub const IDENTITY: M2 = M2 {
        a: 1.0,
        b: 0.0,
        c: 0.0,
        d: 1.0,
    };
    /// The matrix with columns `u` and `v`.
    #[inline(always)]
    pub fn from_columns(u: V2, v: V2) -> M2 {
        M2 {
            a: u.x,
            b: v.x,
            c: u.y,
            d: v.y,
        }
    }
    #[inline(always)]
    pub fn col0(&self) -> V2 {
        V2::new(self.a, self.c)
    }
    #[inline(always)]
    pub fn col1(&self) -> V2 {
        V2::new(self.b, self.d)
    }
    #[inline(always)]
    pub fn det(&self) -> f64 {
        self.a * self.d - self.b * self.c
    }
    #[inline(always)]
    pub fn trace(&self) -> f64 {
        self.a + self.d
    }
    #[inline(always)]
    pub fn transpose(&self) -> M2 {
        M2 {
            a: self.a,
            b: self.c,
            c: self.b,
            d: self.d,
        }
    }
    /// Inverse, or `None` when (nearly) singular.
    #[inline(always)]
    pub fn inverse(&self) -> Option<M2> {
        let det = self.det();
        let scale = self
            .a
            .abs()
            .max(self.b.abs())
            .max(self.c.abs())
            .max(self.d.abs());
        if !det.is_finite() || det.abs() <= 1e-14 * scale * scale {
            return None;
        }
        let k = 1.0 / det;
        Some(M2 {
            a: self.d * k,
            b: -self.b * k,
            c: -self.c * k,
            d: self.a * k,
        })
    }
    /// Frobenius norm.
    #[inline(always)]
    pub fn norm(&self) -> f64 {
        (self.a * self.a + self.b * self.b + self.c * self.c + self.d * self.d).sqrt()
    }
    #[inline(always)]
    pub fn scale(&self, s: f64) -> M2 {
        M2 {
            a: self.a * s,
            b: self.b * s,
            c: self.c * s,
            d: self.d * s,
        }
    }
}

impl Mul for M2 {
    type Output = M2;
    #[inline(always)]
    fn mul(self, o: M2) -> M2 {
        M2 {
            a: self.a * o.a + self.b * o.c,
            b: self.a * o.b + self.b * o.d,
            c: self.c * o.a + self.d * o.c,
            d: self.c * o.b + self.d * o.d,
        }
    }
}
impl Add for M2 {
    type Output = M2;
    #[inline(always)]
    fn add(self, o: M2) -> M2 {
        M2 {
            a: self.a + o.a,
            b: self.b + o.b,
            c: self.c + o.c,
            d: self.d + o.d,
        }
    }
}
impl Sub for M2 {
    type Output = M2;
    #[inline(always)]
    fn sub(self, o: M2) -> M2 {
        M2 {
            a: self.a - o.a,
            b: self.b - o.b,
            c: self.c - o.c,
            d: self.d - o.d,
        }
    }
}
