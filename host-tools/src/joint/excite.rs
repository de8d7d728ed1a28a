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

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Context};
use firmware::control::DriverConfig;
use firmware::supervisor::ThermalConfig;
use hal_sim::{ClosedLoop, Controller, Plant, Schedule};
use plant_joint::identify::{
    log::columns, ElectricalNoise, ExcitationLog, ExcitationPlan, LogRecorder,
};
use plant_joint::PlantError;
use serde::Serialize;

use crate::output::check_number;
use crate::run::joint::{CoreLoopTask, SimJoint};
use crate::run::spec::RunSpec;
use crate::run::summary::{fault_names, CutCause, CutShort, RunCutShort};
use crate::run::trace::RowFile;
use crate::stop::{Stop, StopSignal};

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
                    plant_common::short_number(d.peak_v()),
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
    /// Simulated seconds the log covers (the plan's, unless stopped early).
    pub duration_s: f64,
    /// Seconds the plan asked for.
    pub planned_s: f64,
    /// Supervisor faults seen (the board's own; drives bypass its outputs).
    pub faults_seen: Vec<String>,
    /// Peak coil temperature of the simulated joint (°C).
    pub peak_coil_temperature_c: f64,
    /// Largest modelled rise of the firmware's budget over the drives (K).
    pub budget_peak_rise_k: f64,
    /// The signal that stopped the session before the plan's end (its log
    /// then holds the rows up to there), if one did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stopped_by: Option<StopSignal>,
}

/// Where a session's log rows go as they complete: a file streamed as the
/// session runs ([`LogFile`]) or a log kept in memory (tests, library
/// callers that compare logs).
pub trait LogSink {
    /// Takes the next rows of the session (`piece`'s row times go on from
    /// the rows taken before).
    fn rows(&mut self, piece: ExcitationLog) -> anyhow::Result<()>;
}

impl LogSink for ExcitationLog {
    fn rows(&mut self, piece: ExcitationLog) -> anyhow::Result<()> {
        self.append(piece);
        Ok(())
    }
}

/// A session's log written as it is recorded (the columns and decimals of
/// [`log_csv`], each value checked finite first): memory stays flat
/// however long the plan, and a session that ends early — a signal, a
/// failed link — leaves its rows on disk up to its last whole row.
///
/// A `sim`/`hil` session's log ([`LogFile::create`]) is, like the run
/// trace, written straight to its path as the rows come. A board
/// session's ([`LogFile::create_board`]) streams into a temporary file
/// beside its path that [`LogFile::finish`] renames over it
/// (`run::trace::RowFile::create_atomic`): a session that records no row
/// leaves the previous log as it was. Not covered: a `softjoint` killed
/// with SIGKILL leaves that temporary file (`.NAME.PID-N.tmp`, the rows
/// up to its last block) instead of the log.
pub struct LogFile {
    rows: RowFile,
    cols: Vec<String>,
    places: Vec<usize>,
}

impl LogFile {
    /// Creates (or truncates) `path` and writes the header of a log with
    /// `planes` angles (and the electrical columns if `electrical`): a path
    /// that cannot be written is refused before the session.
    pub fn create(path: &Path, planes: usize, electrical: bool) -> anyhow::Result<Self> {
        let cols = columns(planes, electrical);
        let places = cols.iter().map(|c| log_decimals(c)).collect();
        let rows = RowFile::create(path, &format!("{}\n", cols.join(",")))?;
        Ok(Self { rows, cols, places })
    }

    /// Opens `path` for a board session's log (the columns of
    /// [`board_log_csv`]): the rows go to a temporary file beside it as
    /// they come, renamed over it by [`finish`](Self::finish); dropped
    /// unfinished, the log leaves `path` as it was. A path that cannot be
    /// written is refused here, before the board moves.
    pub fn create_board(path: &Path) -> anyhow::Result<Self> {
        let mut cols = columns(2, false);
        let places = cols.iter().map(|c| log_decimals(c)).collect();
        cols.extend(BOARD_COLUMNS.map(String::from));
        let rows = RowFile::create_atomic(path, &format!("{}\n", cols.join(",")))?;
        Ok(Self { rows, cols, places })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        self.rows.path()
    }

    /// Writes what is waiting and returns the rows in the file (a board
    /// session's log: renamed over its path).
    pub fn finish(self) -> anyhow::Result<u64> {
        self.rows.finish()
    }

