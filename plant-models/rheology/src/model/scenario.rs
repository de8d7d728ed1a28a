//! A push of the block as a user describes it (TOML in `softjoint
//! rheology`): block, lattice and model variant, parameters, rig, plate
//! schedule and what is measured, and the run of a lattice through it.
//!
//! The default is the paper's experiment as far as it is printed: a
//! 10 × 6 × 10 cm dough block (600 cm³, L1717) on the 6 × 4 × 6 lattice
//! (L1923), the paper's default element constants (L1838), pushed from
//! above 0–1 s, held 1–3 s, released from 3 s (L2244–2246). Estimates
//! where the paper is silent: dough density 1.2 g/cm³ (720 g), a 4 × 4 cm
//! indenter centred on the top pushed 15 mm deep and withdrawn at the same
//! speed, shape frames at 1, 2, 3 and 5 s (the paper compares four
//! times, L1738), forces compared over the keeping period 1–3 s (L2251).
use serde::{Deserialize, Serialize};

use crate::error::{bad_setting, check_non_negative, check_positive, Result};
use crate::model::contact::{ContactParams, Contacts, Plate, PlateDrive, Schedule};
use crate::model::lattice::{Lattice, VolumeMode, V3};
use crate::model::params::{ElementParams, LatticeParams, PA_PER_GF_PER_CM2};
use crate::model::sim::{GlobalVolume, Integrator, LatticeSim, SimSettings};
use crate::RheologyError;

/// The block.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BlockSpec {
    /// Size (x, height y, z) in cm (L1717: 10 × 6 × 10).
    pub size_cm: [f64; 3],
    /// Mass (g): 600 cm³ of dough at 1.2 g/cm³ (estimate).
    pub mass_g: f64,
    /// Masses per axis (x, y up, z): 6 × 4 × 6 sparse, 11 × 7 × 11 dense
    /// (L1923–1930), 6 × 6 × 6 Model 1 (L1899).
    pub grid: [usize; 3],
}

impl Default for BlockSpec {
    fn default() -> Self {
        Self {
            size_cm: [10.0, 6.0, 10.0],
            mass_g: 720.0,
            grid: [6, 4, 6],
        }
    }
}

/// Element constants per class: `all` first, then any class overrides.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct ParamsSpec {
    /// Every class (default: the paper's, L1838).
    pub all: Option<ElementParams>,
    pub surface_on: Option<ElementParams>,
    pub surface_in: Option<ElementParams>,
    pub core_on: Option<ElementParams>,
    pub core_in: Option<ElementParams>,
}

impl ParamsSpec {
    /// The resolved parameters.
    pub fn resolve(&self) -> Result<LatticeParams> {
        let base = self.all.unwrap_or(ElementParams::PAPER_DEFAULT);
        let p = LatticeParams {
            surface_on: self.surface_on.unwrap_or(base),
            surface_in: self.surface_in.unwrap_or(base),
            core_on: self.core_on.unwrap_or(base),
            core_in: self.core_in.unwrap_or(base),
        };
        p.validate().map_err(|e| prefix_error("model.params.", e))?;
        Ok(p)
    }
}

fn prefix_error(prefix: &str, e: RheologyError) -> RheologyError {
    match e {
        RheologyError::InvalidParameter {
            name,
            value,
            reason,
        } => RheologyError::InvalidParameter {
            name: format!("{prefix}{name}"),
            value,
            reason,
        },
        other => other,
    }
}

