//! The contour-score experiment of the pushing README ("Contour distance
//! beside the F-score", issue 17): both materials, three pushes each, on
//! 8 px ground truth with tracking noise. Each material's model is
//! calibrated on its training push (the middle of the long side) three
//! ways — by μ(F) against the tracked points, by μ(F) against the
//! smoothing spline, by the mean contour distance within the finger's
//! reach — and every push is then scored by both measures beside an
//! undeformed block, and classified by both, with the models calibrated by
//! F and by contour.
//!
//! ```sh
//! cargo run --release -p plant-pushing --example contour_score -- [GENERATIONS]
//! ```
//!
//! `GENERATIONS` of the Table III search, default 30 (the README's
//! figures; 6–18 min on the shared 2-core machine); 2 gives a short run of
//! the same protocol. The short form with assertions (16 px ground truth,
//! a 10×5 mesh) is the test `contour_score::
//! contour_distance_sees_the_dent_that_the_f_score_hides`.
//!
//! Exits 1 when a push is classified as the wrong material: in the full
//! run all six were right by either score, with either set of models.
use std::process::ExitCode;

use plant_pushing::classify::{classify, MaterialModel};
use plant_pushing::contour_score::{
    classify_by_contour, score_contour_run, skill, still_block_contour_score, still_config,
    track_video, ContourTarget, ReachZone, TrackingOptions,
};
use plant_pushing::evaluate::{score_run, EvalSetup, PreparedVideo};
use plant_pushing::evolution::{calibrate, CalibrationResult, EvolutionSettings, TABLE_III_RANGES};
use plant_pushing::forces::MaterialParams;
use plant_pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial};
use plant_pushing::scenario::{PushScenario, PushSite};
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The model's scheme: the seed's customised integrator, driven by the
/// finger's collisions and the sensed forces.
fn sim() -> SimConfig {
    SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::CollisionAndForces,
        ..SimConfig::default()
    }
}

/// One push prepared both ways (raw tracked points and the spline) with
/// its contour target.
struct Push {
    raw: PreparedVideo,
    spline: PreparedVideo,
    target: ContourTarget,
}

/// Records the push at `site` on 8 px ground truth with 1 px contour
/// noise, tracks it and prepares it for scoring.
fn prepare(mat: ReferenceMaterial, label: &str, site: PushSite, setup: &EvalSetup) -> Result<Push> {
    let sc = PushScenario::seed(site, mat.scale_px_per_m)?;
    let cfg = ReferenceConfig {
        element_size_px: 8.0,
        contour_noise_px: 1.0,
        ..ReferenceConfig::default()
    };
    let v = record_push(label, mat, &sc, &cfg)?;
    let tracked = track_video(&v, &TrackingOptions::default())?;
    let zone = ReachZone::default_of(&v.scenario)?;
    let target = ContourTarget::new(&tracked, zone, 2.0)?;
    Ok(Push {
        spline: PreparedVideo::with_truth_contours(v.clone(), setup, &tracked.contours_px)?,
        raw: PreparedVideo::new(v, setup)?,
        target,
    })
}

/// The three calibrations on the training push: by F (raw truth), by F
/// (spline truth), by contour distance.
fn calibrate_three(train: &Push, generations: usize) -> Result<[CalibrationResult; 3]> {
    let cfg = sim();
    let mut st = EvolutionSettings::table_iii(2016);
    st.generations = generations;
    let by_f = |pv: &PreparedVideo| {
        calibrate(
            &st,
            &TABLE_III_RANGES,
            |p| {
                score_run(pv, &pv.video.forces_n, p, &cfg)
                    .map(|s| s.mean_f)
                    .unwrap_or(f64::NAN)
            },
            |_| {},
        )
    };
    let f_raw = by_f(&train.raw)?;
    let f_spline = by_f(&train.spline)?;
    let contour = calibrate(
        &st,
        &TABLE_III_RANGES,
        |p| {
            score_contour_run(
                &train.raw,
                &train.target,
                &train.raw.video.forces_n,
                p,
                &cfg,
            )
            .map(|s| -s.mean_px)
            .unwrap_or(f64::NAN)
        },
        |_| {},
    )?;
    Ok([f_raw, f_spline, contour])
}

