//! Preconditioned conjugate gradients for the symmetric positive-definite
//! systems of the implicit steps (lattice and reference block), matrix-
//! free over 3-vector blocks, with a block-Jacobi (3×3) preconditioner and
//! nodes whose velocity is prescribed (left out of the solve).
use crate::model::vec3::M3;

use crate::model::lattice::V3;

/// Scratch vectors of one solver, kept between steps (no allocation in a
/// step).
#[derive(Clone, Debug, Default)]
pub struct PcgWork {
    r: Vec<V3>,
    z: Vec<V3>,
    p: Vec<V3>,
    ap: Vec<V3>,
}

/// Why a solve stopped short.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stalled {
    pub iterations: usize,
    pub relative_residual: f64,
}

fn dot(a: &[V3], b: &[V3]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x.dot(y)).sum()
}

/// Solves `A x = b` for the free components (`fixed[n][a]` 0), keeping
/// `x` of the fixed ones (`fixed[n][a]` 1) as given and starting the free ones from `x` (a warm
/// start). `apply(v, out)` writes `A v`; `precondition(r, z)` writes an
/// approximation of `A⁻¹ r` (symmetric positive definite; see
/// [`block_jacobi`]). Stops when `‖r‖ ≤ tol·‖b_free − A_fc x_c‖`.
/// Returns the iterations used.
#[allow(clippy::too_many_arguments)]
pub fn pcg(
    apply: &mut dyn FnMut(&[V3], &mut [V3]),
    precondition: &mut dyn FnMut(&[V3], &mut [V3]),
    fixed: &[V3],
    b: &[V3],
    x: &mut [V3],
    tol: f64,
    max_iter: usize,
    w: &mut PcgWork,
) -> Result<usize, Stalled> {
    let n = b.len();
    for v in [&mut w.r, &mut w.z, &mut w.p, &mut w.ap] {
        v.resize(n, V3::zeros());
    }
    // The right-hand side seen by the free nodes: b − A x with x's fixed
    // part; its norm (with x_free = 0) scales the tolerance.
    let free = |v: V3, fixed: &V3| v - v.component_mul(fixed);
    for ((p, xi), fi) in w.p.iter_mut().zip(x.iter()).zip(fixed) {
        *p = xi.component_mul(fi);
    }
    apply(&w.p, &mut w.ap);
    let scale = b
        .iter()
        .zip(&w.ap)
        .zip(fixed)
        .map(|((bi, ai), fi)| free(*bi - *ai, fi).norm_squared())
        .sum::<f64>()
        .sqrt();
    apply(x, &mut w.ap);
    for (((r, bi), ai), fi) in w.r.iter_mut().zip(b).zip(&w.ap).zip(fixed) {
        *r = free(*bi - *ai, fi);
    }
    if scale == 0.0 {
        // Nothing drives the free components: 0 solves it.
        for i in 0..n {
            x[i] = x[i].component_mul(&fixed[i]);
        }
        return Ok(0);
    }
    let target = tol * scale;
    if dot(&w.r, &w.r).sqrt() <= target {
        return Ok(0);
    }
    precondition(&w.r, &mut w.z);
    for ((z, p), fi) in w.z.iter_mut().zip(w.p.iter_mut()).zip(fixed) {
        *z = free(*z, fi);
        *p = *z;
    }
    let mut rz = dot(&w.r, &w.z);
    for it in 1..=max_iter {
        apply(&w.p, &mut w.ap);
        for (ap, fi) in w.ap.iter_mut().zip(fixed) {
            *ap = free(*ap, fi);
        }
        let pap = dot(&w.p, &w.ap);
        if !(pap.is_finite() && pap > 0.0) {
            return Err(Stalled {
                iterations: it,
                relative_residual: dot(&w.r, &w.r).sqrt() / scale,
            });
        }
        let alpha = rz / pap;
        for (xi, pi) in x.iter_mut().zip(&w.p) {
            *xi += alpha * *pi;
        }
        for (ri, ai) in w.r.iter_mut().zip(&w.ap) {
            *ri -= alpha * *ai;
        }
        let rn = dot(&w.r, &w.r).sqrt();
        if rn <= target {
            return Ok(it);
        }
        if !rn.is_finite() {
            break;
        }
        precondition(&w.r, &mut w.z);
        for (z, fi) in w.z.iter_mut().zip(fixed) {
            *z = free(*z, fi);
        }
        let rz_new = dot(&w.r, &w.z);
        let beta = rz_new / rz;
        rz = rz_new;
        for i in 0..n {
            w.p[i] = w.z[i] + beta * w.p[i];
        }
    }
    Err(Stalled {
        iterations: max_iter,
        relative_residual: dot(&w.r, &w.r).sqrt() / scale,
    })
}