/// The model variant and its numerics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelSpec {
    /// Volume condition: none (Model 1), local (2), global (3), both (4).
    pub volume: VolumeMode,
    pub integrator: Integrator,
    /// Time step (ms). The paper's explicit Euler used 2 ms (L2076); the
    /// implicit default is 5 ms (against a 0.5 ms run of the paper's push:
    /// forces over the keeping period within 1.2 % (L1), masses within
    /// 0.05 mm; 2 ms: 0.35 %, 10 ms: 2.6 %).
    pub dt_ms: f64,
    /// Gravity on.
    pub gravity: bool,
    /// Relative residual at which the implicit step's solver stops
    /// (1e-5: the same forces and shapes as 1e-7 to the digits reported,
    /// with half the iterations).
    pub solver_tolerance: f64,
    /// Global volume condition: k_vol·V0 (gf/cm²). The paper gives no
    /// value; its Model 3 kept 74.97–75.16 cm³ of 75 (L1998–2001). Estimate
    /// 500,000 (49 MPa): the lattice's stresses in the paper's push reach a
    /// few hundred kPa, so this holds the volume to about 1 %.
    pub bulk_gf_per_cm2: f64,
    /// Global volume condition: c_vol·V0 (gf·s/cm²). Estimate 50,000
    /// (4.9 MPa·s), 25× the paper's default element viscosity, so that
    /// the pressure also answers a fast squeeze.
    pub bulk_viscosity_gfs_per_cm2: f64,
    pub params: ParamsSpec,
}

impl Default for ModelSpec {
    fn default() -> Self {
        Self {
            volume: VolumeMode::None,
            integrator: Integrator::ImplicitEuler,
            dt_ms: 5.0,
            gravity: true,
            solver_tolerance: 1e-5,
            bulk_gf_per_cm2: 500_000.0,
            bulk_viscosity_gfs_per_cm2: 50_000.0,
            params: ParamsSpec::default(),
        }
    }
}

/// The plate and its schedule.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlateSpec {
    /// Footprint centre (x, z) in cm; default the block's centre.
    pub centre_cm: Option<[f64; 2]>,
    /// Footprint (x, z) in cm; larger than the block for a full plate.
    pub footprint_cm: [f64; 2],
    /// Depth below the rest top (mm) over time, as [t_s, depth_mm] points
    /// (pushing by displacement). Default: 0 → 15 mm over 0–1 s, held to
    /// 3 s, back to 0 at 4 s.
    pub depth_mm: Option<Vec<[f64; 2]>>,
    /// Downward force (N) over time as [t_s, force_n] points (pushing by
    /// force); excludes `depth_mm`.
    pub force_n: Option<Vec<[f64; 2]>>,
    /// End of the run (s).
    pub end_s: f64,
}

impl Default for PlateSpec {
    fn default() -> Self {
        Self {
            centre_cm: None,
            footprint_cm: [4.0, 4.0],
            depth_mm: None,
            force_n: None,
            end_s: 5.0,
        }
    }
}

/// The paper's push schedule with a given depth and push time (mm, s):
/// push over [0, t], hold to 3t, withdraw at the same speed.
pub fn push_schedule_mm(depth_mm: f64, push_s: f64) -> Vec<[f64; 2]> {
    vec![
        [0.0, 0.0],
        [push_s, depth_mm],
        [3.0 * push_s, depth_mm],
        [4.0 * push_s, 0.0],
    ]
}

/// What is measured.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MeasureSpec {
    /// Times of the shape frames (s).
    pub frame_times_s: Vec<f64>,
    /// The keeping period whose forces S compares (s).
    pub force_window_s: [f64; 2],
}

impl Default for MeasureSpec {
    fn default() -> Self {
        Self {
            frame_times_s: vec![1.0, 2.0, 3.0, 5.0],
            force_window_s: [1.0, 3.0],
        }
    }
}

/// Weights of the objective S (see `identify::objective`):
/// S = shape_per_cm·S_shape + force_per_n·S_force.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Objective {
    /// Weight of S_shape (per cm).
    pub shape_per_cm: f64,
    /// Weight of S_force (per N).
    pub force_per_n: f64,
}

impl Default for Objective {
    fn default() -> Self {
        Self {
            shape_per_cm: 1.0,
            force_per_n: 0.0,
        }
    }
}

