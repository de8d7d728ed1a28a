//! Time stepping of the mass-spring model: the three integrators compared in
//! Table II of the seed, the driving modes of §VI-F, plasticity after each
//! step and detection of unstable runs.
//!
//! One step, in order: internal forces at p(t) (Eq. 20, 23, 26) plus the
//! finger's sensed force on each vertex it touches (§VIII-A), capped per
//! vertex at max(F); the integrator; repair of reversed and flat triangles
//! (§VI-E, optional); finger collision by vertex then by edge (§VI-D, in the
//! collision modes); the table; Algorithm 2 on every spring; the stability
//! check. Masses are all 1 (§VII-A).
//!
//! Left out: sub-stepping, adaptive steps, any implicit solver.
use crate::collision::{repair_triangles, Finger, Table};
use crate::error::{check_positive, Result};
use crate::forces::{accumulate_internal_forces, clamp_forces, length_force, MaterialParams};
use crate::mesh::Mesh;
use crate::plasticity::update_alpha;
use crate::V2;
use serde::{Deserialize, Serialize};

/// Vertex mass (§VII-A: unitary masses).
pub const VERTEX_MASS: f64 = 1.0;

/// Extra distance beyond the finger radius within which a vertex counts as
/// touched by the finger and receives the sensed force, px (estimate: twice
/// the collision clearance ε, so vertices the collision routine parked at
/// radius + ε are still counted).
pub const CONTACT_MARGIN_PX: f64 = 1.0;

/// The integration schemes of §VI-C and Table II.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Integrator {
    /// The seed's first-order scheme, Eq. 13–15: p(t+h) = p(t) + h F(t)/m.
    Customised,
    /// Explicit (forward) Euler on Newton's law, Eq. 6.
    Euler,
    /// Position Verlet on Newton's law, Eq. 6.
    Verlet,
    /// Eq. 15 applied spring by spring: each length spring (Eq. 20) moves
    /// its two ends by h·F/m at once, in mesh edge order, so the next spring
    /// sees positions already moved (a Gauss–Seidel sweep); area, angle and
    /// finger forces are summed at p(t) and applied after the sweep, as in
    /// [`Integrator::Customised`]. Not in the seed's text: a reading of it.
    /// The seed's own Fig. 14 sponge parameters (k_L = 3034.48 on a 20×10
    /// mesh, h = 0.1 s, which the seed found no better at h = 0.01 s)
    /// amplify any perturbation into a torn mesh (bounded only by max(F))
    /// under the printed simultaneous update on a block of the seed's size
    /// in pixels, and stay at rest under this one
    /// (`seed_fig14_parameters_need_the_spring_by_spring_update`).
    /// Not one of Table II's three schemes ([`Integrator::ALL`]).
    CustomisedSequential,
}

impl Integrator {
    pub const ALL: [Integrator; 3] = [
        Integrator::Customised,
        Integrator::Euler,
        Integrator::Verlet,
    ];
    /// Table II's three and the spring-by-spring reading of Eq. 15.
    pub const WITH_VARIANTS: [Integrator; 4] = [
        Integrator::Customised,
        Integrator::Euler,
        Integrator::Verlet,
        Integrator::CustomisedSequential,
    ];
    /// The integrator called `name` (as [`Integrator::name`] prints it).
    pub fn from_name(name: &str) -> Option<Integrator> {
        Self::WITH_VARIANTS.into_iter().find(|i| i.name() == name)
    }
    pub fn name(self) -> &'static str {
        match self {
            Integrator::Customised => "customised",
            Integrator::Euler => "euler",
            Integrator::Verlet => "verlet",
            Integrator::CustomisedSequential => "customised-seq",
        }
    }
}

/// How the finger drives the mesh (§VI-F).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum DrivingMode {
    /// 1) Collision detection only; no force sensor.
    CollisionOnly,
    /// 2) Sensed forces on the vertices under the finger; no collision.
    ForcesOnVertices,
    /// 3) Both.
    CollisionAndForces,
}

impl DrivingMode {
    pub fn uses_collision(self) -> bool {
        !matches!(self, DrivingMode::ForcesOnVertices)
    }
    pub fn uses_forces(self) -> bool {
        !matches!(self, DrivingMode::CollisionOnly)
    }
    pub fn name(self) -> &'static str {
        match self {
            DrivingMode::CollisionOnly => "collision",
            DrivingMode::ForcesOnVertices => "forces",
            DrivingMode::CollisionAndForces => "both",
        }
    }
}

