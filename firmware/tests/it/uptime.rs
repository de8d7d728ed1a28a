//! The control core keeps its checks at any uptime.
//!
//! A controller of heating coils runs for months. Time reaches the core as
//! an integer microsecond `Instant`, so a stale sensor, an implausible jump
//! and a dead link are caught after a year exactly as after a second. Each
//! test runs the same script starting at boot, one second before a `u32`
//! millisecond counter wraps, and after 5 hours, 30 days and a year, and
//! requires every output of every step to be identical.
use firmware::control::{PairCommand, PairGains};
use firmware::estimate::{LinearLaw, Method, PlaneLaw, QuadraticLaw};
use firmware::joint::{Feedback, Joint3d, JointConfig, StepInput, StepOutput};
use firmware::supervisor::{Faults, SupervisorConfig};
use firmware::time::{Duration, Instant};
use proptest::prelude::*;

const MS: Duration = Duration::from_millis(1);

/// Boot, 1 s before the u32 ms wrap, 5 h, 30 days, 1 year.
const UPTIMES: [Instant; 5] = [
    Instant::ZERO,
    Instant::from_millis(u32::MAX as u64 - 1000),
    Instant::from_secs(5 * 3600),
    Instant::from_secs(30 * 86_400),
    Instant::from_secs(365 * 86_400),
];

/// The 3D joint with everything time touches switched on: threshold
/// switching on α (estimator state), P+I on both pairs (integrators), the
/// thermal budget, and a 50 ms link watchdog.
fn joint() -> Joint3d {
    let mut cfg = JointConfig::paper_3d();
    cfg.laws[0] = PlaneLaw::Switching {
        plus: 2,
        minus: 0,
        high: LinearLaw::PAPER_ALPHA,
        sensor: 2,
        low: QuadraticLaw {
            a: 0.05,
            b: 5.0,
            c: 0.3,
        },
        threshold_deg: 1.0,
        hysteresis_deg: 0.5,
    };
    cfg.gains = [PairGains::new(2.0, 2.0, 3.0, 1.0).unwrap(); 2];
    cfg.supervisor = SupervisorConfig {
        link_timeout: Some(Duration::from_millis(50)),
        ..Default::default()
    };
    let mut j = Joint3d::new(cfg).unwrap();
    // Targets inside the sweep, so the integrators work unsaturated.
    j.set_target(0, 0.5).unwrap();
    j.set_target(1, -0.5).unwrap();
    j.arm();
    j
}

/// Counts of a slow α sweep across the switching threshold, β still.
fn sweep(k: u64) -> [Option<i32>; 4] {
    let phase = (k % 400) as i32 - 200; // ±200 counts = ±2 mm
    let d = phase.abs() / 4 - 25;
    [Some(-d), Some(10), Some(d), Some(-10)]
}

/// What happened at each step of the script.
#[derive(Debug, PartialEq)]
struct Run {
    outputs: Vec<StepOutput<2>>,
    integrals: Vec<[u32; 2]>,
    stale_at: Option<u64>,
    rate_at: Option<u64>,
    link_lost_at: Option<u64>,
}

/// The script, from `t0` (step k at `t0 + k ms`):
/// - 0–299 ms: healthy sweep (switching, integrating, driving);
/// - 300–499 ms: sensor 2 silent → stale 50 ms after its last reading;
/// - 520 ms: cause gone, faults cleared;
/// - 700 ms: one reading of sensor 3 jumps 5 mm in 1 ms → implausible rate;
/// - 750 ms: cleared;
/// - host frames stop after 900 ms → link loss 50 ms later.
fn script(t0: Instant) -> Run {
    let mut j = joint();
    let mut run = Run {
        outputs: Vec::new(),
        integrals: Vec::new(),
        stale_at: None,
        rate_at: None,
        link_lost_at: None,
    };
    for k in 0..1000u64 {
        let now = t0 + MS.saturating_mul(k);
        if k <= 900 {
            j.note_link_frame(now);
        }
        if k == 520 || k == 750 {
            j.clear_faults().expect("cause gone");
        }
        let mut counts = sweep(k);
        if (300..500).contains(&k) {
            counts[1] = None;
        }
        if k == 700 {
            counts[2] = counts[2].map(|c| c + 500);
        }
        let out = j.step(&StepInput {
            now,
            dt: MS,
            feedback: Feedback::WireCounts(counts),
        });
        let first = |slot: &mut Option<u64>, f: Faults| {
            if out.faults.contains(f) && slot.is_none() {
                *slot = Some(k);
            }
        };
        first(&mut run.stale_at, Faults::SENSOR_STALE);
        first(&mut run.rate_at, Faults::SENSOR_RATE);
        first(&mut run.link_lost_at, Faults::LINK_LOSS);
        if out.faults.intersects(Faults::LATCHING) {
            assert_eq!(
                out.commands,
                [PairCommand::Off; 2],
                "driven under a fault at {k} ms"
            );
        }
        run.integrals
            .push([0, 1].map(|p| j.integral_v(p).unwrap().to_bits()));
        run.outputs.push(out);
    }
    run
}

