//! The ground truth: a reference block that is *not* the lattice being
//! calibrated, standing in for the paper's recordings (none ship with the
//! seed).
//!
//! What it is: a continuum finite-element block of linear tetrahedra (each
//! grid cube split into the six Kuhn tetrahedra, so neighbouring cubes
//! share faces), co-rotational (rotations removed by the polar
//! decomposition of each element's deformation gradient), with a Burgers
//! material, the classic model of dough in creep and recovery tests: in
//! shear, an instantaneous spring G1 in series with a Kelvin–Voigt unit
//! (G2 ‖ η2) and a Newtonian dashpot η1 (flow, the permanent dent); in
//! bulk, a stiff elastic modulus K (dough is nearly incompressible). So it
//! differs from the lattice in kind: a continuum with a volumetric
//! stiffness (the lattice has none and loses volume), an instantaneous
//! elastic response (the lattice element has none), another mesh and its
//! own hidden constants. It is integrated by backward Euler like the
//! lattice (rotations and contact states from the step's start), with its
//! own solver setup, at 5 ms.
//!
//! The rig (table, plate, friction, pull-off) is the same physical rig as
//! the lattice's (`model::contact`) with its own hidden constants.
//!
//! What the "cameras" and "sensor" hand over: at each frame time, points
//! drawn uniformly over the block's visible surface (every face but the
//! bottom; top-face points under the plate are hidden while it is down),
//! each with Gaussian noise on every coordinate; and the plate force at
//! every step (200 Hz at 5 ms; the paper's sensor ran at 8 kHz, L2234)
//! with Gaussian noise. All random draws come from the run's seed on the
//! registered streams `RHEOLOGY_POINTS`, `RHEOLOGY_POINT_NOISE`,
//! `RHEOLOGY_FORCE_NOISE`.
//!
//! Left out: locking-free elements (linear tetrahedra are stiff in near-
//! incompressible bending; the bulk modulus is kept to ≈ 7× the
//! instantaneous shear modulus), large-strain hyperelasticity, adhesion
//! of the block to the table.
use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

use crate::error::{
    bad_setting, check_non_negative, check_positive, check_range, Instability, Result,
    RheologyError,
};
use crate::identify::measurement::{ForceSample, Measurement, PointFrame};
use crate::model::contact::{ContactParams, Contacts, Plate};
use crate::model::lattice::{enclosed_volume_m3, V3};
use crate::model::scenario::{Frame, Scenario};
use crate::model::sim::GRAVITY_M_S2;
use crate::model::solver::{block_jacobi, invert_block, pcg, PcgWork};
use crate::model::vec3::M3;
use plant_common::linalg::SkylineCholesky;

/// The reference dough's Burgers material (hidden constants; estimates
/// chosen so that the lattice parameters that fit it best lie inside the
/// paper's search intervals, L1808–1811: its slow shear modulus and
/// viscosities correspond to a lattice of roughly K ≈ 900 gf/cm²,
/// C1 ≈ 4000 and C2 ≈ 8000 gf·s/cm², a ≈ 0.5 by the lattice's
/// small-strain shear modulus ≈ 3.2·K/a; fixed before any calibration ran).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BurgersMaterial {
    /// G1, the instantaneous shear modulus (kPa).
    pub instant_shear_kpa: f64,
    /// G2, the retarded (Kelvin–Voigt) shear modulus (kPa).
    pub retarded_shear_kpa: f64,
    /// η2, the Kelvin–Voigt viscosity (kPa·s).
    pub retarded_viscosity_kpa_s: f64,
    /// η1, the flow viscosity (kPa·s).
    pub flow_viscosity_kpa_s: f64,
    /// K, the bulk modulus (kPa).
    pub bulk_kpa: f64,
}

impl Default for BurgersMaterial {
    fn default() -> Self {
        Self {
            instant_shear_kpa: 1700.0,
            retarded_shear_kpa: 560.0,
            retarded_viscosity_kpa_s: 2500.0,
            flow_viscosity_kpa_s: 5000.0,
            bulk_kpa: 12_000.0,
        }
    }
}

impl BurgersMaterial {
    fn validate(&self) -> Result<()> {
        check_positive(
            "reference.material.instant_shear_kpa",
            self.instant_shear_kpa,
        )?;
        check_positive(
            "reference.material.retarded_shear_kpa",
            self.retarded_shear_kpa,
        )?;
        check_positive(
            "reference.material.retarded_viscosity_kpa_s",
            self.retarded_viscosity_kpa_s,
        )?;
        check_positive(
            "reference.material.flow_viscosity_kpa_s",
            self.flow_viscosity_kpa_s,
        )?;
        check_positive("reference.material.bulk_kpa", self.bulk_kpa)?;
        Ok(())
    }
}

