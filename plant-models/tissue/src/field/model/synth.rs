//! Synthetic twins of Zhang's calf MR volumes: a textured volume, and the
//! same tissue after a known non-rigid warp, a rotation, a translation and
//! fresh noise. No MR volumes ship with the seed; these let the project
//! measure errors against the true field, which the paper could not.
//!
//! The tissue is an analytic function of position (mm), not a voxel grid,
//! so the deformed volume is rendered from the same continuous tissue
//! (`I₁(q) = T(ψ(q))`) without interpolating the initial volume — the
//! truth is not the model being tested:
//! - the calf: an elliptic cylinder along z (semi-axes 28 % and 23 % of the
//!   field of view, an estimate of a calf in a 20 cm FOV) with a 4 mm skin
//!   layer (intensity 900);
//! - muscle and fat compartments: the Voronoi cells of seeds on a jittered
//!   3 mm grid, each with its own intensity in 200–700 (3-D junctions of
//!   cells are the high-curvature points Harris responds to);
//! - two bones (tibia, fibula) as elliptic cylinders of intensity 1000;
//! - vessels and fat lobules: spheres of 1.0–1.8 mm radius in 80 % of the
//!   cells, +250 or −150;
//! - the voxel's mean over 2 × 2 × 2 samples (partial volume), a Gaussian
//!   point-spread blur (σ 0.5 mm) and Gaussian noise.
//!
//! The warp (`ψ`, deformed → initial) is a rigid motion about the volume
//! centre (rotation about z, translation) composed with a smooth
//! non-rigid displacement, a sum of Gaussian bumps:
//! `ψ(q) = s + v(s)`, `s = Rᵀ(q − c − t) + c`, `v(s) = Σ a_k exp(−|s − c_k|²/2σ²)`.
//! The forward map `φ = ψ⁻¹` (initial → deformed, what the method
//! measures) is found by fixed-point iteration `s ← p − v(s)`, which
//! converges because `|∇v| < 1` is checked when the twin is made.
//!
//! Left out: MR physics (bias field, Rician noise, partial-volume effects
//! beyond the blur), motion along z larger than the 3-slice search cube.
use super::volume::Volume;
use crate::error::{check_positive, check_range, Result, TissueError};
use plant_common::rng;
use rand::Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// The paper's volumes: 256 × 256 × 57 voxels (Zhang §IV, L562).
pub const PAPER_DIMS: [usize; 3] = [256, 256, 57];
/// Voxel spacing (mm): a 20 × 20 cm field of view over 256 voxels (L562);
/// along z, 2 mm slices with one linearly interpolated slice between each
/// two (L562) give 1 mm (29 slices → 2·29 − 1 = 57).
pub const PAPER_SPACING_MM: [f64; 3] = [200.0 / 256.0, 200.0 / 256.0, 1.0];

/// How a synthetic twin is made. Defaults are estimates (the paper does
/// not give its calf's deformation); see each field.
#[derive(Clone, Debug, PartialEq)]
pub struct SynthSpec {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Voxel spacing (mm).
    pub spacing_mm: [f64; 3],
    /// Seed of the texture, warp and noise.
    pub seed: u64,
    /// Compartment (Voronoi cell) size (mm), estimate.
    pub cell_mm: f64,
    /// Noise standard deviation (intensity units; the compartments span
    /// 200–700), added to both volumes independently.
    pub noise_sigma: f64,
    /// Point-spread blur (mm, σ) of both volumes.
    pub psf_sigma_mm: f64,
    /// Samples per voxel side of the box filter (partial-volume effect;
    /// 1 = point sampling, which aliases the compartments' edges).
    pub supersample: usize,
    /// Rotation about z through the volume centre (degrees).
    pub rotation_deg: f64,
    /// Translation (mm).
    pub translation_mm: [f64; 3],
    /// Number of Gaussian bumps of the non-rigid warp.
    pub warp_bumps: usize,
    /// Largest in-plane amplitude of one bump (mm).
    pub warp_amplitude_mm: f64,
    /// Largest amplitude of one bump along z (mm); the paper's search cube
    /// is 3 slices deep, so motion along z must stay below a slice.
    pub warp_z_amplitude_mm: f64,
    /// Width σ of each bump (mm).
    pub warp_sigma_mm: f64,
}

