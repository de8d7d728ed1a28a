//! embedded-hal implementations backed by the plant models, so the firmware
//! core runs closed loop on the host exactly as it runs on a board.
//!
//! - [`SimPwm`]: one SMA driver channel (`embedded_hal::pwm::SetDutyCycle`).
//!   Its full scale is the supply in millivolts, so one duty count is 1 mV
//!   at the driver input — the resolution the serial protocol carries, which
//!   makes the simulator and the hardware-in-the-loop link see identical
//!   voltages.
//! - [`SimWireSensor`]: one pulse coder (the core's `WireSensor` trait).
//! - [`SimClock`] and [`SimDelay`] (`embedded_hal::delay::DelayNs`): simulated
//!   time that only moves when the simulation says so.
//! - [`ClosedLoop`]: plant + controller + drivers + sensors, stepped at a
//!   fixed control period with the board's own time arithmetic.
//!
//! Fault injection ([`SensorFault`], [`CoilFault`]): stuck and jammed
//! sensors, dropped samples (seeded), dead sensors, open coils, failing PWM
//! channels. Everything is deterministic.

#![deny(unsafe_code)]

use std::cell::Cell;
use std::rc::Rc;

use embedded_hal::pwm::{ErrorKind, ErrorType, SetDutyCycle};
use firmware::control::{DriverConfig, PairDriver};
use firmware::joint::{Feedback, JointController, StepInput, StepOutput};
use firmware::protocol::millivolt_full_scale;
use firmware::sensor::{WireSensor, WireSensorError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

pub mod plants;

/// Simulated time in seconds, shared by the parts of one simulation.
#[derive(Clone, Debug, Default)]
pub struct SimClock(Rc<Cell<f64>>);

impl SimClock {
    /// A clock at t = 0.
    pub fn new() -> Self {
        Self::default()
    }
    /// Current time (s).
    pub fn now_s(&self) -> f64 {
        self.0.get()
    }
    /// Moves time forward by `dt_s` (ignored unless finite and > 0).
    pub fn advance(&self, dt_s: f64) {
        if dt_s.is_finite() && dt_s > 0.0 {
            self.0.set(self.0.get() + dt_s);
        }
    }
}

/// `DelayNs` that advances a [`SimClock`] instead of spinning.
#[derive(Clone, Debug)]
pub struct SimDelay(pub SimClock);

impl embedded_hal::delay::DelayNs for SimDelay {
    fn delay_ns(&mut self, ns: u32) {
        self.0.advance(f64::from(ns) * 1e-9);
    }
}

/// An injected coil or channel fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoilFault {
    /// The coil is disconnected: duty is accepted, no current flows.
    Open,
    /// The PWM channel reports an error on every write.
    ChannelError,
}

/// Error of a failing simulated PWM channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PwmFailure;

impl embedded_hal::pwm::Error for PwmFailure {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

#[derive(Debug, Default)]
struct PwmState {
    duty: Cell<u16>,
    /// `duty / 1000` (V), computed when the duty is written: the plant
    /// reads it every period, the controller writes it less often.
    volts: Cell<f64>,
    fault: Cell<Option<CoilFault>>,
}

/// One simulated SMA driver channel. Clones share the channel, so a test can
/// keep a handle while the controller owns the writer.
#[derive(Clone, Debug)]
pub struct SimPwm {
    state: Rc<PwmState>,
    max_duty: u16,
}

impl SimPwm {
    /// A channel whose full scale is the driver supply in millivolts.
    pub fn for_driver(driver: &DriverConfig) -> Self {
        Self {
            state: Rc::default(),
            max_duty: millivolt_full_scale(driver),
        }
    }
    /// Duty as last written.
    pub fn duty(&self) -> u16 {
        self.state.duty.get()
    }
    /// The voltage the driver input sees (0 with an open coil).
    pub fn coil_input_volts(&self) -> f64 {
        match self.state.fault.get() {
            Some(CoilFault::Open) => 0.0,
            _ => self.state.volts.get(),
        }
    }
    /// Injects or clears a fault.
    pub fn set_fault(&self, fault: Option<CoilFault>) {
        self.state.fault.set(fault);
    }
}

impl ErrorType for SimPwm {
    type Error = PwmFailure;
}

impl SetDutyCycle for SimPwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max_duty
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), PwmFailure> {
        if self.state.fault.get() == Some(CoilFault::ChannelError) {
            return Err(PwmFailure);
        }
        let duty = duty.min(self.max_duty);
        if duty != self.state.duty.get() {
            self.state.duty.set(duty);
            self.state.volts.set(f64::from(duty) / 1000.0);
        }
        Ok(())
    }
}

