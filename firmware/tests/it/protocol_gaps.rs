//! The behaviours `docs/protocol.md` decides where it used to be silent
//! (issue 32), each through the board application as the image runs it
//! (bytes in, frames out): when a request takes effect (§4.5), which
//! refusal comes first (§4.5), a latch ending a drive (§7.1), `HilStop`
//! in free-running mode and a new time base powering nothing before
//! readings (§6.8, §7), the integral's restart and first increment
//! (§8.3), no estimate from a faulted step (§8.2), the rate limit's end
//! point (§8.1), and the lockstep period held to the stale limit (§6.3,
//! §6.6).
use firmware::app::{BoardSensors, NoSensors};
use firmware::control::DriveVolts;
use firmware::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};
use firmware::protocol::*;
use firmware::supervisor::Faults;
use firmware::time::Instant;

use super::board_app::{alpha_drive, armed_free_running, counts_for, nak_code, Board};

/// Sensors that read fixed counts.
struct Fixed([Option<i32>; 4]);

impl BoardSensors for Fixed {
    fn read_counts(&mut self) -> [Option<i32>; 4] {
        self.0
    }
}

fn bit(f: Faults) -> u8 {
    faults_to_u8(f)
}

#[test]
fn outputs_change_at_the_next_step_except_where_a_request_removes_drive() {
    let (mut b, mut s) = armed_free_running(Instant::from_secs(60));
    b.ack(alpha_drive(3000, 1900, 100));
    // The Ack comes before the step that applies the drive.
    let before = b.status();
    assert_eq!((before.coil_mv[0], before.coil_mv[2]), (0, 0), "{before:?}");
    assert_eq!(before.drive_planes, 1, "the request itself is carried out");
    b.tick(&mut s);
    let after = b.status();
    assert_eq!((after.coil_mv[0], after.coil_mv[2]), (3000, 1900));
    // Disarm removes drive before its Ack.
    b.ack(Disarm {});
    let off = b.status();
    assert_eq!((off.coil_mv, off.pair_mv), ([0; 4], [0; 2]), "{off:?}");

    // Lockstep: a new target acts at the next HilSensor.
    let mut b = Board::up_for(Instant::from_secs(60));
    b.lockstep(0.0);
    let c = counts_for(0.0);
    let first = b.sensor(1, c).unwrap().pair_mv[0];
    b.ack(SetTarget {
        plane: 0,
        target_deg: 2.0,
    });
    assert_eq!(b.status().pair_mv[0], first, "still the step before");
    let next = b.sensor(2, c).unwrap().pair_mv[0];
    assert!(next > first + 3000, "{first} mV → {next} mV");
    // HilStart sets the outputs to 0 before its Ack.
    b.ack(HilStart { period_us: 1000 });
    assert_eq!(b.status().pair_mv, [0, 0]);
}

#[test]
fn refusals_come_in_the_documented_order() {
    // Lockstep, disarmed, a fault latched, values out of range: WrongMode.
    let mut b = Board::up_for(Instant::ZERO);
    b.ack(HilStart { period_us: 1000 });
    b.sensor(0, counts_for(0.0));
    b.sensor(1000, counts_for(0.0)); // a gap of 1 s: link-loss latches
    assert_ne!(b.status().latched, 0);
    let bad = Drive {
        planes: 0,
        coil_mv: [9999; 4],
        hold_ms: 0,
    };
    assert_eq!(nak_code(&mut b, bad), Some(ErrorCode::WrongMode));
    b.ack(HilStop {});
    // Free-running, disarmed, latched: OutOfRange, then Disarmed, then
    // Latched.
    assert_eq!(nak_code(&mut b, bad), Some(ErrorCode::OutOfRange));
    let good = alpha_drive(3000, 0, 10);
    assert_eq!(nak_code(&mut b, good), Some(ErrorCode::Disarmed));
    b.ack(Arm {});
    assert_eq!(nak_code(&mut b, good), Some(ErrorCode::Latched));
    // NotFinite before OutOfRange and WrongMode.
    assert_eq!(
        nak_code(
            &mut b,
            SetTarget {
                plane: 7,
                target_deg: f32::NAN
            }
        ),
        Some(ErrorCode::NotFinite)
    );
    let flat_nan = PlaneLaw::Switching {
        plus: 2,
        minus: 2,
        high: LinearLaw {
            gain: 0.0,
            offset: 0.0,
        },
        sensor: 9,
        low: QuadraticLaw {
            a: f32::NAN,
            b: 0.0,
            c: 0.0,
        },
        threshold_deg: 0.0,
        hysteresis_deg: 0.5,
    };
    assert_eq!(
        nak_code(
            &mut b,
            SetCalibration {
                plane: 5,
                law: flat_nan
            }
        ),
        Some(ErrorCode::NotFinite)
    );
}