/// Settings that are not learned.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SimConfig {
    pub integrator: Integrator,
    pub mode: DrivingMode,
    /// Integration step h, s (§VII-A: 0.1 s).
    pub step_s: f64,
    /// Apply the §VI-E repair of reversed and flat triangles.
    pub geometric_repair: bool,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            integrator: Integrator::Customised,
            mode: DrivingMode::CollisionAndForces,
            step_s: crate::scenario::STEP_S,
            geometric_repair: true,
        }
    }
}

/// Why a run was declared unstable.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Instability {
    /// A coordinate became NaN or infinite.
    NonFinite { vertex: usize },
    /// A vertex flew further from the block than [`Simulator::escape_distance_px`].
    Escaped { vertex: usize, distance_px: f64 },
    /// The mesh's total signed area left [0.1, 10]× its rest area.
    AreaCollapse { area_ratio: f64 },
}

impl std::fmt::Display for Instability {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Instability::NonFinite { vertex } => {
                write!(f, "vertex {vertex} has a non-finite coordinate")
            }
            Instability::Escaped {
                vertex,
                distance_px,
            } => write!(
                f,
                "vertex {vertex} flew {} px from the block",
                plant_common::short_number(*distance_px)
            ),
            Instability::AreaCollapse { area_ratio } => write!(
                f,
                "the mesh's area is {}× its rest area (allowed 0.1–10×)",
                plant_common::short_number(*area_ratio)
            ),
        }
    }
}

/// The state of one mass-spring simulation.
#[derive(Debug, Clone)]
pub struct Simulator<'m> {
    mesh: &'m Mesh,
    params: MaterialParams,
    config: SimConfig,
    table: Table,
    positions_px: Vec<V2>,
    prev_positions_px: Vec<V2>,
    velocities_px_s: Vec<V2>,
    alpha: Vec<f64>,
    rest_len_px: Vec<f64>,
    forces: Vec<V2>,
    rest_centroid_px: V2,
    rest_area_px2: f64,
    escape_distance_px: f64,
    time_s: f64,
    instability: Option<Instability>,
}

