//! The board application (`firmware::app::App`) as the image runs it: bytes
//! in, frames out, a board clock from a wrapping `u32` millisecond counter.
//!
//! - free-running and lockstep keep their stale-sensor and link checks
//!   across the counter's wrap and at any uptime;
//! - no output before every channel the law uses has delivered a reading;
//! - a lockstep seq behind the last one answered never steps the core, and
//!   a forward gap longer than the link timeout is a link loss.
use firmware::app::{App, BoardSensors, NoSensors};
use firmware::control::DriveVolts;
use firmware::protocol::*;
use firmware::supervisor::Faults;
use firmware::time::{Instant, MillisCounter};

/// Boot, 1 s before the u32 ms wrap, 5 h, 30 days, 1 year.
const UPTIMES: [Instant; 5] = [
    Instant::ZERO,
    Instant::from_millis(u32::MAX as u64 - 1000),
    Instant::from_secs(5 * 3600),
    Instant::from_secs(30 * 86_400),
    Instant::from_secs(365 * 86_400),
];

/// A board that has been up for `t0`: its u32 millisecond counter reads
/// `t0 mod 2³²` and is extended by `MillisCounter`, as in the image.
pub(crate) struct Board {
    pub(crate) app: App,
    raw_ms: u32,
    counter: MillisCounter,
    first: Instant,
    t0: Instant,
    host: FrameDecoder,
}

impl Board {
    pub(crate) fn up_for(t0: Instant) -> Self {
        let raw_ms = t0.wrapping_millis_u32();
        let mut counter = MillisCounter::new();
        let first = counter.extend(raw_ms);
        Self {
            app: App::new().unwrap(),
            raw_ms,
            counter,
            first,
            t0,
            host: FrameDecoder::host(),
        }
    }

    fn now(&mut self) -> Instant {
        self.t0 + (self.counter.extend(self.raw_ms) - self.first)
    }

    /// Milliseconds since this board's test started.
    fn elapsed_ms(&mut self) -> u64 {
        (self.now() - self.t0).as_millis()
    }

    /// One millisecond passes; the main loop polls.
    pub(crate) fn tick(&mut self, sensors: &mut impl BoardSensors) -> Vec<Message> {
        self.raw_ms = self.raw_ms.wrapping_add(1);
        let now = self.now();
        let mut out = Vec::new();
        self.app
            .poll(now, sensors, &mut |f| out.extend_from_slice(f));
        self.decode(&out)
    }

    fn decode(&mut self, bytes: &[u8]) -> Vec<Message> {
        bytes
            .iter()
            .filter_map(|b| self.host.push(*b))
            .map(|r| r.expect("the board sends valid frames"))
            .collect()
    }

    /// Sends one message as bytes; returns the replies.
    pub(crate) fn send(&mut self, msg: impl Into<Message>) -> Vec<Message> {
        let mut frame = [0u8; MAX_FRAME];
        let n = encode_frame(&msg.into(), &mut frame);
        let now = self.now();
        let mut out = Vec::new();
        for b in &frame[..n] {
            self.app.on_byte(*b, now, &mut |f| out.extend_from_slice(f));
        }
        self.decode(&out)
    }

    pub(crate) fn ack(&mut self, msg: impl Into<Message>) {
        let msg = msg.into();
        let kind = msg.kind();
        assert_eq!(
            self.send(msg),
            [Message::Ack(Ack { request: kind })],
            "{kind:#04x} refused"
        );
    }

    pub(crate) fn status(&mut self) -> Status {
        match self.send(GetStatus {}).as_slice() {
            [Message::Status(s)] => *s,
            other => panic!("{other:?}"),
        }
    }

    pub(crate) fn sensor(&mut self, seq: u16, counts: [i16; 4]) -> Option<HilActuator> {
        match self.send(HilSensor { seq, counts }).as_slice() {
            [] => None,
            [Message::HilActuator(a)] => Some(*a),
            other => panic!("{other:?}"),
        }
    }

    pub(crate) fn lockstep(&mut self, alpha_target_deg: f32) {
        self.ack(HilStart { period_us: 1000 });
        let _ = self.send(ClearFaults {});
        self.ack(SetTarget {
            plane: 0,
            target_deg: alpha_target_deg,
        });
        self.ack(Arm {});
    }
}