/// The reference's rig constants (hidden; other values than the lattice's
/// defaults, all estimates).
pub fn reference_contact() -> ContactParams {
    ContactParams {
        mu_static: 0.5,
        mu_kinetic: 0.35,
        pull_off_kpa_per_mm: 0.5,
        pull_off_damping_kpa_s_per_mm: 0.05,
        pull_off_speed_mm_s: 3.0,
        ..ContactParams::default()
    }
}

/// How the ground truth is made.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReferenceConfig {
    /// Cubes per axis (x, y up, z); six tetrahedra each. Default 12 × 7 ×
    /// 12 (0.83 × 0.86 × 0.83 cm for the default block): finer than the
    /// sparse lattice and not aligned with either lattice's grid.
    pub cells: [usize; 3],
    pub material: BurgersMaterial,
    pub contact: ContactParams,
    /// Time step (ms); 5 ms puts the force at 1 s within 3 % of a 0.5 ms
    /// run (measured on 5 × 3 × 5 cubes) at 2.5× less cost than 2 ms.
    pub dt_ms: f64,
    /// Points drawn per frame before occlusion (the paper's cameras caught
    /// about 1000, L1714).
    pub points_per_frame: usize,
    /// Standard deviation of the point noise per coordinate (mm); estimate
    /// for stereo vision at half a metre.
    pub point_noise_mm: f64,
    /// Standard deviation of the force noise (N); estimate for a six-axis
    /// sensor of a few kN range.
    pub force_noise_n: f64,
    /// Seed of the point choice and the noise.
    pub seed: u64,
    /// Relative residual at which each step's solve stops (1e-6: forces
    /// within 0.3 % of 1e-8 at 30 % fewer iterations).
    pub solver_tolerance: f64,
}

impl Default for ReferenceConfig {
    fn default() -> Self {
        Self {
            cells: [12, 7, 12],
            material: BurgersMaterial::default(),
            contact: reference_contact(),
            dt_ms: 5.0,
            points_per_frame: 1000,
            point_noise_mm: 0.5,
            force_noise_n: 0.5,
            seed: 1,
            solver_tolerance: 1e-6,
        }
    }
}

impl ReferenceConfig {
    /// Checks the settings; names the field.
    pub fn validate(&self) -> Result<()> {
        for (a, &c) in self.cells.iter().enumerate() {
            if !(1..=60).contains(&c) {
                return Err(bad_setting(
                    &format!("reference.cells.{}", ["x", "y", "z"][a]),
                    format!("needs 1..=60 cubes, got {c}"),
                ));
            }
        }
        self.material.validate()?;
        self.contact.validate()?;
        check_positive("reference.dt_ms", self.dt_ms)?;
        check_range(
            "reference.solver_tolerance",
            self.solver_tolerance,
            1e-14,
            1e-2,
        )?;
        check_non_negative("reference.point_noise_mm", self.point_noise_mm)?;
        check_non_negative("reference.force_noise_n", self.force_noise_n)?;
        if self.points_per_frame == 0 || self.points_per_frame > 1_000_000 {
            return Err(bad_setting(
                "reference.points_per_frame",
                "needs 1..=1000000 points",
            ));
        }
        Ok(())
    }
}

/// The reference block's mesh and rest data.
#[derive(Clone, Debug)]
pub struct ReferenceBlock {
    /// Grid nodes per axis.
    pub nodes: [usize; 3],
    pub rest_m: Vec<V3>,
    tets: Vec<[u32; 4]>,
    grads: Vec<[V3; 4]>,
    volumes_m3: Vec<f64>,
    node_mass_kg: Vec<f64>,
    /// Outward surface triangles, and whether each lies on the top face
    /// (`Some(true)`), the bottom (`None`) or a side (`Some(false)`).
    pub surface: Vec<[u32; 3]>,
    surface_kind: Vec<Option<bool>>,
    areas_m2: Vec<f64>,
    spacing_m: [f64; 3],
}

