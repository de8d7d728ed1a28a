//! One complete control step for a joint with `P` antagonistic pairs and `S`
//! wire sensors: feedback → validity checks → angle estimate → pair laws →
//! safety supervisor → bounded driver commands.
//!
//! - [`Joint3d`] (`P = 2`, `S = 4`): the paper's 3D mechanism, α on coils
//!   1/3 and sensors 1/3, β on coils 2/4 and sensors 2/4 (seed 000, last
//!   paper, §VI), estimated with Eq. 3 by default or Eq. 4/5 once
//!   calibrated.
//! - [`Joint2d`] (`P = 1`, `S = 1`): the 2D mechanism with one wire sensor
//!   (Eq. 2) and an antagonistic pair (§V), or with camera feedback and one
//!   actuator (Eq. 1, §III).
//!
//! Feedback is either pulse counts ([`Feedback::WireCounts`]) or externally
//! measured angles ([`Feedback::Angles`], e.g. the 30 frames/s camera). A
//! channel without a new reading holds its last good value until it goes
//! stale. The step never allocates, never panics, and every output is a
//! [`PairCommand`] whose voltage lies in [0, supply].

use crate::control::{
    ControlError, DriveVolts, DriverConfig, PairCommand, PairController, PairDriver, PairGains,
    PairMode,
};
use crate::estimate::{
    CalibrationError, LinearLaw, Method, PlaneEstimator, PlaneLaw, PulseCoder, QuadraticLaw,
};
use crate::sensor::{SensorGuard, SensorLimits};
use crate::supervisor::{Faults, StillFaulted, Supervisor, SupervisorConfig};
use crate::time::{Duration, Instant};
use embedded_hal::pwm::SetDutyCycle;

/// Coil index (0-based) of pair `pair`'s agonist or antagonist in a joint
/// of `pairs` pairs, in the paper's numbering: for the 3D joint coils 1–4
/// are (α agonist, β agonist, α antagonist, β antagonist), for the 2D joint
/// (agonist, antagonist). The one place this numbering is written down: the
/// protocol's coil fields, the simulator's coil arrays and the host's
/// per-coil gains all follow it.
pub const fn coil_index(pairs: usize, pair: usize, antagonist: bool) -> usize {
    if antagonist {
        pair + pairs
    } else {
        pair
    }
}

/// Per-pair `[agonist, antagonist]` values laid out over the coils in paper
/// numbering ([`coil_index`]); coils beyond `C` are dropped, missing ones
/// are `T::default()`.
pub fn pairs_to_coils<T: Copy + Default, const P: usize, const C: usize>(
    pairs: [[T; 2]; P],
) -> [T; C] {
    let mut coils = [T::default(); C];
    for (p, [agonist, antagonist]) in pairs.into_iter().enumerate() {
        if let Some(slot) = coils.get_mut(coil_index(P, p, false)) {
            *slot = agonist;
        }
        if let Some(slot) = coils.get_mut(coil_index(P, p, true)) {
            *slot = antagonist;
        }
    }
    coils
}

/// Coil values in paper numbering gathered per pair as `[agonist,
/// antagonist]` (the inverse of [`pairs_to_coils`]).
pub fn coils_to_pairs<T: Copy + Default, const P: usize, const C: usize>(
    coils: [T; C],
) -> [[T; 2]; P] {
    let at = |i: usize| coils.get(i).copied().unwrap_or_default();
    core::array::from_fn(|p| [at(coil_index(P, p, false)), at(coil_index(P, p, true))])
}

/// Why a joint configuration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ConfigError {
    /// A controller parameter (which one is in the payload).
    Control(ControlError),
    /// A calibration parameter.
    Calibration(CalibrationError),
    /// Sensor limits not finite or not ordered.
    SensorLimits,
    /// The plane index does not exist.
    NoSuchPlane,
    /// A target beyond the allowed range (± `max_target_deg`).
    TargetOutOfRange,
}

