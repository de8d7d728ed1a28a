//! The board application: the protocol state machine around a [`Joint3d`].
//!
//! Portable and clock-free like the rest of the core. The firmware image
//! feeds it UART bytes and its monotonic time (SysTick milliseconds
//! extended by [`MillisCounter`](crate::time::MillisCounter)); the host test
//! harness feeds it bytes from one end of a pty pair. Replies go out through
//! a callback, one complete frame at a time.
//!
//! Modes:
//! - **free-running** (after reset, and after [`HilStop`]): the board steps
//!   the joint itself every millisecond, reading its own sensors through
//!   [`BoardSensors`], and streams [`Telemetry`] when asked. There is no
//!   link watchdog in this mode: the board controls itself, and a console
//!   that goes away does not stop it. On QEMU there are no sensors, so the
//!   joint keeps its outputs off (no sensor has ever delivered) and then
//!   latches sensor-stale — as it should.
//! - **lockstep HIL** (after [`HilStart`]): the host owns time. Each
//!   [`HilSensor`] runs exactly one control step and is answered with a
//!   [`HilActuator`]. The core's clock in this mode is the board's clock at
//!   `HilStart` plus `step × period`, where `step` counts periods from the
//!   first sensor frame (the seq difference to the previous frame, so a
//!   host may start at any seq). A repeated `seq` is answered from a cache
//!   without stepping again (idempotent retries); a seq *behind* the last
//!   one (a late retransmission) is ignored and counted. A forward gap
//!   longer than the link timeout is a link loss (the board was not in
//!   control for that long), and the step's `dt` is capped at the timeout.
//!   If no frame arrives for the link timeout (default 50 ms of the board's
//!   clock), [`Faults::LINK_LOSS`] is latched and every output is zero until
//!   the host clears it.
//!
//! - **open-loop drive** (a plane of free-running mode after [`Drive`]):
//!   the plane's coils get the host's inputs — both coils of a pair may be
//!   heated (co-contraction), which only this mode allows — to record a
//!   log for identification. Every input still goes through the
//!   supervisor (arm state, latched faults, each coil's thermal budget:
//!   a trip cuts that coil and is reported as over-budget). A drive holds
//!   for its `hold_ms` (≤ [`MAX_DRIVE_HOLD_MS`]); not refreshed by then,
//!   the plane's coils go **unpowered** and stay so until the next
//!   `Drive` or a `SetTarget` for the plane, which gives it back to the
//!   controller; a latching fault ends a drive the same way. `Disarm` and
//!   `HilStart` end every drive (the planes go back to the controller).
//!   Like the controller, a drive powers nothing before every sensor the
//!   laws read has delivered a reading. A `Drive` is
//!   refused by name when disarmed, with a fault latched, in lockstep, for
//!   a coil cooling after a trip, or with a value out of range.
//!
//! Outputs are per coil ([`App::outputs`], `[agonist, antagonist]` per
//! pair), bounded to the driver's range. For planes under the controller
//! they are the supervisor's [`PairCommand`]s, so the pair rule holds by
//! type; only a driven plane may heat both coils.

use crate::control::{DriveVolts, PairCommand, PairGains};
use crate::joint::{ConfigError, Feedback, Joint3d, JointConfig, StepInput};
use crate::protocol::*;
use crate::supervisor::Faults;
use crate::time::{Duration, Instant};

/// The board's own wire sensors in free-running mode.
pub trait BoardSensors {
    /// Current counts of sensors 1–4 (`None`: no reading).
    fn read_counts(&mut self) -> [Option<i32>; 4];
}

/// A board without sensors (QEMU): every reading is missing.
pub struct NoSensors;

impl BoardSensors for NoSensors {
    fn read_counts(&mut self) -> [Option<i32>; 4] {
        [None; 4]
    }
}

