//! A board as the closed loop's controller: the firmware image under QEMU,
//! a real board on a serial port, or the pty board, in lockstep over the
//! protocol link. Each control period is one `HilSensor` → `HilActuator`
//! round trip; everything else (plant, schedule, summary) is the same loop
//! `softjoint sim` runs with the core in process.

use std::time::Duration;

use firmware::control::DriverConfig;
use firmware::estimate::PlaneLaw;
use firmware::protocol::{
    cdeg_to_deg, kind, mv_to_coil_volts, Arm, ClearFaults, Disarm, ErrorCode, GetStatus, Hello,
    HelloAck, HilSensor, HilStart, Message, SetCalibration, SetGains, SetLinkTimeout, SetTarget,
    Status, PROTOCOL_VERSION, SCHEMA_HASH,
};
use hal_sim::{Actuation, Controller, Readings};

use crate::board::link::{Link, LinkError, Port};

/// Per-attempt timeout of configuration requests.
pub const CMD_TIMEOUT: Duration = Duration::from_millis(200);
/// Attempts of configuration requests.
pub const CMD_ATTEMPTS: u32 = 10;

/// Handshake: `Hello` → `HelloAck` with our version and schema; checks the
/// board drives the 3D joint (2 pairs, 4 sensors).
pub fn handshake<P: Port>(link: &mut Link<P>) -> anyhow::Result<()> {
    // A lone delimiter first: ends any partial frame in the board's decoder.
    link.send_raw(&[0])?;
    let reply = link.request(
        &Hello {
            version: PROTOCOL_VERSION,
        }
        .into(),
        CMD_TIMEOUT,
        CMD_ATTEMPTS,
        |m| matches!(m, Message::HelloAck(_)),
    )?;
    if let Message::HelloAck(HelloAck {
        version,
        schema,
        pairs,
        sensors,
    }) = reply
    {
        if version != PROTOCOL_VERSION || schema != SCHEMA_HASH {
            anyhow::bail!(
                "board speaks protocol v{version} schema {schema:#010x}; this host v{PROTOCOL_VERSION} schema {SCHEMA_HASH:#010x}: rebuild one of them"
            );
        }
        if (pairs, sensors) != (2, 4) {
            anyhow::bail!("board controls {pairs} pairs with {sensors} sensors; the lockstep runner drives the 3D joint (2, 4)");
        }
    }
    Ok(())
}

/// Reads the board's status.
pub fn status<P: Port>(link: &mut Link<P>) -> Result<Status, LinkError> {
    match link.request(&GetStatus {}.into(), CMD_TIMEOUT, CMD_ATTEMPTS, |m| {
        matches!(m, Message::Status(_))
    })? {
        Message::Status(s) => Ok(s),
        other => Err(LinkError::Unexpected {
            request: kind::GET_STATUS,
            reply: other.kind(),
        }),
    }
}

/// How a board is set up for a lockstep run.
#[derive(Clone, Debug)]
pub struct LockstepSetup {
    /// Control period (µs).
    pub period_us: u32,
    /// Gains per plane.
    pub gains: [firmware::control::PairGains; 2],
    /// Estimation law per plane.
    pub laws: [PlaneLaw; 2],
    /// Link-loss timeout to set (ms of the board's clock); `None` keeps the
    /// board's own.
    pub link_timeout_ms: Option<u16>,
    /// Wait for each lockstep reply (per attempt), and for each
    /// configuration request's when longer than [`CMD_TIMEOUT`]: a host
    /// given more time for a slow link or a loaded machine gets it for
    /// every request of the run, not only the steps.
    pub timeout: Duration,
    /// Attempts per step before giving up.
    pub attempts: u32,
    /// Fault injection: lose the first transmission of every Nth sensor
    /// frame (the retry must recover it).
    pub lose_every: Option<u32>,
    /// A board that restarts during the run (it answers a lockstep frame
    /// as a board not in lockstep) is set up again and the step sent again,
    /// instead of ending the run with [`BoardError::Restarted`]. Its
    /// controller state (integrators, estimator, sensor history) starts
    /// afresh, so the run is not the run it would have been; the count is
    /// in [`BoardController::restarts`].
    pub resume_after_restart: bool,
}

