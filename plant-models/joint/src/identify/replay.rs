//! Replays a log's driver inputs through one plane of the plant with
//! candidate parameters: the model side of every identification stage.
//!
//! The plane is the plant's own [`PlanarJoint`] and [`WireSensor`] (no
//! second copy of the physics), built and settled exactly as `Joint2d` and
//! `Joint3d` do (coils off for `settle_s`, the wire coders zeroed there),
//! then driven with each row's mean input held over the row's interval in
//! substeps of `substep_s`. Prediction stops at the first numerical
//! instability with the plant's error.
//!
//! Wires: the replay records each wire's geometric insertion at every
//! substep ([`Prediction::wire_path_mm`]); [`expected_wire_readings`]
//! then runs the plant's own random sensor along that path
//! a number of times ([`STICK_REALISATIONS`] by default), with stick
//! events from fixed streams,
//! and averages: the *expected* reading over the stick events, which the
//! replay cannot know where the recorded wire stuck. Leaving the sticks
//! out (as until this change) biased the buckling gain by −23 % to +49 %
//! on the twins; drawing one realisation of them (as before that) by up
//! to +186 %. The mean over fixed streams is smooth in the jamming
//! parameters: where a wire sticks depends only on its path and the
//! stick rate and sizes, not on κ or the ceilings. For the same reason the
//! wire stage draws the sticks once ([`StickEvents`]) and replays them for
//! every candidate κ and ceilings, instead of drawing them anew from the
//! streams each time (same readings, to the bit).

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::log::ExcitationLog;
use super::params::{Param, Scale};
use super::IdentifyError;
use crate::wire_sensor::JamState;
use crate::{
    PlanarJoint, PlaneParams, PlaneSeeds, SmaCoil, SmaParams, WireSensor, WireSensorParams,
};
use plant_common::scalar::{Dual, Scalar};
use plant_common::three_element::StepLength;

/// Which coils and sensors of a log belong to one plane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlaneMap {
    /// 0 (θ or α) or 1 (β).
    pub plane: usize,
    /// Coil slots of the log: [raising, lowering].
    pub coils: [usize; 2],
    /// Sensor slots of the log (one for 2D, two for 3D).
    pub sensors: &'static [usize],
}

impl PlaneMap {
    /// The plane `plane` of a log with `planes` angles (paper numbering:
    /// 3D coils 1/3 and sensors 1/3 are α's, 2/4 β's).
    pub fn of(planes: usize, plane: usize) -> Self {
        match (planes, plane) {
            (1, _) => PlaneMap {
                plane: 0,
                coils: [0, 1],
                sensors: &[0],
            },
            (_, 0) => PlaneMap {
                plane: 0,
                coils: [0, 2],
                sensors: &[0, 2],
            },
            _ => PlaneMap {
                plane: 1,
                coils: [1, 3],
                sensors: &[1, 3],
            },
        }
    }
}

/// A plane's model for replay.
#[derive(Clone, Debug, PartialEq)]
pub struct PlaneModel {
    /// The plane.
    pub plane: PlaneParams,
    /// Its wire sensors, in the order of [`PlaneMap::sensors`].
    pub wires: Vec<WireSensorParams>,
    /// Settling time before the log starts (s), as `SimParams::settle_s`.
    pub settle_s: f64,
    /// Substep (s).
    pub substep_s: f64,
}

/// What the model predicts for a log.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Prediction {
    /// Angle at every substep boundary from t = 0 (deg), `substeps_per_row`
    /// per row.
    pub angle_deg: Vec<f64>,
    /// Substeps per row.
    pub substeps_per_row: usize,
    /// Substep (s).
    pub substep_s: f64,
    /// Each plane sensor's geometric insertion (mm) after every substep
    /// (`substeps_per_row` per row), the coder zeroed at the settled pose;
    /// empty unless asked for ([`replay_with_wire_paths`]).
    pub wire_path_mm: Vec<Vec<f64>>,
    /// Coil resistances at each row start (Ω), [raising, lowering].
    pub resistance_ohm: Vec<[f64; 2]>,
    /// Peak coil temperature over the replay (°C).
    pub peak_temperature_c: f64,
}