/// Free-running control period: 1 ms (1 kHz loop).
pub const FREE_RUNNING_PERIOD: Duration = Duration::from_millis(1);
/// Default link-loss timeout in lockstep mode (ms of the board's clock).
pub const DEFAULT_LINK_TIMEOUT_MS: u16 = 50;
/// Accepted lockstep periods (µs). The longest is the wire sensors' stale
/// limit (50 ms): with a longer period every sensor would be stale at the
/// second step, so such a `HilStart` is refused rather than accepted into
/// a certain sensor-stale latch.
pub const LOCKSTEP_PERIOD_US: core::ops::RangeInclusive<u32> = 100..=50_000;
/// Accepted link timeouts (ms).
pub const LINK_TIMEOUT_MS: core::ops::RangeInclusive<u16> = 1..=60_000;
/// Highest telemetry rate (frames per second).
pub const MAX_TELEMETRY_HZ: u16 = 1000;
/// Longest hold of one [`Drive`] (ms): a host that stops refreshing leaves
/// its coils heated for at most this long.
pub const MAX_DRIVE_HOLD_MS: u16 = 1000;

/// How a plane's coils are driven in free-running mode.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PlaneDrive {
    /// By the plane's controller (the pair rule holds).
    Control,
    /// Open loop, `[agonist, antagonist]`, until `until`.
    Driven {
        volts: [DriveVolts; 2],
        until: Instant,
    },
    /// A drive expired: unpowered until the next `Drive` or `SetTarget`.
    Released,
}

/// The last lockstep step, for idempotent retries.
#[derive(Clone, Copy, Debug, PartialEq)]
struct LastStep {
    seq: u16,
    step: u64,
    reply: HilActuator,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    FreeRunning {
        /// Time of the last free-running step (its `dt` is measured).
        last_step: Option<Instant>,
    },
    Lockstep {
        period: Duration,
        /// The board's clock at `HilStart`: step 0's instant.
        anchor: Instant,
        last: Option<LastStep>,
    },
}

/// The instant of lockstep step `step` (periods since the first sensor
/// frame after `HilStart`, whose instant is `anchor`). A simulator that
/// steps the core with these instants reproduces the board's inputs bit for
/// bit.
pub fn lockstep_instant(anchor: Instant, step: u64, period: Duration) -> Instant {
    anchor + period.saturating_mul(step)
}

/// The application state.
pub struct App {
    joint: Joint3d,
    mode: Mode,
    decoder: FrameDecoder,
    /// Per pair `[agonist, antagonist]`: what the drivers are set to.
    outputs: [[DriveVolts; 2]; 2],
    /// The controller's commands (planes under control; `Off` otherwise).
    pair_commands: [PairCommand; 2],
    drive: [PlaneDrive; 2],
    last_counts: [Option<i32>; 4],
    last_faults: Faults,
    last_estimate: [f32; 2],
    link_timeout: Duration,
    last_frame: Option<Instant>,
    telemetry_hz: u16,
    next_telemetry: Instant,
    stale_seqs: u32,
}

impl App {
    /// A board running the paper's 3D joint configuration, disarmed.
    pub fn new() -> Result<Self, ConfigError> {
        Ok(Self::with_joint(Joint3d::new(JointConfig::paper_3d())?))
    }

    /// A board around an already configured joint (disarmed until `Arm`).
    pub fn with_joint(mut joint: Joint3d) -> Self {
        joint.disarm();
        Self {
            joint,
            mode: Mode::FreeRunning { last_step: None },
            decoder: FrameDecoder::board(),
            outputs: [[DriveVolts::ZERO; 2]; 2],
            pair_commands: [PairCommand::Off; 2],
            drive: [PlaneDrive::Control; 2],
            last_counts: [None; 4],
            last_faults: Faults::NONE,
            last_estimate: [f32::NAN; 2],
            link_timeout: Duration::from_millis(u64::from(DEFAULT_LINK_TIMEOUT_MS)),
            last_frame: None,
            telemetry_hz: 0,
            next_telemetry: Instant::ZERO,
            stale_seqs: 0,
        }
    }

