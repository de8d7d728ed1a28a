//! Ground-truth generator: the "real object" the mass-spring model is
//! calibrated against, since no videos ship with the seed.
//!
//! It is deliberately a *different* model from the one being calibrated:
//! * a finer triangle mesh of linear co-rotational finite elements (plane
//!   stress, Young's modulus and Poisson ratio) instead of springs, with an
//!   optional viscoelastic arm (standard linear solid: a second element
//!   whose rest shape relaxes towards the current shape with time constant
//!   τ, i.e. a Maxwell arm in parallel with the long-term spring);
//! * Newtonian dynamics with real densities, mass-proportional damping and
//!   many small symplectic-Euler sub-steps instead of the first-order scheme;
//! * plasticity as flow of each element's rest shape under deviatoric
//!   strain beyond a yield strain (area-preserving, like J2 plasticity)
//!   instead of per-spring compression;
//! * sticking friction with the table (nodes that touch it do not slide);
//! * observation noise: Gaussian noise on every contour point and on the
//!   force-sensor reading, from a seeded ChaCha RNG.
//!
//! The material constants are estimates for a polyurethane sponge and for
//! modelling clay, scaled to px with the seed's camera scales. Left out:
//! viscoelasticity of the plasticine, more than one relaxation time,
//! contact friction with the finger, self-contact, out-of-plane effects.
use crate::error::{check_positive, check_range, PushError, Result};
use crate::mesh::Mesh;
use crate::scenario::{PushScenario, PushSite, PLASTICINE_SCALE_PX_PER_M, SPONGE_SCALE_PX_PER_M};
use crate::vec2::M2;
use crate::V2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};

/// Block depth along the camera axis, m (§VIII-A: 1.8 cm); the slab
/// thickness of the plane-stress elements.
pub const BLOCK_DEPTH_M: f64 = 0.018;

/// Hidden constitutive constants of a reference material.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReferenceMaterial {
    /// Young's modulus, Pa.
    pub youngs_modulus_pa: f64,
    pub poisson_ratio: f64,
    /// Density, kg/m³.
    pub density_kg_m3: f64,
    /// Deviatoric strain beyond which the rest shape flows (∞ = elastic).
    pub yield_strain: f64,
    /// Rate of plastic flow of the excess strain, 1/s.
    pub plastic_flow_rate_per_s: f64,
    /// Mass-proportional damping rate γ (v' = F/m − γ v), 1/s.
    pub damping_rate_per_s: f64,
    /// Young's modulus of the viscoelastic (Maxwell) arm, Pa: the stiffness
    /// added on fast loading, relaxing with [`Self::relaxation_time_s`]
    /// (0 = no arm, purely elastic). `youngs_modulus_pa` is then the
    /// relaxed (long-term) modulus. Same Poisson ratio.
    pub relaxing_modulus_pa: f64,
    /// Relaxation time τ of the viscoelastic arm, s.
    pub relaxation_time_s: f64,
    /// Camera scale of the videos of this material, px/m.
    pub scale_px_per_m: f64,
}