#[test]
fn stale_sensor_implausible_jump_and_dead_link_are_caught_at_any_uptime() {
    let reference = script(Instant::ZERO);
    // What the script provokes, at boot: stale 50 ms after sensor 2's last
    // reading at 299 ms, the jump at once, the link 50 ms after 900 ms.
    assert_eq!(reference.stale_at, Some(350));
    assert_eq!(reference.rate_at, Some(700));
    assert_eq!(reference.link_lost_at, Some(951));
    // The run exercised what it claims to: both estimation methods, the
    // integrators, driven outputs.
    let methods: Vec<_> = reference
        .outputs
        .iter()
        .filter_map(|o| o.methods[0])
        .collect();
    assert!(methods.contains(&Method::Single) && methods.contains(&Method::Differential));
    assert!(reference.integrals.iter().any(|i| i[0] != 0));
    assert!(reference.outputs[..300]
        .iter()
        .any(|o| o.commands != [PairCommand::Off; 2]));
    for t0 in &UPTIMES[1..] {
        let run = script(*t0);
        assert_eq!(run.stale_at, reference.stale_at, "stale sensor from {t0}");
        assert_eq!(run.rate_at, reference.rate_at, "implausible jump from {t0}");
        assert_eq!(
            run.link_lost_at, reference.link_lost_at,
            "dead link from {t0}"
        );
        for (k, (a, b)) in run.outputs.iter().zip(&reference.outputs).enumerate() {
            assert_eq!(a.commands, b.commands, "commands at {k} ms from {t0}");
            assert_eq!(a.faults, b.faults, "faults at {k} ms from {t0}");
            assert_eq!(a.methods, b.methods, "methods at {k} ms from {t0}");
            assert_eq!(
                a.estimate_deg.map(f32::to_bits),
                b.estimate_deg.map(f32::to_bits),
                "estimates at {k} ms from {t0}"
            );
        }
        assert_eq!(run.integrals, reference.integrals, "integrators from {t0}");
    }
}

/// One step of an arbitrary run: sensor counts (some missing), the gap to
/// the previous step in ms, whether a host frame arrived, and whether the
/// host asked to clear faults.
type ArbitraryStep = ([Option<i32>; 4], u64, bool, bool);

fn run_from(t0: Instant, steps: &[ArbitraryStep]) -> Vec<(StepOutput<2>, [u32; 2])> {
    let mut j = joint();
    let mut now = t0;
    let mut out = Vec::with_capacity(steps.len());
    for (counts, gap_ms, link, clear) in steps {
        let dt = MS.saturating_mul(*gap_ms);
        now += dt;
        if *link {
            j.note_link_frame(now);
        }
        if *clear {
            let _ = j.clear_faults();
        }
        let o = j.step(&StepInput {
            now,
            dt,
            feedback: Feedback::WireCounts(*counts),
        });
        out.push((o, [0, 1].map(|p| j.integral_v(p).unwrap().to_bits())));
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    /// Shifting the start time changes no output: commands, estimates (to
    /// the bit), methods, faults and integrator states are identical for
    /// any start up to 2⁶² µs (146,000 years).
    #[test]
    fn shifting_the_start_time_changes_no_output(
        shift_us in 0u64..(1 << 62),
        steps in prop::collection::vec(
            (prop::array::uniform4(prop::option::weighted(0.95, -400i32..400)),
             1u64..80, prop::bool::weighted(0.9), prop::bool::weighted(0.05)),
            1..300),
    ) {
        let base = run_from(Instant::ZERO, &steps);
        let shifted = run_from(Instant::from_micros(shift_us), &steps);
        for (k, ((a, ia), (b, ib))) in base.iter().zip(&shifted).enumerate() {
            prop_assert_eq!(a.commands, b.commands, "commands at step {}", k);
            prop_assert_eq!(a.faults, b.faults, "faults at step {}", k);
            prop_assert_eq!(a.methods, b.methods, "methods at step {}", k);
            prop_assert_eq!(a.estimate_deg.map(f32::to_bits), b.estimate_deg.map(f32::to_bits));
            prop_assert_eq!(ia, ib, "integrators at step {}", k);
        }
    }
}