impl LockstepSetup {
    /// The wait per attempt of a configuration request: [`CMD_TIMEOUT`],
    /// or the lockstep timeout if that is longer.
    pub fn command_timeout(&self) -> Duration {
        self.timeout.max(CMD_TIMEOUT)
    }
}

/// Why a lockstep step failed, by what a user must do about it.
#[derive(Debug, thiserror::Error)]
pub enum BoardError {
    /// The board answered a lockstep frame as a board that is not in
    /// lockstep: it restarted (reset, watchdog, power) and lost the setup
    /// and its controller state.
    #[error("the board restarted: it answered lockstep frame seq {seq} as a board not in lockstep, so its setup and controller state are gone (lockstep handshake lost)")]
    Restarted {
        /// The frame it answered so.
        seq: u16,
    },
    /// The board restarted and setting it up again failed.
    #[error(
        "the board restarted at lockstep frame seq {seq} and could not be set up again: {reason}"
    )]
    NotSetUpAgain {
        /// The frame it answered as a board not in lockstep.
        seq: u16,
        /// Why the setup failed.
        reason: String,
    },
    /// No answer to one step after every retry.
    #[error("the board stopped answering: no reply to lockstep frame seq {seq} after {attempts} attempts of {timeout_ms} ms")]
    Silent {
        /// The unanswered frame.
        seq: u16,
        /// Attempts made.
        attempts: u32,
        /// Wait per attempt (ms).
        timeout_ms: u64,
    },
    /// The link failed otherwise (the line closed, a refusal, a port
    /// error).
    #[error(transparent)]
    Link(LinkError),
}

/// Handshake, configuration, `HilStart`, `ClearFaults` (faults latched
/// before: stale sensors in free-running mode, an earlier link loss), `Arm`.
fn configure<P: Port>(link: &mut Link<P>, setup: &LockstepSetup) -> anyhow::Result<()> {
    handshake(link)?;
    let wait = setup.command_timeout();
    link.command(&Disarm {}.into(), wait, CMD_ATTEMPTS)?;
    for (plane, (g, law)) in (0u8..).zip(setup.gains.iter().zip(setup.laws)) {
        link.command(
            &SetGains {
                plane,
                kp_agonist: g.kp_agonist(),
                kp_antagonist: g.kp_antagonist(),
                ki: g.ki(),
                integral_limit_v: g.integral_limit_v(),
                v_offset_v: g.v_offset_v(),
            }
            .into(),
            wait,
            CMD_ATTEMPTS,
        )?;
        link.command(&SetCalibration { plane, law }.into(), wait, CMD_ATTEMPTS)?;
    }
    if let Some(timeout_ms) = setup.link_timeout_ms {
        link.command(&SetLinkTimeout { timeout_ms }.into(), wait, CMD_ATTEMPTS)?;
    }
    link.command(
        &HilStart {
            period_us: setup.period_us,
        }
        .into(),
        wait,
        CMD_ATTEMPTS,
    )?;
    match link.command(&ClearFaults {}.into(), wait, CMD_ATTEMPTS) {
        Ok(()) | Err(LinkError::Refused { .. }) => {}
        Err(e) => return Err(e.into()),
    }
    link.command(&Arm {}.into(), wait, CMD_ATTEMPTS)?;
    Ok(())
}

/// A board in lockstep: the closed loop's controller.
pub struct BoardController<'a, P: Port> {
    link: &'a mut Link<P>,
    setup: LockstepSetup,
    driver: DriverConfig,
    targets_deg: [f32; 2],
    seq: u16,
    steps: u64,
    restarts: u32,
}

