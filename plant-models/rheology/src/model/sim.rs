//! Time stepping of the lattice: M·P̈ = F_int + F_ext (L1667–1678) with
//! the basic elements' internal flow, the global volume pressure, gravity
//! and the rig's contacts.
//!
//! Two integrators:
//! * [`Integrator::ExplicitEuler`]: the paper's Euler method at 2 ms
//!   (L2076). With physical masses (M = M_obj/N, a few grams) and the
//!   paper's viscosities the lattice is overdamped by about five orders of
//!   magnitude (inertial time M/c ≈ 0.1 µs against rheological times of
//!   seconds), so the explicit step is stable only below ≈ 2M/Σc — tens of
//!   nanoseconds. At 2 ms it diverges within a few steps, and the run stops
//!   with [`Instability`] by name.
//! * [`Integrator::ImplicitEuler`] (the default): backward Euler, linearly
//!   implicit — element directions, contact states and the volume gradient
//!   are taken at the start of the step, everything else (inertia, element
//!   springs and dampers with their internal flow, contact penalties and
//!   friction, the volume pressure) at its end. The step's matrix
//!   `M/Δt + Σ β_e n nᵀ + D_contact + β_V g gᵀ` is symmetric positive
//!   definite, so the step is unconditionally stable for the linearised
//!   system and damps the stiff, physically irrelevant inertial modes
//!   (L-stable), as an overdamped material should; it stays first order
//!   like the paper's Euler. It is solved by block-Jacobi PCG, warm-started
//!   with the last velocity. Momentum balance holds exactly per step, so
//!   an element's flow integrates exactly to ∫F dt/c2.
//!
//! Instabilities are detected after every step: non-finite state, a mass
//! escaping the block, an element folding to under 1 % of its length, or
//! a stalled solve.
use crate::model::vec3::M3;
use serde::{Deserialize, Serialize};

use crate::error::{
    bad_setting, check_non_negative, check_positive, Instability, Result, RheologyError,
};
use crate::model::contact::{Contacts, Schedule};
use crate::model::element::ElementConstants;
use crate::model::lattice::{volume_gradient, Lattice, V3};
use crate::model::solver::{block_jacobi, invert_block, pcg, PcgWork};

/// Standard gravity (m/s²).
pub const GRAVITY_M_S2: f64 = 9.806_65;

/// The time integrator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Integrator {
    /// Linearly implicit (backward) Euler; stable at any step.
    #[default]
    ImplicitEuler,
    /// The paper's explicit Euler.
    ExplicitEuler,
}

impl Integrator {
    /// Snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            Integrator::ImplicitEuler => "implicit_euler",
            Integrator::ExplicitEuler => "explicit_euler",
        }
    }
}

/// The global volume condition (L2176): `p = −k_vol(V − V0) − c_vol·V̇`,
/// given as a bulk modulus `B = k_vol·V0` and bulk viscosity `c_vol·V0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlobalVolume {
    /// k_vol·V0 (Pa).
    pub bulk_pa: f64,
    /// c_vol·V0 (Pa·s).
    pub bulk_viscosity_pa_s: f64,
}

/// Numerical settings of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSettings {
    pub integrator: Integrator,
    /// Time step (s).
    pub dt_s: f64,
    /// Gravity (m/s², downward); 0 turns it off.
    pub gravity_m_s2: f64,
    /// Global volume condition, if on.
    pub global_volume: Option<GlobalVolume>,
    /// Relative residual at which the implicit solve stops.
    pub tolerance: f64,
    /// Most solver iterations per step.
    pub max_iterations: usize,
}

impl Default for SimSettings {
    fn default() -> Self {
        Self {
            integrator: Integrator::ImplicitEuler,
            dt_s: 0.002,
            gravity_m_s2: GRAVITY_M_S2,
            global_volume: None,
            tolerance: 1e-7,
            max_iterations: 2000,
        }
    }
}

/// A mass moved along a prescribed path `origin + direction·offset(t)`
/// in the axes marked in `axes` (free in the others); a pinned mass has
/// a constant offset.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeDrive {
    pub node: usize,
    pub axes: [bool; 3],
    pub origin_m: V3,
    pub direction: V3,
    pub offset_m: Schedule,
}

