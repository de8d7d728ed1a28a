//! 3-D Harris feature points (Zhang §II-A, Eq. 1–3).
//!
//! The gradient `(I_x, I_y, I_z)` comes from central differences (the
//! "gradient template") of the volume after a light Gaussian pre-smoothing,
//! in physical units (per mm, so anisotropic voxels do not bias the
//! tensor); the auto-correlation matrix `M` of Eq. 1 is the Gaussian-
//! weighted (`G ⊗`) sum of the gradient's outer products. Its response is
//! either Eq. 3, `R = det M / trace M` (the paper's choice "to avoid the
//! influence of an improper k"), or Eq. 2 as printed,
//! `R = det M − k (trace M)²` with Harris's k = 0.04–0.06. Eq. 2 mixes
//! powers (det ~ |∇I|⁶, trace² ~ |∇I|⁴), so its ranking of points changes
//! with the image's contrast; Eq. 3 only scales, which is why it is the
//! default here.
//!
//! Feature points are the strongest strict local maxima of `R` over the
//! 26-neighbourhood, away from the border by the match cube's half size
//! (so every point has a whole cube to correlate), refined to sub-voxel
//! position by a parabola through the response along each axis. The paper
//! keeps "voxels whose R_F exceeds a threshold"; its Table I fixes the
//! count instead (1000 and 5000 points), and so do we.
//!
//! Left out: scale selection (one derivative and one integration scale).
use crate::error::{check_positive, check_range, Result, TissueError};
use crate::field::model::volume::{blur_axis, Volume};
use rayon::prelude::*;

/// The response function of a structure tensor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Response {
    /// Eq. 3: det M / trace M.
    DetOverTrace,
    /// Eq. 2 as printed: det M − k (trace M)², k = 0.04–0.06 (Harris).
    DetMinusKTrace2 {
        /// The empirical constant k.
        k: f64,
    },
}

impl Response {
    fn of(&self, m: [f64; 6]) -> f64 {
        let [xx, yy, zz, xy, xz, yz] = m;
        let det = xx * (yy * zz - yz * yz) - xy * (xy * zz - yz * xz) + xz * (xy * yz - yy * xz);
        let tr = xx + yy + zz;
        match *self {
            Response::DetOverTrace => {
                if tr > 1e-300 {
                    det / tr
                } else {
                    0.0
                }
            }
            Response::DetMinusKTrace2 { k } => det - k * tr * tr,
        }
    }
}

/// Parameters of the detector.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HarrisParams {
    /// Pre-smoothing σ (mm) before the gradient template (noise).
    pub derivative_sigma_mm: f64,
    /// σ (mm) of the Gaussian template G of Eq. 1.
    pub integration_sigma_mm: f64,
    /// Response function (Eq. 3 by default).
    pub response: Response,
    /// Points keep this many voxels from every border (x, y, z): the match
    /// cube's half size (9 × 9 × 3 → 4, 4, 1) plus one for the gradient.
    pub margin_vox: [usize; 3],
}

impl Default for HarrisParams {
    /// σ_d = 0.6 mm, σ_i = 1.0 mm (estimates: about one in-plane voxel
    /// of the paper's volumes each), Eq. 3, margins of the 9 × 9 × 3
    /// match cube (L571) plus one.
    fn default() -> Self {
        HarrisParams {
            derivative_sigma_mm: 0.6,
            integration_sigma_mm: 1.0,
            response: Response::DetOverTrace,
            margin_vox: [5, 5, 2],
        }
    }
}

impl HarrisParams {
    fn validate(&self) -> Result<()> {
        check_range(
            "derivative_sigma_mm",
            self.derivative_sigma_mm,
            0.0,
            100.0,
            "must be 0 to 100 mm",
        )?;
        check_positive("integration_sigma_mm", self.integration_sigma_mm)?;
        if let Response::DetMinusKTrace2 { k } = self.response {
            check_range("k", k, 0.0, 1.0, "must be 0 to 1 (Harris: 0.04 to 0.06)")?;
        }
        Ok(())
    }
}