#[test]
fn a_latch_over_budget_comes_after_latched() {
    let (mut b, mut s) = armed_free_running(Instant::ZERO);
    // Trip coil 1 (3.34 s at the supply, §8.4), then latch sensor-stale.
    for k in 0..3500u64 {
        if k % 500 == 0 {
            assert_eq!(nak_code(&mut b, alpha_drive(5000, 0, 600)), None, "{k}");
        }
        b.tick(&mut s);
    }
    assert!(b.app.joint().supervisor().coil_tripped(0, 0));
    s.silent_after = Some(s.reads);
    for _ in 0..60 {
        b.tick(&mut s);
    }
    assert_eq!(
        nak_code(&mut b, alpha_drive(5000, 0, 10)),
        Some(ErrorCode::Latched)
    );
}

#[test]
fn the_flat_quadratic_is_refused_by_the_rule_the_page_names() {
    let mut b = Board::up_for(Instant::ZERO);
    let flat = QuadraticLaw {
        a: 0.0,
        b: 0.0,
        c: 3.0,
    };
    let single = PlaneLaw::Single {
        sensor: 0,
        law: flat,
    };
    let switching = PlaneLaw::Switching {
        plus: 2,
        minus: 0,
        high: LinearLaw::PAPER_ALPHA,
        sensor: 0,
        low: flat,
        threshold_deg: -7.46,
        hysteresis_deg: 0.5,
    };
    for law in [single, switching] {
        assert_eq!(
            nak_code(&mut b, SetCalibration { plane: 0, law }),
            Some(ErrorCode::OutOfRange),
            "{law:?}"
        );
    }
    // With b ≠ 0 the same laws are accepted.
    let sloped = QuadraticLaw { b: 1.0, ..flat };
    let ok = PlaneLaw::Single {
        sensor: 0,
        law: sloped,
    };
    assert_eq!(nak_code(&mut b, SetCalibration { plane: 0, law: ok }), None);
}

#[test]
fn a_latch_ends_a_drive_and_clearing_it_powers_nothing() {
    let (mut b, mut s) = armed_free_running(Instant::from_secs(3600));
    b.ack(alpha_drive(3000, 0, 1000));
    for _ in 0..5 {
        b.tick(&mut s);
    }
    assert_eq!(b.status().coil_mv[0], 3000);
    s.silent_after = Some(s.reads);
    for _ in 0..60 {
        b.tick(&mut s);
    }
    let st = b.status();
    assert_ne!(st.latched & bit(Faults::SENSOR_STALE), 0, "{st:?}");
    assert_eq!((st.coil_mv[0], st.drive_planes), (0, 1), "{st:?}");
    // The sensors come back; the fault is cleared well within the drive's
    // 1000 ms hold, and still α stays unpowered.
    s.silent_after = None;
    b.tick(&mut s);
    b.ack(ClearFaults {});
    for _ in 0..20 {
        b.tick(&mut s);
        assert_eq!(b.app.outputs()[0], [DriveVolts::ZERO; 2]);
    }
    assert_eq!(b.status().drive_planes, 1);
    // A new Drive powers it again.
    b.ack(alpha_drive(3000, 0, 1000));
    b.tick(&mut s);
    assert_eq!(b.status().coil_mv[0], 3000);
}