impl Prediction {
    /// The predicted angle at time `t_s`: at the first substep boundary at
    /// or after it, where the plant's camera takes a frame due at `t_s`.
    pub fn angle_at(&self, t_s: f64) -> Option<f64> {
        let k = (t_s / self.substep_s - 1e-6).ceil();
        if k < 0.0 {
            return None;
        }
        self.angle_deg.get(k as usize).copied()
    }
}

fn step_length(h: f64) -> Result<StepLength, IdentifyError> {
    StepLength::new(h).map_err(|_| IdentifyError::Log(format!("bad substep {h} s")))
}

/// Substeps per row and their length for a log interval `period_s` and a
/// largest substep `substep_s`.
pub fn split(period_s: f64, substep_s: f64) -> (usize, f64) {
    let n = ((period_s / substep_s) - 1e-9).ceil().max(1.0) as usize;
    (n, period_s / n as f64)
}

/// Replays rows `0..rows` of `log` through `model` for plane `map`.
pub fn replay(
    model: &PlaneModel,
    log: &ExcitationLog,
    map: PlaneMap,
    rows: usize,
) -> Result<Prediction, IdentifyError> {
    replay_inner(model, log, map, rows, false)
}

/// [`replay`] recording the wires' paths ([`Prediction::wire_path_mm`]).
pub fn replay_with_wire_paths(
    model: &PlaneModel,
    log: &ExcitationLog,
    map: PlaneMap,
    rows: usize,
) -> Result<Prediction, IdentifyError> {
    replay_inner(model, log, map, rows, true)
}

/// Random realisations of the stick events averaged by
/// [`expected_wire_readings`] by default (`IdentifyOptions::
/// stick_realisations`); each costs a pass of the wire model (not the
/// plane) over the log. See the joint README for what 64 changes.
pub const STICK_REALISATIONS: usize = 32;

/// The expected reading (mm) of each of `wires` at each of the first
/// `rows` row starts along the paths of `pred` (from
/// [`replay_with_wire_paths`]): the mean over `realisations` (at least
/// one) runs of the plant's random sensor, realisation r of sensor j drawing
/// its sticks from `rng::stream(r·8 + j, rng::IDENTIFY_STICKS)` (module
/// docs). Unquantised: the mean of the counts would be a staircase in
/// the parameters. Realisations run in parallel and are summed in order.
pub fn expected_wire_readings(
    wires: &[WireSensorParams],
    pred: &Prediction,
    rows: usize,
    realisations: usize,
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    Ok(wire_realisations(wires, pred, rows, realisations)?
        .into_iter()
        .map(|(mean, _)| mean)
        .collect())
}

/// [`expected_wire_readings`] with each realisation's readings too: per
/// sensor, (the mean, the realisations), from which the mean's own noise
/// can be judged.
#[allow(clippy::type_complexity)] // (mean, runs) per sensor
pub fn wire_realisations(
    wires: &[WireSensorParams],
    pred: &Prediction,
    rows: usize,
    realisations: usize,
) -> Result<Vec<(Vec<f64>, Vec<Vec<f64>>)>, IdentifyError> {
    let sticks = StickEvents::draw(wires, pred, rows, realisations)?;
    sticks.realisations(wires, pred)
}

/// The stick events of every realisation of [`wire_realisations`] along
/// one set of paths, drawn once: where a wire sticks depends on its path
/// and on the stick rate and sizes only, not on the buckling gain or the
/// lag ceilings (see [`WireSensor::advance_to_ideal_with`]), so the wire
/// stage, which fits those along fixed paths, draws the sticks once
/// instead of once per evaluation. The readings are the same to the bit.
#[derive(Clone, Debug, PartialEq)]
pub struct StickEvents {
    /// Rows covered.
    rows: usize,
    /// Per sensor: its (stick_per_mm, stick_min_mm, stick_max_mm), which
    /// the events hold for.
    stick_params: Vec<[f64; 3]>,
    /// Per sensor, per realisation: (substep from the log's start, push
    /// length of the stick in mm), in order.
    events: Vec<Vec<Vec<(usize, f64)>>>,
}

