//! Running the joint: the firmware core in closed loop with the simulated
//! joint (through `hal-sim`), every row to a sink, the summary a user
//! reads. `hil` runs the same loop ([`run_loop`]) with a board as the
//! controller.

use std::time::Instant;

use hal_sim::{ClosedLoop, Controller, CoreController, LoopError, Plant};

use crate::run::joint::{CoreLoopTask, SimJoint};
use crate::run::record::{Row, Trace};
use crate::run::schedule::RunSchedule;
use crate::run::spec::RunSpec;
use crate::run::summary::{CutCause, CutShort, RunCutShort, Summary, SummaryBuilder};
use crate::run::trace::{NoRows, RowSink};
use crate::stop::{Stop, StopSignal};

/// What one run produced.
pub struct RunOutput {
    /// The summary.
    pub summary: Summary,
    /// The time series.
    pub trace: Trace,
}

/// Runs `spec` to completion, keeping the time series.
pub fn run(spec: &RunSpec) -> anyhow::Result<RunOutput> {
    run_with(spec, true)
}

/// Runs `spec` to completion with the firmware core in process; the time
/// series is kept only with `keep_trace` (otherwise `trace.rows` is
/// empty). The summary is the same either way: it is accumulated row by row
/// ([`SummaryBuilder`]). A run that ends early is an error here
/// ([`RunCutShort`]); [`run_into`] returns its summary instead.
pub fn run_with(spec: &RunSpec, keep_trace: bool) -> anyhow::Result<RunOutput> {
    let mut rows = Vec::new();
    let (stop, progress) = (Stop::never(), indicatif::ProgressBar::hidden());
    let summary = if keep_trace {
        run_into(spec, &mut rows, &stop, &progress)?
    } else {
        run_into(spec, &mut NoRows, &stop, &progress)?
    };
    if let Some(cut) = summary.cut_short {
        return Err(RunCutShort(cut).into());
    }
    Ok(RunOutput {
        trace: Trace {
            planes: spec.planes(),
            rows,
        },
        summary,
    })
}

/// Runs `spec` with the firmware core in process, every row to `sink`,
/// until its end, a failure or `stop`. Errors are what prevents the run
/// from starting; a run that ends early returns its summary with
/// [`Summary::cut_short`] set.
pub fn run_into(
    spec: &RunSpec,
    sink: &mut impl RowSink,
    stop: &Stop,
    progress: &indicatif::ProgressBar,
) -> anyhow::Result<Summary> {
    let ctx = RunContext { stop, progress };
    spec.core_loop(InProcess { spec, sink, ctx })
}

/// [`run_loop`] on the core in process.
struct InProcess<'a, K> {
    spec: &'a RunSpec,
    sink: &'a mut K,
    ctx: RunContext<'a>,
}

impl<K: RowSink> CoreLoopTask for InProcess<'_, K> {
    type Output = Summary;

    fn run<Pl, const P: usize, const S: usize, const C: usize>(
        self,
        cl: &mut ClosedLoop<Pl, CoreController<P, S>, P, S, C>,
    ) -> anyhow::Result<Summary>
    where
        Pl: Plant<P, S, C> + SimJoint,
    {
        Ok(run_loop(self.spec, cl, self.sink, &self.ctx))
    }
}

/// What a run reads besides its specification: the stop flag and the progress
/// bar (hidden unless a person watches).
pub struct RunContext<'a> {
    /// Set by SIGINT/SIGTERM/SIGHUP (or a caller).
    pub stop: &'a Stop,
    /// Advanced every few thousand steps.
    pub progress: &'a indicatif::ProgressBar,
}

/// Why [`ClosedLoop::run`] stopped before its last step.
enum Cut<E: std::error::Error + 'static> {
    Loop(LoopError<E>),
    Sink(anyhow::Error),
    Stop(StopSignal),
}

impl<E: std::error::Error + 'static> From<LoopError<E>> for Cut<E> {
    fn from(e: LoopError<E>) -> Self {
        Cut::Loop(e)
    }
}

/// Steps between progress-bar updates.
const PROGRESS_EVERY: u64 = 4096;

