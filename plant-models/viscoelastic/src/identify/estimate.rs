//! From 1D trial fits to per-vertex 3D parameters (seed 002 §4.1–4.2):
//! the damping tensor by least squares `P Pᵀ B_iᵀ = (Q Pᵀ)_iᵀ` with a damped
//! SVD [Han94] (vertex abandoned when singular), the Rayleigh coefficient
//! (Eq. 13), the stiffness multipliers and ratio, and column spreading.
//!
//! Note on Eq. 13: the seed prints `b = Σ K_ij B_ij / Σ K_ij`, but the
//! minimiser of its own `r²(b) = Σ (b K_ij − B_ij)²` is
//! `b = Σ K_ij B_ij / Σ K_ij²` (the printed form is not even dimensionally
//! consistent); we implement the least-squares solution and test that it
//! recovers the b that generated B. The same formula gives k1 and k2
//! (`P' = K P`, `Q' = [k_l,n f̂_n]`).
//!
//! Left out: combining speeds (the seed fits them separately; so do we:
//! estimate per (vertex, speed) and choose which to spread).
use crate::error::{Result, VeError};
use crate::fit::TrialFit;
use crate::measure::Trial;
use crate::object::ColumnParams;
use crate::{Mat3, Vec3};
use plant_common::three_element::RayleighColumn;

/// Damping of the DSVD filter, relative to the largest singular value of
/// P Pᵀ (estimate: small enough to leave a well-conditioned system within
/// 1e-6 relative, large enough to tame a nearly singular one).
pub const DSVD_DAMPING_REL: f64 = 1.0e-3;
/// Smallest/largest singular value of P Pᵀ below which the vertex is
/// abandoned as singular (seed §4.1: "insufficient measurements").
pub const SINGULAR_RATIO: f64 = 1.0e-10;
/// k1 below this (N/m) counts as zero (seed §4.1: then no damping and an
/// arbitrary ratio). Estimate: far below any stiffness of the object.
pub const K1_ZERO_N_PER_M: f64 = 1.0e-9;

/// Damping tensor B minimising `Σ |B û_n − b_n f̂_n|²` (seed §4.1) with the
/// DSVD filter `σ/(σ² + λ²)`, `λ = damping_rel · σ_max`. `None` when P Pᵀ
/// is singular (fewer than three independent directions).
pub fn damping_tensor(
    directions: &[[f64; 3]],
    force_directions: &[[f64; 3]],
    b_n_s_per_m: &[f64],
    damping_rel: f64,
) -> Result<Option<Mat3>> {
    let n = directions.len();
    if force_directions.len() != n || b_n_s_per_m.len() != n {
        return Err(VeError::LengthMismatch {
            what: "trial directions / forces / dampings",
            got: force_directions.len().min(b_n_s_per_m.len()),
            expected: n,
        });
    }
    let mut ppt = Mat3::zeros();
    let mut qpt = Mat3::zeros();
    for k in 0..n {
        let u = Vec3::from(directions[k]);
        let q = Vec3::from(force_directions[k]) * b_n_s_per_m[k];
        ppt += u * u.transpose();
        qpt += q * u.transpose();
    }
    let svd = ppt.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Ok(None);
    };
    let s = svd.singular_values;
    let smax = s.max();
    if smax.is_nan() || smax <= 0.0 || s.min() / smax < SINGULAR_RATIO {
        return Ok(None);
    }
    let lambda = damping_rel * smax;
    let filt = Mat3::from_diagonal(&s.map(|x| x / (x * x + lambda * lambda)));
    let pinv = vt.transpose() * filt * u.transpose();
    // Rows: B_i = (Q Pᵀ)_i (P Pᵀ)⁻¹, i.e. B = Q Pᵀ (P Pᵀ)⁻¹ (P Pᵀ symmetric).
    Ok(Some(qpt * pinv))
}

/// Least-squares scalar `b` minimising `Σ (b K_ij − B_ij)²` (Eq. 13, see
/// the module note on its denominator).
pub fn rayleigh_coefficient(stiffness: &Mat3, damping: &Mat3) -> f64 {
    let kb = stiffness.component_mul(damping).sum();
    let kk = stiffness.norm_squared();
    if kk > 0.0 {
        kb / kk
    } else {
        0.0
    }
}

/// Least-squares multiplier `k_l` minimising `Σ |k_l K û_n − k_l,n f̂_n|²`
/// (seed §4.1, solved like Eq. 13).
pub fn stiffness_multiplier(
    stiffness: &Mat3,
    directions: &[[f64; 3]],
    force_directions: &[[f64; 3]],
    k_n: &[f64],
) -> f64 {
    let (mut pq, mut pp) = (0.0, 0.0);
    for ((u, f), k) in directions.iter().zip(force_directions).zip(k_n) {
        let p = stiffness * Vec3::from(*u);
        let q = Vec3::from(*f) * *k;
        pq += p.dot(&q);
        pp += p.dot(&p);
    }
    if pp > 0.0 {
        pq / pp
    } else {
        0.0
    }
}

