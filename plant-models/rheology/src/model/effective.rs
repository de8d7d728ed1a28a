//! The lattice as a continuum: its effective stiffness tensor, Young's
//! modulus and Poisson ratio as functions of the element constants and the
//! voxel's shape, and the per-class scaling that makes them independent of
//! the voxel's aspect ratio (issue 29; derivation in the crate README,
//! "Effective stiffness of the lattice").
//!
//! Under a homogeneous strain ε every mass of the grid (and every voxel
//! centre) is a centre of inversion of the structure, so the affine
//! displacement is an equilibrium of the infinite lattice; for a diagonal
//! ε it is also the exact equilibrium of a finite block loaded by the
//! stress times each mass's tributary area, because every voxel's corner
//! forces under a diagonal strain are σ_ii·(face area)/4 (mirror symmetry
//! and virtual work). An element along d with spring k stores
//! ½·k·(d·ε·d/|d|)², so a voxel of volume V = h_x·h_y·h_z gives
//!
//! ```text
//!   C_ijkl = (1/V) · Σ_elements k · d_i d_j d_k d_l / |d|²
//! ```
//!
//! (central forces: C_iijj = C_ijij, the Cauchy relation). Every element of
//! one class has k = (K/a)·g, c1 = (C1/a)·g, c2 = (C2/(1−a))·g with g a
//! length (m) per element family (3 edge directions, 3 face-diagonal
//! families, the body diagonals), so the lattice's damping tensors are the
//! same expression with C1/a and C2/(1−a) in place of K/a.
//!
//! On a cubic voxel with g = h for every element (the paper's lattice) the
//! sum is, in units of K/a: C11 = 4 + 4 + 4/3 = 28/3 (edges, face
//! diagonals, body diagonals) and C12 = C44 = 2 + 4/3 = 10/3, so under
//! uniaxial stress
//!
//! ```text
//!   E = (C11 − C12)(C11 + 2 C12)/(C11 + C12) = (144/19)·K/a ≈ 7.58 K/a,
//!   ν = C12/(C11 + C12) = 5/19 ≈ 0.263.
//! ```
//!
//! With the one g = geometric mean of the spacings on every element (the
//! lattice before issue 29), a non-cubic voxel changes the tensor: a
//! 1.43 × 1 × 1.43 cm voxel is 0.50× as stiff vertically, 1.25 × 1.5 ×
//! 0.83 cm 2.1×. [`class_factors_m`] instead picks the seven g so that the
//! tensor is the cubic one for any voxel shape where positive constants can
//! give it; where none can (voxels far from cubic) the lattice is refused.
use crate::error::{bad_setting, Result};
use crate::model::contact::{ContactParams, Contacts};
use crate::model::lattice::{Lattice, V3};
use crate::model::params::{ElementParams, LatticeParams, PA_PER_GF_PER_CM2};
use crate::model::sim::{LatticeSim, NodeDrive, SimSettings};

/// C11 of the cubic lattice, in units of K/a.
pub const CUBIC_C11: f64 = 28.0 / 3.0;
/// C12 = C44 of the cubic lattice, in units of K/a.
pub const CUBIC_C12: f64 = 10.0 / 3.0;
/// E/(K/a) of the lattice: 144/19.
pub const YOUNG_PER_K_OVER_A: f64 = 144.0 / 19.0;
/// ν of the lattice: 5/19.
pub const POISSON: f64 = 5.0 / 19.0;

/// The element families of a voxel by the axes they span (bit 0 x, bit 1
/// y, bit 2 z): 1, 2, 4 edges; 3, 5, 6 face diagonals; 7 body diagonals.
/// A voxel has 4 elements of each family.
pub const FAMILIES: [usize; 7] = [1, 2, 4, 3, 5, 6, 7];

/// The span mask of the element from voxel corner `a` to corner `b`
/// (corner bits: 1 x, 2 y, 4 z).
pub fn family_of(a: usize, b: usize) -> usize {
    a ^ b
}

