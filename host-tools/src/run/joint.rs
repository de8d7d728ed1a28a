//! The simulated joint of a run and the closed loop around it: the one
//! place where the 2D and the 3D joint differ. [`JointSpec`] holds either
//! plant's parameters, and [`JointSpec::core_loop`] builds the matching
//! closed loop (the firmware core in process, configured by a
//! [`ControllerSpec`]) and hands it to a [`CoreLoopTask`], so code that runs
//! a loop — a run, an excitation session, a tuning test, the calibration
//! sweep — is written once, generic over the joint.
use anyhow::{bail, Context};
use firmware::control::{PairGains, PairMode};
use firmware::estimate::PlaneLaw;
use firmware::joint::{JointConfig, JointController};
use hal_sim::{ClosedLoop, CoreController, FeedbackSource, Plant};
use plant_joint::identify::Observation;
use plant_joint::{Joint2d, Joint2dParams, Joint3d, Joint3dParams};

use crate::files::plant::PlantParams;
use crate::files::scenario::Scenario;
use crate::files::JointKind;

/// The simulated joint of a run: its parameters (a plant file's or the
/// defaults), whether the sponge is replaced by a rigid bearing, and the
/// seed of its random streams.
#[derive(Clone, Debug, PartialEq)]
pub struct JointSpec {
    /// 2D or 3D parameters.
    pub params: PlantParams,
    /// The paper's Fig. 10–11 variant: a rigid bearing instead of the
    /// cartilage.
    pub rigid_bearing: bool,
    /// Seed of the plant's random streams (camera, wire stick-slip).
    pub seed: u64,
}

impl JointSpec {
    /// The joint of scenario `s`: its plant file's parameters or the
    /// defaults for its joint kind, its seed and bearing.
    pub fn of(s: &Scenario) -> Self {
        let params = match (&s.plant.params, s.joint) {
            (Some(PlantParams::ThreeD(p)), JointKind::ThreeD) => PlantParams::ThreeD(p.clone()),
            (Some(PlantParams::TwoD(p)), JointKind::TwoD) => PlantParams::TwoD(p.clone()),
            (_, JointKind::ThreeD) => PlantParams::ThreeD(Joint3dParams::default()),
            (_, JointKind::TwoD) => PlantParams::TwoD(Joint2dParams::default()),
        };
        Self {
            params,
            rigid_bearing: s.plant.rigid_bearing,
            seed: s.seed,
        }
    }

    /// 2D or 3D.
    pub fn kind(&self) -> JointKind {
        match self.params {
            PlantParams::TwoD(_) => JointKind::TwoD,
            PlantParams::ThreeD(_) => JointKind::ThreeD,
        }
    }

    /// Controlled angles: 1 (2D) or 2 (3D).
    pub fn planes(&self) -> usize {
        match self.kind() {
            JointKind::TwoD => 1,
            JointKind::ThreeD => 2,
        }
    }

    /// The angles' names, as the summary and the CSV call them.
    pub fn angle_names(&self) -> &'static [&'static str] {
        match self.kind() {
            JointKind::TwoD => &["theta"],
            JointKind::ThreeD => &["alpha", "beta"],
        }
    }

    /// "2d" or "3d", as scenarios and summaries write it.
    pub fn label(&self) -> &'static str {
        match self.kind() {
            JointKind::TwoD => "2d",
            JointKind::ThreeD => "3d",
        }
    }

    /// The same joint with the seed `seed`.
    pub fn with_seed(&self, seed: u64) -> Self {
        Self {
            seed,
            ..self.clone()
        }
    }

    /// The 3D plant, for the board paths (`hil`), which drive the 3D joint
    /// only; the error says so for a 2D joint.
    pub fn plant_3d(&self) -> anyhow::Result<Joint3d> {
        match &self.params {
            PlantParams::ThreeD(p) => build_3d(p, self.rigid_bearing, self.seed),
            PlantParams::TwoD(_) => bail!("this needs the 3D joint; the scenario's is 2D"),
        }
    }

    /// Builds the joint's plant and a controller for it (the firmware core
    /// in process, per `ctl`), and runs `task` on the closed loop.
    pub fn core_loop<T: CoreLoopTask>(
        &self,
        ctl: &ControllerSpec,
        task: T,
    ) -> anyhow::Result<T::Output> {
        match &self.params {
            PlantParams::ThreeD(p) => {
                let plant = build_3d(p, self.rigid_bearing, self.seed)?;
                let mut cfg = JointConfig::paper_3d();
                ctl.configure(&mut cfg.gains, &mut cfg.laws, &mut cfg.modes)?;
                task.run(&mut core_loop(plant, cfg, ctl)?)
            }
            PlantParams::TwoD(p) => {
                let plant = build_2d(p, self.rigid_bearing, self.seed)?;
                let mut cfg = JointConfig::paper_2d_wire();
                ctl.configure(&mut cfg.gains, &mut cfg.laws, &mut cfg.modes)?;
                task.run(&mut core_loop(plant, cfg, ctl)?)
            }
        }
    }
}

