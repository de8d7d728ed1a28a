//! One plane of the joint: a rigid link moving in the plane (x, y, θ) on the
//! cartilage (or on a fixed bearing), pulled by an antagonistic pair of SMA
//! coils, under gravity and point loads.
//!
//! Frames and signs (SI units inside):
//! - socket frame: origin at the centre of the sponge's top face at rest
//!   (the *joint origin*), +y up along the link at rest, gravity along −y;
//! - link frame: origin at the centre of the link base, +y along the link;
//!   the link end is at (0, `end_length_m`);
//! - θ is positive **clockwise**, i.e. when the link end moves towards +x.
//!   A link point q maps to `p + (q_x cos θ + q_y sin θ, −q_x sin θ + q_y cos θ)`;
//! - the *raising* coil (2D coil 1; 3D coil 1 for α, coil 2 for β) sits on
//!   the +x side and increases θ when it contracts; the *lowering* coil (2D
//!   coil 2; 3D coils 3, 4) sits on the −x side;
//! - torques are clockwise-positive.
//!
//! Dynamics: Newton–Euler for the centre of mass (cartilage) or rotation
//! about the fixed pivot (rigid bearing), semi-implicit (symplectic) Euler:
//! velocities first from the forces at the current pose, then positions
//! from the new velocities. The sponge columns integrate their own dashpots
//! implicitly; the coil dashpot and the bearing damping are explicit and
//! small. Left out: the hanging weight's own inertia (a load is a force
//! only), friction between link and socket walls, contact with the socket
//! rim (range of motion is limited by the coils alone).

use plant_common::scalar::Scalar;
use plant_common::three_element::StepLength;
use serde::{Deserialize, Serialize};

use super::cartilage::{Cartilage, CartilageParams};
use super::driver::DriverParams;
use super::sma::{CoilSeeds, SmaCoil, SmaParams};
use super::{check_finite, check_positive, PlantError};

/// Standard gravity (m/s², CGPM 1901, exact). The paper does not state its
/// local g; every part of the project that needs g takes it from the plant
/// (this constant is the plant's default).
pub const STANDARD_GRAVITY_M_S2: f64 = 9.80665;

/// Rigid link parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LinkParams {
    /// Link mass (kg). Estimate: about half of the paper's 21.7 g for link +
    /// socket (the socket is fixed).
    pub mass_kg: f64,
    /// Height of the centre of mass above the link base (m). Estimate: mid
    /// link.
    pub com_height_m: f64,
    /// Moment of inertia about the centre of mass (kg·m²). Estimate: a
    /// uniform 27 × 10 mm block of 12 g, m (a² + b²)/12 ≈ 8.3e-7.
    pub inertia_kg_m2: f64,
    /// Distance from the joint origin to the link end (m). Paper: 27 mm.
    pub end_length_m: f64,
    /// Gravitational acceleration (m/s²), along −y of the socket frame.
    pub gravity_m_s2: f64,
}

impl Default for LinkParams {
    fn default() -> Self {
        Self {
            mass_kg: 0.012,
            com_height_m: 0.0135,
            inertia_kg_m2: 8.3e-7,
            end_length_m: 0.027,
            gravity_m_s2: STANDARD_GRAVITY_M_S2,
        }
    }
}

/// Where each coil of the pair is attached (the two are mirror images in x).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CoilGeometry {
    /// Lateral offset of the attachment on the link, link frame (m). Tuned
    /// estimate: 12.5 mm sets the coils' share of the joint stiffness so the
    /// 50 g compliance test gives ≈ 12° unpowered and ≈ 7.5° at 3 V / 2 V
    /// together with the sponge pad width (README.md).
    pub attach_lateral_m: f64,
    /// Height of the attachment above the link base, link frame (m).
    /// Estimate.
    pub attach_height_m: f64,
    /// Lateral offset of the anchor on the socket (m). Estimate: straight
    /// below the attachment.
    pub anchor_lateral_m: f64,
    /// Height of the anchor, socket frame (m; negative = below the sponge
    /// top). Estimate: the coil is installed at 20 mm, the SPEC's 20 mm
    /// coil, hanging vertically. Any orientation is accepted (inclined or
    /// horizontal coils load the sponge differently: horizontal coils barely
    /// compress it but cannot reach ±20° against the sponge's shear).
    pub anchor_height_m: f64,
}

