//! The excitation plan: what to do to the joint while recording a log for
//! identification. Open-loop driver inputs per coil (steps and ramps), and
//! holds at angles under the joint's own controller. `softjoint sim`,
//! `hil` and the twin tests run it; `host-tools` reads it from TOML and
//! checks it against the firmware's thermal budget.
//!
//! Between drives a coil is off. A hold gives its plane to the controller
//! (target angle) and no drive may touch that plane's coils meanwhile; the
//! log then records the controller's mean outputs, which the replay holds
//! over each interval (an approximation of the millisecond-by-millisecond
//! outputs that open-loop drives do not need).

use serde::{Deserialize, Serialize};

/// One coil driven open loop from `from_s` to `to_s`: a constant input
/// (`volts`) or a ramp (`from_v` → `to_v`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Drive {
    /// Coil, paper numbering (1-based).
    pub coil: usize,
    /// Start (s).
    pub from_s: f64,
    /// End (s).
    pub to_s: f64,
    /// Constant driver input (V) — a step.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub volts: Option<f64>,
    /// Ramp start (V).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub from_v: Option<f64>,
    /// Ramp end (V).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub to_v: Option<f64>,
}

/// A plane held at an angle by the controller from `from_s` to `to_s`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Hold {
    /// 0 (θ or α) or 1 (β).
    pub plane: usize,
    /// Desired angle (deg).
    pub deg: f64,
    /// Start (s).
    pub from_s: f64,
    /// End (s).
    pub to_s: f64,
}

/// A plan (see the module docs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExcitationPlan {
    /// Shown in reports.
    pub name: String,
    /// Length of the session (s).
    pub duration_s: f64,
    /// Log row interval (ms).
    #[serde(default = "default_interval")]
    pub log_interval_ms: u32,
    /// Open-loop drives.
    #[serde(default)]
    pub drive: Vec<Drive>,
    /// Holds at angles.
    #[serde(default)]
    pub hold: Vec<Hold>,
}

fn default_interval() -> u32 {
    10
}

impl Drive {
    /// Input at `t_s` inside the drive (V).
    pub fn volts_at(&self, t_s: f64) -> f64 {
        match (self.volts, self.from_v, self.to_v) {
            (Some(v), _, _) => v,
            (None, Some(a), Some(b)) => {
                let u = ((t_s - self.from_s) / (self.to_s - self.from_s)).clamp(0.0, 1.0);
                a + (b - a) * u
            }
            _ => 0.0,
        }
    }

    /// The largest input of the drive (V).
    pub fn peak_v(&self) -> f64 {
        match (self.volts, self.from_v, self.to_v) {
            (Some(v), _, _) => v,
            (None, Some(a), Some(b)) => a.max(b),
            _ => 0.0,
        }
    }
}