fn stick_params(w: &WireSensorParams) -> [f64; 3] {
    [w.jam.stick_per_mm, w.jam.stick_min_mm, w.jam.stick_max_mm]
}

impl StickEvents {
    /// Runs `realisations` (at least one) of each of `wires` along the
    /// paths of `pred` over rows `0..rows`, realisation r of sensor j
    /// drawing its sticks from `rng::stream(r·8 + j, rng::IDENTIFY_STICKS)`,
    /// and records where they stuck.
    pub fn draw(
        wires: &[WireSensorParams],
        pred: &Prediction,
        rows: usize,
        realisations: usize,
    ) -> Result<Self, IdentifyError> {
        use rayon::prelude::*;
        let n = pred.substeps_per_row;
        let mut events = Vec::with_capacity(wires.len());
        for (j, (w, path)) in wires.iter().zip(&pred.wire_path_mm).enumerate() {
            let rows = rows.min(path.len() / n.max(1));
            let runs: Vec<Vec<(usize, f64)>> = (0..realisations.max(1))
                .into_par_iter()
                .map(|r| {
                    let mut sensor = WireSensor::new(w.clone(), 0.0, 0.0, 0.0)?;
                    let mut rng: ChaCha8Rng = plant_common::rng::stream(
                        (r * 8 + j) as u64,
                        plant_common::rng::IDENTIFY_STICKS,
                    );
                    let mut out = Vec::new();
                    for (step, &ideal) in path[..rows * n].iter().enumerate() {
                        sensor.advance_to_ideal_with(ideal, |jam, delta| {
                            let stuck = (rng.gen::<f64>() < jam.stick_per_mm * delta)
                                .then(|| rng.gen_range(jam.stick_min_mm..=jam.stick_max_mm));
                            if let Some(length_mm) = stuck {
                                out.push((step, length_mm));
                            }
                            stuck
                        });
                    }
                    Ok(out)
                })
                .collect::<Result<_, IdentifyError>>()?;
            events.push(runs);
        }
        Ok(Self {
            rows,
            stick_params: wires.iter().map(stick_params).collect(),
            events,
        })
    }

    /// [`wire_realisations`] of `wires` (which may differ from those the
    /// events were drawn with in the buckling gain and the lag ceilings,
    /// not in the stick rate and sizes) along the paths of `pred` the
    /// events were drawn on: per sensor, (the mean, the realisations).
    #[allow(clippy::type_complexity)] // (mean, runs) per sensor
    pub fn realisations(
        &self,
        wires: &[WireSensorParams],
        pred: &Prediction,
    ) -> Result<Vec<(Vec<f64>, Vec<Vec<f64>>)>, IdentifyError> {
        use rayon::prelude::*;
        if wires
            .iter()
            .map(stick_params)
            .ne(self.stick_params.iter().copied())
        {
            return Err(IdentifyError::Log(
                "wire stick events drawn for another stick rate or size".into(),
            ));
        }
        let n = pred.substeps_per_row;
        let mut out = Vec::with_capacity(wires.len());
        for ((w, path), runs) in wires.iter().zip(&pred.wire_path_mm).zip(&self.events) {
            let rows = self.rows.min(path.len() / n.max(1));
            let groups: Vec<Vec<Vec<f64>>> = runs
                .par_chunks(LOCKSTEP_REALISATIONS)
                .map(|group| lockstep_runs(w, &path[..rows * n], n, group))
                .collect::<Result<_, IdentifyError>>()?;
            let runs: Vec<Vec<f64>> = groups.into_iter().flatten().collect();
            let mut mean = vec![0.0; rows];
            for run in &runs {
                for (m, v) in mean.iter_mut().zip(run) {
                    *m += v;
                }
            }
            let k = runs.len() as f64;
            mean.iter_mut().for_each(|m| *m /= k);
            out.push((mean, runs));
        }
        Ok(out)
    }
}

