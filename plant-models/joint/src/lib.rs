//! The simulated loosely coupled joint (Shibata, Yoshimura, Hirai; seed 000,
//! last paper): a rigid link on a sponge cartilage, moved by BMX200-like SMA
//! coils through ULN2003 channels, observed by wire length sensors and a
//! camera. This is the plant only — no controller.
//!
//! - [`sma`]: coil thermal model, hysteretic phase, phase-dependent spring;
//! - [`driver`]: ULN2003 channel, input voltage → coil current;
//! - [`cartilage`]: the sponge as distributed 3-element columns;
//! - [`link`]: one plane — rigid link, support (cartilage or rigid bearing),
//!   coil pair, gravity and point loads;
//! - [`wire_sensor`]: pose → wire insertion, pulse-coder counts, jamming;
//! - [`camera`]: 30 frames/s, latency, noise, occlusion;
//! - [`Joint2d`], [`Joint3d`]: the assembled plants.
//!
//! **3D as two projection planes.** [`Joint3d`] is two independent planar
//! models (α: coils 1 and 3, sensors 1 and 3; β: coils 2 and 4, sensors 2
//! and 4), each with the full link mass and the full sponge pad. Left out:
//! the coupling through the shared sponge (the pad's compression under one
//! pair changes the other pair's preload), the out-of-plane lever of each
//! coil, twist about the link axis, the wires' cross-sensitivity to the
//! other angle, and gravity's dependence on both angles. The paper itself
//! controls the planes independently and names the interference between the
//! pairs as a possible error source it did not model.
//!
//! **Integration.** Fixed substeps (default 1 ms; `step(dt)` splits `dt`
//! into `ceil(dt/substep)` equal parts). Coil temperature: exact exponential
//! over the substep (unconditionally stable). Sponge columns: the exact
//! solution of the 3-element model for motion linear over the substep
//! (unconditionally stable). Link:
//! semi-implicit (symplectic) Euler — velocities from the forces at the
//! present pose, then positions — stable for `h·ω_max < 2` and free of
//! artificial damping, so the rigid bearing's ringing is not an artefact.
//! The stiffest mode is the link rocking about its centre of mass on the
//! sponge's instantaneous shear and normal stiffness ((1+r)× relaxed,
//! r = 3): ω_max ≈ √((k_t·(13.5 mm)² + 4·K_rot)/I_cm) ≈ 700 rad/s for the
//! defaults, so 1 ms gives h·ω ≈ 0.7, a margin of ~3 to the limit; the
//! slow modes that matter (≈ 150 rad/s) have h·ω ≈ 0.15. Why 1 ms and not
//! less: one substep per 1 kHz control period is what makes ≥ 5000× real
//! time possible. `tests/joint_integration.rs` compares with 62.5 µs: the
//! static figures (compliance, open-loop angle) agree to rounding
//! (< 1e-12°), the rigid bearing's ringing to 0.15 % in amplitude and 1 ms
//! in peak time, and the fastest transient (10 ms into the return after
//! cutting the weight, while the sponge relaxes with its ≈ 9 ms time
//! constant) to 0.58° of an 11.87° deflection (0.10° at 0.25 ms); 2 ms
//! still runs stably. Lower
//! `sim.substep_s` for fast transients or stiffer parameters.
//! After every substep the state is checked: a non-finite value, kinetic
//! energy above `max_kinetic_energy_j` or a pose outside the mechanism's
//! range returns an error naming it; the plant never continues on NaN.
//!
//! **Determinism.** All randomness (wire stick events, camera noise) comes
//! from ChaCha8 streams derived from `seed`; reruns are bit-identical.
//!
//! **Tuned estimates.** Coil lever (`coil_geometry.attach_lateral_m`),
//! sponge pad size and damping (`cartilage.*`) and the coil rest lengths are
//! estimates set so the paper's compliance figures come out (50 g → 12°
//! unpowered, 7.5° at v1 = 3 V, v2 = 2 V; damped return); see README.md and
//! `tests/joint_compliance.rs`.