    /// Appends one row: `r` in the log's columns, then (a board log) the
    /// board's estimates (NaN: none, an empty field) and fault byte. Every
    /// value is checked before any is written: a refused row leaves
    /// nothing of itself.
    fn push(&mut self, r: &[f64], board: Option<([f64; 2], u8)>) -> anyhow::Result<()> {
        let (cols, places) = (&self.cols, &self.places);
        self.rows.row(|s, path, line| {
            for (v, c) in r.iter().zip(cols) {
                check_number(path, line, || c.clone(), *v)?;
            }
            if let Some((estimate_deg, _)) = board {
                for (e, c) in estimate_deg.iter().zip(BOARD_COLUMNS) {
                    if !e.is_nan() {
                        check_number(path, line, || c.to_string(), *e)?;
                    }
                }
            }
            for (i, (v, d)) in r.iter().zip(places).enumerate() {
                if i > 0 {
                    s.push(',');
                }
                let _ = write!(s, "{v:.d$}", d = *d);
            }
            if let Some((e, faults)) = board {
                let _ = write!(
                    s,
                    ",{},{},{faults}",
                    crate::output::estimate_field(e[0], 3),
                    crate::output::estimate_field(e[1], 3)
                );
            }
            s.push('\n');
            Ok::<(), crate::output::NonFinite>(())
        })
    }
}

impl LogSink for LogFile {
    fn rows(&mut self, piece: ExcitationLog) -> anyhow::Result<()> {
        for k in 0..piece.len() {
            self.push(&piece.row(k), None)?;
        }
        self.rows.write_if_due()
    }
}

impl BoardLogSink for LogFile {
    fn board_row(&mut self, row: &BoardRow) -> anyhow::Result<()> {
        self.push(&row.log_fields(), Some((row.estimate_deg, row.faults)))?;
        self.rows.write_if_due()
    }
}

/// Decimals of a log column (ms times, 0.1 mV, 0.1 m°, µm, 10 µA, 0.1 mΩ).
fn log_decimals(name: &str) -> usize {
    if name == "t_s" || name == "cam_capture_s" || name.starts_with('d') {
        3
    } else if name.starts_with('i') {
        5
    } else {
        4
    }
}

/// Runs `plan` through `cl`, handing `sink` the log's rows as they
/// complete. `stop` is read every control period: a stop request ends the
/// session there (the rows recorded up to it handed on, a partial last row
/// dropped) and the summary says which signal. A failure mid-session hands
/// on the whole rows recorded before it, then returns the error.
pub fn run_loop<Pl, Ctl, const P: usize, const S: usize, const C: usize>(
    plan: &ExcitationPlan,
    cl: &mut ClosedLoop<Pl, Ctl, P, S, C>,
    electrical: bool,
    seed: u64,
    sink: &mut dyn LogSink,
    stop: &Stop,
) -> anyhow::Result<SessionSummary>
where
    Pl: Plant<P, S, C> + SimJoint,
    Ctl: Controller<P, S>,
{
    let budget = check_budget(plan)?;
    let period_s = cl.period_s();
    let per_row = ((f64::from(plan.log_interval_ms) * 1e-3 / period_s).round() as usize).max(1);
    let rng = plant_common::rng::stream(seed, plant_common::rng::IDENTIFY_NOISE);
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
    let mut rows = 0usize;
    let mut stopped_by = None;
    let mut ran = Ok(());
    let mut last_piece = std::time::Instant::now();
    for _ in 0..steps {
        if let Some(signal) = stop.requested() {
            stopped_by = Some(signal);
            break;
        }
        let obs = cl.plant.observation();
        let mut sample = None;
        ran = cl.run(1, &mut schedule, |x| -> anyhow::Result<()> {
            sample = Some(*x);
            Ok(())
        });
        let Some(x) = sample.filter(|_| ran.is_ok()) else {
            ran = ran.and_then(|()| Err(anyhow::anyhow!("the loop ran no period")));
            break;
        };
        faults |= x.faults;
        for t in x.coil_temperatures_c {
            peak = peak.max(t);
        }
        rec.push(&obs, &x.coil_volts, &cl.plant.currents_a()[..C]);
        let due = rec.complete_rows() >= LOG_PIECE_ROWS
            || (rec.complete_rows() > 0 && last_piece.elapsed() >= PIECE_INTERVAL);
        if due {
            last_piece = std::time::Instant::now();
            let piece = rec.take_rows();
            rows += piece.len();
            sink.rows(piece)?;
        }
    }
    // On a failure, the whole rows before it (its partial row dropped).
    let last = if ran.is_ok() {
        rec.finish()
    } else {
        rec.take_rows()
    };
    rows += last.len();
    sink.rows(last)?;
    ran?;
    let dt = f64::from(plan.log_interval_ms) * 1e-3;
    Ok(SessionSummary {
        plan: plan.name.clone(),
        rows,
        duration_s: if stopped_by.is_some() {
            rows as f64 * dt
        } else {
            plan.duration_s
        },
        planned_s: plan.duration_s,
        faults_seen: fault_names(faults),
        peak_coil_temperature_c: peak,
        budget_peak_rise_k: budget,
        stopped_by,
    })
}