/// An injected wire-sensor fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensorFault {
    /// The count freezes at its value when the fault starts.
    Stuck,
    /// An extra lag of this many mm on top of the plant's own jamming.
    Jammed {
        /// Extra lag (mm).
        extra_mm: f64,
    },
    /// Each read fails (`NotReady`) with this probability (seeded).
    Dropout {
        /// Probability per read, 0..=1.
        probability: f64,
    },
    /// The coder is dead: every read is a `Fault`.
    Dead,
}

#[derive(Debug)]
struct SensorState {
    counts: Cell<i64>,
    mm_per_count: f64,
    fault: Cell<Option<SensorFault>>,
    stuck_at: Cell<Option<i64>>,
    rng: std::cell::RefCell<ChaCha8Rng>,
}

/// One simulated pulse coder; clones share it.
#[derive(Clone, Debug)]
pub struct SimWireSensor(Rc<SensorState>);

impl SimWireSensor {
    /// A coder with the plant's resolution, seeded for dropouts.
    pub fn new(mm_per_count: f64, seed: u64) -> Self {
        Self(Rc::new(SensorState {
            counts: Cell::new(0),
            mm_per_count,
            fault: Cell::new(None),
            stuck_at: Cell::new(None),
            rng: std::cell::RefCell::new(ChaCha8Rng::seed_from_u64(seed)),
        }))
    }
    /// Sets the plant's current count.
    pub fn set_plant_counts(&self, counts: i64) {
        self.0.counts.set(counts);
    }
    /// Injects or clears a fault.
    pub fn set_fault(&self, fault: Option<SensorFault>) {
        self.0.stuck_at.set(match fault {
            Some(SensorFault::Stuck) => Some(self.0.counts.get()),
            _ => None,
        });
        self.0.fault.set(fault);
    }
}

impl WireSensor for SimWireSensor {
    fn read_counts(&mut self) -> Result<i32, WireSensorError> {
        let s = &self.0;
        let counts = match s.fault.get() {
            None => s.counts.get(),
            Some(SensorFault::Stuck) => s.stuck_at.get().unwrap_or(s.counts.get()),
            Some(SensorFault::Jammed { extra_mm }) => {
                s.counts.get() - (extra_mm / s.mm_per_count).round() as i64
            }
            Some(SensorFault::Dropout { probability }) => {
                if s.rng.borrow_mut().gen_bool(probability.clamp(0.0, 1.0)) {
                    return Err(WireSensorError::NotReady);
                }
                s.counts.get()
            }
            Some(SensorFault::Dead) => return Err(WireSensorError::Fault),
        };
        i32::try_from(counts).map_err(|_| WireSensorError::Fault)
    }
}

/// What the closed loop needs from a plant with `C` coils and `S` sensors
/// and `P` angles.
pub trait Plant<const C: usize, const S: usize, const P: usize> {
    /// Advances by `dt_s` with the driver input voltages held.
    fn advance(
        &mut self,
        dt_s: f64,
        coil_input_volts: &[f64; C],
    ) -> Result<(), plant_models::joint::PlantError>;
    /// Pulse-coder counts now.
    fn counts(&self) -> [i64; S];
    /// Coder resolution (mm/count) of each sensor.
    fn mm_per_count(&self) -> [f64; S];
    /// True angles (deg).
    fn true_angles_deg(&self) -> [f64; P];
    /// A camera frame that became available since the last call.
    fn take_camera(&mut self) -> Option<[f64; P]>;
    /// Coil temperatures (°C).
    fn coil_temperatures_c(&self) -> [f64; C];
}

/// How the controller is fed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedbackSource {
    /// Wire pulse coders (the paper's §V–VI).
    Wire,
    /// The camera (the paper's §III, 30 frames/s).
    Camera,
}

/// One recorded control period.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample<const P: usize, const C: usize> {
    /// Time at the start of the period (s).
    pub t_s: f64,
    /// True angles (deg).
    pub true_deg: [f64; P],
    /// Controller's estimates (deg).
    pub estimate_deg: [f64; P],
    /// Desired angles (deg).
    pub desired_deg: [f64; P],
    /// Driver input voltages applied for the period, coils in the paper's
    /// numbering.
    pub coil_volts: [f64; C],
    /// Fault bits after the step.
    pub faults: u16,
}