impl core::fmt::Display for ConfigError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ConfigError::Control(e) => write!(f, "controller: {e}"),
            ConfigError::Calibration(e) => write!(f, "calibration: {e}"),
            ConfigError::SensorLimits => f.write_str(
                "sensor limits must be finite, ordered (min < max), with a rate > 0 and a stale limit > 0",
            ),
            ConfigError::NoSuchPlane => f.write_str("the joint has no such plane"),
            ConfigError::TargetOutOfRange => {
                f.write_str("the target is beyond the allowed range (±max_target_deg)")
            }
        }
    }
}

impl core::error::Error for ConfigError {}

impl From<ControlError> for ConfigError {
    fn from(e: ControlError) -> Self {
        ConfigError::Control(e)
    }
}

impl From<CalibrationError> for ConfigError {
    fn from(e: CalibrationError) -> Self {
        ConfigError::Calibration(e)
    }
}

/// Everything a joint controller is built from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct JointConfig<const P: usize, const S: usize> {
    /// Driver input range and threshold.
    pub driver: DriverConfig,
    /// Counts → millimetres per sensor.
    pub coders: [PulseCoder; S],
    /// Estimation law per plane.
    pub laws: [PlaneLaw; P],
    /// Gains per pair.
    pub gains: [PairGains; P],
    /// Single actuator (Eq. 1) or antagonistic, per pair.
    pub modes: [PairMode; P],
    /// Plausibility limits of the wire insertions.
    pub wire_limits: SensorLimits,
    /// Plausibility limits of measured or estimated angles.
    pub angle_limits: SensorLimits,
    /// Thermal budget and link watchdog.
    pub supervisor: SupervisorConfig,
    /// Largest accepted |target| (deg). Default 25°: the joint's range is
    /// about ±20° (paper §VI-A) plus margin.
    pub max_target_deg: f32,
}

/// The 3D joint: two pairs, four sensors.
pub type Joint3d = JointController<2, 4>;
/// The 2D joint: one pair, one sensor.
pub type Joint2d = JointController<1, 1>;

/// Default largest |target| (deg), see [`JointConfig::max_target_deg`].
pub const DEFAULT_MAX_TARGET_DEG: f32 = 25.0;

impl JointConfig<2, 4> {
    /// The paper's 3D joint: Eq. 3 with its published constants, Kp = 2.0
    /// V/deg on every coil (the paper's 3D gains are not printed; 2.0 is its
    /// visual-feedback gain), antagonistic pairs, default limits.
    pub fn paper_3d() -> Self {
        Self {
            driver: DriverConfig::default(),
            coders: [PulseCoder::default(); 4],
            laws: [
                PlaneLaw::Differential {
                    plus: 2,
                    minus: 0,
                    law: LinearLaw::PAPER_ALPHA,
                },
                PlaneLaw::Differential {
                    plus: 3,
                    minus: 1,
                    law: LinearLaw::PAPER_BETA,
                },
            ],
            gains: [PairGains::default(); 2],
            modes: [PairMode::Antagonistic; 2],
            wire_limits: SensorLimits::WIRE_DEFAULT,
            angle_limits: SensorLimits::CAMERA_DEFAULT,
            supervisor: SupervisorConfig::default(),
            max_target_deg: DEFAULT_MAX_TARGET_DEG,
        }
    }
}

impl JointConfig<1, 1> {
    /// The paper's 2D joint with one wire sensor (Eq. 2) and an antagonistic
    /// pair (§V-B), Kp = 2.0 V/deg.
    pub fn paper_2d_wire() -> Self {
        Self {
            driver: DriverConfig::default(),
            coders: [PulseCoder::default()],
            laws: [PlaneLaw::Single {
                sensor: 0,
                law: QuadraticLaw::PAPER_2D,
            }],
            gains: [PairGains::default()],
            modes: [PairMode::Antagonistic],
            wire_limits: SensorLimits::WIRE_DEFAULT,
            angle_limits: SensorLimits::CAMERA_DEFAULT,
            supervisor: SupervisorConfig::default(),
            max_target_deg: DEFAULT_MAX_TARGET_DEG,
        }
    }

