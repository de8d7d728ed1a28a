//! Checks of the handshake, the boot state, the framing and every
//! request's refusals (docs/protocol.md §2–§5, §7).

use firmware::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};
use firmware::protocol::{
    cobs, crc, ErrorCode, GetCalibration, GetStatus, Hello, HilSensor, HilStart, Message,
    SetCalibration, SetGains, SetLinkTimeout, SetTarget, SetTelemetry, Status, MAX_ENCODED,
    PROTOCOL_VERSION, SCHEMA_HASH,
};

use super::{need, Check, NotPassed, Session, Verdict, SILENCE};
use crate::board::link::Port;

/// `COBS(payload ‖ CRC16-LE(payload)) ‖ 0x00`, or with the CRC's low byte
/// flipped when `bad_crc`.
pub fn raw_frame(payload: &[u8], bad_crc: bool) -> Vec<u8> {
    let mut body = payload.to_vec();
    let c = crc::crc16(payload) ^ u16::from(bad_crc);
    body.extend_from_slice(&c.to_le_bytes());
    let mut out = vec![0u8; body.len() + body.len() / 254 + 2];
    let n = cobs::encode(&body, &mut out).unwrap_or(0);
    out.truncate(n);
    out.push(0);
    out
}

/// A message's payload (type byte first).
fn payload(msg: impl Into<Message>) -> Vec<u8> {
    let mut buf = [0u8; 64];
    let n = msg.into().write_payload(&mut buf).unwrap_or(0);
    buf[..n].to_vec()
}

pub(super) fn checks<P: Port>() -> Vec<Check<P>> {
    vec![
        Check {
            id: "handshake.hello",
            section: "§5",
            title: "Hello{3} → HelloAck{3, schema 0x6715C80D, 2 pairs, 4 sensors}",
            heats: false,
            run: hello::<P>,
        },
        Check {
            id: "boot.state",
            section: "§7 After reset",
            title: "fresh from reset: free-running, disarmed, no drive, targets 0°, the default laws",
            heats: false,
            run: boot_state::<P>,
        },
        Check {
            id: "handshake.version",
            section: "§5, §4.3",
            title: "Hello with another version → Nak{Version}",
            heats: false,
            run: version::<P>,
        },
        Check {
            id: "framing.empty-frame",
            section: "§2",
            title: "an empty frame is ignored: no reply, no counter",
            heats: false,
            run: empty_frame::<P>,
        },
        Check {
            id: "framing.crc-error",
            section: "§2",
            title: "a CRC mismatch is dropped without reply and counted",
            heats: false,
            run: crc_error::<P>,
        },
        Check {
            id: "framing.cobs-error",
            section: "§2",
            title: "invalid COBS or under 3 decoded bytes: dropped without reply, counted",
            heats: false,
            run: cobs_error::<P>,
        },
        Check {
            id: "framing.overfull",
            section: "§2",
            title: "more than 55 bytes before a delimiter: dropped, counted, resynchronised",
            heats: false,
            run: overfull::<P>,
        },
        Check {
            id: "framing.malformed",
            section: "§2, §4.3",
            title: "unknown type, reply type, wrong length, bad law kind → Nak{UnknownType, UnknownType, BadLength, OutOfRange}, counted",
            heats: false,
            run: malformed::<P>,
        },
        Check {
            id: "requests.ranges",
            section: "§4.1, §4.3",
            title: "values out of range → Nak{OutOfRange}, non-finite floats → Nak{NotFinite}",
            heats: false,
            run: ranges::<P>,
        },
        Check {
            id: "requests.laws",
            section: "§4.4",
            title: "the law rules (indices, distinct sensors, gain ≠ 0, a or b ≠ 0) and a bit-exact round trip",
            heats: false,
            run: laws::<P>,
        },
        Check {
            id: "requests.precedence",
            section: "§4.5",
            title: "NotFinite before WrongMode before OutOfRange",
            heats: false,
            run: precedence::<P>,
        },
        Check {
            id: "requests.idempotent",
            section: "§5",
            title: "a request sent twice is carried out twice with the same result",
            heats: false,
            run: idempotent::<P>,
        },
    ]
}