impl NodeDrive {
    /// A mass held where it is in the marked axes.
    pub fn pin(node: usize, at_m: V3, axes: [bool; 3]) -> Self {
        Self {
            node,
            axes,
            origin_m: at_m,
            direction: V3::zeros(),
            offset_m: Schedule {
                points: vec![(0.0, 0.0)],
            },
        }
    }
}

/// What one step produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// Time at the end of the step (s).
    pub t_s: f64,
    /// The plate's downward force on the block (N).
    pub plate_force_n: f64,
    /// Enclosed volume (m³; 0 without a surface).
    pub volume_m3: f64,
    /// Solver iterations (0 for the explicit step).
    pub iterations: usize,
}

/// A lattice being simulated.
#[derive(Clone, Debug)]
pub struct LatticeSim<'a> {
    lattice: &'a Lattice,
    constants: Vec<ElementConstants>,
    mass_kg: f64,
    settings: SimSettings,
    contacts: Contacts,
    x: Vec<V3>,
    v: Vec<V3>,
    q: Vec<f64>,
    tension: Vec<f64>,
    external: Vec<V3>,
    drives: Vec<NodeDrive>,
    fixed: Vec<V3>,
    t_s: f64,
    steps: usize,
    volume0: f64,
    volume: f64,
    escape_m: f64,
    centre: V3,
    // Scratch, kept between steps.
    dir: Vec<V3>,
    f0: Vec<f64>,
    beta: Vec<f64>,
    pairs: Vec<[u32; 2]>,
    scaled_dir: Vec<V3>,
    v_prev: Vec<V3>,
    rhs: Vec<V3>,
    diag: Vec<M3>,
    grad: Vec<V3>,
    v_new: Vec<V3>,
    work: PcgWork,
    iterations: usize,
}

impl<'a> LatticeSim<'a> {
    /// A lattice at rest in its rest shape, with per-element constants
    /// `constants` (see [`Lattice::element_constants`]) and total mass
    /// `mass_kg` shared equally by the masses (M = M_obj/N).
    pub fn new(
        lattice: &'a Lattice,
        constants: Vec<ElementConstants>,
        mass_kg: f64,
        settings: SimSettings,
        contacts: Contacts,
    ) -> Result<Self> {
        check_positive("mass_g", mass_kg)?;
        check_positive("dt_ms", settings.dt_s)?;
        check_non_negative("gravity_m_s2", settings.gravity_m_s2)?;
        check_positive("tolerance", settings.tolerance)?;
        if constants.len() != lattice.elements.len() {
            return Err(bad_setting(
                "constants",
                format!(
                    "{} element constants for {} elements",
                    constants.len(),
                    lattice.elements.len()
                ),
            ));
        }
        for (e, c) in constants.iter().enumerate() {
            for (name, v) in [
                ("k", c.k_n_per_m),
                ("c1", c.c1_ns_per_m),
                ("c2", c.c2_ns_per_m),
            ] {
                check_positive(&format!("element {e} {name}"), v)?;
            }
        }
        if let Some(g) = settings.global_volume {
            check_non_negative("bulk_gf_per_cm2", g.bulk_pa)?;
            check_non_negative("bulk_viscosity_gfs_per_cm2", g.bulk_viscosity_pa_s)?;
            if lattice.surface.is_empty() {
                return Err(bad_setting(
                    "volume",
                    "the global volume condition needs a closed surface",
                ));
            }
        }
        let n = lattice.masses();
        let x = lattice.rest_m.clone();
        let (centre, escape_m) = escape_sphere(lattice);
        let volume0 = lattice.volume_m3(&x);
        let ne = lattice.elements.len();
        Ok(Self {
            lattice,
            constants,
            mass_kg: mass_kg / n as f64,
            settings,
            contacts,
            v: vec![V3::zeros(); n],
            q: vec![0.0; ne],
            tension: vec![0.0; ne],
            external: vec![V3::zeros(); n],
            drives: Vec::new(),
            fixed: vec![V3::zeros(); n],
            t_s: 0.0,
            steps: 0,
            volume0,
            volume: volume0,
            escape_m,
            centre,
            x,
            dir: vec![V3::zeros(); ne],
            f0: vec![0.0; ne],
            beta: vec![0.0; ne],
            pairs: lattice.elements.iter().map(|e| [e.i, e.j]).collect(),
            scaled_dir: vec![V3::zeros(); ne],
            v_prev: vec![V3::zeros(); n],
            rhs: vec![V3::zeros(); n],
            diag: vec![M3::zeros(); n],
            grad: vec![V3::zeros(); n],
            v_new: vec![V3::zeros(); n],
            work: PcgWork::default(),
            iterations: 0,
        })
    }

