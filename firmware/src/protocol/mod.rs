//! The serial protocol between a host and the board (or the firmware image
//! under QEMU). Specified byte for byte in `docs/protocol.md`; this module is
//! its one implementation, used by the firmware and by the host tools.
//!
//! Wire format: `COBS(payload ‖ CRC16-LE) ‖ 0x00`. The payload is one message
//! in an explicit little-endian layout: a type byte, then fixed-size fields.
//! Every message type has exactly one valid length, so a frame whose
//! structure was damaged is rejected even before its CRC is compared.
//!
//! Lockstep hardware-in-the-loop frames are kept short (15 and 16 bytes on
//! the wire) because the emulated UART costs about 51 µs per byte: the host
//! owns time, simulated time is `seq × period` with the period fixed by
//! [`Message::HilStart`], so the sensor frame carries no time field.

pub mod cobs;
pub mod crc;

use crate::control::{DriverConfig, PairCommand};
use crate::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};
use crate::supervisor::Faults;

/// Protocol version; bumped on any incompatible change.
pub const PROTOCOL_VERSION: u8 = 1;

/// A compact description of every message layout. Its FNV-1a hash is
/// exchanged in the handshake, so two ends built from different layouts
/// notice at once.
pub const SCHEMA: &str = "softjoint-proto v1|01 hello u8|02 hil_start u32|03 hil_sensor u16 4*i16|\
10 set_target u8 f32|11 set_gains u8 4*f32|12 set_calibration u8 law32|13 get_calibration u8|\
14 arm|15 disarm|16 clear_faults|17 get_status|18 set_telemetry u16|19 set_link_timeout u16|\
81 hello_ack u8 u32 u8 u8|83 hil_actuator u16 2*i16 2*i16 u8|93 calibration u8 law32|\
97 status 4*u8 4*f32 2*i16 2*u32 4*u16|a0 telemetry u32 2*f32 2*i16 u8|f0 ack u8|ee error u8 u8|\
law32 u8 3*u8 7*f32|crc16-ccitt-false le|cobs 0x00";

/// FNV-1a (32-bit) of [`SCHEMA`].
pub const SCHEMA_HASH: u32 = fnv1a(SCHEMA.as_bytes());

const fn fnv1a(bytes: &[u8]) -> u32 {
    let mut h: u32 = 0x811C_9DC5;
    let mut i = 0;
    while i < bytes.len() {
        h ^= bytes[i] as u32;
        h = h.wrapping_mul(0x0100_0193);
        i += 1;
    }
    h
}

/// Largest payload (type byte included, CRC excluded) of any message.
pub const MAX_PAYLOAD: usize = 48;
/// Largest frame on the wire: COBS of payload + CRC, plus the delimiter.
pub const MAX_FRAME: usize = cobs::max_encoded_len(MAX_PAYLOAD + 2) + 1;

/// Message type bytes.
pub mod kind {
    #![allow(missing_docs)]
    pub const HELLO: u8 = 0x01;
    pub const HIL_START: u8 = 0x02;
    pub const HIL_SENSOR: u8 = 0x03;
    pub const SET_TARGET: u8 = 0x10;
    pub const SET_GAINS: u8 = 0x11;
    pub const SET_CALIBRATION: u8 = 0x12;
    pub const GET_CALIBRATION: u8 = 0x13;
    pub const ARM: u8 = 0x14;
    pub const DISARM: u8 = 0x15;
    pub const CLEAR_FAULTS: u8 = 0x16;
    pub const GET_STATUS: u8 = 0x17;
    pub const SET_TELEMETRY: u8 = 0x18;
    pub const SET_LINK_TIMEOUT: u8 = 0x19;
    pub const HELLO_ACK: u8 = 0x81;
    pub const HIL_ACTUATOR: u8 = 0x83;
    pub const CALIBRATION: u8 = 0x93;
    pub const STATUS: u8 = 0x97;
    pub const TELEMETRY: u8 = 0xA0;
    pub const ACK: u8 = 0xF0;
    pub const ERROR: u8 = 0xEE;
}

/// Error codes carried by [`Message::Error`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum ErrorCode {
    /// The type byte is not a message the receiver accepts.
    UnknownType = 1,
    /// The payload length does not match the type.
    BadLength = 2,
    /// A field is outside its documented range.
    OutOfRange = 3,
    /// A float field is NaN or infinite.
    NotFinite = 4,
    /// The request is not valid in the current mode (e.g. a sensor frame
    /// before `HilStart`).
    WrongMode = 5,
    /// `ClearFaults` refused: a fault's cause is still present.
    StillFaulted = 6,
    /// The protocol version in `Hello` is not supported.
    Version = 7,
}

