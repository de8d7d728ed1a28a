//! Rheology-lattice benchmarks (seed 000, Noborio): lattice steps per
//! second on the paper's sparse 6×4×6 and dense 11×7×11 lattices, over the
//! paper's whole push (0–1 s push, hold to 3 s, release, 5 s at 5 ms:
//! 1000 implicit steps with the paper's defaults), and the explicit Euler's
//! cost per step (no solve; run at a step it is stable at, 10 ns, since at
//! the paper's 2 ms it diverges). Criterion reports elements/s = steps/s.
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use plant_rheology::scenario::{lattice_sim, run, Scenario};
use plant_rheology::sim::Integrator;
use std::hint::black_box;
use std::time::Duration;

fn scenario(grid: [usize; 3]) -> Scenario {
    let mut sc = Scenario::default();
    sc.block.grid = grid;
    sc
}

fn implicit_push(c: &mut Criterion) {
    let mut g = c.benchmark_group("rheology_push_implicit_5ms");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    for grid in [[6, 4, 6], [11, 7, 11]] {
        let sc = scenario(grid);
        let lattice = sc.lattice().unwrap();
        let params = sc.model.params.resolve().unwrap();
        let steps = (sc.plate.end_s / (sc.model.dt_ms * 1e-3)).round() as u64;
        g.throughput(Throughput::Elements(steps));
        g.bench_function(format!("{}x{}x{}", grid[0], grid[1], grid[2]), |b| {
            b.iter(|| {
                let mut sim = lattice_sim(&sc, &lattice, &params).unwrap();
                let r = run(&mut sim, sc.plate.end_s, &sc.measure.frame_times_s);
                assert!(r.instability.is_none());
                black_box(r.plate_force_n.len())
            })
        });
    }
    g.finish();
}

fn explicit_steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("rheology_steps_explicit");
    g.sample_size(20);
    const STEPS: u64 = 200;
    g.throughput(Throughput::Elements(STEPS));
    for grid in [[6, 4, 6], [11, 7, 11]] {
        let mut sc = scenario(grid);
        sc.model.integrator = Integrator::ExplicitEuler;
        sc.model.dt_ms = 1e-5;
        let lattice = sc.lattice().unwrap();
        let params = sc.model.params.resolve().unwrap();
        g.bench_function(format!("{}x{}x{}", grid[0], grid[1], grid[2]), |b| {
            b.iter(|| {
                let mut sim = lattice_sim(&sc, &lattice, &params).unwrap();
                for _ in 0..STEPS {
                    sim.step().unwrap();
                }
                black_box(sim.positions()[0])
            })
        });
    }
    g.finish();
}

criterion_group!(benches, implicit_push, explicit_steps);
criterion_main!(benches);
