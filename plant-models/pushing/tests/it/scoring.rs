//! Checks of the scoring, ground truth, force regression and evolutionary
//! search of the pushing module against closed forms and known answers.
use plant_pushing::classify::{classify, MaterialModel};
use plant_pushing::evaluate::{score_with_measured_forces, EvalSetup, PreparedVideo};
use plant_pushing::evolution::{calibrate, new_candidate, EvolutionSettings, TABLE_III_RANGES};
use plant_pushing::force_regression::{
    fit_line, segment_family, Family, ForcePredictor, DEFAULT_ERROR_THRESHOLD,
};
use plant_pushing::forces::MaterialParams;
use plant_pushing::mesh::Mesh;
use plant_pushing::raster::{
    f_score, fill_triangle, rasterise_mesh, rasterise_polygon, running_mean, RasterGrid,
};
use plant_pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial, Video};
use plant_pushing::scenario::{PushScenario, PushSite};
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};
use plant_pushing::{PushError, V2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::OnceLock;

fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<V2> {
    vec![
        V2::new(x0, y0),
        V2::new(x1, y0),
        V2::new(x1, y1),
        V2::new(x0, y1),
    ]
}

#[test]
fn f_score_of_two_rectangles_matches_eq_18() {
    let grid = RasterGrid::covering(V2::new(0.0, 0.0), V2::new(100.0, 50.0), 1.0).unwrap();
    let (mut a, mut b) = (grid.empty(), grid.empty());
    rasterise_polygon(&grid, &mut a, &rect(10.0, 10.0, 50.0, 30.0));
    rasterise_polygon(&grid, &mut b, &rect(20.0, 15.0, 60.0, 35.0));
    assert_eq!((a.count(), b.count()), (800, 800));
    let s = f_score(&a, &b);
    assert_eq!(
        (s.true_positive, s.false_positive, s.false_negative),
        (450, 350, 350)
    );
    // F = 1/(1 + (FN + FP)/(2 TP)) = 2·450/1600
    assert!((s.f_score - 0.5625).abs() < 1e-12);
    let precision = 450.0 / 800.0;
    let recall = 450.0 / 800.0;
    assert!((s.f_score - 2.0 / (1.0 / precision + 1.0 / recall)).abs() < 1e-12);
    assert_eq!(f_score(&a, &a).f_score, 1.0);
    assert_eq!(f_score(&a, &grid.empty()).f_score, 0.0);
}

#[test]
fn mesh_raster_equals_its_outline_and_triangle_areas() {
    let grid = RasterGrid::covering(V2::new(0.0, 0.0), V2::new(100.0, 60.0), 0.5).unwrap();
    let mesh = Mesh::grid(V2::new(10.3, 5.2), 70.4, 35.7, 7, 4).unwrap();
    let (mut m, mut p) = (grid.empty(), grid.empty());
    rasterise_mesh(&grid, &mut m, &mesh, &mesh.rest_positions_px);
    rasterise_polygon(&grid, &mut p, &mesh.contour_px(&mesh.rest_positions_px));
    assert_eq!(m, p, "the union of the triangles is the block outline");
    let cells = m.count() as f64 * 0.25;
    assert!(
        (cells - 70.4 * 35.7).abs() < 2.0 * (70.4 + 35.7) * 0.5,
        "{cells}"
    );
    let mut t = grid.empty();
    let (a, b, c) = (V2::new(3.1, 2.2), V2::new(91.7, 13.9), V2::new(40.3, 57.6));
    fill_triangle(&grid, &mut t, a, b, c);
    let area = 0.5 * ((b - a).x * (c - a).y - (b - a).y * (c - a).x).abs();
    let perimeter = (b - a).norm() + (c - b).norm() + (a - c).norm();
    assert!(
        (t.count() as f64 * 0.25 - area).abs() < perimeter * 0.5,
        "{} vs {area}",
        t.count() as f64 * 0.25
    );
    // Either orientation fills the same cells.
    let mut t2 = grid.empty();
    fill_triangle(&grid, &mut t2, a, c, b);
    assert_eq!(t, t2);
}

#[test]
fn running_mean_is_eq_19_mean_so_far() {
    assert_eq!(
        running_mean(&[1.0, 0.0, 0.5, 0.5]),
        vec![1.0, 0.5, 0.5, 0.5]
    );
    assert!(running_mean(&[]).is_empty());
}

#[test]
fn raster_grid_refuses_bad_cells() {
    assert!(matches!(
        RasterGrid::covering(V2::zeros(), V2::new(10.0, 10.0), f64::NAN),
        Err(PushError::InvalidParameter {
            name: "cell_px",
            ..
        })
    ));
    assert!(matches!(
        RasterGrid::covering(V2::zeros(), V2::new(10.0, 10.0), 0.0),
        Err(PushError::InvalidParameter {
            name: "cell_px",
            ..
        })
    ));
    assert!(RasterGrid::covering(V2::zeros(), V2::new(-1.0, 10.0), 1.0).is_err());
}

/// Small, quick ground truth shared by the tests of this file.
fn videos() -> &'static (Video, Video) {
    static V: OnceLock<(Video, Video)> = OnceLock::new();
    V.get_or_init(|| {
        let cfg = ReferenceConfig {
            element_size_px: 16.0,
            ..Default::default()
        };
        let s = PushScenario::seed(
            PushSite::MiddleLongSide,
            ReferenceMaterial::SPONGE.scale_px_per_m,
        )
        .unwrap();
        let p = PushScenario::seed(
            PushSite::MiddleLongSide,
            ReferenceMaterial::PLASTICINE.scale_px_per_m,
        )
        .unwrap();
        (
            record_push("sponge", ReferenceMaterial::SPONGE, &s, &cfg).unwrap(),
            record_push("plasticine", ReferenceMaterial::PLASTICINE, &p, &cfg).unwrap(),
        )
    })
}