pub mod camera;
pub mod cartilage;
pub mod driver;
pub mod identify;
pub mod link;
pub mod sma;
pub mod wire_sensor;

use plant_common::three_element::StepLength;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

pub use camera::{Camera, CameraFrame, CameraParams};
pub use cartilage::CartilageParams;
pub use driver::DriverParams;
pub use link::{
    BearingParams, CoilGeometry, LinkParams, LoadId, PlanarJoint, PlaneParams, PlaneSeeds,
    PointLoad, SupportParams,
};
pub use sma::{CoilSeeds, SmaCoil, SmaParams};
pub use wire_sensor::{JamParams, WireGeometry, WireSensor, WireSensorParams};

/// Why the plant refused parameters or a step.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum PlantError {
    /// A parameter is NaN, infinite, out of range or inconsistent.
    #[error("invalid parameter `{field}`: {reason}")]
    InvalidParameter {
        /// Dotted path of the field, e.g. `plane.coil.convection_w_m2_k`.
        field: String,
        /// What is wrong with it.
        reason: String,
    },
    /// `coil_input_volts` has the wrong length.
    #[error("expected {expected} coil input voltages, got {got}")]
    InputLength {
        /// Coils of this joint.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A coil input voltage is NaN or infinite.
    #[error("coil {coil} input voltage is not finite")]
    NonFiniteInput {
        /// Coil number (1-based, the paper's numbering).
        coil: usize,
    },
    /// The step length is not finite and positive.
    #[error("step length {} s must be finite and > 0", plant_common::short_number(*.dt_s))]
    BadStep {
        /// The rejected step (s).
        dt_s: f64,
    },
    /// A state variable became NaN or infinite.
    #[error("numerical instability in plane {plane}: {quantity} is not finite")]
    NonFinite {
        /// Plane ("2d", "alpha", "beta").
        plane: &'static str,
        /// The state variable.
        quantity: &'static str,
    },
    /// The link's kinetic energy exceeded the physical bound.
    #[error(
        "numerical instability in plane {plane}: kinetic energy {} J exceeds {} J",
        plant_common::short_number(*.kinetic_j),
        plant_common::short_number(*.limit_j)
    )]
    EnergyRunaway {
        /// Plane.
        plane: &'static str,
        /// Kinetic energy (J).
        kinetic_j: f64,
        /// Limit (J).
        limit_j: f64,
    },
    /// The link left the mechanism's range (|θ| > 1.2 rad or the base more
    /// than 20 mm from the joint origin).
    #[error(
        "plane {plane}: link out of range (θ = {}°, base offset {} mm)",
        plant_common::short_number(*.theta_deg),
        plant_common::short_number(*.base_offset_mm)
    )]
    PoseOutOfRange {
        /// Plane.
        plane: &'static str,
        /// Angle (deg).
        theta_deg: f64,
        /// Base distance from the joint origin (mm).
        base_offset_mm: f64,
    },
    /// No free load slot.
    #[error("too many loads attached (max {})", link::MAX_LOADS)]
    TooManyLoads,
}

impl PlantError {
    pub(crate) fn param(field: &str, reason: &str) -> Self {
        PlantError::InvalidParameter {
            field: field.to_string(),
            reason: reason.to_string(),
        }
    }
}

pub(crate) fn check_finite(field: &str, v: f64) -> Result<(), PlantError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(PlantError::param(field, "must be finite"))
    }
}

pub(crate) fn check_positive(field: &str, v: f64) -> Result<(), PlantError> {
    check_finite(field, v)?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(PlantError::param(field, "must be > 0"))
    }
}

