//! Fault injection through hal-sim, closed loop with the 3D joint: what the
//! firmware core does when a sensor dies, drops samples, jams or sticks, or
//! when a coil opens or its PWM channel fails.
use firmware::control::PairCommand;
use firmware::joint::{Joint3d as Controller, JointConfig};
use firmware::supervisor::Faults;
use firmware::time::Duration;
use hal_sim::{
    ClosedLoop, CoilFault, Controller as _, CoreController, FeedbackSource, Plant, SensorFault,
};
use plant_joint::{Joint3d, Joint3dParams};

type Loop = ClosedLoop<Joint3d, CoreController<2, 4>, 2, 4, 4>;

fn closed_loop(target_deg: f32) -> Loop {
    let plant = Joint3d::new(Joint3dParams::default()).unwrap();
    let mut ctl = Controller::new(JointConfig::paper_3d()).unwrap();
    ctl.set_target(0, target_deg).unwrap();
    ctl.set_target(1, target_deg).unwrap();
    let core = CoreController::new(ctl, FeedbackSource::Wire, 1000, plant.mm_per_count(), 7);
    ClosedLoop::new(plant, core, 1000).unwrap()
}

/// Runs `ms` control periods; returns the samples.
fn run(cl: &mut Loop, ms: usize) -> Vec<hal_sim::Sample<2, 4, 4>> {
    (0..ms).map(|_| cl.tick().unwrap()).collect()
}

#[test]
fn a_dead_sensor_latches_the_safe_state_within_the_stale_limit() {
    let mut cl = closed_loop(8.0);
    let before = run(&mut cl, 3000);
    assert!(
        before.last().unwrap().coil_volts.iter().any(|v| *v > 0.0),
        "driving before the fault"
    );
    cl.controller.sensors()[2].set_fault(Some(SensorFault::Dead));
    let after = run(&mut cl, 200);
    let first_off = after
        .iter()
        .position(|s| s.coil_volts.iter().all(|v| *v == 0.0))
        .expect("outputs never went off");
    // Stale after 50 ms (default wire limits), one period to act.
    assert!(
        (49..=51).contains(&first_off),
        "outputs off after {first_off} ms"
    );
    assert!(Faults::from_bits(after[first_off].faults).contains(Faults::SENSOR_STALE));
    assert!(
        after[first_off..]
            .iter()
            .all(|s| s.coil_volts.iter().all(|v| *v == 0.0)),
        "latched off"
    );
}

#[test]
fn dropped_samples_are_held_and_control_carries_on() {
    let mut cl = closed_loop(8.0);
    for s in cl.controller.sensors() {
        s.set_fault(Some(SensorFault::Dropout { probability: 0.3 }));
    }
    let samples = run(&mut cl, 12_000);
    assert!(
        samples.iter().all(|s| s.faults == 0),
        "30 % dropouts are not a fault (held values, never 50 ms stale)"
    );
    let last = samples.last().unwrap();
    for p in 0..2 {
        assert!(
            (last.true_deg[p] - 8.0).abs() < 1.5,
            "plane {p} at {:.2}° with dropouts",
            last.true_deg[p]
        );
    }
}

#[test]
fn a_jammed_sensor_misleads_the_estimate_by_its_jam() {
    // Sensor 3 under-reads by 0.5 mm: Eq. 3 (gain 2.727 deg/mm) reads α
    // 1.36° low, so the controller drives α about that much past its target.
    let mut clean = closed_loop(5.0);
    let mut jammed = closed_loop(5.0);
    jammed.controller.sensors()[2].set_fault(Some(SensorFault::Jammed { extra_mm: 0.5 }));
    let a = run(&mut clean, 10_000);
    let b = run(&mut jammed, 10_000);
    let (ta, tb) = (a.last().unwrap().true_deg[0], b.last().unwrap().true_deg[0]);
    let shift = tb - ta;
    assert!(
        (shift - 2.727 * 0.5).abs() < 0.5,
        "jam shifted α by {shift:.2}°, expected ≈ 1.36°"
    );
    // Nothing flags it: a consistent offset is plausible — which is why the
    // paper cross-checks methods (threshold switching).
    assert!(b.iter().all(|s| s.faults == 0));
}

#[test]
fn a_stuck_sensor_freezes_the_estimate() {
    let mut cl = closed_loop(0.0);
    run(&mut cl, 2000);
    cl.controller.sensors()[2].set_fault(Some(SensorFault::Stuck));
    cl.controller.sensors()[0].set_fault(Some(SensorFault::Stuck));
    cl.controller.set_target(0, 8.0).unwrap();
    let s = run(&mut cl, 6000);
    // The α estimate cannot follow; the agonist saturates while the true
    // angle climbs past the target: nothing in the signals reveals it.
    let est: Vec<f64> = s.iter().map(|x| x.estimate_deg[0]).collect();
    assert!(
        est.iter().all(|e| (e - est[0]).abs() < 1e-9),
        "estimate moved with frozen sensors"
    );
    assert!(
        s.last().unwrap().true_deg[0] > 8.0,
        "true α {:.2}°",
        s.last().unwrap().true_deg[0]
    );
}

#[test]
fn an_open_coil_cannot_pull_and_a_failing_channel_is_a_driver_fault() {
    let mut cl = closed_loop(8.0);
    cl.controller.pwm()[0][0].set_fault(Some(CoilFault::Open)); // coil 1 (α agonist) open
    let s = run(&mut cl, 8000);
    let last = s.last().unwrap();
    assert!(
        last.true_deg[0] < 1.0,
        "α rose to {:.2}° with its agonist open",
        last.true_deg[0]
    );
    assert!(
        (last.true_deg[1] - 8.0).abs() < 1.5,
        "β unaffected: {:.2}°",
        last.true_deg[1]
    );

    let mut cl = closed_loop(8.0);
    run(&mut cl, 500);
    cl.controller.pwm()[1][0].set_fault(Some(CoilFault::ChannelError));
    let s = run(&mut cl, 5);
    let bad = s
        .iter()
        .position(|x| Faults::from_bits(x.faults).contains(Faults::DRIVER))
        .expect("driver fault reported");
    assert_eq!(bad, 0, "reported in the period the channel failed");
    // Every other coil is switched off at once; the failed channel keeps
    // whatever it last held (it takes no writes: only the hardware can
    // stop it), which is why the fault latches and is reported.
    for x in &s {
        for (c, v) in x.coil_volts.iter().enumerate() {
            assert!(
                c == 1 || *v == 0.0,
                "coil {} at {v} V after the failure",
                c + 1
            );
        }
    }
    let now = cl.controller.next_instant();
    assert_eq!(
        cl.controller
            .joint_mut()
            .step(&firmware::joint::StepInput {
                now,
                dt: Duration::from_millis(1),
                feedback: firmware::joint::Feedback::WireCounts([Some(0); 4]),
            })
            .commands,
        [PairCommand::Off; 2],
        "latched: every output off"
    );
}