/// Depth of the dent under the finger, px: block top minus the lowest
/// contour point within 15 px of the finger's axis.
fn dent_px(v: &Video, frame: usize) -> f64 {
    let sc = &v.scenario;
    v.contours_px[frame]
        .iter()
        .filter(|p| (p.x - sc.finger_x_px).abs() < 15.0 && p.y > 0.5 * sc.block_height_px)
        .map(|p| sc.block_height_px - p.y)
        .fold(f64::NEG_INFINITY, f64::max)
}

fn polygon_area(c: &[V2]) -> f64 {
    let n = c.len();
    0.5 * (0..n)
        .map(|i| c[i].x * c[(i + 1) % n].y - c[(i + 1) % n].x * c[i].y)
        .sum::<f64>()
}

#[test]
fn ground_truth_sponge_recovers_and_plasticine_keeps_its_dent() {
    let (sponge, clay) = videos();
    for v in [sponge, clay] {
        assert_eq!(v.contours_px.len(), 100);
        v.validate().unwrap();
        let depth = v.scenario.push_depth_px;
        // At the deepest frame the dent follows the finger (within 10 %).
        assert!(
            (dent_px(v, 50) - depth).abs() < 0.1 * depth,
            "{}: dent {} vs depth {depth}",
            v.material,
            dent_px(v, 50)
        );
        // The sensor feels the push: peak force at the deepest point.
        let peak = v.forces_n.iter().copied().fold(0.0, f64::max);
        assert!(peak > 1.0, "{} peak {peak} N", v.material);
        assert!(v.forces_n[5] < 0.2 * peak && v.forces_n[45] > 0.5 * peak);
    }
    assert!(
        dent_px(sponge, 99) < 0.1 * sponge.scenario.push_depth_px,
        "sponge recovers: {}",
        dent_px(sponge, 99)
    );
    assert!(
        dent_px(clay, 99) > 0.6 * clay.scenario.push_depth_px,
        "plasticine keeps a dent: {}",
        dent_px(clay, 99)
    );
    // Plastic flow is isochoric: the clay's area is kept within 3 % (the
    // contour noise alone moves it by well under 1 %).
    let (a0, a1) = (
        polygon_area(&clay.contours_px[0]),
        polygon_area(&clay.contours_px[99]),
    );
    assert!((a1 / a0 - 1.0).abs() < 0.03, "{a0} → {a1}");
    // The plasticine's force falls to zero as soon as the finger retreats.
    assert!(clay.forces_n[60..].iter().all(|f| f.abs() < 0.5));
}

