//! Pushing-model benchmarks (seed 001): mass-spring steps of the seed's
//! 20×10 mesh with each integrator during a push, one scored run of a whole
//! push (168 steps + 100 rasterised frames at camera resolution), and a full
//! Table III calibration (M = 30, N = 20) on the sponge's training push,
//! parallel over candidates, and the contour tracking of a whole push. Inputs are generated with fixed seeds.
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use plant_pushing::contour_score::{track_video, TrackingOptions};
use plant_pushing::evaluate::{
    score_with_measured_forces, simulate_frames, EvalSetup, PreparedVideo,
};
use plant_pushing::evolution::{calibrate, EvolutionSettings, TABLE_III_RANGES};
use plant_pushing::forces::MaterialParams;
use plant_pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial};
use plant_pushing::scenario::{PushScenario, PushSite};
use plant_pushing::sim::{Integrator, SimConfig};
use std::hint::black_box;
use std::time::Duration;

fn training_push(setup: &EvalSetup) -> PreparedVideo {
    let mat = ReferenceMaterial::SPONGE;
    let sc = PushScenario::seed(PushSite::MiddleLongSide, mat.scale_px_per_m).unwrap();
    let video = record_push("sponge", mat, &sc, &ReferenceConfig::default()).unwrap();
    PreparedVideo::new(video, setup).unwrap()
}

/// A stable parameter set of the order the calibration finds (estimate).
const PARAMS: MaterialParams = MaterialParams {
    k_length: 2600.0,
    k_damping: 0.77,
    k_area: 0.5,
    k_angle: 40.0,
    max_force: 12.0,
    yield_strain: 3e-5,
    creep: 0.005,
    max_alpha: 1e-4,
};

fn steps(c: &mut Criterion) {
    let prep = training_push(&EvalSetup::default());
    let steps = (prep.video.scenario.frame_time_s(99) / 0.1).round() as u64;
    let mut g = c.benchmark_group("pushing_20x10_push_run");
    g.throughput(Throughput::Elements(steps));
    for integ in Integrator::ALL {
        let sim = SimConfig {
            integrator: integ,
            ..SimConfig::default()
        };
        g.bench_function(integ.name(), |b| {
            b.iter(|| {
                let mut last = 0.0;
                simulate_frames(
                    &prep.mesh,
                    &prep.video.scenario,
                    &prep.video.forces_n,
                    black_box(&PARAMS),
                    &sim,
                    |_, pos, _| last = pos[0].x,
                )
                .unwrap();
                last
            })
        });
    }
    g.finish();
    let mut g = c.benchmark_group("pushing_20x10_scored_run");
    g.bench_function("customised_cell_1px", |b| {
        b.iter(|| {
            score_with_measured_forces(&prep, black_box(&PARAMS), &SimConfig::default())
                .unwrap()
                .mean_f
        })
    });
    g.finish();
}

fn calibration(c: &mut Criterion) {
    let prep = training_push(&EvalSetup::default());
    let sim = SimConfig::default();
    let mut g = c.benchmark_group("pushing_calibration_table_iii");
    g.sample_size(10).measurement_time(Duration::from_secs(60));
    g.bench_function("sponge_20x10_cell_1px", |b| {
        b.iter(|| {
            calibrate(
                &EvolutionSettings::table_iii(7),
                &TABLE_III_RANGES,
                |p| {
                    score_with_measured_forces(&prep, p, &sim)
                        .map(|s| s.mean_f)
                        .unwrap_or(f64::NAN)
                },
                |_| {},
            )
            .unwrap()
            .best_score
        })
    });
    g.finish();
}

/// The contour tracking of a whole push: 100 frames of ~156 points, closed
/// curves, λ by GCV each (reported with the contour benchmarks).
fn pushing_tracking(c: &mut Criterion) {
    let mat = ReferenceMaterial::SPONGE;
    let sc = PushScenario::seed(PushSite::MiddleLongSide, mat.scale_px_per_m).unwrap();
    let video = record_push("sponge", mat, &sc, &ReferenceConfig::default()).unwrap();
    let mut g = c.benchmark_group("contour_pushing_tracking");
    g.sample_size(10).measurement_time(Duration::from_secs(10));
    g.bench_function("sponge_100_frames_gcv", |b| {
        b.iter(|| {
            track_video(black_box(&video), &TrackingOptions::default())
                .unwrap()
                .lambda_per_frame[0]
        })
    });
    g.finish();
}

criterion_group!(benches, steps, calibration, pushing_tracking);
criterion_main!(benches);