impl ErrorCode {
    /// From the wire byte.
    pub fn from_u8(b: u8) -> Option<Self> {
        Some(match b {
            1 => Self::UnknownType,
            2 => Self::BadLength,
            3 => Self::OutOfRange,
            4 => Self::NotFinite,
            5 => Self::WrongMode,
            6 => Self::StillFaulted,
            7 => Self::Version,
            _ => return None,
        })
    }
}

/// One lockstep sensor frame (host → board).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorFrame {
    /// Step number, wrapping; simulated time is `seq × period`.
    pub seq: u16,
    /// Pulse-coder counts of wire sensors 1–4 (unused sensors 0).
    pub counts: [i16; 4],
}

/// One lockstep actuator frame (board → host).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ActuatorFrame {
    /// The `seq` of the sensor frame answered.
    pub seq: u16,
    /// Per pair (α, β): driver input in millivolts, positive on the agonist,
    /// negative on the antagonist (so a pair can never report both).
    pub pair_mv: [i16; 2],
    /// Angle estimates (α, β) in centidegrees; `i16::MIN` = no estimate.
    pub estimate_cdeg: [i16; 2],
    /// Fault flags ([`Faults`] bits 0–7).
    pub faults: u8,
}

/// Board status (reply to `GetStatus`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Status {
    /// 1 when armed.
    pub armed: u8,
    /// 0 free-running, 1 lockstep HIL.
    pub mode: u8,
    /// Faults reported on the last step (active or latched).
    pub faults: u8,
    /// Faults latched now.
    pub latched: u8,
    /// Estimates α, β (deg); NaN before the first reading.
    pub estimate_deg: [f32; 2],
    /// Targets α, β (deg).
    pub target_deg: [f32; 2],
    /// Outputs now, as in [`ActuatorFrame::pair_mv`].
    pub pair_mv: [i16; 2],
    /// Board clock (ms since boot, wrapping).
    pub time_ms: u32,
    /// Frames received and decoded.
    pub frames_ok: u32,
    /// Frames dropped: CRC mismatch.
    pub crc_errors: u16,
    /// Frames dropped: bad COBS.
    pub cobs_errors: u16,
    /// Frames dropped: longer than the maximum.
    pub overfull: u16,
    /// Frames dropped: unknown type, bad length or bad field.
    pub malformed: u16,
}

/// Streamed state in free-running mode.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Telemetry {
    /// Board clock (ms since boot, wrapping).
    pub time_ms: u32,
    /// Estimates α, β (deg).
    pub estimate_deg: [f32; 2],
    /// Outputs, as in [`ActuatorFrame::pair_mv`].
    pub pair_mv: [i16; 2],
    /// Fault flags.
    pub faults: u8,
}

