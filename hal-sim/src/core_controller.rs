//! The firmware core in process: [`CoreController`] steps a
//! `JointController` on simulated sensors and drives simulated PWM channels
//! through the core's own driver code, exactly as a board does.

use firmware::app::lockstep_instant;
use firmware::control::PairDriver;
use firmware::joint::{ConfigError, Feedback, JointController, StepInput, StepOutput};
use firmware::sensor::WireSensor;
use firmware::time::{Duration, Instant};

use crate::closed_loop::{Actuation, Controller, Readings};
use crate::devices::{SimPwm, SimWireSensor};

/// How the controller is fed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FeedbackSource {
    /// Wire pulse coders (the paper's §V–VI).
    Wire,
    /// The camera (the paper's §III, 30 frames/s).
    Camera,
}

/// ChaCha stream of wire sensor `k`'s dropout draws (see
/// `plant_common::rng` for the registry of stream numbers).
const DROPOUT_STREAM: u64 = plant_common::rng::HAL_SIM_SENSOR_BASE;

/// The firmware core in process, with `P` pairs and `S` wire sensors,
/// stepped once per control period at the board's lockstep instants.
pub struct CoreController<const P: usize, const S: usize> {
    joint: JointController<P, S>,
    drivers: [PairDriver<SimPwm, SimPwm>; P],
    pwm: [[SimPwm; 2]; P],
    sensors: [SimWireSensor; S],
    feedback: FeedbackSource,
    period: Duration,
    anchor: Instant,
    step: u64,
    last: Option<StepOutput<P>>,
}

impl<const P: usize, const S: usize> CoreController<P, S> {
    /// Wires `joint` to simulated channels and coders (resolution
    /// `mm_per_count`, dropouts drawn from `seed`'s streams) and arms it. Its
    /// clock starts at the epoch and advances `period_us` per step.
    pub fn new(
        mut joint: JointController<P, S>,
        feedback: FeedbackSource,
        period_us: u32,
        mm_per_count: [f64; S],
        seed: u64,
    ) -> Self {
        let driver = *joint.driver();
        let pwm: [[SimPwm; 2]; P] =
            core::array::from_fn(|_| [SimPwm::for_driver(&driver), SimPwm::for_driver(&driver)]);
        let drivers =
            core::array::from_fn(|p| PairDriver::new(pwm[p][0].clone(), pwm[p][1].clone()));
        let sensors = core::array::from_fn(|k| {
            SimWireSensor::new(
                mm_per_count[k],
                plant_common::rng::stream(seed, DROPOUT_STREAM + k as u64),
            )
        });
        joint.arm();
        Self {
            joint,
            drivers,
            pwm,
            sensors,
            feedback,
            period: Duration::from_micros(u64::from(period_us)),
            anchor: Instant::ZERO,
            step: 0,
            last: None,
        }
    }

    /// The same controller whose clock reads `anchor` at its first step (a
    /// board that has been up that long).
    pub fn starting_at(mut self, anchor: Instant) -> Self {
        self.anchor = anchor;
        self
    }

    /// The control core.
    pub fn joint(&self) -> &JointController<P, S> {
        &self.joint
    }

    /// The control core, mutable (targets, gains, fault clearing).
    pub fn joint_mut(&mut self) -> &mut JointController<P, S> {
        &mut self.joint
    }

    /// Sensor handles (for fault injection).
    pub fn sensors(&self) -> &[SimWireSensor; S] {
        &self.sensors
    }

    /// PWM handles `[pair][agonist, antagonist]` (for fault injection).
    pub fn pwm(&self) -> &[[SimPwm; 2]; P] {
        &self.pwm
    }

    /// The core's output of the last step.
    pub fn last_output(&self) -> Option<&StepOutput<P>> {
        self.last.as_ref()
    }

    /// The controller's clock at the next step.
    pub fn next_instant(&self) -> Instant {
        lockstep_instant(self.anchor, self.step, self.period)
    }
}

impl<const P: usize, const S: usize> Controller<P, S> for CoreController<P, S> {
    type Error = ConfigError;

    fn set_target(&mut self, plane: usize, desired_deg: f32) -> Result<(), ConfigError> {
        self.joint.set_target(plane, desired_deg)
    }

    fn targets_deg(&self) -> [f32; P] {
        self.joint.targets_deg()
    }

    fn step(&mut self, readings: &Readings<P, S>) -> Result<Actuation<P>, ConfigError> {
        let feedback = match self.feedback {
            FeedbackSource::Wire => {
                let mut counts = [None; S];
                for ((c, s), plant) in counts
                    .iter_mut()
                    .zip(self.sensors.iter_mut())
                    .zip(readings.counts)
                {
                    s.set_plant_counts(plant);
                    *c = s.read_counts().ok();
                }
                Feedback::WireCounts(counts)
            }
            FeedbackSource::Camera => Feedback::Angles(core::array::from_fn(|p| {
                readings.camera.map(|f| f[p] as f32)
            })),
        };
        let input = StepInput {
            now: self.next_instant(),
            dt: self.period,
            feedback,
        };
        let out = self.joint.step_and_drive(&input, &mut self.drivers);
        self.step = self.step.saturating_add(1);
        self.last = Some(out);
        Ok(Actuation {
            pair_volts: self
                .pwm
                .each_ref()
                .map(|[a, b]| [a.coil_input_volts(), b.coil_input_volts()]),
            estimate_deg: out.estimate_deg.map(f64::from),
            faults: out.faults.bits(),
        })
    }
}