/// Plant + firmware controller + simulated drivers and sensors, stepped in
/// lockstep at a fixed control period. `P` pairs, `S` sensors, `C = 2P`
/// coils, numbered as the paper does: for 3D coils 1..4 are (α agonist, β
/// agonist, α antagonist, β antagonist); for 2D (agonist, antagonist).
pub struct ClosedLoop<Pl, const P: usize, const S: usize, const C: usize> {
    /// The plant.
    pub plant: Pl,
    /// The firmware controller.
    pub controller: JointController<P, S>,
    drivers: [PairDriver<SimPwm, SimPwm>; P],
    pwm: [[SimPwm; 2]; P],
    sensors: [SimWireSensor; S],
    feedback: FeedbackSource,
    period_us: u32,
    step: u32,
    clock: SimClock,
    /// Extra voltages forced onto coils (disturbances), by coil index.
    pub overrides: [Option<f64>; C],
}

/// Why the closed loop stopped.
#[derive(Debug, thiserror::Error)]
pub enum LoopError {
    /// The plant refused a step (instability, bad input). The plant's
    /// error is part of this message and deliberately not also returned
    /// as `source()`: reporters that print the chain (`anyhow`'s `{:#}`)
    /// would otherwise print it twice.
    #[error("plant: {0}")]
    Plant(plant_models::joint::PlantError),
    /// The control period is not usable.
    #[error("control period must be 100 µs..=1 s, got {0} µs")]
    Period(u32),
}

impl From<plant_models::joint::PlantError> for LoopError {
    fn from(e: plant_models::joint::PlantError) -> Self {
        LoopError::Plant(e)
    }
}

/// Coil index (paper numbering, 0-based) of pair `p`'s agonist/antagonist.
pub fn coil_index<const P: usize>(pair: usize, antagonist: bool) -> usize {
    if antagonist {
        pair + P
    } else {
        pair
    }
}