impl<'a, P: Port> BoardController<'a, P> {
    /// Handshake, configuration, `HilStart`, clearing of faults latched
    /// before (stale sensors in free-running mode, an earlier link loss),
    /// `Arm`.
    pub fn start(link: &'a mut Link<P>, setup: LockstepSetup) -> anyhow::Result<Self> {
        configure(link, &setup)?;
        Ok(Self {
            link,
            setup,
            driver: DriverConfig::default(),
            targets_deg: [0.0; 2],
            seq: 0,
            steps: 0,
            restarts: 0,
        })
    }

    /// Times the board restarted during the run and was set up again
    /// ([`LockstepSetup::resume_after_restart`]).
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// Steps answered so far.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// Sets a restarted board up again: the same configuration, then the
    /// targets in force.
    fn set_up_again(&mut self) -> Result<(), BoardError> {
        let again = |e: String| BoardError::NotSetUpAgain {
            seq: self.seq,
            reason: e,
        };
        configure(self.link, &self.setup).map_err(|e| again(format!("{e:#}")))?;
        for (plane, target_deg) in (0u8..).zip(self.targets_deg) {
            self.link
                .command(
                    &SetTarget { plane, target_deg }.into(),
                    self.setup.command_timeout(),
                    CMD_ATTEMPTS,
                )
                .map_err(|e| again(e.to_string()))?;
        }
        self.restarts += 1;
        Ok(())
    }

    /// The link (statistics, further requests).
    pub fn link(&mut self) -> &mut Link<P> {
        self.link
    }

    /// Disarms the board and reads its counters.
    pub fn finish(self) -> Result<Status, LinkError> {
        let _ = self.link.command(
            &Disarm {}.into(),
            self.setup.command_timeout(),
            CMD_ATTEMPTS,
        );
        status(self.link)
    }
}

impl<P: Port> Controller<2, 4> for BoardController<'_, P> {
    type Error = BoardError;

    fn set_target(&mut self, plane: usize, desired_deg: f32) -> Result<(), BoardError> {
        let msg = SetTarget {
            plane: u8::try_from(plane).unwrap_or(u8::MAX),
            target_deg: desired_deg,
        };
        self.link
            .command(&msg.into(), self.setup.command_timeout(), CMD_ATTEMPTS)
            .map_err(BoardError::Link)?;
        if let Some(t) = self.targets_deg.get_mut(plane) {
            *t = desired_deg;
        }
        Ok(())
    }

    fn targets_deg(&self) -> [f32; 2] {
        self.targets_deg
    }

    fn step(&mut self, readings: &Readings<2, 4>) -> Result<Actuation<2>, BoardError> {
        let counts = readings
            .counts
            .map(|c| c.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16);
        let seq = self.seq;
        if self
            .setup
            .lose_every
            .is_some_and(|n| n > 0 && self.steps % u64::from(n) == u64::from(n) - 1)
        {
            self.link.lose_next_send();
        }
        let frame: Message = HilSensor { seq, counts }.into();
        let accept = |m: &Message| matches!(m, Message::HilActuator(a) if a.seq == seq);
        let mut reply = self
            .link
            .request(&frame, self.setup.timeout, self.setup.attempts, accept);
        if let Err(LinkError::Refused {
            code: ErrorCode::WrongMode,
            ..
        }) = reply
        {
            if !self.setup.resume_after_restart {
                return Err(BoardError::Restarted { seq });
            }
            // After `HilStart` the board takes any seq as its first.
            self.set_up_again()?;
            reply = self
                .link
                .request(&frame, self.setup.timeout, self.setup.attempts, accept);
        }
        let reply = reply.map_err(|e| match e {
            LinkError::Timeout {
                attempts,
                timeout_ms,
                ..
            } => BoardError::Silent {
                seq,
                attempts,
                timeout_ms,
            },
            LinkError::Refused {
                code: ErrorCode::WrongMode,
                ..
            } => BoardError::Restarted { seq },
            other => BoardError::Link(other),
        })?;
        let Message::HilActuator(a) = reply else {
            return Err(BoardError::Link(LinkError::Unexpected {
                request: kind::HIL_SENSOR,
                reply: reply.kind(),
            }));
        };
        self.seq = self.seq.wrapping_add(1);
        self.steps += 1;
        Ok(Actuation {
            // The board's millivolts, exactly as a simulated PWM channel with
            // a millivolt full scale applies them.
            pair_volts: a.pair_mv.map(|mv| mv_to_coil_volts(mv, &self.driver)),
            estimate_deg: a.estimate_cdeg.map(|c| f64::from(cdeg_to_deg(c))),
            faults: u16::from(a.faults),
        })
    }
}

