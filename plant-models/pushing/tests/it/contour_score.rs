//! The tracked contour of a pushed block as a periodic smoothing spline
//! (seed 000, Fujioka & Kano) and the contour distance within the finger's
//! reach, beside the pixel F-score (issue 17).
//!
//! These are the short forms (16 px ground truth, 10×5 mesh, 4 px cells, a
//! few generations); the full experiment — calibration by F and by contour
//! distance, both scores against the undeformed block, classification of
//! all six pushes by both — is the example
//! `cargo run --release -p plant-pushing --example contour_score`
//! (figures in the pushing README).
use plant_contour::identify::distance::point_polygon_distance;
use plant_pushing::contour_score::{
    score_contour_run, skill, still_block_contour_score, still_config, track_video, ContourTarget,
    ReachZone, TrackingOptions,
};
use plant_pushing::evaluate::{score_run, EvalSetup, PreparedVideo};
use plant_pushing::evolution::{calibrate, EvolutionSettings, TABLE_III_RANGES};
use plant_pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial, Video};
use plant_pushing::scenario::{PushScenario, PushSite};
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};

fn sim() -> SimConfig {
    SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::CollisionAndForces,
        ..SimConfig::default()
    }
}

fn video(
    mat: ReferenceMaterial,
    label: &str,
    site: PushSite,
    element_px: f64,
    noise: bool,
) -> Video {
    let sc = PushScenario::seed(site, mat.scale_px_per_m).unwrap();
    let cfg = ReferenceConfig {
        element_size_px: element_px,
        contour_noise_px: if noise { 1.0 } else { 0.0 },
        ..ReferenceConfig::default()
    };
    record_push(label, mat, &sc, &cfg).unwrap()
}

/// One push prepared both ways (raw tracked points and the spline) with
/// its contour target.
struct Push {
    raw: PreparedVideo,
    spline: PreparedVideo,
    target: ContourTarget,
}

fn prepare(v: Video, setup: &EvalSetup) -> Push {
    let opts = TrackingOptions::default();
    let tracked = track_video(&v, &opts).unwrap();
    let zone = ReachZone::default_of(&v.scenario).unwrap();
    let target = ContourTarget::new(&tracked, zone, 2.0).unwrap();
    Push {
        spline: PreparedVideo::with_truth_contours(v.clone(), setup, &tracked.contours_px).unwrap(),
        raw: PreparedVideo::new(v, setup).unwrap(),
        target,
    }
}

#[test]
fn the_spline_filters_the_tracking_noise() {
    // Against the noise-free boundary of the same ground truth: the spline
    // (one knot per two points, λ by GCV) lies closer than the tracked
    // points themselves, frame after frame.
    let mat = ReferenceMaterial::SPONGE;
    let noisy = video(mat, "sponge", PushSite::MiddleLongSide, 16.0, true);
    let clean = video(mat, "sponge", PushSite::MiddleLongSide, 16.0, false);
    let tracked = track_video(&noisy, &TrackingOptions::default()).unwrap();
    let (mut raw_sum, mut spline_sum) = (0.0, 0.0);
    let frames: Vec<usize> = (0..100).step_by(7).collect();
    for &f in &frames {
        let truth: Vec<(f64, f64)> = clean.contours_px[f].iter().map(|p| (p.x, p.y)).collect();
        let mean = |pts: &[plant_pushing::V2]| {
            pts.iter()
                .map(|p| point_polygon_distance((p.x, p.y), &truth))
                .sum::<f64>()
                / pts.len() as f64
        };
        let (r, s) = (mean(&noisy.contours_px[f]), mean(&tracked.contours_px[f]));
        raw_sum += r;
        spline_sum += s;
        assert!(
            s < r,
            "frame {f}: spline {s:.3} px vs tracked points {r:.3} px"
        );
    }
    let n = frames.len() as f64;
    println!(
        "mean distance to the noise-free contour: tracked points {:.3} px, spline {:.3} px",
        raw_sum / n,
        spline_sum / n
    );
    assert!(spline_sum < 0.85 * raw_sum);
    // Resampled every 1 px: consecutive points about 1 px apart.
    let c = &tracked.contours_px[50];
    let gaps: Vec<f64> = (0..c.len())
        .map(|i| (c[(i + 1) % c.len()] - c[i]).norm())
        .collect();
    let mean_gap = gaps.iter().sum::<f64>() / gaps.len() as f64;
    assert!((mean_gap - 1.0).abs() < 0.05, "spacing {mean_gap}");
}

