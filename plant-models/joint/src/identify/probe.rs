//! The probe (issue 28): a short plan that drives each coil alone up a
//! staircase of inputs and then to a saturated pulse, within the
//! firmware's thermal budget, and the analysis of its log: per coil where
//! the driver starts to conduct, where the plane starts to move, how far
//! it goes at the top, and how fast it rises and falls back. The
//! identification plan is then placed relative to what was found
//! ([`ExcitationPlan::adapted`]), so that a coil whose driver turns on
//! above the standard plan's levels is still driven through its
//! unsaturated range.
//!
//! The probe's shape (per coil: 13 steps of 1.5 s from 1.4 to 2.6 V, 3 s
//! apart; 15 s of cooling; a 2.5 s pulse at 3 V; 20 s to cool) follows
//! from the firmware's default budget model (1.5 A/V from 1.7 V, capped at
//! 0.5 A; 5 Ω; τ 5 s; 0.032 J/K; trip at 95 K rise): at the cap a
//! 1.5 s-on / 3 s-off train settles at a peak rise of ≈ 85 K, and a
//! 2.5 s pulse from cold reaches ≈ 77 K. The steps span 1.4–2.6 V, wider
//! than the 1.5–2.1 V plausible for a ULN2003 stage's input threshold
//! (the campaign's range, `hidden::campaign_joint_3d`). The two coils of
//! a plane run one after the other; the planes run at the same time (the
//! model has no coupling between planes).

use serde::Serialize;

use super::log::ExcitationLog;
use super::plan::{Drive, ExcitationPlan};
use super::verify::camera_noise_floor_deg;

/// The probe's staircase (V): 1.4, 1.5, …, 2.6.
pub fn probe_levels_v() -> Vec<f64> {
    (0..13).map(|k| 1.4 + 0.1 * k as f64).collect()
}

/// Length of each staircase step (s).
pub const STEP_ON_S: f64 = 1.5;
/// Pause after each step (s).
pub const STEP_OFF_S: f64 = 3.0;
/// Cooling before the top pulse (s): the budget's rise decays by e⁻³.
pub const COOL_BEFORE_TOP_S: f64 = 15.0;
/// The top pulse: input (V) and length (s), as the standard plan's
/// longest pulse.
pub const TOP_V: f64 = 3.0;
/// Length of the top pulse (s).
pub const TOP_ON_S: f64 = 2.5;
/// Time after the top pulse to watch the plane fall back (s).
pub const COOL_AFTER_TOP_S: f64 = 20.0;
/// Still time at the start, for the baseline (s).
pub const LEAD_S: f64 = 2.0;

/// A level moved the plane when its travel exceeds this many times the
/// camera noise (the largest of ≈ 100 frames of noise stays below ≈ 3.5σ,
/// and the baseline is a mean of ≈ 30 frames).
pub const MOTION_SIGMAS: f64 = 5.0;

/// How far above the budget model's driver offset an input may be held
/// sustained (V): the firmware's default budget takes the current as
/// 1.5 A/V · (V − offset); the steady rise I²·5 Ω·5 s/0.032 J/K reaches
/// the 95 K trip at I = 0.349 A, i.e. 0.233 V above the offset (1.93 V
/// with the default 1.7 V offset).
pub const BUDGET_SUSTAINED_ABOVE_OFFSET_V: f64 = 0.23;

/// The firmware's default driver offset (V), which its thermal budget
/// assumes (`firmware::control::PAPER_V_OFFSET_V`).
pub const FIRMWARE_DEFAULT_OFFSET_V: f64 = 1.7;

/// Above the sustained limit the adapted plan chops a level
/// into pulses this long (s) …
pub const CHOP_ON_S: f64 = 1.0;
/// … separated by this much (s): at the 0.5 A cap a 1 s / 2 s train
/// peaks at ≈ 78 K of the budget's rise, under the 95 K trip.
pub const CHOP_OFF_S: f64 = 2.0;

