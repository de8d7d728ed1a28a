//! Closed loop under wire length feedback (seed 000, last paper, §V–VI):
//! the 2D joint with one sensor and Eq. 2 (Fig. 16), the 3D joint with four
//! sensors (Fig. 21), and the estimation methods of §VI-D (Fig. 22, Eq. 4–5)
//! calibrated the way a user calibrates a prototype: a camera-referenced
//! sweep, `calibrate::fit`, a calibration file — then checked on an
//! independent run.
//!
//! Conventions (plant README): 3D wire 3 (4) is pushed into its tube when α
//! (β) rises and pulled out when it falls; a pushed wire jams (reads less
//! insertion than the geometry gives), a pulled one sheds its lag.

use crate::common;

use common::{err_stats, estimate_err_stats, peak_to_peak, run, scratch_dir, wire_2d};
use firmware::control::PairGains;
use firmware::estimate::{PlaneEstimator, PlaneLaw};
use firmware::joint::{JointConfig, JointController};
use hal_sim::{ClosedLoop, Controller, CoreController, FeedbackSource, Plant};
use host_tools::files::calibration::CalibrationFile;
use host_tools::files::scenario::{EstimatorMethod, EstimatorSpec, Scenario};
use host_tools::joint::calibrate;
use plant_joint::{Joint3d, Joint3dParams};

/// Paper §V-C, Fig. 16: 2D joint, one wire sensor read with Eq. 2 as
/// published, antagonistic P law (Kp = 2.0), θd ∈ {0, ±5, ±15}°, each from
/// rest; "each link converged".
///
/// Converged here means: the controller's estimate holds θd within 0.2°
/// (three 0.055° coder quanta), and the true angle has stopped (< 0.3° peak
/// to peak over the last 4 s) within 2.5° of θd — Eq. 2 itself is only good
/// to ≈ 2.1° on the simulated joint (plant README), so the true angle cannot
/// be held closer than the law's own error.
///
/// Measured (seed 5, 8–12 s): true angle 0.00, 5.58, 16.59, −3.58, −13.29°
/// for θd = 0, 5, 15, −5, −15° (estimate within 0.1° of θd in every case).
/// The paper saw accurate convergence for negative θd and sensor–camera
/// differences for positive θd (its pushing side); in the simulation the
/// pushing side is θ < 0 (Eq. 2 as printed makes d fall as θ rises) and the
/// differences appear on both sides, dominated by Eq. 2's fit to the
/// simulated geometry (0.6–1.6° pulling, 1.4–1.7° pushing).
#[test]
fn wire_feedback_2d_converges_for_each_target_of_fig16() {
    for target in [0.0, 5.0, -5.0, 15.0, -15.0] {
        let t = run(&wire_2d(target, 12.0, 5)).trace;
        let est = estimate_err_stats(&t, 0, 8.0, 12.0);
        let tru = err_stats(&t, 0, 8.0, 12.0);
        let ptp = peak_to_peak(&t, 0, 8.0, 12.0);
        println!(
            "θd = {target:+5.1}°: estimate error {:+.3}°, true error {:+.3}°, {ptp:.3}° p-p",
            est.mean, tru.mean
        );
        assert!(
            est.max_abs < 0.2,
            "θd = {target}°: estimate not held at θd: {est:?}"
        );
        assert!(
            ptp < 0.3,
            "θd = {target}°: still moving, {ptp:.3}° peak to peak over 8–12 s"
        );
        assert!(
            tru.max_abs < 2.5,
            "θd = {target}°: true angle off by {tru:?}"
        );
    }
}