impl Default for CoilGeometry {
    fn default() -> Self {
        Self {
            attach_lateral_m: 12.5e-3,
            attach_height_m: 8.0e-3,
            anchor_lateral_m: 12.5e-3,
            anchor_height_m: -12.0e-3,
        }
    }
}

/// Rigid bearing (paper Fig. 10): a fixed pivot at the joint origin.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BearingParams {
    /// Viscous friction of the bearing (N·m·s/rad). Estimate: a small ball
    /// bearing, nearly free.
    pub damping_nm_s_rad: f64,
}

impl Default for BearingParams {
    fn default() -> Self {
        Self {
            damping_nm_s_rad: 2.0e-6,
        }
    }
}

/// What the link rests on.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SupportParams {
    /// The sponge cartilage (the paper's loosely coupled joint).
    Cartilage(CartilageParams),
    /// A fixed pivot (the paper's comparison joint, Fig. 10–11).
    RigidBearing(BearingParams),
}

impl Default for SupportParams {
    fn default() -> Self {
        SupportParams::Cartilage(CartilageParams::default())
    }
}

/// Parameters of one plane (link, support, coil pair, drivers).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlaneParams {
    /// The rigid link.
    pub link: LinkParams,
    /// Cartilage or rigid bearing.
    pub support: SupportParams,
    /// Both coils of the pair.
    pub coil: SmaParams,
    /// Coil attachment geometry.
    pub coil_geometry: CoilGeometry,
    /// Both driver channels.
    pub driver: DriverParams,
}

impl PlaneParams {
    /// The same plane on a rigid bearing.
    pub fn rigid_bearing(mut self) -> Self {
        self.support = SupportParams::RigidBearing(BearingParams::default());
        self
    }

    /// Rejects bad values, naming the field (`prefix` e.g. `"plane."`).
    pub fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        let p = |f: &str| format!("{prefix}{f}");
        let l = &self.link;
        check_positive(&p("link.mass_kg"), l.mass_kg)?;
        check_finite(&p("link.com_height_m"), l.com_height_m)?;
        check_positive(&p("link.inertia_kg_m2"), l.inertia_kg_m2)?;
        check_positive(&p("link.end_length_m"), l.end_length_m)?;
        check_finite(&p("link.gravity_m_s2"), l.gravity_m_s2)?;
        match &self.support {
            SupportParams::Cartilage(c) => c.validate(&p("support."))?,
            SupportParams::RigidBearing(b) => {
                check_finite(&p("support.damping_nm_s_rad"), b.damping_nm_s_rad)?;
                if b.damping_nm_s_rad < 0.0 {
                    return Err(PlantError::param(
                        &p("support.damping_nm_s_rad"),
                        "must be ≥ 0",
                    ));
                }
            }
        }
        self.coil.validate(&p("coil."))?;
        let g = &self.coil_geometry;
        check_positive(&p("coil_geometry.attach_lateral_m"), g.attach_lateral_m)?;
        check_finite(&p("coil_geometry.attach_height_m"), g.attach_height_m)?;
        check_positive(&p("coil_geometry.anchor_lateral_m"), g.anchor_lateral_m)?;
        check_finite(&p("coil_geometry.anchor_height_m"), g.anchor_height_m)?;
        let installed =
            (g.anchor_lateral_m - g.attach_lateral_m).hypot(g.anchor_height_m - g.attach_height_m);
        if installed < 1e-3 {
            return Err(PlantError::param(
                &p("coil_geometry.anchor_height_m"),
                "coil shorter than 1 mm as installed",
            ));
        }
        self.driver.validate(&p("driver."))
    }
}

/// A force applied at a point of the link.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointLoad {
    /// Force in the socket frame (N).
    pub force_n: [f64; 2],
    /// Point of application, link frame (m).
    pub point_link_m: [f64; 2],
}