/// Counts for α = β = `deg` under the default Eq. 3 law (0.01 mm/count).
pub(crate) fn counts_for(deg: f32) -> [i16; 4] {
    let da = ((deg - 0.323) / 2.727 / 2.0 / 0.01) as i16;
    let db = ((deg - 0.131) / 2.670 / 2.0 / 0.01) as i16;
    [-da, -db, da, db]
}

/// Sensors that deliver `counts_for(0°)` on the channels set in `mask`
/// from read number `from` on, and count how often they are read.
pub(crate) struct Scripted {
    pub(crate) reads: u64,
    from: u64,
    mask: [bool; 4],
    pub(crate) silent_after: Option<u64>,
}

impl Scripted {
    pub(crate) fn all_from(from: u64) -> Self {
        Self {
            reads: 0,
            from,
            mask: [true; 4],
            silent_after: None,
        }
    }
}

impl BoardSensors for Scripted {
    fn read_counts(&mut self) -> [Option<i32>; 4] {
        let k = self.reads;
        self.reads += 1;
        let c = counts_for(0.0);
        core::array::from_fn(|i| {
            let on = k >= self.from && self.mask[i] && self.silent_after.is_none_or(|s| k < s);
            on.then_some(i32::from(c[i]))
        })
    }
}

fn driving(outputs: [[DriveVolts; 2]; 2]) -> bool {
    outputs.iter().flatten().any(|v| v.volts() > 0.0)
}

#[test]
fn free_running_checks_hold_across_the_counter_wrap_and_at_any_uptime() {
    let run = |t0: Instant| {
        let mut b = Board::up_for(t0);
        b.ack(SetTarget {
            plane: 0,
            target_deg: 5.0,
        });
        b.ack(Arm {});
        b.ack(SetTelemetry { rate_hz: 100 });
        // Sensors deliver from the first step; sensor 3 goes silent after
        // 1.5 s (the run crosses the wrap for the second start time).
        let mut s = Scripted::all_from(0);
        s.silent_after = Some(1500);
        let mut record = Vec::new();
        let mut stale_at = None;
        for _ in 0..2000 {
            let frames = b.tick(&mut s);
            let k = b.elapsed_ms();
            for m in frames {
                if let Message::Telemetry(t) = m {
                    assert_eq!(t.time_ms, b.now().wrapping_millis_u32());
                    record.push((k, t.estimate_deg.map(f32::to_bits), t.coil_mv, t.faults));
                }
            }
            if stale_at.is_none()
                && b.app
                    .joint()
                    .supervisor()
                    .latched()
                    .contains(Faults::SENSOR_STALE)
            {
                stale_at = Some(k);
                assert!(!driving(b.app.outputs()));
            }
        }
        // One control step per millisecond of board time.
        assert_eq!(s.reads, 2000, "from {t0}");
        (record, stale_at)
    };
    let (reference, stale_at) = run(Instant::ZERO);
    assert_eq!(
        stale_at,
        Some(1551),
        "50 ms after the last reading at 1500 ms"
    );
    // The first frame at the first poll, then one every 10 ms on the grid
    // from the SetTelemetry instant (fixed rate: 10, 20, …, 2000 ms).
    assert_eq!(reference.len(), 201, "100 Hz telemetry for 2 s");
    assert!(
        reference[1..].iter().all(|r| r.0 % 10 == 0),
        "frames on the 10 ms grid"
    );
    assert!(reference.iter().any(|r| r.2 != [0; 4]), "the board drove");
    for t0 in &UPTIMES[1..] {
        assert_eq!(run(*t0), (reference.clone(), stale_at), "from {t0}");
    }
}