/// A feature point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FeaturePoint {
    /// Sub-voxel position (mm).
    pub position_mm: [f64; 3],
    /// The voxel of the response maximum.
    pub voxel: [usize; 3],
    /// Response R at that voxel.
    pub response: f64,
}

/// The response R of every voxel (x fastest).
pub fn response_volume(vol: &Volume, params: &HarrisParams) -> Result<Vec<f64>> {
    params.validate()?;
    let dims = vol.dims();
    let sp = vol.spacing_mm();
    let smooth = if params.derivative_sigma_mm > 0.0 {
        vol.gaussian_blur([params.derivative_sigma_mm; 3])
    } else {
        vol.clone()
    };
    let [nx, ny, nz] = dims;
    let n = nx * ny * nz;
    // Products of the gradient: xx, yy, zz, xy, xz, yz.
    let mut prod: Vec<Vec<f32>> = vec![vec![0.0; n]; 6];
    let d = smooth.data();
    let grad = |x: usize, y: usize, z: usize| -> [f64; 3] {
        let c = |a: usize, lo: usize, hi: usize, i_lo: usize, i_hi: usize| {
            if hi == lo {
                0.0
            } else {
                (f64::from(d[i_hi]) - f64::from(d[i_lo])) / ((hi - lo) as f64 * sp[a])
            }
        };
        let idx = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
        let (x0, x1) = (x.saturating_sub(1), (x + 1).min(nx - 1));
        let (y0, y1) = (y.saturating_sub(1), (y + 1).min(ny - 1));
        let (z0, z1) = (z.saturating_sub(1), (z + 1).min(nz - 1));
        [
            c(0, x0, x1, idx(x0, y, z), idx(x1, y, z)),
            c(1, y0, y1, idx(x, y0, z), idx(x, y1, z)),
            c(2, z0, z1, idx(x, y, z0), idx(x, y, z1)),
        ]
    };
    #[allow(clippy::needless_range_loop)] // i is the voxel and indexes six arrays
    for i in 0..n {
        let x = i % nx;
        let y = (i / nx) % ny;
        let z = i / (nx * ny);
        let g = grad(x, y, z);
        let p = [
            g[0] * g[0],
            g[1] * g[1],
            g[2] * g[2],
            g[0] * g[1],
            g[0] * g[2],
            g[1] * g[2],
        ];
        for (k, v) in p.iter().enumerate() {
            prod[k][i] = *v as f32;
        }
    }
    prod.par_iter_mut().for_each(|p| {
        for (a, &s) in sp.iter().enumerate() {
            if dims[a] > 1 {
                blur_axis(p, dims, a, params.integration_sigma_mm / s);
            }
        }
    });
    Ok((0..n)
        .into_par_iter()
        .map(|i| {
            params
                .response
                .of(std::array::from_fn(|k| f64::from(prod[k][i])))
        })
        .collect())
}

