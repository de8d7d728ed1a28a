//! The dense deformation field by linear shape functions over the
//! tetrahedra of the matches (Zhang §III-C, Eq. 9–11).
//!
//! Eq. 9 is the signed volume of a tetrahedron; Eq. 11 the shape function
//! `N_n = ◇(P with node n replaced by P) / ◇(P_i P_j P_k P_l)`; Eq. 10 the
//! displacement `u(x) = Σ N_n u_n`. The `N_n` sum to one and are linear in
//! `x`, so any affine field given at the nodes is reproduced exactly.
//!
//! The field is evaluated two ways: forward, at points of the initial
//! volume (`u(p)`, the measured deformation), and backward, to deform the
//! initial volume into the deformed one's frame for Eq. 12: each
//! tetrahedron is moved with its nodes (`x + u`), and a voxel `q` of the
//! deformed volume inside a moved tetrahedron takes the initial intensity
//! at `Σ N_n(q) x_n` — the exact inverse of the piecewise-linear map.
//! Voxels outside the tetrahedra (outside the matches' convex hull) are
//! left out and counted. A moved tetrahedron that turned inside out
//! (matches that cross) makes the map fold; such tetrahedra are counted
//! and still used, first come first served.
use super::volume::Volume;
use plant_common::fem::tet_volume;

/// Eq. 9–11: the shape functions of `tet` at `p`, `None` for a flat
/// tetrahedron.
pub fn shape_functions(tet: [[f64; 3]; 4], p: [f64; 3]) -> Option<[f64; 4]> {
    let v = tet_volume(tet);
    let scale: f64 = (1..4)
        .map(|k| (0..3).map(|a| (tet[k][a] - tet[0][a]).powi(2)).sum::<f64>())
        .fold(0.0, f64::max);
    if v.abs() <= 1e-12 * scale.powf(1.5) {
        return None;
    }
    Some(std::array::from_fn(|n| {
        let mut t = tet;
        t[n] = p;
        tet_volume(t) / v
    }))
}

/// A displacement field given at the nodes of tetrahedra.
#[derive(Clone, Debug, PartialEq)]
pub struct TetField {
    /// Node positions in the initial volume (mm).
    pub nodes_mm: Vec<[f64; 3]>,
    /// Displacement of each node (mm).
    pub displacement_mm: Vec<[f64; 3]>,
    /// Tetrahedra as node indices.
    pub tets: Vec<[usize; 4]>,
}

/// A field sampled at every voxel of a grid; `None` outside the
/// tetrahedra.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseField {
    /// Voxels of the grid.
    pub dims: [usize; 3],
    /// Spacing (mm).
    pub spacing_mm: [f64; 3],
    /// Displacement (mm) per voxel, x fastest.
    pub displacement_mm: Vec<Option<[f32; 3]>>,
}

impl DenseField {
    /// Number of voxels the field covers.
    pub fn covered(&self) -> usize {
        self.displacement_mm.iter().filter(|d| d.is_some()).count()
    }
}

/// Calls `f(voxel index, tet, shape functions)` for every voxel centre of
/// the grid inside a tetrahedron (given by its node positions), each voxel
/// once (the first tetrahedron that holds it).
fn rasterise(
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    tets: impl Iterator<Item = (usize, [[f64; 3]; 4])>,
    mut f: impl FnMut(usize, usize, [f64; 4]),
) {
    let mut done = vec![false; dims[0] * dims[1] * dims[2]];
    for (k, t) in tets {
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        let mut empty = false;
        for a in 0..3 {
            let mn = t.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min) / spacing_mm[a];
            let mx = t.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max) / spacing_mm[a];
            let l = mn.ceil().max(0.0);
            let h = mx.floor().min((dims[a] - 1) as f64);
            if l.is_nan() || h.is_nan() || l > h {
                empty = true;
                break;
            }
            lo[a] = l as usize;
            hi[a] = h as usize;
        }
        if empty {
            continue;
        }
        // Shape functions are affine: N(p) = e₀ + G (p − p₀) with p₀ the
        // first node (Eq. 11 evaluated once per axis, not per voxel).
        let p0 = t[0];
        let mut grad = [[0.0; 4]; 3];
        let mut flat = false;
        for (a, g) in grad.iter_mut().enumerate() {
            let mut q = p0;
            q[a] += 1.0;
            match shape_functions(t, q) {
                Some(n) => *g = [n[0] - 1.0, n[1], n[2], n[3]],
                None => flat = true,
            }
        }
        if flat {
            continue;
        }
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let i = x + dims[0] * (y + dims[1] * z);
                    if done[i] {
                        continue;
                    }
                    let d = [
                        x as f64 * spacing_mm[0] - p0[0],
                        y as f64 * spacing_mm[1] - p0[1],
                        z as f64 * spacing_mm[2] - p0[2],
                    ];
                    let n: [f64; 4] = std::array::from_fn(|m| {
                        f64::from(u8::from(m == 0))
                            + grad[0][m] * d[0]
                            + grad[1][m] * d[1]
                            + grad[2][m] * d[2]
                    });
                    if n.iter().all(|&w| w >= -1e-9) {
                        done[i] = true;
                        f(i, k, n);
                    }
                }
            }
        }
    }
}

