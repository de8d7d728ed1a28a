//! The summary of a run, accumulated one row at a time, and how a run that
//! ended early says so.
use firmware::supervisor::Faults;
use serde::Serialize;

use crate::run::record::Row;
use crate::run::spec::RunSpec;
use crate::run::trace::TraceFileReport;
use crate::stop::StopSignal;

/// Steady-state error of one target segment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Segment {
    /// Segment start (s).
    pub from_s: f64,
    /// Segment end (s).
    pub to_s: f64,
    /// Desired angles (deg).
    pub desired_deg: Vec<f64>,
    /// |mean true angle − desired| over the last 20 % of the segment (deg).
    pub steady_state_error_deg: Vec<f64>,
    /// Largest excursion beyond the target in the direction of travel (deg).
    pub overshoot_deg: Vec<f64>,
    /// Whether the run reached the segment's end. For a segment it did
    /// not (a run cut short), `steady_state_error_deg` is the error at its
    /// last row when no row of its last 20 % ran, and the summary's
    /// worst-case figures leave it out.
    pub complete: bool,
}

/// The summary of a run (also the `--json` output).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// Scenario name.
    pub scenario: String,
    /// "2d" or "3d".
    pub joint: String,
    /// Names of the controlled angles.
    pub angles: Vec<String>,
    /// Worst steady-state error over the target segments, per angle (deg).
    pub steady_state_error_deg: Vec<f64>,
    /// Largest |estimate − true| over the run, per angle (deg).
    pub max_estimation_error_deg: Vec<f64>,
    /// Per-segment details.
    pub segments: Vec<Segment>,
    /// Simulated seconds.
    pub sim_seconds: f64,
    /// Wall-clock seconds of the closed loop.
    pub wall_seconds: f64,
    /// sim_seconds / wall_seconds.
    pub realtime_factor: f64,
    /// Control steps.
    pub steps: u64,
    /// Every fault seen during the run.
    pub faults_seen: Vec<String>,
    /// Estimation method and its source.
    pub estimator: String,
    /// Peak modelled coil temperature (°C), per coil.
    pub peak_coil_temperature_c: Vec<f64>,
    /// Control steps the scenario asked for (`steps` is fewer when the run
    /// was cut short).
    pub planned_steps: u64,
    /// Where and why the run ended early; absent when it ran to the end.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cut_short: Option<CutShort>,
    /// The streamed CSV trace, if one was written: its rows and whether
    /// they are the whole run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub trace: Option<TraceFileReport>,
}

/// Why a run ended before its last step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CutCause {
    /// The plant refused a step (instability, a load it cannot take).
    Plant,
    /// The controller failed: for `hil` the board, its link or its
    /// emulator.
    Controller,
    /// A trace file could not be written.
    Output,
    /// SIGINT, SIGTERM or SIGHUP.
    Signal,
}

/// Where and why a run ended early.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CutShort {
    /// The step that did not complete (= steps completed; 0-based).
    pub at_step: u64,
    /// Its time (s).
    pub at_t_s: f64,
    /// What kind of reason.
    pub cause: CutCause,
    /// The reason, for a person.
    pub reason: String,
    /// The signal, when one stopped the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub signal: Option<StopSignal>,
}

impl std::fmt::Display for CutShort {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "run cut short at step {} (t = {:.3} s): {}",
            self.at_step, self.at_t_s, self.reason
        )
    }
}

/// A run that ended early, as an error: the summary and trace are written
/// first; the program then exits with [`RunCutShort::exit_code`].
#[derive(Clone, Debug, thiserror::Error)]
#[error("{0}")]
pub struct RunCutShort(pub CutShort);

impl RunCutShort {
    /// 128 + the signal for a stop by signal (130 for SIGINT), else 1.
    pub fn exit_code(&self) -> u8 {
        self.0.signal.map_or(1, StopSignal::exit_code)
    }
}

/// Names of the set bits of a fault word.
pub fn fault_names(bits: u16) -> Vec<String> {
    Faults::NAMED
        .iter()
        .filter(|(f, _)| Faults::from_bits(bits).contains(*f))
        .map(|(_, n)| (*n).to_string())
        .collect()
}

/// The neutral element of `Iterator::sum` for `f64` (−0.0 in current Rust,
/// +0.0 in older), so running sums match a `sum()` over the same values.
fn sum_start() -> f64 {
    core::iter::empty::<f64>().sum()
}