/// The element lengths g (m) per family (indexed by span mask; index 0
/// unused) that give a voxel of `spacing_m` the cubic lattice's stiffness
/// tensor (C11 = 28/3, C12 = C44 = 10/3 in units of K/a). Equal spacings
/// give g = h for every family (the paper's lattice). The family lengths
/// are linear in the body diagonals' g; of the values that keep every
/// family positive, the one that maximises the smallest is taken (for a
/// cube: all equal). Refused, naming `grid`, when no positive choice
/// exists: the face diagonals' shear coupling then drags more normal
/// stiffness with it than the cubic tensor has.
pub fn class_factors_m(spacing_m: [f64; 3]) -> Result<[f64; 8]> {
    let h = spacing_m;
    let mean = (h[0] * h[1] * h[2]).cbrt();
    if h.iter().all(|&x| (x - mean).abs() <= 1e-12 * mean) {
        return Ok([mean; 8]);
    }
    // Each family's g as α + β·t, t the body diagonals' g.
    let line = |t: f64| family_lengths(h, t);
    let (a, b1) = (line(0.0), line(1.0));
    let beta: Vec<f64> = (0..8).map(|m| b1[m] - a[m]).collect();
    let lowest = |t: f64| {
        FAMILIES
            .iter()
            .map(|&m| a[m] + beta[m] * t)
            .fold(f64::INFINITY, f64::min)
    };
    let mut candidates = vec![0.0];
    for (i, &m) in FAMILIES.iter().enumerate() {
        for &n in &FAMILIES[i + 1..] {
            let db = beta[m] - beta[n];
            if db != 0.0 {
                let t = (a[n] - a[m]) / db;
                if t.is_finite() && t > 0.0 {
                    candidates.push(t);
                }
            }
        }
    }
    let best = candidates
        .into_iter()
        .max_by(|x, y| lowest(*x).total_cmp(&lowest(*y)))
        .unwrap_or(0.0);
    if lowest(best) <= 1e-9 * mean {
        let cm = h.map(|x| x * 100.0);
        return Err(bad_setting(
            "block.grid",
            format!(
                "voxels of {:.3} × {:.3} × {:.3} cm are too far from cubic: no positive element \
                 constants give them the stiffness of cubic voxels (the lattice's modulus would \
                 depend on the voxel's shape); choose masses per axis that make the spacings \
                 (size/(masses − 1)) nearly equal — equal spacings always work \
                 (rheology README, \"Effective stiffness of the lattice\")",
                cm[0], cm[1], cm[2]
            ),
        ));
    }
    Ok(line(best))
}

/// The family lengths (m) for body-diagonal length `t`: face diagonals
/// make up C_iijj, edges make up C_iiii.
fn family_lengths(h: [f64; 3], t: f64) -> [f64; 8] {
    let v = h[0] * h[1] * h[2];
    let lb2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
    let mut g = [0.0; 8];
    g[7] = t;
    let mut normal = [CUBIC_C11; 3];
    for (i, j) in [(0usize, 1usize), (0, 2), (1, 2)] {
        let (hi2, hj2) = (h[i] * h[i], h[j] * h[j]);
        let body = 4.0 * t * hi2 * hj2 / (lb2 * v);
        let rest = CUBIC_C12 - body;
        g[(1 << i) | (1 << j)] = rest * (hi2 + hj2) * v / (4.0 * hi2 * hj2);
        // The face diagonals' share of C_iiii and C_jjjj.
        normal[i] -= rest * hi2 / hj2;
        normal[j] -= rest * hj2 / hi2;
    }
    for (i, n) in normal.iter().enumerate() {
        let hi2 = h[i] * h[i];
        let body = 4.0 * t * hi2 * hi2 / (lb2 * v);
        g[1 << i] = (n - body) * v / (4.0 * hi2);
    }
    g
}