/// Rows a session keeps before handing them to its sink (≈ 100 kB) …
const LOG_PIECE_ROWS: usize = 512;
/// … or the longest it keeps them (a slow lockstep session's rows reach
/// the file at least this often).
const PIECE_INTERVAL: std::time::Duration = std::time::Duration::from_secs(1);

/// Runs `plan` on the simulated joint of the run `spec` (its joint kind,
/// seed, plant file and gains) under the core in process, the log's rows
/// to `sink` as they complete; `stop` ends it early.
pub fn run_sim(
    plan: &ExcitationPlan,
    spec: &RunSpec,
    electrical: bool,
    sink: &mut dyn LogSink,
    stop: &Stop,
) -> anyhow::Result<SessionSummary> {
    spec.core_loop(Session {
        plan,
        electrical,
        seed: spec.seed(),
        sink,
        stop,
    })
}

/// [`run_loop`] on the core in process.
struct Session<'a> {
    plan: &'a ExcitationPlan,
    electrical: bool,
    seed: u64,
    sink: &'a mut dyn LogSink,
    stop: &'a Stop,
}

impl CoreLoopTask for Session<'_> {
    type Output = SessionSummary;

    fn run<Pl, const P: usize, const S: usize, const C: usize>(
        self,
        cl: &mut ClosedLoop<Pl, hal_sim::CoreController<P, S>, P, S, C>,
    ) -> anyhow::Result<Self::Output>
    where
        Pl: Plant<P, S, C> + SimJoint,
    {
        run_loop(
            self.plan,
            cl,
            self.electrical,
            self.seed,
            self.sink,
            self.stop,
        )
    }
}

