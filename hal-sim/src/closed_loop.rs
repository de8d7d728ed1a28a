//! The one closed loop: plant ⇄ controller at a fixed control period, with
//! a schedule of targets and disturbances, one [`Sample`] per period.

use plant_joint::PlantError;

use crate::plants::Plant;

/// What the controller is given each period: the plant's pulse-coder
/// counts and a camera frame if a new one arrived.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Readings<const P: usize, const S: usize> {
    /// Pulse-coder counts of every wire sensor.
    pub counts: [i64; S],
    /// A new camera frame (angles, deg), if one arrived this period.
    pub camera: Option<[f64; P]>,
}

/// What the controller answers: the driver inputs for the next period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Actuation<const P: usize> {
    /// Driver input (V) per pair, `[agonist, antagonist]`, as the channels
    /// apply it.
    pub pair_volts: [[f64; 2]; P],
    /// The controller's angle estimates (deg; NaN when it has none).
    pub estimate_deg: [f64; P],
    /// Fault bits after the step.
    pub faults: u16,
}

/// A controller with `P` pairs and `S` wire sensors, wherever it runs: the
/// core in process ([`crate::CoreController`]) or a board behind a link
/// (`host_tools::board::BoardController`).
pub trait Controller<const P: usize, const S: usize> {
    /// Why a request failed (a refused target, a dead link).
    type Error: std::error::Error + Send + Sync + 'static;
    /// Sets the desired angle of `plane` (0 = α, 1 = β).
    fn set_target(&mut self, plane: usize, desired_deg: f32) -> Result<(), Self::Error>;
    /// The desired angles in force.
    fn targets_deg(&self) -> [f32; P];
    /// One control period.
    fn step(&mut self, readings: &Readings<P, S>) -> Result<Actuation<P>, Self::Error>;
}

/// What changes over a run: targets, and disturbances of the plant.
pub trait Schedule<Pl, const P: usize, const C: usize> {
    /// New desired angles when they change at `t_s` (start of a period).
    fn targets(&mut self, t_s: f64) -> Option<[f32; P]>;
    /// Disturbances during the period starting at `t_s`: coil voltages to
    /// force (by coil index; the loop clears them every period) and loads
    /// hung on or cut from `plant`.
    fn disturb(
        &mut self,
        t_s: f64,
        plant: &mut Pl,
        overrides: &mut [Option<f64>; C],
    ) -> Result<(), PlantError>;
}

/// A schedule in which nothing changes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Hold;

impl<Pl, const P: usize, const C: usize> Schedule<Pl, P, C> for Hold {
    fn targets(&mut self, _t_s: f64) -> Option<[f32; P]> {
        None
    }
    fn disturb(
        &mut self,
        _t_s: f64,
        _plant: &mut Pl,
        _o: &mut [Option<f64>; C],
    ) -> Result<(), PlantError> {
        Ok(())
    }
}

/// One control period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample<const P: usize, const S: usize, const C: usize> {
    /// Time at the start of the period (s).
    pub t_s: f64,
    /// True angles at the start of the period (deg).
    pub true_deg: [f64; P],
    /// What the controller was given.
    pub readings: Readings<P, S>,
    /// Controller's estimates (deg).
    pub estimate_deg: [f64; P],
    /// Desired angles (deg).
    pub desired_deg: [f64; P],
    /// Driver input voltages applied for the period, coils in the paper's
    /// numbering, disturbances included.
    pub coil_volts: [f64; C],
    /// Fault bits after the step.
    pub faults: u16,
    /// Coil temperatures at the end of the period (°C).
    pub coil_temperatures_c: [f64; C],
}

/// Why the loop stopped.
#[derive(Debug, thiserror::Error)]
pub enum LoopError<E: std::error::Error + 'static> {
    /// The plant refused a step (instability, bad input) or a disturbance.
    /// The plant's error is part of this message and deliberately not also
    /// returned as `source()`: reporters that print the chain (`anyhow`'s
    /// `{:#}`) would otherwise print it twice.
    #[error("at t = {t_s:.3} s: plant: {error}")]
    Plant {
        /// Time of the period (s).
        t_s: f64,
        /// The plant's reason.
        error: PlantError,
    },
    /// The controller failed (refused a target, stopped answering).
    #[error("at t = {t_s:.3} s: controller: {error}")]
    Controller {
        /// Time of the period (s).
        t_s: f64,
        /// The controller's reason.
        error: E,
    },
    /// The control period is not usable.
    #[error("control period must be 100 µs..=1 s, got {0} µs")]
    Period(u32),
}