impl PointLoad {
    /// A weight of `mass_kg` hanging from a thread tied at `point_link_m`
    /// and led (over a pulley if needed) along the unit direction
    /// `direction` of the socket frame; `g` in m/s².
    pub fn weight(mass_kg: f64, g: f64, point_link_m: [f64; 2], direction: [f64; 2]) -> Self {
        let n = direction[0].hypot(direction[1]);
        let f = mass_kg * g / n;
        Self {
            force_n: [f * direction[0], f * direction[1]],
            point_link_m,
        }
    }
}

/// Handle of a load attached to a plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LoadId(pub(crate) usize);

/// Loads a plane can carry at once.
pub const MAX_LOADS: usize = 8;

/// Positions and velocities of one plane's link.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LinkState<S = f64> {
    /// Centre of mass x, y (m).
    pub com_m: [S; 2],
    /// Angle (rad, clockwise positive).
    pub theta_rad: S,
    /// Centre-of-mass velocity (m/s).
    pub com_vel_m_s: [S; 2],
    /// Angular velocity (rad/s, clockwise positive).
    pub omega_rad_s: S,
}

/// The plane parameters a plane in duals carries derivatives of
/// ([`PlanarJoint::with_seeds`]): the ones identification's mechanics
/// stage fits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlaneSeeds<S> {
    /// Both coils' convection, transformation temperatures and stress
    /// slope.
    pub coil: CoilSeeds<S>,
    /// `support.youngs_modulus_pa` (a cartilage support).
    pub sponge_modulus_pa: S,
    /// `support.rayleigh_damping_s` (a cartilage support).
    pub sponge_damping_s: S,
    /// `link.inertia_kg_m2`.
    pub link_inertia_kg_m2: S,
    /// `driver.transconductance_a_v`.
    pub transconductance_a_v: S,
}

impl<S: Scalar> PlaneSeeds<S> {
    /// The parameters' values as constants (no derivatives); the sponge's
    /// are NaN on a rigid bearing (unused there).
    pub fn constants(p: &PlaneParams) -> Self {
        let (e, b) = match &p.support {
            SupportParams::Cartilage(c) => (c.youngs_modulus_pa, c.rayleigh_damping_s),
            SupportParams::RigidBearing(_) => (f64::NAN, f64::NAN),
        };
        Self {
            coil: CoilSeeds::constants(&p.coil),
            sponge_modulus_pa: S::cst(e),
            sponge_damping_s: S::cst(b),
            link_inertia_kg_m2: S::cst(p.link.inertia_kg_m2),
            transconductance_a_v: S::cst(p.driver.transconductance_a_v),
        }
    }
}

/// One plane of the joint, in any [`Scalar`]: `f64` for the plant, a dual
/// for identification's sensitivities ([`PlanarJoint::with_seeds`]).
#[derive(Clone, Debug)]
pub struct PlanarJoint<S = f64> {
    params: PlaneParams,
    cartilage: Option<Cartilage<S>>,
    bearing_damping: f64,
    coils: [SmaCoil<S>; 2],
    coil_tension_n: [S; 2],
    loads: [Option<PointLoad>; MAX_LOADS],
    /// Slots in use: the substep skips the load scan when none are.
    loads_attached: usize,
    state: LinkState<S>,
    /// (sin θ, cos θ) of the present state, kept to avoid recomputing.
    sin_cos: (S, S),
    /// `link.inertia_kg_m2` and `driver.transconductance_a_v` as scalars.
    inertia_kg_m2: S,
    transconductance_a_v: S,
}

#[inline(always)]
fn rotate<S: Scalar>(q: [S; 2], s: S, c: S) -> [S; 2] {
    [q[0] * c + q[1] * s, -q[0] * s + q[1] * c]
}

/// Clockwise torque of force `f` applied at offset `r`.
#[inline(always)]
fn torque_cw<S: Scalar>(r: [S; 2], f: [S; 2]) -> S {
    r[1] * f[0] - r[0] * f[1]
}