/// The sponge ground truth is viscoelastic (standard linear solid, τ = 1 s):
/// at the same finger depth the sensor reads less on the way out than on
/// the way in, clearly more so than the same block without the relaxing
/// arm (whose only loss is the mass-proportional damping), and the dent
/// recovers with a delay.
#[test]
fn sponge_ground_truth_has_viscoelastic_hysteresis() {
    let cfg = ReferenceConfig {
        element_size_px: 16.0,
        contour_noise_px: 0.0,
        force_noise_n: 0.0,
        ..Default::default()
    };
    let m = ReferenceMaterial::SPONGE;
    assert!(m.relaxing_modulus_pa > 0.0);
    let sc = PushScenario::seed(PushSite::MiddleLongSide, m.scale_px_per_m).unwrap();
    let visco = record_push("sponge", m, &sc, &cfg).unwrap();
    let elastic = record_push(
        "sponge",
        ReferenceMaterial {
            relaxing_modulus_pa: 0.0,
            ..m
        },
        &sc,
        &cfg,
    )
    .unwrap();
    // Frames 25 and 75 have the finger at the same depth (linear in, out).
    let ratio = |v: &Video| v.forces_n[75] / v.forces_n[25];
    let (rv, re) = (ratio(&visco), ratio(&elastic));
    println!("force out/in at equal depth: viscoelastic {rv:.3}, elastic {re:.3}; at 45 {:.3} vs {:.3}; dent at 99 {:.1} vs {:.1} px", visco.forces_n[45], elastic.forces_n[45], dent_px(&visco, 99), dent_px(&elastic, 99));
    assert!(rv < 0.75 && re > 0.8 && rv < re - 0.1, "{rv} vs {re}");
    // On the way in the arm stiffens the block: more force at frame 45.
    assert!(visco.forces_n[45] > 1.05 * elastic.forces_n[45]);
    // The dent recovers with a delay: after the finger has left (frame
    // 99), the viscoelastic block is still dented, the elastic one not.
    assert!(dent_px(&visco, 99) > dent_px(&elastic, 99) + 1.0);
}

#[test]
fn ground_truth_is_bit_identical_and_refuses_bad_materials() {
    let cfg = ReferenceConfig {
        element_size_px: 30.0,
        ..Default::default()
    };
    let sc = PushScenario::seed(PushSite::NearCorner, 4600.0).unwrap();
    let a = record_push("s", ReferenceMaterial::SPONGE, &sc, &cfg).unwrap();
    let b = record_push("s", ReferenceMaterial::SPONGE, &sc, &cfg).unwrap();
    assert_eq!(a, b);
    let c = record_push(
        "s",
        ReferenceMaterial::SPONGE,
        &sc,
        &ReferenceConfig { seed: 2, ..cfg },
    )
    .unwrap();
    assert_ne!(a.forces_n, c.forces_n, "the seed drives the noise");
    let mut bad = ReferenceMaterial::SPONGE;
    bad.poisson_ratio = 0.5;
    assert!(matches!(
        record_push("s", bad, &sc, &cfg),
        Err(PushError::OutOfRange {
            name: "poisson_ratio",
            ..
        })
    ));
    bad = ReferenceMaterial::SPONGE;
    bad.youngs_modulus_pa = f64::NAN;
    assert!(matches!(
        record_push("s", bad, &sc, &cfg),
        Err(PushError::InvalidParameter {
            name: "youngs_modulus_pa",
            ..
        })
    ));
    assert!(matches!(
        record_push(
            "s",
            ReferenceMaterial::SPONGE,
            &sc,
            &ReferenceConfig {
                contour_noise_px: -1.0,
                ..cfg
            }
        ),
        Err(PushError::OutOfRange {
            name: "contour_noise_px",
            ..
        })
    ));
    let mut sc_bad = sc;
    sc_bad.push_depth_px = sc.block_height_px;
    assert!(matches!(
        record_push("s", ReferenceMaterial::SPONGE, &sc_bad, &cfg),
        Err(PushError::OutOfRange {
            name: "push_depth_px",
            ..
        })
    ));
}

#[test]
fn malformed_videos_are_refused() {
    let (sponge, _) = videos();
    let mut v = sponge.clone();
    v.contours_px[7][3] = V2::new(f64::NAN, 1.0);
    let e = PreparedVideo::new(v, &EvalSetup::default()).unwrap_err();
    assert!(
        matches!(e, PushError::MalformedInput { ref location, .. } if location == "frame 7"),
        "{e}"
    );
    let mut v = sponge.clone();
    v.forces_n.pop();
    assert!(matches!(
        PreparedVideo::new(v, &EvalSetup::default()),
        Err(PushError::LengthMismatch {
            what: "forces_n",
            got: 99,
            expected: 100
        })
    ));
    let mut v = sponge.clone();
    v.contours_px[0].truncate(2);
    assert!(matches!(
        PreparedVideo::new(v, &EvalSetup::default()),
        Err(PushError::MalformedInput { .. })
    ));
}