    /// What the SMA drivers must be set to now: per pair (α, β) the inputs
    /// `[agonist, antagonist]`. Both are non-zero only for a plane in
    /// open-loop drive mode.
    pub fn outputs(&self) -> [[DriveVolts; 2]; 2] {
        self.outputs
    }

    /// The outputs as coil inputs 1–4 in paper numbering (mV, the wire's
    /// rounding).
    pub fn coil_mv(&self) -> [u16; 4] {
        let d = self.joint.driver();
        crate::joint::pairs_to_coils::<DriveVolts, 2, 4>(self.outputs).map(|v| coil_to_mv(v, d))
    }

    /// Planes in open-loop drive mode (driven, or released after a drive
    /// expired), bit 0 = α.
    pub fn drive_planes(&self) -> u8 {
        self.drive
            .iter()
            .enumerate()
            .filter(|(_, d)| **d != PlaneDrive::Control)
            .fold(0, |m, (p, _)| m | (1 << p))
    }

    fn set_pair_outputs(&mut self, commands: [PairCommand; 2]) {
        self.pair_commands = commands;
        self.outputs = commands.map(PairCommand::coil_drive);
    }

    fn outputs_off(&mut self) {
        self.set_pair_outputs([PairCommand::Off; 2]);
    }

    /// The joint (read-only).
    pub fn joint(&self) -> &Joint3d {
        &self.joint
    }

    /// True in lockstep mode.
    pub fn in_hil(&self) -> bool {
        matches!(self.mode, Mode::Lockstep { .. })
    }

    /// Feeds one received byte at board time `now`; replies are passed to
    /// `send` as complete frames.
    pub fn on_byte(&mut self, byte: u8, now: Instant, send: &mut impl FnMut(&[u8])) {
        match self.decoder.push(byte) {
            None => {}
            Some(Ok(msg)) => {
                self.last_frame = Some(now);
                if let Some(reply) = self.handle(msg, now) {
                    emit(&reply, send);
                }
            }
            Some(Err(FrameError::Malformed { request, code })) => {
                // CRC-valid but not understood: tell the host.
                emit(&Message::Nak(Nak { request, code }), send);
            }
            Some(Err(_)) => {} // counted; the host will retry
        }
    }