impl ReferenceMaterial {
    /// A soft polyurethane sponge, no plasticity. All constants are
    /// estimates, fixed before the Table II protocol was re-run with them
    /// and not changed after:
    /// * relaxed modulus E∞ ≈ 30 kPa, ν ≈ 0.1 (soft open-cell foam);
    /// * real density, 30 kg/m³ (flexible PU foam is 20–40 kg/m³; the
    ///   earlier ×10 mass scaling is dropped, generation takes ~3× longer);
    /// * viscoelasticity as one standard-linear-solid arm, E₁ = 15 kPa
    ///   (E₁/E∞ = 0.5) with τ = 1 s: its loss factor peaks at
    ///   tan δ = E₁/(2√(E∞(E∞+E₁))) ≈ 0.20 at ω ≈ 0.8 rad/s, the time scale
    ///   of the 17 s push and retrieval; flexible PU foam has tan δ ≈ 0.1–0.3
    ///   at room temperature and relaxes over seconds (estimate);
    /// * mass-proportional damping γ = 32 /s, the same damping ratio
    ///   (ζ ≈ 1.1) as before for the first mode, which the ÷10 mass raises
    ///   by √10 (ω₁ ≈ 4.6 → 14.5 rad/s). It stands in for the damping of
    ///   the high modes that one relaxation time leaves undamped.
    ///
    /// Scale: §VIII-A.
    pub const SPONGE: Self = Self {
        youngs_modulus_pa: 30.0e3,
        poisson_ratio: 0.1,
        density_kg_m3: 30.0,
        yield_strain: f64::INFINITY,
        plastic_flow_rate_per_s: 0.0,
        damping_rate_per_s: 32.0,
        relaxing_modulus_pa: 15.0e3,
        relaxation_time_s: 1.0,
        scale_px_per_m: SPONGE_SCALE_PX_PER_M,
    };
    /// Modelling clay (estimates: E ≈ 300 kPa, ν ≈ 0.4, ρ ≈ 1800 kg/m³,
    /// yields at 3 % deviatoric strain and flows quickly; damping near
    /// critical for the first mode, ω₁ ≈ 6 rad/s). Scale: §VIII-A.
    pub const PLASTICINE: Self = Self {
        youngs_modulus_pa: 300.0e3,
        poisson_ratio: 0.4,
        density_kg_m3: 1800.0,
        yield_strain: 0.03,
        plastic_flow_rate_per_s: 20.0,
        damping_rate_per_s: 12.0,
        relaxing_modulus_pa: 0.0,
        relaxation_time_s: 1.0,
        scale_px_per_m: PLASTICINE_SCALE_PX_PER_M,
    };

    pub fn validate(&self) -> Result<()> {
        check_positive("youngs_modulus_pa", self.youngs_modulus_pa)?;
        check_range("poisson_ratio", self.poisson_ratio, 0.0, 0.49)?;
        check_positive("density_kg_m3", self.density_kg_m3)?;
        if self.yield_strain.is_nan() || self.yield_strain <= 0.0 {
            return Err(PushError::InvalidParameter {
                name: "yield_strain",
                value: self.yield_strain,
                reason: "must be > 0 (∞ for elastic)",
            });
        }
        check_range(
            "plastic_flow_rate_per_s",
            self.plastic_flow_rate_per_s,
            0.0,
            1e6,
        )?;
        check_range("damping_rate_per_s", self.damping_rate_per_s, 0.0, 1e6)?;
        check_range("relaxing_modulus_pa", self.relaxing_modulus_pa, 0.0, 1e12)?;
        check_positive("relaxation_time_s", self.relaxation_time_s)?;
        check_positive("scale_px_per_m", self.scale_px_per_m)?;
        Ok(())
    }
}

/// How the ground truth is produced and observed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ReferenceConfig {
    /// Target side of the fine mesh's squares, px.
    pub element_size_px: f64,
    /// Standard deviation of the noise on each contour point, px (estimate
    /// of a snake tracker's error).
    pub contour_noise_px: f64,
    /// Standard deviation of the force-sensor noise, N (estimate).
    pub force_noise_n: f64,
    /// Seed of the observation noise.
    pub seed: u64,
}

impl Default for ReferenceConfig {
    fn default() -> Self {
        Self {
            element_size_px: 8.0,
            contour_noise_px: 1.0,
            force_noise_n: 0.05,
            seed: 1,
        }
    }
}

/// One recorded push: what a camera and a wrist force sensor would give.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Video {
    /// Label of the material (e.g. "sponge").
    pub material: String,
    pub scenario: PushScenario,
    /// Tracked contour per frame, px (noisy).
    #[serde(with = "contours_serde")]
    pub contours_px: Vec<Vec<V2>>,
    /// Force-sensor reading per frame along the push direction, N (noisy).
    pub forces_n: Vec<f64>,
}