impl Default for SynthSpec {
    /// The paper's size with an estimated deformation: 2° rotation, 1 mm
    /// translation, ten bumps of up to 2.5 mm in-plane (0.4 mm along z)
    /// and σ 22 mm — largest total motion ≈ 5 mm (6–7 voxels), inside the
    /// paper's 17-voxel search cube; noise σ 20 (4 % of the compartment
    /// range, an MR signal-to-noise ratio of about 25); 3 mm compartments.
    fn default() -> Self {
        SynthSpec {
            dims: PAPER_DIMS,
            spacing_mm: PAPER_SPACING_MM,
            seed: 1,
            cell_mm: 3.0,
            noise_sigma: 20.0,
            psf_sigma_mm: 0.5,
            supersample: 2,
            rotation_deg: 2.0,
            translation_mm: [1.0, -0.6, 0.0],
            warp_bumps: 10,
            warp_amplitude_mm: 2.5,
            warp_z_amplitude_mm: 0.4,
            warp_sigma_mm: 22.0,
        }
    }
}

impl SynthSpec {
    /// The default twin at another size (same spacing and deformation
    /// scale; the calf scales with the field of view).
    pub fn with_dims(dims: [usize; 3]) -> Self {
        SynthSpec {
            dims,
            ..Self::default()
        }
    }

    fn validate(&self) -> Result<()> {
        for (&d, name) in self.dims.iter().zip(["dims x", "dims y", "dims z"]) {
            check_range(name, d as f64, 8.0, 4096.0, "must be 8 to 4096 voxels")?;
        }
        for &s in &self.spacing_mm {
            check_positive("spacing_mm", s)?;
        }
        check_positive("cell_mm", self.cell_mm)?;
        check_range(
            "supersample",
            self.supersample as f64,
            1.0,
            8.0,
            "must be 1 to 8 samples per voxel side",
        )?;
        check_range(
            "noise_sigma",
            self.noise_sigma,
            0.0,
            1e4,
            "must be 0 to 10000",
        )?;
        check_range(
            "psf_sigma_mm",
            self.psf_sigma_mm,
            0.0,
            50.0,
            "must be 0 to 50 mm",
        )?;
        check_range(
            "rotation_deg",
            self.rotation_deg,
            -45.0,
            45.0,
            "must be -45 to 45°",
        )?;
        for &t in &self.translation_mm {
            check_range("translation_mm", t, -1e3, 1e3, "must be within ±1000 mm")?;
        }
        check_range(
            "warp_bumps",
            self.warp_bumps as f64,
            0.0,
            1000.0,
            "must be 0 to 1000",
        )?;
        check_range(
            "warp_amplitude_mm",
            self.warp_amplitude_mm,
            0.0,
            1e3,
            "must be 0 to 1000 mm",
        )?;
        check_range(
            "warp_z_amplitude_mm",
            self.warp_z_amplitude_mm,
            0.0,
            1e3,
            "must be 0 to 1000 mm",
        )?;
        check_positive("warp_sigma_mm", self.warp_sigma_mm)?;
        Ok(())
    }
}

/// One compartment of the texture: its seed, intensity and optional vessel.
#[derive(Clone, Copy, Debug)]
struct Cell {
    seed_mm: [f64; 3],
    intensity: f64,
    /// A vessel or fat lobule: centre, radius (mm), intensity change.
    vessel: Option<([f64; 3], f64, f64)>,
}

/// The continuous tissue: intensity as a function of position (mm).
#[derive(Clone, Debug)]
pub struct Tissue {
    centre_mm: [f64; 2],
    semi_axes_mm: [f64; 2],
    cell_mm: f64,
    origin_mm: [f64; 3],
    grid: [usize; 3],
    cells: Vec<Cell>,
}

/// Skin thickness (mm), estimate.
const SKIN_MM: f64 = 4.0;
/// Radius range of vessels and fat lobules (mm), estimate.
const VESSEL_MM: (f64, f64) = (0.8, 1.4);
/// Fraction of compartments holding a vessel or lobule, estimate.
const VESSEL_FRACTION: f64 = 0.8;