    /// Periodic work at board time `now`: the link watchdog, the
    /// free-running control step and telemetry. Call it often (every
    /// millisecond or faster).
    pub fn poll(
        &mut self,
        now: Instant,
        sensors: &mut impl BoardSensors,
        send: &mut impl FnMut(&[u8]),
    ) {
        match self.mode {
            Mode::Lockstep { .. } => {
                let lost = self
                    .last_frame
                    .is_some_and(|last| now - last > self.link_timeout);
                if lost {
                    if !self
                        .joint
                        .supervisor()
                        .latched()
                        .contains(Faults::LINK_LOSS)
                    {
                        log_warn!("link lost at {=u64} ms", now.as_millis());
                    }
                    self.joint.report_fault(Faults::LINK_LOSS);
                    self.outputs_off();
                    self.last_faults |= Faults::LINK_LOSS;
                }
            }
            Mode::FreeRunning { last_step } => {
                // An expired drive cuts its coils now, not at the next step.
                for (d, out) in self.drive.iter_mut().zip(self.outputs.iter_mut()) {
                    if matches!(d, PlaneDrive::Driven { until, .. } if now >= *until) {
                        *d = PlaneDrive::Released;
                        *out = [DriveVolts::ZERO; 2];
                    }
                }
                let due = last_step.is_none_or(|t| now - t >= FREE_RUNNING_PERIOD);
                if due {
                    // The measured time since the last step (a late poll
                    // integrates over the time that really passed).
                    let dt = last_step.map_or(FREE_RUNNING_PERIOD, |t| now - t);
                    self.mode = Mode::FreeRunning {
                        last_step: Some(now),
                    };
                    let counts = sensors.read_counts();
                    self.last_counts = counts;
                    let input = StepInput {
                        now,
                        dt,
                        feedback: Feedback::WireCounts(counts),
                    };
                    let drive = self.drive.map(|d| match d {
                        PlaneDrive::Control => None,
                        PlaneDrive::Driven { volts, .. } => Some(volts),
                        PlaneDrive::Released => Some([DriveVolts::ZERO; 2]),
                    });
                    let out = self.joint.step_driven(&input, drive);
                    if out.faults.intersects(Faults::LATCHING) {
                        // A latch ends every drive as an expiry does: the
                        // planes stay unpowered, in drive mode, after
                        // ClearFaults until the next Drive or SetTarget.
                        for d in self.drive.iter_mut() {
                            if matches!(d, PlaneDrive::Driven { .. }) {
                                *d = PlaneDrive::Released;
                            }
                        }
                    }
                    self.pair_commands = out.commands;
                    self.outputs = out.coils;
                    self.last_faults = out.faults;
                    self.last_estimate = out.estimate_deg;
                }
                if self.telemetry_hz > 0 && now >= self.next_telemetry {
                    // Fixed rate: frames on a grid of the interval from the
                    // stream's start (a poll that comes late does not push
                    // every later frame back), re-anchored after a gap.
                    let interval =
                        Duration::from_micros((1_000_000 / u64::from(self.telemetry_hz)).max(1));
                    let next = self.next_telemetry + interval;
                    self.next_telemetry = if next > now { next } else { now + interval };
                    let t = Telemetry {
                        time_ms: now.wrapping_millis_u32(),
                        estimate_deg: self.last_estimate,
                        coil_mv: self.coil_mv(),
                        counts: self.last_counts.map(|c| c.unwrap_or(i32::MIN)),
                        faults: faults_to_u8(self.last_faults),
                    };
                    emit(&Message::Telemetry(t), send);
                }
            }
        }
    }

    /// Handles one decoded message at board time `now`; returns the reply,
    /// if any.
    ///
    /// Each request has its own step below; a request that changes state
    /// is answered with an ACK, or a NAK whose code says why it was refused.
    pub fn handle(&mut self, msg: Message, now: Instant) -> Option<Message> {
        let request = msg.kind();
        let answer = |reply: Result<Message, ErrorCode>| {
            Some(reply.unwrap_or_else(|code| Message::Nak(Nak { request, code })))
        };
        let acked =
            |done: Result<(), ErrorCode>| answer(done.map(|()| Message::Ack(Ack { request })));
        match msg {
            Message::Hello(hello) => answer(Self::hello(hello)),
            Message::HilStart(start) => acked(self.start_lockstep(start, now)),
            Message::HilStop(HilStop {}) => {
                // In free-running mode there is no lockstep to leave: the
                // request changes nothing (a retried HilStop must not
                // restart the time base again).
                if self.in_hil() {
                    self.mode = Mode::FreeRunning { last_step: None };
                    self.enter_new_time_base();
                }
                acked(Ok(()))
            }
            Message::HilSensor(frame) => self.lockstep_step(frame),
            Message::SetTarget(target) => acked(self.set_target(target)),
            Message::SetGains(gains) => acked(self.set_gains(gains)),
            Message::SetCalibration(calibration) => acked(self.set_calibration(calibration)),
            Message::GetCalibration(GetCalibration { plane }) => answer(
                self.joint
                    .law(usize::from(plane))
                    .map(|law| Message::Calibration(Calibration { plane, law }))
                    .ok_or(ErrorCode::OutOfRange),
            ),
            Message::Arm(Arm {}) => {
                self.joint.arm();
                acked(Ok(()))
            }
            Message::Disarm(Disarm {}) => {
                self.joint.disarm();
                self.drive = [PlaneDrive::Control; 2];
                self.outputs_off();
                acked(Ok(()))
            }
            Message::Drive(d) => acked(self.start_drive(d, now)),
            Message::ClearFaults(ClearFaults {}) => acked(self.clear_faults()),
            Message::GetStatus(GetStatus {}) => Some(Message::Status(self.status(now))),
            Message::SetTelemetry(rate) => acked(self.set_telemetry(rate, now)),
            Message::SetLinkTimeout(timeout) => acked(self.set_link_timeout(timeout)),
            // The board's decoder only accepts requests; a reply type that
            // reached `handle` some other way is still not a request.
            Message::HelloAck(_)
            | Message::HilActuator(_)
            | Message::Calibration(_)
            | Message::Status(_)
            | Message::Telemetry(_)
            | Message::Ack(_)
            | Message::Nak(_) => answer(Err(ErrorCode::UnknownType)),
        }
    }