impl ExcitationPlan {
    /// The probe for a joint with `planes` angles (see the module docs).
    pub fn probe(planes: usize) -> Self {
        let levels = probe_levels_v();
        let per_coil = levels.len() as f64 * (STEP_ON_S + STEP_OFF_S)
            + COOL_BEFORE_TOP_S
            + TOP_ON_S
            + COOL_AFTER_TOP_S;
        let mut drive = Vec::new();
        for p in 0..planes {
            for (k, coil) in [p + 1, p + 1 + planes].into_iter().enumerate() {
                let t0 = LEAD_S + k as f64 * per_coil;
                let step = |a: f64, z: f64, v: f64| Drive {
                    coil,
                    from_s: a,
                    to_s: z,
                    volts: Some(v),
                    from_v: None,
                    to_v: None,
                };
                let mut t = t0;
                for &v in &levels {
                    drive.push(step(t, t + STEP_ON_S, v));
                    t += STEP_ON_S + STEP_OFF_S;
                }
                t += COOL_BEFORE_TOP_S - STEP_OFF_S;
                drive.push(step(t, t + TOP_ON_S, TOP_V));
            }
        }
        drive.sort_by(|a, b| a.from_s.total_cmp(&b.from_s).then(a.coil.cmp(&b.coil)));
        Self {
            name: "probe: each coil alone, a staircase 1.4–2.6 V and a 3 V pulse".into(),
            duration_s: LEAD_S + 2.0 * per_coil,
            log_interval_ms: 10,
            drive,
            hold: Vec::new(),
        }
    }
}

/// One step of a coil in the probe log.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelProbe {
    /// Input (V).
    pub volts: f64,
    /// Mean current over the step's second half (A), when logged.
    pub current_a: Option<f64>,
    /// Largest angle change from the step's start until the next drive
    /// (deg, signed).
    pub travel_deg: f64,
}

/// What the probe found on one coil.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CoilProbe {
    /// Coil, paper numbering.
    pub coil: usize,
    /// Its plane (0: θ or α, 1: β).
    pub plane: usize,
    /// Every step, lowest input first; the top pulse last.
    pub levels: Vec<LevelProbe>,
    /// Highest input with no current and lowest with one (V), when the
    /// currents are logged.
    pub current_bracket_v: Option<(f64, f64)>,
    /// The driver's turn-on (V): from the unsaturated currents (a line
    /// through two or more levels), else the middle of the bracket; None
    /// without currents.
    pub turn_on_v: Option<f64>,
    /// The lowest input from which every higher step moved the plane
    /// beyond [`MOTION_SIGMAS`] × the camera noise (V). Not serialised:
    /// heat builds up over the staircase, so the plane is still moving
    /// when the next step starts, and this came out 2.6–3 V on the
    /// off-plan twin whose drivers turn on at 2.0 and 1.6 V (README,
    /// "Probe and adapted plan").
    #[serde(skip_serializing)]
    pub motion_from_v: f64,
    /// The input the adapted plan places its levels from (V): the turn-on,
    /// or without currents one probe step (0.1 V) below where motion
    /// starts.
    pub anchor_v: f64,
    /// Input of the top pulse (V).
    pub top_v: f64,
    /// Largest travel after the top pulse (deg, signed: the coil's
    /// direction).
    pub top_travel_deg: f64,
    /// From the top pulse's start to 63 % of its travel (s): how fast the
    /// coil heats through its transformation. Not serialised, for the
    /// reason of [`motion_from_v`](Self::motion_from_v): 76 and 58 s on
    /// the off-plan twin's coils 1 and 2 against ≈ 2 s on 3 and 4.
    #[serde(skip_serializing)]
    pub rise_63_s: f64,
    /// From the peak to 37 % of the travel (s): how fast it cools back;
    /// None when the log ends first. Not serialised (see
    /// [`rise_63_s`](Self::rise_63_s)).
    #[serde(skip_serializing)]
    pub fall_37_s: Option<f64>,
}

/// The probe's analysis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ProbeReport {
    /// Angles of the joint.
    pub planes: usize,
    /// Camera noise per plane (deg, 1σ), from the frames.
    pub camera_noise_deg: Vec<f64>,
    /// Per coil, paper numbering.
    pub coils: Vec<CoilProbe>,
}

/// Why a probe log cannot be read for the plan: the column at fault and
/// what it does not tell.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("column `{column}`: {message}")]
pub struct ProbeError {
    /// The column.
    pub column: String,
    /// What it does not tell.
    pub message: String,
}

fn camera_column(planes: usize, plane: usize) -> String {
    match (planes, plane) {
        (1, _) => "cam_theta_deg".into(),
        (_, 0) => "cam_alpha_deg".into(),
        _ => "cam_beta_deg".into(),
    }
}