#[test]
fn no_output_before_every_sensor_the_law_uses_has_delivered() {
    // QEMU's board has no sensors: armed right after boot it must never
    // drive (it used to drive its pairs for ~50 ms on placeholder zeros
    // until sensor-stale latched).
    let mut b = Board::up_for(Instant::ZERO);
    b.ack(SetTarget {
        plane: 0,
        target_deg: 10.0,
    });
    b.ack(Arm {});
    for k in 0..200 {
        b.tick(&mut NoSensors);
        assert!(!driving(b.app.outputs()), "driven at {k} ms with no sensor");
    }
    let s = b.status();
    assert_eq!(s.pair_mv, [0, 0]);
    assert!(Faults::from_bits(u16::from(s.latched)).contains(Faults::SENSOR_STALE));
    assert!(
        s.estimate_deg.iter().all(|e| e.is_nan()),
        "no estimate: {s:?}"
    );

    // Three of four sensors deliver: still nothing (the α and β laws read
    // all four), until stale.
    let mut b = Board::up_for(Instant::ZERO);
    b.ack(SetTarget {
        plane: 0,
        target_deg: 10.0,
    });
    b.ack(Arm {});
    let mut s = Scripted::all_from(0);
    s.mask = [true, true, false, true];
    for k in 0..100 {
        b.tick(&mut s);
        assert!(
            !driving(b.app.outputs()),
            "driven at {k} ms with sensor 3 missing"
        );
    }

    // All four from the 30th step on: off before, driven from then on.
    let mut b = Board::up_for(Instant::ZERO);
    b.ack(SetTarget {
        plane: 0,
        target_deg: 10.0,
    });
    b.ack(Arm {});
    let mut s = Scripted::all_from(30);
    let mut first_drive = None;
    for _ in 0..45 {
        b.tick(&mut s);
        if driving(b.app.outputs()) {
            first_drive.get_or_insert(s.reads);
        }
    }
    assert_eq!(
        first_drive,
        Some(31),
        "driven from the first step with all four readings"
    );

    // Lockstep: armed after HilStart, nothing until the first sensor frame.
    let mut b = Board::up_for(Instant::ZERO);
    b.lockstep(10.0);
    for _ in 0..20 {
        b.tick(&mut NoSensors);
        assert!(!driving(b.app.outputs()));
    }
    let a = b.sensor(0, counts_for(0.0)).unwrap();
    assert!(a.pair_mv[0] > 0, "the first frame's readings drive: {a:?}");
}

#[test]
fn a_seq_behind_the_last_one_never_steps_the_core() {
    // A slow triangle (plausible rates).
    let counts = |k: u16| counts_for((f32::from(k % 50) - 25.0).abs() * 0.1);
    // Two boards see the same lockstep run; one also gets a late
    // retransmission of seq 12 after seq 20.
    let mut clean = Board::up_for(Instant::ZERO);
    let mut late = Board::up_for(Instant::ZERO);
    for b in [&mut clean, &mut late] {
        b.lockstep(3.0);
    }
    for seq in 0..=20u16 {
        let a = clean.sensor(seq, counts(seq));
        assert_eq!(late.sensor(seq, counts(seq)), a);
        clean.tick(&mut NoSensors);
        late.tick(&mut NoSensors);
    }
    // A retry of the last seq is answered from the cache, unchanged.
    let cached = late.sensor(20, counts(20)).unwrap();
    assert_eq!(Some(cached), clean.sensor(20, counts(20)));
    // The late frame: no reply, counted, and (below) no step.
    assert_eq!(late.sensor(12, counts(12)), None);
    assert_eq!(late.status().stale_seqs, 1);
    assert_eq!(clean.status().stale_seqs, 0);
    for seq in 21..=60u16 {
        let a = clean.sensor(seq, counts(seq)).unwrap();
        let b = late.sensor(seq, counts(seq)).unwrap();
        assert_eq!(a, b, "seq {seq}");
        assert_eq!(
            Faults::from_bits(u16::from(a.faults)),
            Faults::NONE,
            "seq {seq}: {a:?}"
        );
        clean.tick(&mut NoSensors);
        late.tick(&mut NoSensors);
    }
}

#[test]
fn a_forward_gap_longer_than_the_link_timeout_is_a_link_loss() {
    let mut b = Board::up_for(Instant::ZERO);
    b.lockstep(3.0);
    for seq in 0..10u16 {
        let a = b.sensor(seq, counts_for(1.0)).unwrap();
        assert_eq!(a.faults, 0);
    }
    // 49 periods skipped: within the 50 ms timeout, a normal step.
    assert_eq!(b.sensor(59, counts_for(1.0)).unwrap().faults, 0);
    // 60 skipped (60 ms > 50 ms): link loss, outputs off, and the step's dt
    // is capped, so the thermal budget did not see a minute of heating.
    let a = b.sensor(120, counts_for(1.0)).unwrap();
    let f = Faults::from_bits(u16::from(a.faults));
    assert!(f.contains(Faults::LINK_LOSS), "{f:?}");
    assert!(!f.contains(Faults::OVER_BUDGET), "{f:?}");
    assert_eq!(a.pair_mv, [0, 0]);
}