impl Tissue {
    fn new(spec: &SynthSpec) -> Self {
        let mut r = rng::stream(spec.seed, rng::TISSUE_TEXTURE);
        let fov: [f64; 3] = std::array::from_fn(|a| (spec.dims[a] - 1) as f64 * spec.spacing_mm[a]);
        let centre_mm = [fov[0] / 2.0, fov[1] / 2.0];
        let semi_axes_mm = [0.28 * fov[0], 0.23 * fov[1]];
        let cell = spec.cell_mm;
        // Cells cover the body's box and the slab, with two cells of margin
        // (warped samples may fall outside the volume).
        let origin_mm = [
            centre_mm[0] - semi_axes_mm[0] - 2.0 * cell,
            centre_mm[1] - semi_axes_mm[1] - 2.0 * cell,
            -3.0 * cell,
        ];
        let grid = [
            ((2.0 * semi_axes_mm[0]) / cell).ceil() as usize + 5,
            ((2.0 * semi_axes_mm[1]) / cell).ceil() as usize + 5,
            (fov[2] / cell).ceil() as usize + 7,
        ];
        let mut cells = Vec::with_capacity(grid[0] * grid[1] * grid[2]);
        for k in 0..grid[2] {
            for j in 0..grid[1] {
                for i in 0..grid[0] {
                    let base = [
                        origin_mm[0] + (i as f64 + 0.5) * cell,
                        origin_mm[1] + (j as f64 + 0.5) * cell,
                        origin_mm[2] + (k as f64 + 0.5) * cell,
                    ];
                    let seed_mm = base.map(|b| b + (r.gen::<f64>() - 0.5) * 0.7 * cell);
                    let intensity = 200.0 + 500.0 * r.gen::<f64>();
                    let vessel = if r.gen::<f64>() < VESSEL_FRACTION {
                        let c = base.map(|b| b + (r.gen::<f64>() - 0.5) * cell);
                        let radius = VESSEL_MM.0 + (VESSEL_MM.1 - VESSEL_MM.0) * r.gen::<f64>();
                        let change = if r.gen::<f64>() < 0.5 { 250.0 } else { -150.0 };
                        Some((c, radius, change))
                    } else {
                        None
                    };
                    cells.push(Cell {
                        seed_mm,
                        intensity,
                        vessel,
                    });
                }
            }
        }
        Tissue {
            centre_mm,
            semi_axes_mm,
            cell_mm: cell,
            origin_mm,
            grid,
            cells,
        }
    }

    /// Whether a position lies inside the calf's elliptic cylinder.
    pub fn inside_body(&self, p: [f64; 3]) -> bool {
        self.body_radius(p) <= 1.0
    }

    fn body_radius(&self, p: [f64; 3]) -> f64 {
        let u = (p[0] - self.centre_mm[0]) / self.semi_axes_mm[0];
        let v = (p[1] - self.centre_mm[1]) / self.semi_axes_mm[1];
        (u * u + v * v).sqrt()
    }

    /// Intensity at a position (mm), before blur and noise.
    pub fn intensity(&self, p: [f64; 3]) -> f64 {
        let rho = self.body_radius(p);
        if rho > 1.0 {
            return 0.0;
        }
        if rho > 1.0 - SKIN_MM / self.semi_axes_mm[1] {
            return 900.0;
        }
        // Bones: tibia (front, larger) and fibula (side), in body units.
        let u = (p[0] - self.centre_mm[0]) / self.semi_axes_mm[0];
        let v = (p[1] - self.centre_mm[1]) / self.semi_axes_mm[1];
        let bone = |cu: f64, cv: f64, ru: f64, rv: f64| {
            ((u - cu) / ru).powi(2) + ((v - cv) / rv).powi(2) <= 1.0
        };
        if bone(-0.15, -0.35, 0.17, 0.2) || bone(0.45, -0.05, 0.09, 0.11) {
            return 1000.0;
        }
        let c: [i64; 3] =
            std::array::from_fn(|a| ((p[a] - self.origin_mm[a]) / self.cell_mm).floor() as i64);
        let mut best = (f64::INFINITY, 0.0);
        let mut vessel = 0.0;
        for dk in -1..=1 {
            for dj in -1..=1 {
                for di in -1..=1 {
                    let q = [c[0] + di, c[1] + dj, c[2] + dk];
                    if (0..3).any(|a| q[a] < 0 || q[a] >= self.grid[a] as i64) {
                        continue;
                    }
                    let idx = q[0] as usize
                        + self.grid[0] * (q[1] as usize + self.grid[1] * q[2] as usize);
                    let cell = &self.cells[idx];
                    let d2 = dist2(p, cell.seed_mm);
                    if d2 < best.0 {
                        best = (d2, cell.intensity);
                    }
                    if let Some((vc, radius, change)) = cell.vessel {
                        if dist2(p, vc) <= radius * radius {
                            vessel = change;
                        }
                    }
                }
            }
        }
        best.1 + vessel
    }
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum()
}

