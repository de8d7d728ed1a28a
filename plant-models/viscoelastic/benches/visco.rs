//! Viscoelastic object benchmarks (seed 002 §5–6): the DGFM viscoelastic
//! update of the shipped ~200-vertex object with 3 active columns (one
//! touched triangle) and with every column active, for Rayleigh and tensor
//! damping; the DGFM computation; and fitting 1,258 trials (the seed's
//! Table 2 count) in parallel and serially. Inputs are seeded.
use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use plant_viscoelastic::dgfm::Dgfm;
use plant_viscoelastic::fit::{fit_trials, fit_trials_serial, NelderMeadOptions, Weighting};
use plant_viscoelastic::measure::{simulate_campaign, ProbeProtocol, VertexTruth};
use plant_viscoelastic::{ColumnParams, Mat3, TractionModel, Vec3, ViscoObject};
use std::hint::black_box;

fn loaded_object(d: &Dgfm, params: ColumnParams, columns: &[usize]) -> ViscoObject {
    let mut obj = ViscoObject::new(d.clone(), params, 1e-3).unwrap();
    for &j in columns {
        obj.set_traction(j, Vec3::new(100.0, -50.0, -2.0e3))
            .unwrap();
    }
    obj
}

fn object_update(c: &mut Criterion) {
    let d = Dgfm::default_object().unwrap();
    let n = d.len();
    let h = 1e-3;
    let tri: Vec<usize> = d.mesh().triangles[60]
        .iter()
        .map(|&v| d.index_of(v).unwrap())
        .collect();
    let all: Vec<usize> = (0..n).collect();
    let rayleigh = ColumnParams::uniform_rayleigh(n, 0.29, 0.33).unwrap();
    let tensor = ColumnParams::Tensor {
        ratios: vec![0.29; n],
        damping_n_s_per_m: (0..n)
            .map(|j| d.stiffness(j, j).unwrap() * 0.33 + Mat3::from_diagonal_element(5.0))
            .collect(),
    };
    let mut g = c.benchmark_group("visco_object_update");
    for (name, params, cols) in [
        ("rayleigh_3_active", &rayleigh, &tri),
        ("rayleigh_all_active", &rayleigh, &all),
        ("tensor_3_active", &tensor, &tri),
        ("tensor_all_active", &tensor, &all),
    ] {
        let mut obj = loaded_object(&d, params.clone(), cols);
        let mut u = vec![Vec3::zeros(); n];
        g.bench_function(name, |b| {
            b.iter(|| {
                obj.step(h, &mut u).unwrap();
                black_box(&u);
            })
        });
        assert_eq!(obj.active_count(), cols.len());
    }
    g.finish();
}

fn dgfm_build(c: &mut Criterion) {
    let mut g = c.benchmark_group("visco_dgfm");
    g.sample_size(10);
    g.bench_function("default_object_fem_to_dgfm", |b| {
        b.iter(|| black_box(Dgfm::default_object().unwrap()))
    });
    g.finish();
}

/// 1,258 trials (seed Table 2: 269 + 989 for the triceratops): every
/// traction vertex in turn (ratio and b varied), 5 directions × 2 speeds.
fn trials_1258(d: &Dgfm) -> Vec<plant_viscoelastic::measure::Trial> {
    let truths: Vec<VertexTruth> = (0..126)
        .map(|k| {
            let j = k % d.len();
            VertexTruth::from_dgfm(
                d,
                j,
                0.2 + 0.01 * (k % 20) as f64,
                0.1 + 0.004 * (k % 50) as f64,
            )
            .unwrap()
        })
        .collect();
    let mut t = simulate_campaign(d, &truths, &ProbeProtocol::default(), 2004).unwrap();
    t.truncate(1258);
    assert_eq!(t.len(), 1258);
    t
}

fn fitting(c: &mut Criterion) {
    let d = Dgfm::default_object().unwrap();
    let trials = trials_1258(&d);
    let mut g = c.benchmark_group("visco_fit_1258_trials");
    g.sample_size(10);
    g.bench_function("parallel_rayon", |b| {
        b.iter_batched(
            || (),
            |_| {
                black_box(fit_trials(
                    &trials,
                    Weighting::Seed,
                    NelderMeadOptions::default(),
                ))
            },
            BatchSize::PerIteration,
        )
    });
    g.bench_function("serial", |b| {
        b.iter_batched(
            || (),
            |_| {
                black_box(fit_trials_serial(
                    &trials,
                    Weighting::Seed,
                    NelderMeadOptions::default(),
                ))
            },
            BatchSize::PerIteration,
        )
    });
    g.finish();
}

criterion_group!(benches, object_update, dgfm_build, fitting);
criterion_main!(benches);