impl ExcitationPlan {
    /// Checks times, coils and planes for a joint with `planes` angles;
    /// the error names the entry and field.
    pub fn validate(&self, planes: usize) -> Result<(), String> {
        let short = plant_common::short_number;
        if !(self.duration_s.is_finite() && self.duration_s > 0.0 && self.duration_s <= 7200.0) {
            return Err(format!(
                "`duration_s`: must be in (0, 7200] s, got {}",
                short(self.duration_s)
            ));
        }
        if !(1..=100).contains(&self.log_interval_ms) {
            return Err(format!(
                "`log_interval_ms`: must be 1..=100, got {}",
                self.log_interval_ms
            ));
        }
        let coils = 2 * planes;
        let span = |what: &str, from: f64, to: f64| -> Result<(), String> {
            if !(from.is_finite() && to.is_finite() && from >= 0.0 && to > from) {
                return Err(format!(
                    "{what}: need 0 ≤ from_s < to_s, got {} → {}",
                    short(from),
                    short(to)
                ));
            }
            if to > self.duration_s + 1e-9 {
                return Err(format!(
                    "{what}: ends at {} s, after duration_s = {}",
                    short(to),
                    short(self.duration_s)
                ));
            }
            Ok(())
        };
        for (i, d) in self.drive.iter().enumerate() {
            let what = format!("`drive[{i}]`");
            if !(1..=coils).contains(&d.coil) {
                return Err(format!(
                    "{what}.coil: must be 1..={coils} for this joint, got {}",
                    d.coil
                ));
            }
            span(&what, d.from_s, d.to_s)?;
            let ok = |v: f64| v.is_finite() && (0.0..=5.0).contains(&v);
            match (d.volts, d.from_v, d.to_v) {
                (Some(v), None, None) if ok(v) => {}
                (None, Some(a), Some(b)) if ok(a) && ok(b) => {}
                (Some(_), None, None) | (None, Some(_), Some(_)) => {
                    return Err(format!(
                        "{what}: inputs must be 0..=5 V (the driver's input range)"
                    ))
                }
                _ => {
                    return Err(format!(
                        "{what}: give `volts` (a step) or `from_v` and `to_v` (a ramp), not both"
                    ))
                }
            }
            for (j, e) in self.drive.iter().enumerate().take(i) {
                if e.coil == d.coil && e.from_s < d.to_s && d.from_s < e.to_s {
                    return Err(format!("{what}: overlaps `drive[{j}]` on coil {}", d.coil));
                }
            }
        }
        for (i, h) in self.hold.iter().enumerate() {
            let what = format!("`hold[{i}]`");
            if h.plane >= planes {
                return Err(format!(
                    "{what}.plane: must be 0..={} for this joint, got {}",
                    planes - 1,
                    h.plane
                ));
            }
            span(&what, h.from_s, h.to_s)?;
            if !(h.deg.is_finite() && h.deg.abs() <= 25.0) {
                return Err(format!(
                    "{what}.deg: must be within ±25°, got {}",
                    short(h.deg)
                ));
            }
            for (j, d) in self.drive.iter().enumerate() {
                let plane_of = (d.coil - 1) % planes;
                if plane_of == h.plane && d.from_s < h.to_s && h.from_s < d.to_s {
                    return Err(format!(
                        "{what}: drive[{j}] drives coil {} of the held plane meanwhile",
                        d.coil
                    ));
                }
            }
        }
        Ok(())
    }

    /// Inputs of every coil at `t_s` (V), `None` for the coils of a plane
    /// that is held (the controller drives them).
    pub fn volts_at(&self, planes: usize, t_s: f64) -> [Option<f64>; 4] {
        let mut out = [None; 4];
        for (c, o) in out.iter_mut().enumerate().take(2 * planes) {
            let plane = c % planes;
            if self.held(plane, t_s).is_none() {
                *o = Some(
                    self.drive
                        .iter()
                        .find(|d| d.coil == c + 1 && t_s >= d.from_s && t_s < d.to_s)
                        .map(|d| d.volts_at(t_s))
                        .unwrap_or(0.0),
                );
            }
        }
        out
    }

    /// The target of `plane` at `t_s`, if it is held.
    pub fn held(&self, plane: usize, t_s: f64) -> Option<f64> {
        self.hold
            .iter()
            .find(|h| h.plane == plane && t_s >= h.from_s && t_s < h.to_s)
            .map(|h| h.deg)
    }

    /// A 60 s plan with the standard plan's ingredients in short form
    /// (saturated pulses, a slow ramp, a sustained level, one
    /// co-contraction), for tests that must run in a debug build: it
    /// determines fewer parameters, less tightly. The ramp (1.7 → 1.9 V on
    /// the antagonist before the co-contraction) is what spreads the
    /// unsaturated inputs of the fitted part (the first 45 s) for the
    /// driver's regression: the pulses saturate at 0.5 A, and one sustained
    /// level alone cannot separate the transconductance from the turn-on
    /// voltage. Inside the firmware's thermal budget like the standard plan.
    pub fn compact(planes: usize) -> Self {
        let mut drive = Vec::new();
        for p in 0..planes {
            let (ag, ant) = (p + 1, p + 1 + planes);
            let o = 2.0 * p as f64;
            let step = |c: usize, a: f64, z: f64, v: f64| Drive {
                coil: c,
                from_s: o + a,
                to_s: o + z,
                volts: Some(v),
                from_v: None,
                to_v: None,
            };
            drive.extend([
                step(ag, 0.0, 2.0, 3.0),
                step(ant, 10.0, 11.5, 3.0),
                step(ag, 20.0, 21.0, 3.0),
                Drive {
                    coil: ant,
                    from_s: o + 22.0,
                    to_s: o + 29.0,
                    volts: None,
                    from_v: Some(1.7),
                    to_v: Some(1.9),
                },
                step(ant, 30.0, 46.0, 1.9),
                step(ag, 36.0, 37.5, 3.0),
                // The held-out quarter (45–60 s) must move the joint, or
                // it cannot tell a right plant from a wrong one.
                step(ag, 47.0, 49.0, 3.0),
                step(ant, 51.0, 53.0, 3.0),
                step(ag, 55.0, 57.0, 3.0),
            ]);
        }
        Self {
            name: "compact excitation, 60 s".into(),
            duration_s: 60.0,
            log_interval_ms: 10,
            drive,
            hold: Vec::new(),
        }
    }