/// The known deformation of a twin.
#[derive(Clone, Debug, PartialEq)]
pub struct KnownWarp {
    centre_mm: [f64; 3],
    rotation: [[f64; 3]; 3],
    translation_mm: [f64; 3],
    bumps: Vec<([f64; 3], [f64; 3])>,
    sigma_mm: f64,
}

impl KnownWarp {
    /// Rotation about z by `deg` through `centre_mm`, then `translation_mm`;
    /// no non-rigid part.
    pub fn rigid(centre_mm: [f64; 3], deg: f64, translation_mm: [f64; 3]) -> Self {
        let (s, c) = deg.to_radians().sin_cos();
        KnownWarp {
            centre_mm,
            rotation: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            translation_mm,
            bumps: Vec::new(),
            sigma_mm: 1.0,
        }
    }

    /// The rotation R of the rigid part (deformed = R (s − c) + c + t).
    pub fn rotation(&self) -> [[f64; 3]; 3] {
        self.rotation
    }

    /// The translation t of the rigid part (mm).
    pub fn translation_mm(&self) -> [f64; 3] {
        self.translation_mm
    }

    /// The centre c of the rotation (mm).
    pub fn centre_mm(&self) -> [f64; 3] {
        self.centre_mm
    }

    /// The non-rigid backward displacement v(s) (mm) and its Jacobian.
    fn bump_field(&self, s: [f64; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
        let mut v = [0.0; 3];
        let mut j = [[0.0; 3]; 3];
        let inv = 1.0 / (2.0 * self.sigma_mm * self.sigma_mm);
        for (c, a) in &self.bumps {
            let d = [s[0] - c[0], s[1] - c[1], s[2] - c[2]];
            let g = (-(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) * inv).exp();
            for r in 0..3 {
                v[r] += a[r] * g;
                for col in 0..3 {
                    j[r][col] += a[r] * g * (-2.0 * inv * d[col]);
                }
            }
        }
        (v, j)
    }

    /// ψ: where the tissue seen at `q` (deformed volume, mm) was in the
    /// initial volume.
    pub fn backward_mm(&self, q: [f64; 3]) -> [f64; 3] {
        let s = self.unrigid(q);
        let (v, _) = self.bump_field(s);
        [s[0] + v[0], s[1] + v[1], s[2] + v[2]]
    }

    fn unrigid(&self, q: [f64; 3]) -> [f64; 3] {
        let d = [
            q[0] - self.centre_mm[0] - self.translation_mm[0],
            q[1] - self.centre_mm[1] - self.translation_mm[1],
            q[2] - self.centre_mm[2] - self.translation_mm[2],
        ];
        std::array::from_fn(|r| {
            (0..3).map(|k| self.rotation[k][r] * d[k]).sum::<f64>() + self.centre_mm[r]
        })
    }

    /// The true displacement `φ(p) − p` (mm) of the tissue at `p`
    /// (initial volume, mm): the field the method measures.
    pub fn displacement_mm(&self, p: [f64; 3]) -> [f64; 3] {
        let q = self.forward_mm(p);
        [q[0] - p[0], q[1] - p[1], q[2] - p[2]]
    }

    /// φ: where the tissue at `p` (initial volume, mm) is in the deformed
    /// volume — the field the method measures is `φ(p) − p`.
    pub fn forward_mm(&self, p: [f64; 3]) -> [f64; 3] {
        let mut s = p;
        for _ in 0..100 {
            let (v, _) = self.bump_field(s);
            let next = [p[0] - v[0], p[1] - v[1], p[2] - v[2]];
            let step = dist2(next, s);
            s = next;
            if step < 1e-24 {
                break;
            }
        }
        let d = [
            s[0] - self.centre_mm[0],
            s[1] - self.centre_mm[1],
            s[2] - self.centre_mm[2],
        ];
        std::array::from_fn(|r| {
            (0..3).map(|k| self.rotation[r][k] * d[k]).sum::<f64>()
                + self.centre_mm[r]
                + self.translation_mm[r]
        })
    }

    /// Largest row sum of |∂v/∂s| over a grid covering `box_mm` (a bound
    /// on the contraction factor of the fixed-point inversion there).
    fn max_gradient(&self, lo: [f64; 3], hi: [f64; 3]) -> f64 {
        let n = 12;
        let mut worst: f64 = 0.0;
        for i in 0..=n {
            for j in 0..=n {
                for k in 0..=n {
                    let t = [i, j, k].map(|v| v as f64 / n as f64);
                    let s = std::array::from_fn(|a| lo[a] + t[a] * (hi[a] - lo[a]));
                    let (_, jac) = self.bump_field(s);
                    for row in jac {
                        worst = worst.max(row.iter().map(|v| v.abs()).sum());
                    }
                }
            }
        }
        worst
    }
}

/// A synthetic pair: the initial volume, the deformed one and the truth.
#[derive(Clone, Debug)]
pub struct Twin {
    /// The initial volume (IV).
    pub initial: Volume,
    /// The deformed volume (FV).
    pub deformed: Volume,
    /// The true deformation.
    pub warp: KnownWarp,
    /// The tissue both were rendered from.
    pub tissue: Tissue,
}

/// Renders `tissue` through `backward` (deformed → initial position) on
/// the grid of `spec`, blurs it and adds noise from `noise_stream`.
fn render(
    spec: &SynthSpec,
    tissue: &Tissue,
    backward: &(dyn Fn([f64; 3]) -> [f64; 3] + Sync),
    noise_stream: u64,
) -> Volume {
    let [nx, ny, nz] = spec.dims;
    let ss = spec.supersample.max(1);
    // Sub-sample offsets (voxel units) of a box filter over the voxel.
    let offsets: Vec<f64> = (0..ss)
        .map(|k| (k as f64 + 0.5) / ss as f64 - 0.5)
        .collect();
    let weight = 1.0 / (ss * ss * ss) as f64;
    let mut v = Volume::zeros(spec.dims, spec.spacing_mm);
    v.data_mut()
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, slice)| {
            for y in 0..ny {
                for x in 0..nx {
                    let mut acc = 0.0;
                    for oz in &offsets {
                        for oy in &offsets {
                            for ox in &offsets {
                                let q = [
                                    (x as f64 + ox) * spec.spacing_mm[0],
                                    (y as f64 + oy) * spec.spacing_mm[1],
                                    (z as f64 + oz) * spec.spacing_mm[2],
                                ];
                                acc += tissue.intensity(backward(q));
                            }
                        }
                    }
                    slice[x + nx * y] = (acc * weight) as f32;
                }
            }
        });
    debug_assert_eq!(v.data().len(), nx * ny * nz);
    let mut v = if spec.psf_sigma_mm > 0.0 {
        v.gaussian_blur([spec.psf_sigma_mm; 3])
    } else {
        v
    };
    if spec.noise_sigma > 0.0 {
        let mut r = rng::stream(spec.seed, noise_stream);
        let normal = Normal::new(0.0, spec.noise_sigma).expect("σ checked finite and ≥ 0");
        for val in v.data_mut() {
            *val += normal.sample(&mut r) as f32;
        }
    }
    v
}