impl TetField {
    /// Eq. 10 at `p` (mm), searching the tetrahedra (for a few points; use
    /// [`TetField::dense`] for a grid). `None` outside them.
    pub fn at(&self, p: [f64; 3]) -> Option<[f64; 3]> {
        self.tets.iter().find_map(|t| {
            let n = shape_functions(t.map(|i| self.nodes_mm[i]), p)?;
            if n.iter().all(|&w| w >= -1e-9) {
                Some(std::array::from_fn(|a| {
                    (0..4).map(|k| n[k] * self.displacement_mm[t[k]][a]).sum()
                }))
            } else {
                None
            }
        })
    }

    /// Eq. 10 at every voxel of a grid of the initial volume.
    pub fn dense(&self, dims: [usize; 3], spacing_mm: [f64; 3]) -> DenseField {
        let mut out = vec![None; dims[0] * dims[1] * dims[2]];
        let tets = self
            .tets
            .iter()
            .enumerate()
            .map(|(k, t)| (k, t.map(|i| self.nodes_mm[i])));
        rasterise(dims, spacing_mm, tets, |i, k, n| {
            let t = self.tets[k];
            out[i] = Some(std::array::from_fn(|a| {
                (0..4)
                    .map(|m| n[m] * self.displacement_mm[t[m]][a])
                    .sum::<f64>() as f32
            }));
        });
        DenseField {
            dims,
            spacing_mm,
            displacement_mm: out,
        }
    }

    /// Number of tetrahedra that the displacement turns inside out.
    pub fn folded_tets(&self) -> usize {
        self.tets
            .iter()
            .filter(|t| {
                let before = tet_volume(t.map(|i| self.nodes_mm[i]));
                let after = tet_volume(t.map(|i| self.moved(i)));
                before * after <= 0.0
            })
            .count()
    }

    fn moved(&self, i: usize) -> [f64; 3] {
        std::array::from_fn(|a| self.nodes_mm[i][a] + self.displacement_mm[i][a])
    }

    /// The initial volume deformed by the field into the deformed volume's
    /// frame (same grid as `initial`), with the mask of voxels it covers.
    pub fn warp(&self, initial: &Volume) -> (Volume, Vec<bool>) {
        let dims = initial.dims();
        let sp = initial.spacing_mm();
        let mut out = Volume::zeros(dims, sp);
        let mut mask = vec![false; out.data().len()];
        let tets = self
            .tets
            .iter()
            .enumerate()
            .map(|(k, t)| (k, t.map(|i| self.moved(i))));
        let mut values = Vec::new();
        rasterise(dims, sp, tets, |i, k, n| {
            let t = self.tets[k];
            let p: [f64; 3] =
                std::array::from_fn(|a| (0..4).map(|m| n[m] * self.nodes_mm[t[m]][a]).sum());
            if let Some(v) = initial.sample_mm(p) {
                values.push((i, v));
            }
        });
        for (i, v) in values {
            out.data_mut()[i] = v;
            mask[i] = true;
        }
        (out, mask)
    }
}