fn hello<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let reply = s.request(
        Hello {
            version: PROTOCOL_VERSION,
        },
        |m| matches!(m, Message::HelloAck(_)),
    )?;
    let Message::HelloAck(h) = reply else {
        return Err(NotPassed::Fail(format!("{reply:?}")));
    };
    need(
        (h.version, h.schema, h.pairs, h.sensors) == (PROTOCOL_VERSION, SCHEMA_HASH, 2, 4),
        || {
            format!(
                "HelloAck{{version {}, schema {:#010x}, {} pairs, {} sensors}}; the document says {PROTOCOL_VERSION}, {SCHEMA_HASH:#010x}, 2, 4",
                h.version, h.schema, h.pairs, h.sensors
            )
        },
    )?;
    Ok(format!("version {}, schema {:#010x}", h.version, h.schema))
}

fn boot_state<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let st = s.status()?;
    let stale = firmware::protocol::faults_to_u8(firmware::supervisor::Faults::SENSOR_STALE);
    need(
        st.armed == 0
            && st.mode == 0
            && st.drive_planes == 0
            && st.target_deg == [0.0; 2]
            && st.latched & !stale == 0
            && st.coil_mv == [0; 4],
        || format!("not the boot state of §7: {st:?}"),
    )?;
    let defaults = firmware::joint::JointConfig::paper_3d().laws;
    for plane in 0..2u8 {
        let got = s.request(GetCalibration { plane }, |m| {
            matches!(m, Message::Calibration(_))
        })?;
        let Message::Calibration(c) = got else {
            return Err(NotPassed::Fail(format!("{got:?}")));
        };
        need(c.law == defaults[usize::from(plane)], || {
            format!("plane {plane}'s law at boot is {:?}, not §7's", c.law)
        })?;
    }
    Ok(format!(
        "disarmed, free-running, default laws; latched {:#04x} (sensor-stale allowed)",
        st.latched
    ))
}

fn version<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    s.nak(
        Hello {
            version: PROTOCOL_VERSION.wrapping_add(1),
        },
        ErrorCode::Version,
    )?;
    s.nak(Hello { version: 0 }, ErrorCode::Version)?;
    Ok("versions 0 and 4 refused".into())
}

/// Sends `bytes`, expects no reply within [`SILENCE`], then returns the
/// status.
fn silently<P: Port>(
    s: &mut Session<'_, P>,
    bytes: &[u8],
    what: &str,
) -> Result<Status, NotPassed> {
    s.link().send_raw(bytes)?;
    if let Some(m) = s.next_reply(SILENCE)? {
        return Err(NotPassed::Fail(format!("{what} was answered: {m:?}")));
    }
    s.status()
}

fn empty_frame<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let before = s.status()?;
    let after = silently(s, &[0, 0, 0], "an empty frame")?;
    // GetStatus itself is the only frame counted in between.
    need(
        after.frames_ok == before.frames_ok.saturating_add(1)
            && (
                after.crc_errors,
                after.cobs_errors,
                after.overfull,
                after.malformed,
            ) == (
                before.crc_errors,
                before.cobs_errors,
                before.overfull,
                before.malformed,
            ),
        || format!("counters moved: {before:?} → {after:?}"),
    )?;
    Ok("three delimiters: no reply, no counter".into())
}

fn crc_error<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let before = s.status()?;
    let after = silently(s, &raw_frame(&payload(GetStatus {}), true), "a CRC error")?;
    need(
        after.crc_errors == before.crc_errors.saturating_add(1),
        || format!("crc_errors {} → {}", before.crc_errors, after.crc_errors),
    )?;
    Ok(format!(
        "crc_errors {} → {}",
        before.crc_errors, after.crc_errors
    ))
}

fn cobs_error<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let before = s.status()?;
    // A code byte promising 4 data bytes, then the delimiter; and a frame
    // that decodes to no byte at all.
    let after = silently(s, &[0x05, 0x11, 0x00, 0x01, 0x00], "a COBS error")?;
    need(
        after.cobs_errors == before.cobs_errors.saturating_add(2),
        || {
            format!(
                "cobs_errors {} → {} (2 sent)",
                before.cobs_errors, after.cobs_errors
            )
        },
    )?;
    Ok(format!(
        "cobs_errors {} → {}",
        before.cobs_errors, after.cobs_errors
    ))
}