#[test]
fn lockstep_may_start_at_any_seq_and_wrap() {
    let run = |first: u16| {
        let mut b = Board::up_for(Instant::ZERO);
        b.lockstep(4.0);
        (0..300u16)
            .map(|k| {
                let mut a = b
                    .sensor(first.wrapping_add(k), counts_for(f32::from(k % 60) * 0.05))
                    .unwrap();
                a.seq = k;
                a
            })
            .collect::<Vec<_>>()
    };
    let from_zero = run(0);
    assert_eq!(run(65_500), from_zero, "a run through the u16 wrap");
    assert!(from_zero.iter().any(|a| a.pair_mv[0] > 0));
}

#[test]
fn lockstep_dead_link_is_caught_at_any_uptime() {
    let run = |t0: Instant| {
        let mut b = Board::up_for(t0);
        b.lockstep(5.0);
        let mut replies = Vec::new();
        for seq in 0..100u16 {
            replies.push(b.sensor(seq, counts_for(1.0)).unwrap());
            b.tick(&mut NoSensors);
        }
        assert!(driving(b.app.outputs()));
        let last_frame = b.elapsed_ms() - 1;
        let mut lost_at = None;
        for _ in 0..200 {
            b.tick(&mut NoSensors);
            if lost_at.is_none()
                && b.app
                    .joint()
                    .supervisor()
                    .latched()
                    .contains(Faults::LINK_LOSS)
            {
                lost_at = Some(b.elapsed_ms() - last_frame);
                assert!(!driving(b.app.outputs()));
            }
        }
        let s = b.status();
        assert_eq!(s.pair_mv, [0, 0]);
        (replies, lost_at)
    };
    let reference = run(Instant::ZERO);
    assert_eq!(
        reference.1,
        Some(51),
        "link loss 51 ms after the last frame (timeout 50 ms)"
    );
    for t0 in &UPTIMES[1..] {
        assert_eq!(run(*t0), reference, "from {t0}");
    }
}

#[test]
fn hil_stop_returns_to_free_running() {
    let mut b = Board::up_for(Instant::from_secs(3600));
    b.lockstep(5.0);
    let a = b.sensor(0, counts_for(0.0)).unwrap();
    assert!(a.pair_mv[0] > 0);
    b.ack(HilStop {});
    let s = b.status();
    assert_eq!((s.mode, s.pair_mv), (0, [0, 0]));
    // Lockstep frames are refused now; free-running steps read the board's
    // own sensors (and telemetry streams).
    assert_eq!(
        b.send(HilSensor {
            seq: 1,
            counts: [0; 4]
        }),
        [Message::Nak(Nak {
            request: kind::HIL_SENSOR,
            code: ErrorCode::WrongMode
        })]
    );
    b.ack(SetTelemetry { rate_hz: 1000 });
    let mut s = Scripted::all_from(0);
    let mut telemetry = 0;
    for _ in 0..20 {
        telemetry += b.tick(&mut s).len();
    }
    assert_eq!(s.reads, 20);
    assert_eq!(telemetry, 20);
    assert!(driving(b.app.outputs()), "still armed after HilStop");
}

// ---- Open-loop drive mode (`Drive`, the excitation sessions of issue 20).

/// α's coils 1 and 3 both heated (co-contraction), β left to its
/// controller.
pub(crate) fn alpha_drive(c1_mv: u16, c3_mv: u16, hold_ms: u16) -> Drive {
    Drive {
        planes: 1,
        coil_mv: [c1_mv, 0, c3_mv, 0],
        hold_ms,
    }
}

pub(crate) fn nak_code(b: &mut Board, msg: impl Into<Message>) -> Option<ErrorCode> {
    match b.send(msg).as_slice() {
        [Message::Nak(n)] => Some(n.code),
        [Message::Ack(_)] => None,
        other => panic!("{other:?}"),
    }
}

/// An armed free-running board whose sensors deliver (α = β ≈ 0°).
pub(crate) fn armed_free_running(t0: Instant) -> (Board, Scripted) {
    let mut b = Board::up_for(t0);
    let mut s = Scripted::all_from(0);
    for _ in 0..5 {
        b.tick(&mut s);
    }
    b.ack(Arm {});
    (b, s)
}

