//! Hardware-in-the-loop in lockstep: the host owns time and the plant; the
//! board (the firmware image under QEMU, or a real board) runs the control
//! step. The run is `softjoint sim`'s own closed loop ([`sim::run_loop`])
//! with a [`BoardController`] in place of the core in process. See
//! ARCHITECTURE.md.

use std::time::{Duration, Instant};

use anyhow::bail;
use firmware::joint::JointConfig;
use hal_sim::ClosedLoop;
use serde::Serialize;

use crate::board::controller::{BoardController, LockstepSetup};
use crate::board::link::{HostLinkStats, Link, Port};
use crate::files::scenario::FeedbackKind;
use crate::files::JointKind;
use crate::run::record::Trace;
use crate::run::sim::{self, RunContext};
use crate::run::spec::RunSpec;
use crate::run::summary::{CutCause, RunCutShort, Summary};
use crate::run::trace::RowSink;
use crate::stop::Stop;

pub use crate::board::controller::{handshake, status};

/// Lockstep settings.
#[derive(Clone, Copy, Debug)]
pub struct HilOptions {
    /// Wait for each reply (per attempt).
    pub timeout: Duration,
    /// Attempts per step before giving up.
    pub attempts: u32,
    /// Fault injection: lose the first transmission of every Nth sensor
    /// frame (the retry must recover it).
    pub lose_every: Option<u32>,
    /// Link-loss timeout to configure on the board (ms); `None` keeps the
    /// board's own (50 ms by default).
    pub link_timeout_ms: Option<u16>,
    /// Set a board that restarts mid-run up again and go on (see
    /// [`LockstepSetup::resume_after_restart`]); otherwise the run ends
    /// there.
    pub resume_after_restart: bool,
}

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            timeout: Duration::from_millis(100),
            attempts: 20,
            lose_every: None,
            link_timeout_ms: None,
            resume_after_restart: false,
        }
    }
}

/// What a HIL run reports beyond the simulation summary.
#[derive(Clone, Debug, Serialize)]
pub struct HilReport {
    /// The same summary as `softjoint sim`.
    #[serde(flatten)]
    pub summary: Summary,
    /// Host-side link counters.
    pub link: HostLinkStats,
    /// The board's own counters at the end.
    pub board_frames_ok: u32,
    /// Board: CRC errors.
    pub board_crc_errors: u16,
    /// Board: COBS errors.
    pub board_cobs_errors: u16,
    /// Board: oversized frames.
    pub board_overfull: u16,
    /// Board: malformed frames.
    pub board_malformed: u16,
    /// Board: late lockstep frames ignored.
    pub board_stale_seqs: u16,
    /// Lockstep steps per wall-clock second.
    pub lockstep_steps_per_s: f64,
    /// Times the board restarted and was set up again.
    pub board_restarts: u32,
    /// Whether the board's counters above were read at the end (not when
    /// the link had failed).
    pub board_counters_read: bool,
}

/// A finished HIL run.
pub struct HilOutput {
    /// Report (summary + link statistics).
    pub report: HilReport,
    /// Time series, same columns as `sim`.
    pub trace: Trace,
}

/// Runs a 3D wire-feedback run in lockstep with the board on `link`,
/// keeping the time series; a run that ends early is an error
/// ([`RunCutShort`]).
pub fn run<P: Port>(
    spec: &RunSpec,
    link: &mut Link<P>,
    opts: HilOptions,
) -> anyhow::Result<HilOutput> {
    let mut rows = Vec::new();
    let ctx = RunContext {
        stop: &Stop::never(),
        progress: &indicatif::ProgressBar::hidden(),
    };
    let report = run_into(spec, link, opts, &mut rows, &ctx)?;
    if let Some(cut) = report.summary.cut_short.clone() {
        return Err(RunCutShort(cut).into());
    }
    Ok(HilOutput {
        report,
        trace: Trace { planes: 2, rows },
    })
}

/// Runs a 3D wire-feedback run in lockstep with the board on `link`,
/// every row to `sink`. Errors are what prevents the run from starting
/// (the joint, the board's setup); a run that ends early (the board,
/// its link, the plant, `ctx.stop`) returns its report with
/// `summary.cut_short` set.
pub fn run_into<P: Port>(
    spec: &RunSpec,
    link: &mut Link<P>,
    opts: HilOptions,
    sink: &mut impl RowSink,
    ctx: &RunContext,
) -> anyhow::Result<HilReport> {
    let setup = lockstep_setup(spec, &opts)?;
    let plant = spec.joint.plant_3d()?;
    let board = BoardController::start(link, setup)?;
    let mut cl = ClosedLoop::new(plant, board, spec.period_us())?;
    let started = Instant::now();
    let summary = sim::run_loop(spec, &mut cl, sink, ctx);
    let wall = started.elapsed().as_secs_f64();
    let mut board = cl.controller;
    let stats = board.link().stats();
    let restarts = board.restarts();
    let steps = board.steps();
    // A board whose link failed is not asked for anything more (each
    // request would wait out its retries on a dead line).
    let link_failed = summary
        .cut_short
        .as_ref()
        .is_some_and(|c| c.cause == CutCause::Controller);
    let status = if link_failed {
        None
    } else {
        Some(board.finish()?)
    };
    let counter = |f: fn(&firmware::protocol::Status) -> u16| status.as_ref().map_or(0, f);
    Ok(HilReport {
        summary,
        link: stats,
        board_frames_ok: status.as_ref().map_or(0, |s| s.frames_ok),
        board_crc_errors: counter(|s| s.crc_errors),
        board_cobs_errors: counter(|s| s.cobs_errors),
        board_overfull: counter(|s| s.overfull),
        board_malformed: counter(|s| s.malformed),
        board_stale_seqs: counter(|s| s.stale_seqs),
        // (No wall time means no step ran: 0, not ∞, which no result may
        // carry.)
        lockstep_steps_per_s: if wall > 0.0 { steps as f64 / wall } else { 0.0 },
        board_restarts: restarts,
        board_counters_read: status.is_some(),
    })
}

/// The board's lockstep setup for the run `spec` (3D, wire feedback): its
/// gains and estimation laws.
pub fn lockstep_setup(spec: &RunSpec, opts: &HilOptions) -> anyhow::Result<LockstepSetup> {
    if spec.joint.kind() != JointKind::ThreeD || spec.feedback != FeedbackKind::Wire {
        bail!("hardware-in-the-loop runs the 3D joint with wire-sensor feedback (the board's sensor frame carries wire counts)");
    }
    let paper = JointConfig::paper_3d();
    let laws = spec.controller.laws.as_deref().unwrap_or(&paper.laws);
    let gains = spec.controller.gains.as_deref().unwrap_or(&paper.gains);
    if laws.len() != 2 || gains.len() != 2 {
        bail!("the 3D joint has two planes");
    }
    let setup = LockstepSetup {
        period_us: spec.period_us(),
        gains: [gains[0], gains[1]],
        laws: [laws[0], laws[1]],
        link_timeout_ms: opts.link_timeout_ms,
        timeout: opts.timeout,
        attempts: opts.attempts,
        lose_every: opts.lose_every,
        resume_after_restart: opts.resume_after_restart,
    };
    Ok(setup)
}