impl Video {
    /// Checks the series line up and hold finite numbers.
    pub fn validate(&self) -> Result<()> {
        self.scenario.validate()?;
        let n = self.scenario.frame_count();
        if self.contours_px.len() != n {
            return Err(PushError::LengthMismatch {
                what: "contours_px",
                got: self.contours_px.len(),
                expected: n,
            });
        }
        if self.forces_n.len() != n {
            return Err(PushError::LengthMismatch {
                what: "forces_n",
                got: self.forces_n.len(),
                expected: n,
            });
        }
        for (f, c) in self.contours_px.iter().enumerate() {
            if c.len() < 3 {
                return Err(PushError::MalformedInput {
                    location: format!("frame {f}"),
                    reason: "contour has fewer than 3 points".into(),
                });
            }
            if c.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
                return Err(PushError::MalformedInput {
                    location: format!("frame {f}"),
                    reason: "contour has a non-finite point".into(),
                });
            }
        }
        if let Some(f) = self.forces_n.iter().position(|x| !x.is_finite()) {
            return Err(PushError::MalformedInput {
                location: format!("frame {f}"),
                reason: "force reading is not finite".into(),
            });
        }
        Ok(())
    }
}

/// Per-element state of the finite-element block.
#[derive(Debug, Clone)]
struct Element {
    nodes: [usize; 3],
    /// Rest edge matrix [X1 − X0, X2 − X0], px (changes with plastic flow).
    rest: M2,
    rest_inv: M2,
    /// Rest area, px².
    area_px2: f64,
    /// Rest edge matrix of the viscoelastic arm, px (relaxes towards the
    /// current shape), its inverse and area.
    arm_rest: M2,
    arm_rest_inv: M2,
    arm_area_px2: f64,
}

/// The finite-element reference simulation.
pub struct ReferenceBlock {
    mesh: Mesh,
    elements: Vec<Element>,
    pos: Vec<V2>,
    vel: Vec<V2>,
    mass: Vec<f64>,
    force: Vec<V2>,
    table_anchor_x: Vec<Option<f64>>,
    mu: f64,
    lambda: f64,
    /// Lamé constants of the viscoelastic arm, N/px (0 without one).
    arm_mu: f64,
    arm_lambda: f64,
    material: ReferenceMaterial,
    dt_s: f64,
}

/// 2D polar decomposition: the rotation nearest to `f`.
#[inline]
fn rotation_of(f: &M2) -> M2 {
    let th = (f.c - f.b).atan2(f.a + f.d);
    let (s, c) = th.sin_cos();
    M2 {
        a: c,
        b: -s,
        c: s,
        d: c,
    }
}

impl ReferenceBlock {
    /// A block of `width_px × height_px` on the table, at rest.
    pub fn new(
        material: ReferenceMaterial,
        width_px: f64,
        height_px: f64,
        element_size_px: f64,
    ) -> Result<Self> {
        material.validate()?;
        check_positive("element_size_px", element_size_px)?;
        let (nx, ny) = (
            (width_px / element_size_px).round(),
            (height_px / element_size_px).round(),
        );
        // Mesh::grid's own limit, checked here so that the error names the
        // element size the caller chose rather than the grid's `nx`/`ny`.
        if nx.max(ny) > crate::mesh::MAX_SQUARES_PER_SIDE as f64 {
            return Err(PushError::InvalidParameter {
                name: "element_size_px",
                value: element_size_px,
                reason: "too small for the block: more than 2000 elements per side",
            });
        }
        let nx = (nx as usize).max(2);
        let ny = (ny as usize).max(2);
        let mesh = Mesh::grid(V2::zeros(), width_px, height_px, nx, ny)?;
        let scale = material.scale_px_per_m;
        // Plane stress with the slab thickness folded into the modulus:
        // E·t in N/m, then per px.
        let e_2d = material.youngs_modulus_pa * BLOCK_DEPTH_M / scale; // N/px
        let nu = material.poisson_ratio;
        let mu = e_2d / (2.0 * (1.0 + nu));
        let lambda = e_2d * nu / (1.0 - nu * nu);
        let arm_e_2d = material.relaxing_modulus_pa * BLOCK_DEPTH_M / scale;
        let arm_mu = arm_e_2d / (2.0 * (1.0 + nu));
        let arm_lambda = arm_e_2d * nu / (1.0 - nu * nu);
        let areal_mass = material.density_kg_m3 * BLOCK_DEPTH_M / (scale * scale); // kg/px²
        let n = mesh.vertex_count();
        let mut mass = vec![0.0; n];
        let mut elements = Vec::with_capacity(mesh.triangles.len());
        for &[a, b, c] in &mesh.triangles {
            let p = &mesh.rest_positions_px;
            let rest = M2::from_columns(p[b] - p[a], p[c] - p[a]);
            let area = 0.5 * rest.det();
            let rest_inv = rest
                .inverse()
                .ok_or_else(|| PushError::InvalidMesh("singular reference element".into()))?;
            for v in [a, b, c] {
                mass[v] += areal_mass * area / 3.0;
            }
            elements.push(Element {
                nodes: [a, b, c],
                rest,
                rest_inv,
                area_px2: area,
                arm_rest: rest,
                arm_rest_inv: rest_inv,
                arm_area_px2: area,
            });
        }
        // Stable explicit step: a fraction of the time a P-wave needs to
        // cross the smallest element side (unrelaxed: both arms stiff).
        let wave_speed = ((lambda + arm_lambda + 2.0 * (mu + arm_mu)) / areal_mass).sqrt(); // px/s
        let h_min = (width_px / nx as f64).min(height_px / ny as f64);
        let dt_s = 0.3 * h_min / wave_speed;
        let table_anchor_x = mesh
            .rest_positions_px
            .iter()
            .map(|p| if p.y <= 0.0 { Some(p.x) } else { None })
            .collect();
        Ok(Self {
            pos: mesh.rest_positions_px.clone(),
            vel: vec![V2::zeros(); n],
            force: vec![V2::zeros(); n],
            mass,
            elements,
            mesh,
            table_anchor_x,
            mu,
            lambda,
            arm_mu,
            arm_lambda,
            material,
            dt_s,
        })
    }