/// Integration and run settings shared by both joints.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SimParams {
    /// Mechanical substep (s), at most 2 ms. See the module docs.
    pub substep_s: f64,
    /// Time run with all coils off at construction, so the link starts at
    /// its loaded rest pose (s). The clock then restarts at 0 and the wire
    /// coders are zeroed there.
    pub settle_s: f64,
    /// Seed of every random stream.
    pub seed: u64,
    /// Kinetic energy that counts as a numerical blow-up (J). 0.5 J is a
    /// 12 g link at 9 m/s, or the rigid-bearing link spinning at 570 rad/s,
    /// two orders beyond what coils and a 50 g weight can do (a 50 g weight
    /// swinging the free link through 1 rad does ≈ 13 mJ).
    pub max_kinetic_energy_j: f64,
}

impl Default for SimParams {
    fn default() -> Self {
        Self {
            substep_s: 1e-3,
            settle_s: 1.0,
            seed: 0x5eed,
            max_kinetic_energy_j: 0.5,
        }
    }
}

impl SimParams {
    fn validate(&self) -> Result<(), PlantError> {
        check_positive("sim.substep_s", self.substep_s)?;
        if self.substep_s > 2e-3 {
            return Err(PlantError::param(
                "sim.substep_s",
                "must be ≤ 2 ms (stability)",
            ));
        }
        check_finite("sim.settle_s", self.settle_s)?;
        if self.settle_s < 0.0 {
            return Err(PlantError::param("sim.settle_s", "must be ≥ 0"));
        }
        check_positive("sim.max_kinetic_energy_j", self.max_kinetic_energy_j)
    }

    fn split(&self, dt_s: f64) -> Result<(usize, StepLength), PlantError> {
        if !(dt_s.is_finite() && dt_s > 0.0) {
            return Err(PlantError::BadStep { dt_s });
        }
        let n = ((dt_s / self.substep_s) - 1e-9).ceil().max(1.0) as usize;
        let h = StepLength::new(dt_s / n as f64).map_err(|_| PlantError::BadStep { dt_s })?;
        Ok((n, h))
    }
}

/// The last `SimParams::split` answer: a closed loop steps by the same
/// `dt` every period, and the split (a division and a `ceil`, a libm call
/// on baseline x86-64) is a pure function of `dt` and the substep.
#[derive(Clone, Copy, Debug, Default)]
struct SplitCache {
    dt_s: f64,
    split: Option<(usize, StepLength)>,
}

impl SplitCache {
    #[inline]
    fn get(&mut self, sim: &SimParams, dt_s: f64) -> Result<(usize, StepLength), PlantError> {
        match self.split {
            Some(hit) if self.dt_s == dt_s => Ok(hit),
            _ => {
                let split = sim.split(dt_s)?;
                *self = Self {
                    dt_s,
                    split: Some(split),
                };
                Ok(split)
            }
        }
    }
}

fn check_inputs<const N: usize>(v: &[f64]) -> Result<[f64; N], PlantError> {
    if v.len() != N {
        return Err(PlantError::InputLength {
            expected: N,
            got: v.len(),
        });
    }
    let mut out = [0.0; N];
    for (i, (o, x)) in out.iter_mut().zip(v).enumerate() {
        if !x.is_finite() {
            return Err(PlantError::NonFiniteInput { coil: i + 1 });
        }
        *o = *x;
    }
    Ok(out)
}

// ---------------------------------------------------------------- 2D joint

/// Parameters of the 2D joint (one plane, one wire sensor, a camera).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Joint2dParams {
    /// The plane (link, support, coils, drivers).
    pub plane: PlaneParams,
    /// The wire sensor (geometry fitted to the paper's Eq. 2).
    pub wire: WireSensorParams,
    /// The camera.
    pub camera: CameraParams,
    /// Integration, settling, seed.
    pub sim: SimParams,
}

impl Default for Joint2dParams {
    fn default() -> Self {
        Self {
            plane: PlaneParams::default(),
            wire: WireSensorParams::with_geometry(WireGeometry::paper_2d()),
            camera: CameraParams::default(),
            sim: SimParams::default(),
        }
    }
}

impl Joint2dParams {
    /// The paper's comparison joint: same coils and sensor on a rigid bearing.
    pub fn rigid_bearing(mut self) -> Self {
        self.plane = self.plane.rigid_bearing();
        self
    }

