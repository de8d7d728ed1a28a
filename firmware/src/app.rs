//! The board application: the protocol state machine around a [`Joint3d`].
//!
//! Portable and clock-free like the rest of the core. The firmware image
//! feeds it UART bytes and its SysTick time in milliseconds; the host test
//! harness feeds it bytes from one end of a pty pair. Replies go out through
//! a callback, one complete frame at a time.
//!
//! Modes:
//! - **free-running** (after reset): the board steps the joint itself every
//!   `period`, reading its own sensors through [`BoardSensors`], and streams
//!   [`Telemetry`] when asked. On QEMU there are no sensors, so the joint
//!   reports stale sensors and stays unpowered — as it should.
//! - **lockstep HIL** (after [`Message::HilStart`]): the host owns time. Each
//!   [`Message::HilSensor`] runs exactly one control step at simulated time
//!   `seq × period` and is answered with a [`Message::HilActuator`]. A
//!   repeated `seq` is answered from a cache without stepping again
//!   (idempotent retries). If no frame arrives for the link timeout (default
//!   50 ms of the board's clock), [`Faults::LINK_LOSS`] is latched and every
//!   output is zero until the host clears it.
//!
//! The pair rule and output bounds are the core's: outputs are
//! [`PairCommand`]s straight from the supervisor.

use crate::control::{PairCommand, PairGains};
use crate::joint::{Feedback, Joint3d, JointConfig, StepInput};
use crate::protocol::*;
use crate::supervisor::Faults;

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

/// Default free-running control period: 1 ms (1 kHz loop).
pub const DEFAULT_PERIOD_US: u32 = 1000;
/// Default link-loss timeout in lockstep mode (ms of the board's clock).
pub const DEFAULT_LINK_TIMEOUT_MS: u16 = 50;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Mode {
    FreeRunning,
    Hil {
        period_us: u32,
        last: Option<(u16, u32, ActuatorFrame)>,
    },
}

/// The application state.
pub struct App {
    joint: Joint3d,
    mode: Mode,
    decoder: FrameDecoder,
    outputs: [PairCommand; 2],
    last_faults: Faults,
    last_estimate: [f32; 2],
    link_timeout_ms: u16,
    last_frame_ms: Option<u32>,
    telemetry_hz: u16,
    next_telemetry_ms: u32,
    next_step_ms: u32,
}

fn faults_byte(f: Faults) -> u8 {
    faults_to_u8(f)
}

impl App {
    /// A board running the paper's 3D joint configuration, disarmed.
    pub fn new() -> Result<Self, crate::joint::ConfigError> {
        Ok(Self::with_joint(Joint3d::new(JointConfig::paper_3d())?))
    }

    /// A board around an already configured joint (disarmed until `Arm`).
    pub fn with_joint(mut joint: Joint3d) -> Self {
        joint.disarm();
        Self {
            joint,
            mode: Mode::FreeRunning,
            decoder: FrameDecoder::new(),
            outputs: [PairCommand::Off; 2],
            last_faults: Faults::NONE,
            last_estimate: [f32::NAN; 2],
            link_timeout_ms: DEFAULT_LINK_TIMEOUT_MS,
            last_frame_ms: None,
            telemetry_hz: 0,
            next_telemetry_ms: 0,
            next_step_ms: 0,
        }
    }

    /// What the SMA drivers must be set to now.
    pub fn outputs(&self) -> [PairCommand; 2] {
        self.outputs
    }

    /// The joint (read-only).
    pub fn joint(&self) -> &Joint3d {
        &self.joint
    }

    /// True in lockstep mode.
    pub fn in_hil(&self) -> bool {
        matches!(self.mode, Mode::Hil { .. })
    }

    /// Feeds one received byte at board time `now_ms`; replies are passed to
    /// `send` as complete frames.
    pub fn on_byte(&mut self, byte: u8, now_ms: u32, send: &mut impl FnMut(&[u8])) {
        match self.decoder.push(byte) {
            None => {}
            Some(Ok(msg)) => {
                self.last_frame_ms = Some(now_ms);
                if let Some(reply) = self.handle(msg, now_ms) {
                    emit(&reply, send);
                }
            }
            Some(Err(FrameError::Malformed { request, code })) => {
                // CRC-valid but not understood: tell the host.
                emit(&Message::Error { request, code }, send);
            }
            Some(Err(_)) => {} // counted; the host will retry
        }
    }

