//! The excitation log: what a recording of the joint holds for
//! identification, how it is recorded (one [`LogRecorder`] for the twin,
//! `softjoint sim`, `hil` and `console`), and how it is read back from CSV.
//!
//! One row per log interval (default 10 ms) at `t_s = k·Δ`:
//! - `v1_v..`: the **mean** driver input of each coil over `[t, t + Δ)`
//!   (the replay holds it over the interval: exact for steps on interval
//!   boundaries, the midpoint of a ramp's 10 ms piece otherwise);
//! - `cam_capture_s`, `cam_*_deg`: the newest camera frame available at
//!   `t` and when it was captured (−1 before the first frame; an occluded
//!   frame leaves the previous one in place, so readers keep a frame once,
//!   by its capture time);
//! - `d1_mm..`: wire insertions at `t`;
//! - optional `i1_a..` (mean coil current over the interval) and
//!   `r1_ohm..` (coil resistance at `t`), where the lab has a current
//!   sense resistor and a coil-voltage tap. The thermal stage of the
//!   identification needs them; without them it fits the thermal
//!   parameters from the angle alone.

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::IdentifyError;
use plant_common::csv_input::Table;

/// Column names of a log with `planes` angles (1: θ; 2: α, β), in order.
pub fn columns(planes: usize, electrical: bool) -> Vec<String> {
    let coils = 2 * planes;
    let sensors = if planes == 1 { 1 } else { 4 };
    let mut c = vec!["t_s".to_string()];
    c.extend((1..=coils).map(|k| format!("v{k}_v")));
    c.push("cam_capture_s".into());
    if planes == 1 {
        c.push("cam_theta_deg".into());
    } else {
        c.push("cam_alpha_deg".into());
        c.push("cam_beta_deg".into());
    }
    c.extend((1..=sensors).map(|k| format!("d{k}_mm")));
    if electrical {
        c.extend((1..=coils).map(|k| format!("i{k}_a")));
        c.extend((1..=coils).map(|k| format!("r{k}_ohm")));
    }
    c
}

/// The log's angles from its camera columns: 1 with `cam_theta_deg` (2D),
/// 2 with `cam_alpha_deg` (3D); an error naming the header otherwise.
fn planes_of(t: &Table) -> Result<usize, IdentifyError> {
    if t.has("cam_theta_deg") {
        Ok(1)
    } else if t.has("cam_alpha_deg") {
        Ok(2)
    } else {
        Err(t
            .error(
                t.header_line,
                None,
                format!(
                    "missing column `cam_theta_deg` (a 2D log) or `cam_alpha_deg` (3D); the header has: {}",
                    plant_common::csv_input::excerpt(&t.columns.join(", "))
                ),
            )
            .into())
    }
}

/// A recorded excitation session (see the module docs).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ExcitationLog {
    /// Angles: 1 (2D) or 2 (3D).
    pub planes: usize,
    /// Row interval Δ (s).
    pub period_s: f64,
    /// Row times (s), `k·Δ`.
    pub t_s: Vec<f64>,
    /// Mean driver input per coil over each row's interval (V), paper
    /// numbering (2D: coils 1, 2 in slots 0, 1).
    pub volts: Vec<[f64; 4]>,
    /// Capture time of the newest available camera frame (s; −1 = none).
    pub cam_capture_s: Vec<f64>,
    /// Its angles (deg).
    pub cam_deg: Vec<[f64; 2]>,
    /// Wire insertions (mm), sensors in paper numbering (2D: slot 0).
    pub wire_mm: Vec<[f64; 4]>,
    /// Mean coil current over each interval (A), when logged.
    pub current_a: Option<Vec<[f64; 4]>>,
    /// Coil resistance at each row (Ω), when logged.
    pub resistance_ohm: Option<Vec<[f64; 4]>>,
}

impl ExcitationLog {
    /// Rows.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Coils: 2 per angle.
    pub fn coils(&self) -> usize {
        2 * self.planes
    }

    /// Wire sensors: 1 (2D) or 4 (3D).
    pub fn sensors(&self) -> usize {
        if self.planes == 1 {
            1
        } else {
            4
        }
    }

    /// Whether current and resistance were logged.
    pub fn has_electrical(&self) -> bool {
        self.current_a.is_some() && self.resistance_ohm.is_some()
    }

    /// The header and rows as CSV fields (every value finite: the
    /// recorder only stores finite numbers, and `from_table` only reads
    /// them).
    pub fn to_rows(&self) -> (Vec<String>, Vec<Vec<f64>>) {
        let cols = columns(self.planes, self.has_electrical());
        let rows = (0..self.len()).map(|k| self.row(k)).collect();
        (cols, rows)
    }