/// Prints one push's scores: the undeformed block's, then each model's.
fn print_scores(
    label: &str,
    k: usize,
    push: &Push,
    models: &[(&str, &MaterialParams)],
) -> Result<()> {
    let cfg = sim();
    let site = push.raw.video.scenario.site.name();
    let by_f = models[0].1;
    let f_still = score_run(&push.raw, &[0.0; 100], by_f, &still_config(&cfg))?.mean_f;
    let f_still_sp = score_run(&push.spline, &[0.0; 100], by_f, &still_config(&cfg))?.mean_f;
    let d_still = still_block_contour_score(&push.raw, &push.target);
    println!(
        "{label} {site}{}: still block F {f_still:.4} (spline truth {f_still_sp:.4}), contour {:.2} px (max {:.2})",
        if k == 0 { " (training)" } else { "" },
        d_still.mean_px,
        d_still.max_px
    );
    for &(name, p) in models {
        let f = score_run(&push.raw, &push.raw.video.forces_n, p, &cfg)?.mean_f;
        let f_sp = score_run(&push.spline, &push.spline.video.forces_n, p, &cfg)?.mean_f;
        let d = score_contour_run(&push.raw, &push.target, &push.raw.video.forces_n, p, &cfg)?;
        println!(
            "    model {name}: F {f:.4} (spline truth {f_sp:.4}, skill {:.2}) | contour {:.2} px (max {:.2}, worst {:.1}) skill {:.2}",
            (f - f_still) / (1.0 - f_still),
            d.mean_px,
            d.max_px,
            d.worst_px,
            skill(d.mean_px, d_still.mean_px)
        );
    }
    Ok(())
}

/// Classifies every push by F and by contour against `models`; returns
/// how many of the classifications named the wrong material (or none).
fn classify_all(
    set: &str,
    models: &[MaterialModel],
    pushes: &[(&str, Vec<Push>)],
) -> Result<usize> {
    let cfg = sim();
    let mut wrong = 0;
    println!("classification, models {set}:");
    for (label, ps) in pushes {
        for push in ps {
            let site = push.raw.video.scenario.site.name();
            let by_f = classify(&push.raw, &push.raw.video.forces_n, models, &cfg)?;
            let by_c = classify_by_contour(
                &push.raw,
                &push.target,
                &push.raw.video.forces_n,
                models,
                &cfg,
            )?;
            wrong += usize::from(by_f.winner_label() != Some(*label));
            wrong += usize::from(by_c.winner_label() != Some(*label));
            println!(
                "  {label} {site}: by F → {} (frames {:?}, vote {:.3?}); by contour → {} (frames {:?}, vote {:.1?} px)",
                by_f.verdict(),
                by_f.frames_won,
                by_f.vote,
                by_c.verdict(),
                by_c.tally.frames_won,
                by_c.tally.vote
            );
        }
    }
    Ok(wrong)
}

fn run() -> Result<ExitCode> {
    let generations: usize = match std::env::args().nth(1) {
        Some(g) => g
            .parse()
            .map_err(|_| format!("GENERATIONS must be a whole number, got `{g}`"))?,
        None => 30,
    };
    let setup = EvalSetup::default();
    let mut models_f = Vec::new();
    let mut models_c = Vec::new();
    let mut pushes = Vec::new();
    for (label, mat) in [
        ("sponge", ReferenceMaterial::SPONGE),
        ("plasticine", ReferenceMaterial::PLASTICINE),
    ] {
        let ps = PushSite::ALL
            .iter()
            .map(|&site| prepare(mat, label, site, &setup))
            .collect::<Result<Vec<Push>>>()?;
        let [by_f, by_f_spline, by_c] = calibrate_three(&ps[0], generations)?;
        println!(
            "{label}: calibrated by F (raw truth) {:?}",
            by_f.best_params
        );
        println!(
            "{label}: calibrated by F (spline truth) {:?}",
            by_f_spline.best_params
        );
        println!(
            "{label}: calibrated by contour distance {:?}",
            by_c.best_params
        );
        let models = [
            ("by F", &by_f.best_params),
            ("by F, spline truth", &by_f_spline.best_params),
            ("by contour", &by_c.best_params),
        ];
        for (k, push) in ps.iter().enumerate() {
            print_scores(label, k, push, &models)?;
        }
        models_f.push(MaterialModel {
            label: label.into(),
            params: by_f.best_params,
        });
        models_c.push(MaterialModel {
            label: label.into(),
            params: by_c.best_params,
        });
        pushes.push((label, ps));
    }
    let mut wrong = 0;
    for (set, models) in [
        ("calibrated by F", &models_f),
        ("calibrated by contour", &models_c),
    ] {
        wrong += classify_all(set, models, &pushes)?;
    }
    let total = 2 * 2 * pushes.iter().map(|(_, ps)| ps.len()).sum::<usize>();
    println!(
        "{} of {total} classifications right ({generations} generations)",
        total - wrong
    );
    Ok(if wrong == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn main() -> ExitCode {
    run().unwrap_or_else(|e| {
        eprintln!("contour_score: {e}");
        ExitCode::from(2)
    })
}