impl Objective {
    /// Checks the weights (names the field).
    pub fn validate(&self) -> Result<()> {
        check_non_negative("objective.shape_per_cm", self.shape_per_cm)?;
        check_non_negative("objective.force_per_n", self.force_per_n)?;
        if self.shape_per_cm == 0.0 && self.force_per_n == 0.0 {
            return Err(bad_setting(
                "objective",
                "at least one of shape_per_cm and force_per_n must be > 0",
            ));
        }
        Ok(())
    }
}

/// A whole scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    pub block: BlockSpec,
    pub model: ModelSpec,
    pub contact: ContactParams,
    pub plate: PlateSpec,
    pub measure: MeasureSpec,
    /// Weights of the calibration objective S.
    pub objective: Objective,
}

/// Longest run accepted (s).
pub const MAX_END_S: f64 = 600.0;

impl Scenario {
    /// Checks everything; errors name the field (`block.grid.x`,
    /// `plate.depth_mm[2]`, …).
    pub fn validate(&self) -> Result<()> {
        for (a, s) in self.block.size_cm.iter().enumerate() {
            check_positive(&format!("block.size_cm.{}", ["x", "y", "z"][a]), *s)?;
        }
        check_positive("block.mass_g", self.block.mass_g)?;
        self.lattice()?;
        let m = &self.model;
        check_positive("model.dt_ms", m.dt_ms)?;
        if !(m.solver_tolerance > 0.0 && m.solver_tolerance <= 1e-2) {
            return Err(RheologyError::InvalidParameter {
                name: "model.solver_tolerance".into(),
                value: m.solver_tolerance,
                reason: "must be in (0, 0.01]",
            });
        }
        if m.dt_ms > 100.0 {
            return Err(bad_setting("model.dt_ms", "at most 100 ms"));
        }
        check_non_negative("model.bulk_gf_per_cm2", m.bulk_gf_per_cm2)?;
        check_non_negative(
            "model.bulk_viscosity_gfs_per_cm2",
            m.bulk_viscosity_gfs_per_cm2,
        )?;
        m.params.resolve()?;
        self.contact.validate()?;
        let p = &self.plate;
        for (a, f) in p.footprint_cm.iter().enumerate() {
            check_positive(&format!("plate.footprint_cm.{}", ["x", "z"][a]), *f)?;
        }
        if let Some(c) = p.centre_cm {
            for (a, v) in c.iter().enumerate() {
                if !v.is_finite() {
                    return Err(bad_setting(
                        &format!("plate.centre_cm.{}", ["x", "z"][a]),
                        "must be a finite number",
                    ));
                }
            }
        }
        check_positive("plate.end_s", p.end_s)?;
        if p.end_s > MAX_END_S {
            return Err(bad_setting("plate.end_s", format!("at most {MAX_END_S} s")));
        }
        if p.depth_mm.is_some() && p.force_n.is_some() {
            return Err(bad_setting(
                "plate",
                "give either depth_mm (pushing by displacement) or force_n (pushing by force), not both",
            ));
        }
        self.plate()?;
        let steps = p.end_s / (m.dt_ms * 1e-3);
        if steps > 5e6 {
            return Err(bad_setting(
                "model.dt_ms",
                format!("{steps:.0} steps to plate.end_s; at most 5,000,000"),
            ));
        }
        for (k, t) in self.measure.frame_times_s.iter().enumerate() {
            if !(t.is_finite() && *t >= 0.0 && *t <= p.end_s) {
                return Err(bad_setting(
                    &format!("measure.frame_times_s[{k}]"),
                    format!("must lie in [0, plate.end_s = {} s]", p.end_s),
                ));
            }
        }
        self.objective.validate()?;
        let [w0, w1] = self.measure.force_window_s;
        if !(w0.is_finite() && w1.is_finite() && 0.0 <= w0 && w0 < w1) {
            return Err(bad_setting(
                "measure.force_window_s",
                "needs 0 <= start < end",
            ));
        }
        Ok(())
    }