    /// The paper's visual-feedback experiment (Eq. 1): one actuator, camera
    /// angles as feedback, gain `kp_v_per_deg` (the paper tried 0.05 and 2.0).
    pub fn paper_2d_camera(kp_v_per_deg: f32) -> Result<Self, ConfigError> {
        Ok(Self {
            gains: [PairGains::proportional(kp_v_per_deg, kp_v_per_deg)?],
            modes: [PairMode::SingleAgonist],
            ..Self::paper_2d_wire()
        })
    }
}

/// Feedback for one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Feedback<const S: usize, const P: usize> {
    /// Pulse-coder counts per wire sensor (`None`: no new reading).
    WireCounts([Option<i32>; S]),
    /// Measured angles per plane in degrees (`None`: no new frame).
    Angles([Option<f32>; P]),
}

/// Inputs of one step. Time is passed in: the core has no clock.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepInput<const S: usize, const P: usize> {
    /// Current time on the controller's monotonic time base. A step whose
    /// time is earlier than the previous step's is an invalid input.
    pub now: Instant,
    /// Time since the previous step (for the integrators and the thermal
    /// budget).
    pub dt: Duration,
    /// Sensor readings.
    pub feedback: Feedback<S, P>,
}

/// The faults of the sensor checks (§8 steps 1–2 of docs/protocol.md): a
/// step that finds one reports no estimate.
const SENSOR_FAULTS: Faults = Faults::from_bits(
    Faults::SENSOR_RANGE.bits() | Faults::SENSOR_RATE.bits() | Faults::SENSOR_STALE.bits(),
);

/// Result of one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepOutput<const P: usize> {
    /// What to apply to each pair (already supervised).
    pub commands: [PairCommand; P],
    /// Angle estimate per plane (deg): the held value when a channel had no
    /// new reading; NaN until every channel the plane's law uses has
    /// delivered a valid reading (and the outputs are off until then), and
    /// NaN on a step whose sensor checks found a fault.
    pub estimate_deg: [f32; P],
    /// Estimation method per plane (`None` for measured angles).
    pub methods: [Option<Method>; P],
    /// Faults active or latched.
    pub faults: Faults,
    /// What reaches each pair's coils, `[agonist, antagonist]`: the
    /// commands' voltages for planes under the controller, the supervised
    /// open-loop inputs for planes in drive mode
    /// ([`JointController::step_driven`]).
    pub coils: [[DriveVolts; 2]; P],
}

impl<const P: usize> StepOutput<P> {
    /// Driver input voltages per pair, `[agonist, antagonist]`.
    pub fn pair_volts(&self) -> [[f32; 2]; P] {
        let mut out = [[0.0; 2]; P];
        for (o, c) in out.iter_mut().zip(self.commands.iter()) {
            *o = c.coil_volts();
        }
        out
    }
}

impl StepOutput<2> {
    /// The 3D joint's voltages in the paper's coil numbering
    /// `[v1, v2, v3, v4]`: α pair = coils 1 (agonist) and 3, β pair = coils
    /// 2 (agonist) and 4.
    pub fn paper_coil_volts(&self) -> [f32; 4] {
        let [[v1, v3], [v2, v4]] = self.pair_volts();
        [v1, v2, v3, v4]
    }
}

/// The controller for `P` pairs and `S` wire sensors.
#[derive(Clone, Debug)]
pub struct JointController<const P: usize, const S: usize> {
    driver: DriverConfig,
    coders: [PulseCoder; S],
    estimators: [PlaneEstimator<S>; P],
    pairs: [PairController; P],
    targets_deg: [f32; P],
    wire_guard: SensorGuard<S>,
    angle_guard: SensorGuard<P>,
    supervisor: Supervisor<P>,
    max_target_deg: f32,
    estimate_deg: [f32; P],
    /// Wire sensors the laws read (bit k = sensor k).
    required_wires: u32,
    /// Time of the previous step on this time base.
    last_now: Option<Instant>,
}