    /// Rejects bad values, naming the field.
    pub fn validate(&self) -> Result<(), PlantError> {
        self.plane.validate("plane.")?;
        self.wire.validate("wire.")?;
        self.camera.validate("camera.")?;
        self.sim.validate()
    }
}

/// The 2D joint. Coil 1 raises θ (link end towards +x), coil 2 lowers it.
#[derive(Clone, Debug)]
pub struct Joint2d {
    params: Joint2dParams,
    plane: PlanarJoint,
    wire: WireSensor,
    camera: Camera,
    rng_wire: ChaCha8Rng,
    rng_camera: ChaCha8Rng,
    time_s: f64,
    split: SplitCache,
}

impl Joint2d {
    /// Validates, builds and settles the joint (coils off for `settle_s`).
    pub fn new(params: Joint2dParams) -> Result<Self, PlantError> {
        params.validate()?;
        let mut plane = PlanarJoint::new(params.plane.clone())?;
        let (n, h) = params
            .sim
            .split(params.sim.settle_s.max(params.sim.substep_s))?;
        if params.sim.settle_s > 0.0 {
            for _ in 0..n {
                plane.substep(h, [0.0; 2]);
                plane.check("2d", params.sim.max_kinetic_energy_j)?;
            }
        }
        let b = plane.base_m();
        let wire = WireSensor::new(
            params.wire.clone(),
            1e3 * b[0],
            1e3 * b[1],
            plane.angle_rad(),
        )?;
        let camera = Camera::new(params.camera.clone(), false)?;
        let seed = params.sim.seed;
        let mut j = Self {
            plane,
            wire,
            camera,
            rng_wire: plant_common::rng::stream(seed, plant_common::rng::WIRE_BASE),
            rng_camera: plant_common::rng::stream(seed, plant_common::rng::CAMERA),
            time_s: 0.0,
            split: SplitCache::default(),
            params,
        };
        j.observe();
        Ok(j)
    }

    fn observe(&mut self) {
        if !self.camera.is_due(self.time_s) {
            return;
        }
        let th = self.plane.angle_rad().to_degrees();
        let e = self.plane.end_m();
        self.camera.update(
            self.time_s,
            [th, 0.0],
            [1e3 * e[0], 1e3 * e[1]],
            &mut self.rng_camera,
        );
    }

    /// Advances by `dt_s` with driver input voltages `[v1, v2]` held.
    pub fn step(&mut self, dt_s: f64, coil_input_volts: &[f64]) -> Result<(), PlantError> {
        let v: [f64; 2] = check_inputs(coil_input_volts)?;
        let (n, h) = self.split.get(&self.params.sim, dt_s)?;
        for _ in 0..n {
            self.plane.substep(h, v);
            self.plane
                .check("2d", self.params.sim.max_kinetic_energy_j)?;
            let b = self.plane.base_m();
            let (sn, cs) = self.plane.sin_cos();
            self.wire
                .update_sin_cos(1e3 * b[0], 1e3 * b[1], sn, cs, &mut self.rng_wire);
        }
        self.time_s += dt_s;
        self.observe();
        Ok(())
    }