    /// The answer to a [`Hello`]: the board's protocol version, schema and
    /// size, if the host speaks the same version.
    fn hello(Hello { version }: Hello) -> Result<Message, ErrorCode> {
        if version != PROTOCOL_VERSION {
            return Err(ErrorCode::Version);
        }
        Ok(Message::HelloAck(HelloAck {
            version: PROTOCOL_VERSION,
            schema: SCHEMA_HASH,
            pairs: 2,
            sensors: 4,
        }))
    }

    /// Enters lockstep mode with the host's period; board time `now` is
    /// step 0's instant.
    fn start_lockstep(
        &mut self,
        HilStart { period_us }: HilStart,
        now: Instant,
    ) -> Result<(), ErrorCode> {
        if !LOCKSTEP_PERIOD_US.contains(&period_us) {
            return Err(ErrorCode::OutOfRange);
        }
        self.mode = Mode::Lockstep {
            period: Duration::from_micros(u64::from(period_us)),
            anchor: now,
            last: None,
        };
        self.enter_new_time_base();
        Ok(())
    }

    /// Sets a plane's target angle; the plane goes back to its controller
    /// (ending an open-loop drive).
    fn set_target(&mut self, SetTarget { plane, target_deg }: SetTarget) -> Result<(), ErrorCode> {
        if !target_deg.is_finite() {
            return Err(ErrorCode::NotFinite);
        }
        self.joint
            .set_target(usize::from(plane), target_deg)
            .map_err(|_| ErrorCode::OutOfRange)?;
        if let Some(d) = self.drive.get_mut(usize::from(plane)) {
            *d = PlaneDrive::Control;
        }
        Ok(())
    }

    /// Sets a plane's pair gains: non-finite values are refused as such;
    /// bad gains and a plane the joint does not have are both out of range
    /// (the joint owns the plane and supply checks).
    fn set_gains(&mut self, g: SetGains) -> Result<(), ErrorCode> {
        if ![
            g.kp_agonist,
            g.kp_antagonist,
            g.ki,
            g.integral_limit_v,
            g.v_offset_v,
        ]
        .iter()
        .all(|v| v.is_finite())
        {
            return Err(ErrorCode::NotFinite);
        }
        PairGains::new(g.kp_agonist, g.kp_antagonist, g.ki, g.integral_limit_v)
            .and_then(|p| p.with_v_offset(g.v_offset_v))
            .map_err(ConfigError::from)
            .and_then(|gains| self.joint.set_gains(usize::from(g.plane), gains))
            .map_err(|_| ErrorCode::OutOfRange)
    }

