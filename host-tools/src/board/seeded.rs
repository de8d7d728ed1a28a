//! Protocol faults seeded into the pty board ([`crate::board::pty`]): a
//! deliberately broken board, so that the conformance suite
//! (`softjoint conform`, [`crate::board::conform`]) is shown to fail where
//! a board breaks `docs/protocol.md`. Each fault is a small lie told
//! around a correct board application — a rewritten reply, a reply where
//! the document says none, a kept-alive watchdog — of the kind a second
//! implementation of the protocol could get wrong. Nothing here is used
//! by a board without seeded faults.

use firmware::app::App;
use firmware::protocol::{
    encode_frame, kind, Ack, ErrorCode, FrameDecoder, FrameError, GetStatus, HilActuator, Message,
    Nak, MAX_FRAME,
};

/// One seeded protocol fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum SeededFault {
    /// `HelloAck` carries a schema hash one bit off (§5).
    WrongSchema,
    /// A frame with a CRC mismatch is answered (`Nak{0, BadLength}`)
    /// instead of dropped in silence (§2).
    NakCrcErrors,
    /// A lockstep frame whose seq is behind the last one answered is
    /// answered (with the last reply under its seq) instead of ignored
    /// (§6.6).
    AnswerStaleSeqs,
    /// The link watchdog never fires: the board feeds itself a frame
    /// every millisecond in lockstep (§6.7).
    NoLinkWatchdog,
    /// A `Drive` refused as `Disarmed` is acknowledged instead (§7.1).
    AckDisarmedDrive,
    /// Every telemetry frame is sent twice: twice the asked rate (§7).
    DoubleTelemetry,
    /// `Status.cobs_errors` wraps at 65536 instead of saturating (§4.2).
    WrappingCounters,
}

impl SeededFault {
    /// Every seeded fault.
    pub const ALL: [SeededFault; 7] = [
        SeededFault::WrongSchema,
        SeededFault::NakCrcErrors,
        SeededFault::AnswerStaleSeqs,
        SeededFault::NoLinkWatchdog,
        SeededFault::AckDisarmedDrive,
        SeededFault::DoubleTelemetry,
        SeededFault::WrappingCounters,
    ];

    /// The name `--seed-fault` takes.
    pub fn name(self) -> &'static str {
        match self {
            SeededFault::WrongSchema => "wrong-schema",
            SeededFault::NakCrcErrors => "nak-crc-errors",
            SeededFault::AnswerStaleSeqs => "answer-stale-seqs",
            SeededFault::NoLinkWatchdog => "no-link-watchdog",
            SeededFault::AckDisarmedDrive => "ack-disarmed-drive",
            SeededFault::DoubleTelemetry => "double-telemetry",
            SeededFault::WrappingCounters => "wrapping-counters",
        }
    }
}

/// The faults a board has, and what it needs to tell its lies: its own
/// view of the incoming bytes and of the last lockstep reply.
pub struct Seeder {
    faults: Vec<SeededFault>,
    spy: FrameDecoder,
    last_reply: Option<HilActuator>,
    /// COBS errors seen, not saturated (for [`SeededFault::WrappingCounters`]).
    cobs_errors: u64,
}

fn frame(msg: Message) -> Vec<u8> {
    let mut buf = [0u8; MAX_FRAME];
    let n = encode_frame(&msg, &mut buf);
    buf[..n].to_vec()
}

impl Seeder {
    /// A seeder for `faults` (none: the board is left as it is).
    pub fn new(faults: &[SeededFault]) -> Self {
        Self {
            faults: faults.to_vec(),
            spy: FrameDecoder::board(),
            last_reply: None,
            cobs_errors: 0,
        }
    }

    fn has(&self, f: SeededFault) -> bool {
        self.faults.contains(&f)
    }

    /// Sees a byte the board received, after the board did; extra replies
    /// go to `out`.
    pub fn on_byte(&mut self, byte: u8, out: &mut Vec<Vec<u8>>) {
        if self.faults.is_empty() {
            return;
        }
        match self.spy.push(byte) {
            Some(Err(FrameError::Crc)) if self.has(SeededFault::NakCrcErrors) => {
                out.push(frame(Message::Nak(Nak {
                    request: 0,
                    code: ErrorCode::BadLength,
                })));
            }
            Some(Err(FrameError::Cobs | FrameError::TooShort)) => self.cobs_errors += 1,
            Some(Ok(Message::HilSensor(s))) if self.has(SeededFault::AnswerStaleSeqs) => {
                if let Some(last) = self.last_reply {
                    if (s.seq.wrapping_sub(last.seq) as i16) < 0 {
                        out.push(frame(Message::HilActuator(HilActuator {
                            seq: s.seq,
                            ..last
                        })));
                    }
                }
            }
            _ => {}
        }
    }

    /// Before the board's poll: keeps the watchdog fed when asked to.
    pub fn before_poll(&mut self, app: &mut App, now: firmware::time::Instant) {
        if self.has(SeededFault::NoLinkWatchdog) && app.in_hil() {
            for b in frame(Message::GetStatus(GetStatus {})) {
                app.on_byte(b, now, &mut |_| {});
            }
        }
    }

    /// The frames the board sends, as the faults rewrite them.
    pub fn rewrite(&mut self, frames: Vec<Vec<u8>>) -> Vec<Vec<u8>> {
        if self.faults.is_empty() {
            return frames;
        }
        let mut out = Vec::with_capacity(frames.len());
        for f in frames {
            let Some(body) = f.strip_suffix(&[0]) else {
                out.push(f);
                continue;
            };
            let Ok(msg) = FrameDecoder::decode(body, firmware::protocol::Accept::Host) else {
                out.push(f);
                continue;
            };
            match self.lie(msg) {
                Some(lies) => out.extend(lies.into_iter().map(frame)),
                None => out.push(f),
            }
        }
        out
    }

    /// The message(s) sent instead of `msg`, if a fault changes it.
    fn lie(&mut self, msg: Message) -> Option<Vec<Message>> {
        match msg {
            Message::HilActuator(a) => {
                self.last_reply = Some(a);
                None
            }
            Message::HelloAck(mut h) if self.has(SeededFault::WrongSchema) => {
                h.schema ^= 1;
                Some(vec![Message::HelloAck(h)])
            }
            Message::Nak(Nak {
                request: kind::DRIVE,
                code: ErrorCode::Disarmed,
            }) if self.has(SeededFault::AckDisarmedDrive) => Some(vec![Message::Ack(Ack {
                request: kind::DRIVE,
            })]),
            Message::Telemetry(t) if self.has(SeededFault::DoubleTelemetry) => {
                Some(vec![Message::Telemetry(t), Message::Telemetry(t)])
            }
            Message::Status(mut s) if self.has(SeededFault::WrappingCounters) => {
                s.cobs_errors = (self.cobs_errors % 65_536) as u16;
                Some(vec![Message::Status(s)])
            }
            _ => None,
        }
    }
}
