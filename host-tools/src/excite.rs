//! Excitation sessions: an [`ExcitationPlan`] run on the joint through the
//! one closed loop — the simulated joint under the core in process (`sim
//! --excite`) or a board in lockstep (`hil --excite`) — recording the log
//! that `softjoint identify joint` reads.
//!
//! Open-loop drives are forced onto the plant's coils (the loop's coil
//! overrides, the mechanism of the scenarios' `coil_voltage`
//! disturbances); holds hand the plane to the controller with the hold's
//! target. Before anything runs, every drive is checked against the
//! firmware's default thermal budget (its own coil model and trip rise),
//! so a plan that would trip the board's supervisor is refused by name.

use std::path::Path;

use anyhow::{bail, Context};
use firmware::control::DriverConfig;
use firmware::supervisor::ThermalConfig;
use hal_sim::{ClosedLoop, Controller, Plant, Schedule};
use plant_models::joint::identify::{
    log::columns, ElectricalNoise, ExcitationLog, ExcitationPlan, LogRecorder, Observation,
};
use plant_models::joint::{Joint2d, Joint3d, PlantError};
use serde::Serialize;

use crate::scenario::{JointKind, Scenario};
use crate::sim;

/// What the plant shows the recorder (the sensors a lab logs).
pub trait Recorded {
    /// Camera, wires and coil resistances now.
    fn observation(&self) -> Observation;
    /// Coil currents of the last step, paper numbering (A).
    fn currents_a(&self) -> [f64; 4];
}

impl Recorded for Joint2d {
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

impl Recorded for Joint3d {
    fn observation(&self) -> Observation {
        Observation {
            camera: self
                .camera_latest()
                .and_then(|f| f.angles_deg.map(|a| (f.capture_time_s, a))),
            wire_mm: self.wire_insertions_mm(),
            resistance_ohm: plant_models::joint::identify::twin::resistances_3d(self),
        }
    }
    fn currents_a(&self) -> [f64; 4] {
        self.coil_currents_a()
    }
}

/// Reads a plan (TOML) and checks it for a joint with `planes` angles and
/// against the thermal budget; errors name the file and the entry.
pub fn load_plan(path: &Path, planes: usize) -> anyhow::Result<ExcitationPlan> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read excitation plan {}", path.display()))?;
    let plan: ExcitationPlan = crate::input::from_toml(&text, &path.display().to_string())?;
    plan.validate(planes)
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    check_budget(&plan).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(plan)
}

/// The largest modelled coil rise the plan's drives reach (K), by the
/// firmware's default thermal model; an error names the drive that would
/// trip the supervisor (rise ≥ trip rise).
pub fn check_budget(plan: &ExcitationPlan) -> anyhow::Result<f64> {
    let cfg = ThermalConfig::default();
    let driver = DriverConfig::default();
    let coils = plan.drive.iter().map(|d| d.coil).max().unwrap_or(0);
    let dt = 0.01;
    let steps = (plan.duration_s / dt).ceil() as usize;
    let mut peak = 0.0f64;
    for coil in 1..=coils {
        let mut rise = 0.0f64;
        for k in 0..steps {
            let t = (k as f64 + 0.5) * dt;
            let Some((i, d)) = plan
                .drive
                .iter()
                .enumerate()
                .find(|(_, d)| d.coil == coil && t >= d.from_s && t < d.to_s)
            else {
                rise *= (-dt / f64::from(cfg.time_constant_s)).exp();
                continue;
            };
            let amps = f64::from(cfg.current_a(driver.clamp(d.volts_at(t) as f32), &driver));
            let p = amps * amps * f64::from(cfg.coil_resistance_ohm);
            let steady = p * f64::from(cfg.time_constant_s) / f64::from(cfg.heat_capacity_j_per_k);
            rise = steady + (rise - steady) * (-dt / f64::from(cfg.time_constant_s)).exp();
            peak = peak.max(rise);
            if rise >= f64::from(cfg.trip_rise_k) {
                bail!(
                    "`drive[{i}]` (coil {coil}, {} V) would trip the board's thermal budget at t = {:.1} s: modelled rise {:.0} K ≥ trip {:.0} K; shorten it or lower its input",
                    plant_models::short_number(d.peak_v()),
                    t,
                    rise,
                    cfg.trip_rise_k
                );
            }
        }
    }
    Ok(peak)
}

/// Drives and holds of a plan as the loop's schedule.
struct PlanSchedule<'a, const P: usize> {
    plan: &'a ExcitationPlan,
    period_s: f64,
    last: Option<[f32; P]>,
}

impl<Pl, const P: usize, const C: usize> Schedule<Pl, P, C> for PlanSchedule<'_, P> {
    fn targets(&mut self, t_s: f64) -> Option<[f32; P]> {
        let mut t = [0.0f32; P];
        for (p, v) in t.iter_mut().enumerate() {
            *v = self.plan.held(p, t_s).unwrap_or(0.0) as f32;
        }
        if self.last == Some(t) {
            return None;
        }
        self.last = Some(t);
        Some(t)
    }
    fn disturb(
        &mut self,
        t_s: f64,
        _plant: &mut Pl,
        overrides: &mut [Option<f64>; C],
    ) -> Result<(), PlantError> {
        // A ramp's mean over the period is its midpoint value.
        let v = self.plan.volts_at(P, t_s + 0.5 * self.period_s);
        overrides.copy_from_slice(&v[..C]);
        Ok(())
    }
}