#[test]
fn contour_distance_sees_the_dent_that_the_f_score_hides() {
    // Short form: 16 px ground truth, 10×5 mesh, 4 px cells, a 3-generation
    // calibration by F on the training push. The undeformed block scores
    // high on F but is far from the tracked contour where the finger
    // pushes; the calibrated model closes most of that gap.
    let setup = EvalSetup {
        nx: 10,
        ny: 5,
        cell_px: 4.0,
    };
    let mat = ReferenceMaterial::SPONGE;
    let push = prepare(
        video(mat, "sponge", PushSite::MiddleLongSide, 16.0, true),
        &setup,
    );
    let cfg = sim();
    let mut st = EvolutionSettings::table_iii(2016);
    st.generations = 3;
    let cal = calibrate(
        &st,
        &TABLE_III_RANGES,
        |p| {
            score_run(&push.raw, &push.raw.video.forces_n, p, &cfg)
                .map(|s| s.mean_f)
                .unwrap_or(f64::NAN)
        },
        |_| {},
    )
    .unwrap();
    let p = cal.best_params;
    let f_model = score_run(&push.raw, &push.raw.video.forces_n, &p, &cfg)
        .unwrap()
        .mean_f;
    let f_still = score_run(&push.raw, &[0.0; 100], &p, &still_config(&cfg))
        .unwrap()
        .mean_f;
    let d_model =
        score_contour_run(&push.raw, &push.target, &push.raw.video.forces_n, &p, &cfg).unwrap();
    let d_still = still_block_contour_score(&push.raw, &push.target);
    let f_skill = (f_model - f_still) / (1.0 - f_still);
    let c_skill = skill(d_model.mean_px, d_still.mean_px);
    println!(
        "F: model {f_model:.4}, still {f_still:.4} (skill {f_skill:.2}); contour distance: model {:.2} px (max {:.2}), still {:.2} px (max {:.2}) (skill {c_skill:.2})",
        d_model.mean_px, d_model.max_px, d_still.mean_px, d_still.max_px
    );
    // The still block's F is within a few hundredths of the model's …
    assert!(f_still > 0.9 && f_model - f_still < 0.05);
    // … while its contour distance where the finger pushes is several px,
    // and the model's a fraction of it.
    assert!(d_still.mean_px > 8.0, "still {}", d_still.mean_px);
    assert!(c_skill > 0.4, "contour skill {c_skill}");
    // At the deepest frame the still block misses the dent by about the
    // finger's travel into the block.
    let deepest = d_still.max_px_per_frame[49];
    assert!(
        deepest > 0.7 * push.raw.video.scenario.push_depth_px,
        "{deepest}"
    );
    // A frame where nothing has touched the block yet: both near 0.
    let still_sp = still_block_contour_score(&push.spline, &push.target);
    println!(
        "frame 0: still {:.2} px, model {:.2} px; mesh from the spline's box: still {:.2} px",
        d_still.mean_px_per_frame[0], d_model.mean_px_per_frame[0], still_sp.mean_px_per_frame[0]
    );
    // (Not 0: the mesh starts from the bounding box of frame 0's tracked
    // points, which noise pushes ≈ 2 px outward; from the spline's box
    // about 1.5 px, its wiggles being smaller.)
    assert!(d_still.mean_px_per_frame[0] < 2.5 && d_model.mean_px_per_frame[0] < 2.5);
    assert!(still_sp.mean_px_per_frame[0] < d_still.mean_px_per_frame[0]);
    // The spline truth changes the F-scores only in the third decimal.
    let f_spline = score_run(&push.spline, &push.spline.video.forces_n, &p, &cfg)
        .unwrap()
        .mean_f;
    println!("μ(F) against the raw contour {f_model:.4}, against the spline {f_spline:.4}");
    assert!((f_spline - f_model).abs() < 0.01);
}