/// Settles a replay's plane as `Joint2d` and `Joint3d` do (coils off
/// for `settle_s`, checked every substep); the plane's name and the
/// kinetic-energy limit its replay checks with.
fn settle<S: Scalar>(
    plane: &mut PlanarJoint<S>,
    model: &PlaneModel,
    map: PlaneMap,
) -> Result<(&'static str, f64), IdentifyError> {
    let name = if map.plane == 0 { "alpha" } else { "beta" };
    let limit_j = 0.5;
    if model.settle_s > 0.0 {
        let (n, h) = split(model.settle_s, model.substep_s);
        let h = step_length(h)?;
        for _ in 0..n {
            plane.substep(h, [0.0; 2]);
            plane.check(name, limit_j)?;
        }
    }
    Ok((name, limit_j))
}

fn replay_inner(
    model: &PlaneModel,
    log: &ExcitationLog,
    map: PlaneMap,
    rows: usize,
    wire_paths: bool,
) -> Result<Prediction, IdentifyError> {
    let rows = rows.min(log.len());
    let mut plane = PlanarJoint::new(model.plane.clone())?;
    let (name, limit_j) = settle(&mut plane, model, map)?;
    let b = plane.base_m();
    // Zeroed at the settled pose; only their geometry is used here.
    let wires = if wire_paths {
        model
            .wires
            .iter()
            .map(|w| WireSensor::new(w.clone(), 1e3 * b[0], 1e3 * b[1], plane.angle_rad()))
            .collect::<Result<Vec<_>, _>>()?
    } else {
        Vec::new()
    };
    let (n, h_s) = split(log.period_s, model.substep_s);
    let h = step_length(h_s)?;
    let mut out = Prediction {
        angle_deg: Vec::with_capacity(rows * n + 1),
        substeps_per_row: n,
        substep_s: h_s,
        wire_path_mm: vec![Vec::with_capacity(rows * n); wires.len()],
        resistance_ohm: Vec::with_capacity(rows),
        peak_temperature_c: f64::NEG_INFINITY,
    };
    for k in 0..rows {
        let c = plane.coils();
        out.resistance_ohm
            .push([c[0].resistance_ohm(), c[1].resistance_ohm()]);
        let v = [log.volts[k][map.coils[0]], log.volts[k][map.coils[1]]];
        for _ in 0..n {
            out.angle_deg.push(plane.angle_rad().to_degrees());
            plane.substep(h, v);
            plane.check(name, limit_j)?;
            if wire_paths {
                let base = plane.base_m();
                let (sn, cs) = plane.sin_cos();
                for (w, path) in wires.iter().zip(out.wire_path_mm.iter_mut()) {
                    path.push(w.ideal_insertion_at_mm(1e3 * base[0], 1e3 * base[1], sn, cs));
                }
            }
        }
        for coil in plane.coils() {
            out.peak_temperature_c = out.peak_temperature_c.max(coil.temperature_c());
        }
    }
    out.angle_deg.push(plane.angle_rad().to_degrees());
    Ok(out)
}

/// Whether a replay can carry the derivatives of the prediction with
/// respect to `p` ([`replay_sensitivities`]): the plane's parameters the
/// mechanics stage fits.
pub fn carries_derivative(p: Param) -> bool {
    matches!(
        p,
        Param::Transconductance
            | Param::Convection
            | Param::AusteniteStart
            | Param::AusteniteFinish
            | Param::MartensiteStart
            | Param::MartensiteFinish
            | Param::StressShift
            | Param::SpongeModulus
            | Param::SpongeDamping
            | Param::LinkInertia
    )
}