    /// Moves a mass along a prescribed path from now on.
    pub fn drive(&mut self, d: NodeDrive) -> Result<()> {
        if d.node >= self.x.len() {
            return Err(bad_setting(
                "drive.node",
                format!("there are {} masses", self.x.len()),
            ));
        }
        for a in 0..3 {
            if d.axes[a] {
                self.fixed[d.node][a] = 1.0;
            }
        }
        self.drives.push(d);
        Ok(())
    }

    /// Sets a constant external force on a mass (N) until changed.
    pub fn set_external_force(&mut self, node: usize, f_n: V3) {
        self.external[node] = f_n;
    }

    /// Current time (s).
    pub fn time_s(&self) -> f64 {
        self.t_s
    }
    /// Steps taken.
    pub fn steps(&self) -> usize {
        self.steps
    }
    /// Positions (m).
    pub fn positions(&self) -> &[V3] {
        &self.x
    }
    /// Velocities (m/s).
    pub fn velocities(&self) -> &[V3] {
        &self.v
    }
    /// Each element's flow through its series damper (m).
    pub fn flow_m(&self) -> &[f64] {
        &self.q
    }
    /// Each element's tension over the last step (N).
    pub fn tensions_n(&self) -> &[f64] {
        &self.tension
    }
    /// The mass of one point (kg).
    pub fn point_mass_kg(&self) -> f64 {
        self.mass_kg
    }
    /// Enclosed volume now and at rest (m³).
    pub fn volume_m3(&self) -> (f64, f64) {
        (self.volume, self.volume0)
    }
    /// Solver iterations over all steps.
    pub fn total_iterations(&self) -> usize {
        self.iterations
    }
    /// The contacts (plate, pull-off bonds).
    pub fn contacts(&self) -> &Contacts {
        &self.contacts
    }
    /// The structure.
    pub fn lattice(&self) -> &Lattice {
        self.lattice
    }
    /// The time step (s).
    pub fn settings_dt(&self) -> f64 {
        self.settings.dt_s
    }

    /// Advances one step.
    pub fn step(&mut self) -> Result<StepReport> {
        let report = match self.settings.integrator {
            Integrator::ImplicitEuler => self.step_implicit(),
            Integrator::ExplicitEuler => self.step_explicit(),
        };
        match report {
            Ok(r) => {
                self.check()?;
                Ok(r)
            }
            Err(kind) => Err(self.unstable(kind)),
        }
    }

    fn unstable(&self, kind: Instability) -> RheologyError {
        RheologyError::Unstable {
            step: self.steps,
            time_s: self.t_s,
            kind,
        }
    }

    /// Element geometry at the start of a step; refuses folded elements.
    fn element_geometry(&mut self) -> core::result::Result<(), Instability> {
        for (e, el) in self.lattice.elements.iter().enumerate() {
            let d = self.x[el.j as usize] - self.x[el.i as usize];
            let len = d.norm();
            if len.is_nan() || len <= 0.01 * el.rest_m {
                return Err(Instability::Collapsed {
                    element: e,
                    length_ratio: len / el.rest_m,
                });
            }
            self.dir[e] = d / len;
            self.f0[e] = len - el.rest_m; // elongation, turned into forces below
        }
        Ok(())
    }

    fn drive_velocity(&self, d: &NodeDrive, t_next: f64, dt: f64) -> V3 {
        let target = d.origin_m + d.direction * d.offset_m.at(t_next);
        (target - self.x[d.node]) / dt
    }

