//! Sparse symmetric solves shared by the systems that need them: a skyline
//! (variable-band, "profile") Cholesky factorisation, its solve, the
//! entries of the inverse inside the profile (selected inversion), and the
//! reverse Cuthill–McKee ordering that keeps the profile narrow.
//!
//! Used by the tetrahedral FEM of seed 002 (`viscoelastic::fem`, the
//! stiffness solve), by the static reference of the tetrahedral Voigt
//! network (`tetmsd::statics`), and by the smoothing splines of Fujioka & Kano
//! (`contour`, the penalised least-squares normal equations and the trace of
//! their hat matrix for generalised cross-validation). The cost of a
//! factorisation is O(Σ row length²), O(n·b²) for a band of half-width b,
//! instead of the dense O(n³).
use std::collections::VecDeque;
use thiserror::Error;

/// The matrix handed to [`SkylineCholesky::factor`] is not (numerically)
/// positive definite: the pivot of `equation` was ≤ 0 or not finite.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Error)]
#[error("matrix is not positive definite at equation {equation}")]
pub struct NotPositiveDefinite {
    /// Index of the pivot that failed.
    pub equation: usize,
}

/// A symmetric positive-definite matrix in skyline (variable band) storage,
/// factored in place as `L Lᵀ`.
#[derive(Clone, Debug)]
pub struct SkylineCholesky {
    first: Vec<usize>,
    offset: Vec<usize>,
    data: Vec<f64>,
}

impl SkylineCholesky {
    /// Storage for `n` equations where row `i` has nonzeros from column
    /// `first[i]` to `i`.
    pub fn with_profile(first: Vec<usize>) -> Self {
        let mut offset = Vec::with_capacity(first.len() + 1);
        let mut total = 0;
        for (i, &f) in first.iter().enumerate() {
            offset.push(total);
            total += i + 1 - f.min(i);
        }
        offset.push(total);
        let first = first.iter().enumerate().map(|(i, &f)| f.min(i)).collect();
        SkylineCholesky {
            first,
            offset,
            data: vec![0.0; total],
        }
    }

    /// Number of equations.
    pub fn len(&self) -> usize {
        self.first.len()
    }

    /// True for a matrix of no equations.
    pub fn is_empty(&self) -> bool {
        self.first.is_empty()
    }

    /// Number of stored entries (the profile size).
    pub fn profile_len(&self) -> usize {
        self.data.len()
    }

    /// First stored column of row `i`.
    pub fn first_column(&self, i: usize) -> usize {
        self.first[i]
    }

    /// Sets every stored entry to 0 (the profile stays).
    pub fn clear(&mut self) {
        self.data.iter_mut().for_each(|v| *v = 0.0);
    }

    /// Adds `v` to entry (i, j) of the lower triangle (`j ≤ i`, inside the
    /// profile; entries outside it are a caller bug and are ignored).
    pub fn add(&mut self, i: usize, j: usize, v: f64) {
        let (i, j) = if j > i { (j, i) } else { (i, j) };
        if j >= self.first[i] {
            self.data[self.offset[i] + j - self.first[i]] += v;
        }
    }