impl<const P: usize, const S: usize> JointController<P, S> {
    /// Validates `config` and builds a disarmed controller with every target
    /// at 0°.
    pub fn new(config: JointConfig<P, S>) -> Result<Self, ConfigError> {
        if !config.wire_limits.is_valid() || !config.angle_limits.is_valid() {
            return Err(ConfigError::SensorLimits);
        }
        if !(config.max_target_deg.is_finite() && config.max_target_deg > 0.0) {
            return Err(ConfigError::TargetOutOfRange);
        }
        for law in config.laws.iter() {
            law.validate(S)?;
        }
        if config
            .gains
            .iter()
            .any(|g| g.v_offset_v() >= config.driver.supply_v())
        {
            return Err(ConfigError::Control(ControlError::OffsetOutOfRange));
        }
        let estimators = config.laws.map(PlaneEstimator::from_validated);
        let required_wires = config.laws.iter().fold(0, |m, l| m | l.sensor_mask());
        let mut pairs = config
            .gains
            .map(|g| PairController::new(g, PairMode::Antagonistic));
        for (p, m) in pairs.iter_mut().zip(config.modes.iter()) {
            *p = PairController::new(p.gains(), *m);
        }
        Ok(Self {
            driver: config.driver,
            coders: config.coders,
            estimators,
            pairs,
            targets_deg: [0.0; P],
            wire_guard: SensorGuard::new(config.wire_limits),
            angle_guard: SensorGuard::new(config.angle_limits),
            supervisor: Supervisor::new(config.supervisor),
            max_target_deg: config.max_target_deg,
            estimate_deg: [f32::NAN; P],
            required_wires,
            last_now: None,
        })
    }

    /// The driver configuration.
    pub fn driver(&self) -> &DriverConfig {
        &self.driver
    }

    /// Sets the desired angle of `plane` (0 = α, 1 = β).
    pub fn set_target(&mut self, plane: usize, desired_deg: f32) -> Result<(), ConfigError> {
        if !desired_deg.is_finite() {
            return Err(ConfigError::Control(ControlError::TargetNotFinite));
        }
        if desired_deg.abs() > self.max_target_deg {
            return Err(ConfigError::TargetOutOfRange);
        }
        let t = self
            .targets_deg
            .get_mut(plane)
            .ok_or(ConfigError::NoSuchPlane)?;
        *t = desired_deg;
        Ok(())
    }

    /// Desired angles (deg).
    pub fn targets_deg(&self) -> [f32; P] {
        self.targets_deg
    }

    /// Replaces the gains of `plane`. Their `v_offset` must lie below the
    /// driver's supply.
    pub fn set_gains(&mut self, plane: usize, gains: PairGains) -> Result<(), ConfigError> {
        if gains.v_offset_v() >= self.driver.supply_v() {
            return Err(ConfigError::Control(ControlError::OffsetOutOfRange));
        }
        self.pairs
            .get_mut(plane)
            .ok_or(ConfigError::NoSuchPlane)?
            .set_gains(gains);
        Ok(())
    }

    /// Gains of `plane`.
    pub fn gains(&self, plane: usize) -> Option<PairGains> {
        self.pairs.get(plane).map(|p| p.gains())
    }

    /// Replaces the estimation law of `plane` (validated).
    pub fn set_law(&mut self, plane: usize, law: PlaneLaw) -> Result<(), ConfigError> {
        let est = PlaneEstimator::new(law)?;
        *self
            .estimators
            .get_mut(plane)
            .ok_or(ConfigError::NoSuchPlane)? = est;
        self.required_wires = self
            .estimators
            .iter()
            .fold(0, |m, e| m | e.law().sensor_mask());
        Ok(())
    }

    /// Estimation law of `plane`.
    pub fn law(&self, plane: usize) -> Option<PlaneLaw> {
        self.estimators.get(plane).map(|e| e.law())
    }

    /// Integrator contribution of `plane` in volts.
    pub fn integral_v(&self, plane: usize) -> Option<f32> {
        self.pairs.get(plane).map(|p| p.integral_v())
    }

    /// Starts a new time base (entering lockstep, or after the clock was
    /// reset): sensor guards, estimator switching state, integrators and the
    /// supervisor's record of present causes start afresh. Latched faults
    /// remain until [`Self::clear_faults`].
    pub fn restart_time_base(&mut self) {
        self.wire_guard.reset();
        self.angle_guard.reset();
        for e in self.estimators.iter_mut() {
            e.reset();
        }
        for p in self.pairs.iter_mut() {
            p.reset();
        }
        self.estimate_deg = [f32::NAN; P];
        self.last_now = None;
        self.supervisor.restart_time_base();
    }

