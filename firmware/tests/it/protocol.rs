//! The wire protocol: every message round-trips; every single-bit flip in a
//! frame is rejected; garbage, truncated, oversized and duplicated frames
//! are counted and dropped and the decoder resyncs at the next delimiter;
//! bounded property tests over arbitrary byte streams.
use firmware::control::DriverConfig;
use firmware::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};
use firmware::protocol::*;
use proptest::prelude::*;

fn every_message() -> Vec<Message> {
    let law = PlaneLaw::Switching {
        plus: 2,
        minus: 0,
        high: LinearLaw::PAPER_ALPHA,
        sensor: 2,
        low: QuadraticLaw {
            a: 0.02,
            b: 5.4,
            c: -0.3,
        },
        threshold_deg: -7.46,
        hysteresis_deg: 0.5,
    };
    vec![
        Hello {
            version: PROTOCOL_VERSION,
        }
        .into(),
        HilStart { period_us: 1000 }.into(),
        HilSensor {
            seq: 0xBEEF,
            counts: [0, -1, 1000, i16::MIN],
        }
        .into(),
        HilStop {}.into(),
        SetTarget {
            plane: 1,
            target_deg: -5.5,
        }
        .into(),
        SetGains {
            plane: 0,
            kp_agonist: 2.0,
            kp_antagonist: 1.5,
            ki: 0.1,
            integral_limit_v: 1.0,
            v_offset_v: 1.5,
        }
        .into(),
        SetCalibration { plane: 0, law }.into(),
        SetCalibration {
            plane: 1,
            law: PlaneLaw::Differential {
                plus: 3,
                minus: 1,
                law: LinearLaw::PAPER_BETA,
            },
        }
        .into(),
        GetCalibration { plane: 1 }.into(),
        Arm {}.into(),
        Disarm {}.into(),
        ClearFaults {}.into(),
        GetStatus {}.into(),
        SetTelemetry { rate_hz: 50 }.into(),
        SetLinkTimeout { timeout_ms: 50 }.into(),
        Drive {
            planes: 3,
            coil_mv: [3000, 0, 1900, 1],
            hold_ms: 1000,
        }
        .into(),
        HelloAck {
            version: PROTOCOL_VERSION,
            schema: SCHEMA_HASH,
            pairs: 2,
            sensors: 4,
        }
        .into(),
        HilActuator {
            seq: 7,
            pair_mv: [3200, -1700],
            estimate_cdeg: [512, i16::MIN],
            faults: 0x11,
        }
        .into(),
        Calibration {
            plane: 0,
            law: PlaneLaw::Single {
                sensor: 0,
                law: QuadraticLaw::PAPER_2D,
            },
        }
        .into(),
        Status {
            armed: 1,
            mode: 1,
            faults: 0x08,
            latched: 0x08,
            estimate_deg: [1.5, f32::NAN],
            target_deg: [5.0, 5.0],
            pair_mv: [0, 0],
            coil_mv: [0, 1700, 1900, 5000],
            drive_planes: 2,
            time_ms: 123_456,
            frames_ok: 99,
            crc_errors: 1,
            cobs_errors: 2,
            overfull: 3,
            malformed: 4,
            stale_seqs: 5,
        }
        .into(),
        Telemetry {
            time_ms: 5,
            estimate_deg: [1.0, -1.0],
            coil_mv: [100, 0, 2000, 0],
            counts: [i32::MIN, -1, 70_000, 0],
            faults: 0,
        }
        .into(),
        Ack { request: kind::ARM }.into(),
        Nak {
            request: kind::SET_TARGET,
            code: ErrorCode::OutOfRange,
        }
        .into(),
    ]
}

/// A frame around an arbitrary payload (with a correct CRC).
fn raw_frame(payload: &[u8]) -> Vec<u8> {
    let mut raw = payload.to_vec();
    raw.extend(firmware::protocol::crc::crc16(payload).to_le_bytes());
    let mut enc = vec![0u8; cobs::max_encoded_len(raw.len())];
    let n = cobs::encode(&raw, &mut enc).unwrap();
    enc.truncate(n);
    enc.push(0);
    enc
}

fn frame(msg: &Message) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = encode_frame(msg, &mut out);
    assert!(n > 0, "{msg:?} did not encode");
    out[..n].to_vec()
}

/// Bitwise equality, so NaN fields compare equal to themselves.
fn same(a: &Message, b: &Message) -> bool {
    format!("{a:?}") == format!("{b:?}")
}

fn feed(dec: &mut FrameDecoder, bytes: &[u8]) -> Vec<Result<Message, FrameError>> {
    bytes.iter().filter_map(|b| dec.push(*b)).collect()
}