    /// Row `k` as CSV fields, in the order of [`columns`] (panics if `k`
    /// is not a row).
    pub fn row(&self, k: usize) -> Vec<f64> {
        let (c, s) = (self.coils(), self.sensors());
        let mut r = vec![self.t_s[k]];
        r.extend_from_slice(&self.volts[k][..c]);
        r.push(self.cam_capture_s[k]);
        r.extend_from_slice(&self.cam_deg[k][..self.planes]);
        r.extend_from_slice(&self.wire_mm[k][..s]);
        if let (Some(i), Some(rr)) = (&self.current_a, &self.resistance_ohm) {
            r.extend_from_slice(&i[k][..c]);
            r.extend_from_slice(&rr[k][..c]);
        }
        r
    }

    /// Appends the rows of `more` (the next rows of the same session, as
    /// [`LogRecorder::take_rows`] hands them out); an empty log without
    /// angles takes `more` as it is.
    pub fn append(&mut self, more: ExcitationLog) {
        if self.planes == 0 && self.is_empty() {
            *self = more;
            return;
        }
        self.t_s.extend(more.t_s);
        self.volts.extend(more.volts);
        self.cam_capture_s.extend(more.cam_capture_s);
        self.cam_deg.extend(more.cam_deg);
        self.wire_mm.extend(more.wire_mm);
        if let (Some(a), Some(b)) = (self.current_a.as_mut(), more.current_a) {
            a.extend(b);
        }
        if let (Some(a), Some(b)) = (self.resistance_ohm.as_mut(), more.resistance_ohm) {
            a.extend(b);
        }
    }

    /// Reads a log from a CSV table (read with `csv_input::read_numeric`):
    /// 2D or 3D from the camera columns, the electrical columns if all are
    /// there. Rows must be evenly spaced from 0; errors name the file, line
    /// and column.
    pub fn from_table(t: &Table) -> Result<Self, IdentifyError> {
        let planes = planes_of(t)?;
        let electrical = t.has("i1_a") || t.has("r1_ohm");
        let want = columns(planes, electrical);
        let idx: Vec<usize> = want.iter().map(|c| t.column(c)).collect::<Result<_, _>>()?;
        t.require_rows(10, "(a log of at least 10 intervals)")?;
        let mut log = Self::read_rows(t, &idx, planes, electrical);
        let dt = log.t_s[1] - log.t_s[0];
        log.period_s = dt;
        let col_t = &t.columns[idx[0]];
        if !(1e-3 - 1e-9..=0.1 + 1e-9).contains(&dt) {
            return Err(t
                .error(
                    t.rows[1].line,
                    Some(col_t),
                    format!(
                        "rows must be 1..100 ms apart, got {} s",
                        plant_common::short_number(dt)
                    ),
                )
                .into());
        }
        for (k, row) in t.rows.iter().enumerate() {
            log.check_row(t, k, row.line, col_t)?;
        }
        Ok(log)
    }

    /// The table's rows as a log, the columns `idx` in the order of
    /// [`columns`]`(planes, electrical)`; the period is left at 0 and
    /// nothing is checked yet.
    fn read_rows(t: &Table, idx: &[usize], planes: usize, electrical: bool) -> Self {
        let (c, s) = (2 * planes, if planes == 1 { 1 } else { 4 });
        let mut log = ExcitationLog {
            planes,
            current_a: electrical.then(Vec::new),
            resistance_ohm: electrical.then(Vec::new),
            ..Default::default()
        };
        for row in &t.rows {
            let v = |j: usize| row.values[idx[j]];
            let mut j = 0;
            let mut take = |n: usize| {
                let mut out = [0.0; 4];
                for o in out.iter_mut().take(n) {
                    *o = v(j);
                    j += 1;
                }
                out
            };
            let time = take(1)[0];
            let volts = take(c);
            let cap = take(1)[0];
            let cam = take(planes);
            let wire = take(s);
            log.t_s.push(time);
            log.volts.push(volts);
            log.cam_capture_s.push(cap);
            log.cam_deg.push([cam[0], cam[1]]);
            log.wire_mm.push(wire);
            if electrical {
                let i = take(c);
                let r = take(c);
                if let Some(x) = log.current_a.as_mut() {
                    x.push(i);
                }
                if let Some(x) = log.resistance_ohm.as_mut() {
                    x.push(r);
                }
            }
        }
        log
    }

