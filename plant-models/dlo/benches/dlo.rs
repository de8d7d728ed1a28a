//! Deformable-linear-object benchmarks (seed 000): one step of the Table I
//! rope at N = 50 (hanging free, and knotted on the desk with its
//! self-contacts), and the static solves of the wire (twist by π, the
//! 0.6 L → 0.1 L sequence) and of the paper's belt. Inputs come from the
//! shipped scenarios; everything is deterministic.
use criterion::{criterion_group, criterion_main, Criterion};
use plant_dlo::rope::script::RopeScenario;
use plant_dlo::rope::{Desk, Rope, RopeParams, V3};
use plant_dlo::wire::belt::{belt_settings, BeltProblem};
use plant_dlo::wire::linear::end_distance_sequence;
use plant_dlo::wire::optimize::Settings;
use plant_dlo::wire::{Constraint, WireParams, WireProblem};
use std::hint::black_box;
use std::time::Duration;

const OVERHAND: &str = include_str!("../../../scenarios/dlo/overhand.toml");

fn rope_steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("rope_step_n50");
    // Hanging from its top point, no contact.
    let mut hanging =
        Rope::straight(RopeParams::default(), V3::new(0.0, 0.0, 10.0), -V3::z()).unwrap();
    hanging.pin(0).unwrap();
    g.bench_function("hanging", |b| b.iter(|| hanging.step().unwrap()));
    // The overhand scenario at 20 s: knotted and pulled tight on the desk.
    let scenario: RopeScenario = toml::from_str(OVERHAND).unwrap();
    let short = RopeScenario {
        duration_s: 20.0,
        ..scenario.clone()
    };
    let run = short.run(|_| {}).unwrap();
    let last = run.frames.last().unwrap();
    let mut knotted = Rope::from_points(scenario.rope.clone(), last.x.clone()).unwrap();
    knotted.pin(0).unwrap();
    knotted.desk = Some(Desk { height_m: 0.0 });
    let mut contacts = 0;
    for _ in 0..200 {
        knotted.step().unwrap();
        contacts += knotted.stats.contacts;
    }
    assert!(contacts > 200, "the knotted rope should touch itself");
    g.bench_function("knotted_with_contacts", |b| {
        b.iter(|| knotted.step().unwrap())
    });
    g.finish();
}

fn wire_solves(c: &mut Criterion) {
    let mut g = c.benchmark_group("wire_solve");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    let w = WireParams::paper_wire();
    let l = w.length_m;
    let twist = WireProblem {
        constraints: vec![
            Constraint::Orientation {
                s_m: 0.0,
                euler_rad: [0.0; 3],
            },
            Constraint::Position {
                s_a_m: 0.0,
                s_b_m: l,
                l_m: [0.0, 0.0, l],
            },
            Constraint::Orientation {
                s_m: l,
                euler_rad: [0.0, 0.0, std::f64::consts::PI],
            },
        ],
        wire: w.clone(),
        harmonics: 4,
        intervals: 64,
        self_contact: false,
        initial_tilt_rad: 0.0,
    };
    g.bench_function("twist_pi", |b| {
        b.iter(|| black_box(twist.solve(&Settings::default(), None).unwrap()))
    });
    g.bench_function("sequence_0.6L_to_0.1L", |b| {
        b.iter(|| {
            black_box(
                end_distance_sequence(
                    &w,
                    &[0.6, 0.5, 0.4, 0.3, 0.2, 0.1],
                    0.05,
                    96,
                    &Settings::default(),
                )
                .unwrap(),
            )
        })
    });
    g.bench_function("belt_fig10", |b| {
        b.iter(|| black_box(BeltProblem::default().solve(&belt_settings()).unwrap()))
    });
    g.finish();
}

criterion_group!(benches, rope_steps, wire_solves);
criterion_main!(benches);