/// What a session saw beyond its log.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SessionSummary {
    /// The plan's name.
    pub plan: String,
    /// Log rows.
    pub rows: usize,
    /// Simulated seconds.
    pub duration_s: f64,
    /// Supervisor faults seen (the board's own; drives bypass its outputs).
    pub faults_seen: Vec<String>,
    /// Peak coil temperature of the simulated joint (°C).
    pub peak_coil_temperature_c: f64,
    /// Largest modelled rise of the firmware's budget over the drives (K).
    pub budget_peak_rise_k: f64,
}

/// Runs `plan` through `cl` and records the log.
pub fn run_loop<Pl, Ctl, const P: usize, const S: usize, const C: usize>(
    plan: &ExcitationPlan,
    cl: &mut ClosedLoop<Pl, Ctl, P, S, C>,
    electrical: bool,
    seed: u64,
) -> anyhow::Result<(ExcitationLog, SessionSummary)>
where
    Pl: Plant<P, S, C> + Recorded,
    Ctl: Controller<P, S>,
{
    let budget = check_budget(plan)?;
    let period_s = cl.period_s();
    let per_row = ((f64::from(plan.log_interval_ms) * 1e-3 / period_s).round() as usize).max(1);
    let rng = plant_models::rng::stream(seed, plant_models::rng::IDENTIFY_NOISE);
    let mut rec = LogRecorder::new(
        P,
        period_s,
        per_row,
        electrical,
        ElectricalNoise::default(),
        rng,
    );
    let mut schedule = PlanSchedule::<P> {
        plan,
        period_s,
        last: None,
    };
    let steps = (plan.duration_s / period_s).round() as u64;
    let mut faults = 0u16;
    let mut peak = f64::NEG_INFINITY;
    for _ in 0..steps {
        let obs = cl.plant.observation();
        let mut sample = None;
        cl.run(1, &mut schedule, |x| -> anyhow::Result<()> {
            sample = Some(*x);
            Ok(())
        })?;
        let x = sample.context("the loop ran no period")?;
        faults |= x.faults;
        for t in x.coil_temperatures_c {
            peak = peak.max(t);
        }
        rec.push(&obs, &x.coil_volts, &cl.plant.currents_a()[..C]);
    }
    let log = rec.finish();
    let summary = SessionSummary {
        plan: plan.name.clone(),
        rows: log.len(),
        duration_s: plan.duration_s,
        faults_seen: sim::fault_names(faults),
        peak_coil_temperature_c: peak,
        budget_peak_rise_k: budget,
    };
    Ok((log, summary))
}

/// Runs `plan` on the simulated joint of scenario `s` (its joint kind,
/// seed, plant file and gains) under the core in process.
pub fn run_sim(
    plan: &ExcitationPlan,
    s: &Scenario,
    electrical: bool,
) -> anyhow::Result<(ExcitationLog, SessionSummary)> {
    s.validate()?;
    let (laws, _) = sim::laws_for(s)?;
    match s.joint {
        JointKind::ThreeD => run_loop(
            plan,
            &mut sim::core_loop_3d(s, laws.as_deref())?,
            electrical,
            s.seed,
        ),
        JointKind::TwoD => run_loop(
            plan,
            &mut sim::core_loop_2d(s, laws.as_deref())?,
            electrical,
            s.seed,
        ),
    }
}

/// The log as CSV text (fixed decimals: ms times, 0.1 mV, 0.1 m°, µm,
/// 10 µA, 0.1 mΩ).
pub fn log_csv(log: &ExcitationLog) -> String {
    let (cols, rows) = log.to_rows();
    let mut out = cols.join(",");
    out.push('\n');
    let decimals = |name: &str| -> usize {
        if name == "t_s" || name == "cam_capture_s" || name.starts_with('d') {
            3
        } else if name.starts_with('i') {
            5
        } else {
            4
        }
    };
    let places: Vec<usize> = cols.iter().map(|c| decimals(c)).collect();
    for r in rows {
        let line: Vec<String> = r
            .iter()
            .zip(&places)
            .map(|(v, d)| format!("{v:.d$}", d = *d))
            .collect();
        out.push_str(&line.join(","));
        out.push('\n');
    }
    out
}

/// Writes the log (checked writer).
pub fn write_log(path: &Path, log: &ExcitationLog) -> anyhow::Result<()> {
    crate::output::write_csv(path, &log_csv(log))
}

/// Reads a log; errors name the file, line and column.
pub fn read_log(path: &Path) -> anyhow::Result<ExcitationLog> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read log {}", path.display()))?;
    let table = plant_models::csv_input::read_numeric(&text, &path.display().to_string())?;
    Ok(ExcitationLog::from_table(&table)?)
}

/// Column names of a log (for help texts).
pub fn log_columns(planes: usize) -> String {
    columns(planes, true).join(",")
}

/// Runs `plan` in lockstep with the board on `link` (the 3D joint of
/// scenario `s`, wire feedback): the board's controller holds, the host
/// forces the drives onto the simulated coils.
pub fn run_hil<Po: crate::link::Port>(
    plan: &ExcitationPlan,
    s: &Scenario,
    link: &mut crate::link::Link<Po>,
    opts: crate::hil::HilOptions,
    electrical: bool,
) -> anyhow::Result<(ExcitationLog, SessionSummary)> {
    let (setup, _) = crate::hil::lockstep_setup(s, &opts)?;
    let plant = sim::plant_3d(s)?;
    let board = crate::board::BoardController::start(link, setup)?;
    let mut cl = ClosedLoop::new(plant, board, s.control_period_us)?;
    let out = run_loop(plan, &mut cl, electrical, s.seed)?;
    cl.controller.finish()?;
    Ok(out)
}