    /// Parameters.
    pub fn params(&self) -> &Joint2dParams {
        &self.params
    }
    /// Plant time since construction (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// The plane (link state, coils, loads).
    pub fn plane(&self) -> &PlanarJoint {
        &self.plane
    }
    /// Mutable plane (loads, warm starts).
    pub fn plane_mut(&mut self) -> &mut PlanarJoint {
        &mut self.plane
    }
    /// True link angle (deg; positive = link end towards +x, coil 1's way).
    pub fn angle_deg(&self) -> f64 {
        self.plane.angle_rad().to_degrees()
    }
    /// Link end in the socket frame (mm).
    pub fn end_mm(&self) -> [f64; 2] {
        let e = self.plane.end_m();
        [1e3 * e[0], 1e3 * e[1]]
    }
    /// Link base origin in the socket frame (mm).
    pub fn base_mm(&self) -> [f64; 2] {
        let b = self.plane.base_m();
        [1e3 * b[0], 1e3 * b[1]]
    }
    /// Coil temperatures [coil 1, coil 2] (°C).
    pub fn coil_temperatures_c(&self) -> [f64; 2] {
        self.plane.coils().each_ref().map(SmaCoil::temperature_c)
    }
    /// Coil currents during the last substep (A).
    pub fn coil_currents_a(&self) -> [f64; 2] {
        self.plane.coils().each_ref().map(SmaCoil::current_a)
    }
    /// Martensite fractions.
    pub fn martensite_fractions(&self) -> [f64; 2] {
        self.plane
            .coils()
            .each_ref()
            .map(SmaCoil::martensite_fraction)
    }
    /// The wire sensor.
    pub fn wire(&self) -> &WireSensor {
        &self.wire
    }
    /// Pulse-coder count.
    pub fn wire_counts(&self) -> i64 {
        self.wire.counts()
    }
    /// Measured insertion (mm, quantised, with jamming).
    pub fn wire_insertion_mm(&self) -> f64 {
        self.wire.insertion_mm()
    }
    /// The camera (latest frame, new frames).
    pub fn camera(&mut self) -> &mut Camera {
        &mut self.camera
    }
    /// The newest available camera frame, read-only.
    pub fn camera_latest(&self) -> Option<&CameraFrame> {
        self.camera.latest()
    }
    /// Attaches a point load (weight thread, push).
    pub fn add_load(&mut self, load: PointLoad) -> Result<LoadId, PlantError> {
        self.plane.add_load(load)
    }
    /// Hangs `mass_kg` from the link end, the thread led along `direction`
    /// (socket frame, e.g. `[-1, 0]`: horizontal over a pulley, towards −θ).
    pub fn add_weight_at_end(
        &mut self,
        mass_kg: f64,
        direction: [f64; 2],
    ) -> Result<LoadId, PlantError> {
        check_positive("load.mass_kg", mass_kg)?;
        let lp = &self.params.plane.link;
        self.plane.add_load(PointLoad::weight(
            mass_kg,
            lp.gravity_m_s2,
            [0.0, lp.end_length_m],
            direction,
        ))
    }
    /// Removes a load (cuts the thread).
    pub fn remove_load(&mut self, id: LoadId) -> Option<PointLoad> {
        self.plane.remove_load(id)
    }
}

// ---------------------------------------------------------------- 3D joint

/// The two projection planes of the 3D joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Plane {
    /// α: coils 1 (raises α) and 3 (lowers), sensors 1 and 3.
    Alpha,
    /// β: coils 2 (raises β) and 4 (lowers), sensors 2 and 4.
    Beta,
}

/// Parameters of the 3D joint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Joint3dParams {
    /// α plane.
    pub alpha: PlaneParams,
    /// β plane.
    pub beta: PlaneParams,
    /// Wire sensors 1..4 (geometries fitted to the paper's Eq. 3).
    pub wires: [WireSensorParams; 4],
    /// The camera (reports α and β).
    pub camera: CameraParams,
    /// Integration, settling, seed.
    pub sim: SimParams,
}

impl Default for Joint3dParams {
    fn default() -> Self {
        Self {
            alpha: PlaneParams::default(),
            beta: PlaneParams::default(),
            wires: core::array::from_fn(|i| {
                WireSensorParams::with_geometry(WireGeometry::paper_3d(i + 1))
            }),
            camera: CameraParams::default(),
            sim: SimParams::default(),
        }
    }
}

impl Joint3dParams {
    /// Rejects bad values, naming the field.
    pub fn validate(&self) -> Result<(), PlantError> {
        self.alpha.validate("alpha.")?;
        self.beta.validate("beta.")?;
        for (i, w) in self.wires.iter().enumerate() {
            w.validate(&format!("wires[{i}]."))?;
        }
        self.camera.validate("camera.")?;
        self.sim.validate()
    }
}

