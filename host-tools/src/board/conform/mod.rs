//! The protocol conformance suite (`softjoint conform`): any board — a
//! real one on a serial port, the firmware images under QEMU, the pty
//! board, someone's own firmware — held to `docs/protocol.md`, check by
//! check, each check naming the section it holds the board to.
//!
//! The suite speaks only the protocol: it knows nothing of the board's
//! insides, so a board it did not build is judged by what it answers, by
//! what it does not answer, and by its own clock (`Status.time_ms`, read
//! against the wall clock to learn the board's clock ratio — under QEMU
//! 0.06–1× wall time). What it asks for is chosen so a conforming board
//! needs seconds, not minutes, for the whole suite.
//!
//! **Safe mode** (`--safe`, for a board with real coils): the suite never
//! asks for a driver input that passes current by the document's own
//! driver model (§8.4: nothing below 1.7 V) — lockstep outputs come from a
//! law with `v_offset = 0` and a gain of 0.01 V/deg (so do free-running
//! outputs once armed: safe mode never arms with the default law's 1.7 V
//! offset), drives stay at 1.5 V — and it skips the check that heats a coil to its trip level. If
//! the board reports a coil input above 1.7 V all the same, the suite
//! disarms it at once and fails the check that saw it.
//!
//! Left out: timing under load (the suite's waits are the document's
//! timeouts with slack, not a measurement of latency), the baud rate, and
//! a board's sensors (whether its counts are right is the board's own
//! test; the suite checks what the board does with what it reads).

mod checks_frame;
mod checks_run;
pub mod report;

use std::time::{Duration, Instant};

use firmware::protocol::{
    Arm, Disarm, ErrorCode, GetStatus, HilStop, Message, SetCalibration, SetGains, SetLinkTimeout,
    SetTarget, SetTelemetry, Status,
};
use serde::Serialize;

use crate::board::link::{Link, LinkError, Port};

/// Per-attempt reply timeout (§5: at least 200 ms).
pub const REPLY_TIMEOUT: Duration = Duration::from_millis(300);
/// Attempts per request (§5: about 10; a conforming board answers the
/// first).
pub const ATTEMPTS: u32 = 5;
/// How long silence is awaited where the document says "no reply".
pub const SILENCE: Duration = Duration::from_millis(400);
/// The highest driver input (mV) through which the document's driver
/// passes no current (§8.4): what safe mode may ask for.
pub const NO_CURRENT_MV: u16 = 1700;

/// How the suite runs.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// Never ask for a coil input that passes current; skip the thermal
    /// trip (see the module docs).
    pub safe: bool,
    /// The board is fresh from reset (the suite started it): its boot
    /// state is checked.
    pub fresh: bool,
}

/// How one check ended.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase", tag = "outcome", content = "detail")]
pub enum Outcome {
    /// The board did what the section says; the evidence.
    Pass(String),
    /// It did not; what it did instead.
    Fail(String),
    /// Not run, and why (never counted as passed).
    Skip(String),
}

/// One check's result.
#[derive(Clone, Debug, Serialize)]
pub struct CheckResult {
    /// The check's name, `area.what`.
    pub id: &'static str,
    /// The section of docs/protocol.md it holds the board to.
    pub section: &'static str,
    /// What it checks, in a line.
    pub title: &'static str,
    /// How it ended.
    #[serde(flatten)]
    pub outcome: Outcome,
    /// Wall-clock seconds it took.
    pub seconds: f64,
}

/// The suite's report.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The board, as the user named it.
    pub board: String,
    /// Safe mode.
    pub safe: bool,
    /// The board's clock per wall-clock second, as measured (none if the
    /// board never answered `GetStatus`).
    pub clock_ratio: Option<f64>,
    /// Every check, in the order run.
    pub checks: Vec<CheckResult>,
    /// Counts.
    pub passed: usize,
    /// Counts.
    pub failed: usize,
    /// Counts.
    pub skipped: usize,
}

impl Report {
    /// True when no check failed.
    pub fn ok(&self) -> bool {
        self.failed == 0
    }
}

/// Why a check did not pass.
#[derive(Debug)]
pub enum NotPassed {
    /// The board broke the rule.
    Fail(String),
    /// The check does not apply to this board or mode.
    Skip(String),
}