#[test]
fn hil_stop_in_free_running_changes_nothing() {
    let mut b = Board::up_for(Instant::from_secs(10));
    for _ in 0..60 {
        b.tick(&mut NoSensors);
    }
    assert_ne!(b.status().latched & bit(Faults::SENSOR_STALE), 0);
    b.ack(HilStop {});
    // The time base was not restarted: the stale cause is still present.
    assert_eq!(
        nak_code(&mut b, ClearFaults {}),
        Some(ErrorCode::StillFaulted)
    );
}

#[test]
fn a_new_time_base_powers_nothing_before_readings() {
    // A board without sensors: after HilStop from lockstep there is no
    // fault cause for 50 ms, so ClearFaults, Arm and Drive are accepted —
    // and nothing is powered, because no sensor has delivered.
    let mut b = Board::up_for(Instant::from_secs(10));
    for _ in 0..60 {
        b.tick(&mut NoSensors);
    }
    b.ack(HilStart { period_us: 1000 });
    b.ack(HilStop {});
    b.ack(ClearFaults {});
    b.ack(Arm {});
    b.ack(alpha_drive(3000, 3000, 1000));
    for k in 0..70 {
        b.tick(&mut NoSensors);
        assert_eq!(
            b.app.outputs(),
            [[DriveVolts::ZERO; 2]; 2],
            "powered {k} ms after the drive with no sensor reading"
        );
    }
    let st = b.status();
    assert_ne!(st.latched & bit(Faults::SENSOR_STALE), 0, "{st:?}");
    assert_eq!(st.drive_planes, 1, "the latch ended the drive: {st:?}");
}

/// The volts of a pair output in millivolts.
fn volts(mv: i16) -> f32 {
    f32::from(mv) * 1e-3
}

#[test]
fn the_integral_starts_empty_and_its_first_step_holds_one_increment() {
    let (kp, ki, dt_s, target) = (1.0f32, 5.0f32, 0.01f32, 1.0f32);
    let mut b = Board::up_for(Instant::from_secs(100));
    b.ack(HilStart { period_us: 10_000 });
    b.ack(SetGains {
        plane: 0,
        kp_agonist: kp,
        kp_antagonist: kp,
        ki,
        integral_limit_v: 2.0,
        v_offset_v: 1.7,
    });
    b.ack(SetTarget {
        plane: 0,
        target_deg: target,
    });
    b.ack(Arm {});
    let c = counts_for(0.0);
    let first = b.sensor(10, c).unwrap();
    let e = target - b.status().estimate_deg[0];
    // v_offset + kp·e + ki·e·dt: the step's own increment is in.
    let expect1 = 1.7 + kp * e + ki * e * dt_s;
    assert!(
        (volts(first.pair_mv[0]) - expect1).abs() <= 1e-3,
        "{first:?} vs {expect1} V"
    );
    let second = b.sensor(11, c).unwrap();
    let expect2 = 1.7 + kp * e + 2.0 * ki * e * dt_s;
    assert!((volts(second.pair_mv[0]) - expect2).abs() <= 1e-3);
    // A gap of 10 periods (100 ms > the 50 ms link timeout) latches
    // link-loss; cleared, the integral starts again from 0.
    let latched = b.sensor(21, c).unwrap();
    assert_eq!(latched.pair_mv, [0, 0]);
    assert_ne!(latched.faults & bit(Faults::LINK_LOSS), 0);
    b.ack(ClearFaults {});
    let resumed = b.sensor(22, c).unwrap();
    assert!(
        (volts(resumed.pair_mv[0]) - expect1).abs() <= 1e-3,
        "{resumed:?}: not restarted from an empty integral ({expect1} V)"
    );
}

