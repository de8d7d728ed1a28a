//! Every message of the protocol, declared once.
//!
//! The table below is the single definition of the message set. From it the
//! [`protocol_messages!`] macro generates the type bytes ([`kind`]), one
//! struct per message, the [`Message`] enum, each payload's length, the
//! encoder and decoder, the layout string [`SCHEMA`] whose hash the
//! handshake exchanges, and [`MESSAGES`], a description that the tests hold
//! `docs/protocol.md`'s tables to. Changing a field's type changes its
//! length, the codec and the schema hash together.

use super::wire::{FieldError, Reader, Wire, Writer};
use super::{ErrorCode, FrameError};
use crate::estimate::PlaneLaw;

/// Who sends a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// Host → board: a request.
    ToBoard,
    /// Board → host: a reply or telemetry.
    ToHost,
}

/// Which messages a receiver decodes. A frame of the other direction is
/// *malformed* (`UnknownType`) for it: a board is not sent replies.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Accept {
    /// A board: host → board messages only.
    Board,
    /// A host: board → host messages only.
    Host,
    /// Both (tests, the fuzzer, protocol analysers).
    Any,
}

impl Accept {
    /// True when this receiver decodes messages sent in `direction`.
    pub const fn allows(self, direction: Direction) -> bool {
        matches!(
            (self, direction),
            (Accept::Any, _)
                | (Accept::Board, Direction::ToBoard)
                | (Accept::Host, Direction::ToHost)
        )
    }
}

/// One field of a message, as the docs describe it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldSpec {
    /// Field name.
    pub name: &'static str,
    /// Element type as the docs write it (`u8`, `f32`, `law`).
    pub doc_type: &'static str,
    /// 1, or N for an array (written `name[N]`).
    pub count: usize,
    /// Bytes on the wire.
    pub len: usize,
}

/// One message type, as the docs describe it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MessageSpec {
    /// Type byte.
    pub kind: u8,
    /// Name.
    pub name: &'static str,
    /// Who sends it.
    pub direction: Direction,
    /// Payload length including the type byte (CRC not counted).
    pub len: usize,
    /// Fields after the type byte, in order.
    pub fields: &'static [FieldSpec],
}

