//! Safe state on every fault, at the level of a whole joint step, and
//! property tests (proptest): for any inputs no output is NaN, every output
//! lies in [0, supply], and both coils of a pair are never on together.
use firmware::control::{PairCommand, PairGains};
use firmware::joint::{Feedback, Joint3d, JointConfig, StepInput};
use firmware::supervisor::{Faults, SupervisorConfig};
use firmware::time::{Duration, Instant};
use proptest::prelude::*;

const DT: Duration = Duration::from_millis(1);

/// Board time `k_ms` milliseconds after the epoch.
fn ms(k_ms: u64) -> Instant {
    Instant::from_millis(k_ms)
}

fn armed_3d() -> Joint3d {
    let mut j = Joint3d::new(JointConfig::paper_3d()).unwrap();
    j.arm();
    j
}

/// Counts for α = β = `angle` under the default Eq. 3 law and coder.
fn counts_for(angle_deg: f32) -> [Option<i32>; 4] {
    let da = (angle_deg - 0.323) / 2.727 / 2.0 / 0.01;
    let db = (angle_deg - 0.131) / 2.670 / 2.0 / 0.01;
    [
        Some(-da as i32),
        Some(-db as i32),
        Some(da as i32),
        Some(db as i32),
    ]
}

/// A step at `k_ms` milliseconds with the given counts.
fn input(k_ms: u64, counts: [Option<i32>; 4]) -> StepInput<4, 2> {
    StepInput {
        now: ms(k_ms),
        dt: DT,
        feedback: Feedback::WireCounts(counts),
    }
}

/// Runs a healthy joint, then `fault` from 100 ms on; checks every output is
/// zero with the fault reported, and (for latching faults) that it stays
/// zero after the cause has gone until cleared.
fn check_fault(
    name: &str,
    expect: Faults,
    mut make: impl FnMut(u64) -> StepInput<4, 2>,
    joint: &mut Joint3d,
) {
    joint.set_target(0, 10.0).unwrap();
    joint.set_target(1, -10.0).unwrap();
    let mut faulted_at = None;
    for k in 0..300 {
        let out = joint.step(&make(k));
        if out.faults.contains(expect) {
            faulted_at.get_or_insert(k);
            assert_eq!(
                out.commands,
                [PairCommand::Off; 2],
                "{name}: outputs not zero at {k} ms"
            );
        } else if faulted_at.is_none() && k < 100 {
            assert_ne!(
                out.commands,
                [PairCommand::Off; 2],
                "{name}: healthy joint should drive"
            );
        }
    }
    assert!(faulted_at.is_some(), "{name}: fault never reported");
}

#[test]
fn sensor_out_of_range_latches_the_safe_state() {
    let mut j = armed_3d();
    check_fault(
        "range",
        Faults::SENSOR_RANGE,
        |k| {
            input(
                k,
                if k > 100 && k < 150 {
                    [Some(5000), Some(0), Some(0), Some(0)]
                } else {
                    counts_for(0.0)
                },
            )
        },
        &mut j,
    );
    // The cause went away at 150 ms, but the latch holds until cleared.
    let out = j.step(&input(310, counts_for(0.0)));
    assert_eq!(out.commands, [PairCommand::Off; 2]);
    assert!(out.faults.contains(Faults::SENSOR_RANGE));
    j.clear_faults().unwrap();
    let out = j.step(&input(312, counts_for(0.0)));
    assert_ne!(
        out.commands,
        [PairCommand::Off; 2],
        "cleared joint drives again"
    );
}

#[test]
fn implausible_rate_latches_the_safe_state() {
    let mut j = armed_3d();
    check_fault(
        "rate",
        Faults::SENSOR_RATE,
        |k| {
            input(
                k,
                if k > 100 {
                    counts_for(15.0)
                } else {
                    counts_for(0.0)
                },
            )
        },
        &mut j,
    );
}

#[test]
fn stale_sensor_latches_the_safe_state() {
    let mut j = armed_3d();
    check_fault(
        "stale",
        Faults::SENSOR_STALE,
        |k| {
            let mut c = counts_for(0.0);
            if k > 100 {
                c[2] = None;
            }
            input(k, c)
        },
        &mut j,
    );
}