/// Running statistics of one target segment (see [`SummaryBuilder`]).
#[derive(Clone, Debug)]
struct SegmentStats {
    from_s: f64,
    to_s: f64,
    /// Start of the last 20 % of the segment.
    tail_from_s: f64,
    desired_deg: Vec<f64>,
    rows: u64,
    first_true_deg: [f64; 2],
    last_true_deg: [f64; 2],
    tail_sum_deg: [f64; 2],
    tail_rows: usize,
    /// Running max (from 0) of `true − desired`: the overshoot if the
    /// segment moves upwards.
    above_deg: [f64; 2],
    /// Running max (from 0) of `−(true − desired)`: the overshoot if it
    /// moves downwards.
    below_deg: [f64; 2],
}

/// The run summary accumulated one row at a time, so a run need not keep
/// its time series to be summarised. Each statistic sees the same values
/// in the same order as a pass over the stored rows would (sums start from
/// `sum()`'s neutral element, maxima from 0), so the figures are identical.
#[derive(Clone, Debug)]
pub struct SummaryBuilder {
    planes: usize,
    rows: u64,
    max_estimation_error_deg: [f64; 2],
    segments: Vec<SegmentStats>,
    /// First segment that has not ended at the last row's time: targets are
    /// validated in time order, so segments are ordered and disjoint and
    /// each row belongs to this one or to none.
    cursor: usize,
    /// Time of the last row (s); −∞ before the first.
    last_t_s: f64,
    /// Control period (s).
    period_s: f64,
    /// Control steps the run is planned to take: a run that took them all
    /// completed every segment, even the last when the duration is not a
    /// whole number of periods.
    planned_steps: u64,
}

impl SummaryBuilder {
    /// Nothing seen yet, for the run `spec`.
    pub fn new(spec: &RunSpec) -> Self {
        let end = spec.duration_s;
        let targets = &spec.targets;
        let segments = targets
            .iter()
            .enumerate()
            .filter_map(|(i, t)| {
                let from = t.t_s;
                let to = targets.get(i + 1).map(|n| n.t_s).unwrap_or(end).min(end);
                (to > from).then(|| SegmentStats {
                    from_s: from,
                    to_s: to,
                    tail_from_s: to - 0.2 * (to - from),
                    desired_deg: t.deg.clone(),
                    rows: 0,
                    first_true_deg: [0.0; 2],
                    last_true_deg: [0.0; 2],
                    tail_sum_deg: [sum_start(); 2],
                    tail_rows: 0,
                    above_deg: [0.0; 2],
                    below_deg: [0.0; 2],
                })
            })
            .collect();
        Self {
            planes: spec.planes(),
            rows: 0,
            max_estimation_error_deg: [0.0; 2],
            segments,
            cursor: 0,
            last_t_s: f64::NEG_INFINITY,
            period_s: spec.period_s(),
            planned_steps: spec.steps(),
        }
    }

    /// Rows seen so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Adds one control period's row; rows come in time order.
    #[inline]
    pub fn push(&mut self, r: &Row) {
        self.rows += 1;
        self.last_t_s = r.t_s;
        for (p, m) in self
            .max_estimation_error_deg
            .iter_mut()
            .enumerate()
            .take(self.planes)
        {
            let e = (r.estimate_deg[p] - r.true_deg[p]).abs();
            if e.is_finite() {
                *m = m.max(e);
            }
        }
        while self
            .segments
            .get(self.cursor)
            .is_some_and(|g| r.t_s >= g.to_s)
        {
            self.cursor += 1;
        }
        if let Some(g) = self.segments.get_mut(self.cursor) {
            if r.t_s < g.from_s {
                return;
            }
            if g.rows == 0 {
                g.first_true_deg = r.true_deg;
            }
            g.rows += 1;
            g.last_true_deg = r.true_deg;
            let tail = r.t_s >= g.tail_from_s;
            if tail {
                g.tail_rows += 1;
            }
            for (p, d) in g.desired_deg.iter().enumerate() {
                let x = r.true_deg[p];
                if tail {
                    g.tail_sum_deg[p] += x;
                }
                let e = x - d;
                g.above_deg[p] = g.above_deg[p].max(e);
                g.below_deg[p] = g.below_deg[p].max(-e);
            }
        }
    }