fn build_3d(p: &Joint3dParams, rigid_bearing: bool, seed: u64) -> anyhow::Result<Joint3d> {
    let mut params = p.clone();
    params.sim.seed = seed;
    if rigid_bearing {
        params.alpha = params.alpha.rigid_bearing();
        params.beta = params.beta.rigid_bearing();
    }
    Joint3d::new(params).context("building the 3D plant")
}

fn build_2d(p: &Joint2dParams, rigid_bearing: bool, seed: u64) -> anyhow::Result<Joint2d> {
    let mut params = p.clone();
    params.sim.seed = seed;
    if rigid_bearing {
        params = params.rigid_bearing();
    }
    Joint2d::new(params).context("building the 2D plant")
}

/// `plant` under the firmware core in process, configured by `cfg`.
fn core_loop<Pl, const P: usize, const S: usize, const C: usize>(
    plant: Pl,
    cfg: JointConfig<P, S>,
    ctl: &ControllerSpec,
) -> anyhow::Result<ClosedLoop<Pl, CoreController<P, S>, P, S, C>>
where
    Pl: Plant<P, S, C> + SimJoint,
{
    let joint = JointController::new(cfg).context("controller")?;
    let mm_per_count = plant.mm_per_count();
    let core = CoreController::new(joint, ctl.feedback, ctl.period_us, mm_per_count, ctl.seed);
    Ok(ClosedLoop::new(plant, core, ctl.period_us)?)
}

/// Something done with a run's closed loop (the firmware core in process),
/// written once for both joints: [`JointSpec::core_loop`] calls it with
/// the 2D or the 3D loop.
pub trait CoreLoopTask {
    /// What the task returns.
    type Output;
    /// Runs the task on `cl`.
    fn run<Pl, const P: usize, const S: usize, const C: usize>(
        self,
        cl: &mut ClosedLoop<Pl, CoreController<P, S>, P, S, C>,
    ) -> anyhow::Result<Self::Output>
    where
        Pl: Plant<P, S, C> + SimJoint;
}

/// What a simulated joint shows besides the closed loop's sensors: the
/// measurements a lab logs for identification.
pub trait SimJoint {
    /// Camera, wires and coil resistances now.
    fn observation(&self) -> Observation;
    /// Coil currents of the last step, paper numbering (A).
    fn currents_a(&self) -> [f64; 4];
}

impl SimJoint for Joint2d {
    fn observation(&self) -> Observation {
        let c = self.plane().coils();
        Observation {
            camera: self
                .camera_latest()
                .and_then(|f| f.angles_deg.map(|a| (f.capture_time_s, a))),
            wire_mm: [self.wire_insertion_mm(), 0.0, 0.0, 0.0],
            resistance_ohm: [c[0].resistance_ohm(), c[1].resistance_ohm(), 0.0, 0.0],
        }
    }
    fn currents_a(&self) -> [f64; 4] {
        let c = self.plane().coils();
        [c[0].current_a(), c[1].current_a(), 0.0, 0.0]
    }
}

impl SimJoint for Joint3d {
    fn observation(&self) -> Observation {
        Observation {
            camera: self
                .camera_latest()
                .and_then(|f| f.angles_deg.map(|a| (f.capture_time_s, a))),
            wire_mm: self.wire_insertions_mm(),
            resistance_ohm: plant_joint::identify::twin::resistances_3d(self),
        }
    }
    fn currents_a(&self) -> [f64; 4] {
        self.coil_currents_a()
    }
}

/// The controller of a run as the firmware core takes it.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerSpec {
    /// Gains per pair (plane); `None` keeps the firmware's defaults (the
    /// paper's).
    pub gains: Option<Vec<PairGains>>,
    /// One actuator per pair, the other a bias spring (Eq. 1).
    pub single_actuator: bool,
    /// Estimation laws per plane; `None` keeps the firmware's defaults
    /// (the paper's published laws).
    pub laws: Option<Vec<PlaneLaw>>,
    /// What the controller is fed.
    pub feedback: FeedbackSource,
    /// Control period (µs).
    pub period_us: u32,
    /// Seed of the simulated devices' random streams (coder dropouts).
    pub seed: u64,
}

impl ControllerSpec {
    /// The paper's controller (the firmware's default gains and published
    /// laws) on wire feedback.
    pub fn paper(period_us: u32, seed: u64) -> Self {
        Self {
            gains: None,
            single_actuator: false,
            laws: None,
            feedback: FeedbackSource::Wire,
            period_us,
            seed,
        }
    }

    /// Writes the gains, laws and modes into a joint configuration of `P`
    /// pairs.
    fn configure<const P: usize>(
        &self,
        gains: &mut [PairGains; P],
        laws: &mut [PlaneLaw; P],
        modes: &mut [PairMode; P],
    ) -> anyhow::Result<()> {
        if let Some(g) = &self.gains {
            if g.len() != P {
                bail!("{} pair gains for a joint of {P} pairs", g.len());
            }
            gains.copy_from_slice(g);
        }
        if let Some(l) = &self.laws {
            if l.len() != P {
                bail!("{} estimation laws for a joint of {P} planes", l.len());
            }
            laws.copy_from_slice(l);
        }
        if self.single_actuator {
            *modes = [PairMode::SingleAgonist; P];
        }
        Ok(())
    }
}