/// The log as CSV text (fixed decimals: ms times, 0.1 mV, 0.1 m°, µm,
/// 10 µA, 0.1 mΩ).
pub fn log_csv(log: &ExcitationLog) -> String {
    let (cols, rows) = log.to_rows();
    let mut out = cols.join(",");
    out.push('\n');
    let places: Vec<usize> = cols.iter().map(|c| log_decimals(c)).collect();
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

/// The columns a board session's log has beyond [`log_csv`]'s.
const BOARD_COLUMNS: [&str; 3] = ["est_alpha_deg", "est_beta_deg", "faults"];

/// A board session's log as CSV, formatted whole: the columns of
/// [`log_csv`] (what `identify joint` reads) and the board's estimates and
/// fault byte (`est_alpha_deg`, `est_beta_deg`, `faults`; an estimate is
/// empty where the board had none). `console excite` streams the same
/// text row by row ([`LogFile::create_board`]); this is the form for a
/// [`BoardLog`] kept in memory.
pub fn board_log_csv(log: &ExcitationLog, extras: &BoardExtras) -> String {
    let base = log_csv(log);
    let mut out = String::with_capacity(base.len() * 5 / 4);
    for (k, line) in base.lines().enumerate() {
        out.push_str(line);
        match k.checked_sub(1) {
            None => out.push_str(&format!(",{}", BOARD_COLUMNS.join(","))),
            Some(r) => {
                let e = extras.estimate_deg.get(r).copied().unwrap_or([f64::NAN; 2]);
                out.push_str(&format!(
                    ",{},{},{}",
                    crate::output::estimate_field(e[0], 3),
                    crate::output::estimate_field(e[1], 3),
                    extras.faults.get(r).copied().unwrap_or(0)
                ));
            }
        }
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
    log_from_text(&text, &path.display().to_string(), false)
}

/// Rows between two board estimates used as angle frames (every 3rd row
/// of a 10 ms log: 33 frames/s, about the camera's 30, so the angle
/// residuals keep the weight the camera's would have).
pub const ESTIMATE_FRAME_ROWS: usize = 3;

/// The log in `text` (named `name` in errors); with `board_estimates`,
/// its camera columns replaced by the board's own wire-based estimates
/// (columns `est_alpha_deg`, `est_beta_deg` of a `console excite` log, one
/// frame every [`ESTIMATE_FRAME_ROWS`] rows; refused for a log that has
/// camera frames). What `identify joint` fits, and what a Ray worker
/// running its units rebuilds from the same text.
pub fn log_from_text(
    text: &str,
    name: &str,
    board_estimates: bool,
) -> anyhow::Result<ExcitationLog> {
    let table = plant_common::csv_input::read_numeric(text, name)?;
    let mut log = ExcitationLog::from_table(&table)?;
    if board_estimates {
        if log.cam_capture_s.iter().any(|c| *c >= 0.0) {
            anyhow::bail!(
                "{name}: the log has camera frames; --angles board-estimate is for a log without a camera (`console excite`)"
            );
        }
        let names = ["est_alpha_deg", "est_beta_deg"];
        let mut cols = Vec::new();
        for col in names.iter().take(log.planes) {
            cols.push(table.values(table.column(col)?));
        }
        for (k, (cap, deg)) in log
            .cam_capture_s
            .iter_mut()
            .zip(log.cam_deg.iter_mut())
            .enumerate()
        {
            let frame = k - k % ESTIMATE_FRAME_ROWS;
            *cap = log.t_s[frame];
            for (d, col) in deg.iter_mut().zip(&cols) {
                *d = col[frame];
            }
        }
    }
    Ok(log)
}

/// Column names of a log (for help texts).
pub fn log_columns(planes: usize) -> String {
    columns(planes, true).join(",")
}

/// Runs `plan` in lockstep with the board on `link` (the 3D joint of
/// the run `spec`, wire feedback): the board's controller holds, the host
/// forces the drives onto the simulated coils. The log's rows go to
/// `sink` as they complete; `stop` ends the session early (the board still
/// leaves lockstep).
pub fn run_hil<Po: crate::board::link::Port>(
    plan: &ExcitationPlan,
    spec: &RunSpec,
    link: &mut crate::board::link::Link<Po>,
    opts: crate::board::hil::HilOptions,
    electrical: bool,
    sink: &mut dyn LogSink,
    stop: &Stop,
) -> anyhow::Result<SessionSummary> {
    let setup = crate::board::hil::lockstep_setup(spec, &opts)?;
    let plant = spec.joint.plant_3d()?;
    let board = crate::board::controller::BoardController::start(link, setup)?;
    let mut cl = ClosedLoop::new(plant, board, spec.period_us())?;
    let out = run_loop(plan, &mut cl, electrical, spec.seed(), sink, stop)?;
    // Stopped early or not, the board leaves lockstep.
    cl.controller.finish()?;
    Ok(out)
}

/// How long one `Drive` of a board session holds (ms of the board's
/// clock): a session refreshes every log interval, so this is the longest
/// a coil stays heated after the host stops talking (a crash, an unplugged
/// cable) before the board unpowers it.
pub const BOARD_DRIVE_HOLD_MS: u16 = 250;

/// One row of a board session's log: row `k` at `t_s = k·Δ` of the
/// board's clock, its wires and the board's estimates and faults from
/// frame k, its driver inputs from frame k+1 (see [`BoardRecorder`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoardRow {
    /// Row time from the session's first frame (s).
    pub t_s: f64,
    /// Driver input per coil over the row's interval (V), coils 1–4.
    pub volts: [f64; 4],
    /// Wire insertions (mm), sensors 1–4.
    pub wire_mm: [f64; 4],
    /// The board's estimates (α, β) (deg; NaN: none yet).
    pub estimate_deg: [f64; 2],
    /// The board's fault byte.
    pub faults: u8,
}

impl BoardRow {
    /// The row in the columns of a 3D log without electrical columns
    /// (`identify::log::columns(2, false)`): no camera (capture time −1).
    fn log_fields(&self) -> [f64; 12] {
        let [v1, v2, v3, v4] = self.volts;
        let [d1, d2, d3, d4] = self.wire_mm;
        [self.t_s, v1, v2, v3, v4, -1.0, 0.0, 0.0, d1, d2, d3, d4]
    }
}

/// Where a board session's rows go as they complete: its log file
/// ([`LogFile::create_board`], what `console excite` writes) or a
/// [`BoardLog`] in memory.
pub trait BoardLogSink {
    /// Takes the session's next row; an error ends the session there (the
    /// board disarmed, the rows taken before kept).
    fn board_row(&mut self, row: &BoardRow) -> anyhow::Result<()>;
}

/// What a board session recorded besides the log: the board's own angle
/// estimates and fault flags per row.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BoardExtras {
    /// The board's estimates (α, β) per row (deg).
    pub estimate_deg: Vec<[f64; 2]>,
    /// The board's fault byte per row.
    pub faults: Vec<u8>,
}