/// Every message of the protocol.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Message {
    /// Handshake request with the host's protocol version.
    Hello {
        /// Host's [`PROTOCOL_VERSION`].
        version: u8,
    },
    /// Enter lockstep mode with a control period in microseconds.
    HilStart {
        /// Control period (µs), 100..=1_000_000.
        period_us: u32,
    },
    /// A lockstep sensor frame.
    HilSensor(SensorFrame),
    /// Set a plane's desired angle.
    SetTarget {
        /// 0 = α, 1 = β.
        plane: u8,
        /// Desired angle (deg).
        target_deg: f32,
    },
    /// Set a plane's gains.
    SetGains {
        /// 0 = α, 1 = β.
        plane: u8,
        /// Agonist Kp (V/deg).
        kp_agonist: f32,
        /// Antagonist Kp (V/deg).
        kp_antagonist: f32,
        /// Ki (V/(deg·s)).
        ki: f32,
        /// Integral limit (V).
        integral_limit_v: f32,
    },
    /// Set a plane's estimation law.
    SetCalibration {
        /// 0 = α, 1 = β.
        plane: u8,
        /// The law.
        law: PlaneLaw,
    },
    /// Ask for a plane's estimation law.
    GetCalibration {
        /// 0 = α, 1 = β.
        plane: u8,
    },
    /// Allow outputs.
    Arm,
    /// Force outputs off.
    Disarm,
    /// Clear latched faults.
    ClearFaults,
    /// Ask for [`Status`].
    GetStatus,
    /// Stream telemetry at `rate_hz` (0 = off), free-running mode.
    SetTelemetry {
        /// Frames per second, 0..=1000.
        rate_hz: u16,
    },
    /// Set the link-loss timeout (ms of the board's clock), 1..=60000.
    SetLinkTimeout {
        /// Timeout (ms).
        timeout_ms: u16,
    },
    /// Handshake reply.
    HelloAck {
        /// Board's [`PROTOCOL_VERSION`].
        version: u8,
        /// Board's [`SCHEMA_HASH`].
        schema: u32,
        /// Antagonistic pairs.
        pairs: u8,
        /// Wire sensors.
        sensors: u8,
    },
    /// A lockstep actuator frame.
    HilActuator(ActuatorFrame),
    /// Reply to `GetCalibration`.
    Calibration {
        /// 0 = α, 1 = β.
        plane: u8,
        /// The law.
        law: PlaneLaw,
    },
    /// Reply to `GetStatus`.
    Status(Status),
    /// Telemetry frame.
    Telemetry(Telemetry),
    /// A request was carried out.
    Ack {
        /// Type byte of the request.
        request: u8,
    },
    /// A request was refused.
    Error {
        /// Type byte of the request (0 if unknown).
        request: u8,
        /// Why.
        code: ErrorCode,
    },
}

/// Why a received frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// More bytes than [`MAX_FRAME`] before a delimiter.
    Overfull,
    /// The COBS encoding was invalid.
    Cobs,
    /// Shorter than a type byte plus CRC.
    TooShort,
    /// CRC mismatch.
    Crc,
    /// CRC-valid, but the type is unknown or the length is wrong for it.
    Malformed {
        /// Type byte.
        request: u8,
        /// [`ErrorCode::UnknownType`] or [`ErrorCode::BadLength`] or
        /// [`ErrorCode::OutOfRange`] (bad enum value inside).
        code: ErrorCode,
    },
}

/// Counters of what a decoder saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkStats {
    /// Frames decoded.
    pub frames_ok: u32,
    /// CRC mismatches.
    pub crc_errors: u32,
    /// COBS errors and frames too short to hold a CRC.
    pub cobs_errors: u32,
    /// Frames longer than the maximum.
    pub overfull: u32,
    /// CRC-valid frames with an unknown type or a bad length.
    pub malformed: u32,
}

struct Writer<'a> {
    buf: &'a mut [u8],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, bytes: &[u8]) -> Option<()> {
        self.buf
            .get_mut(self.at..self.at + bytes.len())?
            .copy_from_slice(bytes);
        self.at += bytes.len();
        Some(())
    }
    fn u8(&mut self, v: u8) -> Option<()> {
        self.put(&[v])
    }
    fn u16(&mut self, v: u16) -> Option<()> {
        self.put(&v.to_le_bytes())
    }
    fn i16(&mut self, v: i16) -> Option<()> {
        self.put(&v.to_le_bytes())
    }
    fn u32(&mut self, v: u32) -> Option<()> {
        self.put(&v.to_le_bytes())
    }
    fn f32(&mut self, v: f32) -> Option<()> {
        self.put(&v.to_le_bytes())
    }
    fn law(&mut self, law: &PlaneLaw) -> Option<()> {
        let (kind, plus, minus, sensor, f) = law_fields(law);
        self.u8(kind)?;
        self.u8(plus)?;
        self.u8(minus)?;
        self.u8(sensor)?;
        f.iter().try_for_each(|v| self.f32(*v))
    }
}

