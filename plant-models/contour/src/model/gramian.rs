//! The Gramians of Eq. 19, `Q^{(ij)} = ∫_I (dⁱb/dsⁱ)(dʲbᵀ/dsʲ) ds` over the
//! domain of one axis, and the surface Gramian `Q` of Eq. 18 (the
//! quadratic form of `∫∫ (∇²x)² ds dt`, with `∇² = ∂²/∂s² + ∂²/∂t²`).
//!
//! Each entry is integrated piece by piece with 4-point Gauss–Legendre
//! quadrature, exact for the degree-≤ 6 products of cubic pieces. The
//! matrices are banded (`|p − q| ≤ 3`) and kept so; dense copies are for
//! tests and the dense KKT solver.
use crate::model::basis::{local_cubic, Axis};
use nalgebra::DMatrix;

/// Gauss–Legendre nodes on [0, 1] and weights (4 points).
const GAUSS4: [(f64, f64); 4] = [
    (0.069_431_844_202_973_71, 0.173_927_422_568_726_93),
    (0.330_009_478_207_571_87, 0.326_072_577_431_273_07),
    (0.669_990_521_792_428_1, 0.326_072_577_431_273_07),
    (0.930_568_155_797_026_3, 0.173_927_422_568_726_93),
];

/// Points and weights of the 4-point Gauss rule on [0, 1].
pub fn gauss4() -> &'static [(f64, f64); 4] {
    &GAUSS4
}

/// A symmetric-pattern band matrix of half-width 3: entry (p, q) for
/// `|p − q| ≤ 3` at `rows[p][q − p + 3]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Band7 {
    /// One row per coefficient, seven diagonals.
    pub rows: Vec<[f64; 7]>,
}

impl Band7 {
    /// Entry (p, q); 0 outside the band.
    pub fn get(&self, p: usize, q: usize) -> f64 {
        let d = q as i64 - p as i64;
        if d.abs() > 3 || p >= self.rows.len() || q >= self.rows.len() {
            0.0
        } else {
            self.rows[p][(d + 3) as usize]
        }
    }

    /// Size n of the n×n matrix.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True for an empty matrix.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// The nonzero band entries as (p, q, value).
    pub fn entries(&self) -> impl Iterator<Item = (usize, usize, f64)> + '_ {
        let n = self.rows.len();
        self.rows.iter().enumerate().flat_map(move |(p, r)| {
            (0..7).filter_map(move |k| {
                let q = p as i64 + k as i64 - 3;
                (q >= 0 && (q as usize) < n && r[k] != 0.0).then_some((p, q as usize, r[k]))
            })
        })
    }

    /// The transpose.
    pub fn transpose(&self) -> Band7 {
        let n = self.rows.len();
        let mut rows = vec![[0.0; 7]; n];
        for (p, q, v) in self.entries() {
            rows[q][p + 3 - q] = v;
        }
        Band7 { rows }
    }

    /// A dense copy.
    pub fn to_dense(&self) -> DMatrix<f64> {
        let n = self.rows.len();
        let mut d = DMatrix::zeros(n, n);
        for (p, q, v) in self.entries() {
            d[(p, q)] = v;
        }
        d
    }
}

/// `Q^{(ij)}` of Eq. 19 for one axis: `∫_{s_0}^{s_m} b^{(i)}(s) b^{(j)}(s)ᵀ ds`
/// (derivatives with respect to s, so the knot density α enters as
/// `α^{i+j−1}`).
pub fn gramian(axis: &Axis, i: usize, j: usize) -> Band7 {
    let n = axis.coefficients();
    let mut rows = vec![[0.0; 7]; n];
    let h = 1.0 / axis.alpha;
    let (si, sj) = (axis.alpha.powi(i as i32), axis.alpha.powi(j as i32));
    for interval in 0..axis.intervals {
        for &(x, w) in &GAUSS4 {
            let bi = local_cubic(x, i);
            let bj = local_cubic(x, j);
            for (p, vp) in bi.iter().enumerate() {
                for (q, vq) in bj.iter().enumerate() {
                    // Row interval + p, column interval + q: diagonal q − p.
                    rows[interval + p][q + 3 - p] += w * h * si * vp * sj * vq;
                }
            }
        }
    }
    Band7 { rows }
}

/// The four 1-D Gramians an axis contributes to Eq. 18.
#[derive(Debug, Clone, PartialEq)]
pub struct AxisGramians {
    /// `Q^{(00)}`.
    pub q00: Band7,
    /// `Q^{(02)}`.
    pub q02: Band7,
    /// `Q^{(20)} = (Q^{(02)})ᵀ`.
    pub q20: Band7,
    /// `Q^{(22)}`.
    pub q22: Band7,
}

impl AxisGramians {
    /// The Gramians of `axis`.
    pub fn of(axis: &Axis) -> Self {
        let q02 = gramian(axis, 0, 2);
        Self {
            q00: gramian(axis, 0, 0),
            q20: q02.transpose(),
            q02,
            q22: gramian(axis, 2, 2),
        }
    }
}