/// A board session's rows kept in memory (tests, library callers that
/// compare logs); [`board_log_csv`] formats it.
#[derive(Clone, Debug, PartialEq)]
pub struct BoardLog {
    /// The log rows.
    pub log: ExcitationLog,
    /// The board's estimates and faults per row.
    pub extras: BoardExtras,
}

impl BoardLog {
    /// Empty, for a session of `plan` (its rows every `log_interval_ms`).
    pub fn new(plan: &ExcitationPlan) -> Self {
        Self {
            log: ExcitationLog {
                planes: 2,
                period_s: f64::from(plan.log_interval_ms) * 1e-3,
                ..Default::default()
            },
            extras: BoardExtras::default(),
        }
    }
}

impl BoardLogSink for BoardLog {
    fn board_row(&mut self, row: &BoardRow) -> anyhow::Result<()> {
        self.log.t_s.push(row.t_s);
        self.log.volts.push(row.volts);
        self.log.cam_capture_s.push(-1.0);
        self.log.cam_deg.push([0.0; 2]);
        self.log.wire_mm.push(row.wire_mm);
        self.extras.estimate_deg.push(row.estimate_deg);
        self.extras.faults.push(row.faults);
        Ok(())
    }
}

/// A summary of a session recorded on a board.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BoardSessionSummary {
    /// The plan's name.
    pub plan: String,
    /// Log rows written.
    pub rows: usize,
    /// Seconds of the plan the rows cover.
    pub recorded_s: f64,
    /// Seconds the plan asked for.
    pub planned_s: f64,
    /// Rows whose telemetry frame did not arrive (filled with the previous
    /// row's values).
    pub rows_filled: usize,
    /// Fault flags the board reported during the session.
    pub faults_seen: Vec<String>,
    /// Highest input of each coil the board reported (mV, coils 1–4).
    pub peak_coil_mv: [u16; 4],
    /// Why the session ended before the plan did, if it did.
    pub ended_early: Option<String>,
}

/// How a board session ended (its rows went to its sink as they came,
/// up to where it stopped).
pub struct BoardRun {
    /// The summary.
    pub summary: BoardSessionSummary,
    /// Why the session failed or was stopped (`None`: the plan ran to its
    /// end and the board was disarmed).
    pub error: Option<anyhow::Error>,
}

/// Builds the log from telemetry frames, handing each row to its sink as
/// soon as it is known: it keeps one frame, not the session. Row k is at
/// `k·Δ` of the board's clock from the first frame; its wires and
/// estimates are frame k's, its driver inputs frame k+1's: the board
/// reports the inputs it has set, and those of frame k+1 are the ones the
/// host's commands for interval k set (sent on frame k's arrival), so they
/// held over `[t_k, t_(k+1))` up to the link's latency.
struct BoardRecorder<'s> {
    interval_ms: u32,
    max_rows: usize,
    t0_ms: Option<u32>,
    /// Frames taken (arrived or filled).
    frames: usize,
    /// The last of them.
    last: Option<firmware::protocol::Telemetry>,
    /// Rows handed to `sink`.
    rows: usize,
    filled: usize,
    /// Fault flags and peak coil inputs over every frame taken.
    faults: u16,
    peak_mv: [u16; 4],
    coder: firmware::estimate::PulseCoder,
    sink: &'s mut dyn BoardLogSink,
}

impl<'s> BoardRecorder<'s> {
    /// A recorder of `max_rows` rows every `interval_ms`, handing them to
    /// `sink`.
    fn new(interval_ms: u32, max_rows: usize, sink: &'s mut dyn BoardLogSink) -> Self {
        Self {
            interval_ms,
            max_rows,
            t0_ms: None,
            frames: 0,
            last: None,
            rows: 0,
            filled: 0,
            faults: 0,
            peak_mv: [0; 4],
            coder: firmware::estimate::PulseCoder::default(),
            sink,
        }
    }

    /// Takes a frame; returns its row index, or `None` for a frame that
    /// repeats a row already taken. An error names a frame without a
    /// sensor reading, or is the sink's.
    fn push(&mut self, t: &firmware::protocol::Telemetry) -> anyhow::Result<Option<usize>> {
        let t0 = *self.t0_ms.get_or_insert(t.time_ms);
        let rel = t.time_ms.wrapping_sub(t0);
        let k = ((rel + self.interval_ms / 2) / self.interval_ms) as usize;
        if k < self.frames {
            return Ok(None);
        }
        if let Some(s) = t.counts.iter().position(|c| *c == i32::MIN) {
            bail!(
                "wire sensor {} gave no reading at board time {} ms: a log needs every wire",
                s + 1,
                t.time_ms
            );
        }
        while self.frames < k {
            // A frame that did not arrive: hold the previous one.
            let last = self.last.context("no first frame")?;
            self.take(last)?;
            self.filled += 1;
        }
        self.take(*t)?;
        Ok(Some(k))
    }