impl ReferenceBlock {
    /// The block of `size_m` and mass `mass_kg` cut into `cells` cubes.
    pub fn new(size_m: [f64; 3], mass_kg: f64, cells: [usize; 3]) -> Result<Self> {
        let nodes = cells.map(|c| c + 1);
        let h = [0, 1, 2].map(|a| size_m[a] / cells[a] as f64);
        let id = |i: usize, j: usize, k: usize| (i + nodes[0] * (j + nodes[1] * k)) as u32;
        let mut rest_m = Vec::new();
        for k in 0..nodes[2] {
            for j in 0..nodes[1] {
                for i in 0..nodes[0] {
                    rest_m.push(V3::new(i as f64 * h[0], j as f64 * h[1], k as f64 * h[2]));
                }
            }
        }
        let mut tets = Vec::new();
        for ck in 0..cells[2] {
            for cj in 0..cells[1] {
                for ci in 0..cells[0] {
                    let corner = |b: usize| id(ci + (b & 1), cj + ((b >> 1) & 1), ck + (b >> 2));
                    for perm in [
                        [0, 1, 2],
                        [0, 2, 1],
                        [1, 0, 2],
                        [1, 2, 0],
                        [2, 0, 1],
                        [2, 1, 0],
                    ] {
                        let b1 = 1usize << perm[0];
                        let b2 = b1 | (1 << perm[1]);
                        let mut t = [corner(0), corner(b1), corner(b2), corner(7)];
                        let p = |n: u32| rest_m[n as usize];
                        let vol = (p(t[1]) - p(t[0]))
                            .dot(&(p(t[2]) - p(t[0])).cross(&(p(t[3]) - p(t[0]))));
                        if vol < 0.0 {
                            t.swap(2, 3);
                        }
                        tets.push(t);
                    }
                }
            }
        }
        let total_volume = size_m[0] * size_m[1] * size_m[2];
        let density = mass_kg / total_volume;
        let mut grads = Vec::with_capacity(tets.len());
        let mut volumes_m3 = Vec::with_capacity(tets.len());
        let mut node_mass_kg = vec![0.0; rest_m.len()];
        for t in &tets {
            let p = t.map(|n| rest_m[n as usize]);
            let dm = M3::from_columns(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
            let vol = dm.determinant() / 6.0;
            let inv = dm
                .try_inverse()
                .ok_or_else(|| bad_setting("reference.cells", "a degenerate tetrahedron"))?;
            let row = |r: usize| V3::new(inv[(r, 0)], inv[(r, 1)], inv[(r, 2)]);
            let (g1, g2, g3) = (row(0), row(1), row(2));
            grads.push([-(g1 + g2 + g3), g1, g2, g3]);
            volumes_m3.push(vol);
            for &n in t {
                node_mass_kg[n as usize] += density * vol / 4.0;
            }
        }
        // Boundary faces, split along their Kuhn diagonal (lowest corner to
        // highest), oriented outward.
        let mut surface = Vec::new();
        let mut surface_kind = Vec::new();
        for a in 0..3 {
            let (b, c) = ((a + 1) % 3, (a + 2) % 3);
            for side in [0usize, nodes[a] - 1] {
                let outward = if side == 0 { -1.0 } else { 1.0 };
                for u in 0..cells[b] {
                    for w in 0..cells[c] {
                        let at = |du: usize, dw: usize| {
                            let mut ijk = [0usize; 3];
                            ijk[a] = side;
                            ijk[b] = u + du;
                            ijk[c] = w + dw;
                            id(ijk[0], ijk[1], ijk[2])
                        };
                        let (lo, hi, p1, p2) = (at(0, 0), at(1, 1), at(1, 0), at(0, 1));
                        for mid in [p1, p2] {
                            let mut t = [lo, mid, hi];
                            let q = |n: u32| rest_m[n as usize];
                            let normal = (q(t[1]) - q(t[0])).cross(&(q(t[2]) - q(t[0])));
                            if normal[a] * outward < 0.0 {
                                t.swap(1, 2);
                            }
                            surface.push(t);
                            surface_kind.push(match (a, side) {
                                (1, 0) => None,
                                (1, _) => Some(true),
                                _ => Some(false),
                            });
                        }
                    }
                }
            }
        }
        let w = |n: usize, i: usize, h: f64| if i == 0 || i == n - 1 { h / 2.0 } else { h };
        let areas_m2 = (0..rest_m.len())
            .map(|g| {
                let (i, k) = (g % nodes[0], g / (nodes[0] * nodes[1]));
                w(nodes[0], i, h[0]) * w(nodes[2], k, h[2])
            })
            .collect();
        Ok(Self {
            nodes,
            rest_m,
            tets,
            grads,
            volumes_m3,
            node_mass_kg,
            surface,
            surface_kind,
            areas_m2,
            spacing_m: h,
        })
    }

    /// Number of tetrahedra.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }
}

/// What the reference recorded: the measurement handed to calibration,
/// and its own noise-free state for pictures and checks.
#[derive(Clone, Debug)]
pub struct ReferenceRun {
    pub measurement: Measurement,
    /// Node positions at the frame times.
    pub frames: Vec<Frame>,
    /// Noise-free plate force per step (N) and the step times (s).
    pub t_s: Vec<f64>,
    pub plate_force_n: Vec<f64>,
    /// Enclosed volume per step (m³) and at rest.
    pub volume_m3: Vec<f64>,
    pub volume0_m3: f64,
    /// Grid nodes per axis of the reference mesh.
    pub nodes: [usize; 3],
    /// Solver iterations over the run.
    pub iterations: usize,
}

/// The rotation of the polar decomposition F = R·S (scaled Newton
/// iteration, Higham 1986); `None` for an inverted or degenerate F.
pub fn polar_rotation(f: &M3) -> Option<M3> {
    let det = f.determinant();
    if det.is_nan() || det <= 1e-9 {
        return None;
    }
    let mut x = *f;
    for _ in 0..40 {
        let inv_t = x.try_inverse()?.transpose();
        let gamma = x.determinant().abs().powf(-1.0 / 3.0);
        let next = (x * gamma + inv_t * (1.0 / gamma)) * 0.5;
        let change = (next - x).ddot(&(next - x)).sqrt();
        x = next;
        if change < 1e-13 {
            break;
        }
    }
    Some(x)
}

/// Refactor the preconditioner when a solve took more iterations than
/// this …
const REFACTOR_ITERATIONS: usize = 12;
/// … or after this many steps.
const REFACTOR_STEPS: usize = 100;

fn dev(m: &M3) -> M3 {
    *m - M3::identity() * (m.trace() / 3.0)
}

/// A tetrahedron's step matrix `scale·K_e` (12×12, row-major, node-major
/// xyz) with the rotation `r` held: block (k, l) is
/// `G (g_l·g_k) I + G (R g_l)(R g_k)ᵀ + (K − 2G/3)(R g_k)(R g_l)ᵀ`
/// (the co-rotated small-strain stiffness; equal to probing
/// [`tet_force_change`] with unit velocities, as a test checks).
fn tet_step_matrix(r: &M3, grads: &[V3; 4], g: f64, bulk: f64, scale: f64, ke: &mut [f64; 144]) {
    let h = grads.map(|gk| *r * gk);
    let lam = bulk - 2.0 * g / 3.0;
    for k in 0..4 {
        for l in 0..4 {
            let gg = g * grads[l].dot(&grads[k]);
            for a in 0..3 {
                for b in 0..3 {
                    let mut v = g * h[l][a] * h[k][b] + lam * h[k][a] * h[l][b];
                    if a == b {
                        v += gg;
                    }
                    ke[(3 * k + a) * 12 + 3 * l + b] = v * scale;
                }
            }
        }
    }
}

/// The force change on a tetrahedron's nodes (per unit volume) for nodal
/// velocities `dv`, rotation `r` held: the co-rotated small-strain
/// increment times the step's moduli.
#[cfg(test)]
fn tet_force_change(r: &M3, grads: &[V3; 4], g: f64, bulk: f64, dv: &[V3; 4]) -> [V3; 4] {
    let mut df = M3::zeros();
    for k in 0..4 {
        df += dv[k].outer(&grads[k]);
    }
    let de = (r.transpose() * df).sym();
    let dp = *r * (dev(&de) * (2.0 * g) + M3::identity() * (bulk * de.trace()));
    [0, 1, 2, 3].map(|k| dp * grads[k])
}

/// Runs the scenario's push on the reference block and records what the
/// cameras and the force sensor would.
pub fn record_push(scenario: &Scenario, cfg: &ReferenceConfig) -> Result<ReferenceRun> {
    scenario.validate()?;
    cfg.validate()?;
    let block = ReferenceBlock::new(scenario.size_m(), scenario.block.mass_g * 1e-3, cfg.cells)?;
    let plate = scenario.plate()?;
    let [nx, ny, nz] = block.nodes;
    let top: Vec<usize> = (0..nz)
        .flat_map(|k| (0..nx).map(move |i| i + nx * (ny - 1 + ny * k)))
        .collect();
    let contacts = Contacts::new(
        cfg.contact,
        Some(plate.clone()),
        block.areas_m2.clone(),
        [block.spacing_m[0], block.spacing_m[2]],
        top,
    )?;
    let mut sim = ReferenceSim::new(&block, cfg, contacts, scenario.model.gravity);
    let dt = cfg.dt_ms * 1e-3;
    let steps = (scenario.plate.end_s / dt).round() as usize;
    let frame_steps: Vec<usize> = scenario
        .measure
        .frame_times_s
        .iter()
        .map(|t| (t / dt).round() as usize)
        .collect();
    let mut out = ReferenceRun {
        measurement: Measurement::default(),
        frames: Vec::new(),
        t_s: Vec::with_capacity(steps),
        plate_force_n: Vec::with_capacity(steps),
        volume_m3: Vec::with_capacity(steps),
        volume0_m3: enclosed_volume_m3(&block.surface, &block.rest_m),
        nodes: block.nodes,
        iterations: 0,
    };
    let mut point_rng = plant_common::rng::stream(cfg.seed, plant_common::rng::RHEOLOGY_POINTS);
    let mut noise_rng =
        plant_common::rng::stream(cfg.seed, plant_common::rng::RHEOLOGY_POINT_NOISE);
    let mut force_rng =
        plant_common::rng::stream(cfg.seed, plant_common::rng::RHEOLOGY_FORCE_NOISE);
    let point_noise = Normal::new(0.0, cfg.point_noise_mm * 1e-3)
        .map_err(|_| bad_setting("reference.point_noise_mm", "not a valid deviation"))?;
    let force_noise = Normal::new(0.0, cfg.force_noise_n)
        .map_err(|_| bad_setting("reference.force_noise_n", "not a valid deviation"))?;
    let mut take = |sim: &ReferenceSim<'_>, step: usize, out: &mut ReferenceRun| {
        for (k, &s) in frame_steps.iter().enumerate() {
            if s == step {
                let t = scenario.measure.frame_times_s[k];
                out.frames.push(Frame {
                    t_s: t,
                    positions_m: sim.x.clone(),
                });
                let points = sample_surface(
                    &block,
                    &sim.x,
                    &plate,
                    t,
                    cfg.points_per_frame,
                    &mut point_rng,
                )
                .into_iter()
                .map(|p| {
                    p + V3::new(
                        point_noise.sample(&mut noise_rng),
                        point_noise.sample(&mut noise_rng),
                        point_noise.sample(&mut noise_rng),
                    )
                })
                .collect();
                out.measurement.frames.push(PointFrame {
                    t_s: t,
                    points_m: points,
                });
            }
        }
    };
    take(&sim, 0, &mut out);
    for step in 1..=steps {
        let force = sim.step(dt)?;
        let t = step as f64 * dt;
        out.t_s.push(t);
        out.plate_force_n.push(force);
        out.volume_m3
            .push(enclosed_volume_m3(&block.surface, &sim.x));
        out.measurement.forces.push(ForceSample {
            t_s: t,
            force_n: force + force_noise.sample(&mut force_rng),
        });
        take(&sim, step, &mut out);
    }
    out.iterations = sim.iterations;
    Ok(out)
}