#[test]
fn every_message_round_trips_and_has_its_declared_length() {
    let all = every_message();
    for spec in MESSAGES {
        assert!(
            all.iter().any(|m| m.kind() == spec.kind),
            "every_message() misses {}",
            spec.name
        );
    }
    for msg in all {
        let f = frame(&msg);
        // Decoded by a receiver of its direction, and by `Any`.
        let mut dec = FrameDecoder::new(match msg.direction() {
            Direction::ToBoard => Accept::Board,
            Direction::ToHost => Accept::Host,
        });
        let got = feed(&mut dec, &f);
        assert_eq!(got.len(), 1);
        let back = got[0].as_ref().unwrap();
        assert!(same(back, &msg), "{msg:?} came back as {back:?}");
        let mut any = FrameDecoder::new(Accept::Any);
        assert!(same(feed(&mut any, &f)[0].as_ref().unwrap(), &msg));
        let mut raw = [0u8; 64];
        let n = msg.write_payload(&mut raw).unwrap();
        assert_eq!(Some((n, msg.direction())), layout(msg.kind()), "{msg:?}");
        let spec = MESSAGES.iter().find(|s| s.kind == msg.kind()).unwrap();
        assert_eq!(
            spec.len,
            1 + spec.fields.iter().map(|f| f.len).sum::<usize>()
        );
        assert!(n <= MAX_PAYLOAD);
        assert!(f.len() <= MAX_FRAME);
    }
}

#[test]
fn a_receiver_refuses_the_other_directions_messages_as_malformed() {
    for msg in every_message() {
        let (wrong, right) = match msg.direction() {
            Direction::ToBoard => (Accept::Host, Accept::Board),
            Direction::ToHost => (Accept::Board, Accept::Host),
        };
        let mut dec = FrameDecoder::new(wrong);
        let got = feed(&mut dec, &frame(&msg));
        assert_eq!(
            got,
            [Err(FrameError::Malformed {
                request: msg.kind(),
                code: ErrorCode::UnknownType
            })],
            "{msg:?} at a {wrong:?} receiver"
        );
        assert_eq!(dec.stats().malformed, 1);
        assert!(FrameDecoder::new(right).push(0).is_none());
    }
}

#[test]
fn lockstep_frames_fit_the_wire_budget() {
    // ARCHITECTURE.md: ≥ 1000 round trips/s needs ~15 bytes per frame.
    let s = frame(
        &HilSensor {
            seq: 1,
            counts: [1, 2, 3, 4],
        }
        .into(),
    );
    let a = frame(
        &HilActuator {
            seq: 1,
            pair_mv: [1, 2],
            estimate_cdeg: [3, 4],
            faults: 0,
        }
        .into(),
    );
    assert_eq!(s.len(), 15);
    assert_eq!(a.len(), 16);
}

#[test]
fn every_single_bit_flip_is_rejected() {
    let mut flips = 0;
    for msg in every_message() {
        let f = frame(&msg);
        for byte in 0..f.len() {
            for bit in 0..8 {
                let mut g = f.clone();
                g[byte] ^= 1 << bit;
                let mut dec = FrameDecoder::new(Accept::Any);
                // A flip may create or destroy a delimiter: feed the damaged
                // frame plus a closing delimiter; nothing may decode as a
                // message.
                g.push(0);
                for r in feed(&mut dec, &g) {
                    assert!(
                        r.is_err(),
                        "flip of bit {bit} in byte {byte} of {msg:?} accepted as {r:?}"
                    );
                }
                flips += 1;
            }
        }
    }
    assert!(flips > 1500, "only {flips} flips tried");
}

#[test]
fn decoder_resyncs_after_garbage_and_counts_it() {
    let good = frame(&Arm {}.into());
    let mut stream = vec![0x13, 0x37, 0xFF, 0x42]; // noise, no delimiter
    stream.push(0); // the receiver sees one bad frame here
    stream.extend(&good);
    stream.extend(std::iter::repeat_n(0x55, MAX_FRAME + 10)); // oversized
    stream.push(0);
    stream.extend(&good[..good.len() - 3]); // truncated, then delimiter
    stream.push(0);
    stream.extend(&good);
    stream.extend(&good); // duplicate: decodes twice, dedup is the app's job
    let mut dec = FrameDecoder::board();
    let got = feed(&mut dec, &stream);
    let ok: Vec<_> = got.iter().filter(|r| r.is_ok()).collect();
    assert_eq!(ok.len(), 3, "{got:?}");
    let s = dec.stats();
    assert_eq!(s.frames_ok, 3);
    assert_eq!(s.overfull, 1);
    assert_eq!(s.crc_errors + s.cobs_errors, 2, "{s:?}");
}

#[test]
fn unknown_types_wrong_lengths_and_bad_enumerations_are_malformed_not_crashes() {
    let mut dec = FrameDecoder::new(Accept::Any);
    let mut law = vec![kind::SET_CALIBRATION, 0, 9];
    law.resize(SetCalibration::LEN, 0);
    for (payload, code) in [
        (&[0x7Fu8][..], ErrorCode::UnknownType),
        (&[kind::ARM, 0x01][..], ErrorCode::BadLength),
        (&[kind::HIL_SENSOR, 1, 2][..], ErrorCode::BadLength),
        (&[kind::NAK, 1, 99][..], ErrorCode::OutOfRange),
        (&law[..], ErrorCode::OutOfRange),
    ] {
        let got = feed(&mut dec, &raw_frame(payload));
        assert_eq!(
            got,
            [Err(FrameError::Malformed {
                request: payload[0],
                code
            })],
            "{payload:?}"
        );
    }
    assert_eq!(dec.stats().malformed, 5);
}

