//! A run specification: a scenario resolved once into what a run of the
//! joint needs — the joint and its plant, the controller's gains and
//! estimation laws, feedback, period, seed, and the schedule of targets and
//! disturbances. `sim`, `hil`, excitation sessions, tuning and the
//! calibration sweep all take a [`RunSpec`] (or its [`JointSpec`]), never
//! the raw scenario.
use firmware::control::PairGains;
use hal_sim::FeedbackSource;

use crate::files::scenario::{ControlMode, Disturbance, FeedbackKind, Scenario, TargetStep};
use crate::run::joint::{ControllerSpec, CoreLoopTask, JointSpec};
use crate::run::laws::{self, Estimation};

/// A scenario resolved once: everything a run of the joint needs.
#[derive(Clone, Debug, PartialEq)]
pub struct RunSpec {
    /// Shown in reports.
    pub name: String,
    /// The simulated joint.
    pub joint: JointSpec,
    /// The controller: gains, laws, feedback, period, seed.
    pub controller: ControllerSpec,
    /// Where the estimation laws come from, for the summary.
    pub estimator: String,
    /// Wire sensors or the camera.
    pub feedback: FeedbackKind,
    /// Simulated duration (s).
    pub duration_s: f64,
    /// Desired angles over time (validated: in time order, one angle per
    /// plane).
    pub targets: Vec<TargetStep>,
    /// Disturbances (validated).
    pub disturbances: Vec<Disturbance>,
}

impl RunSpec {
    /// Resolves scenario `s`: validates it, builds its joint, gains and
    /// estimation laws. The laws are the paper's, a calibration file's, or
    /// fitted to a simulated calibration sweep of the joint — that last
    /// step is [`laws::resolve`]'s, cached per joint and method.
    pub fn resolve(s: &Scenario) -> anyhow::Result<Self> {
        s.validate()?;
        let joint = JointSpec::of(s);
        let Estimation { laws, description } = laws::resolve(s, &joint)?;
        let planes = joint.planes();
        let gains = (0..planes)
            .map(|pair| pair_gains(s, pair))
            .collect::<anyhow::Result<Vec<_>>>()?;
        Ok(Self {
            name: s.name.clone(),
            controller: ControllerSpec {
                gains: Some(gains),
                single_actuator: s.controller.mode == ControlMode::Single,
                laws,
                feedback: match s.feedback {
                    FeedbackKind::Wire => FeedbackSource::Wire,
                    FeedbackKind::Camera => FeedbackSource::Camera,
                },
                period_us: s.control_period_us,
                seed: s.seed,
            },
            joint,
            estimator: description,
            feedback: s.feedback,
            duration_s: s.duration_s,
            targets: s.targets.clone(),
            disturbances: s.disturbances.clone(),
        })
    }

    /// Control period (µs).
    pub fn period_us(&self) -> u32 {
        self.controller.period_us
    }

    /// Control period (s).
    pub fn period_s(&self) -> f64 {
        f64::from(self.controller.period_us) * 1e-6
    }

    /// Control steps in the run.
    pub fn steps(&self) -> u64 {
        (self.duration_s / self.period_s()).round() as u64
    }

    /// The seed of every random stream of the run.
    pub fn seed(&self) -> u64 {
        self.joint.seed
    }

    /// Controlled angles: 1 (2D) or 2 (3D).
    pub fn planes(&self) -> usize {
        self.joint.planes()
    }

    /// Runs `task` on the run's closed loop with the core in process.
    pub fn core_loop<T: CoreLoopTask>(&self, task: T) -> anyhow::Result<T::Output> {
        self.joint.core_loop(&self.controller, task)
    }
}

/// Pair `pair`'s gains from the scenario's per-coil K_P (paper numbering:
/// pair p's agonist and antagonist are [`firmware::joint::coil_index`]).
fn pair_gains(s: &Scenario, pair: usize) -> anyhow::Result<PairGains> {
    let kp = &s.controller.kp_v_per_deg;
    let planes = s.planes();
    let k = |coil: usize| kp.get(coil).or(kp.first()).copied().unwrap_or(2.0) as f32;
    PairGains::new(
        k(firmware::joint::coil_index(planes, pair, false)),
        k(firmware::joint::coil_index(planes, pair, true)),
        s.controller.ki_v_per_deg_s as f32,
        s.controller.integral_limit_v as f32,
    )
    .and_then(|g| g.with_v_offset(s.controller.v_offset_v as f32))
    .map_err(|e| anyhow::anyhow!("controller gains: {e}"))
}