fn overfull<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let before = s.status()?;
    let mut junk = vec![0x42u8; MAX_ENCODED + 1];
    junk.push(0);
    let after = silently(s, &junk, "an overfull frame")?;
    need(after.overfull == before.overfull.saturating_add(1), || {
        format!("overfull {} → {}", before.overfull, after.overfull)
    })?;
    // Exactly the longest frame is not overfull.
    let mut longest = vec![0x42u8; MAX_ENCODED];
    longest.push(0);
    let last = silently(s, &longest, "a 55-byte frame with a bad CRC")?;
    need(last.overfull == after.overfull, || {
        format!("a {MAX_ENCODED}-byte frame was counted overfull")
    })?;
    Ok(format!(
        "{} bytes: overfull {} → {}; {MAX_ENCODED} bytes: not overfull; resynchronised",
        MAX_ENCODED + 1,
        before.overfull,
        after.overfull
    ))
}

fn malformed<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    let before = s.status()?;
    let mut law = payload(SetCalibration {
        plane: 0,
        law: firmware::joint::JointConfig::paper_3d().laws[0],
    });
    law[2] = 7; // the law's kind byte: no such kind
    let cases: [(Vec<u8>, u8, ErrorCode); 4] = [
        (vec![0x55], 0x55, ErrorCode::UnknownType),
        (vec![0xF0, 0x17], 0xF0, ErrorCode::UnknownType),
        (vec![0x17, 0x00], 0x17, ErrorCode::BadLength),
        (law, 0x12, ErrorCode::OutOfRange),
    ];
    for (p, request, code) in &cases {
        s.link().send_raw(&raw_frame(p, false))?;
        let got = s.next_reply(super::REPLY_TIMEOUT)?;
        let want = firmware::protocol::Nak {
            request: *request,
            code: *code,
        };
        need(got == Some(Message::Nak(want)), || {
            format!("payload {p:02x?}: expected {want:?}, got {got:?}")
        })?;
    }
    let after = s.status()?;
    need(
        after.malformed == before.malformed.saturating_add(4),
        || {
            format!(
                "malformed {} → {} (4 sent)",
                before.malformed, after.malformed
            )
        },
    )?;
    Ok(format!(
        "4 refusals by name; malformed {} → {}",
        before.malformed, after.malformed
    ))
}

fn ranges<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    use ErrorCode::{NotFinite, OutOfRange};
    let gains = |plane, kp, v_offset_v| SetGains {
        plane,
        kp_agonist: kp,
        kp_antagonist: 2.0,
        ki: 0.0,
        integral_limit_v: 0.0,
        v_offset_v,
    };
    let target = |plane, target_deg| SetTarget { plane, target_deg };
    let refused: Vec<(Message, ErrorCode)> = vec![
        (target(0, 25.5).into(), OutOfRange),
        (target(0, -25.5).into(), OutOfRange),
        (target(2, 0.0).into(), OutOfRange),
        (target(0, f32::NAN).into(), NotFinite),
        (target(1, f32::INFINITY).into(), NotFinite),
        (gains(0, 0.0, 1.7).into(), OutOfRange),
        (gains(0, 2.0, 5.0).into(), OutOfRange),
        (gains(0, 2.0, -0.1).into(), OutOfRange),
        (gains(2, 2.0, 1.7).into(), OutOfRange),
        (gains(0, f32::NAN, 1.7).into(), NotFinite),
        (GetCalibration { plane: 2 }.into(), OutOfRange),
        (SetTelemetry { rate_hz: 1001 }.into(), OutOfRange),
        (SetLinkTimeout { timeout_ms: 0 }.into(), OutOfRange),
        (SetLinkTimeout { timeout_ms: 60_001 }.into(), OutOfRange),
        (HilStart { period_us: 99 }.into(), OutOfRange),
        (HilStart { period_us: 50_001 }.into(), OutOfRange),
    ];
    let n = refused.len();
    for (msg, code) in refused {
        s.nak(msg, code)?;
    }
    // The ends of the ranges are accepted.
    s.ack(target(0, 25.0))?;
    s.ack(target(1, -25.0))?;
    s.ack(SetTelemetry { rate_hz: 1000 })?;
    s.ack(SetTelemetry { rate_hz: 0 })?;
    s.ack(SetLinkTimeout { timeout_ms: 60_000 })?;
    s.ack(SetLinkTimeout { timeout_ms: 1 })?;
    s.ack(SetLinkTimeout { timeout_ms: 50 })?;
    Ok(format!(
        "{n} refusals by name; the ends of each range accepted"
    ))
}