impl From<LinkError> for NotPassed {
    fn from(e: LinkError) -> Self {
        NotPassed::Fail(e.to_string())
    }
}

impl From<std::io::Error> for NotPassed {
    fn from(e: std::io::Error) -> Self {
        NotPassed::Fail(format!("serial line: {e}"))
    }
}

/// A check's body: the evidence when it passes.
pub type Verdict = Result<String, NotPassed>;

/// Fails with `why()` unless `ok`.
pub fn need(ok: bool, why: impl FnOnce() -> String) -> Result<(), NotPassed> {
    if ok {
        Ok(())
    } else {
        Err(NotPassed::Fail(why()))
    }
}

/// One check of the suite.
pub struct Check<P: Port> {
    /// Name, `area.what`.
    pub id: &'static str,
    /// Section of docs/protocol.md.
    pub section: &'static str,
    /// What it checks.
    pub title: &'static str,
    /// Heats a coil (skipped in safe mode).
    pub heats: bool,
    /// The check.
    pub run: fn(&mut Session<'_, P>) -> Verdict,
}

/// Every check, in the order they run (the order matters only for
/// speed: each starts from [`Session::settle`]).
pub fn checks<P: Port>() -> Vec<Check<P>> {
    let mut all = checks_frame::checks();
    all.extend(checks_run::checks());
    all
}

/// The link to the board, with what the checks share: the options, the
/// board's clock ratio, and the safe-mode watch on every reply.
pub struct Session<'a, P: Port> {
    link: &'a mut Link<P>,
    /// How the suite runs.
    pub opts: Options,
    /// Board milliseconds per wall-clock millisecond.
    pub clock_ratio: f64,
    /// Set when safe mode saw a coil input that passes current.
    unsafe_output: Option<String>,
}

impl<'a, P: Port> Session<'a, P> {
    /// A session on `link`.
    pub fn new(link: &'a mut Link<P>, opts: Options) -> Self {
        Self {
            link,
            opts,
            clock_ratio: 1.0,
            unsafe_output: None,
        }
    }

    /// The link (for raw bytes).
    pub fn link(&mut self) -> &mut Link<P> {
        self.link
    }

    /// Safe mode: a reply that shows a coil input passing current.
    fn watch(&mut self, msg: &Message) {
        if !self.opts.safe {
            return;
        }
        let limit = i32::from(NO_CURRENT_MV);
        let hot = match msg {
            Message::Status(s) => s
                .coil_mv
                .iter()
                .map(|v| i32::from(*v))
                .chain(s.pair_mv.iter().map(|v| i32::from(*v).abs()))
                .max(),
            Message::HilActuator(a) => a.pair_mv.iter().map(|v| i32::from(*v).abs()).max(),
            Message::Telemetry(t) => t.coil_mv.iter().map(|v| i32::from(*v)).max(),
            _ => None,
        };
        if let Some(mv) = hot.filter(|mv| *mv > limit) {
            // Off first, then the record.
            let _ = self.link.send(&Disarm {}.into());
            self.unsafe_output.get_or_insert(format!(
                "safe mode: the board drove a coil at {mv} mV (> {limit} mV passes current, §8.4) though the suite never asked for it; disarmed"
            ));
        }
    }

    /// Sends `msg` and returns its reply: `Ok(None)` for its `Ack`,
    /// `Ok(Some(code))` for its `Nak`, `Err` for anything else.
    pub fn ask(&mut self, msg: impl Into<Message>) -> Result<Option<ErrorCode>, NotPassed> {
        let msg = msg.into();
        let k = msg.kind();
        let retries = self.link.stats().retries;
        let reply = match self.link.request(
            &msg,
            REPLY_TIMEOUT,
            ATTEMPTS,
            |m| matches!(m, Message::Ack(a) if a.request == k),
        ) {
            Ok(_) => Ok(None),
            Err(LinkError::Refused { code, .. }) => Ok(Some(code)),
            Err(e) => Err(e.into()),
        };
        if self.link.stats().retries != retries {
            self.drain_duplicates()?;
        }
        reply
    }

    /// After a retry (a reply slower than [`REPLY_TIMEOUT`], as on a
    /// loaded host): the board may answer the repeated request too, and
    /// that answer must not be taken for the next request's (replies name
    /// only the request's type). Waits a reply timeout and drops what came.
    fn drain_duplicates(&mut self) -> Result<(), NotPassed> {
        let deadline = Instant::now() + REPLY_TIMEOUT;
        while let Some(m) = self.link.recv_until(deadline)? {
            self.watch(&m);
        }
        Ok(())
    }