/// Plant ⇄ controller at a fixed control period. `P` angles, `S` wire
/// sensors, `C = 2P` coils numbered as the paper does (see
/// [`crate::coil_index`]).
pub struct ClosedLoop<Pl, Ctl, const P: usize, const S: usize, const C: usize> {
    /// The plant.
    pub plant: Pl,
    /// The controller.
    pub controller: Ctl,
    period_us: u32,
    step: u64,
    /// Voltages forced onto coils (disturbances) for the next period, by
    /// coil index. [`Self::run`] sets them from the schedule every period.
    pub overrides: [Option<f64>; C],
}

impl<Pl, Ctl, const P: usize, const S: usize, const C: usize> ClosedLoop<Pl, Ctl, P, S, C>
where
    Pl: Plant<P, S, C>,
    Ctl: Controller<P, S>,
{
    /// Wires `controller` to `plant` with a control period of `period_us`.
    pub fn new(plant: Pl, controller: Ctl, period_us: u32) -> Result<Self, LoopError<Ctl::Error>> {
        if !firmware::app::LOCKSTEP_PERIOD_US.contains(&period_us) {
            return Err(LoopError::Period(period_us));
        }
        Ok(Self {
            plant,
            controller,
            period_us,
            step: 0,
            overrides: [None; C],
        })
    }

    /// Control period (s).
    pub fn period_s(&self) -> f64 {
        f64::from(self.period_us) * 1e-6
    }

    /// Periods run so far.
    pub fn steps(&self) -> u64 {
        self.step
    }

    /// Simulated time at the start of the next period (s).
    pub fn time_s(&self) -> f64 {
        self.step as f64 * self.period_s()
    }

    /// One period: the controller reads the plant's sensors and answers,
    /// the plant runs the period with those outputs (and any overrides).
    pub fn tick(&mut self) -> Result<Sample<P, S, C>, LoopError<Ctl::Error>> {
        let t_s = self.time_s();
        let readings = Readings {
            counts: self.plant.counts(),
            camera: self.plant.take_camera(),
        };
        let true_deg = self.plant.true_angles_deg();
        let act = self
            .controller
            .step(&readings)
            .map_err(|error| LoopError::Controller { t_s, error })?;
        let mut coil_volts: [f64; C] = crate::pairs_to_coils(act.pair_volts);
        for (v, o) in coil_volts.iter_mut().zip(self.overrides) {
            if let Some(forced) = o {
                *v = forced;
            }
        }
        self.plant
            .advance(self.period_s(), &coil_volts)
            .map_err(|error| LoopError::Plant { t_s, error })?;
        self.step += 1;
        Ok(Sample {
            t_s,
            true_deg,
            readings,
            estimate_deg: act.estimate_deg,
            desired_deg: self.controller.targets_deg().map(f64::from),
            coil_volts,
            faults: act.faults,
            coil_temperatures_c: self.plant.coil_temperatures_c(),
        })
    }

    /// Runs `steps` periods under `schedule`, passing every sample to
    /// `sink`. A sink error stops the run and is returned.
    pub fn run<E>(
        &mut self,
        steps: u64,
        schedule: &mut impl Schedule<Pl, P, C>,
        mut sink: impl FnMut(&Sample<P, S, C>) -> Result<(), E>,
    ) -> Result<(), E>
    where
        E: From<LoopError<Ctl::Error>>,
    {
        for _ in 0..steps {
            let t_s = self.time_s();
            if let Some(targets) = schedule.targets(t_s) {
                for (plane, d) in targets.into_iter().enumerate() {
                    self.controller
                        .set_target(plane, d)
                        .map_err(|error| LoopError::Controller { t_s, error })?;
                }
            }
            self.overrides = [None; C];
            schedule
                .disturb(t_s, &mut self.plant, &mut self.overrides)
                .map_err(|error| LoopError::Plant { t_s, error })?;
            let sample = self.tick()?;
            sink(&sample)?;
        }
        Ok(())
    }
}
