//! Benchmarks of the portable core on the host: one 3D control step (the
//! paper's joint, Eq. 3 estimation, two antagonistic pairs, supervisor), the
//! same with threshold switching, and the DGFM viscoelastic update of a
//! 193-vertex object (the seed's triceratops size) with 3 active vertices.
//! Inputs are deterministic; figures go in docs/benchmarks.md.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use firmware::estimate::{LinearLaw, PlaneLaw, QuadraticLaw};
use firmware::joint::{Feedback, Joint3d, JointConfig, StepInput};
use firmware::linalg::{Mat3, Vec3};
use firmware::real::Real;
use firmware::time::{Duration, Instant};
use firmware::viscoelastic::{DgfmBuffers, RayleighColumns, RayleighParams, TimeStep};

fn control_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("control_step_3d");
    for (name, switching) in [("eq3_differential", false), ("eq4_switching", true)] {
        let mut cfg = JointConfig::paper_3d();
        if switching {
            cfg.laws[0] = PlaneLaw::Switching {
                plus: 2,
                minus: 0,
                high: LinearLaw::PAPER_ALPHA,
                sensor: 2,
                low: QuadraticLaw {
                    a: 0.02,
                    b: 5.4,
                    c: 0.3,
                },
                threshold_deg: -7.46,
                hysteresis_deg: 0.5,
            };
        }
        let mut joint = Joint3d::new(cfg).unwrap();
        joint.arm();
        joint.set_target(0, 5.0).unwrap();
        joint.set_target(1, 5.0).unwrap();
        let mut k: i32 = 0;
        group.bench_function(name, |b| {
            b.iter(|| {
                k = k.wrapping_add(1);
                let d = (k % 400 - 200).abs() - 100;
                let input = StepInput {
                    now: Instant::from_millis(k as u32 as u64),
                    dt: Duration::from_millis(1),
                    feedback: Feedback::WireCounts([Some(-d), Some(d / 2), Some(d), Some(-d / 2)]),
                };
                black_box(joint.step(black_box(&input)))
            })
        });
    }
    group.finish();
}

const V: usize = 193;

/// A synthetic 193-vertex DGFM, column-major.
fn dgfm<T: Real>() -> Vec<Mat3<T>> {
    (0..V * V)
        .map(|k| {
            let (i, j) = (k % V, k / V);
            let d = (i as f64 - j as f64).abs();
            let s = 1e-3 / (1.0 + d);
            Mat3::diagonal(T::lit(s), T::lit(1.2 * s), T::lit(0.8 * s))
        })
        .collect()
}

fn bench_dgfm<T: Real, const A: usize>(c: &mut Criterion, name: &str, active: usize) {
    let xi = dgfm::<T>();
    let params = [RayleighParams::new(T::lit(2.0), T::lit(0.05)).unwrap(); V];
    let mut buffers = Box::new(DgfmBuffers::<T, V, A>::default());
    let mut model = buffers
        .dgfm(RayleighColumns::new(&xi, &params).unwrap())
        .unwrap();
    for k in 0..active {
        model
            .set_traction((k * 61) % V, Vec3::new(T::one(), T::zero(), T::lit(0.5)))
            .unwrap();
    }
    let h = TimeStep::new(T::lit(1e-3)).unwrap();
    let mut u = vec![Vec3::zero(); V];
    c.bench_function(name, |b| b.iter(|| model.step(black_box(h), &mut u)));
}

fn dgfm_update(c: &mut Criterion) {
    bench_dgfm::<f32, 3>(c, "dgfm_193v_3active_f32", 3);
    bench_dgfm::<f64, 3>(c, "dgfm_193v_3active_f64", 3);
}

criterion_group!(benches, control_step, dgfm_update);
criterion_main!(benches);