/// Makes a synthetic twin: the initial volume, the deformed one (warp,
/// rotation, translation, fresh noise) and the known warp.
pub fn make_twin(spec: &SynthSpec) -> Result<Twin> {
    spec.validate()?;
    let tissue = Tissue::new(spec);
    let fov: [f64; 3] = std::array::from_fn(|a| (spec.dims[a] - 1) as f64 * spec.spacing_mm[a]);
    let centre = fov.map(|f| f / 2.0);
    let mut warp = KnownWarp::rigid(centre, spec.rotation_deg, spec.translation_mm);
    let mut r = rng::stream(spec.seed, rng::TISSUE_WARP);
    warp.sigma_mm = spec.warp_sigma_mm;
    for _ in 0..spec.warp_bumps {
        let c = [
            tissue.centre_mm[0] + (r.gen::<f64>() - 0.5) * 2.0 * tissue.semi_axes_mm[0],
            tissue.centre_mm[1] + (r.gen::<f64>() - 0.5) * 2.0 * tissue.semi_axes_mm[1],
            r.gen::<f64>() * fov[2],
        ];
        let angle = r.gen::<f64>() * std::f64::consts::TAU;
        let mag = spec.warp_amplitude_mm * (0.5 + 0.5 * r.gen::<f64>());
        let a = [
            mag * angle.cos(),
            mag * angle.sin(),
            spec.warp_z_amplitude_mm * (2.0 * r.gen::<f64>() - 1.0),
        ];
        warp.bumps.push((c, a));
    }
    let margin = 3.0 * spec.warp_sigma_mm;
    let contraction = warp.max_gradient(
        [-margin, -margin, -margin],
        [fov[0] + margin, fov[1] + margin, fov[2] + margin],
    );
    if contraction >= 0.5 {
        return Err(TissueError::InvalidParameter {
            name: "warp_amplitude_mm",
            value: spec.warp_amplitude_mm,
            reason: "the bumps are too steep for their width (|∂v/∂s| ≥ 0.5): the warp would fold or not be invertible; lower it or widen warp_sigma_mm",
        });
    }
    let initial = render(spec, &tissue, &|q| q, rng::TISSUE_NOISE_INITIAL);
    let deformed = render(
        spec,
        &tissue,
        &|q| warp.backward_mm(q),
        rng::TISSUE_NOISE_DEFORMED,
    );
    Ok(Twin {
        initial,
        deformed,
        warp,
        tissue,
    })
}