/// A constant input of one coil over rows `start..end`.
struct Segment {
    start: usize,
    end: usize,
    volts: f64,
}

/// The coil's constant-input runs with the other coil of its plane off.
fn segments(log: &ExcitationLog, slot: usize, other: usize) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::new();
    let mut k = 0;
    while k < log.len() {
        let v = log.volts[k][slot];
        if v <= 0.05 {
            k += 1;
            continue;
        }
        let start = k;
        while k < log.len() && (log.volts[k][slot] - v).abs() < 1e-3 {
            k += 1;
        }
        // The first and last rows may hold a partial period; the inside
        // rows carry the level.
        let alone = (start..k).all(|r| log.volts[r][other] <= 0.05);
        if alone && k - start >= 3 {
            out.push(Segment {
                start,
                end: k,
                volts: v,
            });
        }
    }
    out
}

/// Frames of `plane` with capture times in `[from, to)` (time, deg).
fn frames_between(log: &ExcitationLog, plane: usize, from: f64, to: f64) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut last = f64::NEG_INFINITY;
    for k in 0..log.len() {
        let c = log.cam_capture_s[k];
        if c >= from && c < to && c > last {
            out.push((c, log.cam_deg[k][plane]));
            last = c;
        }
    }
    out
}

/// Analyses a probe log (see the module docs); the error names the column
/// that cannot tell what the plan needs.
pub fn analyse(log: &ExcitationLog) -> Result<ProbeReport, ProbeError> {
    let planes = log.planes;
    let mut noise = Vec::new();
    for p in 0..planes {
        let n = camera_noise_floor_deg(log, p, log.len()).ok_or_else(|| ProbeError {
            column: camera_column(planes, p),
            message: "fewer than 20 camera frames: the probe needs the camera to see where the plane moves".into(),
        })?;
        // A camera without noise (a synthetic log) would make any
        // difference motion; 0.001° is below the logs' 0.1 m° resolution.
        noise.push(n.max(0.001));
    }
    let mut coils = Vec::new();
    for slot in 0..2 * planes {
        coils.push(analyse_coil(log, slot, noise[slot % planes])?);
    }
    Ok(ProbeReport {
        planes,
        camera_noise_deg: noise,
        coils,
    })
}

fn analyse_coil(log: &ExcitationLog, slot: usize, noise: f64) -> Result<CoilProbe, ProbeError> {
    let planes = log.planes;
    let plane = slot % planes;
    let other = (slot + planes) % (2 * planes);
    let coil = slot + 1;
    let cam = camera_column(planes, plane);
    let segs = segments(log, slot, other);
    if segs.len() < 2 {
        return Err(ProbeError {
            column: format!("v{coil}_v"),
            message: format!(
                "coil {coil} is driven alone at {} constant level(s); a probe log (`softjoint identify probe`) has a staircase of steps per coil",
                segs.len()
            ),
        });
    }
    // Current noise: rows where the coil has no input.
    let currents = log.current_a.as_ref();
    let i_noise = currents.map(|c| {
        let off: Vec<f64> = (0..log.len())
            .filter(|&k| log.volts[k][slot] <= 0.0)
            .map(|k| c[k][slot])
            .collect();
        super::rms(off.iter().copied())
    });
    let levels = level_probes(log, plane, slot, &segs, currents);
    if levels.iter().any(|(_, l)| l.travel_deg.is_nan()) {
        return Err(ProbeError {
            column: cam.clone(),
            message: format!("no camera frame during or before some of coil {coil}'s steps"),
        });
    }
    // The top pulse: the highest input, the last one of that input.
    let (top_seg, top) = levels
        .iter()
        .rev()
        .max_by(|a, b| a.1.volts.total_cmp(&b.1.volts))
        .map(|(s, l)| (*s, l.clone()))
        .expect("two segments or more");
    let threshold = MOTION_SIGMAS * noise;
    let mut steps: Vec<LevelProbe> = levels
        .iter()
        .filter(|(s, _)| !std::ptr::eq(*s, top_seg))
        .map(|(_, l)| l.clone())
        .collect();
    steps.sort_by(|a, b| a.volts.total_cmp(&b.volts));
    if top.travel_deg.abs() <= threshold {
        let largest = levels
            .iter()
            .map(|(_, l)| l.travel_deg.abs())
            .fold(0.0, f64::max);
        return Err(ProbeError {
            column: cam,
            message: format!(
                "the plane never moved on coil {coil}'s drives, up to {} V (largest travel {largest:.3}° against {MOTION_SIGMAS}× the camera noise, {threshold:.3}°): the probe cannot place the plan's levels; check the coil, its driver and the camera",
                plant_common::short_number(top.volts)
            ),
        });
    }
    let sign = top.travel_deg.signum();
    let moved = |l: &LevelProbe| sign * l.travel_deg > threshold;
    let mut motion_from_v = top.volts;
    for l in steps.iter().rev() {
        if moved(l) {
            motion_from_v = l.volts;
        } else {
            break;
        }
    }
    // The driver from the currents.
    let (bracket, turn_on) = driver_from_currents(coil, &steps, &top, i_noise)?;
    // Rise and fall of the top pulse's travel.
    let (rise_63_s, fall_37_s) = rise_and_fall(log, plane, &segs, top_seg, &top, sign);
    let anchor_v = turn_on.unwrap_or(motion_from_v - 0.1);
    Ok(CoilProbe {
        coil,
        plane,
        levels: steps
            .into_iter()
            .chain(std::iter::once(top.clone()))
            .collect(),
        current_bracket_v: bracket,
        turn_on_v: turn_on,
        motion_from_v,
        anchor_v,
        top_v: top.volts,
        top_travel_deg: top.travel_deg,
        rise_63_s,
        fall_37_s,
    })
}