/// Points drawn uniformly by area over the visible surface at positions
/// `x`; top-face points under the plate are dropped while it is down.
fn sample_surface(
    block: &ReferenceBlock,
    x: &[V3],
    plate: &Plate,
    t_s: f64,
    count: usize,
    rng: &mut impl Rng,
) -> Vec<V3> {
    let visible: Vec<usize> = (0..block.surface.len())
        .filter(|&t| block.surface_kind[t].is_some())
        .collect();
    let mut cumulative = Vec::with_capacity(visible.len());
    let mut total = 0.0;
    for &t in &visible {
        let [a, b, c] = block.surface[t].map(|n| x[n as usize]);
        total += 0.5 * (b - a).cross(&(c - a)).norm();
        cumulative.push(total);
    }
    let plate_down = plate.face_y_m(t_s).map(|f| f < plate.top_m).unwrap_or(true);
    let mut points = Vec::with_capacity(count);
    for _ in 0..count {
        let r = rng.gen::<f64>() * total;
        let k = cumulative
            .partition_point(|&c| c < r)
            .min(visible.len() - 1);
        let t = visible[k];
        let [a, b, c] = block.surface[t].map(|n| x[n as usize]);
        let (u, v): (f64, f64) = (rng.gen(), rng.gen());
        let su = u.sqrt();
        let p = a * (1.0 - su) + b * (su * (1.0 - v)) + c * (su * v);
        let hidden = block.surface_kind[t] == Some(true)
            && plate_down
            && plate.coverage(p.x, p.z, [1e-9, 1e-9]) > 0.0;
        if !hidden {
            points.push(p);
        }
    }
    points
}