    /// Entry (i, j) as stored (0 outside the profile). Before
    /// [`factor`](Self::factor) this is the matrix, after it the factor `L`.
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if j > i { (j, i) } else { (i, j) };
        if j >= self.first[i] {
            self.data[self.offset[i] + j - self.first[i]]
        } else {
            0.0
        }
    }

    /// In-place Cholesky factorisation.
    pub fn factor(&mut self) -> Result<(), NotPositiveDefinite> {
        let n = self.first.len();
        for i in 0..n {
            let (fi, oi) = (self.first[i], self.offset[i]);
            for j in fi..=i {
                let (fj, oj) = (self.first[j], self.offset[j]);
                let k0 = fi.max(fj);
                let (row_i, row_j) = (
                    &self.data[oi + k0 - fi..oi + j - fi],
                    &self.data[oj + k0 - fj..oj + j - fj],
                );
                let s: f64 = row_i.iter().zip(row_j).map(|(a, b)| a * b).sum();
                let a = self.data[oi + j - fi] - s;
                if i == j {
                    if !(a > 0.0 && a.is_finite()) {
                        return Err(NotPositiveDefinite { equation: i });
                    }
                    self.data[oi + j - fi] = a.sqrt();
                } else {
                    let djj = self.data[oj + j - fj];
                    self.data[oi + j - fi] = a / djj;
                }
            }
        }
        Ok(())
    }

    /// Solves `L Lᵀ x = b` in place (after [`factor`](Self::factor)).
    pub fn solve_in_place(&self, b: &mut [f64]) {
        // Leading zeros of b stay zero in the forward pass: skip them.
        let start = b.iter().position(|v| *v != 0.0).unwrap_or(b.len());
        self.solve_from(b, start);
    }

    fn solve_from(&self, b: &mut [f64], start: usize) {
        let n = self.first.len();
        for i in start..n {
            let (fi, oi) = (self.first[i], self.offset[i]);
            let k0 = fi.max(start);
            let row = &self.data[oi + k0 - fi..oi + i - fi];
            let s: f64 = row.iter().zip(&b[k0..i]).map(|(a, x)| a * x).sum();
            b[i] = (b[i] - s) / self.data[oi + i - fi];
        }
        for i in (0..n).rev() {
            let (fi, oi) = (self.first[i], self.offset[i]);
            b[i] /= self.data[oi + i - fi];
            let xi = b[i];
            for (bk, l) in b[fi..i].iter_mut().zip(&self.data[oi..oi + i - fi]) {
                *bk -= l * xi;
            }
        }
    }

    /// The entries of `A⁻¹` inside the profile, after
    /// [`factor`](Self::factor), in the same skyline layout (read them with
    /// [`get`](Self::get) on the returned matrix).
    ///
    /// Selected inversion by the recurrences of Takahashi, Fagan & Chin
    /// (1973): with `A = L Lᵀ` and `Z = A⁻¹ = L⁻ᵀ L⁻¹`,
    /// `Z_ij = δ_ij / L_ii² − (1/L_ii) Σ_{k>i} L_ki Z_kj` for `j ≥ i`, taken
    /// from the last row up. Every `Z_kj` the sum needs lies in the profile
    /// (a row k with `L_ki ≠ 0` starts at or before i ≤ j, k), so the cost is
    /// that of the factorisation. Used for traces such as `tr(A⁻¹ C)` with
    /// `C` inside the profile, without forming `A⁻¹`.
    pub fn inverse_in_profile(&self) -> SkylineCholesky {
        let n = self.first.len();
        let mut z = SkylineCholesky {
            first: self.first.clone(),
            offset: self.offset.clone(),
            data: vec![0.0; self.data.len()],
        };
        // Rows k > i whose profile reaches column i, per i: the nonzeros of
        // column i of L below the diagonal.
        let mut below: Vec<Vec<usize>> = vec![Vec::new(); n];
        for k in 0..n {
            for rows in &mut below[self.first[k]..k] {
                rows.push(k);
            }
        }
        let mut l: Vec<f64> = Vec::new();
        for i in (0..n).rev() {
            let lii = self.data[self.offset[i] + i - self.first[i]];
            let ks = &below[i];
            // Column i of L below the diagonal.
            l.clear();
            l.extend(
                ks.iter()
                    .map(|&k| self.data[self.offset[k] + i - self.first[k]]),
            );
            // Off-diagonal Z_ji (j > i) first: the diagonal needs them.
            let mut diag_sum = 0.0;
            for (a, &j) in ks.iter().enumerate() {
                let (fj, oj) = (z.first[j], z.offset[j]);
                // k < j: Z_jk in row j; k ≥ j: Z_kj in row k (ks ascends).
                let mut s: f64 = ks[..a]
                    .iter()
                    .zip(&l[..a])
                    .map(|(&k, lk)| lk * z.data[oj + k - fj])
                    .sum();
                s += ks[a..]
                    .iter()
                    .zip(&l[a..])
                    .map(|(&k, lk)| lk * z.data[z.offset[k] + j - z.first[k]])
                    .sum::<f64>();
                let zji = -s / lii;
                z.data[oj + i - fj] = zji;
                diag_sum += l[a] * zji;
            }
            z.data[z.offset[i] + i - z.first[i]] = 1.0 / (lii * lii) - diag_sum / lii;
        }
        z
    }
}