#[test]
fn unstable_model_scores_zero_from_the_unstable_frame() {
    let (sponge, _) = videos();
    let prep = PreparedVideo::new(
        sponge.clone(),
        &EvalSetup {
            nx: 10,
            ny: 5,
            cell_px: 4.0,
        },
    )
    .unwrap();
    let stiff = MaterialParams {
        k_length: 1e4,
        k_damping: 0.0,
        k_area: 1e4,
        k_angle: 100.0,
        max_force: 1e5,
        yield_strain: 1.0,
        creep: 1e-5,
        max_alpha: 1e-5,
    };
    let sim = SimConfig {
        integrator: Integrator::Euler,
        mode: DrivingMode::CollisionAndForces,
        ..Default::default()
    };
    let s = score_with_measured_forces(&prep, &stiff, &sim).unwrap();
    let k = s
        .unstable_from_frame
        .expect("stiff explicit Euler blows up once the finger touches");
    assert!(s.instability.is_some());
    assert!(s.f_per_frame[k..].iter().all(|f| *f == 0.0));
    assert!(
        s.f_per_frame[..k].iter().all(|f| *f > 0.5),
        "before it, the block is still there"
    );
    assert!((s.mean_f - s.f_per_frame.iter().sum::<f64>() / 100.0).abs() < 1e-12);
}

#[test]
fn line_fit_is_eq_2_to_4() {
    let x = [1.0, 2.0, 3.0, 4.0];
    let y = [3.0, 5.0, 7.0, 9.5];
    let (m, y0, err) = fit_line(&x, &y).unwrap();
    // Closed form: m = (nΣxy − ΣxΣy)/(nΣx² − (Σx)²) = (4·72 − 10·24.5)/(4·30 − 100)
    assert!((m - (4.0 * 72.0 - 10.0 * 24.5) / 20.0).abs() < 1e-12);
    assert!((y0 - (24.5 / 4.0 - m * 2.5)).abs() < 1e-12);
    let e: f64 = x
        .iter()
        .zip(&y)
        .map(|(a, b)| (b - (m * a + y0)).powi(2))
        .sum();
    assert!((err - e).abs() < 1e-12);
    assert!(
        fit_line(&[2.0, 2.0], &[1.0, 3.0]).is_none(),
        "vertical data has no line"
    );
}

#[test]
fn segmented_regression_finds_the_kink_and_the_right_family() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    // Linear with a kink at x = 30 (slope 0.1 then 0.4), small noise.
    let x: Vec<f64> = (0..60).map(|i| i as f64).collect();
    let y: Vec<f64> = x.iter().map(|&v| if v < 30.0 { 0.1 * v } else { 3.0 + 0.4 * (v - 30.0) } + rng.gen_range(-0.02..0.02)).collect();
    let segs = segment_family(Family::Linear, &x, &y, DEFAULT_ERROR_THRESHOLD);
    assert!(segs.len() >= 2);
    // A growing window notices the kink only once enough points past it
    // have raised the error: never before it, and within a dozen samples.
    assert!(
        segs[0].x_end_px >= 30.0 && segs[0].x_end_px <= 42.0,
        "first break at {}",
        segs[0].x_end_px
    );
    assert!((segs[1].slope - 0.4).abs() < 0.02, "{:?}", segs[1]);
    // A logarithmic law is covered better by the log family.
    let xl: Vec<f64> = (1..60).map(|i| i as f64).collect();
    let yl: Vec<f64> = xl
        .iter()
        .map(|&v| 2.0 * v.ln() + 1.0 + rng.gen_range(-0.02..0.02))
        .collect();
    let lin = segment_family(Family::Linear, &xl, &yl, DEFAULT_ERROR_THRESHOLD);
    let log = segment_family(Family::Logarithmic, &xl, &yl, DEFAULT_ERROR_THRESHOLD);
    let cover =
        |s: &[plant_pushing::force_regression::Segment]| s.iter().map(|x| x.points).max().unwrap();
    assert_eq!(cover(&log), 59, "one log segment covers everything");
    assert!(cover(&lin) < 59);
    assert!((log[0].slope - 2.0).abs() < 0.05 && (log[0].intercept_n - 1.0).abs() < 0.1);
}