/// Generates the message set from its table (see the module docs).
macro_rules! protocol_messages {
    (
        version: $version:literal;
        $(
            $(#[doc = $doc:literal])*
            $code:literal $konst:ident $name:ident $dir:ident {
                $( $(#[doc = $fdoc:literal])* $field:ident : $ty:ty ),* $(,)?
            }
        )*
    ) => {
        /// Protocol version; bumped on any incompatible change.
        pub const PROTOCOL_VERSION: u8 = $version;

        /// Message type bytes.
        pub mod kind {
            $(
                #[doc = concat!("Type byte of [`", stringify!($name), "`](super::", stringify!($name), ").")]
                pub const $konst: u8 = $code;
            )*
        }

        $(
            $(#[doc = $doc])*
            #[derive(Clone, Copy, Debug, PartialEq)]
            #[cfg_attr(feature = "defmt", derive(defmt::Format))]
            pub struct $name {
                $( $(#[doc = $fdoc])* pub $field: $ty, )*
            }

            impl $name {
                /// The type byte.
                pub const KIND: u8 = $code;
                /// Who sends it.
                pub const DIRECTION: Direction = Direction::$dir;
                /// Payload length, type byte included.
                pub const LEN: usize = 1 $( + <$ty as Wire>::LEN )*;
            }

            impl From<$name> for Message {
                fn from(m: $name) -> Message {
                    Message::$name(m)
                }
            }
        )*

        /// Every message of the protocol.
        #[derive(Clone, Copy, Debug, PartialEq)]
        #[cfg_attr(feature = "defmt", derive(defmt::Format))]
        pub enum Message {
            $( $(#[doc = $doc])* $name($name), )*
        }

        impl Message {
            /// The type byte.
            pub const fn kind(&self) -> u8 {
                match self {
                    $( Message::$name(_) => $code, )*
                }
            }

            /// Who sends it.
            pub const fn direction(&self) -> Direction {
                match self {
                    $( Message::$name(_) => Direction::$dir, )*
                }
            }

            /// Writes the payload (type byte first) into `buf`; returns its
            /// length, or `None` if `buf` is too short.
            pub fn write_payload(&self, buf: &mut [u8]) -> Option<usize> {
                let mut w = Writer::new(buf);
                match self {
                    $(
                        Message::$name(_m) => {
                            Wire::put(&($code as u8), &mut w)?;
                            $( Wire::put(&_m.$field, &mut w)?; )*
                        }
                    )*
                }
                Some(w.len())
            }

            /// Parses a payload (type byte first, CRC already removed) as a
            /// receiver that decodes `accept`'s messages.
            pub fn read_payload(payload: &[u8], accept: Accept) -> Result<Message, FrameError> {
                let (&kind, fields) = payload.split_first().ok_or(FrameError::TooShort)?;
                let malformed = |code| FrameError::Malformed { request: kind, code };
                let (len, direction) = layout(kind).ok_or(malformed(ErrorCode::UnknownType))?;
                if !accept.allows(direction) {
                    return Err(malformed(ErrorCode::UnknownType));
                }
                if payload.len() != len {
                    return Err(malformed(ErrorCode::BadLength));
                }
                let field = |e| match e {
                    FieldError::Short => malformed(ErrorCode::BadLength),
                    FieldError::BadEnum => malformed(ErrorCode::OutOfRange),
                };
                let mut _r = Reader::new(fields);
                match kind {
                    $(
                        $code => Ok(Message::$name($name {
                            $( $field: Wire::get(&mut _r).map_err(field)?, )*
                        })),
                    )*
                    _ => Err(malformed(ErrorCode::UnknownType)),
                }
            }
        }

        /// Payload length and direction of type byte `kind`.
        pub const fn layout(kind: u8) -> Option<(usize, Direction)> {
            match kind {
                $( $code => Some(($name::LEN, Direction::$dir)), )*
                _ => None,
            }
        }

        /// The message layouts as text: type byte, name, direction and every
        /// field's name and type. Its hash ([`SCHEMA_HASH`]) is exchanged in
        /// the handshake.
        pub const SCHEMA: &str = concat!(
            "softjoint-proto v", stringify!($version),
            $( "|", stringify!($code), " ", stringify!($name), " ", stringify!($dir),
               $( " ", stringify!($field), ":", stringify!($ty), )* )*
            "|crc16-ccitt-false le|cobs 0x00"
        );

        /// Every message type, for documentation checks and tools.
        pub const MESSAGES: &[MessageSpec] = &[
            $(
                MessageSpec {
                    kind: $code,
                    name: stringify!($name),
                    direction: Direction::$dir,
                    len: $name::LEN,
                    fields: &[
                        $(
                            FieldSpec {
                                name: stringify!($field),
                                doc_type: <$ty as Wire>::DOC_TYPE,
                                count: <$ty as Wire>::COUNT,
                                len: <$ty as Wire>::LEN,
                            },
                        )*
                    ],
                },
            )*
        ];
    };
}

protocol_messages! {
    version: 3;

    /// Handshake request.
    0x01 HELLO Hello ToBoard {
        /// The host's [`PROTOCOL_VERSION`].
        version: u8,
    }
    /// Enter lockstep mode (or restart it) with a control period.
    0x02 HIL_START HilStart ToBoard {
        /// Control period (µs), 100..=50 000 (the wire sensors' stale limit).
        period_us: u32,
    }
    /// A lockstep sensor frame: run one control step.
    0x03 HIL_SENSOR HilSensor ToBoard {
        /// Step number, wrapping; each step is one period after the last.
        seq: u16,
        /// Pulse-coder counts of wire sensors 1–4 (unused sensors 0).
        counts: [i16; 4],
    }
    /// Leave lockstep mode: outputs off, back to free-running.
    0x04 HIL_STOP HilStop ToBoard {}
    /// Set a plane's desired angle.
    0x10 SET_TARGET SetTarget ToBoard {
        /// 0 = α, 1 = β.
        plane: u8,
        /// Desired angle (deg).
        target_deg: f32,
    }
    /// Set a plane's gains.
    0x11 SET_GAINS SetGains ToBoard {
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
        /// The law's v_offset (V): the input at zero effort, 0 ≤ · <
        /// supply (the paper's 1.7 V).
        v_offset_v: f32,
    }
    /// Set a plane's estimation law.
    0x12 SET_CALIBRATION SetCalibration ToBoard {
        /// 0 = α, 1 = β.
        plane: u8,
        /// The law.
        law: PlaneLaw,
    }
    /// Ask for a plane's estimation law.
    0x13 GET_CALIBRATION GetCalibration ToBoard {
        /// 0 = α, 1 = β.
        plane: u8,
    }
    /// Allow outputs.
    0x14 ARM Arm ToBoard {}
    /// Force outputs off.
    0x15 DISARM Disarm ToBoard {}
    /// Clear latched faults.
    0x16 CLEAR_FAULTS ClearFaults ToBoard {}
    /// Ask for [`Status`].
    0x17 GET_STATUS GetStatus ToBoard {}
    /// Stream telemetry in free-running mode.
    0x18 SET_TELEMETRY SetTelemetry ToBoard {
        /// Frames per second, 0 (off) ..= 1000.
        rate_hz: u16,
    }
    /// Set the lockstep link-loss timeout.
    0x19 SET_LINK_TIMEOUT SetLinkTimeout ToBoard {
        /// Timeout (ms of the board's clock), 1..=60000.
        timeout_ms: u16,
    }
    /// Drive coils open loop (the excitation mode; free-running only, and
    /// only when armed with no fault latched). The coils of the planes in
    /// `planes` get these inputs — both coils of a pair may be heated — for
    /// `hold_ms`, still counted by each coil's thermal budget; a drive not
    /// refreshed by then ends with those coils unpowered until the next
    /// `Drive` or a `SetTarget` for the plane (which gives it back to the
    /// controller). The other planes stay under the controller.
    0x1A DRIVE Drive ToBoard {
        /// Planes driven: bit 0 = α (coils 1, 3), bit 1 = β (coils 2, 4);
        /// 1..=3.
        planes: u8,
        /// Driver inputs of coils 1–4, paper numbering (mV), 0..=supply;
        /// a coil of a plane not in `planes` must be 0.
        coil_mv: [u16; 4],
        /// How long the inputs hold (ms of the board's clock), 1..=1000.
        hold_ms: u16,
    }
    /// Handshake reply.
    0x81 HELLO_ACK HelloAck ToHost {
        /// The board's [`PROTOCOL_VERSION`].
        version: u8,
        /// The board's [`SCHEMA_HASH`].
        schema: u32,
        /// Antagonistic pairs.
        pairs: u8,
        /// Wire sensors.
        sensors: u8,
    }
    /// A lockstep actuator frame.
    0x83 HIL_ACTUATOR HilActuator ToHost {
        /// The `seq` of the sensor frame answered.
        seq: u16,
        /// Per pair (α, β): driver input in millivolts, positive on the
        /// agonist, negative on the antagonist.
        pair_mv: [i16; 2],
        /// Angle estimates (α, β) in centidegrees; `i16::MIN` = none.
        estimate_cdeg: [i16; 2],
        /// Fault flags (bits 0–7 of `Faults`).
        faults: u8,
    }
    /// Reply to [`GetCalibration`].
    0x93 CALIBRATION Calibration ToHost {
        /// 0 = α, 1 = β.
        plane: u8,
        /// The law.
        law: PlaneLaw,
    }
    /// Board status (reply to [`GetStatus`]).
    0x97 STATUS Status ToHost {
        /// 1 when armed.
        armed: u8,
        /// 0 free-running, 1 lockstep.
        mode: u8,
        /// Faults reported on the last step (active or latched).
        faults: u8,
        /// Faults latched now.
        latched: u8,
        /// Estimates α, β (deg); NaN while there is none.
        estimate_deg: [f32; 2],
        /// Targets α, β (deg).
        target_deg: [f32; 2],
        /// Outputs now, as in [`HilActuator::pair_mv`], of the planes under
        /// the controller (0 for a plane in drive mode).
        pair_mv: [i16; 2],
        /// Every coil's driver input now, coils 1–4 in paper numbering (mV).
        coil_mv: [u16; 4],
        /// Planes in open-loop drive mode (bits as in [`Drive::planes`]).
        drive_planes: u8,
        /// Board clock (ms since boot, wrapping).
        time_ms: u32,
        /// Frames received and decoded.
        frames_ok: u32,
        /// Frames dropped: CRC mismatch.
        crc_errors: u16,
        /// Frames dropped: bad COBS or too short.
        cobs_errors: u16,
        /// Frames dropped: longer than the maximum.
        overfull: u16,
        /// Frames refused: unknown type, bad length, bad enumeration.
        malformed: u16,
        /// Lockstep sensor frames ignored because their seq was behind the
        /// last one answered (late retransmissions).
        stale_seqs: u16,
    }
    /// Streamed state in free-running mode.
    0xA0 TELEMETRY Telemetry ToHost {
        /// Board clock (ms since boot, wrapping).
        time_ms: u32,
        /// Estimates α, β (deg).
        estimate_deg: [f32; 2],
        /// Every coil's driver input, coils 1–4 in paper numbering (mV).
        coil_mv: [u16; 4],
        /// The wire counts the step read, sensors 1–4 (`i32::MIN` = no
        /// reading).
        counts: [i32; 4],
        /// Fault flags.
        faults: u8,
    }
    /// A request was carried out.
    0xF0 ACK Ack ToHost {
        /// Type byte of the request.
        request: u8,
    }
    /// A request was refused.
    0xEE NAK Nak ToHost {
        /// Type byte of the request.
        request: u8,
        /// Why.
        code: ErrorCode,
    }
}

/// The name of message type `kind` (`None` for a byte that is no type).
pub fn message_name(kind: u8) -> Option<&'static str> {
    MESSAGES.iter().find(|m| m.kind == kind).map(|m| m.name)
}

/// Largest payload (type byte included, CRC excluded) of any message.
pub const MAX_PAYLOAD: usize = max_len(MESSAGES);

const fn max_len(mut specs: &[MessageSpec]) -> usize {
    let mut max = 0;
    while let [s, rest @ ..] = specs {
        if s.len > max {
            max = s.len;
        }
        specs = rest;
    }
    max
}

/// FNV-1a (32-bit) of [`SCHEMA`], continued over every message's and
/// field's length, so that a change of a composite field's encoding (the
/// law) is noticed too.
pub const SCHEMA_HASH: u32 = schema_hash();

const fn fnv1a(mut h: u32, mut bytes: &[u8]) -> u32 {
    while let [b, rest @ ..] = bytes {
        h ^= *b as u32;
        h = h.wrapping_mul(0x0100_0193);
        bytes = rest;
    }
    h
}

const fn schema_hash() -> u32 {
    let mut h = fnv1a(0x811C_9DC5, SCHEMA.as_bytes());
    let mut specs = MESSAGES;
    while let [s, rest @ ..] = specs {
        h = fnv1a(h, &(s.len as u32).to_le_bytes());
        let mut fields = s.fields;
        while let [f, more @ ..] = fields {
            h = fnv1a(h, &(f.len as u32).to_le_bytes());
            fields = more;
        }
        specs = rest;
    }
    h
}
