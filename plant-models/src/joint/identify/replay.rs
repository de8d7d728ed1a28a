//! Replays a log's driver inputs through one plane of the plant with
//! candidate parameters: the model side of every identification stage.
//!
//! The plane is the plant's own [`PlanarJoint`] and [`WireSensor`] (no
//! second copy of the physics), built and settled exactly as `Joint2d` and
//! `Joint3d` do (coils off for `settle_s`, the wire coders zeroed there),
//! then driven with each row's mean input held over the row's interval in
//! substeps of `substep_s`. Stick events are left out (they are random);
//! the deterministic buckling lag is kept. Prediction stops at the first
//! numerical instability with the plant's error.

use rand_chacha::ChaCha8Rng;

use super::log::ExcitationLog;
use super::IdentifyError;
use crate::joint::{PlanarJoint, PlaneParams, SmaCoil, SmaParams, WireSensor, WireSensorParams};
use crate::viscoelastic::three_element::StepLength;

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
    /// Wire insertions at each row start (mm), per plane sensor.
    pub wire_mm: Vec<Vec<f64>>,
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
    let rows = rows.min(log.len());
    let mut plane = PlanarJoint::new(model.plane.clone())?;
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
    let b = plane.base_m();
    // The stick events are random: the replay leaves them out (rate 0),
    // as the module docs say. With the model's own rate it drew another
    // realisation of them than the log's, which made the wire residuals
    // jump when a small parameter step moved a stick (finite-difference
    // Jacobians of the jamming stage off).
    let mut wires = model
        .wires
        .iter()
        .map(|w| {
            let mut w = w.clone();
            w.jam.stick_per_mm = 0.0;
            WireSensor::new(w, 1e3 * b[0], 1e3 * b[1], plane.angle_rad())
        })
        .collect::<Result<Vec<_>, _>>()?;
    // Stick events need a stream; at rate 0 it is never drawn from, so any
    // seed gives the same prediction.
    let mut rng: ChaCha8Rng = crate::rng::stream(0, crate::rng::IDENTIFY_REPLAY);
    let (n, h_s) = split(log.period_s, model.substep_s);
    let h = step_length(h_s)?;
    let mut out = Prediction {
        angle_deg: Vec::with_capacity(rows * n + 1),
        substeps_per_row: n,
        substep_s: h_s,
        wire_mm: vec![Vec::with_capacity(rows); wires.len()],
        resistance_ohm: Vec::with_capacity(rows),
        peak_temperature_c: f64::NEG_INFINITY,
    };
    for k in 0..rows {
        let c = plane.coils();
        out.resistance_ohm
            .push([c[0].resistance_ohm(), c[1].resistance_ohm()]);
        for (w, series) in wires.iter().zip(out.wire_mm.iter_mut()) {
            series.push(w.ideal_insertion_mm() - w.lag_mm());
        }
        let v = [log.volts[k][map.coils[0]], log.volts[k][map.coils[1]]];
        for _ in 0..n {
            out.angle_deg.push(plane.angle_rad().to_degrees());
            plane.substep(h, v);
            plane.check(name, limit_j)?;
            let base = plane.base_m();
            let (sn, cs) = plane.sin_cos();
            for w in wires.iter_mut() {
                w.update_sin_cos(1e3 * base[0], 1e3 * base[1], sn, cs, &mut rng);
            }
        }
        for coil in plane.coils() {
            out.peak_temperature_c = out.peak_temperature_c.max(coil.temperature_c());
        }
    }
    out.angle_deg.push(plane.angle_rad().to_degrees());
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