struct ReferenceSim<'a> {
    block: &'a ReferenceBlock,
    material: BurgersMaterial,
    contacts: Contacts,
    gravity: bool,
    tolerance: f64,
    x: Vec<V3>,
    v: Vec<V3>,
    v_prev: Vec<V3>,
    rot: Vec<M3>,
    e_voigt: Vec<M3>,
    e_flow: Vec<M3>,
    e_star: Vec<M3>,
    /// Each tetrahedron's step matrix Δt·K_e (12×12, row-major, node-major
    /// xyz), rebuilt every step with the step's rotation.
    stiffness: Vec<[f64; 144]>,
    iterations: usize,
    /// Cholesky factor of a recent step matrix, the preconditioner (the
    /// matrix changes slowly: rotations and contacts); refreshed when a
    /// solve takes more than `REFACTOR_ITERATIONS` or every
    /// `REFACTOR_STEPS` steps.
    factor: Option<SkylineCholesky>,
    profile: Vec<usize>,
    since_factor: usize,
    last_iterations: usize,
    flat: Vec<f64>,
    blocks: Vec<M3>,
    rhs: Vec<V3>,
    diag: Vec<M3>,
    v_new: Vec<V3>,
    fixed: Vec<V3>,
    work: PcgWork,
    steps: usize,
}