/// The `count` strongest feature points of `vol` (fewer if the volume has
/// fewer local maxima with a positive response), strongest first.
pub fn detect(vol: &Volume, params: &HarrisParams, count: usize) -> Result<Vec<FeaturePoint>> {
    let r = response_volume(vol, params)?;
    let [nx, ny, nz] = vol.dims();
    let m = params.margin_vox;
    if nx <= 2 * m[0] || ny <= 2 * m[1] || nz <= 2 * m[2] {
        return Err(TissueError::VolumeShape {
            what: "volume".into(),
            reason: format!(
                "{nx}×{ny}×{nz} voxels leave no room for feature points inside margins of {}, {}, {} voxels",
                m[0], m[1], m[2]
            ),
        });
    }
    let idx = |x: usize, y: usize, z: usize| x + nx * (y + ny * z);
    let mut maxima: Vec<(f64, [usize; 3])> = (m[2]..nz - m[2])
        .into_par_iter()
        .flat_map_iter(|z| {
            let r = &r;
            (m[1]..ny - m[1]).flat_map(move |y| {
                (m[0]..nx - m[0]).filter_map(move |x| {
                    let v = r[idx(x, y, z)];
                    if v.is_nan() || v <= 0.0 {
                        return None;
                    }
                    for dz in -1i64..=1 {
                        for dy in -1i64..=1 {
                            for dx in -1i64..=1 {
                                if dx == 0 && dy == 0 && dz == 0 {
                                    continue;
                                }
                                let (qx, qy, qz) = (x as i64 + dx, y as i64 + dy, z as i64 + dz);
                                let w = r[idx(qx as usize, qy as usize, qz as usize)];
                                // Strict maximum; ties go to the earlier voxel.
                                let earlier = (dz, dy, dx) < (0, 0, 0);
                                if w > v || (w == v && earlier) {
                                    return None;
                                }
                            }
                        }
                    }
                    Some((v, [x, y, z]))
                })
            })
        })
        .collect();
    maxima.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    maxima.truncate(count);
    let sp = vol.spacing_mm();
    Ok(maxima
        .into_iter()
        .map(|(v, [x, y, z])| {
            let offset = |lo: f64, hi: f64| {
                let den = lo - 2.0 * v + hi;
                if den < 0.0 {
                    (0.5 * (lo - hi) / den).clamp(-0.5, 0.5)
                } else {
                    0.0
                }
            };
            let o = [
                offset(r[idx(x - 1, y, z)], r[idx(x + 1, y, z)]),
                offset(r[idx(x, y - 1, z)], r[idx(x, y + 1, z)]),
                offset(r[idx(x, y, z - 1)], r[idx(x, y, z + 1)]),
            ];
            FeaturePoint {
                position_mm: [
                    (x as f64 + o[0]) * sp[0],
                    (y as f64 + o[1]) * sp[1],
                    (z as f64 + o[2]) * sp[2],
                ],
                voxel: [x, y, z],
                response: v,
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cube_corner_responds_and_a_flat_face_does_not() {
        // A bright box in a dark volume: Eq. 3's response is largest near
        // its 8 corners; along a face (one gradient direction) det M ≈ 0.
        let dims = [30, 30, 30];
        let mut v = Volume::zeros(dims, [1.0; 3]);
        for z in 10..20 {
            for y in 10..20 {
                for x in 10..20 {
                    let i = v.index(x, y, z);
                    v.data_mut()[i] = 100.0;
                }
            }
        }
        let p = HarrisParams {
            margin_vox: [3, 3, 3],
            ..HarrisParams::default()
        };
        let pts = detect(&v, &p, 8).unwrap();
        assert_eq!(pts.len(), 8);
        for f in &pts {
            // Each is within 2 voxels of a corner at 9.5 or 19.5 (Harris
            // corners sit a little inside, by about the integration σ).
            for c in f.position_mm {
                let near = (c - 9.5).abs().min((c - 19.5).abs());
                assert!(near < 2.0, "{f:?}");
            }
        }
        let r = response_volume(&v, &p).unwrap();
        let face = r[v.index(15, 15, 10)];
        assert!(
            face.abs() < 1e-2 * pts[0].response,
            "face {face} vs corner {}",
            pts[0].response
        );
    }

    #[test]
    fn eq2_ranking_depends_on_contrast_and_eq3_does_not() {
        // Scaling intensities by c scales Eq. 3 by c² (ranking kept); Eq. 2
        // is not homogeneous, so with k > 0 its values change shape.
        let m = [3.0, 2.0, 1.0, 0.5, 0.2, 0.1];
        let s = |c: f64| m.map(|v| v * c * c);
        let r3 = Response::DetOverTrace;
        assert!((r3.of(s(10.0)) / r3.of(m) - 1e4).abs() < 1e-6);
        let r2 = Response::DetMinusKTrace2 { k: 0.05 };
        let ratio = r2.of(s(10.0)) / r2.of(m);
        assert!(
            (ratio - 1e6).abs() > 1.0,
            "Eq. 2 scaled like a power: {ratio}"
        );
    }
}