#[test]
fn a_frame_longer_than_the_longest_message_is_overfull() {
    // The longest valid frame fills the receiver's buffer exactly...
    let longest = MESSAGES.iter().map(|m| m.len).max().unwrap();
    assert_eq!(longest, MAX_PAYLOAD);
    let mut payload = vec![kind::STATUS];
    payload.resize(MAX_PAYLOAD, 0x11);
    let f = raw_frame(&payload);
    assert_eq!(f.len(), MAX_FRAME);
    let mut dec = FrameDecoder::host();
    assert!(matches!(feed(&mut dec, &f)[..], [Ok(Message::Status(_))]));
    // ...and one payload byte more is dropped as overfull, not decoded and
    // answered (whatever its type).
    for kind in [kind::STATUS, 0x7F] {
        let mut payload = vec![kind];
        payload.resize(MAX_PAYLOAD + 1, 0x11);
        let f = raw_frame(&payload);
        assert_eq!(f.len(), MAX_FRAME + 1);
        let mut dec = FrameDecoder::new(Accept::Any);
        assert_eq!(feed(&mut dec, &f), [Err(FrameError::Overfull)]);
        assert_eq!(dec.stats().overfull, 1);
    }
}

#[test]
fn unit_conversions_saturate_and_keep_sign() {
    let d = DriverConfig::default();
    assert_eq!(
        mv_to_pair(
            pair_to_mv(firmware::control::PairCommand::Antagonist(d.clamp(2.5)), &d),
            &d
        )
        .coil_volts(),
        [0.0, 2.5]
    );
    assert_eq!(deg_to_cdeg(f32::NAN), i16::MIN);
    assert!(cdeg_to_deg(i16::MIN).is_nan());
    assert_eq!(deg_to_cdeg(1e9), i16::MAX);
    assert_eq!(deg_to_cdeg(-1e9), i16::MIN + 1);
    assert_eq!(deg_to_cdeg(-7.46), -746);
    assert_eq!(
        mv_to_pair(i16::MAX, &d).coil_volts(),
        [5.0, 0.0],
        "clamped to the supply"
    );
}

#[test]
fn schema_hash_is_pinned() {
    // FNV-1a of SCHEMA continued over every message's and field's length
    // (u32 LE), computed independently (Python) when
    // the layouts were last changed. A change to the message table must
    // update docs/protocol.md and this value together.
    assert_eq!(SCHEMA_HASH, SCHEMA_HASH_PINNED);
    assert_eq!((MAX_PAYLOAD, MAX_ENCODED, MAX_FRAME), (52, 55, 56));
}

/// See `schema_hash_is_pinned`.
const SCHEMA_HASH_PINNED: u32 = 0x6715_C80D;

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Arbitrary byte streams: the decoder never panics, every yielded
    /// message re-encodes to a valid frame, and the counters account for
    /// every non-empty frame.
    #[test]
    fn decoder_survives_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600)) {
        let mut dec = FrameDecoder::new(Accept::Any);
        let mut yielded = 0u32;
        for b in &bytes {
            if let Some(r) = dec.push(*b) {
                yielded += 1;
                if let Ok(m) = r {
                    let mut out = [0u8; MAX_FRAME];
                    prop_assert!(encode_frame(&m, &mut out) > 0);
                }
            }
        }
        let s = dec.stats();
        prop_assert_eq!(yielded, s.frames_ok + s.crc_errors + s.cobs_errors + s.overfull + s.malformed);
    }

    /// Sensor frames with arbitrary fields round-trip, even when embedded
    /// between arbitrary noise separated by delimiters.
    #[test]
    fn sensor_frames_survive_noise(seq: u16, counts: [i16; 4], noise in prop::collection::vec(1u8..=255, 0..100)) {
        let msg = Message::HilSensor(HilSensor { seq, counts });
        let mut stream = noise.clone();
        stream.push(0);
        stream.extend(frame(&msg));
        let mut dec = FrameDecoder::board();
        let got = feed(&mut dec, &stream);
        prop_assert!(got.last().map(|r| r.as_ref().ok() == Some(&msg)).unwrap_or(false));
    }

    /// COBS round-trips any data and never emits a zero.
    #[test]
    fn cobs_round_trip(data in prop::collection::vec(any::<u8>(), 0..700)) {
        let mut enc = vec![0u8; cobs::max_encoded_len(data.len())];
        let n = cobs::encode(&data, &mut enc).unwrap();
        prop_assert!(!enc[..n].contains(&0));
        let mut dec = vec![0u8; data.len()];
        let m = cobs::decode(&enc[..n], &mut dec).unwrap();
        prop_assert_eq!(&dec[..m], &data[..]);
    }
}