    /// The target segments that saw rows, measured: steady-state error over
    /// the last 20 %, overshoot in the direction of travel from the previous
    /// segment's target (the first from its first true angle).
    pub fn segments(&self) -> Vec<Segment> {
        let mut out = Vec::new();
        let mut prev_target: Option<&[f64]> = None;
        for g in self.segments.iter().filter(|g| g.rows > 0) {
            let planes = g.desired_deg.len();
            // Rows of a segment: those with from ≤ t < to, one per period.
            let complete =
                self.rows >= self.planned_steps || self.last_t_s + self.period_s >= g.to_s - 1e-9;
            let sse = (0..planes)
                .map(|p| {
                    let at = if g.tail_rows == 0 && !complete {
                        g.last_true_deg[p]
                    } else {
                        g.tail_sum_deg[p] / g.tail_rows.max(1) as f64
                    };
                    (at - g.desired_deg[p]).abs()
                })
                .collect();
            let overshoot = (0..planes)
                .map(|p| {
                    let start = prev_target.map(|v| v[p]).unwrap_or(g.first_true_deg[p]);
                    let dir = (g.desired_deg[p] - start).signum();
                    if dir == 1.0 {
                        g.above_deg[p]
                    } else if dir == -1.0 {
                        g.below_deg[p]
                    } else {
                        // 0 or NaN: no direction of travel.
                        0.0
                    }
                })
                .collect();
            out.push(Segment {
                from_s: g.from_s,
                to_s: g.to_s,
                desired_deg: g.desired_deg.clone(),
                steady_state_error_deg: sse,
                overshoot_deg: overshoot,
                complete,
            });
            prev_target = Some(&g.desired_deg);
        }
        out
    }

    /// The summary of the rows seen, for the run `spec`: `wall_seconds`
    /// of wall time, the union of the fault words, each coil's peak
    /// temperature.
    pub fn finish(
        &self,
        spec: &RunSpec,
        wall_seconds: f64,
        faults_seen: u16,
        peak_coil_temperature_c: Vec<f64>,
    ) -> Summary {
        let planes = self.planes;
        let segments = self.segments();
        let sse: Vec<f64> = (0..planes)
            .map(|p| {
                segments
                    .iter()
                    .filter(|g| g.complete)
                    .map(|g| g.steady_state_error_deg[p])
                    .fold(0.0, f64::max)
            })
            .collect();
        let sim_seconds = self.rows as f64 * spec.period_s();
        Summary {
            scenario: spec.name.clone(),
            joint: spec.joint.label().into(),
            angles: spec
                .joint
                .angle_names()
                .iter()
                .map(|n| n.to_string())
                .collect(),
            steady_state_error_deg: sse,
            max_estimation_error_deg: self.max_estimation_error_deg[..planes].to_vec(),
            segments,
            sim_seconds,
            wall_seconds,
            // (No wall time means no step ran: 0, not ∞, which no result
            // may carry.)
            realtime_factor: if wall_seconds > 0.0 {
                sim_seconds / wall_seconds
            } else {
                0.0
            },
            steps: self.rows,
            faults_seen: fault_names(faults_seen),
            estimator: spec.estimator.clone(),
            peak_coil_temperature_c,
            planned_steps: spec.steps(),
            cut_short: None,
            trace: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::scenario::{EstimatorMethod, Scenario, TargetStep};

    /// A run whose duration is not a whole number of periods (6.0004 s at
    /// 1 ms: 6000 steps) completes its last segment: the headline counts
    /// it. It once called the segment cut short and left it out.
    #[test]
    fn the_last_segment_of_a_whole_run_counts_in_the_headline() {
        let mut s = Scenario {
            duration_s: 6.0004,
            ..Scenario::default()
        };
        s.estimator.method = EstimatorMethod::Paper;
        s.targets = [(0.0, 0.0), (3.0, 5.0)]
            .map(|(t_s, d)| TargetStep {
                t_s,
                deg: vec![d, d],
            })
            .to_vec();
        let spec = RunSpec::resolve(&s).unwrap();
        assert_eq!(spec.steps(), 6000);
        let mut b = SummaryBuilder::new(&spec);
        for k in 0..spec.steps() {
            let t_s = k as f64 * 1e-3;
            // 1° short of the second target throughout its segment.
            let angle = if t_s < 3.0 { 0.0 } else { 4.0 };
            b.push(&Row {
                t_s,
                true_deg: [angle; 2],
                estimate_deg: [angle; 2],
                desired_deg: [0.0; 2],
                coil_volts: [0.0; 4],
                faults: 0,
            });
        }
        let summary = b.finish(&spec, 1.0, 0, vec![]);
        assert!(summary.segments.iter().all(|g| g.complete));
        assert_eq!(summary.steady_state_error_deg, vec![1.0, 1.0]);
    }
}