impl PlanarJoint {
    /// A plane at its nominal rest pose with cold coils (not yet settled).
    pub fn new(params: PlaneParams) -> Result<Self, PlantError> {
        let seeds = PlaneSeeds::constants(&params);
        Self::with_seeds(params, seeds)
    }
}

impl<S: Scalar> PlanarJoint<S> {
    /// A plane at its nominal rest pose with cold coils (not yet settled)
    /// whose fitted parameters are `seeds` (their values must be
    /// `params`'; duals carry their derivatives through every substep).
    pub fn with_seeds(params: PlaneParams, seeds: PlaneSeeds<S>) -> Result<Self, PlantError> {
        params.validate("plane.")?;
        let same = |a: S, b: f64| a.val().to_bits() == b.to_bits();
        if !same(seeds.link_inertia_kg_m2, params.link.inertia_kg_m2)
            || !same(
                seeds.transconductance_a_v,
                params.driver.transconductance_a_v,
            )
        {
            return Err(PlantError::param(
                "plane",
                "seeded parameters differ from the plane's own values",
            ));
        }
        let (cartilage, bearing_damping) = match &params.support {
            SupportParams::Cartilage(c) => (
                Some(Cartilage::with_seeds(
                    c.clone(),
                    seeds.sponge_modulus_pa,
                    seeds.sponge_damping_s,
                )?),
                0.0,
            ),
            SupportParams::RigidBearing(b) => (None, b.damping_nm_s_rad),
        };
        let coil = SmaCoil::with_seeds(params.coil.clone(), seeds.coil)?;
        let zero = S::cst(0.0);
        let state = LinkState {
            com_m: [zero, S::cst(params.link.com_height_m)],
            theta_rad: zero,
            com_vel_m_s: [zero; 2],
            omega_rad_s: zero,
        };
        Ok(Self {
            cartilage,
            bearing_damping,
            coils: [coil.clone(), coil],
            coil_tension_n: [zero; 2],
            loads: [None; MAX_LOADS],
            loads_attached: 0,
            state,
            sin_cos: (zero, S::cst(1.0)),
            inertia_kg_m2: seeds.link_inertia_kg_m2,
            transconductance_a_v: seeds.transconductance_a_v,
            params,
        })
    }

    /// Parameters.
    pub fn params(&self) -> &PlaneParams {
        &self.params
    }

    /// Whether the link rests on a rigid bearing.
    pub fn is_rigid_bearing(&self) -> bool {
        self.cartilage.is_none()
    }

    /// Link state.
    pub fn state(&self) -> &LinkState<S> {
        &self.state
    }

    /// Link angle (rad, clockwise positive: link end towards +x).
    pub fn angle_rad(&self) -> S {
        self.state.theta_rad
    }

    /// (sin θ, cos θ) of the present angle.
    #[inline]
    pub fn sin_cos(&self) -> (S, S) {
        self.sin_cos
    }

    /// Link base origin in the socket frame (m).
    #[inline]
    pub fn base_m(&self) -> [S; 2] {
        let (s, c) = self.sin_cos;
        let r = rotate([S::cst(0.0), S::cst(self.params.link.com_height_m)], s, c);
        [self.state.com_m[0] - r[0], self.state.com_m[1] - r[1]]
    }

    /// A link point (link frame, m) in the socket frame (m).
    pub fn world_point_m(&self, q: [f64; 2]) -> [S; 2] {
        let (s, c) = self.sin_cos;
        let b = self.base_m();
        let r = rotate(q.map(S::cst), s, c);
        [b[0] + r[0], b[1] + r[1]]
    }

    /// Link end in the socket frame (m).
    pub fn end_m(&self) -> [S; 2] {
        self.world_point_m([0.0, self.params.link.end_length_m])
    }

    /// The two coils: index 0 raises θ, index 1 lowers it.
    pub fn coils(&self) -> &[SmaCoil<S>; 2] {
        &self.coils
    }

    /// Mutable coils (tests, warm starts).
    pub fn coils_mut(&mut self) -> &mut [SmaCoil<S>; 2] {
        &mut self.coils
    }