/// Each constant level of the staircase: its input, the current over its
/// second half and the plane's largest travel from the second before it.
fn level_probes<'a>(
    log: &ExcitationLog,
    plane: usize,
    slot: usize,
    segs: &'a [Segment],
    currents: Option<&Vec<[f64; 4]>>,
) -> Vec<(&'a Segment, LevelProbe)> {
    let dt = log.period_s;
    let mut levels = Vec::new();
    for (n, s) in segs.iter().enumerate() {
        let t_on = log.t_s[s.start];
        let t_next = segs
            .get(n + 1)
            .map_or(log.t_s[log.len() - 1] + dt, |x| log.t_s[x.start]);
        let before = frames_between(log, plane, t_on - 1.0, t_on);
        let base = if before.is_empty() {
            frames_between(log, plane, t_on, t_on + 0.1)
                .first()
                .map_or(f64::NAN, |f| f.1)
        } else {
            before.iter().map(|f| f.1).sum::<f64>() / before.len() as f64
        };
        let after = frames_between(log, plane, t_on, t_next);
        let travel = after
            .iter()
            .map(|f| f.1 - base)
            .max_by(|a, b| a.abs().total_cmp(&b.abs()))
            .unwrap_or(f64::NAN);
        let current_a = currents.map(|c| {
            let half = s.start + (s.end - s.start) / 2;
            let rows = &c[half..s.end - 1];
            rows.iter().map(|r| r[slot]).sum::<f64>() / rows.len().max(1) as f64
        });
        levels.push((
            s,
            LevelProbe {
                volts: s.volts,
                current_a,
                travel_deg: travel,
            },
        ));
    }
    levels
}

/// Highest input without a current and lowest with one (V).
type Bracket = Option<(f64, f64)>;