/// A pair under a rigid motion only, noise-free unless `spec` says
/// otherwise (the Harris invariance check).
pub fn make_rigid_pair(spec: &SynthSpec) -> Result<Twin> {
    let spec = SynthSpec {
        warp_bumps: 0,
        ..spec.clone()
    };
    make_twin(&spec)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forward_inverts_backward_to_round_off() {
        let spec = SynthSpec::with_dims([40, 40, 12]);
        let twin = make_twin(&spec).unwrap();
        for p in [[10.0, 12.0, 4.0], [20.0, 15.5, 9.0], [3.0, 28.0, 1.0]] {
            let q = twin.warp.forward_mm(p);
            let back = twin.warp.backward_mm(q);
            assert!(dist2(back, p).sqrt() < 1e-9, "{p:?} → {q:?} → {back:?}");
        }
    }

    #[test]
    fn the_deformed_volume_is_the_initial_tissue_moved() {
        // Noise-free: a deformed voxel equals the blurred tissue at ψ(q);
        // away from edges the unblurred tissue must agree at most voxels.
        let spec = SynthSpec {
            noise_sigma: 0.0,
            psf_sigma_mm: 0.0,
            supersample: 1,
            ..SynthSpec::with_dims([48, 48, 12])
        };
        let twin = make_twin(&spec).unwrap();
        let mut same = 0;
        let mut total = 0;
        for z in 2..10 {
            for y in 4..44 {
                for x in 4..44 {
                    let q = twin.deformed.position_mm([x, y, z]);
                    let want = twin.tissue.intensity(twin.warp.backward_mm(q));
                    total += 1;
                    same += usize::from((f64::from(twin.deformed.at(x, y, z)) - want).abs() < 1e-3);
                }
            }
        }
        assert_eq!(same, total);
        // And the two volumes differ: the warp moved something.
        let diff = twin
            .initial
            .data()
            .iter()
            .zip(twin.deformed.data())
            .filter(|(a, b)| (*a - *b).abs() > 1.0)
            .count();
        assert!(diff > 1000, "only {diff} voxels changed");
    }

    #[test]
    fn twins_are_reproducible_and_seeds_differ() {
        let spec = SynthSpec::with_dims([24, 24, 8]);
        let a = make_twin(&spec).unwrap();
        let b = make_twin(&spec).unwrap();
        assert_eq!(a.initial, b.initial);
        assert_eq!(a.deformed, b.deformed);
        let c = make_twin(&SynthSpec { seed: 2, ..spec }).unwrap();
        assert_ne!(a.initial, c.initial);
    }

    #[test]
    fn a_steep_warp_is_refused_by_name() {
        let spec = SynthSpec {
            warp_amplitude_mm: 40.0,
            warp_sigma_mm: 5.0,
            ..SynthSpec::with_dims([24, 24, 8])
        };
        let e = make_twin(&spec).unwrap_err();
        assert!(e.to_string().contains("warp_amplitude_mm"), "{e}");
    }
}