    /// Block size (m).
    pub fn size_m(&self) -> [f64; 3] {
        self.block.size_cm.map(|c| c * 0.01)
    }

    /// The lattice of this scenario.
    pub fn lattice(&self) -> Result<Lattice> {
        Lattice::grid(self.block.grid, self.size_m(), self.model.volume)
    }

    /// The plate.
    pub fn plate(&self) -> Result<Plate> {
        let s = self.size_m();
        let p = &self.plate;
        let points = |name: &str, pts: &[[f64; 2]], scale: f64| {
            Schedule::new(name, pts.iter().map(|q| (q[0], q[1] * scale)).collect())
        };
        let drive = match (&p.depth_mm, &p.force_n) {
            (_, Some(f)) => PlateDrive::Force(points("plate.force_n", f, 1.0)?),
            (Some(d), None) => PlateDrive::Depth(points("plate.depth_mm", d, 1e-3)?),
            (None, None) => PlateDrive::Depth(points(
                "plate.depth_mm",
                &push_schedule_mm(15.0, 1.0),
                1e-3,
            )?),
        };
        if let PlateDrive::Depth(d) = &drive {
            if d.max_value() >= s[1] {
                return Err(bad_setting(
                    "plate.depth_mm",
                    "the plate would reach the table",
                ));
            }
        }
        Ok(Plate {
            centre_xz_m: p
                .centre_cm
                .map(|c| c.map(|v| v * 0.01))
                .unwrap_or([s[0] / 2.0, s[2] / 2.0]),
            footprint_m: p.footprint_cm.map(|v| v * 0.01),
            top_m: s[1],
            drive,
        })
    }

    /// Numerical settings.
    pub fn settings(&self) -> SimSettings {
        let m = &self.model;
        SimSettings {
            integrator: m.integrator,
            dt_s: m.dt_ms * 1e-3,
            gravity_m_s2: if m.gravity {
                crate::model::sim::GRAVITY_M_S2
            } else {
                0.0
            },
            global_volume: m.volume.global().then_some(GlobalVolume {
                bulk_pa: m.bulk_gf_per_cm2 * PA_PER_GF_PER_CM2,
                bulk_viscosity_pa_s: m.bulk_viscosity_gfs_per_cm2 * PA_PER_GF_PER_CM2,
            }),
            tolerance: m.solver_tolerance,
            ..SimSettings::default()
        }
    }

    /// The rig for `lattice`.
    pub fn contacts(&self, lattice: &Lattice) -> Result<Contacts> {
        let h = lattice.spacing_m();
        let [nx, ny, nz] = lattice.nodes;
        let top: Vec<usize> = (0..nz)
            .flat_map(|k| (0..nx).map(move |i| i + nx * (ny - 1 + ny * k)))
            .collect();
        Contacts::new(
            self.contact,
            Some(self.plate()?),
            lattice.tributary_area_m2.clone(),
            [h[0], h[2]],
            top,
        )
    }
}

/// One recorded state of the block.
#[derive(Clone, Debug, PartialEq)]
pub struct Frame {
    /// Time (s).
    pub t_s: f64,
    /// Positions of every mass (m).
    pub positions_m: Vec<V3>,
}

/// What a run recorded: per step, and frames at the asked times.
#[derive(Clone, Debug, Default)]
pub struct Run {
    /// Time at the end of each step (s).
    pub t_s: Vec<f64>,
    /// The plate's downward force on the block (N).
    pub plate_force_n: Vec<f64>,
    /// The plate's depth below the rest top (m): the schedule's for a
    /// depth-driven plate, the loaded masses' mean for a force-driven one.
    pub plate_depth_m: Vec<f64>,
    /// Enclosed volume (m³).
    pub volume_m3: Vec<f64>,
    /// Frames at the asked times (the step nearest each).
    pub frames: Vec<Frame>,
    /// Why the run stopped before its end, if it did.
    pub instability: Option<RheologyError>,
    /// Implicit-solver iterations over the run.
    pub iterations: usize,
    /// Rest volume (m³).
    pub volume0_m3: f64,
}