    /// Coil tensions at the last step (N).
    pub fn coil_tensions_n(&self) -> [S; 2] {
        self.coil_tension_n
    }

    /// Attaches a load; fails when `MAX_LOADS` are attached or it is not
    /// finite.
    pub fn add_load(&mut self, load: PointLoad) -> Result<LoadId, PlantError> {
        for (name, v) in [
            ("load.force_n[0]", load.force_n[0]),
            ("load.force_n[1]", load.force_n[1]),
            ("load.point_link_m[0]", load.point_link_m[0]),
            ("load.point_link_m[1]", load.point_link_m[1]),
        ] {
            check_finite(name, v)?;
        }
        let slot = self
            .loads
            .iter()
            .position(Option::is_none)
            .ok_or(PlantError::TooManyLoads)?;
        self.loads[slot] = Some(load);
        self.loads_attached += 1;
        Ok(LoadId(slot))
    }

    /// Removes a load (cutting the thread). Returns it if it was attached.
    pub fn remove_load(&mut self, id: LoadId) -> Option<PointLoad> {
        let removed = self.loads.get_mut(id.0).and_then(Option::take);
        if removed.is_some() {
            self.loads_attached -= 1;
        }
        removed
    }

    /// Kinetic energy of the link (J).
    pub fn kinetic_energy_j(&self) -> f64 {
        let s = &self.state;
        let m = self.params.link.mass_kg;
        let (vx, vy, om) = (
            s.com_vel_m_s[0].val(),
            s.com_vel_m_s[1].val(),
            s.omega_rad_s.val(),
        );
        if self.cartilage.is_some() {
            0.5 * m * (vx.powi(2) + vy.powi(2)) + 0.5 * self.params.link.inertia_kg_m2 * om.powi(2)
        } else {
            let i_o = self.params.link.inertia_kg_m2 + m * self.params.link.com_height_m.powi(2);
            0.5 * i_o * om.powi(2)
        }
    }

