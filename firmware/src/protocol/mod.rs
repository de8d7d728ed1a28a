//! The serial protocol between a host and the board (or the firmware image
//! under QEMU). Specified byte for byte in `docs/protocol.md`; this module is
//! its one implementation, used by the firmware and by the host tools.
//!
//! - [`messages`]: the message table — one declaration from which the
//!   types, lengths, codec and schema hash are generated;
//! - [`wire`]: how each field type is laid out;
//! - [`framing`]: `COBS(payload ‖ CRC16-LE) ‖ 0x00`, the encoder and the
//!   streaming decoder with its counters;
//! - [`units`]: quantities in their wire units (millivolts, centidegrees,
//!   the fault byte);
//! - [`cobs`], [`crc`]: the two algorithms of the framing.
//!
//! Lockstep hardware-in-the-loop frames are kept short (15 and 16 bytes on
//! the wire) because the emulated UART costs about 51 µs per byte: the host
//! owns time, each sensor frame is one period after the last, so the frame
//! carries no time field.

pub mod cobs;
pub mod crc;
pub mod framing;
pub mod messages;
pub mod units;
pub mod wire;

pub use framing::{encode_frame, FrameDecoder, FrameError, LinkStats, MAX_ENCODED, MAX_FRAME};
pub use messages::*;
pub use units::*;

/// Error codes carried by [`Nak`].
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
    /// `Drive` refused: the board is disarmed.
    Disarmed = 8,
    /// `Drive` refused: a fault is latched (clear it first).
    Latched = 9,
    /// `Drive` refused: a coil it heats is held off by its thermal budget
    /// (cooling after a trip).
    OverBudget = 10,
}

impl ErrorCode {
    /// Every code, in wire order.
    pub const ALL: [ErrorCode; 10] = [
        ErrorCode::UnknownType,
        ErrorCode::BadLength,
        ErrorCode::OutOfRange,
        ErrorCode::NotFinite,
        ErrorCode::WrongMode,
        ErrorCode::StillFaulted,
        ErrorCode::Version,
        ErrorCode::Disarmed,
        ErrorCode::Latched,
        ErrorCode::OverBudget,
    ];

    /// From the wire byte.
    pub fn from_u8(b: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|c| *c as u8 == b)
    }

    /// The name used in `docs/protocol.md`.
    pub const fn name(self) -> &'static str {
        match self {
            ErrorCode::UnknownType => "UnknownType",
            ErrorCode::BadLength => "BadLength",
            ErrorCode::OutOfRange => "OutOfRange",
            ErrorCode::NotFinite => "NotFinite",
            ErrorCode::WrongMode => "WrongMode",
            ErrorCode::StillFaulted => "StillFaulted",
            ErrorCode::Version => "Version",
            ErrorCode::Disarmed => "Disarmed",
            ErrorCode::Latched => "Latched",
            ErrorCode::OverBudget => "OverBudget",
        }
    }
}

impl core::fmt::Display for ErrorCode {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ErrorCode::UnknownType => "not a message type the receiver accepts",
            ErrorCode::BadLength => "payload length does not match the message type",
            ErrorCode::OutOfRange => "a field is outside its range",
            ErrorCode::NotFinite => "a float field is NaN or infinite",
            ErrorCode::WrongMode => "not valid in the board's current mode",
            ErrorCode::StillFaulted => "a fault's cause is still present",
            ErrorCode::Version => "unsupported protocol version",
            ErrorCode::Disarmed => "the board is disarmed",
            ErrorCode::Latched => "a fault is latched; clear it first",
            ErrorCode::OverBudget => "a coil is held off by its thermal budget",
        })
    }
}

impl core::error::Error for ErrorCode {}