#[test]
fn force_predictor_learns_the_push_and_retrieval_of_the_ground_truth() {
    let (sponge, clay) = videos();
    let fs =
        ForcePredictor::fit(&sponge.scenario, &sponge.forces_n, DEFAULT_ERROR_THRESHOLD).unwrap();
    let fc = ForcePredictor::fit(&clay.scenario, &clay.forces_n, DEFAULT_ERROR_THRESHOLD).unwrap();
    // §VIII-C: a linear law characterises the elastic sponge, a logarithmic
    // one the plastic clay.
    assert_eq!(fs.push_family, Family::Linear, "coverage {:?}", fs.coverage);
    assert_eq!(
        fc.push_family,
        Family::Logarithmic,
        "coverage {:?}",
        fc.coverage
    );
    for (fp, v) in [(&fs, sponge), (&fc, clay)] {
        let pred = fp.predict_series(&v.scenario);
        let peak = v.forces_n.iter().copied().fold(0.0, f64::max);
        let rms = (pred
            .iter()
            .zip(&v.forces_n)
            .map(|(a, b)| (a - b).powi(2))
            .sum::<f64>()
            / 100.0)
            .sqrt();
        assert!(
            rms < 0.1 * peak,
            "{}: rms {rms} N vs peak {peak} N",
            v.material
        );
    }
    let mut bad = sponge.forces_n.clone();
    bad[10] = f64::NAN;
    assert!(matches!(
        ForcePredictor::fit(&sponge.scenario, &bad, 0.04),
        Err(PushError::MalformedInput { .. })
    ));
    assert!(matches!(
        ForcePredictor::fit(&sponge.scenario, &bad[..50], 0.04),
        Err(PushError::LengthMismatch { .. })
    ));
    assert!(matches!(
        ForcePredictor::fit(&sponge.scenario, &vec![0.0; 100], 0.04),
        Err(PushError::MalformedInput { .. })
    ));
}

#[test]
fn new_candidates_are_log_uniform_with_five_percent_zeros() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let n = 20_000;
    let mut zeros = [0usize; 8];
    let mut log_pos = [0.0f64; 8];
    for _ in 0..n {
        let c = new_candidate(&mut rng, &TABLE_III_RANGES, 0.05);
        for k in 0..8 {
            let r = TABLE_III_RANGES[k];
            if c[k] == 0.0 {
                assert!(r.allows_zero, "parameter {k} may not be 0");
                zeros[k] += 1;
            } else {
                assert!(c[k] >= r.min && c[k] <= r.max);
                log_pos[k] += (c[k].ln() - r.min.ln()) / (r.max.ln() - r.min.ln());
            }
        }
    }
    for k in 0..8 {
        let nz = n - zeros[k];
        // Mean position in log space of a log-uniform draw is ½ (σ ≈ 0.29/√n).
        assert!((log_pos[k] / nz as f64 - 0.5).abs() < 0.01, "param {k}");
        if TABLE_III_RANGES[k].allows_zero {
            // Binomial(20000, 0.05): σ ≈ 31; 5σ tolerance.
            assert!(
                (zeros[k] as f64 - 1000.0).abs() < 155.0,
                "param {k}: {} zeros",
                zeros[k]
            );
        } else {
            assert_eq!(zeros[k], 0);
        }
    }
}

/// A smooth fitness with a known optimum, in log space.
fn toy_fitness(p: &MaterialParams) -> f64 {
    let target: [f64; 8] = [0.01, 300.0, 50.0, 2.0, 800.0, 0.2, 0.05, 0.3];
    let a = p.to_array();
    let mut d = 0.0;
    for k in 0..8 {
        let r = TABLE_III_RANGES[k];
        let x = if a[k] == 0.0 { r.min } else { a[k] };
        d += ((x.ln() - target[k].ln()) / (r.max.ln() - r.min.ln())).powi(2);
    }
    1.0 / (1.0 + 10.0 * d)
}