    /// One substep of `h`: coil heating from the two driver inputs (V), then
    /// forces at the present pose, then semi-implicit Euler.
    #[inline]
    pub fn substep(&mut self, h: StepLength, inputs_v: [f64; 2]) {
        let dt = h.seconds();
        for ((coil, v), tension) in self.coils.iter_mut().zip(inputs_v).zip(self.coil_tension_n) {
            coil.set_tension_for_phase(tension);
            let i = self.params.driver.current_a_of(
                self.transconductance_a_v,
                v,
                coil.resistance_ohm(),
            );
            coil.step(dt, i, false);
        }
        let lp = &self.params.link;
        let st = self.state;
        let (s, c) = self.sin_cos;
        let cst = S::cst;
        let r_com = rotate([cst(0.0), cst(lp.com_height_m)], s, c);
        let base = [st.com_m[0] - r_com[0], st.com_m[1] - r_com[1]];
        // Forces, and clockwise torque about the centre of mass.
        let mut f = [cst(0.0), cst(-lp.mass_kg * lp.gravity_m_s2)];
        let mut tau_cm = cst(0.0);
        let g = &self.params.coil_geometry;
        for (k, side) in [1.0f64, -1.0].into_iter().enumerate() {
            let r = rotate(
                [cst(side * g.attach_lateral_m), cst(g.attach_height_m)],
                s,
                c,
            );
            let a = [base[0] + r[0], base[1] + r[1]];
            let d = [
                cst(side * g.anchor_lateral_m) - a[0],
                cst(g.anchor_height_m) - a[1],
            ];
            // sqrt rather than hypot: no overflow risk at mm scale, and
            // several times cheaper on the hot path.
            let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
            let u = [d[0] / len, d[1] / len];
            // Velocity of the attachment: v_com + ω × (a − com) (clockwise ω).
            let ra = [a[0] - st.com_m[0], a[1] - st.com_m[1]];
            let va = [
                st.com_vel_m_s[0] + st.omega_rad_s * ra[1],
                st.com_vel_m_s[1] - st.omega_rad_s * ra[0],
            ];
            let rate = -(u[0] * va[0] + u[1] * va[1]);
            let t = self.coils[k].tension_n(len, rate);
            self.coil_tension_n[k] = t;
            let fk = [t * u[0], t * u[1]];
            f[0] = f[0] + fk[0];
            f[1] = f[1] + fk[1];
            tau_cm = tau_cm + torque_cw(ra, fk);
        }
        let loads = if self.loads_attached > 0 {
            &self.loads[..]
        } else {
            &[]
        };
        for load in loads.iter().flatten() {
            let r = rotate(load.point_link_m.map(cst), s, c);
            let ra = [base[0] + r[0] - st.com_m[0], base[1] + r[1] - st.com_m[1]];
            f[0] = f[0] + load.force_n[0];
            f[1] = f[1] + load.force_n[1];
            tau_cm = tau_cm + torque_cw(ra, load.force_n.map(cst));
        }
        match self.cartilage.as_mut() {
            Some(cart) => {
                let w = cart.step(h, base[0], base[1], s, c);
                f[0] = f[0] + w.fx_n;
                f[1] = f[1] + w.fy_n;
                // Move the sponge's torque from the base to the centre of mass.
                let rb = [base[0] - st.com_m[0], base[1] - st.com_m[1]];
                tau_cm = tau_cm + (w.torque_cw_nm + torque_cw(rb, [w.fx_n, w.fy_n]));
                let m = lp.mass_kg;
                let vx = st.com_vel_m_s[0] + f[0] * dt / m;
                let vy = st.com_vel_m_s[1] + f[1] * dt / m;
                let om = st.omega_rad_s + tau_cm * dt / self.inertia_kg_m2;
                self.state.com_vel_m_s = [vx, vy];
                self.state.omega_rad_s = om;
                self.state.com_m = [st.com_m[0] + vx * dt, st.com_m[1] + vy * dt];
                self.state.theta_rad = st.theta_rad + om * dt;
                // A link at rest keeps θ to the bit: sin_cos (a libm call)
                // of the same argument gives the same pair. A dual's
                // derivatives still move: those of sin θ and cos θ follow.
                let th = self.state.theta_rad;
                if th.val().to_bits() != st.theta_rad.val().to_bits() {
                    self.sin_cos = th.sin_cos();
                } else if S::TANGENTS {
                    let (sn, cs) = (s.val(), c.val());
                    let dth = th - th.val();
                    self.sin_cos = (dth * cs + sn, dth * -sn + cs);
                }
            }
            None => {
                // Pivot at the joint origin: torque about it, the reaction
                // force does no work.
                let tau_o = tau_cm + torque_cw(r_com, f) - st.omega_rad_s * self.bearing_damping;
                let i_o = self.inertia_kg_m2 + lp.mass_kg * lp.com_height_m * lp.com_height_m;
                let om = st.omega_rad_s + tau_o * dt / i_o;
                let th = st.theta_rad + om * dt;
                let (s2, c2) = th.sin_cos();
                self.sin_cos = (s2, c2);
                let rc = rotate([cst(0.0), cst(lp.com_height_m)], s2, c2);
                self.state.omega_rad_s = om;
                self.state.theta_rad = th;
                self.state.com_m = rc;
                self.state.com_vel_m_s = [om * rc[1], -om * rc[0]];
            }
        }
    }

    /// Checks the state after a step: finite, energy and pose in range.
    /// Inlined into the step loops; a failure is described out of line.
    #[inline(always)]
    pub fn check(&self, plane: &'static str, max_kinetic_j: f64) -> Result<(), PlantError> {
        let vals = self.checked_values();
        // NaN and ±∞ propagate through the sum: one test on the hot path,
        // the per-variable search only once something is wrong.
        let finite = vals.iter().map(|v| v.1).sum::<f64>().is_finite();
        let runaway = self.kinetic_energy_j() > max_kinetic_j;
        let b = self.base_m().map(S::val);
        let out_of_range =
            self.state.theta_rad.val().abs() > 1.2 || b[0] * b[0] + b[1] * b[1] > 0.02 * 0.02;
        if finite && !runaway && !out_of_range {
            Ok(())
        } else {
            Err(self.check_failure(plane, max_kinetic_j))
        }
    }