    /// Sets a plane's calibration law; a non-finite coefficient or
    /// threshold is refused as such, anything else the joint refuses is out
    /// of range.
    fn set_calibration(
        &mut self,
        SetCalibration { plane, law }: SetCalibration,
    ) -> Result<(), ErrorCode> {
        // NotFinite comes before every other refusal, as for SetTarget and
        // SetGains (§4.5 of docs/protocol.md).
        if !law.is_finite() {
            return Err(ErrorCode::NotFinite);
        }
        self.joint
            .set_law(usize::from(plane), law)
            .map_err(|e| match e {
                ConfigError::Calibration(
                    crate::estimate::CalibrationError::CoefficientNotFinite
                    | crate::estimate::CalibrationError::ThresholdNotFinite,
                ) => ErrorCode::NotFinite,
                _ => ErrorCode::OutOfRange,
            })
    }

    /// Clears the latched faults, if none of their causes is still present.
    fn clear_faults(&mut self) -> Result<(), ErrorCode> {
        self.joint
            .clear_faults()
            .map_err(|_| ErrorCode::StillFaulted)?;
        self.last_faults = Faults::NONE;
        Ok(())
    }

    /// Sets the telemetry rate (0: off); the first frame is due at `now`.
    fn set_telemetry(
        &mut self,
        SetTelemetry { rate_hz }: SetTelemetry,
        now: Instant,
    ) -> Result<(), ErrorCode> {
        if rate_hz > MAX_TELEMETRY_HZ {
            return Err(ErrorCode::OutOfRange);
        }
        self.telemetry_hz = rate_hz;
        self.next_telemetry = now;
        Ok(())
    }

    /// Sets the lockstep link-loss timeout.
    fn set_link_timeout(
        &mut self,
        SetLinkTimeout { timeout_ms }: SetLinkTimeout,
    ) -> Result<(), ErrorCode> {
        if !LINK_TIMEOUT_MS.contains(&timeout_ms) {
            return Err(ErrorCode::OutOfRange);
        }
        self.link_timeout = Duration::from_millis(u64::from(timeout_ms));
        Ok(())
    }

    /// Checks a [`Drive`] and starts it (see the module docs for the
    /// rules); the error is the NAK's code.
    fn start_drive(&mut self, d: Drive, now: Instant) -> Result<(), ErrorCode> {
        if self.in_hil() {
            return Err(ErrorCode::WrongMode);
        }
        if !(1..=3).contains(&d.planes) || !(1..=MAX_DRIVE_HOLD_MS).contains(&d.hold_ms) {
            return Err(ErrorCode::OutOfRange);
        }
        let driver = *self.joint.driver();
        let pairs: [[u16; 2]; 2] = crate::joint::coils_to_pairs(d.coil_mv);
        let mut volts = [[DriveVolts::ZERO; 2]; 2];
        for (p, (v, mv)) in volts.iter_mut().zip(pairs).enumerate() {
            let driven = d.planes & (1 << p) != 0;
            for (slot, m) in v.iter_mut().zip(mv) {
                if !driven && m != 0 {
                    return Err(ErrorCode::OutOfRange);
                }
                *slot = mv_to_coil(m, &driver).ok_or(ErrorCode::OutOfRange)?;
            }
        }
        if !self.joint.is_armed() {
            return Err(ErrorCode::Disarmed);
        }
        if !self.joint.supervisor().latched().is_empty() {
            return Err(ErrorCode::Latched);
        }
        for (p, v) in volts.iter().enumerate() {
            for (k, c) in v.iter().enumerate() {
                if c.volts() > 0.0 && self.joint.supervisor().coil_tripped(p, k) {
                    return Err(ErrorCode::OverBudget);
                }
            }
        }
        let until = now + Duration::from_millis(u64::from(d.hold_ms));
        for (p, (slot, v)) in self.drive.iter_mut().zip(volts).enumerate() {
            if d.planes & (1 << p) != 0 {
                *slot = PlaneDrive::Driven { volts: v, until };
            }
        }
        Ok(())
    }

