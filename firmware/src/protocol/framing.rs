//! Frames on the wire: `COBS(payload ‖ CRC16-LE) ‖ 0x00`, the encoder, and
//! a streaming decoder that resynchronises on every delimiter and counts
//! what it drops.

use super::cobs;
use super::crc;
use super::messages::{Accept, Message, MAX_PAYLOAD};
use super::ErrorCode;

/// Longest encoded frame before its delimiter: COBS of the largest payload
/// plus its CRC. A receiver that has buffered this many bytes without a
/// delimiter drops the frame as overfull.
pub const MAX_ENCODED: usize = cobs::max_encoded_len(MAX_PAYLOAD + 2);
/// Largest frame on the wire, delimiter included.
pub const MAX_FRAME: usize = MAX_ENCODED + 1;

/// Why a received frame was dropped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// More than [`MAX_ENCODED`] bytes before a delimiter.
    Overfull,
    /// The COBS encoding was invalid.
    Cobs,
    /// Shorter than a type byte plus CRC.
    TooShort,
    /// CRC mismatch.
    Crc,
    /// CRC-valid, but not a message this receiver accepts.
    Malformed {
        /// Type byte.
        request: u8,
        /// [`ErrorCode::UnknownType`] (unknown, or the other direction's
        /// type), [`ErrorCode::BadLength`], or [`ErrorCode::OutOfRange`] (an
        /// enumeration byte outside its enumeration).
        code: ErrorCode,
    },
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::Overfull => write!(
                f,
                "frame longer than {MAX_ENCODED} bytes before its delimiter"
            ),
            FrameError::Cobs => f.write_str("invalid COBS encoding"),
            FrameError::TooShort => f.write_str("frame shorter than a type byte and a CRC"),
            FrameError::Crc => f.write_str("CRC mismatch"),
            FrameError::Malformed { request, code } => {
                write!(f, "malformed message of type {request:#04x}: {code}")
            }
        }
    }
}

impl core::error::Error for FrameError {}

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
    /// CRC-valid frames that are not an accepted message (unknown type,
    /// the other direction's type, bad length, bad enumeration byte).
    pub malformed: u32,
}

/// Encodes `msg` as a complete frame (ending in 0x00) into `out`; returns
/// the frame length.
pub fn encode_frame(msg: &Message, out: &mut [u8; MAX_FRAME]) -> usize {
    let mut raw = [0u8; MAX_PAYLOAD + 2];
    // Every message fits MAX_PAYLOAD by construction (MAX_PAYLOAD is the
    // longest message's length); a failure here would yield an empty frame,
    // which receivers ignore.
    let Some(n) = raw
        .get_mut(..MAX_PAYLOAD)
        .and_then(|buf| msg.write_payload(buf))
    else {
        return 0;
    };
    let Some(payload) = raw.get(..n) else {
        return 0;
    };
    let crc = crc::crc16(payload).to_le_bytes();
    let Some(slot) = raw.get_mut(n..n + 2) else {
        return 0;
    };
    slot.copy_from_slice(&crc);
    let (Some(src), Some(dst)) = (raw.get(..n + 2), out.get_mut(..MAX_ENCODED)) else {
        return 0;
    };
    match cobs::encode(src, dst) {
        Ok(len) => match out.get_mut(len) {
            Some(delimiter) => {
                *delimiter = 0;
                len + 1
            }
            None => 0,
        },
        Err(_) => 0,
    }
}

/// Accumulates bytes from the wire and yields messages. Resynchronises on
/// every 0x00: whatever garbage precedes a delimiter costs at most the frame
/// it lands in. Never allocates; never panics.
pub struct FrameDecoder {
    accept: Accept,
    buf: [u8; MAX_ENCODED],
    len: usize,
    overflowed: bool,
    stats: LinkStats,
}

impl FrameDecoder {
    /// An empty decoder for a receiver that takes `accept`'s messages.
    pub const fn new(accept: Accept) -> Self {
        Self {
            accept,
            buf: [0; MAX_ENCODED],
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

    /// A board's decoder: requests only.
    pub const fn board() -> Self {
        Self::new(Accept::Board)
    }

    /// A host's decoder: replies and telemetry only.
    pub const fn host() -> Self {
        Self::new(Accept::Host)
    }

    /// Counters so far.
    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Feeds one byte. Returns `Some` when a delimiter completes a
    /// non-empty frame: the message, or why it was dropped (also counted).
    pub fn push(&mut self, byte: u8) -> Option<Result<Message, FrameError>> {
        if byte != 0 {
            match self.buf.get_mut(self.len) {
                Some(slot) => {
                    *slot = byte;
                    self.len += 1;
                }
                None => self.overflowed = true,
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
        let result = match self.buf.get(..len) {
            Some(frame) => Self::decode(frame, self.accept),
            None => Err(FrameError::Overfull),
        };
        let s = &mut self.stats;
        let counter = match result {
            Ok(_) => &mut s.frames_ok,
            Err(FrameError::Crc) => &mut s.crc_errors,
            Err(FrameError::Cobs | FrameError::TooShort) => &mut s.cobs_errors,
            Err(FrameError::Overfull) => &mut s.overfull,
            Err(FrameError::Malformed { .. }) => &mut s.malformed,
        };
        *counter = counter.saturating_add(1);
        Some(result)
    }

    /// Decodes one frame's bytes (delimiter removed) for a receiver that
    /// takes `accept`'s messages.
    pub fn decode(encoded: &[u8], accept: Accept) -> Result<Message, FrameError> {
        let mut raw = [0u8; MAX_ENCODED];
        let n = cobs::decode(encoded, &mut raw).map_err(|_| FrameError::Cobs)?;
        if n < 3 {
            return Err(FrameError::TooShort);
        }
        let (payload, crc) = raw
            .get(..n)
            .and_then(|frame| frame.split_at_checked(n - 2))
            .ok_or(FrameError::TooShort)?;
        let received = match crc {
            [lo, hi] => u16::from_le_bytes([*lo, *hi]),
            _ => return Err(FrameError::TooShort),
        };
        if received != crc::crc16(payload) {
            return Err(FrameError::Crc);
        }
        Message::read_payload(payload, accept)
    }
}