impl<'a> ReferenceSim<'a> {
    fn new(
        block: &'a ReferenceBlock,
        cfg: &ReferenceConfig,
        contacts: Contacts,
        gravity: bool,
    ) -> Self {
        let (n, t) = (block.rest_m.len(), block.tets.len());
        Self {
            block,
            material: cfg.material,
            contacts,
            gravity,
            tolerance: cfg.solver_tolerance,
            x: block.rest_m.clone(),
            v: vec![V3::zeros(); n],
            v_prev: vec![V3::zeros(); n],
            rot: vec![M3::identity(); t],
            e_voigt: vec![M3::zeros(); t],
            e_flow: vec![M3::zeros(); t],
            e_star: vec![M3::zeros(); t],
            stiffness: vec![[0.0; 144]; t],
            iterations: 0,
            factor: None,
            profile: {
                // Row 3n+a starts at the first coordinate of n's lowest
                // neighbour.
                let mut low: Vec<usize> = (0..n).collect();
                for tet in &block.tets {
                    let m = *tet.iter().min().unwrap_or(&0) as usize;
                    for &v in tet {
                        low[v as usize] = low[v as usize].min(m);
                    }
                }
                (0..3 * n).map(|r| 3 * low[r / 3]).collect()
            },
            since_factor: 0,
            last_iterations: 0,
            flat: vec![0.0; 3 * n],
            blocks: vec![M3::zeros(); n],
            rhs: vec![V3::zeros(); n],
            diag: vec![M3::zeros(); n],
            v_new: vec![V3::zeros(); n],
            fixed: vec![V3::zeros(); n],
            work: PcgWork::default(),
            steps: 0,
        }
    }

    fn unstable(&self, dt: f64, kind: Instability) -> RheologyError {
        RheologyError::Unstable {
            step: self.steps,
            time_s: self.steps as f64 * dt,
            kind,
        }
    }

    /// Effective shear modulus of a backward-Euler step of the Burgers
    /// body: 1/G = 1/G1 + 1/(G2 + η2/Δt) + Δt/η1.
    fn step_shear(&self, dt: f64) -> (f64, f64) {
        let m = &self.material;
        let (g1, g2) = (m.instant_shear_kpa * 1e3, m.retarded_shear_kpa * 1e3);
        let (eta2, eta1) = (
            m.retarded_viscosity_kpa_s * 1e3,
            m.flow_viscosity_kpa_s * 1e3,
        );
        let voigt = g2 + eta2 / dt;
        (
            1.0 / (1.0 / g1 + 1.0 / voigt + dt / eta1),
            eta2 / dt / voigt,
        )
    }

    /// Factors this step's matrix (mass, tetrahedra, contacts) for the
    /// preconditioner; on failure the solve falls back to block Jacobi.
    fn refactor(&mut self, dt: f64) {
        let block = self.block;
        let mut sk = SkylineCholesky::with_profile(self.profile.clone());
        for (i, m) in block.node_mass_kg.iter().enumerate() {
            for a in 0..3 {
                sk.add(3 * i + a, 3 * i + a, m / dt);
            }
        }
        for (t, ke) in self.stiffness.iter().enumerate() {
            let tet = block.tets[t];
            for r in 0..12 {
                let gr = 3 * tet[r / 3] as usize + r % 3;
                for c in 0..12 {
                    let gc = 3 * tet[c / 3] as usize + c % 3;
                    if gc <= gr {
                        sk.add(gr, gc, ke[r * 12 + c]);
                    }
                }
            }
        }
        self.blocks.fill(M3::zeros());
        self.contacts.add_diag(&mut self.blocks);
        for (i, b) in self.blocks.iter().enumerate() {
            for a in 0..3 {
                for c in 0..=a {
                    if b[(a, c)] != 0.0 {
                        sk.add(3 * i + a, 3 * i + c, b[(a, c)]);
                    }
                }
            }
        }
        self.factor = sk.factor().ok().map(|_| sk);
        self.since_factor = 0;
        self.last_iterations = 0;
    }

    fn deformation(&self, t: usize, x: &[V3]) -> M3 {
        let tet = self.block.tets[t];
        let g = &self.block.grads[t];
        let mut f = M3::zeros();
        for k in 0..4 {
            f += x[tet[k] as usize].outer(&g[k]);
        }
        f
    }

    /// One backward-Euler step; returns the plate force (N).
    fn step(&mut self, dt: f64) -> Result<f64> {
        let t_next = (self.steps + 1) as f64 * dt;
        let (g, voigt_share) = self.step_shear(dt);
        self.contacts.prepare(t_next, dt, &self.x, &self.v);
        self.start_with_inertia(dt);
        self.assemble_elements(dt, g, voigt_share)?;
        self.contacts.add_rhs(&mut self.rhs);
        self.contacts.add_diag(&mut self.diag);
        if self.factor.is_none()
            || self.last_iterations > REFACTOR_ITERATIONS
            || self.since_factor >= REFACTOR_STEPS
        {
            self.refactor(dt);
        }
        self.since_factor += 1;
        let iterations = self.solve_velocities(dt)?;
        self.iterations += iterations;
        self.last_iterations = iterations;
        self.advance(dt)?;
        self.update_internal_states(dt, g);
        self.steps += 1;
        Ok(self.contacts.finish(&self.x, &self.v))
    }

    /// The right-hand side and block diagonal start as the masses' momentum
    /// and weight over the step: `m v / Δt − m g`, `m / Δt`.
    #[inline]
    fn start_with_inertia(&mut self, dt: f64) {
        let grav = if self.gravity { GRAVITY_M_S2 } else { 0.0 };
        for i in 0..self.x.len() {
            let m = self.block.node_mass_kg[i];
            self.rhs[i] = self.v[i] * (m / dt) + V3::new(0.0, -m * grav, 0.0);
            self.diag[i] = M3::identity() * (m / dt);
        }
    }

