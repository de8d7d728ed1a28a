//! Logs of a simulated joint under an open-loop excitation plan, for the
//! twin tests and benchmarks: the plant (with its own noise, jamming and
//! camera) is the ground truth, recorded through the same [`LogRecorder`]
//! as `softjoint sim`. Holds need a controller and are refused here
//! (`softjoint sim` runs them).

use super::log::{ElectricalNoise, ExcitationLog, LogRecorder, Observation};
use super::plan::ExcitationPlan;
use super::IdentifyError;
use crate::{Joint2d, Joint2dParams, Joint3d, Joint3dParams};

/// Control period of the recording (s).
pub const CONTROL_PERIOD_S: f64 = 1e-3;

fn check(plan: &ExcitationPlan, planes: usize) -> Result<(usize, usize), IdentifyError> {
    plan.validate(planes).map_err(IdentifyError::Log)?;
    if !plan.hold.is_empty() {
        return Err(IdentifyError::Log(
            "holds need a controller: run the plan with `softjoint sim excite`".into(),
        ));
    }
    let steps = (plan.duration_s / CONTROL_PERIOD_S).round() as usize;
    Ok((steps, plan.log_interval_ms as usize))
}

fn inputs(plan: &ExcitationPlan, planes: usize, k: usize) -> [f64; 4] {
    // The mean of a linear input over the period is its midpoint value.
    let t = (k as f64 + 0.5) * CONTROL_PERIOD_S;
    plan.volts_at(planes, t).map(|v| v.unwrap_or(0.0))
}

/// Records `plan` on the 2D joint `params`; `electrical` logs currents and
/// resistances with `noise` (drawn from the identification noise stream
/// of `params.sim.seed`).
pub fn record_2d(
    params: &Joint2dParams,
    plan: &ExcitationPlan,
    electrical: bool,
    noise: ElectricalNoise,
) -> Result<ExcitationLog, IdentifyError> {
    let (steps, per_row) = check(plan, 1)?;
    let mut j = Joint2d::new(params.clone())?;
    let rng = plant_common::rng::stream(params.sim.seed, plant_common::rng::IDENTIFY_NOISE);
    let mut rec = LogRecorder::new(1, CONTROL_PERIOD_S, per_row, electrical, noise, rng);
    for k in 0..steps {
        let coils = j.plane().coils();
        let obs = Observation {
            camera: j
                .camera_latest()
                .and_then(|f| f.angles_deg.map(|a| (f.capture_time_s, a))),
            wire_mm: [j.wire_insertion_mm(), 0.0, 0.0, 0.0],
            resistance_ohm: [
                coils[0].resistance_ohm(),
                coils[1].resistance_ohm(),
                0.0,
                0.0,
            ],
        };
        let v = inputs(plan, 1, k);
        j.step(CONTROL_PERIOD_S, &v[..2])?;
        let c = j.plane().coils();
        rec.push(&obs, &v[..2], &[c[0].current_a(), c[1].current_a()]);
    }
    Ok(rec.finish())
}

/// Records `plan` on the 3D joint `params` (see [`record_2d`]).
pub fn record_3d(
    params: &Joint3dParams,
    plan: &ExcitationPlan,
    electrical: bool,
    noise: ElectricalNoise,
) -> Result<ExcitationLog, IdentifyError> {
    let (steps, per_row) = check(plan, 2)?;
    let mut j = Joint3d::new(params.clone())?;
    let rng = plant_common::rng::stream(params.sim.seed, plant_common::rng::IDENTIFY_NOISE);
    let mut rec = LogRecorder::new(2, CONTROL_PERIOD_S, per_row, electrical, noise, rng);
    for k in 0..steps {
        let obs = Observation {
            camera: j
                .camera_latest()
                .and_then(|f| f.angles_deg.map(|a| (f.capture_time_s, a))),
            wire_mm: j.wire_insertions_mm(),
            resistance_ohm: resistances_3d(&j),
        };
        let v = inputs(plan, 2, k);
        j.step(CONTROL_PERIOD_S, &v)?;
        rec.push(&obs, &v, &j.coil_currents_a());
    }
    Ok(rec.finish())
}

/// The plan `softjoint identify plan --probe` gives for the 3D joint
/// `params`: the probe ([`ExcitationPlan::probe`]) recorded on it and
/// analysed, and the standard plan of `seconds` adapted to what it found
/// ([`ExcitationPlan::adapted`], the firmware's default budget). The
/// error says what failed: the recording, or the analysis by column.
pub fn adapted_plan_3d(
    params: &Joint3dParams,
    seconds: f64,
    noise: ElectricalNoise,
) -> Result<ExcitationPlan, String> {
    let log =
        record_3d(params, &ExcitationPlan::probe(2), true, noise).map_err(|e| e.to_string())?;
    let found = super::probe::analyse(&log).map_err(|e| format!("the probe log: {e}"))?;
    Ok(ExcitationPlan::adapted(2, seconds, &found, false))
}

/// The plan a campaign records on `params`: with `probe`,
/// [`adapted_plan_3d`], or the standard plan of `seconds` where the probe
/// cannot place one (what a user falls back to when `identify plan
/// --probe` refuses the probe) with the reason; without, the standard
/// plan.
pub fn campaign_plan_3d(
    params: &Joint3dParams,
    seconds: f64,
    noise: ElectricalNoise,
    probe: bool,
) -> (ExcitationPlan, Option<String>) {
    let standard = || ExcitationPlan::standard(2, seconds, false);
    if !probe {
        return (standard(), None);
    }
    match adapted_plan_3d(params, seconds, noise) {
        Ok(plan) => (plan, None),
        Err(e) => (standard(), Some(e)),
    }
}

/// Coil resistances of the 3D joint, coils 1..4 (Ω).
pub fn resistances_3d(j: &Joint3d) -> [f64; 4] {
    let a = j.plane(crate::Plane::Alpha).coils();
    let b = j.plane(crate::Plane::Beta).coils();
    [
        a[0].resistance_ohm(),
        b[0].resistance_ohm(),
        a[1].resistance_ohm(),
        b[1].resistance_ohm(),
    ]
}