    /// Entering or leaving lockstep: outputs off, and the core starts a new
    /// time base (sensor checks, estimator, integrators, present fault
    /// causes). The arm state and latched faults are kept.
    fn enter_new_time_base(&mut self) {
        self.drive = [PlaneDrive::Control; 2];
        self.outputs_off();
        self.joint.restart_time_base();
        self.last_faults = self.joint.supervisor().latched();
        self.last_estimate = [f32::NAN; 2];
    }

    fn lockstep_step(&mut self, frame: HilSensor) -> Option<Message> {
        let Mode::Lockstep {
            period,
            anchor,
            last,
        } = self.mode
        else {
            return Some(Message::Nak(Nak {
                request: kind::HIL_SENSOR,
                code: ErrorCode::WrongMode,
            }));
        };
        // The seq difference as a signed window: ahead by up to 32767 is a
        // forward gap, behind by up to 32768 is a late frame.
        let (step, gap) = match last {
            None => (0, 1),
            Some(l) => {
                let diff = frame.seq.wrapping_sub(l.seq) as i16;
                if diff == 0 {
                    return Some(Message::HilActuator(l.reply)); // idempotent retry
                }
                if diff < 0 {
                    // A late retransmission of a step already answered: it
                    // must never step the core again. No reply (the host
                    // has moved on and is waiting for a newer seq).
                    self.stale_seqs = self.stale_seqs.saturating_add(1);
                    return None;
                }
                let gap = u64::from(diff.unsigned_abs());
                (l.step.saturating_add(gap), gap)
            }
        };
        let mut dt = period.saturating_mul(gap);
        if dt > self.link_timeout {
            // The host says more time passed than the link timeout allows
            // without the board in control: that is a link loss.
            self.joint.report_fault(Faults::LINK_LOSS);
            dt = self.link_timeout;
        }
        let input = StepInput {
            now: lockstep_instant(anchor, step, period),
            dt,
            feedback: Feedback::WireCounts(frame.counts.map(|c| Some(i32::from(c)))),
        };
        let out = self.joint.step(&input);
        self.set_pair_outputs(out.commands);
        self.last_faults = out.faults;
        self.last_estimate = out.estimate_deg;
        let reply = HilActuator {
            seq: frame.seq,
            pair_mv: out.commands.map(|c| pair_to_mv(c, self.joint.driver())),
            estimate_cdeg: out.estimate_deg.map(deg_to_cdeg),
            faults: faults_to_u8(out.faults),
        };
        self.mode = Mode::Lockstep {
            period,
            anchor,
            last: Some(LastStep {
                seq: frame.seq,
                step,
                reply,
            }),
        };
        Some(Message::HilActuator(reply))
    }

    /// The status report at board time `now`.
    pub fn status(&self, now: Instant) -> Status {
        let s = self.decoder.stats();
        let sat16 = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
        Status {
            armed: u8::from(self.joint.is_armed()),
            mode: u8::from(self.in_hil()),
            faults: faults_to_u8(self.last_faults),
            latched: faults_to_u8(self.joint.supervisor().latched()),
            estimate_deg: self.last_estimate,
            target_deg: self.joint.targets_deg(),
            pair_mv: self
                .pair_commands
                .map(|c| pair_to_mv(c, self.joint.driver())),
            coil_mv: self.coil_mv(),
            drive_planes: self.drive_planes(),
            time_ms: now.wrapping_millis_u32(),
            frames_ok: s.frames_ok,
            crc_errors: sat16(s.crc_errors),
            cobs_errors: sat16(s.cobs_errors),
            overfull: sat16(s.overfull),
            malformed: sat16(s.malformed),
            stale_seqs: sat16(self.stale_seqs),
        }
    }
}

fn emit(msg: &Message, send: &mut impl FnMut(&[u8])) {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode_frame(msg, &mut buf);
    if let Some(frame) = buf.get(..n) {
        if !frame.is_empty() {
            send(frame);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_3d_config_is_valid() {
        assert!(Joint3d::new(JointConfig::paper_3d()).is_ok());
    }
}