    /// Takes the next frame: the previous frame's row is now known (up to
    /// the plan's rows) and goes to the sink.
    fn take(&mut self, next: firmware::protocol::Telemetry) -> anyhow::Result<()> {
        if let Some(now) = self.last.filter(|_| self.rows < self.max_rows) {
            self.sink.board_row(&BoardRow {
                t_s: self.rows as f64 * f64::from(self.interval_ms) * 1e-3,
                volts: next.coil_mv.map(firmware::protocol::millivolts_to_volts),
                wire_mm: now.counts.map(|c| f64::from(self.coder.insertion_mm(c))),
                estimate_deg: now.estimate_deg.map(f64::from),
                faults: now.faults,
            })?;
            self.rows += 1;
        }
        self.faults |= u16::from(next.faults);
        for (p, v) in self.peak_mv.iter_mut().zip(next.coil_mv) {
            *p = (*p).max(v);
        }
        self.last = Some(next);
        self.frames += 1;
        Ok(())
    }

    fn done(&self) -> bool {
        self.frames > self.max_rows
    }
}

/// Runs `plan` on a board in free-running mode over `link`: open-loop
/// drives with `Drive` (refreshed every log interval, each holding
/// [`BOARD_DRIVE_HOLD_MS`]), holds with `SetTarget`, paced by the board's
/// telemetry (one frame per log interval: the host answers each frame
/// with the commands for the interval it starts). The board's supervisor
/// has the last word: a refused command (a coil over its thermal budget,
/// a latched fault) ends the session by name. Each row goes to `sink` as
/// soon as it is known (memory stays flat however long the plan). The
/// board is disarmed at the end, on an error and when `stop` is asked;
/// the rows up to there are the sink's either way.
pub fn run_board<Po: crate::board::link::Port>(
    plan: &ExcitationPlan,
    link: &mut crate::board::link::Link<Po>,
    stop: &crate::stop::Stop,
    sink: &mut dyn BoardLogSink,
) -> BoardRun {
    let max_rows = (plan.duration_s * 1e3 / f64::from(plan.log_interval_ms)).round() as usize;
    let mut rec = BoardRecorder::new(plan.log_interval_ms, max_rows, sink);
    let result = drive_board(plan, link, stop, &mut rec);
    // Outputs off whatever happened; a failure here is reported too.
    let off = link
        .command(
            &firmware::protocol::Disarm {}.into(),
            crate::board::controller::CMD_TIMEOUT,
            crate::board::controller::CMD_ATTEMPTS,
        )
        .and_then(|()| {
            link.command(
                &firmware::protocol::SetTelemetry { rate_hz: 0 }.into(),
                crate::board::controller::CMD_TIMEOUT,
                crate::board::controller::CMD_ATTEMPTS,
            )
        });
    let error = match (result, off) {
        (Ok(()), Ok(())) => None,
        (Err(e), _) => Some(e),
        (Ok(()), Err(e)) => Some(anyhow::Error::new(e).context("disarming the board at the end")),
    };
    let dt = f64::from(plan.log_interval_ms) * 1e-3;
    let summary = BoardSessionSummary {
        plan: plan.name.clone(),
        rows: rec.rows,
        recorded_s: rec.rows as f64 * dt,
        planned_s: plan.duration_s,
        rows_filled: rec.filled,
        faults_seen: fault_names(rec.faults),
        peak_coil_mv: rec.peak_mv,
        ended_early: error.as_ref().map(|e| format!("{e:#}")),
    };
    BoardRun { summary, error }
}

