//! The protocol between the host tools and the firmware's board application
//! over a real pty pair: every message, error replies, garbage on the line,
//! dropped and delayed frames, and a dead link.
use std::time::{Duration, Instant};

use firmware::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};
use firmware::protocol::*;
use firmware::supervisor::Faults;
use host_tools::board::link::{Link, LinkError};
use integration_tests::{start_lockstep, PtyBoard};
use rand::{Rng, SeedableRng};

const T: Duration = Duration::from_millis(300);

fn refused(r: Result<(), LinkError>) -> ErrorCode {
    match r {
        Err(LinkError::Refused { code, .. }) => code,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

fn status<P: host_tools::board::link::Port>(link: &mut Link<P>) -> Status {
    host_tools::board::hil::status(link).expect("status")
}

fn sensor(
    link: &mut Link<impl host_tools::board::link::Port>,
    seq: u16,
    counts: [i16; 4],
) -> HilActuator {
    match link
        .request(
            &HilSensor { seq, counts }.into(),
            T,
            10,
            |m| matches!(m, Message::HilActuator(a) if a.seq == seq),
        )
        .expect("actuator frame")
    {
        Message::HilActuator(a) => a,
        _ => unreachable!(),
    }
}

/// Counts for α = β = `deg` under the default Eq. 3 law (0.01 mm/count).
fn counts_for(deg: f32) -> [i16; 4] {
    let da = ((deg - 0.323) / 2.727 / 2.0 / 0.01) as i16;
    let db = ((deg - 0.131) / 2.670 / 2.0 / 0.01) as i16;
    [-da, -db, da, db]
}

#[test]
fn every_message_over_a_real_pty() {
    let (_board, port) = PtyBoard::start().expect("pty pair");
    let mut link = Link::new(port);
    host_tools::board::hil::handshake(&mut link).expect("handshake");
    assert_eq!(
        link.request(&Hello { version: 9 }.into(), T, 3, |m| matches!(
            m,
            Message::HelloAck(_)
        ))
        .err()
        .map(|e| e.to_string()),
        Some(
            LinkError::Refused {
                request: kind::HELLO,
                code: ErrorCode::Version
            }
            .to_string()
        )
    );

    // Configuration round trips.
    let law = PlaneLaw::Switching {
        plus: 2,
        minus: 0,
        high: LinearLaw {
            gain: 2.7,
            offset: 0.3,
        },
        sensor: 2,
        low: QuadraticLaw {
            a: 0.02,
            b: 5.4,
            c: 0.25,
        },
        threshold_deg: -7.46,
        hysteresis_deg: 0.5,
    };
    link.command(&SetCalibration { plane: 0, law }.into(), T, 3)
        .unwrap();
    match link
        .request(&GetCalibration { plane: 0 }.into(), T, 3, |m| {
            matches!(m, Message::Calibration(_))
        })
        .unwrap()
    {
        Message::Calibration(Calibration {
            plane: 0,
            law: back,
        }) => assert_eq!(back, law),
        other => panic!("{other:?}"),
    }
    let bad_law = PlaneLaw::Single {
        sensor: 7,
        law: QuadraticLaw::PAPER_2D,
    };
    assert_eq!(
        refused(
            link.command(
                &SetCalibration {
                    plane: 0,
                    law: bad_law
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::OutOfRange
    );
    let nan_law = PlaneLaw::Single {
        sensor: 0,
        law: QuadraticLaw {
            a: f32::NAN,
            b: 0.0,
            c: 0.0,
        },
    };
    assert_eq!(
        refused(
            link.command(
                &SetCalibration {
                    plane: 1,
                    law: nan_law
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::NotFinite
    );
    assert_eq!(
        refused(
            link.request(&GetCalibration { plane: 4 }.into(), T, 3, |m| matches!(
                m,
                Message::Calibration(_)
            ))
            .map(|_| ())
        ),
        ErrorCode::OutOfRange
    );
    link.command(
        &SetGains {
            plane: 1,
            kp_agonist: 1.5,
            kp_antagonist: 1.0,
            ki: 0.2,
            integral_limit_v: 1.0,
            v_offset_v: 1.7,
        }
        .into(),
        T,
        3,
    )
    .unwrap();
    assert_eq!(
        refused(
            link.command(
                &SetGains {
                    plane: 1,
                    kp_agonist: -1.0,
                    kp_antagonist: 1.0,
                    ki: 0.0,
                    integral_limit_v: 0.0,
                    v_offset_v: 1.7,
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::OutOfRange
    );
    assert_eq!(
        refused(
            link.command(
                &SetGains {
                    plane: 0,
                    kp_agonist: f32::INFINITY,
                    kp_antagonist: 1.0,
                    ki: 0.0,
                    integral_limit_v: 0.0,
                    v_offset_v: 1.7,
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::NotFinite
    );
    link.command(
        &SetTarget {
            plane: 0,
            target_deg: 5.0,
        }
        .into(),
        T,
        3,
    )
    .unwrap();
    assert_eq!(
        refused(
            link.command(
                &SetTarget {
                    plane: 0,
                    target_deg: f32::NAN
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::NotFinite
    );
    assert_eq!(
        refused(
            link.command(
                &SetTarget {
                    plane: 0,
                    target_deg: 90.0
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::OutOfRange
    );
    assert_eq!(
        refused(
            link.command(
                &SetTarget {
                    plane: 3,
                    target_deg: 1.0
                }
                .into(),
                T,
                3
            )
        ),
        ErrorCode::OutOfRange
    );
    assert_eq!(
        refused(link.command(&SetLinkTimeout { timeout_ms: 0 }.into(), T, 3)),
        ErrorCode::OutOfRange
    );
    assert_eq!(
        refused(link.command(&SetTelemetry { rate_hz: 5000 }.into(), T, 3)),
        ErrorCode::OutOfRange
    );
    assert_eq!(
        refused(link.command(&HilStart { period_us: 10 }.into(), T, 3)),
        ErrorCode::OutOfRange
    );
    // A board-to-host message sent to the board is not a request.
    assert_eq!(
        refused(link.command(&Ack { request: 1 }.into(), T, 3)),
        ErrorCode::UnknownType
    );
    // Lockstep frames before HilStart.
    assert_eq!(
        refused(
            link.request(
                &HilSensor {
                    seq: 0,
                    counts: [0; 4]
                }
                .into(),
                T,
                3,
                |_| false
            )
            .map(|_| ())
        ),
        ErrorCode::WrongMode
    );

    // Free-running telemetry: a 100 Hz stream, then off.
    link.command(&SetTelemetry { rate_hz: 100 }.into(), T, 3)
        .unwrap();
    let end = Instant::now() + Duration::from_millis(300);
    let mut n = 0;
    while let Some(m) = link.recv_until(end).unwrap() {
        if matches!(m, Message::Telemetry(_)) {
            n += 1;
        }
    }
    assert!(
        (15..=40).contains(&n),
        "{n} telemetry frames in 0.3 s at 100 Hz"
    );
    link.command(&SetTelemetry { rate_hz: 0 }.into(), T, 3)
        .unwrap();
    // The board without sensors latches a stale-sensor fault in free-running
    // mode and reports it.
    let s = status(&mut link);
    assert_eq!(s.mode, 0);
    assert!(
        Faults::from_bits(u16::from(s.latched)).contains(Faults::SENSOR_STALE),
        "{s:?}"
    );

    // Lockstep: HilStart, clear, arm, frames.
    link.command(&HilStart { period_us: 1000 }.into(), T, 3)
        .unwrap();
    link.command(&ClearFaults {}.into(), T, 3).unwrap();
    link.command(
        &SetTarget {
            plane: 1,
            target_deg: 0.0,
        }
        .into(),
        T,
        3,
    )
    .unwrap();
    link.command(
        &SetCalibration {
            plane: 0,
            law: PlaneLaw::Differential {
                plus: 2,
                minus: 0,
                law: LinearLaw::PAPER_ALPHA,
            },
        }
        .into(),
        T,
        3,
    )
    .unwrap();
    link.command(&Arm {}.into(), T, 3).unwrap();
    let mut last = None;
    for seq in 0..50u16 {
        let a = sensor(&mut link, seq, counts_for(0.0));
        assert_eq!(a.faults, 0, "step {seq}: {a:?}");
        last = Some(a);
    }
    let a = last.unwrap();
    assert!(
        a.pair_mv[0] > 1700,
        "α below its 5° target: agonist driven ({a:?})"
    );
    assert!((cdeg_to_deg(a.estimate_cdeg[0]) - 0.0).abs() < 0.1, "{a:?}");
    // A repeated seq is answered from the cache, identically.
    assert_eq!(
        sensor(&mut link, 49, counts_for(3.0)),
        a,
        "retry of seq 49 must not step again"
    );
    let s = status(&mut link);
    assert_eq!((s.mode, s.armed), (1, 1));
    assert_eq!(s.pair_mv, a.pair_mv);
    link.command(&Disarm {}.into(), T, 3).unwrap();
    assert_eq!(status(&mut link).pair_mv, [0, 0], "disarm zeroes outputs");
    assert_eq!(link.stats().retries, 0);
}

#[test]
fn garbage_on_the_line_is_counted_dropped_and_never_wedges_the_board() {
    let (_board, port) = PtyBoard::start().expect("pty pair");
    let mut link = Link::new(port);
    host_tools::board::hil::handshake(&mut link).unwrap();
    let before = status(&mut link);
    // Build an adversarial stream: random bytes, truncated frames, an
    // oversized frame, bit-flipped frames, duplicated frames. An independent
    // decoder predicts what the board must count.
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
    let mut stream = Vec::new();
    let mut frame = [0u8; MAX_FRAME];
    for i in 0..200u16 {
        let n = encode_frame(
            &SetTarget {
                plane: 0,
                target_deg: f32::from(i % 20),
            }
            .into(),
            &mut frame,
        );
        match i % 5 {
            0 => stream.extend((0..rng.gen_range(1..40)).map(|_| rng.gen::<u8>())),
            1 => stream.extend_from_slice(&frame[..rng.gen_range(1..n - 1)]),
            2 => stream.extend(std::iter::repeat_n(0x5A, MAX_FRAME + 5)),
            3 => {
                let mut f = frame[..n].to_vec();
                let byte = rng.gen_range(0..n - 1);
                f[byte] ^= 1 << rng.gen_range(0..8);
                stream.extend(f);
            }
            _ => {
                stream.extend_from_slice(&frame[..n]);
                stream.extend_from_slice(&frame[..n]);
            }
        }
        stream.push(0);
    }
    let mut model = FrameDecoder::board();
    let mut expected_acks = 0;
    let mut expected_errors = 0;
    for b in &stream {
        match model.push(*b) {
            Some(Ok(_)) => expected_acks += 1,
            Some(Err(FrameError::Malformed { .. })) => expected_errors += 1,
            _ => {}
        }
    }
    for chunk in stream.chunks(64) {
        link.send_raw(chunk).unwrap();
        std::thread::sleep(Duration::from_millis(1));
    }
    // Collect the replies the valid (and malformed-but-CRC-valid) frames got.
    let end = Instant::now() + Duration::from_millis(1500);
    let (mut acks, mut errors) = (0, 0);
    while let Some(m) = link.recv_until(end).unwrap() {
        match m {
            Message::Ack(_) => acks += 1,
            Message::Nak(_) => errors += 1,
            _ => {}
        }
        if acks == expected_acks && errors == expected_errors {
            break;
        }
    }
    assert_eq!(
        (acks, errors),
        (expected_acks, expected_errors),
        "replies to the valid frames in the garbage"
    );
    let after = status(&mut link);
    let m = model.stats();
    assert_eq!(
        u32::from(after.crc_errors - before.crc_errors),
        m.crc_errors,
        "CRC errors counted"
    );
    assert_eq!(
        u32::from(after.cobs_errors - before.cobs_errors),
        m.cobs_errors,
        "COBS errors counted"
    );
    assert_eq!(
        u32::from(after.overfull - before.overfull),
        m.overfull,
        "oversized frames counted"
    );
    assert!(
        m.crc_errors + m.cobs_errors > 50 && m.overfull == 40,
        "the stream exercised every kind: {m:?}"
    );
    // And the board still answers normally.
    host_tools::board::hil::handshake(&mut link).unwrap();
}

#[test]
fn lost_and_delayed_frames_are_retried_and_steps_run_once() {
    let (board, port) = PtyBoard::start().expect("pty pair");
    let mut link = Link::new(port);
    // Retries take longer than the default 50 ms link-loss time (which
    // would then rightly latch); give the link 500 ms for this test.
    start_lockstep(&mut link, Some(500), 5.0, T);
    let timeout = Duration::from_millis(60);
    let step = |link: &mut Link<_>, seq: u16| -> HilActuator {
        match link
            .request(
                &HilSensor {
                    seq,
                    counts: counts_for(0.0),
                }
                .into(),
                timeout,
                10,
                |m| matches!(m, Message::HilActuator(a) if a.seq == seq),
            )
            .unwrap()
        {
            Message::HilActuator(a) => a,
            _ => unreachable!(),
        }
    };
    let mut replies = Vec::new();
    for seq in 0..30u16 {
        match seq {
            5 => link.lose_next_send(),                          // request lost
            10 => board.faults.lock().unwrap().drop_replies = 1, // reply lost
            20 => board.faults.lock().unwrap().delay_replies = Duration::from_millis(90), // late
            21 => board.faults.lock().unwrap().delay_replies = Duration::ZERO,
            _ => {}
        }
        replies.push(step(&mut link, seq));
    }
    let stats = link.stats();
    assert!(
        stats.retries >= 3,
        "one retry each for the lost request, lost reply and late reply: {stats:?}"
    );
    assert!(
        stats.unexpected >= 1,
        "the late reply arrives after its retry was sent: {stats:?}"
    );
    assert_eq!(board.state.lock().unwrap().dropped, 1);
    // Idempotency: the same frames on a fault-free board give the same
    // replies, so the retried steps ran exactly once.
    let (_clean, port) = PtyBoard::start().expect("pty pair");
    let mut clean = Link::new(port);
    start_lockstep(&mut clean, Some(500), 5.0, T);
    for (seq, r) in replies.iter().enumerate() {
        assert_eq!(
            &sensor(&mut clean, seq as u16, counts_for(0.0)),
            r,
            "seq {seq}"
        );
    }
}

#[test]
fn a_dead_link_zeroes_the_outputs_within_the_link_loss_time() {
    let (board, port) = PtyBoard::start().expect("pty pair");
    let mut link = Link::new(port);
    start_lockstep(&mut link, None, 10.0, T);
    let mut a = None;
    for seq in 0..20u16 {
        a = Some(sensor(&mut link, seq, counts_for(0.0)));
    }
    assert!(a.unwrap().pair_mv[0] > 0, "driving before the link dies");
    // The host goes silent.
    std::thread::sleep(Duration::from_millis(300));
    let st = board.state.lock().unwrap();
    let (last_rx, off_at) = (
        st.last_rx_ms.unwrap(),
        st.outputs_off_at_ms.expect("outputs never went off"),
    );
    assert!(st.outputs.iter().flatten().all(|v| v.volts() == 0.0));
    let waited = off_at - last_rx;
    // Default link-loss time 50 ms. The board thread polls every ~1 ms; the
    // upper bound leaves room for thread scheduling on a shared 2-core CI
    // machine (the firmware image polls the same way, without that jitter).
    assert!(
        (50..=75).contains(&waited),
        "outputs off {waited} ms after the last frame"
    );
    drop(st);
    let s = status(&mut link);
    assert!(Faults::from_bits(u16::from(s.latched)).contains(Faults::LINK_LOSS));
    assert_eq!(s.pair_mv, [0, 0]);
    // Frames resume: outputs stay off (latched) until the host clears.
    let r = sensor(&mut link, 20, counts_for(0.0));
    assert_eq!(r.pair_mv, [0, 0]);
    assert!(Faults::from_bits(u16::from(r.faults)).contains(Faults::LINK_LOSS));
    link.command(&ClearFaults {}.into(), T, 3).unwrap();
    let r = sensor(&mut link, 21, counts_for(0.0));
    assert!(r.pair_mv[0] > 0, "cleared: driving again ({r:?})");
}