    /// Checks row `k` (on file line `line`) of a log read from `t` whose
    /// period is set: its time on the grid `k·Δ` (column `col_t`), driver
    /// inputs within 0..=30 V, coil resistances positive.
    fn check_row(
        &self,
        t: &Table,
        k: usize,
        line: usize,
        col_t: &str,
    ) -> Result<(), IdentifyError> {
        let (c, dt) = (self.coils(), self.period_s);
        let expect = k as f64 * dt;
        if (self.t_s[k] - expect).abs() > 1e-6 + 1e-9 * expect {
            return Err(t
                .error(
                    line,
                    Some(col_t),
                    format!(
                        "rows must be evenly spaced from 0 ({} s apart): expected {}, got {}",
                        plant_common::short_number(dt),
                        plant_common::short_number(expect),
                        plant_common::short_number(self.t_s[k])
                    ),
                )
                .into());
        }
        for (j, v) in self.volts[k][..c].iter().enumerate() {
            if !(0.0..=30.0).contains(v) {
                return Err(t
                    .error(
                        line,
                        Some(&format!("v{}_v", j + 1)),
                        format!(
                            "driver input must be 0..=30 V, got {}",
                            plant_common::short_number(*v)
                        ),
                    )
                    .into());
            }
        }
        self.check_measured(t, k, line)?;
        if let Some(r) = &self.resistance_ohm {
            for (j, v) in r[k][..c].iter().enumerate() {
                if *v <= 0.0 {
                    return Err(t
                        .error(
                            line,
                            Some(&format!("r{}_ohm", j + 1)),
                            "a coil resistance must be > 0",
                        )
                        .into());
                }
            }
        }
        Ok(())
    }

    /// Checks row `k`'s measurements against what the joint can show
    /// ([`MAX_ANGLE_DEG`], [`MAX_INSERTION_MM`], [`MAX_COIL_CURRENT_A`],
    /// [`MAX_COIL_RESISTANCE_OHM`]): an outlier (a unit slip, a corrupted
    /// value) is refused by line and column rather than fitted.
    fn check_measured(&self, t: &Table, k: usize, line: usize) -> Result<(), IdentifyError> {
        let (c, s) = (self.coils(), self.sensors());
        let names = columns(self.planes, self.has_electrical());
        let beyond = |col: &str, v: f64, limit: f64, unit: &str, what: &str| {
            IdentifyError::from(t.error(
                line,
                Some(col),
                format!(
                    "{} {unit} is beyond {what} (|value| ≤ {} {unit})",
                    plant_common::short_number(v),
                    plant_common::short_number(limit)
                ),
            ))
        };
        let cam = &names[2 + c..2 + c + self.planes];
        for (v, col) in self.cam_deg[k][..self.planes].iter().zip(cam) {
            if v.abs() > MAX_ANGLE_DEG {
                return Err(beyond(col, *v, MAX_ANGLE_DEG, "°", "any bend of the joint"));
            }
        }
        let wires = &names[2 + c + self.planes..2 + c + self.planes + s];
        for (v, col) in self.wire_mm[k][..s].iter().zip(wires) {
            if v.abs() > MAX_INSERTION_MM {
                return Err(beyond(
                    col,
                    *v,
                    MAX_INSERTION_MM,
                    "mm",
                    "a wire's insertion",
                ));
            }
        }
        let electrical = &names[2 + c + self.planes + s..];
        if let (Some(i), Some(r)) = (&self.current_a, &self.resistance_ohm) {
            for (v, col) in i[k][..c].iter().zip(electrical) {
                if v.abs() > MAX_COIL_CURRENT_A {
                    return Err(beyond(col, *v, MAX_COIL_CURRENT_A, "A", "a coil's current"));
                }
            }
            for (v, col) in r[k][..c].iter().zip(&electrical[c..]) {
                if *v > MAX_COIL_RESISTANCE_OHM {
                    return Err(beyond(
                        col,
                        *v,
                        MAX_COIL_RESISTANCE_OHM,
                        "Ω",
                        "a coil's resistance",
                    ));
                }
            }
        }
        Ok(())
    }

    /// The rows `from..to` as a log of their own whose time starts at the
    /// original times (used to cut the held-out part).
    pub fn slice_rows(&self, to: usize) -> Self {
        let to = to.min(self.len());
        ExcitationLog {
            planes: self.planes,
            period_s: self.period_s,
            t_s: self.t_s[..to].to_vec(),
            volts: self.volts[..to].to_vec(),
            cam_capture_s: self.cam_capture_s[..to].to_vec(),
            cam_deg: self.cam_deg[..to].to_vec(),
            wire_mm: self.wire_mm[..to].to_vec(),
            current_a: self.current_a.as_ref().map(|v| v[..to].to_vec()),
            resistance_ohm: self.resistance_ohm.as_ref().map(|v| v[..to].to_vec()),
        }
    }
}