/// Eq. 12: the root-mean-square intensity difference of two volumes over
/// the voxels of `mask` in slices `z_range` (the paper: slices 10–50 of
/// 57, where resampling leaves no slice out of bounds). Returns the RMS and
/// the number of voxels; `None` when no voxel qualifies.
pub fn rms_difference(
    actual: &Volume,
    computed: &Volume,
    mask: &[bool],
    z_range: std::ops::RangeInclusive<usize>,
) -> Option<(f64, usize)> {
    let [nx, ny, nz] = actual.dims();
    if computed.dims() != actual.dims() || mask.len() != nx * ny * nz {
        return None;
    }
    let mut sum = 0.0;
    let mut count = 0usize;
    for z in z_range.filter(|&z| z < nz) {
        for y in 0..ny {
            for x in 0..nx {
                let i = actual.index(x, y, z);
                if mask[i] {
                    let d = f64::from(actual.data()[i]) - f64::from(computed.data()[i]);
                    sum += d * d;
                    count += 1;
                }
            }
        }
    }
    (count > 0).then(|| ((sum / count as f64).sqrt(), count))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn affine(p: [f64; 3]) -> [f64; 3] {
        [
            0.3 + 0.02 * p[0] - 0.05 * p[1] + 0.01 * p[2],
            -1.2 + 0.04 * p[0] + 0.03 * p[1] - 0.02 * p[2],
            0.7 - 0.01 * p[0] + 0.015 * p[1] + 0.06 * p[2],
        ]
    }

    fn field() -> TetField {
        // A box split into tetrahedra by the Delaunay code, with an affine
        // field at the nodes.
        let mut nodes = Vec::new();
        for k in 0..3 {
            for j in 0..4 {
                for i in 0..4 {
                    let w = ((i * 7 + j * 3 + k * 5) % 11) as f64 * 0.13;
                    nodes.push([
                        i as f64 * 5.0 + w,
                        j as f64 * 4.0 - w,
                        k as f64 * 3.0 + 0.5 * w,
                    ]);
                }
            }
        }
        let tets = crate::field::model::delaunay::tetrahedralise(&nodes, 1)
            .unwrap()
            .tets;
        TetField {
            displacement_mm: nodes.iter().map(|p| affine(*p)).collect(),
            nodes_mm: nodes,
            tets,
        }
    }

    #[test]
    fn shape_functions_reproduce_any_affine_field_exactly() {
        let f = field();
        let mut inside = 0;
        for s in 0..200 {
            let p = [
                (s as f64 * 0.731) % 15.0,
                (s as f64 * 0.377) % 12.0,
                (s as f64 * 0.193) % 6.0,
            ];
            if let Some(u) = f.at(p) {
                inside += 1;
                let want = affine(p);
                for a in 0..3 {
                    assert!((u[a] - want[a]).abs() < 1e-12, "{p:?}: {u:?} vs {want:?}");
                }
            }
        }
        assert!(inside > 100, "{inside}");
        // On a grid too, and the partition of unity.
        let dense = f.dense([16, 13, 7], [1.0, 1.0, 1.0]);
        assert!(dense.covered() > 600);
        for (i, d) in dense.displacement_mm.iter().enumerate() {
            if let Some(u) = d {
                let p = [(i % 16) as f64, ((i / 16) % 13) as f64, (i / 208) as f64];
                let want = affine(p);
                for a in 0..3 {
                    assert!((f64::from(u[a]) - want[a]).abs() < 1e-5, "{p:?}");
                }
            }
        }
        let t = f.tets[3].map(|i| f.nodes_mm[i]);
        let n = shape_functions(t, [3.3, 2.2, 1.1]).unwrap();
        assert!((n.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn warping_by_a_translation_moves_the_volume() {
        // A constant field of +2 voxels in x: the warped volume at q is the
        // initial at q − 2.
        let dims = [20, 10, 6];
        let data = (0..20 * 10 * 6)
            .map(|i| ((i % 20) as f32).powi(2))
            .collect();
        let vol = Volume::new(dims, [1.0; 3], data, "ramp").unwrap();
        let mut f = field();
        for d in &mut f.displacement_mm {
            *d = [2.0, 0.0, 0.0];
        }
        let (w, mask) = f.warp(&vol);
        let mut checked = 0;
        for z in 0..6 {
            for y in 0..10 {
                for x in 3..18 {
                    let i = w.index(x, y, z);
                    if mask[i] {
                        checked += 1;
                        assert!((w.data()[i] - ((x - 2) as f32).powi(2)).abs() < 1e-3);
                    }
                }
            }
        }
        assert!(checked > 200);
        assert_eq!(f.folded_tets(), 0);
        let (rms, n) = rms_difference(&vol, &vol, &mask, 0..=5).unwrap();
        assert_eq!(rms, 0.0);
        assert!(n == mask.iter().filter(|m| **m).count());
    }
}