/// The commands of interval `[t, t + Δ)`: a `Drive` for the planes not
/// held, a `SetTarget` for a plane whose hold begins or changes.
fn send_interval<Po: crate::board::link::Port>(
    plan: &ExcitationPlan,
    link: &mut crate::board::link::Link<Po>,
    t_s: f64,
    targets: &mut [Option<f64>; 2],
) -> anyhow::Result<()> {
    use crate::board::controller::{CMD_ATTEMPTS, CMD_TIMEOUT};
    use firmware::protocol::{Drive, SetTarget};
    let dt = f64::from(plan.log_interval_ms) * 1e-3;
    // A ramp's mean over the interval is its midpoint value.
    let volts = plan.volts_at(2, t_s + 0.5 * dt);
    let driver = DriverConfig::default();
    let mut planes = 0u8;
    let mut coil_mv = [0u16; 4];
    for (p, target) in targets.iter_mut().enumerate() {
        match plan.held(p, t_s) {
            Some(deg) => {
                if *target != Some(deg) {
                    link.command(
                        &SetTarget {
                            plane: p as u8,
                            target_deg: deg as f32,
                        }
                        .into(),
                        CMD_TIMEOUT,
                        CMD_ATTEMPTS,
                    )
                    .with_context(|| format!("holding plane {p} at {deg}° from t = {t_s:.2} s"))?;
                    *target = Some(deg);
                }
            }
            None => {
                *target = None;
                planes |= 1 << p;
                for c in [false, true].map(|ant| firmware::joint::coil_index(2, p, ant)) {
                    let v = volts[c].unwrap_or(0.0) as f32;
                    coil_mv[c] = firmware::protocol::coil_to_mv(driver.clamp(v), &driver);
                }
            }
        }
    }
    if planes != 0 {
        link.command(
            &Drive {
                planes,
                coil_mv,
                hold_ms: BOARD_DRIVE_HOLD_MS,
            }
            .into(),
            CMD_TIMEOUT,
            CMD_ATTEMPTS,
        )
        .with_context(|| {
            format!(
                "driving coils 1–4 at {} mV from t = {t_s:.2} s",
                coil_mv.map(|m| m.to_string()).join("/")
            )
        })?;
    }
    Ok(())
}