    /// Each tetrahedron's elastic force at the start of the step (its
    /// rotation held), added to the right-hand side, and its step matrix
    /// Δt·K_e, kept and added to the block diagonal. Fails on a collapsed
    /// tetrahedron.
    #[inline]
    fn assemble_elements(&mut self, dt: f64, g: f64, voigt_share: f64) -> Result<()> {
        let block = self.block;
        let bulk = self.material.bulk_kpa * 1e3;
        for t in 0..block.tets.len() {
            let f = self.deformation(t, &self.x);
            let r = polar_rotation(&f).ok_or_else(|| {
                self.unstable(
                    dt,
                    Instability::Collapsed {
                        element: t,
                        length_ratio: f.determinant().max(0.0).cbrt(),
                    },
                )
            })?;
            self.rot[t] = r;
            self.e_star[t] = self.e_flow[t] + self.e_voigt[t] * voigt_share;
            let eps = (r.transpose() * f).sym() - M3::identity();
            let sigma =
                (dev(&eps) - self.e_star[t]) * (2.0 * g) + M3::identity() * (bulk * eps.trace());
            let p = r * sigma;
            let vol = block.volumes_m3[t];
            let gr = &block.grads[t];
            for (&n, g_k) in block.tets[t].iter().zip(gr) {
                self.rhs[n as usize] -= (p * *g_k) * vol;
            }
            let ke = &mut self.stiffness[t];
            tet_step_matrix(&r, gr, g, bulk, vol * dt, ke);
            for k in 0..4 {
                let n = block.tets[t][k] as usize;
                for a in 0..3 {
                    for b in 0..3 {
                        self.diag[n][(a, b)] += ke[(3 * k + a) * 12 + 3 * k + b];
                    }
                }
            }
        }
        Ok(())
    }

    /// Solves the step's system for the end-of-step velocities (in
    /// `v_new`) by preconditioned conjugate gradients from the linear
    /// extrapolation of the last two; returns the iterations. Fails when
    /// the solver stalls.
    fn solve_velocities(&mut self, dt: f64) -> Result<usize> {
        let block = self.block;
        for d in self.diag.iter_mut() {
            *d = invert_block(d);
        }
        for i in 0..self.v.len() {
            self.v_new[i] = self.v[i] * 2.0 - self.v_prev[i];
        }
        let (stiffness, contacts) = (&self.stiffness, &self.contacts);
        let mut apply = |v: &[V3], out: &mut [V3]| {
            for (i, (o, vi)) in out.iter_mut().zip(v).enumerate() {
                *o = *vi * (block.node_mass_kg[i] / dt);
            }
            for (t, ke) in stiffness.iter().enumerate() {
                apply_tet(&block.tets[t], ke, v, out);
            }
            contacts.add_apply(v, out);
        };
        let mut jacobi = block_jacobi(&self.diag);
        let (factor, flat) = (&self.factor, &mut self.flat);
        let mut precondition = |r: &[V3], z: &mut [V3]| match factor {
            Some(f) => {
                for (i, ri) in r.iter().enumerate() {
                    flat[3 * i] = ri.x;
                    flat[3 * i + 1] = ri.y;
                    flat[3 * i + 2] = ri.z;
                }
                f.solve_in_place(flat);
                for (i, zi) in z.iter_mut().enumerate() {
                    *zi = V3::new(flat[3 * i], flat[3 * i + 1], flat[3 * i + 2]);
                }
            }
            None => jacobi(r, z),
        };
        pcg(
            &mut apply,
            &mut precondition,
            &self.fixed,
            &self.rhs,
            &mut self.v_new,
            self.tolerance,
            5000,
            &mut self.work,
        )
        .map_err(|s| {
            self.unstable(
                dt,
                Instability::SolverStalled {
                    iterations: s.iterations,
                    residual: s.relative_residual,
                },
            )
        })
    }

    /// Takes the solved velocities and moves the nodes by them; fails on a
    /// non-finite node.
    #[inline]
    fn advance(&mut self, dt: f64) -> Result<()> {
        for i in 0..self.x.len() {
            self.v_prev[i] = self.v[i];
            self.v[i] = self.v_new[i];
            self.x[i] += self.v_new[i] * dt;
            if !(self.x[i].is_finite() && self.v[i].is_finite()) {
                return Err(self.unstable(dt, Instability::NonFinite { node: i }));
            }
        }
        Ok(())
    }