    /// The quantities [`Self::check`] requires finite, named.
    #[inline(always)]
    fn checked_values(&self) -> [(&'static str, f64); 8] {
        let s = &self.state;
        [
            ("com_x", s.com_m[0].val()),
            ("com_y", s.com_m[1].val()),
            ("theta", s.theta_rad.val()),
            ("com_vx", s.com_vel_m_s[0].val()),
            ("com_vy", s.com_vel_m_s[1].val()),
            ("omega", s.omega_rad_s.val()),
            ("coil_temperature[0]", self.coils[0].temperature_c().val()),
            ("coil_temperature[1]", self.coils[1].temperature_c().val()),
        ]
    }

    /// What [`Self::check`] found wrong: the first of a non-finite value,
    /// the kinetic energy above `max_kinetic_j`, the pose out of range.
    #[cold]
    #[inline(never)]
    fn check_failure(&self, plane: &'static str, max_kinetic_j: f64) -> PlantError {
        let vals = self.checked_values();
        if !vals.iter().map(|v| v.1).sum::<f64>().is_finite() {
            // Finite values whose sum overflows (absurd magnitudes) have
            // no culprit of their own.
            let name = vals
                .iter()
                .find(|v| !v.1.is_finite())
                .map_or("state sum", |v| v.0);
            return PlantError::NonFinite {
                plane,
                quantity: name,
            };
        }
        let ke = self.kinetic_energy_j();
        if ke > max_kinetic_j {
            return PlantError::EnergyRunaway {
                plane,
                kinetic_j: ke,
                limit_j: max_kinetic_j,
            };
        }
        let b = self.base_m().map(S::val);
        PlantError::PoseOutOfRange {
            plane,
            theta_deg: self.state.theta_rad.val().to_degrees(),
            base_offset_mm: 1e3 * b[0].hypot(b[1]),
        }
    }

    /// Zeroes the link's velocities (warm starts in tests).
    pub fn reset_velocities(&mut self) {
        self.state.com_vel_m_s = [S::cst(0.0); 2];
        self.state.omega_rad_s = S::cst(0.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant_common::scalar::Dual;

    /// Pulses on both coils, one after the other and overlapping, as an
    /// excitation plan drives a plane.
    fn inputs(k: usize) -> [f64; 2] {
        let t = k as f64 * 1e-3;
        let a = if (t % 7.0) < 2.5 {
            3.0 + 1.5 * (t * 0.7).sin()
        } else {
            0.0
        };
        let b = if ((t + 3.3) % 9.0) < 3.0 {
            3.5 + (t * 0.31).cos()
        } else {
            0.0
        };
        [a, b]
    }

    const NAMES: [&str; 10] = [
        "convection",
        "A_s",
        "A_f",
        "M_s",
        "M_f",
        "stress slope",
        "sponge modulus",
        "sponge damping",
        "link inertia",
        "transconductance",
    ];

    fn set(p: &mut PlaneParams, j: usize, v: f64) {
        let SupportParams::Cartilage(c) = &mut p.support else {
            panic!("a cartilage plane")
        };
        match j {
            0 => p.coil.convection_w_m2_k = v,
            1 => p.coil.austenite_start_c = v,
            2 => p.coil.austenite_finish_c = v,
            3 => p.coil.martensite_start_c = v,
            4 => p.coil.martensite_finish_c = v,
            5 => p.coil.stress_shift_k_per_mpa = v,
            6 => c.youngs_modulus_pa = v,
            7 => c.rayleigh_damping_s = v,
            8 => p.link.inertia_kg_m2 = v,
            _ => p.driver.transconductance_a_v = v,
        }
    }

    fn get(p: &PlaneParams, j: usize) -> f64 {
        let SupportParams::Cartilage(c) = &p.support else {
            panic!("a cartilage plane")
        };
        [
            p.coil.convection_w_m2_k,
            p.coil.austenite_start_c,
            p.coil.austenite_finish_c,
            p.coil.martensite_start_c,
            p.coil.martensite_finish_c,
            p.coil.stress_shift_k_per_mpa,
            c.youngs_modulus_pa,
            c.rayleigh_damping_s,
            p.link.inertia_kg_m2,
            p.driver.transconductance_a_v,
        ][j]
    }

    fn angles(p: &PlaneParams, steps: usize) -> Vec<f64> {
        let h = StepLength::new(1e-3).unwrap();
        let mut plane = PlanarJoint::new(p.clone()).unwrap();
        (0..steps)
            .map(|k| {
                plane.substep(h, inputs(k));
                plane.check("alpha", 0.5).unwrap();
                plane.angle_rad()
            })
            .collect()
    }

    /// A plane stepped in duals of its ten fitted parameters: the angle's
    /// value is the f64 plane's to the bit at every substep, and each
    /// derivative is what central differences of the f64 plane give.
    #[test]
    fn a_dual_plane_is_the_plane_and_its_derivatives() {
        let mut p = PlaneParams::default();
        p.coil.stress_shift_k_per_mpa = 0.07;
        let steps = 30_000;
        let plain = angles(&p, steps);
        let mut seeds = PlaneSeeds::<Dual<10>>::constants(&p);
        seeds.coil.convection_w_m2_k = Dual::var(get(&p, 0), 0);
        for k in 0..4 {
            seeds.coil.transformation_c[k] = Dual::var(get(&p, 1 + k), 1 + k);
        }
        seeds.coil.stress_shift_k_per_mpa = Dual::var(get(&p, 5), 5);
        seeds.sponge_modulus_pa = Dual::var(get(&p, 6), 6);
        seeds.sponge_damping_s = Dual::var(get(&p, 7), 7);
        seeds.link_inertia_kg_m2 = Dual::var(get(&p, 8), 8);
        seeds.transconductance_a_v = Dual::var(get(&p, 9), 9);
        let h = StepLength::new(1e-3).unwrap();
        let mut dual = PlanarJoint::with_seeds(p.clone(), seeds).unwrap();
        let mut d = Vec::with_capacity(steps);
        for (k, angle) in plain.iter().enumerate() {
            dual.substep(h, inputs(k));
            dual.check("alpha", 0.5).unwrap();
            let a = dual.angle_rad();
            assert_eq!(a.v.to_bits(), angle.to_bits(), "substep {k}");
            d.push(a);
        }
        let amplitude = plain.iter().fold(0.0f64, |m, a| m.max(a.abs()));
        assert!(
            amplitude.to_degrees() > 5.0,
            "the link moves ({amplitude} rad)"
        );
        for (j, name) in NAMES.iter().enumerate() {
            // Relative step 1e-4: smaller ones meet the rounding of a link
            // at rest (θ kept to the bit), larger ones the curvature.
            let eps = 1e-4 * get(&p, j).abs();
            let run = |v: f64| {
                let mut q = p.clone();
                set(&mut q, j, v);
                angles(&q, steps)
            };
            let (up, down) = (run(get(&p, j) + eps), run(get(&p, j) - eps));
            let diff: Vec<f64> = up
                .iter()
                .zip(&down)
                .map(|(u, w)| (u - w) / (2.0 * eps))
                .collect();
            let rms = |v: &mut dyn Iterator<Item = f64>| {
                let (s, n) = v.fold((0.0, 0), |(s, n), x| (s + x * x, n + 1));
                (s / n as f64).sqrt()
            };
            let scale = rms(&mut diff.iter().copied());
            let err = rms(&mut diff.iter().zip(&d).map(|(f, x)| f - x.d[j]));
            assert!(scale > 0.0, "{name}: the angle depends on it");
            // Seen: 2e-8 – 1.6e-5 of the rms (2.5e-4 – 6.4e-4 with steps
            // of 1e-3); a wrong rule anywhere is of order 1.
            assert!(
                err <= 1e-3 * scale,
                "{name}: rms of dual − difference {err:.3e} against rms {scale:.3e}"
            );
        }
    }
}