    pub fn mesh(&self) -> &Mesh {
        &self.mesh
    }
    pub fn positions_px(&self) -> &[V2] {
        &self.pos
    }
    pub fn substep_s(&self) -> f64 {
        self.dt_s
    }

    /// Elastic and viscoelastic forces of all elements into `self.force`,
    /// N; then the viscoelastic arms relax over `dt_s` (from the same
    /// state, explicit like the rest of the sub-step).
    fn compute_forces(&mut self, dt_s: f64) {
        self.force.iter_mut().for_each(|f| *f = V2::zeros());
        let arm_kappa = (dt_s / self.material.relaxation_time_s).min(1.0);
        for el in &mut self.elements {
            let [a, b, c] = el.nodes;
            let ds = M2::from_columns(self.pos[b] - self.pos[a], self.pos[c] - self.pos[a]);
            let f = ds * el.rest_inv;
            let r = rotation_of(&f);
            let strain_trace = (r.transpose() * f).trace() - 2.0;
            let p = (f - r).scale(2.0 * self.mu) + r.scale(self.lambda * strain_trace);
            let h = (p * el.rest_inv.transpose()).scale(-el.area_px2);
            let f1 = h.col0();
            let f2 = h.col1();
            self.force[b] += f1;
            self.force[c] += f2;
            self.force[a] -= f1 + f2;
            if self.arm_mu > 0.0 {
                // Maxwell arm: the same co-rotational element on its own
                // rest shape, which then moves towards the current
                // (unrotated) shape at rate 1/τ, so the arm's strain obeys
                // ε' = ε̇_total − ε/τ.
                let f = ds * el.arm_rest_inv;
                let r = rotation_of(&f);
                let s = r.transpose() * f;
                let strain_trace = s.trace() - 2.0;
                let p = (f - r).scale(2.0 * self.arm_mu) + r.scale(self.arm_lambda * strain_trace);
                let h = (p * el.arm_rest_inv.transpose()).scale(-el.arm_area_px2);
                let f1 = h.col0();
                let f2 = h.col1();
                self.force[b] += f1;
                self.force[c] += f2;
                self.force[a] -= f1 + f2;
                let stretch = (s + s.transpose()).scale(0.5);
                let rest = (M2::IDENTITY + (stretch - M2::IDENTITY).scale(arm_kappa)) * el.arm_rest;
                let det = rest.det();
                if det > 0.0 {
                    if let Some(inv) = rest.inverse() {
                        el.arm_rest = rest;
                        el.arm_rest_inv = inv;
                        el.arm_area_px2 = 0.5 * det;
                    }
                }
            }
        }
    }