/// The largest joint angle a log or a calibration sweep may show (deg):
/// the joint works within ±25° (the firmware's target limit) and its
/// calibration sweep spans ±21°; past ±90° the link would fold back on its
/// base, so such a value is a unit slip or a corrupted reading.
pub const MAX_ANGLE_DEG: f64 = 90.0;

/// The largest wire insertion a log or sweep may show (mm): the wires move
/// −2…6 mm over the ±21° sweep; 100 mm is longer than the joint.
pub const MAX_INSERTION_MM: f64 = 100.0;

/// The largest coil current a log may show (A): the coils draw ≈ 0.5 A at
/// the driver's full 5 V.
pub const MAX_COIL_CURRENT_A: f64 = 20.0;

/// The largest coil resistance a log may show (Ω): the coils measure
/// ≈ 6 Ω.
pub const MAX_COIL_RESISTANCE_OHM: f64 = 1000.0;

/// Measurement noise a recorder adds to the electrical columns (a lab's
/// current sense and coil-voltage tap). The twin tests use it; `sim`
/// records the plant's values as they are.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ElectricalNoise {
    /// Standard deviation of each current reading (A).
    pub current_a: f64,
    /// Standard deviation of each resistance reading (Ω).
    pub resistance_ohm: f64,
}

/// What the plant shows at the start of a control period.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Observation {
    /// Newest available camera frame: capture time (s) and angles (deg).
    pub camera: Option<(f64, [f64; 2])>,
    /// Wire insertions (mm).
    pub wire_mm: [f64; 4],
    /// Coil resistances (Ω).
    pub resistance_ohm: [f64; 4],
}

/// Builds an [`ExcitationLog`] one control period at a time.
#[derive(Clone, Debug)]
pub struct LogRecorder {
    log: ExcitationLog,
    /// Rows already handed out by [`LogRecorder::take_rows`].
    rows_taken: usize,
    periods_per_row: usize,
    in_row: usize,
    volt_sum: [f64; 4],
    current_sum: [f64; 4],
    last_camera: (f64, [f64; 2]),
    noise: ElectricalNoise,
    rng: ChaCha8Rng,
}

impl LogRecorder {
    /// A recorder for `planes` angles, one row every `periods_per_row`
    /// control periods of `control_period_s`; `electrical` logs currents and
    /// resistances with `noise` (drawn from `rng`).
    pub fn new(
        planes: usize,
        control_period_s: f64,
        periods_per_row: usize,
        electrical: bool,
        noise: ElectricalNoise,
        rng: ChaCha8Rng,
    ) -> Self {
        Self {
            log: ExcitationLog {
                planes,
                period_s: control_period_s * periods_per_row.max(1) as f64,
                current_a: electrical.then(Vec::new),
                resistance_ohm: electrical.then(Vec::new),
                ..Default::default()
            },
            rows_taken: 0,
            periods_per_row: periods_per_row.max(1),
            in_row: 0,
            volt_sum: [0.0; 4],
            current_sum: [0.0; 4],
            last_camera: (-1.0, [0.0; 2]),
            noise,
            rng,
        }
    }

    /// One control period: `obs` at its start, the driver inputs applied
    /// during it, the coil currents that flowed.
    pub fn push(&mut self, obs: &Observation, volts: &[f64], currents_a: &[f64]) {
        if let Some(c) = obs.camera {
            self.last_camera = c;
        }
        if self.in_row == 0 {
            let k = self.rows_taken + self.log.t_s.len();
            self.log.t_s.push(k as f64 * self.log.period_s);
            self.log.cam_capture_s.push(self.last_camera.0);
            self.log.cam_deg.push(self.last_camera.1);
            self.log.wire_mm.push(obs.wire_mm);
            if let Some(r) = self.log.resistance_ohm.as_mut() {
                let mut v = obs.resistance_ohm;
                if let Ok(n) = Normal::new(0.0, self.noise.resistance_ohm) {
                    for x in v.iter_mut() {
                        *x = (*x + n.sample(&mut self.rng)).max(1e-3);
                    }
                }
                r.push(v);
            }
        }
        for (s, v) in self.volt_sum.iter_mut().zip(volts) {
            *s += v;
        }
        for (s, i) in self.current_sum.iter_mut().zip(currents_a) {
            *s += i;
        }
        self.in_row += 1;
        if self.in_row == self.periods_per_row {
            self.close_row();
        }
    }