/// Estimated parameters of one vertex at one probe speed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexEstimate {
    /// DGFM index.
    pub vertex: usize,
    /// Probe speed of the trials used (m/s).
    pub speed_m_per_s: f64,
    /// Damping tensor B (N·s/m), `None` if abandoned (singular P Pᵀ).
    pub damping_tensor_n_s_per_m: Option<Mat3>,
    /// Rayleigh coefficient b (s), Eq. 13 (0 when abandoned or k1 = 0).
    pub rayleigh_b_s: f64,
    /// Multiplier k1 of K.
    pub k1: f64,
    /// Multiplier k2 of K.
    pub k2: f64,
    /// Stiffness ratio r = k2/k1 (1, arbitrary, when k1 = 0).
    pub ratio: f64,
}

/// Estimates one vertex from its trials at one speed and their fits, given
/// its stiffness tensor K_ii (N/m).
pub fn estimate_vertex(
    stiffness: &Mat3,
    trials: &[&Trial],
    fits: &[TrialFit],
) -> Result<VertexEstimate> {
    let Some(first) = trials.first() else {
        return Err(VeError::InvalidParameter {
            name: "trials",
            value: 0.0,
            reason: "a vertex estimate needs trials",
        });
    };
    if fits.len() != trials.len() {
        return Err(VeError::LengthMismatch {
            what: "fits",
            got: fits.len(),
            expected: trials.len(),
        });
    }
    let dirs: Vec<[f64; 3]> = trials.iter().map(|t| t.direction).collect();
    let fdirs: Vec<[f64; 3]> = trials.iter().map(|t| t.force_direction).collect();
    let b_n: Vec<f64> = fits.iter().map(|f| f.b_n_s_per_m).collect();
    let k1_n: Vec<f64> = fits.iter().map(|f| f.k1_n_per_m).collect();
    let k2_n: Vec<f64> = fits.iter().map(|f| f.k2_n_per_m).collect();
    let k1 = stiffness_multiplier(stiffness, &dirs, &fdirs, &k1_n);
    let k2 = stiffness_multiplier(stiffness, &dirs, &fdirs, &k2_n);
    let mut tensor = damping_tensor(&dirs, &fdirs, &b_n, DSVD_DAMPING_REL)?;
    let (mut b, ratio) = if k1 > K1_ZERO_N_PER_M && k2 > 0.0 {
        (
            tensor
                .map(|t| rayleigh_coefficient(stiffness, &t))
                .unwrap_or(0.0),
            k2 / k1,
        )
    } else {
        tensor = tensor.map(|_| Mat3::zeros());
        (0.0, 1.0)
    };
    if b.is_nan() || b < 0.0 {
        b = 0.0; // a negative Rayleigh fit means no usable damping
    }
    Ok(VertexEstimate {
        vertex: first.vertex,
        speed_m_per_s: first.speed_m_per_s,
        damping_tensor_n_s_per_m: tensor,
        rayleigh_b_s: b,
        k1,
        k2,
        ratio,
    })
}

/// Groups trials by (vertex, speed) and estimates each group.
pub fn estimate_all(
    dgfm: &crate::dgfm::Dgfm,
    trials: &[Trial],
    fits: &[Result<TrialFit>],
) -> Result<Vec<VertexEstimate>> {
    let mut groups: Vec<((usize, u64), Vec<usize>)> = Vec::new();
    for (k, t) in trials.iter().enumerate() {
        if fits.get(k).is_none_or(|f| f.is_err()) {
            continue; // a failed fit drops only that trial
        }
        let key = (t.vertex, t.speed_m_per_s.to_bits());
        match groups.iter_mut().find(|(g, _)| *g == key) {
            Some((_, v)) => v.push(k),
            None => groups.push((key, vec![k])),
        }
    }
    groups
        .iter()
        .map(|((vertex, _), idx)| {
            let k = dgfm
                .stiffness(*vertex, *vertex)
                .ok_or(VeError::VertexNotInTractionSet {
                    vertex: *vertex,
                    n: dgfm.len(),
                })?;
            let ts: Vec<&Trial> = idx.iter().map(|&i| &trials[i]).collect();
            let fs: Vec<TrialFit> = idx
                .iter()
                .filter_map(|&i| fits[i].as_ref().ok().copied())
                .collect();
            estimate_vertex(&k, &ts, &fs)
        })
        .collect()
}

/// Column spreading (seed §4.2): every column k measured gets its vertex's
/// parameters down the whole column; unmeasured (or abandoned) columns get
/// `default_ratio` and no damping (the seed's k1 = 0 rule: elastic only).
/// `tensor` chooses general damping tensors instead of Rayleigh.
pub fn spread_columns(
    n: usize,
    estimates: &[VertexEstimate],
    default_ratio: f64,
    tensor: bool,
) -> Result<ColumnParams> {
    let mut ratios = vec![default_ratio; n];
    let mut b = vec![0.0; n];
    let mut bt = vec![Mat3::zeros(); n];
    for e in estimates {
        if e.vertex >= n {
            return Err(VeError::VertexNotInTractionSet {
                vertex: e.vertex,
                n,
            });
        }
        if let Some(t) = e.damping_tensor_n_s_per_m {
            ratios[e.vertex] = e.ratio;
            b[e.vertex] = e.rayleigh_b_s;
            bt[e.vertex] = t;
        }
    }
    if tensor {
        Ok(ColumnParams::Tensor {
            ratios,
            damping_n_s_per_m: bt,
        })
    } else {
        Ok(ColumnParams::Rayleigh(
            ratios
                .iter()
                .zip(&b)
                .map(|(&r, &b)| RayleighColumn::new(r, b).map_err(VeError::from))
                .collect::<Result<_>>()?,
        ))
    }
}