/// A replay's predictions with their derivatives with respect to the
/// coordinates of some parameters ([`Param::to_coord`]): what the
/// mechanics stage needs for its Jacobian, in one replay instead of one
/// per parameter moved a little (issue 34).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Sensitivities {
    /// The predicted angle (deg) at each substep boundary asked for
    /// (those of the plane's replay ([`Prediction::angle_deg`]), in the
    /// order asked; a boundary past the replay is left out).
    pub angle_deg: Vec<f64>,
    /// Its derivatives, one vector per parameter, one entry per angle.
    pub angle_deg_d: Vec<Vec<f64>>,
    /// Coil resistances at each row start (Ω), [raising, lowering].
    pub resistance_ohm: Vec<[f64; 2]>,
    /// Their derivatives: per parameter, per row, [raising, lowering].
    pub resistance_ohm_d: Vec<Vec<[f64; 2]>>,
}

/// [`replay`] of rows `0..rows` with the plane's parameters `active`
/// carried as dual numbers (each must [`carries_derivative`]): the angles
/// at the substep boundaries `at` (ascending; the indices of
/// [`Prediction::angle_deg`]) and the resistances at the row starts, with
/// their derivatives with respect to the parameters' coordinates (for a
/// parameter on a log scale, `v·∂/∂v`). Every value is the plain replay's
/// to the bit (the same operations); the derivatives are those of the
/// plane's own substep (`link::tests`). More than 10 parameters are
/// refused.
pub fn replay_sensitivities(
    model: &PlaneModel,
    log: &ExcitationLog,
    map: PlaneMap,
    rows: usize,
    active: &[Param],
    at: &[usize],
) -> Result<Sensitivities, IdentifyError> {
    if let Some(p) = active.iter().find(|p| !carries_derivative(**p)) {
        return Err(IdentifyError::Log(format!(
            "a replay cannot carry the derivative with respect to {}",
            p.field()
        )));
    }
    // Lanes in even numbers: nine in ten take less time than in nine
    // (the vectorised tangents need no odd lane; 4.25 against 4.60 plain
    // substeps, docs/benchmarks.md).
    match active.len() {
        0..=2 => sensitivities::<2>(model, log, map, rows, active, at),
        3..=4 => sensitivities::<4>(model, log, map, rows, active, at),
        5..=6 => sensitivities::<6>(model, log, map, rows, active, at),
        7..=8 => sensitivities::<8>(model, log, map, rows, active, at),
        9..=10 => sensitivities::<10>(model, log, map, rows, active, at),
        n => Err(IdentifyError::Log(format!(
            "a replay carries at most 10 derivatives, {n} asked"
        ))),
    }
}