    /// Sends `msg`, which must be acknowledged.
    pub fn ack(&mut self, msg: impl Into<Message>) -> Result<(), NotPassed> {
        let msg = msg.into();
        let name = firmware::protocol::message_name(msg.kind()).unwrap_or("?");
        match self.ask(msg)? {
            None => Ok(()),
            Some(code) => Err(NotPassed::Fail(format!(
                "{name} refused with {}",
                code.name()
            ))),
        }
    }

    /// Sends `msg`, which must be refused with `code`.
    pub fn nak(&mut self, msg: impl Into<Message>, code: ErrorCode) -> Result<(), NotPassed> {
        let msg = msg.into();
        let shown = format!("{msg:?}");
        let got = self.ask(msg)?;
        need(got == Some(code), || {
            let got = got.map_or("Ack".to_string(), |c| format!("Nak{{{}}}", c.name()));
            format!("{shown}: expected Nak{{{}}}, got {got}", code.name())
        })
    }

    /// Sends `msg` and returns the reply `accept` takes.
    pub fn request(
        &mut self,
        msg: impl Into<Message>,
        accept: impl Fn(&Message) -> bool,
    ) -> Result<Message, NotPassed> {
        let retries = self.link.stats().retries;
        let reply = self
            .link
            .request(&msg.into(), REPLY_TIMEOUT, ATTEMPTS, accept)?;
        self.watch(&reply);
        if self.link.stats().retries != retries {
            self.drain_duplicates()?;
        }
        Ok(reply)
    }

    /// The board's status.
    pub fn status(&mut self) -> Result<Status, NotPassed> {
        match self.request(GetStatus {}, |m| matches!(m, Message::Status(_)))? {
            Message::Status(s) => Ok(s),
            other => Err(NotPassed::Fail(format!("GetStatus answered {other:?}"))),
        }
    }

    /// The next frame that is not telemetry within `wait` (telemetry is
    /// watched and dropped).
    pub fn next_reply(&mut self, wait: Duration) -> Result<Option<Message>, NotPassed> {
        let deadline = Instant::now() + wait;
        while let Some(m) = self.link.recv_until(deadline)? {
            self.watch(&m);
            if !matches!(m, Message::Telemetry(_)) {
                return Ok(Some(m));
            }
        }
        Ok(None)
    }

    /// Waits until about `board_ms` of the board's clock have passed,
    /// sending nothing (from the measured clock ratio).
    pub fn wait_board_ms(&mut self, board_ms: f64) {
        let wall_ms = board_ms / self.clock_ratio.max(1e-3);
        std::thread::sleep(Duration::from_secs_f64((wall_ms / 1e3).min(60.0)));
    }

    /// Measures the board's clock ratio from two `Status` replies.
    pub fn measure_clock(&mut self) -> Result<f64, NotPassed> {
        let (s0, w0) = (self.status()?, Instant::now());
        std::thread::sleep(Duration::from_millis(400));
        let (s1, w1) = (self.status()?, Instant::now());
        let board_ms = f64::from(s1.time_ms.wrapping_sub(s0.time_ms));
        let ratio = board_ms / ((w1 - w0).as_secs_f64() * 1e3);
        need(ratio > 0.0, || {
            format!(
                "the board's clock did not advance ({} ms, then {} ms)",
                s0.time_ms, s1.time_ms
            )
        })?;
        self.clock_ratio = ratio;
        Ok(ratio)
    }