    fn step_implicit(&mut self) -> core::result::Result<StepReport, Instability> {
        let dt = self.settings.dt_s;
        let t_next = self.t_s + dt;
        let m = self.mass_kg;
        self.element_geometry()?;
        self.contacts.prepare(t_next, dt, &self.x, &self.v);
        let gravity = V3::new(0.0, -self.settings.gravity_m_s2 * m, 0.0);
        for i in 0..self.x.len() {
            self.rhs[i] = self.v[i] * (m / dt) + gravity + self.external[i];
            self.diag[i] = M3::identity() * (m / dt);
        }
        for (e, el) in self.lattice.elements.iter().enumerate() {
            let (f0, beta) = self.constants[e].implicit_step(self.f0[e], self.q[e], dt);
            self.f0[e] = f0;
            self.beta[e] = beta;
            let n = self.dir[e];
            self.scaled_dir[e] = n * beta.sqrt();
            self.rhs[el.i as usize] += f0 * n;
            self.rhs[el.j as usize] -= f0 * n;
            let block = n.outer(&n) * beta;
            self.diag[el.i as usize] += block;
            self.diag[el.j as usize] += block;
        }
        let mut beta_vol = 0.0;
        if let Some(g) = self.settings.global_volume {
            volume_gradient(&self.lattice.surface, &self.x, &mut self.grad);
            let k_vol = g.bulk_pa / self.volume0;
            beta_vol = k_vol * dt + g.bulk_viscosity_pa_s / self.volume0;
            let p0 = -k_vol * (self.volume - self.volume0);
            for i in 0..self.x.len() {
                self.rhs[i] += p0 * self.grad[i];
                self.diag[i] += self.grad[i].outer(&self.grad[i]) * beta_vol;
            }
        }
        self.contacts.add_rhs(&mut self.rhs);
        self.contacts.add_diag(&mut self.diag);
        for d in self.diag.iter_mut() {
            *d = invert_block(d);
        }
        // Warm start: the velocity extrapolated linearly over the step.
        for i in 0..self.v.len() {
            self.v_new[i] = self.v[i] * 2.0 - self.v_prev[i];
        }
        for d in &self.drives {
            let vel = self.drive_velocity(d, t_next, dt);
            for a in 0..3 {
                if d.axes[a] {
                    self.v_new[d.node][a] = vel[a];
                }
            }
        }
        let (pairs, sdir, contacts, grad) =
            (&self.pairs, &self.scaled_dir, &self.contacts, &self.grad);
        let mut apply = |v: &[V3], out: &mut [V3]| {
            for (o, vi) in out.iter_mut().zip(v) {
                *o = *vi * (m / dt);
            }
            for (&[i, j], s) in pairs.iter().zip(sdir) {
                let (i, j) = (i as usize, j as usize);
                let f = *s * s.dot(&(v[i] - v[j]));
                out[i] += f;
                out[j] -= f;
            }
            if beta_vol > 0.0 {
                let gv: f64 = grad.iter().zip(v).map(|(g, vi)| g.dot(vi)).sum();
                for (o, g) in out.iter_mut().zip(grad) {
                    *o += *g * (beta_vol * gv);
                }
            }
            contacts.add_apply(v, out);
        };
        let iterations = pcg(
            &mut apply,
            &mut block_jacobi(&self.diag),
            &self.fixed,
            &self.rhs,
            &mut self.v_new,
            self.settings.tolerance,
            self.settings.max_iterations,
            &mut self.work,
        )
        .map_err(|s| Instability::SolverStalled {
            iterations: s.iterations,
            residual: s.relative_residual,
        })?;
        self.iterations += iterations;
        for (e, el) in self.lattice.elements.iter().enumerate() {
            let rate = self.dir[e].dot(&(self.v_new[el.j as usize] - self.v_new[el.i as usize]));
            let f = self.f0[e] + self.beta[e] * rate;
            self.tension[e] = f;
            self.q[e] += dt * f / self.constants[e].c2_ns_per_m;
        }
        for i in 0..self.x.len() {
            self.v_prev[i] = self.v[i];
            self.v[i] = self.v_new[i];
            self.x[i] += dt * self.v_new[i];
        }
        let plate_force_n = self.contacts.finish(&self.x, &self.v);
        self.finish_step(t_next, plate_force_n, iterations)
    }