/// Runs `spec` through a closed loop — the firmware core in process, or a
/// board behind a link (`hil`): the one run of the joint. Targets and
/// disturbances come from the run ([`RunSchedule`]); every period
/// gives one [`Row`] to the summary and to `sink`. The run ends at its last
/// step, or early when the loop fails (plant, controller), `sink` fails or
/// `ctx.stop` is set; the summary then says where and why
/// ([`Summary::cut_short`]), and `sink` holds every row up to there.
pub fn run_loop<Pl, Ctl, const P: usize, const S: usize, const C: usize>(
    spec: &RunSpec,
    cl: &mut ClosedLoop<Pl, Ctl, P, S, C>,
    sink: &mut impl RowSink,
    ctx: &RunContext,
) -> Summary
where
    Pl: Plant<P, S, C>,
    Ctl: Controller<P, S>,
{
    let steps = spec.steps();
    let mut stats = SummaryBuilder::new(spec);
    let mut faults_seen = 0u16;
    let mut peak_temp = [f64::NEG_INFINITY; C];
    let mut schedule = RunSchedule::new(spec);
    ctx.progress.set_length(steps);
    let started = Instant::now();
    let result = cl.run(
        steps,
        &mut schedule,
        |sample| -> Result<(), Cut<Ctl::Error>> {
            faults_seen |= sample.faults;
            for (p, c) in peak_temp.iter_mut().zip(sample.coil_temperatures_c) {
                *p = p.max(c);
            }
            let row = Row::of_sample(sample);
            stats.push(&row);
            sink.row(&row).map_err(Cut::Sink)?;
            let done = stats.rows();
            if done % PROGRESS_EVERY == 0 {
                ctx.progress.set_position(done);
            }
            match ctx.stop.requested() {
                Some(signal) if done < steps => Err(Cut::Stop(signal)),
                _ => Ok(()),
            }
        },
    );
    let wall = started.elapsed().as_secs_f64();
    ctx.progress.set_position(stats.rows());
    let at_step = stats.rows();
    let at_t_s = at_step as f64 * spec.period_s();
    let cut_short = result.err().map(|cut| {
        let (cause, reason, signal) = match cut {
            Cut::Loop(LoopError::Plant { error, .. }) => {
                (CutCause::Plant, format!("plant: {error}"), None)
            }
            Cut::Loop(LoopError::Controller { error, .. }) => {
                (CutCause::Controller, format!("controller: {error}"), None)
            }
            Cut::Loop(e @ LoopError::Period(_)) => (CutCause::Controller, e.to_string(), None),
            Cut::Sink(e) => (CutCause::Output, format!("{e:#}"), None),
            Cut::Stop(sig) => (
                CutCause::Signal,
                format!("stopped by {}", sig.name()),
                Some(sig),
            ),
        };
        CutShort {
            at_step,
            at_t_s,
            cause,
            reason,
            signal,
        }
    });
    // A run cut short before its first row has no peak temperature (the
    // −∞ it starts from is no number a summary may carry).
    let peaks = if stats.rows() == 0 {
        Vec::new()
    } else {
        peak_temp.to_vec()
    };
    let mut summary = stats.finish(spec, wall, faults_seen, peaks);
    summary.cut_short = cut_short;
    summary
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::scenario::{EstimatorMethod, Scenario, TargetStep};
    use crate::run::summary::Segment;

    /// The segment statistics as a pass over the stored rows (the form the
    /// running [`SummaryBuilder`] replaced).
    fn segments_from_rows(s: &Scenario, trace: &Trace) -> Vec<Segment> {
        let end = s.duration_s;
        let mut out = Vec::new();
        let mut prev_target: Option<Vec<f64>> = None;
        for (i, t) in s.targets.iter().enumerate() {
            let from = t.t_s;
            let to = s.targets.get(i + 1).map(|n| n.t_s).unwrap_or(end).min(end);
            if to <= from {
                continue;
            }
            let rows: Vec<&Row> = trace
                .rows
                .iter()
                .filter(|r| r.t_s >= from && r.t_s < to)
                .collect();
            if rows.is_empty() {
                continue;
            }
            let tail_from = to - 0.2 * (to - from);
            let tail: Vec<&&Row> = rows.iter().filter(|r| r.t_s >= tail_from).collect();
            let planes = t.deg.len();
            let sse = (0..planes)
                .map(|p| {
                    let mean =
                        tail.iter().map(|r| r.true_deg[p]).sum::<f64>() / tail.len().max(1) as f64;
                    (mean - t.deg[p]).abs()
                })
                .collect();
            let overshoot = (0..planes)
                .map(|p| {
                    let start = prev_target
                        .as_ref()
                        .map(|v| v[p])
                        .unwrap_or(rows[0].true_deg[p]);
                    let dir = (t.deg[p] - start).signum();
                    if dir == 0.0 {
                        return 0.0;
                    }
                    rows.iter()
                        .map(|r| dir * (r.true_deg[p] - t.deg[p]))
                        .fold(0.0, f64::max)
                })
                .collect();
            out.push(Segment {
                from_s: from,
                to_s: to,
                desired_deg: t.deg.clone(),
                steady_state_error_deg: sse,
                overshoot_deg: overshoot,
                complete: true,
            });
            prev_target = Some(t.deg.clone());
        }
        out
    }

    #[test]
    fn running_summary_equals_the_pass_over_the_rows() {
        let mut s = Scenario {
            duration_s: 6.0,
            ..Scenario::default()
        };
        s.estimator.method = EstimatorMethod::Paper;
        // Up, down (overshoot the other way), an empty segment past the end.
        s.targets = [(0.0, 0.0), (1.0, 6.0), (3.5, -4.0), (9.0, 1.0)]
            .map(|(t_s, d)| TargetStep {
                t_s,
                deg: vec![d, -d],
            })
            .to_vec();
        let spec = RunSpec::resolve(&s).unwrap();
        let kept = run(&spec).unwrap();
        assert_eq!(kept.trace.rows.len(), 6000);
        let want = segments_from_rows(&s, &kept.trace);
        assert_eq!(want.len(), 3);
        assert_eq!(kept.summary.segments, want);
        let mut b = SummaryBuilder::new(&spec);
        for r in &kept.trace.rows {
            b.push(r);
        }
        assert_eq!(b.segments(), want);
        let again = b.finish(&spec, 1.0, 0, vec![]);
        assert_eq!(again.segments, want);
        assert_eq!(
            again.max_estimation_error_deg,
            kept.summary.max_estimation_error_deg
        );
        // Without the trace: the same summary, no rows.
        let lean = run_with(&spec, false).unwrap();
        assert!(lean.trace.rows.is_empty());
        let strip = |mut m: Summary| {
            m.wall_seconds = 0.0;
            m.realtime_factor = 0.0;
            m
        };
        assert_eq!(strip(lean.summary), strip(kept.summary));
    }
}
