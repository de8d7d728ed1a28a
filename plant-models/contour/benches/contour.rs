//! Contour-spline benchmarks (seed 000, Fujioka & Kano): fitting a tracked
//! deforming contour of 100 frames × 110 points — as one contour × time
//! surface and as 100 independent periodic signature curves, with a fixed
//! λ and with λ by GCV — the paper's Eq. 38 surface (N = 40) by the reduced
//! and by the dense KKT solver. Inputs come from the synthetic movie with
//! fixed seeds. (The tracking of a pushed block is in plant-pushing's
//! bench: it needs the pushing ground truth.)
use criterion::{criterion_group, criterion_main, Criterion};
use plant_common::rng;
use plant_contour::fit::Solver;
use plant_contour::identify::gcv::Lambda;
use plant_contour::identify::movie::PulsatingContour;
use plant_contour::identify::paper::{axes, grid_sites, rbc_surface, LAMBDA};
use plant_contour::identify::tracked::{
    fit_movie, fit_signature, ContourOptions, MovieOptions, Signature,
};
use plant_contour::surface::fit_surface;
use std::hint::black_box;
use std::time::Duration;

/// 100 frames × 110 angles of the synthetic movie, 1 px tracking noise.
fn movie_100x110() -> Vec<(f64, Signature)> {
    let movie = PulsatingContour {
        frames: 100,
        ..PulsatingContour::default()
    };
    let mut r = rng::stream(1, rng::CONTOUR_MOVIE_NOISE);
    (0..100)
        .map(|f| (f as f64, movie.observe(f, 110, 1.0, &mut r).unwrap()))
        .collect()
}

fn movie(c: &mut Criterion) {
    let frames = movie_100x110();
    let mut g = c.benchmark_group("contour_100_frames_x_110_points");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    for (name, time_knots, lambda) in [
        ("surface_33x55_fixed_lambda", 33, Lambda::Fixed(1e-4)),
        ("surface_99x55_fixed_lambda", 99, Lambda::Fixed(1e-4)),
        ("surface_33x55_gcv", 33, Lambda::Gcv),
    ] {
        let opts = MovieOptions {
            time_knots,
            angle_knots: 55,
            lambda,
            centre_lambda: lambda,
            solver: Solver::Reduced,
        };
        g.bench_function(name, |b| {
            b.iter(|| fit_movie(black_box(&frames), &opts).unwrap().rms_residual)
        });
    }
    for (name, lambda) in [
        ("curves_55_fixed_lambda", Lambda::Fixed(1e-4)),
        ("curves_55_gcv", Lambda::Gcv),
    ] {
        let opts = ContourOptions {
            knots: 55,
            lambda,
            solver: Solver::Reduced,
        };
        g.bench_function(name, |b| {
            b.iter(|| {
                frames
                    .iter()
                    .map(|(_, s)| fit_signature("f", black_box(s), &opts).unwrap().area())
                    .sum::<f64>()
            })
        });
    }
    g.finish();
}

fn paper_surface(c: &mut Criterion) {
    let (sa, ta) = axes(false).unwrap();
    let sites = grid_sites(40, 40, false);
    let d: Vec<f64> = sites.iter().map(|&(s, t)| rbc_surface(s, t)).collect();
    let mut g = c.benchmark_group("contour_eq38_n40");
    g.sample_size(10);
    for solver in [Solver::Reduced, Solver::Kkt] {
        g.bench_function(solver.name(), |b| {
            b.iter(|| {
                fit_surface(&sa, &ta, black_box(&sites), &d, None, LAMBDA, solver)
                    .unwrap()
                    .0
                    .coef[0]
            })
        });
    }
    g.finish();
}

criterion_group!(benches, movie, paper_surface);
criterion_main!(benches);