/// Entry of the surface Gramian `Q` of Eq. 18 between coefficients
/// `(p1, p2)` and `(q1, q2)` (s-index, t-index):
/// `Q = Q₂⁽⁰⁰⁾⊗Q₁⁽²²⁾ + Q₂⁽⁰²⁾⊗(Q₁⁽⁰²⁾)ᵀ + (Q₂⁽⁰²⁾)ᵀ⊗Q₁⁽⁰²⁾ + Q₂⁽²²⁾⊗Q₁⁽⁰⁰⁾`.
pub fn surface_entry(
    g1: &AxisGramians,
    g2: &AxisGramians,
    (p1, p2): (usize, usize),
    (q1, q2): (usize, usize),
) -> f64 {
    g2.q00.get(p2, q2) * g1.q22.get(p1, q1)
        + g2.q02.get(p2, q2) * g1.q20.get(p1, q1)
        + g2.q20.get(p2, q2) * g1.q02.get(p1, q1)
        + g2.q22.get(p2, q2) * g1.q00.get(p1, q1)
}

/// Kronecker product `A ⊗ B` of dense matrices.
pub fn kron(a: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let (ar, ac) = a.shape();
    let (br, bc) = b.shape();
    let mut k = DMatrix::zeros(ar * br, ac * bc);
    for i in 0..ar {
        for j in 0..ac {
            let aij = a[(i, j)];
            if aij != 0.0 {
                k.view_mut((i * br, j * bc), (br, bc)).copy_from(&(b * aij));
            }
        }
    }
    k
}

/// The dense surface Gramian of Eq. 18 over `vec τ` (s-index fastest),
/// for tests and small problems.
pub fn surface_gramian_dense(s_axis: &Axis, t_axis: &Axis) -> DMatrix<f64> {
    let g1 = AxisGramians::of(s_axis);
    let g2 = AxisGramians::of(t_axis);
    kron(&g2.q00.to_dense(), &g1.q22.to_dense())
        + kron(&g2.q02.to_dense(), &g1.q02.to_dense().transpose())
        + kron(&g2.q02.to_dense().transpose(), &g1.q02.to_dense())
        + kron(&g2.q22.to_dense(), &g1.q00.to_dense())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interior_entries_are_the_cubic_b_spline_closed_forms() {
        // ∫B₃(t)B₃(t+k) dt = 2416, 1191, 120, 1 (/5040) for k = 0..3, and
        // ∫B₃″(t)B₃″(t+k) dt = 8/3, −3/2, 0, 1/6; scaled by 1/α and α³.
        let alpha = 2.5;
        let a = Axis::over(0.0, 8.0, 20, false).unwrap();
        assert!((a.alpha - alpha).abs() < 1e-15);
        let q00 = gramian(&a, 0, 0);
        let q22 = gramian(&a, 2, 2);
        let p = 10;
        for (k, (g0, g2)) in [
            (2416.0 / 5040.0, 8.0 / 3.0),
            (1191.0 / 5040.0, -1.5),
            (120.0 / 5040.0, 0.0),
            (1.0 / 5040.0, 1.0 / 6.0),
        ]
        .into_iter()
        .enumerate()
        {
            assert!((q00.get(p, p + k) - g0 / alpha).abs() < 1e-14, "Q00 k={k}");
            assert!(
                (q22.get(p, p + k) - g2 * alpha.powi(3)).abs() < 1e-12,
                "Q22 k={k}"
            );
        }
        // Symmetric; constants are in the null space of Q22, and Q02·1 =
        // ∫ b (Σ b″) = 0 (the second derivatives of a partition of unity
        // cancel).
        let d22 = q22.to_dense();
        assert!((&d22 - d22.transpose()).amax() < 1e-12);
        let ones = nalgebra::DVector::from_element(a.coefficients(), 1.0);
        assert!((&d22 * &ones).amax() < 1e-11);
        assert!((gramian(&a, 0, 2).to_dense() * &ones).amax() < 1e-11);
        // ∫ b(s) ds = 1ᵀQ00·1 = domain length (partition of unity).
        let total: f64 = q00.entries().map(|e| e.2).sum();
        assert!((total - 8.0).abs() < 1e-12);
    }

    #[test]
    fn sparse_surface_entries_equal_the_kronecker_form() {
        let s = Axis::over(0.0, 5.0, 5, false).unwrap();
        let t = Axis::over(0.0, 4.0, 4, true).unwrap();
        let dense = surface_gramian_dense(&s, &t);
        let (g1, g2) = (AxisGramians::of(&s), AxisGramians::of(&t));
        let m1 = s.coefficients();
        for a in 0..dense.nrows() {
            for b in 0..dense.ncols() {
                let e = surface_entry(&g1, &g2, (a % m1, a / m1), (b % m1, b / m1));
                assert!((e - dense[(a, b)]).abs() < 1e-12, "({a},{b})");
            }
        }
        // A linear function a + b·s has ∇²x = 0: in Q's null space.
        let tau: Vec<f64> = (0..dense.nrows())
            .map(|k| 1.0 + 0.5 * s.knot((k % m1) as i64 - 1))
            .collect();
        let v = nalgebra::DVector::from_vec(tau);
        assert!((v.transpose() * &dense * &v)[0].abs() < 1e-10);
    }
}