/// What a board accepts for a request's fields, in the words of the
/// command that sends it (for a refusal; the board only says `OutOfRange`
/// or `NotFinite`). From the firmware's own limits.
pub fn accepted_range(request: u8) -> Option<String> {
    use firmware::app::{LINK_TIMEOUT_MS, LOCKSTEP_PERIOD_US, MAX_TELEMETRY_HZ};
    use firmware::joint::DEFAULT_MAX_TARGET_DEG;
    Some(match request {
        kind::SET_LINK_TIMEOUT => format!(
            "the link timeout (hil --link-timeout-ms, console `link-timeout MS`) must be {}..={} ms",
            LINK_TIMEOUT_MS.start(),
            LINK_TIMEOUT_MS.end()
        ),
        kind::SET_TARGET => format!(
            "a target (console `target PLANE DEG`, scenario targets) must be a finite angle within ±{DEFAULT_MAX_TARGET_DEG}° on plane 0 (α) or 1 (β)"
        ),
        kind::SET_TELEMETRY => {
            format!("the telemetry rate (console `telemetry HZ`) must be 0..={MAX_TELEMETRY_HZ} Hz")
        }
        kind::HIL_START => format!(
            "the lockstep period (scenario control_period_us) must be {}..={} µs",
            LOCKSTEP_PERIOD_US.start(),
            LOCKSTEP_PERIOD_US.end()
        ),
        kind::SET_GAINS => "gains (console `gains PLANE KP_AG KP_ANT KI ILIM`, scenario [controller]) must be finite, Kp > 0, Ki ≥ 0, the integral limit ≥ 0, on plane 0 (α) or 1 (β)".into(),
        kind::SET_CALIBRATION | kind::GET_CALIBRATION => "a calibration (console `calibration set FILE`, scenario estimator.calibration) must be a valid law for the board's 4 sensors, on plane 0 (α) or 1 (β)".into(),
        kind::CLEAR_FAULTS => "faults clear only once their cause is gone (see `status`)".into(),
        _ => return None,
    })
}

/// A link error as a user should read it: which board (`port`), which
/// request, and for a refusal what the board accepts; for no reply, what
/// to check.
pub fn explain(e: &LinkError, port: &str, baud: u32) -> String {
    let name = |k: u8| firmware::protocol::message_name(k).unwrap_or("a request");
    match e {
        LinkError::Refused { request, code } => {
            let range = accepted_range(*request)
                .map(|r| format!(": {r}"))
                .unwrap_or_default();
            format!(
                "the board on {port} refused {} ({}: {code}){range}",
                name(*request),
                code.name()
            )
        }
        LinkError::Timeout {
            request,
            attempts,
            timeout_ms,
        } => format!(
            "no reply from {port} to {} after {attempts} attempts of {timeout_ms} ms: is a board running softjoint-fw connected there, at {baud} baud (--port, --baud)?",
            name(*request)
        ),
        _ => format!("{port}: {e}"),
    }
}

/// `e` with a [`LinkError`] inside it told as [`explain`] tells it (the
/// contexts around it kept); other errors unchanged.
pub fn name_the_board(e: anyhow::Error, port: &str, baud: u32) -> anyhow::Error {
    let Some(link) = e.chain().find_map(|c| c.downcast_ref::<LinkError>()) else {
        return e;
    };
    let mut text = String::new();
    for c in e.chain() {
        if c.downcast_ref::<LinkError>().is_some() {
            break;
        }
        text.push_str(&format!("{c}: "));
    }
    text.push_str(&explain(link, port, baud));
    anyhow::anyhow!(text)
}