/// The bracket of the driver's turn-on (highest input without a current,
/// lowest with one) and the turn-on itself from the staircase's currents:
/// a line through the unsaturated steps where it falls inside the bracket,
/// else the bracket's middle. `None`s without current columns.
fn driver_from_currents(
    coil: usize,
    steps: &[LevelProbe],
    top: &LevelProbe,
    i_noise: Option<f64>,
) -> Result<(Bracket, Option<f64>), ProbeError> {
    Ok(match i_noise {
        Some(n) => {
            let on_at = 3.0 * n + 0.005;
            let with: Vec<&LevelProbe> = steps
                .iter()
                .filter(|l| l.current_a.unwrap_or(0.0) > on_at)
                .collect();
            let highest_off = steps
                .iter()
                .filter(|l| l.current_a.unwrap_or(0.0) <= on_at)
                .map(|l| l.volts)
                .fold(f64::NEG_INFINITY, f64::max);
            let top_i = top.current_a.unwrap_or(0.0);
            let Some(lowest_on) = with.first().map(|l| l.volts) else {
                return Err(ProbeError {
                column: format!("i{coil}_a"),
                message: format!(
                    "coil {coil} carried no current on any step up to {} V: its driver turns on above the probe's staircase (or does not conduct)",
                    plant_common::short_number(steps.last().map_or(0.0, |l| l.volts))
                ),
            });
            };
            // Unsaturated: below 0.85 × the top pulse's (saturated) current.
            let lin: Vec<(f64, f64)> = with
                .iter()
                .filter(|l| l.current_a.unwrap_or(0.0) < 0.85 * top_i)
                .map(|l| (l.volts, l.current_a.unwrap_or(0.0)))
                .collect();
            let mid = if highest_off.is_finite() {
                0.5 * (highest_off + lowest_on)
            } else {
                lowest_on
            };
            let v_on = if lin.len() >= 2 {
                let n = lin.len() as f64;
                let (mx, my) = lin
                    .iter()
                    .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
                let sxy: f64 = lin.iter().map(|(x, y)| (x - mx) * (y - my)).sum();
                let sxx: f64 = lin.iter().map(|(x, _)| (x - mx) * (x - mx)).sum();
                let g = sxy / sxx;
                let v = mx - my / g;
                // A line that misses the bracket (a bent current curve)
                // is not trusted over the bracket itself.
                if g > 0.0 && v.is_finite() && v >= highest_off.max(0.0) - 0.05 && v <= lowest_on {
                    v
                } else {
                    mid
                }
            } else {
                mid
            };
            (
                highest_off.is_finite().then_some((highest_off, lowest_on)),
                Some(v_on),
            )
        }
        None => (None, None),
    })
}

/// Seconds to 63 % of the top pulse's travel and from its peak down to
/// 37 % (`None` when the log ends first).
fn rise_and_fall(
    log: &ExcitationLog,
    plane: usize,
    segs: &[Segment],
    top_seg: &Segment,
    top: &LevelProbe,
    sign: f64,
) -> (f64, Option<f64>) {
    let dt = log.period_s;
    let t_on = log.t_s[top_seg.start];
    let t_next = segs
        .iter()
        .find(|s| s.start > top_seg.start)
        .map_or(log.t_s[log.len() - 1] + dt, |x| log.t_s[x.start]);
    let before = frames_between(log, plane, t_on - 1.0, t_on);
    let b0 = before.iter().map(|f| f.1).sum::<f64>() / before.len().max(1) as f64;
    let after = frames_between(log, plane, t_on, t_next);
    let d: Vec<(f64, f64)> = after.iter().map(|f| (f.0, sign * (f.1 - b0))).collect();
    let peak = top.travel_deg.abs();
    let (tp, _) = d
        .iter()
        .copied()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((t_on, 0.0));
    let rise_63_s = d
        .iter()
        .find(|f| f.1 >= 0.63 * peak)
        .map_or(tp - t_on, |f| f.0 - t_on);
    let fall_37_s = d
        .iter()
        .find(|f| f.0 > tp && f.1 <= 0.37 * peak)
        .map(|f| f.0 - tp);
    (rise_63_s, fall_37_s)
}

/// Splits a drive whose peak exceeds `limit_v` into
/// [`CHOP_ON_S`] pulses [`CHOP_OFF_S`] apart (a ramp keeps its slope across
/// the pieces); others are kept whole.
pub fn chop(d: &Drive, limit_v: f64) -> Vec<Drive> {
    // 1 µV of slack: a level rounded to 10 mV at the limit is held.
    if d.peak_v() <= limit_v + 1e-6 {
        return vec![d.clone()];
    }
    let mut out = Vec::new();
    let mut t = d.from_s;
    while t < d.to_s - 1e-9 {
        let z = (t + CHOP_ON_S).min(d.to_s);
        let mut p = d.clone();
        p.from_s = t;
        p.to_s = z;
        if d.volts.is_none() {
            p.from_v = Some(d.volts_at(t));
            p.to_v = Some(d.volts_at(z));
        }
        out.push(p);
        t += CHOP_ON_S + CHOP_OFF_S;
    }
    out
}

/// The turn-on the standard plan's levels are placed from (V): the
/// default driver's (`DriverParams::default().turn_on_v`).
pub const STANDARD_ANCHOR_V: f64 = 1.7;