    /// The standard plan: for every pair, sustained low levels (1.85 and
    /// 1.9 V: warm coils, a partial transformation where the driver is
    /// strong), saturated pulses of 1–2.5 s (0.5 A whatever the driver's
    /// gain: partial to full transformations), a slow ramp, co-contraction
    /// (the antagonist warm while the agonist is pulsed, which raises the
    /// agonist's stress and shows the Clausius–Clapeyron shift), cooling
    /// gaps, and, for `with_holds`, holds at ±8° under the controller.
    /// The firmware's budget model (1.5 A/V, conservative) allows no
    /// sustained input above ≈ 1.9 V and 0.5 A pulses of ≈ 3 s from cold,
    /// hence the shape. The block of 240 s is repeated to fill `duration_s`.
    /// Every level stays inside the firmware's default thermal budget
    /// (checked by host-tools before a plan runs).
    pub fn standard(planes: usize, duration_s: f64, with_holds: bool) -> Self {
        let mut drive = Vec::new();
        let mut hold = Vec::new();
        let block = 240.0;
        let blocks = (duration_s / block).ceil().max(1.0) as usize;
        for b in 0..blocks {
            let t0 = b as f64 * block;
            for p in 0..planes {
                let (ag, ant) = (p + 1, p + 1 + planes);
                // Plane β runs the same block shifted by 5 s.
                let o = t0 + 5.0 * p as f64;
                let step = |c: usize, a: f64, z: f64, v: f64| Drive {
                    coil: c,
                    from_s: o + a,
                    to_s: o + z,
                    volts: Some(v),
                    from_v: None,
                    to_v: None,
                };
                let ramp = |c: usize, a: f64, z: f64, va: f64, vb: f64| Drive {
                    coil: c,
                    from_s: o + a,
                    to_s: o + z,
                    volts: None,
                    from_v: Some(va),
                    to_v: Some(vb),
                };
                drive.extend([
                    step(ag, 0.0, 15.0, 1.85),
                    step(ag, 15.0, 30.0, 1.9),
                    step(ant, 45.0, 60.0, 1.85),
                    step(ant, 60.0, 75.0, 1.9),
                    step(ag, 90.0, 91.0, 3.0),
                    step(ant, 105.0, 106.5, 3.0),
                    step(ag, 120.0, 122.5, 3.0),
                    step(ant, 140.0, 142.0, 3.0),
                    ramp(ag, 160.0, 175.0, 1.7, 1.9),
                    // Co-contraction: antagonist warm, agonist pulsed.
                    step(ant, 180.0, 205.0, 1.9),
                    step(ag, 190.0, 191.5, 3.0),
                ]);
                if with_holds {
                    hold.push(Hold {
                        plane: p,
                        deg: 8.0,
                        from_s: o + 212.0,
                        to_s: o + 222.0,
                    });
                    hold.push(Hold {
                        plane: p,
                        deg: -8.0,
                        from_s: o + 222.0,
                        to_s: o + 232.0,
                    });
                }
            }
        }
        let mut plan = Self {
            name: format!(
                "standard excitation, {} s{}",
                plant_common::short_number(duration_s),
                if with_holds { ", with holds" } else { "" }
            ),
            duration_s,
            log_interval_ms: 10,
            drive,
            hold,
        };
        let end = duration_s;
        plan.drive.retain(|d| d.from_s < end);
        for d in plan.drive.iter_mut() {
            if d.to_s > end {
                if d.volts.is_none() {
                    d.to_v = Some(d.volts_at(end));
                }
                d.to_s = end;
            }
        }
        plan.hold.retain(|h| h.from_s < end);
        for h in plan.hold.iter_mut() {
            h.to_s = h.to_s.min(end);
        }
        plan
    }
}