    /// Periodic work at board time `now_ms`: the link watchdog, the
    /// free-running control step and telemetry. Call it often (every
    /// millisecond or faster).
    pub fn poll(
        &mut self,
        now_ms: u32,
        sensors: &mut impl BoardSensors,
        send: &mut impl FnMut(&[u8]),
    ) {
        match self.mode {
            Mode::Hil { .. } => {
                if let Some(last) = self.last_frame_ms {
                    if now_ms.wrapping_sub(last) > u32::from(self.link_timeout_ms) {
                        if !self
                            .joint
                            .supervisor()
                            .latched()
                            .contains(Faults::LINK_LOSS)
                        {
                            log_warn!("link lost at {=u32} ms", now_ms);
                        }
                        self.joint.report_fault(Faults::LINK_LOSS);
                        self.outputs = [PairCommand::Off; 2];
                        self.last_faults |= Faults::LINK_LOSS;
                    }
                }
            }
            Mode::FreeRunning => {
                if now_ms.wrapping_sub(self.next_step_ms) < u32::MAX / 2 {
                    let period_ms = DEFAULT_PERIOD_US / 1000;
                    self.next_step_ms = now_ms.wrapping_add(period_ms);
                    let input = StepInput {
                        now_s: now_ms as f32 * 1e-3,
                        dt_s: DEFAULT_PERIOD_US as f32 * 1e-6,
                        feedback: Feedback::WireCounts(sensors.read_counts()),
                    };
                    let out = self.joint.step(&input);
                    self.outputs = out.commands;
                    self.last_faults = out.faults;
                    self.last_estimate = out.estimate_deg;
                }
                if self.telemetry_hz > 0
                    && now_ms.wrapping_sub(self.next_telemetry_ms) < u32::MAX / 2
                {
                    let interval = (1000 / u32::from(self.telemetry_hz)).max(1);
                    self.next_telemetry_ms = now_ms.wrapping_add(interval);
                    let t = Telemetry {
                        time_ms: now_ms,
                        estimate_deg: self.last_estimate,
                        pair_mv: self.outputs.map(|c| pair_to_mv(c, self.joint.driver())),
                        faults: faults_byte(self.last_faults),
                    };
                    emit(&Message::Telemetry(t), send);
                }
            }
        }
    }

    /// Handles one decoded message; returns the reply, if any.
    pub fn handle(&mut self, msg: Message, now_ms: u32) -> Option<Message> {
        let request = msg.kind();
        let err = |code| Some(Message::Error { request, code });
        let ack = Some(Message::Ack { request });
        match msg {
            Message::Hello { version } => {
                if version != PROTOCOL_VERSION {
                    return err(ErrorCode::Version);
                }
                Some(Message::HelloAck {
                    version: PROTOCOL_VERSION,
                    schema: SCHEMA_HASH,
                    pairs: 2,
                    sensors: 4,
                })
            }
            Message::HilStart { period_us } => {
                if !(100..=1_000_000).contains(&period_us) {
                    return err(ErrorCode::OutOfRange);
                }
                self.mode = Mode::Hil {
                    period_us,
                    last: None,
                };
                self.outputs = [PairCommand::Off; 2];
                // Simulated time starts at seq × period: a new time base.
                self.joint.restart_time_base();
                self.last_faults = self.joint.supervisor().latched();
                ack
            }
            Message::HilSensor(frame) => self.hil_step(frame),
            Message::SetTarget { plane, target_deg } => {
                if !target_deg.is_finite() {
                    return err(ErrorCode::NotFinite);
                }
                match self.joint.set_target(usize::from(plane), target_deg) {
                    Ok(()) => ack,
                    Err(_) => err(ErrorCode::OutOfRange),
                }
            }
            Message::SetGains {
                plane,
                kp_agonist,
                kp_antagonist,
                ki,
                integral_limit_v,
            } => {
                if ![kp_agonist, kp_antagonist, ki, integral_limit_v]
                    .iter()
                    .all(|v| v.is_finite())
                {
                    return err(ErrorCode::NotFinite);
                }
                // Bad gains and a plane the joint does not have are both
                // out of range; the joint owns the plane check.
                let set = PairGains::new(kp_agonist, kp_antagonist, ki, integral_limit_v)
                    .map_err(crate::joint::ConfigError::from)
                    .and_then(|g| self.joint.set_gains(usize::from(plane), g));
                match set {
                    Ok(()) => ack,
                    Err(_) => err(ErrorCode::OutOfRange),
                }
            }
            Message::SetCalibration { plane, law } => {
                match self.joint.set_law(usize::from(plane), law) {
                    Ok(()) => ack,
                    Err(crate::joint::ConfigError::Calibration(
                        crate::estimate::CalibrationError::CoefficientNotFinite,
                    ))
                    | Err(crate::joint::ConfigError::Calibration(
                        crate::estimate::CalibrationError::ThresholdNotFinite,
                    )) => err(ErrorCode::NotFinite),
                    Err(_) => err(ErrorCode::OutOfRange),
                }
            }
            Message::GetCalibration { plane } => match self.joint.law(usize::from(plane)) {
                Some(law) => Some(Message::Calibration { plane, law }),
                None => err(ErrorCode::OutOfRange),
            },
            Message::Arm => {
                self.joint.arm();
                ack
            }
            Message::Disarm => {
                self.joint.disarm();
                self.outputs = [PairCommand::Off; 2];
                ack
            }
            Message::ClearFaults => match self.joint.clear_faults() {
                Ok(()) => {
                    self.last_faults = Faults::NONE;
                    ack
                }
                Err(_) => err(ErrorCode::StillFaulted),
            },
            Message::GetStatus => Some(Message::Status(self.status(now_ms))),
            Message::SetTelemetry { rate_hz } => {
                if rate_hz > 1000 {
                    return err(ErrorCode::OutOfRange);
                }
                self.telemetry_hz = rate_hz;
                self.next_telemetry_ms = now_ms;
                ack
            }
            Message::SetLinkTimeout { timeout_ms } => {
                if timeout_ms == 0 || timeout_ms > 60_000 {
                    return err(ErrorCode::OutOfRange);
                }
                self.link_timeout_ms = timeout_ms;
                ack
            }
            // Board-to-host messages are not requests.
            Message::HelloAck { .. }
            | Message::HilActuator(_)
            | Message::Calibration { .. }
            | Message::Status(_)
            | Message::Telemetry(_)
            | Message::Ack { .. }
            | Message::Error { .. } => err(ErrorCode::UnknownType),
        }
    }