#[test]
fn a_drive_co_contracts_and_ends_unpowered_when_not_refreshed() {
    for t0 in UPTIMES {
        let (mut b, mut s) = armed_free_running(t0);
        b.ack(alpha_drive(3000, 1900, 100));
        let mut on_for = 0;
        let mut off_at = None;
        for k in 1..=600u64 {
            b.tick(&mut s);
            let [[ag, ant], _] = b.app.outputs();
            if ag.volts() > 0.0 && ant.volts() > 0.0 {
                // Both coils of the pair at the requested inputs.
                assert_eq!((ag.volts(), ant.volts()), (3.0, 1.9), "from {t0}");
                on_for = k;
            } else if off_at.is_none() {
                off_at = Some(k);
            }
            if let Some(off) = off_at {
                assert_eq!(
                    b.app.outputs()[0],
                    [DriveVolts::ZERO; 2],
                    "from {t0}: α powered again at {k} ms after the drive ended at {off} ms"
                );
            }
        }
        assert_eq!((on_for, off_at), (99, Some(100)), "from {t0}: hold 100 ms");
        let st = b.status();
        // α's coils 1 and 3 are off; β (coils 2, 4) is its controller's.
        assert_eq!(
            (st.coil_mv[0], st.coil_mv[2], st.drive_planes),
            (0, 0, 1),
            "from {t0}"
        );
        // A target gives the plane back to its controller.
        b.ack(SetTarget {
            plane: 0,
            target_deg: 5.0,
        });
        b.tick(&mut s);
        assert_eq!(b.status().drive_planes, 0);
        let [[ag, ant], _] = b.app.outputs();
        assert!(ag.volts() > 0.0 && ant.volts() == 0.0, "controller again");
    }
}

#[test]
fn a_drive_is_refused_by_name() {
    let (mut b, mut s) = armed_free_running(Instant::from_secs(3600));
    let out_of_range = [
        Drive {
            planes: 0,
            coil_mv: [0; 4],
            hold_ms: 10,
        },
        Drive {
            planes: 4,
            coil_mv: [0; 4],
            hold_ms: 10,
        },
        alpha_drive(3000, 0, 0),
        alpha_drive(3000, 0, 1001),
        alpha_drive(5001, 0, 10),
        // A coil of β, which the frame does not drive.
        Drive {
            planes: 1,
            coil_mv: [3000, 1, 0, 0],
            hold_ms: 10,
        },
    ];
    for d in out_of_range {
        assert_eq!(nak_code(&mut b, d), Some(ErrorCode::OutOfRange), "{d:?}");
    }
    assert_eq!(nak_code(&mut b, alpha_drive(5000, 5000, 1000)), None);
    b.ack(Disarm {});
    assert_eq!(b.status().drive_planes, 0, "Disarm ends every drive");
    assert_eq!(
        nak_code(&mut b, alpha_drive(3000, 0, 10)),
        Some(ErrorCode::Disarmed)
    );
    // Lockstep: the host owns time, so there is no open loop.
    b.ack(HilStart { period_us: 1000 });
    b.ack(Arm {});
    assert_eq!(
        nak_code(&mut b, alpha_drive(3000, 0, 10)),
        Some(ErrorCode::WrongMode)
    );
    b.ack(HilStop {});
    // A latched fault (the sensors went silent: stale).
    s.silent_after = Some(s.reads);
    for _ in 0..100 {
        b.tick(&mut s);
    }
    assert!(b
        .app
        .joint()
        .supervisor()
        .latched()
        .contains(Faults::SENSOR_STALE));
    assert_eq!(
        nak_code(&mut b, alpha_drive(3000, 0, 10)),
        Some(ErrorCode::Latched)
    );
}