/// The 3D joint as two projection planes (see the module docs).
#[derive(Clone, Debug)]
pub struct Joint3d {
    params: Joint3dParams,
    planes: [PlanarJoint; 2],
    wires: [WireSensor; 4],
    camera: Camera,
    rng_wires: [ChaCha8Rng; 4],
    rng_camera: ChaCha8Rng,
    time_s: f64,
    split: SplitCache,
}

/// Plane index (0 = α, 1 = β) of 3D sensor/coil `k` (0-based, paper's k+1).
const PLANE_OF: [usize; 4] = [0, 1, 0, 1];

impl Joint3d {
    /// Validates, builds and settles the joint.
    pub fn new(params: Joint3dParams) -> Result<Self, PlantError> {
        params.validate()?;
        let mut planes = [
            PlanarJoint::new(params.alpha.clone())?,
            PlanarJoint::new(params.beta.clone())?,
        ];
        let names = ["alpha", "beta"];
        if params.sim.settle_s > 0.0 {
            let (n, h) = params.sim.split(params.sim.settle_s)?;
            for _ in 0..n {
                for (p, name) in planes.iter_mut().zip(names) {
                    p.substep(h, [0.0; 2]);
                    p.check(name, params.sim.max_kinetic_energy_j)?;
                }
            }
        }
        let mut wires = Vec::with_capacity(4);
        for (k, w) in params.wires.iter().enumerate() {
            let p = &planes[PLANE_OF[k]];
            let b = p.base_m();
            wires.push(WireSensor::new(
                w.clone(),
                1e3 * b[0],
                1e3 * b[1],
                p.angle_rad(),
            )?);
        }
        let wires: [WireSensor; 4] = wires
            .try_into()
            .map_err(|_| PlantError::param("wires", "need 4"))?;
        let seed = params.sim.seed;
        let mut j = Self {
            camera: Camera::new(params.camera.clone(), true)?,
            planes,
            wires,
            rng_wires: core::array::from_fn(|k| {
                plant_common::rng::stream(seed, plant_common::rng::WIRE_BASE + k as u64)
            }),
            rng_camera: plant_common::rng::stream(seed, plant_common::rng::CAMERA),
            time_s: 0.0,
            split: SplitCache::default(),
            params,
        };
        j.observe();
        Ok(j)
    }

    fn observe(&mut self) {
        if !self.camera.is_due(self.time_s) {
            return;
        }
        let a = self.angles_deg();
        let e = self.planes[0].end_m();
        self.camera.update(
            self.time_s,
            a,
            [1e3 * e[0], 1e3 * e[1]],
            &mut self.rng_camera,
        );
    }

    /// Advances by `dt_s` with driver inputs `[v1, v2, v3, v4]` (V), the
    /// paper's coil numbering: 1 raises α, 3 lowers α, 2 raises β, 4 lowers β.
    pub fn step(&mut self, dt_s: f64, coil_input_volts: &[f64]) -> Result<(), PlantError> {
        let v: [f64; 4] = check_inputs(coil_input_volts)?;
        let (n, h) = self.split.get(&self.params.sim, dt_s)?;
        let plane_inputs = [[v[0], v[2]], [v[1], v[3]]];
        let names = ["alpha", "beta"];
        for _ in 0..n {
            for ((p, vin), name) in self.planes.iter_mut().zip(plane_inputs).zip(names) {
                p.substep(h, vin);
                p.check(name, self.params.sim.max_kinetic_energy_j)?;
            }
            // Each plane's pose once for its two wires.
            let poses = self.planes.each_ref().map(|p| {
                let b = p.base_m();
                (1e3 * b[0], 1e3 * b[1], p.sin_cos())
            });
            for (k, (w, rng)) in self
                .wires
                .iter_mut()
                .zip(self.rng_wires.iter_mut())
                .enumerate()
            {
                let (x, y, (sn, cs)) = poses[PLANE_OF[k]];
                w.update_sin_cos(x, y, sn, cs, rng);
            }
        }
        self.time_s += dt_s;
        self.observe();
        Ok(())
    }