#[test]
fn time_running_backwards_latches_the_safe_state() {
    let mut j = armed_3d();
    check_fault(
        "time backwards",
        Faults::INVALID_INPUT,
        // From 100 ms on the clock jumps back by a second.
        |k| {
            input(
                if k > 100 {
                    k + 1_000_000 - 1000
                } else {
                    k + 1_000_000
                },
                counts_for(0.0),
            )
        },
        &mut j,
    );
}

#[test]
fn link_loss_latches_the_safe_state() {
    let mut cfg = JointConfig::paper_3d();
    cfg.supervisor = SupervisorConfig {
        link_timeout: Some(Duration::from_millis(50)),
        ..Default::default()
    };
    let mut j = Joint3d::new(cfg).unwrap();
    j.arm();
    // Frames arrive until 100 ms, then stop: link loss after 150 ms.
    let mut lost_at = None;
    for k in 0..300 {
        if k <= 100 {
            j.note_link_frame(ms(k));
        }
        j.set_target(0, 10.0).unwrap();
        let out = j.step(&input(k, counts_for(0.0)));
        if out.faults.contains(Faults::LINK_LOSS) {
            lost_at.get_or_insert(k);
            assert_eq!(out.commands, [PairCommand::Off; 2]);
        }
    }
    assert_eq!(lost_at, Some(151), "link loss 50 ms after the last frame");
}

#[test]
fn external_faults_latch_too() {
    for f in [Faults::DRIVER, Faults::INTERNAL] {
        let mut j = armed_3d();
        j.set_target(0, 10.0).unwrap();
        assert_ne!(
            j.step(&input(0, counts_for(0.0))).commands,
            [PairCommand::Off; 2]
        );
        j.report_fault(f);
        let out = j.step(&input(1, counts_for(0.0)));
        assert_eq!(out.commands, [PairCommand::Off; 2]);
        assert!(out.faults.contains(f));
    }
}

#[test]
fn thermal_budget_cuts_a_saturated_coil_and_reports_it() {
    let mut j = armed_3d();
    j.set_target(0, 20.0).unwrap(); // far away: coil 1 saturates at 5 V
    let mut cut = false;
    for k in 0..10_000 {
        let out = j.step(&input(k, counts_for(0.0)));
        if out.faults.contains(Faults::OVER_BUDGET) {
            assert_eq!(
                out.paper_coil_volts()[0],
                0.0,
                "coil 1 still driven while over budget"
            );
            cut = true;
            break;
        }
    }
    assert!(cut, "5 V for 10 s never exhausted the budget");
}

#[test]
fn disarmed_joint_drives_nothing() {
    let mut j = Joint3d::new(JointConfig::paper_3d()).unwrap();
    j.set_target(0, 10.0).unwrap();
    assert_eq!(
        j.step(&input(0, counts_for(0.0))).commands,
        [PairCommand::Off; 2]
    );
}

#[test]
fn bad_targets_are_refused_not_clamped_silently() {
    let mut j = armed_3d();
    assert!(j.set_target(0, f32::NAN).is_err());
    assert!(j.set_target(0, 90.0).is_err());
    assert!(j.set_target(2, 1.0).is_err());
    assert_eq!(j.targets_deg(), [0.0, 0.0]);
}

fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -100.0f32..100.0,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => any::<f32>(),
    ]
}