#[test]
fn evolutionary_search_improves_and_is_deterministic_across_thread_counts() {
    let st = EvolutionSettings::table_iii(42);
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| calibrate(&st, &TABLE_III_RANGES, toy_fitness, |_| {}).unwrap())
    };
    let (a, b, c) = (run(1), run(2), run(2));
    assert_eq!(a, b);
    assert_eq!(b, c);
    assert_eq!(a.history.len(), 30);
    // Survivors keep their score: the best never gets worse.
    assert!(a.history.windows(2).all(|w| w[1].best >= w[0].best));
    assert!(a.best_score > a.history[0].best);
    // It beats pure random search with the same number of evaluations.
    let mut rng = ChaCha8Rng::seed_from_u64(4242);
    let random_best = (0..a.evaluations)
        .map(|_| {
            toy_fitness(&MaterialParams::from_array(new_candidate(
                &mut rng,
                &TABLE_III_RANGES,
                0.05,
            )))
        })
        .fold(0.0, f64::max);
    assert!(
        a.best_score > random_best,
        "GA {} vs random {random_best}",
        a.best_score
    );
    // σ falls linearly from σ_max to σ_min over M generations.
    assert!((a.history[29].sigma - 10.0).abs() < 1e-9);
    // Survivors are not re-run: N + (M − 1)(N − α) evaluations.
    assert_eq!(a.evaluations, 20 + 29 * 15);
    let mut bad = st;
    bad.generations = 0;
    assert!(matches!(
        calibrate(&bad, &TABLE_III_RANGES, toy_fitness, |_| {}),
        Err(PushError::InvalidParameter {
            name: "generations",
            ..
        })
    ));
    let mut bad = st;
    bad.p_special = 1.5;
    assert!(matches!(
        calibrate(&bad, &TABLE_III_RANGES, toy_fitness, |_| {}),
        Err(PushError::OutOfRange {
            name: "p_special",
            ..
        })
    ));
}

#[test]
fn classification_needs_two_models() {
    let (sponge, _) = videos();
    let prep = PreparedVideo::new(
        sponge.clone(),
        &EvalSetup {
            nx: 3,
            ny: 2,
            cell_px: 8.0,
        },
    )
    .unwrap();
    let one = [MaterialModel {
        label: "a".into(),
        params: MaterialParams::SEED_FIG14_SPONGE,
    }];
    assert!(matches!(
        classify(&prep, &sponge.forces_n, &one, &SimConfig::default()),
        Err(PushError::InvalidParameter { name: "models", .. })
    ));
}

#[test]
fn video_csv_round_trips_and_reports_malformed_lines() {
    use plant_pushing::video_csv::{parse_video_csv, write_video_csv};
    let (sponge, _) = videos();
    let text = write_video_csv(sponge);
    let back = parse_video_csv(&text, "v.csv", &sponge.scenario, "sponge").unwrap();
    assert_eq!(back.contours_px.len(), 100);
    for (a, b) in back
        .contours_px
        .iter()
        .flatten()
        .zip(sponge.contours_px.iter().flatten())
    {
        assert_eq!(
            (a.x.to_bits(), a.y.to_bits()),
            (b.x.to_bits(), b.y.to_bits()),
            "shortest round-trip float printing"
        );
    }
    assert_eq!(back.forces_n, sponge.forces_n);
    let sc = &sponge.scenario;
    let err = |t: &str| {
        parse_video_csv(t, "v.csv", sc, "x")
            .unwrap_err()
            .to_string()
    };
    assert!(err("").contains("empty file"));
    assert!(err("frame,force,x,y\n").starts_with("v.csv:1: expected the header"));
    assert_eq!(
        err("frame,force_n,x_px,y_px\n0,1,2\n"),
        "v.csv:2: 3 fields, but the header has 4"
    );
    assert_eq!(
        err("frame,force_n,x_px,y_px\n0,1,abc,2\n"),
        "v.csv:2: column `x_px`: `abc` is not a number"
    );
    assert!(err("frame,force_n,x_px,y_px\n0,1,NaN,2\n")
        .starts_with("v.csv:2: column `x_px`: `NaN` is not finite"));
    assert!(err("frame,force_n,x_px,y_px\n-1,1,2,2\n").contains("frame `-1`"));
    assert!(err("frame,force_n,x_px,y_px\n1,1,2,2\n").contains("out of order"));
    assert!(err("# c\nframe,force_n,x_px,y_px\n0,1,2,2\n0,1.5,2,3\n")
        .starts_with("v.csv:4: frame 0 has two force readings"));
    // Well-formed but too short for the scenario's 100 frames.
    assert!(err("frame,force_n,x_px,y_px\n0,1,0,0\n0,1,5,0\n0,1,5,5\n")
        .contains("contours_px has 1 entries, expected 100"));
}

#[test]
fn mesh_counts_must_be_positive() {
    let (sponge, _) = videos();
    assert!(matches!(
        PreparedVideo::new(
            sponge.clone(),
            &EvalSetup {
                nx: 0,
                ny: 5,
                cell_px: 4.0
            }
        ),
        Err(PushError::InvalidParameter { name: "nx", .. })
    ));
    assert!(matches!(
        PreparedVideo::new(
            sponge.clone(),
            &EvalSetup {
                nx: 10,
                ny: 0,
                cell_px: 4.0
            }
        ),
        Err(PushError::InvalidParameter { name: "ny", .. })
    ));
}