/// Reverse Cuthill–McKee order of the nodes in `keep` (a bandwidth-
/// reducing permutation); returns the kept nodes in the new order.
pub fn reverse_cuthill_mckee(adj: &[Vec<usize>], keep: &[bool]) -> Vec<usize> {
    let n = adj.len();
    let degree = |i: usize| adj[i].iter().filter(|&&j| keep[j]).count();
    let mut seen = vec![false; n];
    let mut order = Vec::with_capacity(n);
    loop {
        // Start each component at a kept, unseen node of minimum degree.
        let start = (0..n)
            .filter(|&i| keep[i] && !seen[i])
            .min_by_key(|&i| (degree(i), i));
        let Some(start) = start else { break };
        seen[start] = true;
        let mut queue = VecDeque::from([start]);
        while let Some(i) = queue.pop_front() {
            order.push(i);
            let mut next: Vec<usize> = adj[i]
                .iter()
                .copied()
                .filter(|&j| keep[j] && !seen[j])
                .collect();
            next.sort_by_key(|&j| (degree(j), j));
            for j in next {
                seen[j] = true;
                queue.push_back(j);
            }
        }
    }
    order.reverse();
    order
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// A banded SPD matrix with a ragged profile, dense and skyline.
    fn ragged(n: usize) -> (DMatrix<f64>, SkylineCholesky) {
        let mut dense = DMatrix::<f64>::zeros(n, n);
        let first: Vec<usize> = (0..n).map(|i| i.saturating_sub(1 + (i * 7) % 5)).collect();
        let mut sky = SkylineCholesky::with_profile(first.clone());
        for i in 0..n {
            for j in first[i]..i {
                let v = ((i * 31 + j * 17) % 11) as f64 / 11.0 - 0.5;
                dense[(i, j)] = v;
                dense[(j, i)] = v;
                sky.add(i, j, v);
            }
            dense[(i, i)] = 6.0;
            sky.add(i, i, 6.0);
        }
        (dense, sky)
    }

    #[test]
    fn skyline_cholesky_matches_dense_nalgebra_solve() {
        let n = 40;
        let (dense, mut sky) = ragged(n);
        sky.factor().unwrap();
        let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
        let mut x = b.clone();
        sky.solve_in_place(&mut x);
        let want = dense
            .cholesky()
            .unwrap()
            .solve(&nalgebra::DVector::from_vec(b));
        for i in 0..n {
            assert!(
                (x[i] - want[i]).abs() < 1e-13,
                "row {i}: {} vs {}",
                x[i],
                want[i]
            );
        }
    }

    #[test]
    fn selected_inverse_matches_the_dense_inverse_inside_the_profile() {
        let n = 37;
        let (dense, mut sky) = ragged(n);
        let inv = dense.clone().try_inverse().unwrap();
        sky.factor().unwrap();
        let z = sky.inverse_in_profile();
        let mut checked = 0;
        for i in 0..n {
            for j in z.first_column(i)..=i {
                assert!(
                    (z.get(i, j) - inv[(i, j)]).abs() < 1e-14,
                    "({i},{j}): {} vs {}",
                    z.get(i, j),
                    inv[(i, j)]
                );
                checked += 1;
            }
        }
        assert_eq!(checked, z.profile_len());
        // And with rows whose profile reaches far back (the last rows start
        // at 0, as the wrap-around rows of a periodic spline do).
        let first: Vec<usize> = (0..n)
            .map(|i| if i + 3 >= n { 0 } else { i.saturating_sub(3) })
            .collect();
        let mut sky = SkylineCholesky::with_profile(first.clone());
        let mut dense = DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            for j in first[i]..i {
                let v = 0.3 * ((i + 2 * j) as f64).cos();
                dense[(i, j)] = v;
                dense[(j, i)] = v;
                sky.add(i, j, v);
            }
            dense[(i, i)] = 8.0;
            sky.add(i, i, 8.0);
        }
        let inv = dense.try_inverse().unwrap();
        sky.factor().unwrap();
        let z = sky.inverse_in_profile();
        for i in 0..n {
            for j in first[i]..=i {
                assert!((z.get(i, j) - inv[(i, j)]).abs() < 1e-14, "({i},{j})");
            }
        }
    }

    #[test]
    fn indefinite_matrix_names_the_failing_equation() {
        let mut sky = SkylineCholesky::with_profile(vec![0, 0, 1]);
        sky.add(0, 0, 1.0);
        sky.add(1, 0, 2.0);
        sky.add(1, 1, 1.0);
        sky.add(2, 2, 1.0);
        let e = sky.factor().unwrap_err();
        assert_eq!(e, NotPositiveDefinite { equation: 1 });
        assert!(e.to_string().contains("equation 1"));
    }
}