    fn hil_step(&mut self, frame: SensorFrame) -> Option<Message> {
        let Mode::Hil { period_us, last } = self.mode else {
            return Some(Message::Error {
                request: kind::HIL_SENSOR,
                code: ErrorCode::WrongMode,
            });
        };
        if let Some((seq, _, reply)) = last {
            if seq == frame.seq {
                return Some(Message::HilActuator(reply)); // idempotent retry
            }
        }
        // Extend the wrapping u16 sequence to a step count.
        let (step, gap) = match last {
            None => (u32::from(frame.seq), 1),
            Some((seq, step, _)) => {
                let gap = u32::from(frame.seq.wrapping_sub(seq));
                (step.wrapping_add(gap), gap)
            }
        };
        let (now_s, dt_s) = lockstep_times(step, gap, period_us);
        let input = StepInput {
            now_s,
            dt_s,
            feedback: Feedback::WireCounts(frame.counts.map(|c| Some(i32::from(c)))),
        };
        let out = self.joint.step(&input);
        self.outputs = out.commands;
        self.last_faults = out.faults;
        self.last_estimate = out.estimate_deg;
        let reply = ActuatorFrame {
            seq: frame.seq,
            pair_mv: out.commands.map(|c| pair_to_mv(c, self.joint.driver())),
            estimate_cdeg: out.estimate_deg.map(deg_to_cdeg),
            faults: faults_byte(out.faults),
        };
        self.mode = Mode::Hil {
            period_us,
            last: Some((frame.seq, step, reply)),
        };
        Some(Message::HilActuator(reply))
    }

    /// The status report.
    pub fn status(&self, now_ms: u32) -> Status {
        let s = self.decoder.stats();
        let sat16 = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
        Status {
            armed: u8::from(self.joint.is_armed()),
            mode: u8::from(self.in_hil()),
            faults: faults_byte(self.last_faults),
            latched: faults_byte(self.joint.supervisor().latched()),
            estimate_deg: self.last_estimate,
            target_deg: self.joint.targets_deg(),
            pair_mv: self.outputs.map(|c| pair_to_mv(c, self.joint.driver())),
            time_ms: now_ms,
            frames_ok: s.frames_ok,
            crc_errors: sat16(s.crc_errors),
            cobs_errors: sat16(s.cobs_errors),
            overfull: sat16(s.overfull),
            malformed: sat16(s.malformed),
        }
    }
}

/// Simulated time and step length of lockstep step number `step`, `gap`
/// periods after the previous one, in the exact f32 arithmetic the board
/// uses — so a host simulation that calls this reproduces the board's inputs
/// bit for bit.
pub fn lockstep_times(step: u32, gap: u32, period_us: u32) -> (f32, f32) {
    let period_s = period_us as f32 * 1e-6;
    (step as f32 * period_s, gap as f32 * period_s)
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