/// Paper §VI-C, Fig. 21: 3D joint, (αd, βd) = (0, 0), (5, 5), (10, 10),
/// independent P laws per plane; "we were able to control two projecting
/// angles", with sensor errors growing at the larger angles.
///
/// Run twice: with Eq. 3 and its published constants (as in Fig. 21), and
/// with the `softjoint sim` default (threshold switching fitted to a
/// simulated sweep). Converged: true angles within 1.0° of the target over
/// the last 20 % of each 10 s segment (the paper's own sensor accuracy,
/// §VI-D), the estimates within 0.3°, no fault.
///
/// Measured (seed 7): Eq. 3 — worst steady-state error 0.11° (α), 0.10° (β);
/// switching — 0.43° (α), 0.42° (β).
#[test]
fn wire_feedback_3d_converges_to_the_targets_of_fig21() {
    for method in [EstimatorMethod::Paper, EstimatorMethod::Switching] {
        let s = Scenario {
            seed: 7,
            estimator: EstimatorSpec {
                method,
                calibration: None,
            },
            ..Scenario::default()
        };
        let out = run(&s);
        println!(
            "{method:?}: steady-state error {:?}°, estimation error up to {:?}°",
            out.summary.steady_state_error_deg, out.summary.max_estimation_error_deg
        );
        assert!(
            out.summary.faults_seen.is_empty(),
            "{method:?}: faults {:?}",
            out.summary.faults_seen
        );
        assert_eq!(out.summary.segments.len(), 3);
        for g in &out.summary.segments {
            for p in 0..2 {
                assert!(
                    g.steady_state_error_deg[p] < 1.0,
                    "{method:?}: target {:?}, plane {p}: steady-state error {:.3}°",
                    g.desired_deg,
                    g.steady_state_error_deg[p]
                );
                let tail = g.to_s - 0.2 * (g.to_s - g.from_s);
                let est = estimate_err_stats(&out.trace, p, tail, g.to_s);
                assert!(
                    est.mean.abs() < 0.3,
                    "{method:?}: target {:?}, plane {p}: estimate {est:?}",
                    g.desired_deg
                );
            }
        }
    }
}

/// Sweep rate and amplitude of `run::sweep::calibration_sweep` (1°/s, ±20°).
const SWEEP_AMPLITUDE_DEG: f64 = 20.0;
const SWEEP_S: f64 = 80.0;

/// The sweep's triangle, 0 → +A → −A → 0 (`sign` = −1: 0 → −A → +A → 0).
fn triangle(t: f64, sign: f64) -> f64 {
    let q = SWEEP_AMPLITUDE_DEG;
    let v = if t < q {
        t
    } else if t < 3.0 * q {
        q - (t - q)
    } else {
        -q + (t - 3.0 * q)
    };
    sign * v
}

/// One step of an evaluation run: true angles, the coder readings and the
/// jam-free insertions the geometry gives (mm).
struct EvalStep {
    t_s: f64,
    true_deg: [f64; 2],
    measured_mm: [f32; 4],
    ideal_mm: [f32; 4],
}

/// An independent camera-referenced sweep of the 3D joint (same procedure
/// as the calibration sweep: the firmware's P law on camera feedback
/// follows the triangle at 1°/s), recording every 1 ms step.
fn evaluation_run(seed: u64, sign: f64) -> Vec<EvalStep> {
    let mut params = Joint3dParams::default();
    params.sim.seed = seed;
    let plant = Joint3d::new(params).expect("3D plant");
    let mut cfg = JointConfig::paper_3d();
    cfg.gains = [PairGains::default(); 2];
    let ctl = JointController::new(cfg).expect("controller");
    let core = CoreController::new(
        ctl,
        FeedbackSource::Camera,
        1000,
        plant.mm_per_count(),
        seed,
    );
    let mut cl = ClosedLoop::new(plant, core, 1000).expect("closed loop");
    let steps = (SWEEP_S * 1000.0) as u64;
    let mut out = Vec::with_capacity(steps as usize);
    for k in 0..steps {
        let t_s = k as f64 * 1e-3;
        let d = triangle(t_s, sign) as f32;
        cl.controller.set_target(0, d).expect("target");
        cl.controller.set_target(1, d).expect("target");
        cl.tick().expect("period");
        let wires = cl.plant.wires();
        out.push(EvalStep {
            t_s,
            true_deg: cl.plant.true_angles_deg(),
            measured_mm: cl.plant.wire_insertions_mm().map(|v| v as f32),
            ideal_mm: core::array::from_fn(|i| wires[i].ideal_insertion_mm() as f32),
        });
    }
    out
}

/// Largest |estimate − true| per plane along a run, the estimator running
/// step by step as the firmware runs it (switching state included).
fn max_errors(laws: &[PlaneLaw], run: &[EvalStep]) -> [f64; 2] {
    let mut est: Vec<PlaneEstimator<4>> = laws
        .iter()
        .map(|l| PlaneEstimator::new(*l).expect("valid law"))
        .collect();
    let mut worst = [0.0f64; 2];
    for s in run {
        for (p, e) in est.iter_mut().enumerate() {
            let err = (f64::from(e.estimate(&s.measured_mm).angle_deg) - s.true_deg[p]).abs();
            worst[p] = worst[p].max(err);
        }
    }
    worst
}

/// Laws fitted by the calibration code, as a user gets them.
struct Calibrated {
    /// What the calibration file holds: the method `calibrate wire` chose
    /// per plane (smallest worst-case error on the sweep).
    chosen: Vec<PlaneLaw>,
    /// The single-sensor quadratic of the same fit (d3 for α, d4 for β).
    single: Vec<PlaneLaw>,
    /// The differential linear law of the same fit (Eq. 3's form, refitted;
    /// the high branch of Eq. 4 and the whole of Eq. 5).
    differential: Vec<PlaneLaw>,
}