/// The normal block (C_iijj, i, j ∈ x, y, z) of the stiffness tensor of a
/// voxel of `spacing_m` whose families have lengths `g_m` (span-mask
/// indexed), in units of K/a: the closed-form sum above over the voxel's
/// 28 elements. The shear moduli are C_ijij = C_iijj (i ≠ j).
pub fn normal_stiffness(spacing_m: [f64; 3], g_m: &[f64; 8]) -> [[f64; 3]; 3] {
    let h = spacing_m;
    let v = h[0] * h[1] * h[2];
    let mut c = [[0.0; 3]; 3];
    for a in 0..8usize {
        for b in a + 1..8 {
            let d: [f64; 3] = std::array::from_fn(|i| h[i] * (((a ^ b) >> i) & 1) as f64);
            let l2: f64 = d.iter().map(|x| x * x).sum();
            let k = g_m[family_of(a, b)] / (v * l2);
            for i in 0..3 {
                for j in 0..3 {
                    c[i][j] += k * d[i] * d[i] * d[j] * d[j];
                }
            }
        }
    }
    c
}

/// Young's moduli E_x, E_y, E_z and the Poisson ratios ν_ij (strain −ε_j/ε_i
/// under stress along i) of an orthotropic normal block `c` (any unit; E in
/// the same unit).
pub fn young_and_poisson(c: &[[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let m = nalgebra::Matrix3::from_fn(|i, j| c[i][j]);
    let s = m.try_inverse().unwrap_or_else(nalgebra::Matrix3::zeros);
    let young = [0, 1, 2].map(|i| 1.0 / s[(i, i)]);
    let poisson = std::array::from_fn(|i| std::array::from_fn(|j| -s[(j, i)] / s[(i, i)]));
    (young, poisson)
}

/// The continuum a uniform lattice stands for: under a uniaxial stress σ
/// it strains as one basic element does, with spring E_k, Voigt viscosity
/// η1 and series viscosity η2, laterally by −ν times the axial strain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EffectiveMaterial {
    /// E_k = (144/19)·K/a (Pa).
    pub young_pa: f64,
    /// η1 = (144/19)·C1/a (Pa·s).
    pub voigt_viscosity_pa_s: f64,
    /// η2 = (144/19)·C2/(1 − a) (Pa·s).
    pub series_viscosity_pa_s: f64,
    /// ν = 5/19.
    pub poisson: f64,
}

impl EffectiveMaterial {
    /// The material of a lattice whose every element has `p`.
    pub fn of(p: &ElementParams) -> Self {
        let s = YOUNG_PER_K_OVER_A * PA_PER_GF_PER_CM2;
        Self {
            young_pa: s * p.k_gf_per_cm2 / p.a,
            voigt_viscosity_pa_s: s * p.c1_gfs_per_cm2 / p.a,
            series_viscosity_pa_s: s * p.c2_gfs_per_cm2 / (1.0 - p.a),
            poisson: POISSON,
        }
    }

    /// Axial strain at `t_s` under a uniaxial stress `stress_pa` applied
    /// at t = 0 (the element's creep law with the moduli above).
    pub fn creep_strain(&self, stress_pa: f64, t_s: f64) -> f64 {
        let e = self.young_pa;
        stress_pa / e * (1.0 - (-t_s * e / self.voigt_viscosity_pa_s).exp())
            + stress_pa * t_s / self.series_viscosity_pa_s
    }
}

/// What [`uniaxial_creep`] measured at one time: the block's mean axial
/// (y) strain and its lateral strains (x, z), from the top, bottom and
/// side faces' mean positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockStrain {
    pub t_s: f64,
    pub axial: f64,
    pub lateral: [f64; 2],
}