/// Flattens a law to its wire fields: kind, plus, minus, sensor and
/// `[gain, offset, a, b, c, threshold, hysteresis]` (unused fields 0).
fn law_fields(law: &PlaneLaw) -> (u8, u8, u8, u8, [f32; 7]) {
    match *law {
        PlaneLaw::Single { sensor, law } => {
            (0, 0, 0, sensor, [0.0, 0.0, law.a, law.b, law.c, 0.0, 0.0])
        }
        PlaneLaw::Differential { plus, minus, law } => (
            1,
            plus,
            minus,
            0,
            [law.gain, law.offset, 0.0, 0.0, 0.0, 0.0, 0.0],
        ),
        PlaneLaw::Switching {
            plus,
            minus,
            high,
            sensor,
            low,
            threshold_deg,
            hysteresis_deg,
        } => (
            2,
            plus,
            minus,
            sensor,
            [
                high.gain,
                high.offset,
                low.a,
                low.b,
                low.c,
                threshold_deg,
                hysteresis_deg,
            ],
        ),
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Option<[u8; N]> {
        let s = self.buf.get(self.at..self.at + N)?;
        self.at += N;
        s.try_into().ok()
    }
    fn u8(&mut self) -> Option<u8> {
        self.take::<1>().map(|b| b[0])
    }
    fn u16(&mut self) -> Option<u16> {
        self.take().map(u16::from_le_bytes)
    }
    fn i16(&mut self) -> Option<i16> {
        self.take().map(i16::from_le_bytes)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take().map(u32::from_le_bytes)
    }
    fn f32(&mut self) -> Option<f32> {
        self.take().map(f32::from_le_bytes)
    }
    /// A law; `None` on a bad kind (reported as out of range).
    fn law(&mut self) -> Option<Option<PlaneLaw>> {
        let kind = self.u8()?;
        let plus = self.u8()?;
        let minus = self.u8()?;
        let sensor = self.u8()?;
        let mut f = [0.0f32; 7];
        for v in f.iter_mut() {
            *v = self.f32()?;
        }
        let [gain, offset, a, b, c, threshold_deg, hysteresis_deg] = f;
        Some(match kind {
            0 => Some(PlaneLaw::Single {
                sensor,
                law: QuadraticLaw { a, b, c },
            }),
            1 => Some(PlaneLaw::Differential {
                plus,
                minus,
                law: LinearLaw { gain, offset },
            }),
            2 => Some(PlaneLaw::Switching {
                plus,
                minus,
                high: LinearLaw { gain, offset },
                sensor,
                low: QuadraticLaw { a, b, c },
                threshold_deg,
                hysteresis_deg,
            }),
            _ => None,
        })
    }
}

/// Payload length (type byte included) of each message type, or `None`
/// for an unknown type.
pub fn payload_len(kind_byte: u8) -> Option<usize> {
    use kind::*;
    Some(match kind_byte {
        HELLO => 2,
        HIL_START => 5,
        HIL_SENSOR => 11,
        SET_TARGET => 6,
        SET_GAINS => 18,
        SET_CALIBRATION | CALIBRATION => 34,
        GET_CALIBRATION => 2,
        ARM | DISARM | CLEAR_FAULTS | GET_STATUS => 1,
        SET_TELEMETRY | SET_LINK_TIMEOUT => 3,
        HELLO_ACK => 8,
        HIL_ACTUATOR => 12,
        STATUS => 41,
        TELEMETRY => 18,
        ACK => 2,
        ERROR => 3,
        _ => return None,
    })
}

impl Message {
    /// The type byte.
    pub fn kind(&self) -> u8 {
        use kind::*;
        match self {
            Message::Hello { .. } => HELLO,
            Message::HilStart { .. } => HIL_START,
            Message::HilSensor(_) => HIL_SENSOR,
            Message::SetTarget { .. } => SET_TARGET,
            Message::SetGains { .. } => SET_GAINS,
            Message::SetCalibration { .. } => SET_CALIBRATION,
            Message::GetCalibration { .. } => GET_CALIBRATION,
            Message::Arm => ARM,
            Message::Disarm => DISARM,
            Message::ClearFaults => CLEAR_FAULTS,
            Message::GetStatus => GET_STATUS,
            Message::SetTelemetry { .. } => SET_TELEMETRY,
            Message::SetLinkTimeout { .. } => SET_LINK_TIMEOUT,
            Message::HelloAck { .. } => HELLO_ACK,
            Message::HilActuator(_) => HIL_ACTUATOR,
            Message::Calibration { .. } => CALIBRATION,
            Message::Status(_) => STATUS,
            Message::Telemetry(_) => TELEMETRY,
            Message::Ack { .. } => ACK,
            Message::Error { .. } => ERROR,
        }
    }

    /// Writes the payload (type byte first) into `buf`; returns its length.
    pub fn write_payload(&self, buf: &mut [u8]) -> Option<usize> {
        let mut w = Writer { buf, at: 0 };
        w.u8(self.kind())?;
        match self {
            Message::Hello { version } => w.u8(*version)?,
            Message::HilStart { period_us } => w.u32(*period_us)?,
            Message::HilSensor(f) => {
                w.u16(f.seq)?;
                f.counts.iter().try_for_each(|c| w.i16(*c))?;
            }
            Message::SetTarget { plane, target_deg } => {
                w.u8(*plane)?;
                w.f32(*target_deg)?;
            }
            Message::SetGains {
                plane,
                kp_agonist,
                kp_antagonist,
                ki,
                integral_limit_v,
            } => {
                w.u8(*plane)?;
                [*kp_agonist, *kp_antagonist, *ki, *integral_limit_v]
                    .iter()
                    .try_for_each(|v| w.f32(*v))?;
            }
            Message::SetCalibration { plane, law } | Message::Calibration { plane, law } => {
                w.u8(*plane)?;
                w.law(law)?;
            }
            Message::GetCalibration { plane } => w.u8(*plane)?,
            Message::Arm | Message::Disarm | Message::ClearFaults | Message::GetStatus => {}
            Message::SetTelemetry { rate_hz } => w.u16(*rate_hz)?,
            Message::SetLinkTimeout { timeout_ms } => w.u16(*timeout_ms)?,
            Message::HelloAck {
                version,
                schema,
                pairs,
                sensors,
            } => {
                w.u8(*version)?;
                w.u32(*schema)?;
                w.u8(*pairs)?;
                w.u8(*sensors)?;
            }
            Message::HilActuator(a) => {
                w.u16(a.seq)?;
                a.pair_mv.iter().try_for_each(|v| w.i16(*v))?;
                a.estimate_cdeg.iter().try_for_each(|v| w.i16(*v))?;
                w.u8(a.faults)?;
            }
            Message::Status(s) => {
                [s.armed, s.mode, s.faults, s.latched]
                    .iter()
                    .try_for_each(|v| w.u8(*v))?;
                s.estimate_deg
                    .iter()
                    .chain(s.target_deg.iter())
                    .try_for_each(|v| w.f32(*v))?;
                s.pair_mv.iter().try_for_each(|v| w.i16(*v))?;
                w.u32(s.time_ms)?;
                w.u32(s.frames_ok)?;
                [s.crc_errors, s.cobs_errors, s.overfull, s.malformed]
                    .iter()
                    .try_for_each(|v| w.u16(*v))?;
            }
            Message::Telemetry(t) => {
                w.u32(t.time_ms)?;
                t.estimate_deg.iter().try_for_each(|v| w.f32(*v))?;
                t.pair_mv.iter().try_for_each(|v| w.i16(*v))?;
                w.u8(t.faults)?;
            }
            Message::Ack { request } => w.u8(*request)?,
            Message::Error { request, code } => {
                w.u8(*request)?;
                w.u8(*code as u8)?;
            }
        }
        Some(w.at)
    }

    /// Parses a payload (type byte first, CRC already removed).
    pub fn read_payload(payload: &[u8]) -> Result<Message, FrameError> {
        let kind_byte = payload.first().copied().ok_or(FrameError::TooShort)?;
        let malformed = |code| FrameError::Malformed {
            request: kind_byte,
            code,
        };
        let expect = payload_len(kind_byte).ok_or(malformed(ErrorCode::UnknownType))?;
        if payload.len() != expect {
            return Err(malformed(ErrorCode::BadLength));
        }
        let mut r = Reader {
            buf: payload,
            at: 1,
        };
        let bad_len = malformed(ErrorCode::BadLength);
        let parsed = (|| -> Option<Result<Message, FrameError>> {
            use kind::*;
            Some(Ok(match kind_byte {
                HELLO => Message::Hello { version: r.u8()? },
                HIL_START => Message::HilStart {
                    period_us: r.u32()?,
                },
                HIL_SENSOR => {
                    let seq = r.u16()?;
                    let mut counts = [0i16; 4];
                    for c in counts.iter_mut() {
                        *c = r.i16()?;
                    }
                    Message::HilSensor(SensorFrame { seq, counts })
                }
                SET_TARGET => Message::SetTarget {
                    plane: r.u8()?,
                    target_deg: r.f32()?,
                },
                SET_GAINS => Message::SetGains {
                    plane: r.u8()?,
                    kp_agonist: r.f32()?,
                    kp_antagonist: r.f32()?,
                    ki: r.f32()?,
                    integral_limit_v: r.f32()?,
                },
                SET_CALIBRATION | CALIBRATION => {
                    let plane = r.u8()?;
                    let Some(law) = r.law()? else {
                        return Some(Err(malformed(ErrorCode::OutOfRange)));
                    };
                    if kind_byte == SET_CALIBRATION {
                        Message::SetCalibration { plane, law }
                    } else {
                        Message::Calibration { plane, law }
                    }
                }
                GET_CALIBRATION => Message::GetCalibration { plane: r.u8()? },
                ARM => Message::Arm,
                DISARM => Message::Disarm,
                CLEAR_FAULTS => Message::ClearFaults,
                GET_STATUS => Message::GetStatus,
                SET_TELEMETRY => Message::SetTelemetry { rate_hz: r.u16()? },
                SET_LINK_TIMEOUT => Message::SetLinkTimeout {
                    timeout_ms: r.u16()?,
                },
                HELLO_ACK => Message::HelloAck {
                    version: r.u8()?,
                    schema: r.u32()?,
                    pairs: r.u8()?,
                    sensors: r.u8()?,
                },
                HIL_ACTUATOR => Message::HilActuator(ActuatorFrame {
                    seq: r.u16()?,
                    pair_mv: [r.i16()?, r.i16()?],
                    estimate_cdeg: [r.i16()?, r.i16()?],
                    faults: r.u8()?,
                }),
                STATUS => Message::Status(Status {
                    armed: r.u8()?,
                    mode: r.u8()?,
                    faults: r.u8()?,
                    latched: r.u8()?,
                    estimate_deg: [r.f32()?, r.f32()?],
                    target_deg: [r.f32()?, r.f32()?],
                    pair_mv: [r.i16()?, r.i16()?],
                    time_ms: r.u32()?,
                    frames_ok: r.u32()?,
                    crc_errors: r.u16()?,
                    cobs_errors: r.u16()?,
                    overfull: r.u16()?,
                    malformed: r.u16()?,
                }),
                TELEMETRY => Message::Telemetry(Telemetry {
                    time_ms: r.u32()?,
                    estimate_deg: [r.f32()?, r.f32()?],
                    pair_mv: [r.i16()?, r.i16()?],
                    faults: r.u8()?,
                }),
                ACK => Message::Ack { request: r.u8()? },
                ERROR => {
                    let request = r.u8()?;
                    let Some(code) = ErrorCode::from_u8(r.u8()?) else {
                        return Some(Err(malformed(ErrorCode::OutOfRange)));
                    };
                    Message::Error { request, code }
                }
                _ => return Some(Err(malformed(ErrorCode::UnknownType))),
            }))
        })();
        parsed.unwrap_or(Err(bad_len))
    }
}

/// Encodes `msg` as a complete frame (ending in 0x00) into `out`; returns
/// the frame length.
pub fn encode_frame(msg: &Message, out: &mut [u8; MAX_FRAME]) -> usize {
    let mut raw = [0u8; MAX_PAYLOAD + 2];
    // Every message fits MAX_PAYLOAD by construction (checked in tests);
    // a failure here yields an empty frame, which receivers ignore.
    let Some(n) = msg.write_payload(&mut raw[..MAX_PAYLOAD]) else {
        return 0;
    };
    let crc = crc::crc16(&raw[..n]).to_le_bytes();
    raw[n..n + 2].copy_from_slice(&crc);
    match cobs::encode(&raw[..n + 2], &mut out[..MAX_FRAME - 1]) {
        Ok(len) => {
            out[len] = 0;
            len + 1
        }
        Err(_) => 0,
    }
}

/// Accumulates bytes from the wire and yields messages. Resynchronises on
/// every 0x00: whatever garbage precedes a delimiter costs at most the frame
/// it lands in. Never allocates; never panics.
pub struct FrameDecoder {
    buf: [u8; MAX_FRAME],
    len: usize,
    overflowed: bool,
    stats: LinkStats,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder.
    pub const fn new() -> Self {
        Self {
            buf: [0; MAX_FRAME],
            len: 0,
            overflowed: false,
            stats: LinkStats {
                frames_ok: 0,
                crc_errors: 0,
                cobs_errors: 0,
                overfull: 0,
                malformed: 0,
            },
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Feeds one byte. Returns `Some` when a delimiter completes a
    /// non-empty frame: the message, or why it was dropped (also counted).
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        if byte != 0 {
            if self.len < self.buf.len() {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflowed = true;
            }
            return None;
        }
        let len = core::mem::replace(&mut self.len, 0);
        if core::mem::replace(&mut self.overflowed, false) {
            self.stats.overfull = self.stats.overfull.saturating_add(1);
            return Some(Err(FrameError::Overfull));
        }
        if len == 0 {
            return None; // empty frame: a flush, not an error
        }
        let result = Self::decode(&self.buf[..len]);
        let s = &mut self.stats;
        match result {
            Ok(_) => s.frames_ok = s.frames_ok.saturating_add(1),
            Err(FrameError::Crc) => s.crc_errors = s.crc_errors.saturating_add(1),
            Err(FrameError::Cobs | FrameError::TooShort) => {
                s.cobs_errors = s.cobs_errors.saturating_add(1)
            }
            Err(FrameError::Overfull) => s.overfull = s.overfull.saturating_add(1),
            Err(FrameError::Malformed { .. }) => s.malformed = s.malformed.saturating_add(1),
        }
        Some(result)
    }

    /// Decodes one frame's bytes (delimiter removed).
    pub fn decode(encoded: &[u8]) -> Result<Message, FrameError> {
        let mut raw = [0u8; MAX_FRAME];
        let n = cobs::decode(encoded, &mut raw).map_err(|_| FrameError::Cobs)?;
        if n < 3 {
            return Err(FrameError::TooShort);
        }
        let (payload, crc) = raw[..n].split_at(n - 2);
        if crc16_le(crc) != crc::crc16(payload) {
            return Err(FrameError::Crc);
        }
        Message::read_payload(payload)
    }
}

fn crc16_le(b: &[u8]) -> u16 {
    match b {
        [lo, hi] => u16::from_le_bytes([*lo, *hi]),
        _ => 0,
    }
}

/// Encodes a pair command as signed millivolts (+ agonist, − antagonist).
/// Uses the same rounding as a PWM channel whose full scale is the supply in
/// millivolts ([`volts_to_duty`](crate::control::volts_to_duty)), so a
/// simulator driving such a channel and a host receiving these frames see
/// identical values.
pub fn pair_to_mv(cmd: PairCommand, driver: &DriverConfig) -> i16 {
    let full_scale = millivolt_full_scale(driver);
    let mv =
        |v| i16::try_from(crate::control::volts_to_duty(v, driver, full_scale)).unwrap_or(i16::MAX);
    match cmd {
        PairCommand::Off => 0,
        PairCommand::Agonist(v) => mv(v),
        PairCommand::Antagonist(v) => -mv(v),
    }
}

/// The supply in millivolts, as a duty-cycle full scale (saturating).
pub fn millivolt_full_scale(driver: &DriverConfig) -> u16 {
    let mv = num_traits::Float::round(driver.supply_v() * 1000.0);
    if mv >= f32::from(i16::MAX) {
        i16::MAX as u16
    } else if mv >= 1.0 {
        mv as u16
    } else {
        1
    }
}

/// Decodes signed millivolts into a pair command, clamped to the driver.
pub fn mv_to_pair(mv: i16, driver: &DriverConfig) -> PairCommand {
    let v = f32::from(mv) / 1000.0;
    match mv {
        0 => PairCommand::Off,
        m if m > 0 => PairCommand::Agonist(driver.clamp(v)),
        _ => PairCommand::Antagonist(driver.clamp(-v)),
    }
}

/// Angle in centidegrees for the wire (`i16::MIN` for NaN; saturating).
pub fn deg_to_cdeg(deg: f32) -> i16 {
    if deg.is_nan() {
        return i16::MIN;
    }
    let c = num_traits::Float::round(deg * 100.0);
    if c >= f32::from(i16::MAX) {
        i16::MAX
    } else if c <= f32::from(i16::MIN + 1) {
        i16::MIN + 1
    } else {
        c as i16
    }
}

/// Centidegrees from the wire to degrees (NaN for `i16::MIN`).
pub fn cdeg_to_deg(c: i16) -> f32 {
    if c == i16::MIN {
        f32::NAN
    } else {
        f32::from(c) / 100.0
    }
}

/// Fault flags to their wire byte (all defined flags fit in 8 bits).
pub fn faults_to_u8(f: Faults) -> u8 {
    (f.bits() & 0xFF) as u8
}