/// Inputs at or above this (V) are the standard plan's saturated pulses,
/// which the adapted plan keeps (3 V; raised to anchor + 0.8 V should a
/// coil turn on so high that 3 V would not saturate it).
const PULSE_V: f64 = 2.5;

/// The adapted levels lie this much higher above the turn-on than
/// the standard's above 1.7 V (V): on issue 28's twin β (turn-on 1.6 V)
/// the standard's 1.85/1.9 V levels transform the coil and its plane is
/// verified, while 1.75/1.8 V (the same distance from the turn-on as the
/// standard's from 1.7 V) left the plane within 0.2° of rest all plan
/// long (`examples/identify_probe.rs`). None (the standard's levels)
/// where the full margin would lift a level the budget allows held above
/// the budget's limit (`level_placement`).
pub const LEVEL_MARGIN_V: f64 = 0.1;

/// The standard plan's highest held level (V): its second sustained
/// level, the ramp's end and the warm antagonist, 0.2 V above 1.7 V.
const STANDARD_TOP_HELD_V: f64 = 1.9;

/// Where a coil anchored at `anchor_v` (V) has its levels placed: the
/// anchor and margin its levels are shifted by. The whole
/// [`LEVEL_MARGIN_V`] above the turn-on when the highest held level fits
/// within `limit_v` with it, or when it does not fit even without it (the
/// coil's levels are pulsed anyway, and the margin gives its pulses more
/// current). In between (turn-ons of 1.63–1.73 V under the default
/// budget), the standard plan's own levels: the design point the standard
/// plan was made and checked for. Both alternatives failed there on the
/// seeded campaign (`examples/identify_campaign.rs`, `CAMPAIGN_PLAN=adapted`):
/// a partial margin, which puts the top level at the budget's ceiling
/// (1.93 V, a 92 K peak), left three of twins 7, 11, 13 and 19's planes in
/// that band unverified and called one's convection identifiable 10.5σ
/// from the truth; no margin (levels 0.15 and 0.2 V above the turn-on)
/// called twin 120 β's convection identifiable 12.3σ off. The standard
/// plan verified all five, within their 1σ.
fn level_placement(anchor_v: f64, limit_v: f64) -> (f64, f64) {
    let top_without = STANDARD_TOP_HELD_V + anchor_v - STANDARD_ANCHOR_V;
    if top_without + LEVEL_MARGIN_V <= limit_v + 1e-6 || pulsed_from(anchor_v, limit_v) {
        (anchor_v, LEVEL_MARGIN_V)
    } else {
        (STANDARD_ANCHOR_V, 0.0)
    }
}

/// Whether a coil anchored at `anchor_v` (V) has held levels above
/// `limit_v` even without the margin: its levels are then pulsed.
fn pulsed_from(anchor_v: f64, limit_v: f64) -> bool {
    STANDARD_TOP_HELD_V + anchor_v - STANDARD_ANCHOR_V > limit_v + 1e-6
}

/// The probe's anchor of `coil` rounded to 10 mV, or the standard's.
fn coil_anchor(probe: &ProbeReport, coil: usize) -> f64 {
    probe
        .coils
        .iter()
        .find(|c| c.coil == coil)
        .map_or(STANDARD_ANCHOR_V, |c| (c.anchor_v * 100.0).round() / 100.0)
}

/// The highest input the budget allows held for a coil anchored at
/// `anchor_v` (V): its driver offset is the firmware default's, or with
/// `budget_offset_from_probe` the anchor itself.
fn sustained_limit_v(anchor_v: f64, budget_offset_from_probe: bool) -> f64 {
    let offset = if budget_offset_from_probe {
        anchor_v
    } else {
        FIRMWARE_DEFAULT_OFFSET_V
    };
    offset + BUDGET_SUSTAINED_ABOVE_OFFSET_V
}

impl ExcitationPlan {
    /// The coils of `probe` whose held levels lie above what the budget
    /// allows held even without the margin: [`adapted`](Self::adapted)
    /// pulses them (some or all of their levels, and their saturated
    /// pulses cut to 1 s).
    pub fn pulsed_coils(probe: &ProbeReport, budget_offset_from_probe: bool) -> Vec<usize> {
        probe
            .coils
            .iter()
            .map(|c| c.coil)
            .filter(|&coil| {
                let a = coil_anchor(probe, coil);
                pulsed_from(a, sustained_limit_v(a, budget_offset_from_probe))
            })
            .collect()
    }