fn drive_board<Po: crate::board::link::Port>(
    plan: &ExcitationPlan,
    link: &mut crate::board::link::Link<Po>,
    stop: &crate::stop::Stop,
    rec: &mut BoardRecorder<'_>,
) -> anyhow::Result<()> {
    use crate::board::controller::{CMD_ATTEMPTS, CMD_TIMEOUT};
    use firmware::protocol::{Arm, ClearFaults, HilStop, Message, SetTelemetry};
    if 1000 % plan.log_interval_ms != 0 {
        bail!(
            "`log_interval_ms` = {} does not divide 1000: the board streams telemetry at a whole rate in Hz, one frame per row",
            plan.log_interval_ms
        );
    }
    crate::board::controller::handshake(link)?;
    let cmd = |link: &mut crate::board::link::Link<Po>, m: Message| {
        link.command(&m, CMD_TIMEOUT, CMD_ATTEMPTS)
    };
    if crate::board::controller::status(link)?.mode != 0 {
        cmd(link, HilStop {}.into()).context("leaving lockstep mode")?;
    }
    cmd(link, ClearFaults {}.into()).context("clearing the board's faults before the session")?;
    cmd(link, Arm {}.into())?;
    let mut targets = [None; 2];
    send_interval(plan, link, 0.0, &mut targets)?;
    let start_ms = crate::board::controller::status(link)?.time_ms;
    cmd(
        link,
        SetTelemetry {
            rate_hz: (1000 / plan.log_interval_ms) as u16,
        }
        .into(),
    )?;
    let dt = f64::from(plan.log_interval_ms) * 1e-3;
    let quiet = std::time::Duration::from_millis(u64::from(plan.log_interval_ms) * 20 + 500);
    let mut last_row = None;
    while !rec.done() {
        if let Some(signal) = stop.requested() {
            // Exits as the signal would (130 for SIGINT), after the log.
            let at_t_s = rec.frames.saturating_sub(1) as f64 * dt;
            return Err(RunCutShort(CutShort {
                at_step: rec.frames.saturating_sub(1) as u64,
                at_t_s,
                cause: CutCause::Signal,
                reason: format!(
                    "stopped by {} at t = {at_t_s:.2} s of the plan",
                    signal.name()
                ),
                signal: Some(signal),
            })
            .into());
        }
        let deadline = crate::board::link::deadline_after(quiet);
        let Some(m) = link.recv_until(deadline)? else {
            bail!(
                "the board's telemetry stopped at t = {:.2} s of the plan (nothing for {} ms)",
                rec.frames as f64 * dt,
                quiet.as_millis()
            );
        };
        let Message::Telemetry(t) = m else { continue };
        if (t.time_ms.wrapping_sub(start_ms) as i32) < 0 {
            // A frame of an earlier stream, still on the line.
            continue;
        }
        let Some(k) = rec.push(&t)? else { continue };
        if last_row == Some(k) {
            continue;
        }
        last_row = Some(k);
        if !rec.done() {
            send_interval(plan, link, k as f64 * dt, &mut targets)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::protocol::Telemetry;

    /// Frame `k` of a made-up 10 ms stream: inputs, counts and estimates
    /// that differ from frame to frame (no estimate in the first three).
    fn frame(k: u32) -> Telemetry {
        let i = k as i32;
        Telemetry {
            time_ms: 5_000 + 10 * k,
            estimate_deg: if k < 3 {
                [f32::NAN; 2]
            } else {
                [0.01 * k as f32, -0.02 * k as f32]
            },
            coil_mv: [(k % 3000) as u16, 1900, (7 * k % 5000) as u16, 0],
            counts: [1000 + i, 2000 - i, 3000 + 2 * i, 4000],
            faults: u8::from(k == 700),
        }
    }

    /// Feeds `frames` (frame 500 lost on the way) to a recorder of 1,000
    /// rows into `sink`; returns (rows, filled).
    fn feed(sink: &mut dyn BoardLogSink, frames: u32) -> (usize, usize) {
        let mut rec = BoardRecorder::new(10, 1000, sink);
        for k in (0..frames).filter(|k| *k != 500) {
            rec.push(&frame(k)).unwrap();
        }
        (rec.rows, rec.filled)
    }

    /// The temporary files beside `dir`'s log.
    fn temporaries(dir: &Path) -> Vec<std::path::PathBuf> {
        std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "tmp"))
            .collect()
    }

    /// `console excite` kept a board session's whole log in memory and
    /// wrote it at the end. Now each row goes to the log's temporary file
    /// as it is known (the recorder keeps one frame): most rows are on disk
    /// while the session runs, the previous log is untouched until the
    /// end, and the file renamed over it is the whole log formatted at
    /// once (`board_log_csv`, the writer it replaces). A session dropped
    /// with no end leaves the previous log and no temporary file.
    #[test]
    fn a_board_sessions_rows_reach_the_disk_as_they_come_and_replace_the_log_at_the_end() {
        let scratch = tempfile::tempdir().unwrap();
        let dir = scratch.path();
        let path = dir.join("board.csv");
        std::fs::write(&path, "the previous log\n").unwrap();

        let mut file = LogFile::create_board(&path).unwrap();
        // 801 frames: 800 rows, ≈ 95 kB, more than one 64 kB block.
        assert_eq!(feed(&mut file, 801), (800, 1));
        let temps = temporaries(dir);
        assert_eq!(temps.len(), 1, "{temps:?}");
        let on_disk = std::fs::read_to_string(&temps[0]).unwrap().lines().count();
        assert!(
            on_disk > 400,
            "{on_disk} lines on disk before the end of the session"
        );
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "the previous log\n"
        );
        assert_eq!(file.finish().unwrap(), 800);
        assert!(temporaries(dir).is_empty());

        let plan: ExcitationPlan =
            toml::from_str("name = \"n\"\nduration_s = 10.0\nlog_interval_ms = 10\n").unwrap();
        let mut whole = BoardLog::new(&plan);
        feed(&mut whole, 801);
        let text = std::fs::read_to_string(&path).unwrap();
        assert_eq!(text, board_log_csv(&whole.log, &whole.extras));
        // Row k: frame k's wires and estimates, frame k+1's inputs; the
        // lost frame 500 holds frame 499: row 500 has row 499's wires and
        // estimates, and row 499 frame 499's inputs (as row 498).
        let coder = firmware::estimate::PulseCoder::default();
        let line = |k: usize| text.lines().nth(k + 1).unwrap().to_string();
        let fields = |k: usize| line(k).split(',').map(str::to_string).collect::<Vec<_>>();
        let f = fields(10);
        assert_eq!(f[0], "0.100");
        assert_eq!(f[1], "0.0110"); // frame 11's 11 mV
        let d1 = f64::from(coder.insertion_mm(1010));
        assert_eq!(f[8], format!("{d1:.3}"));
        assert_eq!(fields(0)[12], ""); // no estimate yet
        assert_eq!(f[12], format!("{:.3}", f64::from(0.01 * 10f32)));
        assert_eq!(fields(499)[5..], fields(500)[5..]);
        assert_ne!(fields(498)[8], fields(499)[8]);
        assert_eq!(fields(498)[1], "0.4990");
        assert_eq!(fields(499)[1], "0.4990");
        assert_eq!(fields(500)[1], "0.5010");
        assert_eq!(fields(700)[14], "1");

        // A session dropped before its end: the previous log stays.
        let mut file = LogFile::create_board(&path).unwrap();
        feed(&mut file, 801);
        drop(file);
        assert_eq!(std::fs::read_to_string(&path).unwrap(), text);
        assert!(temporaries(dir).is_empty());
    }
}