/// Runs `sim` to `end_s`, recording frames at `frame_times_s` (the step
/// nearest each). An instability ends the run early and is kept in
/// [`Run::instability`].
pub fn run(sim: &mut LatticeSim<'_>, end_s: f64, frame_times_s: &[f64]) -> Run {
    let dt = sim_dt(sim);
    let steps = (end_s / dt).round() as usize;
    let frame_steps: Vec<usize> = frame_times_s
        .iter()
        .map(|t| (t / dt).round() as usize)
        .collect();
    let (_, v0) = sim.volume_m3();
    let mut out = Run {
        volume0_m3: v0,
        ..Run::default()
    };
    let top = sim.contacts().plate().map(|p| p.top_m).unwrap_or(0.0);
    let take_frames = |sim: &LatticeSim<'_>, step: usize, out: &mut Run| {
        for (k, &s) in frame_steps.iter().enumerate() {
            if s == step {
                out.frames.push(Frame {
                    t_s: frame_times_s[k],
                    positions_m: sim.positions().to_vec(),
                });
            }
        }
    };
    take_frames(sim, 0, &mut out);
    for step in 1..=steps {
        match sim.step() {
            Ok(r) => {
                out.t_s.push(r.t_s);
                out.plate_force_n.push(r.plate_force_n);
                out.volume_m3.push(r.volume_m3);
                out.plate_depth_m.push(plate_depth(sim, top));
                take_frames(sim, step, &mut out);
            }
            Err(e) => {
                out.instability = Some(e);
                break;
            }
        }
    }
    out.iterations = sim.total_iterations();
    out
}

fn sim_dt(sim: &LatticeSim<'_>) -> f64 {
    sim.settings_dt()
}

fn plate_depth(sim: &LatticeSim<'_>, top: f64) -> f64 {
    match sim.contacts().plate_face_m() {
        Some(face) => top - face,
        None => {
            // Force-driven: the mean height of the loaded top masses.
            let lat = sim.lattice();
            let [nx, ny, nz] = lat.nodes;
            let plate = sim.contacts().plate();
            let h = lat.spacing_m();
            let (mut sum, mut w) = (0.0, 0.0);
            for k in 0..nz {
                for i in 0..nx {
                    let n = i + nx * (ny - 1 + ny * k);
                    let p = sim.positions()[n];
                    let c = plate
                        .map(|pl| pl.coverage(p.x, p.z, [h[0], h[2]]))
                        .unwrap_or(0.0)
                        * lat.tributary_area_m2[n];
                    sum += c * p.y;
                    w += c;
                }
            }
            if w > 0.0 {
                top - sum / w
            } else {
                0.0
            }
        }
    }
}

/// Builds the lattice simulation of `scenario` with `params`.
pub fn lattice_sim<'a>(
    scenario: &Scenario,
    lattice: &'a Lattice,
    params: &LatticeParams,
) -> Result<LatticeSim<'a>> {
    LatticeSim::new(
        lattice,
        lattice.element_constants(params),
        scenario.block.mass_g * 1e-3,
        scenario.settings(),
        scenario.contacts(lattice)?,
    )
}

/// Runs the scenario's lattice with `params` (its own when `None`).
pub fn run_scenario(scenario: &Scenario, params: Option<&LatticeParams>) -> Result<Run> {
    scenario.validate()?;
    let lattice = scenario.lattice()?;
    let own = scenario.model.params.resolve()?;
    let mut sim = lattice_sim(scenario, &lattice, params.unwrap_or(&own))?;
    Ok(run(
        &mut sim,
        scenario.plate.end_s,
        &scenario.measure.frame_times_s,
    ))
}