    /// The standard plan (without holds) with each coil's levels moved by
    /// its probe anchor's distance from [`STANDARD_ANCHOR_V`]: sustained
    /// levels at anchor + 0.15 and + 0.2 V, the ramp from the anchor to
    /// anchor + 0.2 V, the co-contraction's warm antagonist at anchor +
    /// 0.2 V — so each coil is driven through its unsaturated range,
    /// partly transforming, wherever its driver turns on. Levels are
    /// rounded to 10 mV, and lie [`LEVEL_MARGIN_V`] further above the
    /// turn-on than the standard's above 1.7 V — but where the margin
    /// would push a level the budget allows held past its limit, the coil
    /// keeps the standard plan's levels (a coil that turns on at 1.7 V
    /// gets the standard's 1.85 and 1.9 V, not 1.95 and 2.0 V pulsed:
    /// never a pulsed level where the standard plan holds one; see
    /// `level_placement`).
    /// A level above what the
    /// budget allows sustained ([`BUDGET_SUSTAINED_ABOVE_OFFSET_V`] above
    /// the budget's driver offset) is chopped into 1 s pulses 2 s apart
    /// ([`chop`]), its distance above the turn-on multiplied by √3 first,
    /// so that the pulses (duty 1/3, current ∝ input above the turn-on
    /// below the driver's cap) put into the coil the mean power the held
    /// level would have: pulsed at the held level itself, issue 28's twin
    /// α barely moved (0.19°) and was not identified. The budget's offset is the firmware default's (1.7 V)
    /// unless `budget_offset_from_probe`, when it is each coil's probe
    /// anchor: the board's driver offset must then be set to it, or its
    /// supervisor trips on the plan.
    pub fn adapted(
        planes: usize,
        duration_s: f64,
        probe: &ProbeReport,
        budget_offset_from_probe: bool,
    ) -> Self {
        let base = Self::standard(planes, duration_s, false);
        let anchor = |coil: usize| coil_anchor(probe, coil);
        let shift = |v: f64, a: f64, margin: f64| {
            if v >= PULSE_V {
                v.max(a + 0.8).min(5.0)
            } else {
                // Rounded to 10 mV: the standard's levels are exact in TOML.
                ((v + a + margin - STANDARD_ANCHOR_V) * 100.0).round() / 100.0
            }
        };
        let pulsed = Self::pulsed_coils(probe, budget_offset_from_probe);
        let mut drive = Vec::new();
        for d in &base.drive {
            let a = anchor(d.coil);
            let limit = sustained_limit_v(a, budget_offset_from_probe);
            let (a, margin) = level_placement(a, limit);
            let mut m = d.clone();
            m.volts = d.volts.map(|v| shift(v, a, margin));
            m.from_v = d.from_v.map(|v| shift(v, a, margin));
            m.to_v = d.to_v.map(|v| shift(v, a, margin));
            if m.peak_v() > limit + 1e-6 && m.peak_v() < PULSE_V {
                // Pulsed at duty d, the level's distance above the
                // turn-on grows by 1/√d: the same mean power as held.
                let k = ((CHOP_ON_S + CHOP_OFF_S) / CHOP_ON_S).sqrt();
                let up = |v: f64| (((a + (v - a) * k) * 100.0).round() / 100.0).min(5.0);
                m.volts = m.volts.map(up);
                m.from_v = m.from_v.map(up);
                m.to_v = m.to_v.map(up);
            }
            if d.peak_v() < PULSE_V || pulsed.contains(&d.coil) {
                // A pulsed coil's saturated pulses (1–2.5 s) are cut to
                // 1 s too: kept whole, the off-plan twin's α ended in a
                // wrong basin (fit rms 0.238° against 0.049° of noise,
                // unverified); cut, it was verified within 1.4σ
                // (`examples/identify_probe.rs`).
                drive.extend(chop(&m, limit));
            } else {
                drive.push(m);
            }
        }
        let anchors: Vec<String> = probe
            .coils
            .iter()
            .map(|c| format!("coil {} {:.2} V", c.coil, anchor(c.coil)))
            .collect();
        Self {
            name: format!(
                "adapted excitation, {} s, levels from the probe's turn-ons ({})",
                plant_common::short_number(duration_s),
                anchors.join(", ")
            ),
            duration_s,
            log_interval_ms: base.log_interval_ms,
            drive,
            hold: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::{twin, ElectricalNoise};

    /// Steps below any driver's turn-on: the plane cannot move, and the
    /// analysis says so by the camera column instead of placing levels.
    #[test]
    fn a_probe_without_motion_names_the_camera_column() {
        let step = |coil: usize, a: f64, v: f64| Drive {
            coil,
            from_s: a,
            to_s: a + 1.5,
            volts: Some(v),
            from_v: None,
            to_v: None,
        };
        let plan = ExcitationPlan {
            name: "too low".into(),
            duration_s: 14.0,
            log_interval_ms: 10,
            drive: vec![
                step(1, 2.0, 1.0),
                step(1, 5.0, 1.2),
                step(2, 8.0, 1.0),
                step(2, 11.0, 1.2),
            ],
            hold: Vec::new(),
        };
        let noise = ElectricalNoise {
            current_a: 0.002,
            resistance_ohm: 0.02,
        };
        let log = twin::record_2d(&crate::Joint2dParams::default(), &plan, true, noise).unwrap();
        let e = analyse(&log).unwrap_err();
        assert_eq!(e.column, "cam_theta_deg", "{e}");
        assert!(e.message.contains("never moved"), "{e}");
    }

    /// A coil that turns on at the default 1.7 V keeps every level held:
    /// instead of the margin, which would pulse 1.95 and 2.0 V, it gets the
    /// standard plan itself.
    #[test]
    fn a_default_turn_on_keeps_its_levels_held() {
        let coil = |c: usize| CoilProbe {
            coil: c,
            plane: (c - 1) % 2,
            levels: Vec::new(),
            current_bracket_v: Some((1.7, 1.8)),
            turn_on_v: Some(1.7),
            motion_from_v: 2.0,
            anchor_v: 1.7,
            top_v: 3.0,
            top_travel_deg: -23.0,
            rise_63_s: 1.0,
            fall_37_s: None,
        };
        let probe = ProbeReport {
            planes: 2,
            camera_noise_deg: vec![0.05; 2],
            coils: (1..=4).map(coil).collect(),
        };
        let a = ExcitationPlan::adapted(2, 240.0, &probe, false);
        let s = ExcitationPlan::standard(2, 240.0, false);
        assert_eq!(a.drive, s.drive);
        // The whole margin where it fits (1.5, 1.63 V) or where the
        // levels are pulsed anyway (from 1.74 V); the standard's levels
        // in between.
        for (anchor, placed) in [
            (1.5, (1.5, 0.1)),
            (1.63, (1.63, 0.1)),
            (1.64, (1.7, 0.0)),
            (1.73, (1.7, 0.0)),
            (1.74, (1.74, 0.1)),
            (2.0, (2.0, 0.1)),
        ] {
            assert_eq!(level_placement(anchor, 1.93), placed, "anchor {anchor} V");
        }
    }

    /// The standard plan is what the adapted plan gives for a probe that
    /// found the default turn-on, but for the margin.
    #[test]
    fn adapted_levels_follow_the_anchor() {
        let coil = |c: usize, a: f64| CoilProbe {
            coil: c,
            plane: (c - 1) % 2,
            levels: Vec::new(),
            current_bracket_v: None,
            turn_on_v: Some(a),
            motion_from_v: a + 0.5,
            anchor_v: a,
            top_v: 3.0,
            top_travel_deg: 10.0,
            rise_63_s: 1.0,
            fall_37_s: None,
        };
        let probe = ProbeReport {
            planes: 2,
            camera_noise_deg: vec![0.05; 2],
            coils: vec![coil(1, 1.6), coil(2, 1.6), coil(3, 1.6), coil(4, 1.6)],
        };
        let a = ExcitationPlan::adapted(2, 240.0, &probe, false);
        let s = ExcitationPlan::standard(2, 240.0, false);
        assert_eq!(a.drive.len(), s.drive.len());
        for (x, y) in a.drive.iter().zip(&s.drive) {
            assert_eq!(x.volts, y.volts, "{x:?} {y:?}");
            assert_eq!(x.from_s, y.from_s);
        }
    }
}