    /// Plastic flow of each element's rest shape (deviatoric, so the rest
    /// area is kept to first order).
    fn plastic_flow(&mut self, dt_s: f64) {
        let yield_strain = self.material.yield_strain;
        if !yield_strain.is_finite() || self.material.plastic_flow_rate_per_s == 0.0 {
            return;
        }
        let rate = (self.material.plastic_flow_rate_per_s * dt_s).min(1.0);
        for el in &mut self.elements {
            let [a, b, c] = el.nodes;
            let ds = M2::from_columns(self.pos[b] - self.pos[a], self.pos[c] - self.pos[a]);
            let f = ds * el.rest_inv;
            let r = rotation_of(&f);
            let s = r.transpose() * f;
            let eps = (s + s.transpose()).scale(0.5) - M2::IDENTITY;
            let dev = eps - M2::IDENTITY.scale(0.5 * eps.trace());
            let e = dev.norm();
            if e > yield_strain && e.is_finite() {
                // At most 10 % strain flows per sub-step (keeps the update
                // well-conditioned near the finger).
                let kappa = (rate * (e - yield_strain) / e).min(0.1 / e);
                let rest = (M2::IDENTITY + dev.scale(kappa)) * el.rest;
                let det = rest.det();
                if det > 0.0 {
                    if let Some(inv) = rest.inverse() {
                        el.rest = rest;
                        el.rest_inv = inv;
                        el.area_px2 = 0.5 * det;
                    }
                }
            }
        }
    }

    /// One sub-step with the finger at `finger_centre_px`. Returns the force
    /// the block exerts on the finger along −`push_dir` (the sensor's
    /// reading), N.
    fn substep(&mut self, finger_centre_px: V2, finger_radius_px: f64, push_dir: V2) -> f64 {
        let dt = self.dt_s;
        self.compute_forces(dt);
        let mut reaction = 0.0;
        for i in 0..self.pos.len() {
            let d = self.pos[i] - finger_centre_px;
            if d.norm() <= finger_radius_px + 0.5 {
                // The finger holds this node: the node's elastic force is
                // what presses on the finger.
                reaction += (-self.force[i].dot(&push_dir)).max(0.0);
            }
            let damp = self.material.damping_rate_per_s;
            let acc = self.force[i] / self.mass[i] - self.vel[i] * damp;
            self.vel[i] += acc * dt;
            self.pos[i] += self.vel[i] * dt;
        }
        for i in 0..self.pos.len() {
            // Finger: project out radially, remove the inward velocity.
            let d = self.pos[i] - finger_centre_px;
            let n = d.norm();
            if n < finger_radius_px {
                let dir = if n > 1e-12 { d / n } else { -push_dir };
                self.pos[i] = finger_centre_px + dir * finger_radius_px;
                let vn = self.vel[i].dot(&dir);
                if vn < 0.0 {
                    self.vel[i] -= dir * vn;
                }
            }
            // Table with sticking friction.
            if self.pos[i].y <= 0.0 {
                self.pos[i].y = 0.0;
                let ax = *self.table_anchor_x[i].get_or_insert(self.pos[i].x);
                self.pos[i].x = ax;
                self.vel[i] = V2::zeros();
            } else if self.pos[i].y > 0.5 {
                self.table_anchor_x[i] = None;
            }
        }
        self.plastic_flow(dt);
        reaction
    }
}

