//! Scaffolding shared by the integration tests: scenario builders,
//! measurements on a run's trace, and scratch directories that delete
//! themselves. Each test binary uses a subset.
#![allow(dead_code)]

use host_tools::files::scenario::{
    ControlMode, ControllerSpec, Disturbance, EstimatorMethod, EstimatorSpec, FeedbackKind,
    JointKind, PlantSpec, Scenario, TargetStep,
};
use host_tools::run::record::{Row, Trace};
use host_tools::run::sim::{self, RunOutput};
use host_tools::run::spec::RunSpec;

/// The paper's visual-feedback experiment (§III-B, Eq. 1): 2D joint, camera
/// feedback, one actuator (coil 2 unpowered, a bias spring), gain `kp`,
/// constant target `target_deg`.
pub fn camera_p(kp: f64, target_deg: f64, duration_s: f64, seed: u64) -> Scenario {
    Scenario {
        name: format!("camera P, Kp = {kp}, θd = {target_deg}°"),
        joint: JointKind::TwoD,
        duration_s,
        control_period_us: 1000,
        seed,
        feedback: FeedbackKind::Camera,
        controller: ControllerSpec {
            mode: ControlMode::Single,
            kp_v_per_deg: vec![kp],
            ki_v_per_deg_s: 0.0,
            integral_limit_v: 1.0,
            v_offset_v: 1.7,
            gains_file: None,
        },
        estimator: EstimatorSpec {
            method: EstimatorMethod::Paper,
            calibration: None,
        },
        targets: vec![TargetStep {
            t_s: 0.0,
            deg: vec![target_deg],
        }],
        disturbances: vec![],
        plant: PlantSpec::default(),
    }
}

/// The paper's 2D length-feedback experiment (§V, Fig. 16): 2D joint, one
/// wire sensor read with Eq. 2 as published, antagonistic pair, Kp = 2.0.
pub fn wire_2d(target_deg: f64, duration_s: f64, seed: u64) -> Scenario {
    Scenario {
        name: format!("2D wire, θd = {target_deg}°"),
        joint: JointKind::TwoD,
        duration_s,
        control_period_us: 1000,
        seed,
        feedback: FeedbackKind::Wire,
        controller: ControllerSpec {
            mode: ControlMode::Antagonistic,
            ..ControllerSpec::default()
        },
        estimator: EstimatorSpec {
            method: EstimatorMethod::Paper,
            calibration: None,
        },
        targets: vec![TargetStep {
            t_s: 0.0,
            deg: vec![target_deg],
        }],
        disturbances: vec![],
        plant: PlantSpec::default(),
    }
}

/// Coil `coil` (paper numbering) forced to `volts` from `from_s` to `to_s`.
pub fn coil_disturbance(coil: usize, volts: f64, from_s: f64, to_s: f64) -> Disturbance {
    Disturbance::CoilVoltage {
        coil,
        volts,
        from_s,
        to_s,
    }
}

/// Runs a scenario; a run that errors is a test failure with the reason.
pub fn run(s: &Scenario) -> RunOutput {
    RunSpec::resolve(s)
        .and_then(|spec| sim::run(&spec))
        .unwrap_or_else(|e| panic!("scenario `{}` failed: {e:#}", s.name))
}

/// Statistics of `true − desired` for one angle over `[from_s, to_s)`.
#[derive(Clone, Copy, Debug)]
pub struct ErrStats {
    /// Time mean of the error (deg): the steady offset.
    pub mean: f64,
    /// Smallest error (deg).
    pub min: f64,
    /// Largest error (deg).
    pub max: f64,
    /// Largest |error| (deg).
    pub max_abs: f64,
}

/// Statistics of `angle(row) − desired` over `[from_s, to_s)`.
fn stats_of(
    trace: &Trace,
    plane: usize,
    from_s: f64,
    to_s: f64,
    angle: impl Fn(&Row) -> f64,
) -> ErrStats {
    let errs: Vec<f64> = trace
        .rows
        .iter()
        .filter(|r| r.t_s >= from_s && r.t_s < to_s)
        .map(|r| angle(r) - r.desired_deg[plane])
        .collect();
    assert!(!errs.is_empty(), "no samples in [{from_s}, {to_s})");
    let mean = errs.iter().sum::<f64>() / errs.len() as f64;
    let min = errs.iter().copied().fold(f64::INFINITY, f64::min);
    let max = errs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    ErrStats {
        mean,
        min,
        max,
        max_abs: min.abs().max(max.abs()),
    }
}

/// Error statistics of the true angle `plane` against its desired angle.
pub fn err_stats(trace: &Trace, plane: usize, from_s: f64, to_s: f64) -> ErrStats {
    stats_of(trace, plane, from_s, to_s, |r| r.true_deg[plane])
}

/// Same as [`err_stats`] for the controller's estimate (what it regulates).
pub fn estimate_err_stats(trace: &Trace, plane: usize, from_s: f64, to_s: f64) -> ErrStats {
    stats_of(trace, plane, from_s, to_s, |r| r.estimate_deg[plane])
}

/// Peak-to-peak of the true angle `plane` over `[from_s, to_s)` (deg).
pub fn peak_to_peak(trace: &Trace, plane: usize, from_s: f64, to_s: f64) -> f64 {
    let s = err_stats(trace, plane, from_s, to_s);
    s.max - s.min
}

/// Number of direction reversals of the true angle `plane` over
/// `[from_s, to_s)`, counting a reversal only once the angle has come back
/// by more than `hysteresis_deg` from its last extreme (so quantisation and
/// noise do not count; a full oscillation period is two reversals).
pub fn reversals(
    trace: &Trace,
    plane: usize,
    hysteresis_deg: f64,
    from_s: f64,
    to_s: f64,
) -> usize {
    let mut n = 0;
    let mut dir = 0i8;
    let mut extreme: Option<f64> = None;
    for r in trace
        .rows
        .iter()
        .filter(|r| r.t_s >= from_s && r.t_s < to_s)
    {
        let x = r.true_deg[plane];
        let Some(ext) = extreme.as_mut() else {
            extreme = Some(x);
            continue;
        };
        match dir {
            1 => *ext = ext.max(x),
            -1 => *ext = ext.min(x),
            _ => {}
        }
        if dir != -1 && x < *ext - hysteresis_deg {
            n += usize::from(dir == 1);
            dir = -1;
            *ext = x;
        } else if dir != 1 && x > *ext + hysteresis_deg {
            n += usize::from(dir == -1);
            dir = 1;
            *ext = x;
        }
    }
    n
}

/// A scratch directory, deleted with everything in it when dropped; it
/// dereferences to its path.
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        self.0.path()
    }
}

/// A fresh scratch directory for one test (`test` names it).
pub fn scratch_dir(test: &str) -> Scratch {
    Scratch(
        tempfile::Builder::new()
            .prefix(&format!("closed_loop_{test}_"))
            .tempdir()
            .expect("scratch dir"),
    )
}