    /// The Burgers body's internal strains from the end-of-step strain
    /// (rotation of the step's start, as in the solve).
    #[inline]
    fn update_internal_states(&mut self, dt: f64, g: f64) {
        let m = self.material;
        let (eta2, eta1) = (
            m.retarded_viscosity_kpa_s * 1e3,
            m.flow_viscosity_kpa_s * 1e3,
        );
        let g2 = m.retarded_shear_kpa * 1e3;
        for t in 0..self.block.tets.len() {
            let f = self.deformation(t, &self.x);
            let eps = (self.rot[t].transpose() * f).sym() - M3::identity();
            let s = (dev(&eps) - self.e_star[t]) * (2.0 * g);
            self.e_voigt[t] = (s * 0.5 + self.e_voigt[t] * (eta2 / dt)) * (1.0 / (g2 + eta2 / dt));
            self.e_flow[t] += s * (dt / (2.0 * eta1));
        }
    }
}

/// `out += K_e v` for one tetrahedron's step matrix `ke` (12×12,
/// row-major, node-major xyz) and its nodes `tet`.
#[inline]
fn apply_tet(tet: &[u32; 4], ke: &[f64; 144], v: &[V3], out: &mut [V3]) {
    let mut x = [0.0; 12];
    for k in 0..4 {
        let vk = v[tet[k] as usize];
        x[3 * k] = vk.x;
        x[3 * k + 1] = vk.y;
        x[3 * k + 2] = vk.z;
    }
    for k in 0..4 {
        let mut y = [0.0; 3];
        for (a, ya) in y.iter_mut().enumerate() {
            let row = &ke[(3 * k + a) * 12..(3 * k + a) * 12 + 12];
            *ya = row.iter().zip(&x).map(|(r, x)| r * x).sum();
        }
        out[tet[k] as usize] += V3::new(y[0], y[1], y[2]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_polar_rotation_of_a_rotated_stretch_is_the_rotation() {
        let (c, s) = (0.6f64, 0.8f64);
        let r = M3 {
            m: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        };
        let stretch = M3 {
            m: [[1.2, 0.1, 0.0], [0.1, 0.9, 0.05], [0.0, 0.05, 1.1]],
        };
        let got = polar_rotation(&(r * stretch)).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((got[(i, j)] - r[(i, j)]).abs() < 1e-12);
            }
        }
        let mut mirror = M3::identity();
        mirror[(0, 0)] = -1.0;
        assert!(polar_rotation(&mirror).is_none());
    }

    #[test]
    fn the_analytic_step_matrix_equals_probing_the_force_change() {
        let b = ReferenceBlock::new([0.02, 0.01, 0.02], 0.01, [1, 1, 1]).unwrap();
        let r = polar_rotation(&M3 {
            m: [[0.9, -0.3, 0.1], [0.35, 0.95, 0.0], [-0.1, 0.05, 1.1]],
        })
        .unwrap();
        let (g, bulk) = (1.3e6, 9e6);
        for t in 0..b.tet_count() {
            let mut ke = [0.0; 144];
            tet_step_matrix(&r, &b.grads[t], g, bulk, 1.0, &mut ke);
            for col in 0..12 {
                let mut unit = [V3::zeros(); 4];
                unit[col / 3][col % 3] = 1.0;
                let out = tet_force_change(&r, &b.grads[t], g, bulk, &unit);
                for (k, o) in out.iter().enumerate() {
                    for a in 0..3 {
                        let want = o[a];
                        let got = ke[(3 * k + a) * 12 + col];
                        assert!(
                            (got - want).abs() < 1e-9 * want.abs().max(1.0),
                            "{got} vs {want}"
                        );
                    }
                }
            }
            // Symmetric.
            for i in 0..12 {
                for j in 0..12 {
                    let scale = ke[i * 12 + j].abs().max(1.0);
                    assert!((ke[i * 12 + j] - ke[j * 12 + i]).abs() < 1e-12 * scale);
                }
            }
        }
    }

    #[test]
    fn the_reference_mesh_fills_the_block_with_positive_tetrahedra() {
        let b = ReferenceBlock::new([0.1, 0.06, 0.1], 0.72, [3, 2, 3]).unwrap();
        assert_eq!(b.tet_count(), 3 * 2 * 3 * 6);
        assert!(b.volumes_m3.iter().all(|&v| v > 0.0));
        let v: f64 = b.volumes_m3.iter().sum();
        assert!((v - 6e-4).abs() < 1e-15);
        assert!((enclosed_volume_m3(&b.surface, &b.rest_m) - 6e-4).abs() < 1e-15);
        let m: f64 = b.node_mass_kg.iter().sum();
        assert!((m - 0.72).abs() < 1e-12);
        // Shape-function gradients sum to zero and reproduce a linear field.
        for (t, g) in b.grads.iter().enumerate() {
            let sum = g[0] + g[1] + g[2] + g[3];
            assert!(sum.norm() < 1e-9);
            let field = |p: V3| 2.0 * p.x - 3.0 * p.y + 0.5 * p.z;
            let grad: V3 = (0..4).fold(V3::zeros(), |acc, k| {
                acc + g[k] * field(b.rest_m[b.tets[t][k] as usize])
            });
            assert!((grad - V3::new(2.0, -3.0, 0.5)).norm() < 1e-9);
        }
    }
}