    /// Allows outputs (unless a fault is latched).
    pub fn arm(&mut self) {
        for p in self.pairs.iter_mut() {
            p.reset();
        }
        self.supervisor.arm();
    }

    /// Forces outputs off.
    pub fn disarm(&mut self) {
        self.supervisor.disarm();
    }

    /// True when armed.
    pub fn is_armed(&self) -> bool {
        self.supervisor.is_armed()
    }

    /// Clears latched faults if their causes have gone.
    pub fn clear_faults(&mut self) -> Result<(), StillFaulted> {
        self.supervisor.clear()
    }

    /// Latches a fault detected outside the step (link, driver, image).
    pub fn report_fault(&mut self, faults: Faults) {
        self.supervisor.report(faults);
    }

    /// Records a frame from the host (for the link watchdog).
    pub fn note_link_frame(&mut self, now: Instant) {
        self.supervisor.note_link_frame(now);
    }

    /// Wire sensors the estimation laws read (bit k = sensor k): the
    /// channels that must have delivered before any output is driven.
    pub fn required_wires(&self) -> u32 {
        self.required_wires
    }

    /// Runs one step and applies its commands to the pairs' drivers (the
    /// board's or the simulator's PWM channels). A channel that fails is
    /// the core's business, not the caller's: every pair is switched off at
    /// once, [`Faults::DRIVER`] latches (outputs stay off until cleared),
    /// and the returned output says so.
    pub fn step_and_drive<A: SetDutyCycle, B: SetDutyCycle>(
        &mut self,
        input: &StepInput<S, P>,
        drivers: &mut [PairDriver<A, B>; P],
    ) -> StepOutput<P> {
        let mut out = self.step(input);
        let driver = self.driver;
        let failed = drivers
            .iter_mut()
            .zip(out.coils.iter())
            .fold(false, |failed, (d, volts)| {
                d.apply_coils(*volts, &driver).is_err() || failed
            });
        if failed {
            for d in drivers.iter_mut() {
                // Both channels are tried even if one fails; nothing more
                // can be done about a channel that cannot be switched off.
                let _ = d.all_off();
            }
            self.supervisor.report(Faults::DRIVER);
            for p in self.pairs.iter_mut() {
                p.reset();
            }
            out.commands = [PairCommand::Off; P];
            out.coils = [[DriveVolts::ZERO; 2]; P];
            out.faults |= Faults::DRIVER;
        }
        out
    }

    /// The supervisor (thermal state, latched faults).
    pub fn supervisor(&self) -> &Supervisor<P> {
        &self.supervisor
    }

    /// Runs one control step.
    pub fn step(&mut self, input: &StepInput<S, P>) -> StepOutput<P> {
        self.step_driven(input, [None; P])
    }