#[test]
fn a_sustained_over_budget_drive_trips_that_coil_and_is_then_refused() {
    use firmware::supervisor::ThermalConfig;
    let (mut b, mut s) = armed_free_running(Instant::from_secs(5 * 3600));
    b.ack(SetTelemetry { rate_hz: 100 });
    // Coil 1 at the supply (0.5 A: steady rise 195 K > trip 95 K), coil 3
    // warm at 1.9 V (steady rise 14 K: never trips), refreshed every
    // 500 ms as a host would.
    let mut tripped_at = None;
    let mut over_budget_seen = false;
    for k in 0..6000u64 {
        if k % 500 == 0 {
            let refused = nak_code(&mut b, alpha_drive(5000, 1900, 600));
            if tripped_at.is_some() {
                assert_eq!(refused, Some(ErrorCode::OverBudget));
                break;
            }
            assert_eq!(refused, None, "at {k} ms");
        }
        for m in b.tick(&mut s) {
            if let Message::Telemetry(t) = m {
                over_budget_seen |= t.faults & faults_to_u8(Faults::OVER_BUDGET) != 0;
                if tripped_at.is_none() {
                    assert_eq!(t.coil_mv[0], 5000, "at {k} ms: {t:?}");
                }
                assert_eq!(t.coil_mv[2], 1900, "the other coil is unaffected: {t:?}");
                assert!(t.counts.iter().all(|c| *c != i32::MIN), "{t:?}");
            }
        }
        let [[ag, ant], _] = b.app.outputs();
        assert_eq!(ant.volts(), 1.9, "coil 3 still driven at {k} ms");
        if ag.volts() == 0.0 && tripped_at.is_none() {
            tripped_at = Some(k);
        }
    }
    // Closed form of the first-order budget: the rise T∞(1 − e^(−t/τ))
    // reaches 95 K at −τ ln(1 − 95/195.3) ≈ 3.34 s.
    let cfg = ThermalConfig::default();
    let d = firmware::control::DriverConfig::default();
    let expect_s =
        -cfg.time_constant_s * (1.0 - cfg.trip_rise_k / cfg.steady_rise_k(d.clamp(5.0), &d)).ln();
    let t_s = tripped_at.expect("never tripped") as f32 * 1e-3;
    assert!(
        (t_s - expect_s).abs() < 0.02,
        "tripped at {t_s} s, closed form {expect_s} s"
    );
    assert!(over_budget_seen, "telemetry said over-budget");
    // The trip is not latched: the other coil may still be driven.
    assert_eq!(nak_code(&mut b, alpha_drive(0, 1900, 100)), None);
}

#[test]
fn without_a_drive_the_pair_rule_holds_and_the_other_plane_stays_controlled() {
    let (mut b, mut s) = armed_free_running(Instant::ZERO);
    b.ack(SetTarget {
        plane: 1,
        target_deg: -5.0,
    });
    b.ack(SetTarget {
        plane: 0,
        target_deg: 5.0,
    });
    // Closed loop: never both coils of a pair.
    for _ in 0..200 {
        b.tick(&mut s);
        for [ag, ant] in b.app.outputs() {
            assert!(ag.volts() == 0.0 || ant.volts() == 0.0);
        }
    }
    // α driven open loop; β keeps its controller (antagonist for −5°).
    b.ack(alpha_drive(2500, 2000, 1000));
    for _ in 0..50 {
        b.tick(&mut s);
    }
    let [alpha, [b_ag, b_ant]] = b.app.outputs();
    assert_eq!(alpha.map(DriveVolts::volts), [2.5, 2.0]);
    assert!(
        b_ag.volts() == 0.0 && b_ant.volts() > 1.7,
        "β under control"
    );
    let st = b.status();
    assert_eq!(st.coil_mv[0], 2500);
    assert_eq!(st.coil_mv[2], 2000);
    assert_eq!(st.pair_mv[0], 0, "α is not a controller output");
    assert!(st.pair_mv[1] < 0, "β's controller drives its antagonist");
}

/// `SetGains.v_offset_v` is the law's input at zero effort: the same
/// error with the offset at 1.2 V instead of the paper's 1.7 V drives the
/// agonist 0.5 V lower; an offset at or above the supply, or not finite,
/// is refused by name.
#[test]
fn set_gains_carries_v_offset() {
    let mut b = Board::up_for(Instant::ZERO);
    let gains = |v_offset_v: f32| SetGains {
        plane: 0,
        kp_agonist: 0.1,
        kp_antagonist: 0.1,
        ki: 0.0,
        integral_limit_v: 0.0,
        v_offset_v,
    };
    let mut agonist_mv = Vec::new();
    for v in [1.7, 1.2] {
        b.ack(gains(v));
        b.lockstep(5.0);
        let a = b.sensor(0, counts_for(0.0)).unwrap();
        agonist_mv.push(a.pair_mv[0]);
    }
    // α ≈ 0.3° from counts_for(0): effort 0.1 V/° × 4.7° ≈ 0.47 V.
    assert!((2100..2250).contains(&agonist_mv[0]), "{agonist_mv:?}");
    assert_eq!(agonist_mv[0] - agonist_mv[1], 500, "{agonist_mv:?}");
    for (v, code) in [
        (5.0, ErrorCode::OutOfRange),
        (-0.1, ErrorCode::OutOfRange),
        (f32::NAN, ErrorCode::NotFinite),
    ] {
        assert_eq!(
            b.send(gains(v)),
            [Message::Nak(Nak {
                request: kind::SET_GAINS,
                code
            })],
            "v_offset {v}"
        );
    }
}