    fn close_row(&mut self) {
        let n = self.in_row.max(1) as f64;
        self.log.volts.push(self.volt_sum.map(|s| s / n));
        if let Some(c) = self.log.current_a.as_mut() {
            let mut v = self.current_sum.map(|s| s / n);
            if let Ok(noise) = Normal::new(0.0, self.noise.current_a) {
                for x in v.iter_mut() {
                    *x += noise.sample(&mut self.rng);
                }
            }
            c.push(v);
        }
        self.volt_sum = [0.0; 4];
        self.current_sum = [0.0; 4];
        self.in_row = 0;
    }

    /// Complete rows recorded and not yet taken.
    pub fn complete_rows(&self) -> usize {
        self.log.volts.len()
    }

    /// Takes the complete rows recorded so far, leaving the row being
    /// recorded: a session streams its log to disk in pieces instead of
    /// keeping it whole. Row times go on across takes, and the pieces
    /// appended ([`ExcitationLog::append`]) are the log [`Self::finish`]
    /// would have given.
    pub fn take_rows(&mut self) -> ExcitationLog {
        let n = self.log.volts.len();
        let log = &mut self.log;
        // The row being recorded: its start-of-row columns, no inputs yet.
        let partial = ExcitationLog {
            planes: log.planes,
            period_s: log.period_s,
            t_s: log.t_s.split_off(n),
            volts: Vec::new(),
            cam_capture_s: log.cam_capture_s.split_off(n),
            cam_deg: log.cam_deg.split_off(n),
            wire_mm: log.wire_mm.split_off(n),
            current_a: log.current_a.as_ref().map(|_| Vec::new()),
            resistance_ohm: log.resistance_ohm.as_mut().map(|r| r.split_off(n)),
        };
        self.rows_taken += n;
        std::mem::replace(log, partial)
    }

    /// The log (the rows not taken yet); a partial last row is dropped.
    pub fn finish(mut self) -> ExcitationLog {
        if self.in_row > 0 {
            let k = self.log.volts.len();
            self.log.t_s.truncate(k);
            self.log.cam_capture_s.truncate(k);
            self.log.cam_deg.truncate(k);
            self.log.wire_mm.truncate(k);
            if let Some(r) = self.log.resistance_ohm.as_mut() {
                r.truncate(k);
            }
        }
        self.log
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng as _;

    /// A recorder fed 3 ms control periods, 4 per row, with made-up but
    /// varying observations and noisy electrical columns.
    fn feed(rec: &mut LogRecorder, from: usize, to: usize) {
        for k in from..to {
            let x = k as f64;
            let obs = Observation {
                camera: (k % 11 == 0).then_some((x * 3e-3, [x.sin(), x.cos()])),
                wire_mm: [x * 1e-3, -x * 1e-3, 0.5, 0.25],
                resistance_ohm: [10.0 + x * 1e-4; 4],
            };
            rec.push(
                &obs,
                &[1.0 + (x * 0.1).sin(), 0.5, 0.0, 2.0],
                &[0.1, 0.2, 0.3, x * 1e-3],
            );
        }
    }

    fn recorder() -> LogRecorder {
        let noise = ElectricalNoise {
            current_a: 0.01,
            resistance_ohm: 0.05,
        };
        LogRecorder::new(2, 3e-3, 4, true, noise, ChaCha8Rng::seed_from_u64(5))
    }

    /// Rows taken in pieces (at row boundaries and in the middle of a
    /// row) and appended are the log of a recorder never taken from, value
    /// for value, its partial last row dropped alike.
    #[test]
    fn rows_taken_in_pieces_are_the_whole_log() {
        let mut whole = recorder();
        feed(&mut whole, 0, 1003);
        let whole = whole.finish();
        assert_eq!(whole.len(), 250);
        let mut rec = recorder();
        let mut pieces = ExcitationLog::default();
        for (from, to) in [(0, 8), (8, 8), (8, 13), (13, 402), (402, 1003)] {
            feed(&mut rec, from, to);
            assert_eq!(rec.complete_rows(), to / 4 - pieces.len(), "at {to}");
            pieces.append(rec.take_rows());
        }
        pieces.append(rec.finish());
        assert_eq!(pieces, whole);
        assert_eq!(pieces.t_s[249], 249.0 * 12e-3);
    }
}