/// The lattice's own response to a uniaxial stress: a grid lattice with
/// `params` in every class, its bottom masses held vertically only (a
/// frictionless table; one corner also held sideways), its top masses
/// pulled up by `stress_pa` times their tributary area from t = 0, no
/// gravity, no plate, implicit Euler at `dt_s` with tight solves; the
/// strains at `times_s` (each rounded to a step). The block weighs 1 kg
/// per m³ of it, so inertia is negligible against the dampers.
pub fn uniaxial_creep(
    lattice: &Lattice,
    params: &ElementParams,
    stress_pa: f64,
    dt_s: f64,
    times_s: &[f64],
) -> Result<Vec<BlockStrain>> {
    let constants = lattice.element_constants(&LatticeParams::uniform(*params));
    let n = lattice.masses();
    let contacts = Contacts::new(
        ContactParams::default(),
        None,
        vec![0.0; n],
        [1.0, 1.0],
        Vec::new(),
    )?;
    let settings = SimSettings {
        dt_s,
        gravity_m_s2: 0.0,
        tolerance: 1e-11,
        max_iterations: 20_000,
        ..SimSettings::default()
    };
    let volume: f64 = lattice.size_m.iter().product();
    let mut sim = LatticeSim::new(lattice, constants, volume, settings, contacts)?;
    let [nx, ny, nz] = lattice.nodes;
    for k in 0..nz {
        for i in 0..nx {
            let bottom = lattice.node_index(i, 0, k);
            let corner = i == 0 && k == 0;
            sim.drive(NodeDrive::pin(
                bottom,
                lattice.rest_m[bottom],
                [corner, true, corner],
            ))?;
            let top = lattice.node_index(i, ny - 1, k);
            let area = lattice.tributary_area_m2[top];
            sim.set_external_force(top, V3::new(0.0, stress_pa * area, 0.0));
        }
    }
    let face_mean = |x: &[V3], axis: usize, side: usize| {
        let nodes = &lattice.nodes;
        let (mut sum, mut count) = (0.0, 0.0);
        for (g, p) in x.iter().enumerate().take(lattice.grid_masses) {
            let ijk = [
                g % nodes[0],
                (g / nodes[0]) % nodes[1],
                g / (nodes[0] * nodes[1]),
            ];
            if ijk[axis] == side {
                sum += p[axis];
                count += 1.0;
            }
        }
        sum / count
    };
    let size = lattice.size_m;
    let strain = |x: &[V3], axis: usize| {
        (face_mean(x, axis, lattice.nodes[axis] - 1) - face_mean(x, axis, 0)) / size[axis] - 1.0
    };
    let mut out = Vec::with_capacity(times_s.len());
    for &t in times_s {
        let steps = ((t - sim.time_s()) / dt_s).round().max(0.0) as usize;
        for _ in 0..steps {
            sim.step()?;
        }
        let x = sim.positions();
        out.push(BlockStrain {
            t_s: sim.time_s(),
            axial: strain(x, 1),
            lateral: [strain(x, 0), strain(x, 2)],
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cubic_voxel_sums_to_28_thirds_and_10_thirds() {
        let c = normal_stiffness([0.01; 3], &[0.01; 8]);
        for (i, row) in c.iter().enumerate() {
            for (j, cij) in row.iter().enumerate() {
                let want = if i == j { 28.0 / 3.0 } else { 10.0 / 3.0 };
                assert!((cij - want).abs() < 1e-12, "{i}{j}: {cij}");
            }
        }
        let (e, nu) = young_and_poisson(&c);
        assert!((e[1] - 144.0 / 19.0).abs() < 1e-12);
        assert!((nu[1][0] - 5.0 / 19.0).abs() < 1e-12);
    }

    #[test]
    fn non_cubic_voxels_get_the_cubic_tensor_or_are_refused_by_name() {
        // The issue's grids on the 10 × 6 × 10 cm block.
        for h in [
            [0.10 / 7.0, 0.01, 0.10 / 7.0],
            [0.015, 0.02, 0.015],
            [0.01, 0.012, 0.011],
        ] {
            let g = class_factors_m(h).unwrap();
            assert!(FAMILIES.iter().all(|&m| g[m] > 0.0), "{h:?}: {g:?}");
            let c = normal_stiffness(h, &g);
            for (i, row) in c.iter().enumerate() {
                for (j, cij) in row.iter().enumerate() {
                    let want = if i == j { CUBIC_C11 } else { CUBIC_C12 };
                    assert!((cij - want).abs() < 1e-9, "{h:?} {i}{j}: {cij}");
                }
            }
        }
        let e = class_factors_m([0.0125, 0.015, 0.10 / 12.0]).unwrap_err();
        assert!(e.to_string().contains("block.grid"), "{e}");
        assert_eq!(class_factors_m([0.02; 3]).unwrap(), [0.02; 8]);
    }
}