#[test]
fn a_step_whose_sensor_checks_fail_reports_no_estimate() {
    let mut b = Board::up_for(Instant::from_secs(100));
    b.lockstep(0.0);
    let c = counts_for(0.0);
    let good = b.sensor(0, c).unwrap();
    assert!(
        good.estimate_cdeg.iter().all(|e| *e != i16::MIN),
        "{good:?}"
    );
    // Sensor 1 at 15 mm: out of range.
    let bad = b.sensor(1, [1500, c[1], c[2], c[3]]).unwrap();
    assert_eq!(bad.estimate_cdeg, [i16::MIN; 2], "{bad:?}");
    assert_ne!(bad.faults & bit(Faults::SENSOR_RANGE), 0);
    assert!(b.status().estimate_deg.iter().all(|e| e.is_nan()));
    // Good readings again: an estimate, while the fault stays latched.
    let again = b.sensor(2, c).unwrap();
    assert_ne!(again.faults & bit(Faults::SENSOR_RANGE), 0);
    assert_eq!(again.estimate_cdeg, good.estimate_cdeg, "{again:?}");
    // A jump too fast (100 counts in 1 ms): sensor-rate, no estimate.
    let jump = b.sensor(3, [c[0] + 100, c[1], c[2], c[3]]).unwrap();
    assert_ne!(jump.faults & bit(Faults::SENSOR_RATE), 0);
    assert_eq!(jump.estimate_cdeg, [i16::MIN; 2]);

    // Free-running: the telemetry of a stale step says "no estimate".
    let mut b = Board::up_for(Instant::ZERO);
    let mut s = Fixed(c.map(|v| Some(i32::from(v))));
    b.ack(SetTelemetry { rate_hz: 1000 });
    let mut seen_estimate = false;
    for _ in 0..5 {
        for m in b.tick(&mut s) {
            if let Message::Telemetry(t) = m {
                seen_estimate |= t.estimate_deg.iter().all(|e| e.is_finite());
            }
        }
    }
    assert!(seen_estimate);
    s.0 = [None; 4];
    let mut last = None;
    for _ in 0..60 {
        last = b.tick(&mut s).into_iter().last();
    }
    let Some(Message::Telemetry(t)) = last else {
        panic!("{last:?}")
    };
    assert_ne!(t.faults & bit(Faults::SENSOR_STALE), 0);
    assert!(t.estimate_deg.iter().all(|e| e.is_nan()), "{t:?}");
}

#[test]
fn the_rate_limit_includes_its_end_point_at_every_count() {
    // (period µs, counts per period at exactly 200 mm/s). Periods of the
    // rate window (1 ms) or longer: in a faster loop the rate is judged
    // over the window, not per period (§8.1; firmware `sensor` tests).
    for (period_us, step) in [(1000u32, 20i16), (2000, 40), (5000, 100)] {
        let mut b = Board::up_for(Instant::from_secs(7));
        b.ack(HilStart { period_us });
        b.ack(ClearFaults {});
        // Different offsets per sensor, so the ramp visits many f32
        // roundings of counts × 0.01 mm.
        let offsets = [0i16, 3, 7, 11];
        let ramp: Vec<i16> = (-960..=960).step_by(step as usize).collect();
        let mut seq = 0u16;
        for c in ramp.iter().chain(ramp.iter().rev()) {
            let counts = offsets.map(|o| c + o);
            let r = b.sensor(seq, counts).unwrap();
            assert_eq!(
                r.faults & bit(Faults::SENSOR_RATE),
                0,
                "{step} counts per {period_us} µs refused at {counts:?}"
            );
            seq += 1;
        }
        // One count more per period is refused.
        let last = ramp[0];
        let r = b.sensor(seq, offsets.map(|o| last + o + step + 1)).unwrap();
        assert_ne!(r.faults & bit(Faults::SENSOR_RATE), 0, "{step}+1 counts");
    }
}

#[test]
fn the_lockstep_period_is_held_to_the_stale_limit() {
    let mut b = Board::up_for(Instant::from_secs(1));
    assert_eq!(
        nak_code(&mut b, HilStart { period_us: 50_001 }),
        Some(ErrorCode::OutOfRange)
    );
    b.ack(HilStart { period_us: 50_000 });
    b.ack(ClearFaults {});
    for seq in 0..5 {
        let r = b.sensor(seq, counts_for(0.0)).unwrap();
        assert_eq!(r.faults, 0, "step {seq} at 50 ms: {r:?}");
    }
    // A period longer than the link timeout is a link loss at every step.
    b.ack(SetLinkTimeout { timeout_ms: 10 });
    b.ack(HilStart { period_us: 20_000 });
    let r = b.sensor(0, counts_for(0.0)).unwrap();
    assert_ne!(r.faults & bit(Faults::LINK_LOSS), 0, "{r:?}");
}