    /// Parameters.
    pub fn params(&self) -> &Joint3dParams {
        &self.params
    }
    /// Plant time since construction (s).
    pub fn time_s(&self) -> f64 {
        self.time_s
    }
    /// One plane.
    pub fn plane(&self, which: Plane) -> &PlanarJoint {
        &self.planes[which as usize]
    }
    /// One plane, mutable (loads, warm starts).
    pub fn plane_mut(&mut self, which: Plane) -> &mut PlanarJoint {
        &mut self.planes[which as usize]
    }
    /// True projection angles [α, β] (deg).
    pub fn angles_deg(&self) -> [f64; 2] {
        [
            self.planes[0].angle_rad().to_degrees(),
            self.planes[1].angle_rad().to_degrees(),
        ]
    }
    /// Link end in each projection plane (mm): [[x_α, y_α], [x_β, y_β]].
    pub fn end_mm(&self) -> [[f64; 2]; 2] {
        self.planes.each_ref().map(|p| {
            let e = p.end_m();
            [1e3 * e[0], 1e3 * e[1]]
        })
    }
    /// Coil temperatures, coils 1..4 (°C).
    pub fn coil_temperatures_c(&self) -> [f64; 4] {
        let [a, b] = &self.planes;
        [
            a.coils()[0].temperature_c(),
            b.coils()[0].temperature_c(),
            a.coils()[1].temperature_c(),
            b.coils()[1].temperature_c(),
        ]
    }
    /// Coil currents, coils 1..4 (A).
    pub fn coil_currents_a(&self) -> [f64; 4] {
        let [a, b] = &self.planes;
        [
            a.coils()[0].current_a(),
            b.coils()[0].current_a(),
            a.coils()[1].current_a(),
            b.coils()[1].current_a(),
        ]
    }
    /// Wire sensors 1..4.
    pub fn wires(&self) -> &[WireSensor; 4] {
        &self.wires
    }
    /// Pulse-coder counts d1..d4.
    pub fn wire_counts(&self) -> [i64; 4] {
        self.wires.each_ref().map(WireSensor::counts)
    }
    /// Measured insertions d1..d4 (mm).
    pub fn wire_insertions_mm(&self) -> [f64; 4] {
        self.wires.each_ref().map(WireSensor::insertion_mm)
    }
    /// The camera (reports [α, β]).
    pub fn camera(&mut self) -> &mut Camera {
        &mut self.camera
    }
    /// The newest available camera frame, read-only.
    pub fn camera_latest(&self) -> Option<&CameraFrame> {
        self.camera.latest()
    }
    /// Martensite fractions, coils 1..4.
    pub fn martensite_fractions(&self) -> [f64; 4] {
        let [a, b] = &self.planes;
        [
            a.coils()[0].martensite_fraction(),
            b.coils()[0].martensite_fraction(),
            a.coils()[1].martensite_fraction(),
            b.coils()[1].martensite_fraction(),
        ]
    }
    /// Hangs `mass_kg` from the link end in one plane, the thread led along
    /// `direction` (that plane's socket frame).
    pub fn add_weight_at_end(
        &mut self,
        which: Plane,
        mass_kg: f64,
        direction: [f64; 2],
    ) -> Result<LoadId, PlantError> {
        check_positive("load.mass_kg", mass_kg)?;
        let p = &mut self.planes[which as usize];
        let (g, l) = (p.params().link.gravity_m_s2, p.params().link.end_length_m);
        p.add_load(PointLoad::weight(mass_kg, g, [0.0, l], direction))
    }
    /// Attaches a load to one plane.
    pub fn add_load(&mut self, which: Plane, load: PointLoad) -> Result<LoadId, PlantError> {
        self.planes[which as usize].add_load(load)
    }
    /// Removes a load from one plane.
    pub fn remove_load(&mut self, which: Plane, id: LoadId) -> Option<PointLoad> {
        self.planes[which as usize].remove_load(id)
    }
}