/// The block-Jacobi preconditioner of inverse diagonal blocks `inv_diag`.
pub fn block_jacobi(inv_diag: &[M3]) -> impl FnMut(&[V3], &mut [V3]) + '_ {
    move |r: &[V3], z: &mut [V3]| {
        for ((zi, ri), d) in z.iter_mut().zip(r).zip(inv_diag) {
            *zi = *d * *ri;
        }
    }
}

/// The inverse of a symmetric positive 3×3 block, or of its diagonal when
/// it is singular.
pub fn invert_block(m: &M3) -> M3 {
    m.try_inverse().unwrap_or_else(|| {
        let d = m.diagonal();
        let inv = |v: f64| if v > 0.0 { 1.0 / v } else { 0.0 };
        M3::from_diagonal(V3::new(inv(d.x), inv(d.y), inv(d.z)))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pcg_solves_a_chain_with_a_fixed_end_as_a_dense_solve_does() {
        // A chain of 6 nodes with springs s between neighbours (along every
        // axis) and mass term m; node 0 fixed at x0.
        let (n, s, m) = (6, 50.0, 2.0);
        let mut apply = |v: &[V3], out: &mut [V3]| {
            for i in 0..n {
                out[i] = m * v[i];
            }
            for i in 0..n - 1 {
                let d = s * (v[i] - v[i + 1]);
                out[i] += d;
                out[i + 1] -= d;
            }
        };
        let diag: Vec<M3> = (0..n)
            .map(|i| {
                let deg = if i == 0 || i == n - 1 { 1.0 } else { 2.0 };
                invert_block(&(M3::identity() * (m + s * deg)))
            })
            .collect();
        let mut fixed = vec![V3::zeros(); n];
        fixed[0] = V3::repeat(1.0);
        let b: Vec<V3> = (0..n).map(|i| V3::new(i as f64, 1.0, -2.0)).collect();
        let mut x = vec![V3::zeros(); n];
        x[0] = V3::new(0.5, -0.5, 1.0);
        let mut w = PcgWork::default();
        let it = pcg(
            &mut apply,
            &mut block_jacobi(&diag),
            &fixed,
            &b,
            &mut x,
            1e-12,
            100,
            &mut w,
        )
        .unwrap();
        assert!(it <= n);
        // Dense reference, per axis.
        for a in 0..3 {
            let mut k = nalgebra::DMatrix::<f64>::zeros(n - 1, n - 1);
            let mut rhs = nalgebra::DVector::<f64>::zeros(n - 1);
            for i in 1..n {
                k[(i - 1, i - 1)] = m + s * if i == n - 1 { 1.0 } else { 2.0 };
                if i + 1 < n {
                    k[(i - 1, i)] = -s;
                    k[(i, i - 1)] = -s;
                }
                rhs[i - 1] = b[i][a];
            }
            rhs[0] += s * x[0][a];
            let sol = k.cholesky().unwrap().solve(&rhs);
            for i in 1..n {
                assert!((sol[i - 1] - x[i][a]).abs() < 1e-9);
            }
        }
        assert_eq!(x[0], V3::new(0.5, -0.5, 1.0));
    }
}