    fn step_explicit(&mut self) -> core::result::Result<StepReport, Instability> {
        let dt = self.settings.dt_s;
        let t_next = self.t_s + dt;
        let m = self.mass_kg;
        self.element_geometry()?;
        self.contacts.prepare(self.t_s, 0.0, &self.x, &self.v);
        let gravity = V3::new(0.0, -self.settings.gravity_m_s2 * m, 0.0);
        for i in 0..self.x.len() {
            self.rhs[i] = gravity + self.external[i];
        }
        for (e, el) in self.lattice.elements.iter().enumerate() {
            let (i, j) = (el.i as usize, el.j as usize);
            let n = self.dir[e];
            let rate = n.dot(&(self.v[j] - self.v[i]));
            let f = self.constants[e].force_n(self.f0[e], self.q[e], rate);
            self.tension[e] = f;
            self.rhs[i] += f * n;
            self.rhs[j] -= f * n;
        }
        if let Some(g) = self.settings.global_volume {
            volume_gradient(&self.lattice.surface, &self.x, &mut self.grad);
            let rate: f64 = self.grad.iter().zip(&self.v).map(|(g, v)| g.dot(v)).sum();
            let p = -g.bulk_pa / self.volume0 * (self.volume - self.volume0)
                - g.bulk_viscosity_pa_s / self.volume0 * rate;
            for i in 0..self.x.len() {
                self.rhs[i] += p * self.grad[i];
            }
        }
        self.contacts.add_rhs(&mut self.rhs);
        self.v_new.fill(V3::zeros());
        self.contacts.add_apply(&self.v, &mut self.v_new);
        for e in 0..self.q.len() {
            self.q[e] += dt * self.tension[e] / self.constants[e].c2_ns_per_m;
        }
        let driven: Vec<(usize, V3, V3)> = self
            .drives
            .iter()
            .map(|d| {
                let target = d.origin_m + d.direction * d.offset_m.at(t_next);
                (d.node, target, (target - self.x[d.node]) / dt)
            })
            .collect();
        for i in 0..self.x.len() {
            let a = (self.rhs[i] - self.v_new[i]) / m;
            self.x[i] += dt * self.v[i];
            self.v[i] += dt * a;
        }
        for (node, target, vel) in driven {
            for a in 0..3 {
                if self.fixed[node][a] > 0.0 {
                    self.x[node][a] = target[a];
                    self.v[node][a] = vel[a];
                }
            }
        }
        let plate_force_n = self.contacts.finish(&self.x, &self.v);
        self.finish_step(t_next, plate_force_n, 0)
    }

    fn finish_step(
        &mut self,
        t_next: f64,
        plate_force_n: f64,
        iterations: usize,
    ) -> core::result::Result<StepReport, Instability> {
        self.t_s = t_next;
        self.steps += 1;
        if !self.lattice.surface.is_empty() {
            self.volume = self.lattice.volume_m3(&self.x);
        }
        Ok(StepReport {
            t_s: self.t_s,
            plate_force_n,
            volume_m3: self.volume,
            iterations,
        })
    }

    fn check(&self) -> Result<()> {
        for (i, (x, v)) in self.x.iter().zip(&self.v).enumerate() {
            if !(x.is_finite() && v.is_finite()) {
                return Err(self.unstable(Instability::NonFinite { node: i }));
            }
            let d = (*x - self.centre).norm();
            if d > self.escape_m {
                return Err(self.unstable(Instability::Escaped {
                    node: i,
                    distance_m: d,
                }));
            }
        }
        Ok(())
    }
}

/// The sphere a stable run stays in: its centre (the middle of the rest
/// lattice's bounding box) and radius, the escape distance (10 × the box's
/// diagonal, at least a voxel edge; m). Every step checks each node
/// against it, so every recorded frame of a stable run lies inside.
pub fn escape_sphere(lattice: &Lattice) -> (V3, f64) {
    let (lo, hi) = lattice.rest_m.iter().fold(
        (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY)),
        |(lo, hi), p| (lo.inf(p), hi.sup(p)),
    );
    (
        (lo + hi) / 2.0,
        10.0 * (hi - lo).norm().max(lattice.voxel_edge_m),
    )
}