/// Records a push of `material` as a [`Video`]: the fine finite-element
/// block driven by the scenario's finger, observed with noise.
pub fn record_push(
    label: &str,
    material: ReferenceMaterial,
    scenario: &PushScenario,
    config: &ReferenceConfig,
) -> Result<Video> {
    scenario.validate()?;
    check_range("contour_noise_px", config.contour_noise_px, 0.0, 1e3)?;
    check_range("force_noise_n", config.force_noise_n, 0.0, 1e6)?;
    let mut block = ReferenceBlock::new(
        material,
        scenario.block_width_px,
        scenario.block_height_px,
        config.element_size_px,
    )?;
    // Different seeds per site so the three pushes get independent noise.
    let site_salt = match scenario.site {
        PushSite::MiddleLongSide => 11,
        PushSite::NearCorner => 23,
        PushSite::MiddleShortSide => 37,
    };
    let mut rng =
        ChaCha8Rng::seed_from_u64(config.seed.wrapping_mul(1_000_003).wrapping_add(site_salt));
    let contour_noise = Normal::new(0.0, config.contour_noise_px.max(1e-300)).map_err(|_| {
        PushError::InvalidParameter {
            name: "contour_noise_px",
            value: config.contour_noise_px,
            reason: "not a valid standard deviation",
        }
    })?;
    let force_noise = Normal::new(0.0, config.force_noise_n.max(1e-300)).map_err(|_| {
        PushError::InvalidParameter {
            name: "force_noise_n",
            value: config.force_noise_n,
            reason: "not a valid standard deviation",
        }
    })?;
    let n_frames = scenario.frame_count();
    let push_dir = scenario.push_direction();
    let mut contours = Vec::with_capacity(n_frames);
    let mut forces = Vec::with_capacity(n_frames);
    let mut t = 0.0;
    let mut reaction = 0.0;
    for f in 0..n_frames {
        let t_frame = scenario.frame_time_s(f);
        // Advance to the frame time with whole sub-steps of at most dt.
        let span = t_frame - t;
        if span > 0.0 {
            let k = (span / block.dt_s).ceil().max(1.0) as usize;
            let dt = span / k as f64;
            let saved = block.dt_s;
            block.dt_s = dt;
            for s in 1..=k {
                let ts = t + dt * s as f64;
                let finger = scenario.finger_at(ts);
                reaction = block.substep(finger.centre_px, finger.radius_px, push_dir);
            }
            block.dt_s = saved;
            t = t_frame;
        }
        if let Some(i) = block
            .pos
            .iter()
            .position(|p| !(p.x.is_finite() && p.y.is_finite()))
        {
            return Err(PushError::MalformedInput {
                location: format!("reference simulation, frame {f}, node {i}"),
                reason: "the finite-element block became unstable (non-finite position); try a larger element_size_px".into(),
            });
        }
        let contour: Vec<V2> = block
            .mesh
            .boundary_loop
            .iter()
            .map(|&i| {
                let p = block.pos[i];
                if config.contour_noise_px > 0.0 {
                    V2::new(
                        p.x + contour_noise.sample(&mut rng),
                        p.y + contour_noise.sample(&mut rng),
                    )
                } else {
                    p
                }
            })
            .collect();
        contours.push(contour);
        let noise = if config.force_noise_n > 0.0 {
            force_noise.sample(&mut rng)
        } else {
            0.0
        };
        forces.push(reaction + noise);
    }
    Ok(Video {
        material: label.to_string(),
        scenario: *scenario,
        contours_px: contours,
        forces_n: forces,
    })
}

/// The six videos of §VIII: sponge and plasticine, three sites each.
pub fn seed_videos(config: &ReferenceConfig) -> Result<Vec<Video>> {
    let mut out = Vec::new();
    for (label, mat) in [
        ("sponge", ReferenceMaterial::SPONGE),
        ("plasticine", ReferenceMaterial::PLASTICINE),
    ] {
        for site in PushSite::ALL {
            let sc = PushScenario::seed(site, mat.scale_px_per_m)?;
            out.push(record_push(label, mat, &sc, config)?);
        }
    }
    Ok(out)
}

/// Contours as nested `[x, y]` arrays in JSON (nalgebra's serde feature is
/// not enabled in this crate).
mod contours_serde {
    use crate::V2;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};
    pub fn serialize<S: Serializer>(c: &[Vec<V2>], s: S) -> Result<S::Ok, S::Error> {
        let v: Vec<Vec<[f64; 2]>> = c
            .iter()
            .map(|f| f.iter().map(|p| [p.x, p.y]).collect())
            .collect();
        v.serialize(s)
    }
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<V2>>, D::Error> {
        let v: Vec<Vec<[f64; 2]>> = Vec::deserialize(d)?;
        Ok(v.into_iter()
            .map(|f| f.into_iter().map(|p| V2::new(p[0], p[1])).collect())
            .collect())
    }
}