impl<'m> Simulator<'m> {
    /// A simulation at rest in the mesh's rest shape.
    pub fn new(
        mesh: &'m Mesh,
        params: MaterialParams,
        config: SimConfig,
        table: Table,
    ) -> Result<Self> {
        params.validate()?;
        check_positive("step_s", config.step_s)?;
        let n = mesh.vertex_count();
        let rest = mesh.rest_positions_px.clone();
        let centroid = rest.iter().fold(V2::zeros(), |a, p| a + p) / n as f64;
        let (mut lo, mut hi) = (rest[0], rest[0]);
        for p in &rest {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        Ok(Self {
            mesh,
            params,
            config,
            table,
            prev_positions_px: rest.clone(),
            positions_px: rest,
            velocities_px_s: vec![V2::zeros(); n],
            alpha: vec![0.0; mesh.edges.len()],
            rest_len_px: mesh.rest_lengths_px.clone(),
            forces: vec![V2::zeros(); n],
            rest_centroid_px: centroid,
            rest_area_px2: mesh.total_area_px2(&mesh.rest_positions_px),
            // Estimate: ten block diagonals is far beyond any real push.
            escape_distance_px: 10.0 * (hi - lo).norm(),
            time_s: 0.0,
            instability: None,
        })
    }

    pub fn positions_px(&self) -> &[V2] {
        &self.positions_px
    }
    pub fn mesh(&self) -> &Mesh {
        self.mesh
    }
    pub fn alpha(&self) -> &[f64] {
        &self.alpha
    }
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    pub fn instability(&self) -> Option<Instability> {
        self.instability
    }
    pub fn escape_distance_px(&self) -> f64 {
        self.escape_distance_px
    }
    /// Sets positions (and zero velocity) — for tests and for feeding a mesh
    /// back in (§VI-F).
    pub fn set_positions(&mut self, positions_px: &[V2]) {
        self.positions_px.copy_from_slice(positions_px);
        self.prev_positions_px.copy_from_slice(positions_px);
        self.velocities_px_s
            .iter_mut()
            .for_each(|v| *v = V2::zeros());
    }

    /// Current velocities as the integrator sees them, px/s.
    fn refresh_velocities(&mut self) {
        if self.config.integrator != Integrator::Euler {
            let inv_h = 1.0 / self.config.step_s;
            for ((v, p), q) in self
                .velocities_px_s
                .iter_mut()
                .zip(&self.positions_px)
                .zip(&self.prev_positions_px)
            {
                *v = (*p - *q) * inv_h;
            }
        }
    }

    /// Adds the radial component of the sensed finger force at every
    /// vertex within the finger's reach (§VIII-A: "the radial component of
    /// the registered force is applied at any vertex that happens to be
    /// located within the radius of the robotic finger"; §VI-F mode 2: "the
    /// forces to be applied on the vertices around the actuator are
    /// approximated by the measured reaction forces"). Each touched vertex
    /// gets the reading's component along its own radius, not a share of
    /// it: the seed divides the reading nowhere, and with unit masses a
    /// share (1/3 to 1/16 of a few N on a 20×10 mesh) moves a vertex by
    /// less than 0.1 px per step, so forces alone could not dent the block.
    /// Returns how many vertices were touched.
    fn add_finger_force(&mut self, finger: &Finger, force_on_object: V2) -> usize {
        let reach = finger.radius_px + CONTACT_MARGIN_PX;
        let mut touched = 0usize;
        for (p, f) in self.positions_px.iter().zip(self.forces.iter_mut()) {
            let d = p - finger.centre_px;
            let n = d.norm();
            if n <= reach {
                touched += 1;
                let radial = if n > 1e-12 {
                    d / n
                } else {
                    force_on_object.normalize()
                };
                let along = force_on_object.dot(&radial);
                if along > 0.0 {
                    *f += radial * along;
                }
            }
        }
        touched
    }

    /// Advances one step h. `finger` is the finger at t + h; `force_on_object`
    /// is the sensed force at t + h (what the finger exerts on the block).
    /// Once unstable, the state is frozen and the reason returned.
    pub fn step(
        &mut self,
        finger: Option<&Finger>,
        force_on_object: Option<V2>,
    ) -> core::result::Result<(), Instability> {
        if let Some(i) = self.instability {
            return Err(i);
        }
        let h = self.config.step_s;
        self.gather_forces(finger, force_on_object);
        self.integrate(h);
        self.resolve_contacts(finger);
        self.yield_compressed_springs();
        self.time_s += h;
        if let Some(i) = self.check_stability() {
            self.instability = Some(i);
            return Err(i);
        }
        Ok(())
    }

    /// The forces of this step at p(t): the springs (less the length
    /// springs the sequential sweep applies itself), the sensed finger
    /// force when the mode uses it, each capped at max(F).
    #[inline]
    fn gather_forces(&mut self, finger: Option<&Finger>, force_on_object: Option<V2>) {
        self.refresh_velocities();
        self.forces.iter_mut().for_each(|f| *f = V2::zeros());
        let sequential = self.config.integrator == Integrator::CustomisedSequential;
        // The sequential sweep applies the length springs itself.
        let summed = if sequential {
            MaterialParams {
                k_length: 0.0,
                k_damping: 0.0,
                ..self.params
            }
        } else {
            self.params
        };
        accumulate_internal_forces(
            self.mesh,
            &self.positions_px,
            &self.velocities_px_s,
            &self.rest_len_px,
            &summed,
            &mut self.forces,
        );
        if self.config.mode.uses_forces() {
            if let (Some(fg), Some(fo)) = (finger, force_on_object) {
                if fo.norm() > 0.0 {
                    self.add_finger_force(fg, fo);
                }
            }
        }
        clamp_forces(&mut self.forces, self.params.max_force);
    }

    /// Moves the vertices by the gathered forces over `h`, as the
    /// integrator says (the previous positions kept for velocities).
    #[inline]
    fn integrate(&mut self, h: f64) {
        let inv_m = 1.0 / VERTEX_MASS;
        match self.config.integrator {
            Integrator::CustomisedSequential => {
                self.prev_positions_px.copy_from_slice(&self.positions_px);
                self.sweep_length_springs(h * inv_m);
                for (p, f) in self.positions_px.iter_mut().zip(&self.forces) {
                    *p += f * (h * inv_m);
                }
            }
            Integrator::Customised => {
                for ((p, q), f) in self
                    .positions_px
                    .iter_mut()
                    .zip(self.prev_positions_px.iter_mut())
                    .zip(&self.forces)
                {
                    *q = *p;
                    *p += f * (h * inv_m);
                }
            }
            Integrator::Euler => {
                for (((p, q), v), f) in self
                    .positions_px
                    .iter_mut()
                    .zip(self.prev_positions_px.iter_mut())
                    .zip(self.velocities_px_s.iter_mut())
                    .zip(&self.forces)
                {
                    *q = *p;
                    *p += *v * h;
                    *v += f * (h * inv_m);
                }
            }
            Integrator::Verlet => {
                for ((p, q), f) in self
                    .positions_px
                    .iter_mut()
                    .zip(self.prev_positions_px.iter_mut())
                    .zip(&self.forces)
                {
                    let next = *p * 2.0 - *q + f * (h * h * inv_m);
                    *q = *p;
                    *p = next;
                }
            }
        }
    }

    /// The spring-by-spring update of Eq. 15: each length spring moves its
    /// two ends by `h_over_m`·F at once, in mesh edge order.
    #[inline]
    fn sweep_length_springs(&mut self, h_over_m: f64) {
        let cap = self.params.max_force;
        for (k, &[i, j]) in self.mesh.edges.iter().enumerate() {
            let mut f = length_force(
                self.positions_px[i],
                self.positions_px[j],
                self.velocities_px_s[i],
                self.velocities_px_s[j],
                self.mesh.rest_lengths_px[k],
                self.rest_len_px[k],
                self.params.k_length,
                self.params.k_damping,
            );
            // max(F) caps each spring's push here, the summed
            // remainder after the sweep.
            let n = f.norm();
            if n > cap {
                f *= cap / n;
            }
            self.positions_px[i] += f * h_over_m;
            self.positions_px[j] -= f * h_over_m;
        }
    }

    /// The geometric repair, then the finger (when the mode collides) and
    /// the table push the vertices out of themselves.
    #[inline]
    fn resolve_contacts(&mut self, finger: Option<&Finger>) {
        if self.config.geometric_repair {
            repair_triangles(self.mesh, &mut self.positions_px);
        }
        if self.config.mode.uses_collision() {
            if let Some(fg) = finger {
                let up = V2::new(0.0, 1.0);
                fg.resolve_vertices(&mut self.positions_px, up);
                fg.resolve_edges(&self.mesh.edges, &mut self.positions_px, up);
            }
        }
        self.table.resolve(&mut self.positions_px);
    }

    /// Plasticity (Algorithm 2): a spring compressed below its rest
    /// length yields, shortening its rest length.
    #[inline]
    fn yield_compressed_springs(&mut self) {
        for (k, &[i, j]) in self.mesh.edges.iter().enumerate() {
            let l = (self.positions_px[j] - self.positions_px[i]).norm();
            if l >= self.rest_len_px[k] {
                // Not compressed below its rest length: Algorithm 2 leaves
                // α as it is (yield ≥ 0), and so the rest length.
                continue;
            }
            let d0 = self.mesh.rest_lengths_px[k];
            self.alpha[k] = update_alpha(self.alpha[k], l, d0, &self.params);
            self.rest_len_px[k] = (1.0 - self.alpha[k]) * d0;
        }
    }

    fn check_stability(&self) -> Option<Instability> {
        for (i, p) in self.positions_px.iter().enumerate() {
            if !(p.x.is_finite() && p.y.is_finite()) {
                return Some(Instability::NonFinite { vertex: i });
            }
            let d2 = (p - self.rest_centroid_px).norm_squared();
            if d2 <= self.escape_distance_px * self.escape_distance_px {
                continue;
            }
            let d = d2.sqrt();
            if d > self.escape_distance_px {
                return Some(Instability::Escaped {
                    vertex: i,
                    distance_px: d,
                });
            }
        }
        let ratio = self.mesh.total_area_px2(&self.positions_px) / self.rest_area_px2;
        if !(0.1..=10.0).contains(&ratio) {
            return Some(Instability::AreaCollapse { area_ratio: ratio });
        }
        None
    }
}