/// [`replay_sensitivities`] with `N` ≥ `active.len()` lanes.
fn sensitivities<const N: usize>(
    model: &PlaneModel,
    log: &ExcitationLog,
    map: PlaneMap,
    rows: usize,
    active: &[Param],
    at: &[usize],
) -> Result<Sensitivities, IdentifyError> {
    let rows = rows.min(log.len());
    let p = &model.plane;
    let mut seeds = PlaneSeeds::<Dual<N>>::constants(p);
    for (k, &param) in active.iter().enumerate() {
        let v = param.get(model);
        // ∂v/∂coordinate: v on a log scale, 1 on a linear one.
        let dv = match param.scale() {
            Scale::Log { .. } => v,
            Scale::Linear { .. } => 1.0,
        };
        let mut seed = Dual::<N>::cst(v);
        seed.d[k] = dv;
        match param {
            Param::Transconductance => seeds.transconductance_a_v = seed,
            Param::Convection => seeds.coil.convection_w_m2_k = seed,
            Param::AusteniteStart => seeds.coil.transformation_c[0] = seed,
            Param::AusteniteFinish => seeds.coil.transformation_c[1] = seed,
            Param::MartensiteStart => seeds.coil.transformation_c[2] = seed,
            Param::MartensiteFinish => seeds.coil.transformation_c[3] = seed,
            Param::StressShift => seeds.coil.stress_shift_k_per_mpa = seed,
            Param::SpongeModulus => seeds.sponge_modulus_pa = seed,
            Param::SpongeDamping => seeds.sponge_damping_s = seed,
            Param::LinkInertia => seeds.link_inertia_kg_m2 = seed,
            _ => unreachable!("refused by replay_sensitivities"),
        }
    }
    let mut plane = PlanarJoint::with_seeds(p.clone(), seeds)?;
    let (name, limit_j) = settle(&mut plane, model, map)?;
    let (n, h_s) = split(log.period_s, model.substep_s);
    let h = step_length(h_s)?;
    let lanes = active.len();
    let mut out = Sensitivities {
        angle_deg: Vec::with_capacity(at.len()),
        angle_deg_d: vec![Vec::with_capacity(at.len()); lanes],
        resistance_ohm: Vec::with_capacity(rows),
        resistance_ohm_d: vec![Vec::with_capacity(rows); lanes],
    };
    let mut wanted = at.iter().copied().peekable();
    let mut record = |boundary: usize, a: Dual<N>, out: &mut Sensitivities| {
        while wanted.next_if(|&k| k == boundary).is_some() {
            let deg = a * (180.0f64 / core::f64::consts::PI);
            out.angle_deg.push(deg.v);
            for (j, d) in out.angle_deg_d.iter_mut().enumerate() {
                d.push(deg.d[j]);
            }
        }
    };
    let mut boundary = 0;
    for k in 0..rows {
        let c = plane.coils();
        let r = [c[0].resistance_ohm(), c[1].resistance_ohm()];
        out.resistance_ohm.push([r[0].v, r[1].v]);
        for (j, d) in out.resistance_ohm_d.iter_mut().enumerate() {
            d.push([r[0].d[j], r[1].d[j]]);
        }
        let v = [log.volts[k][map.coils[0]], log.volts[k][map.coils[1]]];
        for _ in 0..n {
            record(boundary, plane.angle_rad(), &mut out);
            plane.substep(h, v);
            plane.check(name, limit_j)?;
            boundary += 1;
        }
    }
    record(boundary, plane.angle_rad(), &mut out);
    Ok(out)
}

/// The thermal stage's model: one coil heated by the log's measured
/// current (held over each interval), no mechanics and no stress. Returns
/// its resistance at each row start.
pub fn replay_thermal(
    coil: &SmaParams,
    current_a: &[f64],
    period_s: f64,
    substep_s: f64,
) -> Result<Vec<f64>, IdentifyError> {
    let mut c = SmaCoil::new(coil.clone())?;
    let (n, h) = split(period_s, substep_s);
    let mut out = Vec::with_capacity(current_a.len());
    for &i in current_a {
        out.push(c.resistance_ohm());
        let i = i.max(0.0);
        for _ in 0..n {
            c.step(h, i, false);
        }
        if !c.temperature_c().is_finite() {
            return Err(IdentifyError::Unstable("coil temperature".into()));
        }
    }
    Ok(out)
}

/// Realisations a thread runs side by side (see [`lockstep_runs`]).
const LOCKSTEP_REALISATIONS: usize = 8;