/// A switching law as §4.4 lays it out, with a quadratic `a`, `b`.
fn switching(plus: u8, minus: u8, single: u8, gain: f32, a: f32, b: f32) -> PlaneLaw {
    PlaneLaw::Switching {
        plus,
        minus,
        high: LinearLaw {
            gain,
            offset: 0.323,
        },
        sensor: single,
        low: QuadraticLaw { a, b, c: -1.5 },
        threshold_deg: -7.46,
        hysteresis_deg: 0.5,
    }
}

fn laws<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    use ErrorCode::{NotFinite, OutOfRange};
    let single = |sensor, a, b| PlaneLaw::Single {
        sensor,
        law: QuadraticLaw { a, b, c: 1.0 },
    };
    let cases = [
        (single(0, 0.0, 0.0), OutOfRange),
        (switching(2, 0, 0, 2.7, 0.0, 0.0), OutOfRange),
        (single(4, 1.0, 0.0), OutOfRange),
        (switching(2, 2, 0, 2.7, 1.0, 1.0), OutOfRange),
        (switching(2, 0, 0, 0.0, 1.0, 1.0), OutOfRange),
        (switching(4, 0, 0, 2.7, 1.0, 1.0), OutOfRange),
        (switching(2, 0, 0, 2.7, f32::NAN, 1.0), NotFinite),
    ];
    for (law, code) in cases {
        s.nak(SetCalibration { plane: 0, law }, code)?;
    }
    // A valid law comes back bit for bit.
    let law = switching(2, 0, 0, 2.727, 0.0, -5.6);
    s.ack(SetCalibration { plane: 1, law })?;
    let got = s.request(GetCalibration { plane: 1 }, |m| {
        matches!(m, Message::Calibration(_))
    })?;
    let sent = payload(SetCalibration { plane: 1, law });
    let back = payload(got);
    need(sent[1..] == back[1..], || {
        format!("sent {:02x?}, read back {:02x?}", &sent[1..], &back[1..])
    })?;
    Ok(format!(
        "{} bad laws refused by name; a switching law with a = 0 round-trips bit-exactly",
        cases.len()
    ))
}

fn precedence<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    s.nak(
        SetTarget {
            plane: 7,
            target_deg: f32::NAN,
        },
        ErrorCode::NotFinite,
    )?;
    s.nak(
        SetCalibration {
            plane: 9,
            law: switching(5, 5, 9, 0.0, f32::NAN, 0.0),
        },
        ErrorCode::NotFinite,
    )?;
    s.nak(
        HilSensor {
            seq: 0,
            counts: [0; 4],
        },
        ErrorCode::WrongMode,
    )?;
    Ok("NotFinite over a bad plane and bad indices; HilSensor outside lockstep: WrongMode".into())
}

fn idempotent<P: Port>(s: &mut Session<'_, P>) -> Verdict {
    for _ in 0..2 {
        s.ack(SetTarget {
            plane: 0,
            target_deg: 3.5,
        })?;
        s.ack(firmware::protocol::Disarm {})?;
        s.ack(firmware::protocol::HilStop {})?;
    }
    let st = s.status()?;
    need(
        st.target_deg[0] == 3.5 && st.mode == 0 && st.armed == 0,
        || format!("{st:?}"),
    )?;
    Ok("SetTarget, Disarm, HilStop twice each: acknowledged, same state".into())
}