    /// Back to a known state between checks: free-running, disarmed,
    /// telemetry off, the default link timeout, targets 0°, default gains
    /// and laws, telemetry still queued dropped.
    pub fn settle(&mut self) -> Result<(), NotPassed> {
        self.ack(HilStop {})?;
        self.ack(Disarm {})?;
        self.ack(SetTelemetry { rate_hz: 0 })?;
        self.ack(SetLinkTimeout { timeout_ms: 50 })?;
        let defaults = firmware::joint::JointConfig::paper_3d();
        for plane in 0..2u8 {
            self.ack(SetTarget {
                plane,
                target_deg: 0.0,
            })?;
            let g = defaults.gains[usize::from(plane)];
            // Safe mode arms with a law that cannot pass current (the
            // default law's 1.7 V offset is the driver's threshold).
            self.ack(if self.opts.safe {
                cold_gains(plane)
            } else {
                SetGains {
                    plane,
                    kp_agonist: g.kp_agonist(),
                    kp_antagonist: g.kp_antagonist(),
                    ki: g.ki(),
                    integral_limit_v: g.integral_limit_v(),
                    v_offset_v: g.v_offset_v(),
                }
            })?;
            self.ack(SetCalibration {
                plane,
                law: defaults.laws[usize::from(plane)],
            })?;
        }
        // Drop telemetry still on its way.
        while self
            .link
            .recv_until(Instant::now() + Duration::from_millis(20))?
            .is_some()
        {}
        Ok(())
    }

    /// Arms the board (after `ClearFaults` if it can): for checks that
    /// need outputs.
    pub fn arm(&mut self) -> Result<(), NotPassed> {
        let _ = self.ask(firmware::protocol::ClearFaults {})?;
        self.ack(Arm {})
    }
}

/// Gains under which no reading passes current (§8.4: nothing below
/// 1.7 V): `v_offset = 0`, 0.01 V/deg, no integral.
pub fn cold_gains(plane: u8) -> SetGains {
    SetGains {
        plane,
        kp_agonist: 0.01,
        kp_antagonist: 0.01,
        ki: 0.0,
        integral_limit_v: 0.0,
        v_offset_v: 0.0,
    }
}

/// `text` with every word that reads as a non-finite number (a board's
/// NaN "no estimate" in a shown reply) written `none`, so the report's
/// files pass the output checks (`crate::output`).
fn readable(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut word = String::new();
    let flush = |word: &mut String, out: &mut String| {
        if word.parse::<f64>().is_ok_and(|v| !v.is_finite()) {
            out.push_str("none");
        } else {
            out.push_str(word);
        }
        word.clear();
    };
    for c in text.chars() {
        if c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.' | '_') {
            word.push(c);
        } else {
            flush(&mut word, &mut out);
            out.push(c);
        }
    }
    flush(&mut word, &mut out);
    out
}

/// Runs every check against the board on `link`; `board` names it in the
/// report.
pub fn run<P: Port>(link: &mut Link<P>, board: &str, opts: Options) -> Report {
    let mut s = Session::new(link, opts);
    // The host speaks first; a lone delimiter ends any partial frame.
    let _ = s.link.send_raw(&[0]);
    let mut results = Vec::new();
    let mut clock_ratio = None;
    for check in checks::<P>() {
        let started = Instant::now();
        let outcome = if check.heats && opts.safe {
            Outcome::Skip("--safe: this check heats a coil to its trip level".into())
        } else if check.id == "boot.state" && !opts.fresh {
            Outcome::Skip(
                "the board may not be fresh from reset (--fresh, or let the suite start it)".into(),
            )
        } else {
            let verdict = (|| {
                if check.id != "handshake.hello" && check.id != "boot.state" {
                    s.settle()?;
                    if clock_ratio.is_none() {
                        clock_ratio = Some(s.measure_clock()?);
                    }
                }
                (check.run)(&mut s)
            })();
            match (verdict, s.unsafe_output.take()) {
                (_, Some(hot)) => Outcome::Fail(hot),
                (Ok(evidence), None) => Outcome::Pass(readable(&evidence)),
                (Err(NotPassed::Fail(why)), None) => Outcome::Fail(readable(&why)),
                (Err(NotPassed::Skip(why)), None) => Outcome::Skip(readable(&why)),
            }
        };
        results.push(CheckResult {
            id: check.id,
            section: check.section,
            title: check.title,
            outcome,
            seconds: started.elapsed().as_secs_f64(),
        });
    }
    // Leave the board as the suite found a fresh one: free-running,
    // disarmed, defaults.
    let _ = s.settle();
    let count = |f: fn(&Outcome) -> bool| results.iter().filter(|r| f(&r.outcome)).count();
    Report {
        board: board.to_string(),
        safe: opts.safe,
        clock_ratio,
        passed: count(|o| matches!(o, Outcome::Pass(_))),
        failed: count(|o| matches!(o, Outcome::Fail(_))),
        skipped: count(|o| matches!(o, Outcome::Skip(_))),
        checks: results,
    }
}