impl<Pl, const P: usize, const S: usize, const C: usize> ClosedLoop<Pl, P, S, C>
where
    Pl: Plant<C, S, P>,
{
    /// Wires `controller` to `plant` with a control period of `period_us`.
    /// The controller is armed.
    pub fn new(
        plant: Pl,
        mut controller: JointController<P, S>,
        feedback: FeedbackSource,
        period_us: u32,
        seed: u64,
    ) -> Result<Self, LoopError> {
        if !(100..=1_000_000).contains(&period_us) {
            return Err(LoopError::Period(period_us));
        }
        let driver = *controller.driver();
        let pwm: [[SimPwm; 2]; P] =
            core::array::from_fn(|_| [SimPwm::for_driver(&driver), SimPwm::for_driver(&driver)]);
        let drivers =
            core::array::from_fn(|p| PairDriver::new(pwm[p][0].clone(), pwm[p][1].clone()));
        let res = plant.mm_per_count();
        let sensors =
            core::array::from_fn(|k| SimWireSensor::new(res[k], seed.wrapping_add(k as u64)));
        for (s, c) in sensors.iter().zip(plant.counts()) {
            s.set_plant_counts(c);
        }
        controller.arm();
        Ok(Self {
            plant,
            controller,
            drivers,
            pwm,
            sensors,
            feedback,
            period_us,
            step: 0,
            clock: SimClock::new(),
            overrides: [None; C],
        })
    }

    /// Simulated time (s).
    pub fn time_s(&self) -> f64 {
        self.clock.now_s()
    }

    /// Steps taken.
    pub fn steps(&self) -> u32 {
        self.step
    }

    /// Control period (s).
    pub fn period_s(&self) -> f64 {
        f64::from(self.period_us) * 1e-6
    }

    /// Sensor handles (for fault injection).
    pub fn sensors(&self) -> &[SimWireSensor; S] {
        &self.sensors
    }

    /// PWM handles `[pair][agonist, antagonist]` (for fault injection).
    pub fn pwm(&self) -> &[[SimPwm; 2]; P] {
        &self.pwm
    }

    /// Runs the controller on the current sensors (one step of the board),
    /// applies its commands, and returns them with the step output.
    pub fn control(&mut self) -> StepOutput<P> {
        let (now_s, dt_s) = firmware::app::lockstep_times(self.step, 1, self.period_us);
        let feedback = match self.feedback {
            FeedbackSource::Wire => {
                let mut counts = [None; S];
                for (c, s) in counts.iter_mut().zip(self.sensors.iter_mut()) {
                    *c = s.read_counts().ok();
                }
                Feedback::WireCounts(counts)
            }
            FeedbackSource::Camera => {
                let frame = self.plant.take_camera();
                Feedback::Angles(core::array::from_fn(|p| frame.map(|f| f[p] as f32)))
            }
        };
        let out = self.controller.step(&StepInput {
            now_s,
            dt_s,
            feedback,
        });
        let driver = *self.controller.driver();
        let mut driver_error = false;
        for (d, cmd) in self.drivers.iter_mut().zip(out.commands) {
            if d.apply(cmd, &driver).is_err() {
                driver_error = true;
                let _ = d.all_off();
            }
        }
        if driver_error {
            self.controller
                .report_fault(firmware::supervisor::Faults::DRIVER);
        }
        out
    }

    /// The driver input voltages the plant sees now (overrides applied).
    pub fn coil_volts(&self) -> [f64; C] {
        let mut v = [0.0; C];
        for (p, pair) in self.pwm.iter().enumerate() {
            if let Some(slot) = v.get_mut(coil_index::<P>(p, false)) {
                *slot = pair[0].coil_input_volts();
            }
            if let Some(slot) = v.get_mut(coil_index::<P>(p, true)) {
                *slot = pair[1].coil_input_volts();
            }
        }
        for (slot, o) in v.iter_mut().zip(self.overrides) {
            if let Some(volts) = o {
                *slot = volts;
            }
        }
        v
    }

    /// Advances the plant one control period with the current outputs.
    pub fn advance(&mut self) -> Result<(), LoopError> {
        let v = self.coil_volts();
        self.advance_with(&v)
    }

    /// [`Self::advance`] with the voltages already read.
    fn advance_with(&mut self, v: &[f64; C]) -> Result<(), LoopError> {
        let dt = self.period_s();
        self.plant.advance(dt, v)?;
        for (s, c) in self.sensors.iter().zip(self.plant.counts()) {
            s.set_plant_counts(c);
        }
        self.step = self.step.wrapping_add(1);
        self.clock.advance(dt);
        Ok(())
    }

    /// One full period: control, then plant. Returns the record.
    pub fn tick(&mut self) -> Result<Sample<P, C>, LoopError> {
        let t_s = self.time_s();
        let true_deg = self.plant.true_angles_deg();
        let out = self.control();
        let coil_volts = self.coil_volts();
        self.advance_with(&coil_volts)?;
        Ok(Sample {
            t_s,
            true_deg,
            estimate_deg: out.estimate_deg.map(f64::from),
            desired_deg: self.controller.targets_deg().map(f64::from),
            coil_volts,
            faults: out.faults.bits(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::delay::DelayNs;

    #[test]
    fn a_plant_error_is_printed_once() {
        use std::error::Error as _;
        let e = LoopError::from(plant_models::joint::PlantError::BadStep { dt_s: -1.0 });
        assert_eq!(
            e.to_string(),
            "plant: step length -1 s must be finite and > 0"
        );
        assert!(e.source().is_none(), "the plant error would print twice");
    }

    #[test]
    fn pwm_counts_millivolts_and_faults_bite() {
        let d = DriverConfig::default();
        let mut p = SimPwm::for_driver(&d);
        assert_eq!(p.max_duty_cycle(), 5000);
        p.set_duty_cycle(3200).unwrap();
        assert!((p.coil_input_volts() - 3.2).abs() < 1e-12);
        p.set_fault(Some(CoilFault::Open));
        assert_eq!(p.coil_input_volts(), 0.0);
        p.set_fault(Some(CoilFault::ChannelError));
        assert_eq!(p.set_duty_cycle(1), Err(PwmFailure));
    }

    #[test]
    fn sensor_faults_behave_as_named() {
        let mut s = SimWireSensor::new(0.01, 7);
        s.set_plant_counts(120);
        assert_eq!(s.read_counts(), Ok(120));
        s.set_fault(Some(SensorFault::Stuck));
        s.set_plant_counts(300);
        assert_eq!(s.read_counts(), Ok(120));
        s.set_fault(Some(SensorFault::Jammed { extra_mm: 0.5 }));
        assert_eq!(s.read_counts(), Ok(250));
        s.set_fault(Some(SensorFault::Dead));
        assert_eq!(s.read_counts(), Err(WireSensorError::Fault));
        s.set_fault(Some(SensorFault::Dropout { probability: 0.5 }));
        let dropped = (0..1000).filter(|_| s.read_counts().is_err()).count();
        assert!(
            (400..600).contains(&dropped),
            "{dropped} of 1000 dropped at p = 0.5"
        );
    }

    #[test]
    fn delay_advances_simulated_time_only() {
        let clock = SimClock::new();
        let mut d = SimDelay(clock.clone());
        d.delay_ms(3);
        d.delay_us(500);
        assert!((clock.now_s() - 0.0035).abs() < 1e-12);
    }
}