/// The calibration a user would make: the simulated camera-referenced sweep
/// (seed `seed`) written as CSV, read back, fitted, written as a
/// calibration file and loaded — the path of `softjoint sim
/// --calibration-sweep` + `softjoint calibrate wire` + a scenario's
/// `estimator.calibration`.
fn calibrate_from_simulated_sweep(seed: u64, dir: &std::path::Path) -> Calibrated {
    let s = Scenario {
        seed,
        ..Scenario::default()
    };
    let rows =
        host_tools::run::sweep::calibration_sweep(&host_tools::run::joint::JointSpec::of(&s))
            .expect("sweep");
    let csv = dir.join(format!("sweep_{seed}.csv"));
    host_tools::files::sweep::write_sweep(&csv, &rows).expect("write sweep");
    let rows = host_tools::files::sweep::read_sweep(&csv).expect("read sweep");
    let fits = calibrate::fit(&rows).expect("fit");
    print!("calibration seed {seed}:\n{}", calibrate::table(&fits));
    let path = dir.join(format!("calibration_{seed}.toml"));
    calibrate::calibration_of(&fits)
        .expect("calibration")
        .save(&path)
        .expect("save");
    let laws = |m| {
        calibrate::calibration_with(&fits, m)
            .expect("fit has the method")
            .laws()
            .expect("laws")
    };
    Calibrated {
        chosen: CalibrationFile::load(&path)
            .expect("load")
            .laws()
            .expect("laws"),
        single: laws(calibrate::Method::Single),
        differential: laws(calibrate::Method::Differential),
    }
}

const CALIBRATION_SEED: u64 = 11;
/// Independent evaluation runs: same procedure, other seeds (camera noise
/// and wire stick-slip events differ; the mechanics is deterministic).
const EVALUATION_SEEDS: [u64; 3] = [12, 22, 32];

/// Paper §VI-D, Fig. 22: "when we applied only one length sensor, the
/// measurement errors were large due to wire sensor jamming while pushing
/// into the sensor tube"; the laws using both wires of a pair stay below
/// 1.0°.
///
/// Calibrated on a simulated sweep (seed 11), evaluated along independent
/// sweeps of the same ±20° range (seeds 12, 22, 32). Measured:
/// - single-sensor quadratic: 15.2° (every seed) / 14.2–15.0° (α / β).
///   Mostly not jamming: once both coils of a pair have been hot the
///   sponge has sunk (up to 3.5 mm on these sweeps), moving both wires of
///   the pair alike (plant README, "left out"); the differential law
///   cancels that;
/// - the jamming share of the single-sensor estimate, isolated by applying
///   the same law to the measured and to the jam-free (geometric)
///   insertions: mean 0.34–0.38° while the wire is pushed in (rising
///   angle), 0.009–0.025° while it is pulled out; up to 0.78–1.14°;
/// - the differential law of the same fit: 0.75–0.87° (α), 0.75–0.86° (β).
///
/// The paper's claim with threshold switching is the next test.
#[test]
fn single_sensor_jams_on_the_pushing_side_and_two_wire_laws_stay_below_1_deg() {
    let dir = scratch_dir("jamming");
    let cal = calibrate_from_simulated_sweep(CALIBRATION_SEED, &dir);
    for seed in EVALUATION_SEEDS {
        let eval = evaluation_run(seed, 1.0);
        let e_single = max_errors(&cal.single, &eval);
        let e_diff = max_errors(&cal.differential, &eval);
        let e_chosen = max_errors(&cal.chosen, &eval);
        println!("seed {seed}: single {e_single:.3?}°, differential {e_diff:.3?}°, chosen {e_chosen:.3?}°");
        for (p, name) in ["α", "β"].iter().enumerate() {
            assert!(
                e_single[p] > 1.0,
                "seed {seed}, {name}: single sensor only off by {:.3}°",
                e_single[p]
            );
            assert!(
                e_diff[p] < 1.0,
                "seed {seed}, {name}: differential law off by {:.3}° (paper: < 1.0°)",
                e_diff[p]
            );
        }

        // The jam's share of the single-sensor estimate, by direction of
        // travel: a rising angle (0–20 s, 60–80 s) pushes wire 3 (α) / 4 (β)
        // in, a falling one pulls it out.
        let mut pushing = [(0.0f64, 0usize, 0.0f64); 2];
        let mut pulling = [(0.0f64, 0usize); 2];
        let mut on_meas: Vec<PlaneEstimator<4>> = cal
            .single
            .iter()
            .map(|l| PlaneEstimator::new(*l).expect("law"))
            .collect();
        let mut on_ideal = on_meas.clone();
        for s in &eval {
            let rising = !(20.0..60.0).contains(&s.t_s);
            for p in 0..2 {
                let jam = f64::from(
                    on_meas[p].estimate(&s.measured_mm).angle_deg
                        - on_ideal[p].estimate(&s.ideal_mm).angle_deg,
                )
                .abs();
                if rising {
                    pushing[p] = (pushing[p].0 + jam, pushing[p].1 + 1, pushing[p].2.max(jam));
                } else {
                    pulling[p] = (pulling[p].0 + jam, pulling[p].1 + 1);
                }
            }
        }
        for (p, name) in ["α", "β"].iter().enumerate() {
            let push = pushing[p].0 / pushing[p].1 as f64;
            let pull = pulling[p].0 / pulling[p].1 as f64;
            println!(
                "seed {seed}, {name}: jam share of the single estimate: pushing mean {push:.3}° (max {:.3}°), pulling mean {pull:.3}°",
                pushing[p].2
            );
            assert!(
                push > 0.3 && push > 5.0 * pull,
                "seed {seed}, {name}: jamming error pushing {push:.3}° vs pulling {pull:.3}°"
            );
            // How large the jam's share gets depends on the fitted
            // quadratic's slope (up to 1.14° on seed 22 with the current
            // calibration); the single method's total error, asserted above,
            // is what exceeds 1.0°.
        }
    }
}