fn check_outputs(out: &firmware::joint::StepOutput<2>, supply: f32) -> Result<(), TestCaseError> {
    for [a, b] in out.pair_volts() {
        prop_assert!(!a.is_nan() && !b.is_nan(), "NaN output");
        prop_assert!(
            (0.0..=supply).contains(&a) && (0.0..=supply).contains(&b),
            "{a} {b} outside [0, {supply}]"
        );
        prop_assert!(a == 0.0 || b == 0.0, "both coils of a pair on: {a} {b}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Any finite gains, targets and sensor counts, over a run of steps.
    #[test]
    fn outputs_bounded_for_any_finite_wire_inputs(
        kp in prop::array::uniform4(1e-3f32..100.0),
        ki in 0.0f32..50.0,
        targets in prop::array::uniform2(-25.0f32..25.0),
        steps in prop::collection::vec((prop::array::uniform4(prop::option::weighted(0.9, -2000i32..2000)), 10u64..50_000), 1..60),
    ) {
        let mut cfg = JointConfig::paper_3d();
        cfg.gains = [
            PairGains::new(kp[0], kp[2], ki, 2.0).unwrap(),
            PairGains::new(kp[1], kp[3], ki, 2.0).unwrap(),
        ];
        let mut j = Joint3d::new(cfg).unwrap();
        j.arm();
        j.set_target(0, targets[0]).unwrap();
        j.set_target(1, targets[1]).unwrap();
        let mut t = Instant::ZERO;
        // Sensors that have delivered an in-range reading (±10 mm = ±1000
        // counts) so far.
        let mut delivered = [false; 4];
        for (counts, dt_us) in steps {
            let dt = Duration::from_micros(dt_us);
            t += dt;
            for (d, c) in delivered.iter_mut().zip(counts) {
                *d |= c.is_some_and(|c| c.abs() <= 1000);
            }
            let out = j.step(&StepInput { now: t, dt, feedback: Feedback::WireCounts(counts) });
            check_outputs(&out, 5.0)?;
            if !delivered.iter().all(|d| *d) {
                prop_assert_eq!(out.commands, [PairCommand::Off; 2],
                    "driven before every sensor delivered: {:?}", delivered);
            }
            prop_assert!(out.estimate_deg.iter().all(|e| e.is_finite())
                || !out.faults.is_empty()
                || !delivered.iter().all(|d| *d),
                "non-finite estimate without a fault: {:?}", out.estimate_deg);
        }
    }

    /// Anything at all in camera feedback (NaN and infinities included)
    /// and any instants, earlier ones included: still bounded, and time
    /// running backwards is reported.
    #[test]
    fn outputs_bounded_for_arbitrary_angle_inputs(
        steps in prop::collection::vec((any::<u64>(), any::<u64>(), prop::array::uniform2(prop::option::of(any_f32()))), 1..40),
    ) {
        let mut j = armed_3d();
        j.set_target(0, 5.0).unwrap();
        let mut last = None;
        for (now_us, dt_us, angles) in steps {
            let now = Instant::from_micros(now_us);
            let out = j.step(&StepInput { now, dt: Duration::from_micros(dt_us), feedback: Feedback::Angles(angles) });
            check_outputs(&out, 5.0)?;
            if last.is_some_and(|l| now < l) {
                prop_assert!(out.faults.contains(Faults::INVALID_INPUT));
                prop_assert_eq!(out.commands, [PairCommand::Off; 2]);
            } else {
                last = Some(now);
            }
        }
    }

    /// The pair law alone, for any finite or non-finite angle/target/dt and
    /// any valid gains.
    #[test]
    fn pair_law_bounded(kp in 1e-4f32..1e3, ki in 0.0f32..1e3, lim in 0.0f32..10.0,
                        angle in any_f32(), target in any_f32(), dt in any_f32()) {
        use firmware::control::*;
        let d = DriverConfig::default();
        for mode in [PairMode::Antagonistic, PairMode::SingleAgonist] {
            let mut c = PairController::new(PairGains::new(kp, kp, ki, lim).unwrap(), mode);
            for _ in 0..3 {
                let [a, b] = c.update(&d, angle, target, dt).coil_volts();
                prop_assert!((0.0..=5.0).contains(&a) && (0.0..=5.0).contains(&b) && (a == 0.0 || b == 0.0));
                prop_assert!(c.integral_v().abs() <= lim);
            }
        }
    }

    /// The viscoelastic update stays finite for any valid parameters and
    /// finite loads.
    #[test]
    fn three_element_finite(k1 in 1e-3f64..1e3, k2 in 1e-3f64..1e3, b in 0.0f64..1e3,
                            h in 1e-6f64..1.0, loads in prop::collection::vec(-1e3f64..1e3, 1..50)) {
        use firmware::viscoelastic::*;
        let m = ThreeElement::new(k1, k2, b).unwrap();
        let h = TimeStep::new(h).unwrap();
        let (mut s1, mut s2) = (ThreeElementState::default(), ThreeElementState::default());
        for f in loads {
            prop_assert!(m.step_displacement(&mut s1, f, h).is_finite());
            prop_assert!(m.step_force(&mut s2, f, h).is_finite());
        }
    }
}