    /// Runs one step with some planes driven open loop: `drive[p] =
    /// Some([agonist, antagonist])` replaces plane `p`'s control law by
    /// those inputs (both coils may be heated: co-contraction), `None`
    /// leaves the plane under its controller. Sensors are still checked and
    /// the estimate still runs; every input goes through the supervisor
    /// (arm state, latched faults, each coil's thermal budget). A driven
    /// plane's controller is reset, so it resumes without integrator state.
    /// An open-loop drive does not use the estimate, but like the
    /// controller it drives nothing before every sensor the laws read has
    /// delivered (the sensor checks must be watching the coils it heats),
    /// nor after a sensor fault, which latches.
    pub fn step_driven(
        &mut self,
        input: &StepInput<S, P>,
        drive: [Option<[DriveVolts; 2]>; P],
    ) -> StepOutput<P> {
        let mut faults = Faults::NONE;
        // Time must not run backwards on one time base; a caller that
        // restarts its clock calls `restart_time_base` first.
        if self.last_now.is_some_and(|last| input.now < last) {
            faults |= Faults::INVALID_INPUT;
        } else {
            self.last_now = Some(input.now);
        }
        let mut methods = [None; P];
        // True once every channel the estimate needs has delivered.
        let ready = match input.feedback {
            Feedback::WireCounts(counts) => {
                let mut mm = [None; S];
                for ((m, c), coder) in mm.iter_mut().zip(counts.iter()).zip(self.coders.iter()) {
                    *m = c.map(|c| coder.insertion_mm(c));
                }
                let checked = self.wire_guard.check(input.now, &mm);
                faults |= checked.faults;
                let ready = checked.has_delivered(self.required_wires);
                // Estimate from held values only while every channel is
                // healthy, so a faulty channel cannot move the switching
                // state; otherwise the last estimate is held.
                if ready && checked.faults.is_empty() {
                    for ((est, out), method) in self
                        .estimators
                        .iter_mut()
                        .zip(self.estimate_deg.iter_mut())
                        .zip(methods.iter_mut())
                    {
                        let e = est.estimate(&checked.values);
                        *out = e.angle_deg;
                        *method = Some(e.method);
                    }
                    let lim = self.angle_guard.limits();
                    if self
                        .estimate_deg
                        .iter()
                        .any(|a| !(lim.min..=lim.max).contains(a))
                    {
                        faults |= Faults::SENSOR_RANGE;
                    }
                }
                ready
            }
            Feedback::Angles(angles) => {
                let checked = self.angle_guard.check(input.now, &angles);
                faults |= checked.faults;
                let all = 1u32.checked_shl(P as u32).map_or(u32::MAX, |b| b - 1);
                let ready = checked.has_delivered(all);
                if ready {
                    self.estimate_deg = checked.values;
                }
                ready
            }
        };

        let mut commands = [PairCommand::Off; P];
        let dt_s = input.dt.as_secs_f32();
        for (((cmd, pair), (angle, target)), d) in commands
            .iter_mut()
            .zip(self.pairs.iter_mut())
            .zip(self.estimate_deg.iter().zip(self.targets_deg.iter()))
            .zip(drive.iter())
        {
            if d.is_some() {
                pair.reset();
            } else if ready && faults.is_empty() {
                *cmd = pair.update(&self.driver, *angle, *target, dt_s);
            }
        }
        let mut want = [[DriveVolts::ZERO; 2]; P];
        for ((w, c), d) in want.iter_mut().zip(commands.iter()).zip(drive.iter()) {
            *w = match d {
                // No output before readings (as for the controller): a drive
                // waits until every sensor the laws read has delivered, so
                // the sensor checks watch every coil it heats.
                Some(v) if ready && faults.is_empty() => *v,
                Some(_) => [DriveVolts::ZERO; 2],
                None => c.coil_drive(),
            };
        }
        let supervised =
            self.supervisor
                .supervise_coils(input.now, input.dt, want, faults, &self.driver);
        // Planes under the controller: their commands with whatever the
        // supervisor removed removed (the pair rule holds for them); a
        // driven plane's command is `Off` and stays so.
        let out_commands = supervised.limit(commands);
        if supervised.faults.intersects(Faults::LATCHING) || !self.supervisor.is_armed() {
            // While outputs are forced off, integrators must not keep state
            // that would kick the coils when control resumes.
            for p in self.pairs.iter_mut() {
                p.reset();
            }
        }
        // A step whose sensor checks failed reports no estimate: the held
        // value is not what the sensors say now.
        let estimate_deg = if faults.intersects(SENSOR_FAULTS) {
            [f32::NAN; P]
        } else {
            self.estimate_deg
        };
        StepOutput {
            commands: out_commands,
            estimate_deg,
            methods,
            faults: supervised.faults,
            coils: supervised.coils,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coils_are_numbered_as_the_paper_does() {
        assert_eq!(
            pairs_to_coils::<f64, 2, 4>([[1.0, 3.0], [2.0, 4.0]]),
            [1.0, 2.0, 3.0, 4.0]
        );
        assert_eq!(pairs_to_coils::<f64, 1, 2>([[1.0, 2.0]]), [1.0, 2.0]);
        assert_eq!(coils_to_pairs::<u16, 2, 4>([1, 2, 3, 4]), [[1, 3], [2, 4]]);
        assert_eq!(coil_index(2, 1, true), 3);
        assert_eq!(coil_index(1, 0, true), 1);
    }
}