/// The readings (mm, at each row start) of one run of the sensor `w`
/// along `path` (`n` substeps per row) per list of recorded sticks in
/// `group`. The runs advance side by side, substep by substep: each is a
/// chain of dependent operations (the lag), so that the processor can
/// overlap several; each run's operations are those of running it alone
/// ([`WireSensor::advance_to_ideal_with`]: the same [`JamState::advance`]),
/// except that what all runs share is found once per substep — the push
/// and the lag ceiling, which depend on the path only — and the counts,
/// which the readings here do not use, are not rounded. The readings are
/// the same to the bit.
fn lockstep_runs(
    w: &WireSensorParams,
    path: &[f64],
    n: usize,
    group: &[Vec<(usize, f64)>],
) -> Result<Vec<Vec<f64>>, IdentifyError> {
    // Validated as the sensor would be; its state starts at rest.
    let sensor = WireSensor::new(w.clone(), 0.0, 0.0, 0.0)?;
    let rest_mm = w.geometry.insertion_at_rest_mm;
    let mut ideal_mm = sensor.ideal_insertion_mm();
    let j = &w.jam;
    let rows = path.len() / n.max(1);
    let mut states = vec![JamState::default(); group.len()];
    let mut next: Vec<_> = group.iter().map(|e| e.iter().peekable()).collect();
    let mut reads = vec![Vec::with_capacity(rows); group.len()];
    for k in 0..rows {
        for (read, state) in reads.iter_mut().zip(&states) {
            read.push(ideal_mm - state.lag_mm);
        }
        for (i, &ideal) in path[k * n..(k + 1) * n].iter().enumerate() {
            let step = k * n + i;
            let delta = ideal - ideal_mm;
            ideal_mm = ideal;
            if delta == 0.0 {
                // No push and no pull (the link at rest, most substeps):
                // `advance` would only clamp each lag to the ceiling at
                // this insertion, which the last substep at it already
                // did (or, at the first, a lag of 0 to a ceiling ≥ 0),
                // and no stick is drawn; so it changes no bit.
                continue;
            }
            let e_max = j.ceiling_mm(ideal, rest_mm);
            for (state, next) in states.iter_mut().zip(&mut next) {
                state.advance(j, delta, e_max, |_, _| {
                    next.next_if(|e| e.0 == step).map(|e| e.1)
                });
            }
        }
    }
    Ok(reads)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sticks drawn once along a path and replayed with another buckling
    /// gain and other lag ceilings give, to the bit, the runs of the
    /// random sensor with those values drawing its sticks as it goes.
    #[test]
    fn recorded_sticks_replay_the_random_runs_with_other_jamming() {
        let n = 10;
        let rows = 400;
        // Pushes and pulls of a few mm, with pauses; every third stretch
        // of 150 substeps holds still (no change to the bit, as a link at
        // rest gives: the lockstep runs skip those substeps).
        let path: Vec<f64> = (0..rows * n)
            .map(|s| {
                let s = if (s / 150) % 3 == 2 { s - s % 150 } else { s };
                let t = s as f64 * 1e-3;
                0.137 + 1.5 * (0.8 * t).sin().max(-0.2) + 0.3 * (5.0 * t).sin()
            })
            .collect();
        assert!(path.windows(2).filter(|w| w[0] == w[1]).count() > rows * n / 4);
        let pred = Prediction {
            substeps_per_row: n,
            substep_s: 1e-3,
            wire_path_mm: vec![path.clone(), path.iter().map(|d| 0.5 - d).collect()],
            ..Prediction::default()
        };
        let mut w = WireSensorParams::with_geometry(crate::WireGeometry::paper_2d());
        w.jam.stick_per_mm = 4.0;
        let drawn_with = vec![w; 2];
        let sticks = StickEvents::draw(&drawn_with, &pred, rows, 5).unwrap();
        assert!(sticks.events.iter().flatten().all(|e| !e.is_empty()));
        let mut other = drawn_with.clone();
        for w in &mut other {
            w.jam.buckling_gain *= 1.7;
            w.jam.max_lag_mm *= 0.6;
            w.jam.max_lag_per_mm *= 1.4;
        }
        let replayed = sticks.realisations(&other, &pred).unwrap();
        for (j, (w, path)) in other.iter().zip(&pred.wire_path_mm).enumerate() {
            for r in 0..5 {
                let mut sensor = WireSensor::new(w.clone(), 0.0, 0.0, 0.0).unwrap();
                let mut rng: ChaCha8Rng = plant_common::rng::stream(
                    (r * 8 + j) as u64,
                    plant_common::rng::IDENTIFY_STICKS,
                );
                let mut read = Vec::new();
                for k in 0..rows {
                    read.push(sensor.ideal_insertion_mm() - sensor.lag_mm());
                    for &ideal in &path[k * n..(k + 1) * n] {
                        sensor.advance_to_ideal(ideal, &mut rng);
                    }
                }
                assert_eq!(replayed[j].1[r], read, "sensor {j}, realisation {r}");
            }
        }
        // Another stick rate is refused: the events would not hold.
        other[1].jam.stick_per_mm *= 2.0;
        assert!(sticks.realisations(&other, &pred).is_err());
    }
}