/// Paper §VI-D, Eq. 4–5: "for each projecting plane, the measurement angle
/// errors were less than 1.0 deg" with threshold switching, coefficients
/// "obtained by angle calibrations".
///
/// The law `calibrate wire` chooses (threshold search with the firmware's
/// switching estimator in the loop; switching only if it beats the simpler
/// laws' worst case by ≥ 5 %) on sweeps of three calibration seeds,
/// evaluated on independent runs of three other seeds, worst error α / β:
/// 0.75–0.87° / 0.71–0.86° (all nine pairs below 1.0°). On this plant the
/// search finds no threshold that pays: the single-wire branch carries the
/// sponge's history-dependent sink (see plant-models/joint/README.md),
/// so the chosen law is the differential one over the whole range — Eq. 4
/// with its threshold below the range, i.e. Eq. 5's form in both planes.
/// (Before the calibration sweep was held by the wire law instead of
/// camera P control, which overheated the coils, and before the switching
/// selector was the differential estimate, the chosen laws reached
/// 0.70–2.11° here.)
#[test]
fn threshold_switching_below_1_deg_on_independent_runs() {
    let dir = scratch_dir("switching_seeds");
    let mut failures = Vec::new();
    for cal_seed in [11, 21, 31] {
        let cal = calibrate_from_simulated_sweep(cal_seed, &dir);
        for seed in EVALUATION_SEEDS {
            let e = max_errors(&cal.chosen, &evaluation_run(seed, 1.0));
            println!("calibration {cal_seed}, evaluation {seed}: chosen {e:.3?}°");
            if e.iter().any(|x| *x >= 1.0) {
                failures.push((cal_seed, seed, e));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "estimation error ≥ 1.0° (paper: < 1.0°): {failures:.3?}"
    );
}

/// The claim "over the ±20° range" on a sweep taken the other way round
/// (0 → −20 → +20 → 0, seed 12), i.e. reaching α < α_th with both coils
/// still cold instead of after the +20° excursion as in the calibration.
///
/// Measured: α 0.73°, β 0.59° (paper < 1.0°). With the earlier calibration
/// (a switching law whose single-wire branch was fitted on readings taken
/// with the sponge sunk) this read α 11.67°: from cold the same angle reads
/// ≈ 3 mm differently on that wire. The calibration now only keeps a
/// single-wire branch when it clearly pays, and on this plant it does not.
#[test]
fn threshold_switching_holds_on_a_sweep_in_the_other_direction() {
    let dir = scratch_dir("switching_reverse");
    let cal = calibrate_from_simulated_sweep(CALIBRATION_SEED, &dir);
    let e = max_errors(&cal.chosen, &evaluation_run(12, -1.0));
    println!("reverse sweep: {e:.3?}°");
    assert!(
        e[0] < 1.0 && e[1] < 1.0,
        "reverse sweep estimation error {e:.3?}° (paper: < 1.0°)"
    );
}
