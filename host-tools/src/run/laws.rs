//! The estimation laws of a run: the paper's published laws, a calibration
//! file's, or laws fitted to a simulated calibration sweep of the run's own
//! joint. The fit is an explicit step ([`fitted`]) whose result is cached
//! for the process, keyed by the joint and the method, so a program that
//! resolves the same scenario many times (tests, sweeps) runs one sweep,
//! and between runs in a file ([`crate::run::law_cache`]), so the main
//! job's second run does not sweep at all.
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

use anyhow::bail;
use firmware::estimate::PlaneLaw;

use crate::files::calibration::CalibrationFile;
use crate::files::scenario::{EstimatorMethod, FeedbackKind, Scenario};
use crate::joint::calibrate;
use crate::run::joint::JointSpec;
use crate::run::law_cache;
use crate::run::sweep::calibration_sweep;

/// A run's estimation laws and where they come from.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimation {
    /// One law per plane; `None`: the firmware's defaults (the paper's
    /// Eq. 2 / Eq. 3 with published constants).
    pub laws: Option<Vec<PlaneLaw>>,
    /// For the summary: the method and its source.
    pub description: String,
}

/// The laws scenario `s` asks for on `joint`: the paper's (also for camera
/// feedback, which estimates nothing), its calibration file's, or fitted
/// to a simulated sweep of `joint` ([`fitted`]).
pub fn resolve(s: &Scenario, joint: &JointSpec) -> anyhow::Result<Estimation> {
    if s.estimator.method == EstimatorMethod::Paper || s.feedback == FeedbackKind::Camera {
        return Ok(Estimation {
            laws: None,
            description: "paper (Eq. 2 / Eq. 3, published constants)".into(),
        });
    }
    let (calibration, source) = match &s.estimator.calibration {
        Some(path) => (
            CalibrationFile::load(path)?,
            format!("calibration file {}", path.display()),
        ),
        None => {
            let fit = fitted(joint, s.estimator.method)?;
            (
                fit.calibration.clone(),
                format!("fitted to a simulated sweep ({} rows)", fit.sweep_rows),
            )
        }
    };
    let laws = calibration.laws()?;
    if laws.len() != joint.planes() {
        let tables = if laws.len() == 1 {
            "[alpha] only: a 2D calibration"
        } else {
            "[alpha] and [beta]: a 3D calibration"
        };
        bail!(
            "{source} has {} angle(s) ({tables}), but the scenario's `joint = \"{}\"` has {}",
            laws.len(),
            joint.label(),
            joint.planes()
        );
    }
    let method = match laws[0] {
        PlaneLaw::Single { .. } => "single-sensor quadratic",
        PlaneLaw::Differential { .. } => "differential linear",
        PlaneLaw::Switching { .. } => "threshold switching",
    };
    Ok(Estimation {
        laws: Some(laws),
        description: format!("{method}, {source}"),
    })
}

/// Laws fitted to a simulated calibration sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct FittedLaws {
    /// The calibration the fit gives (what `calibrate wire` would write).
    pub calibration: CalibrationFile,
    /// Rows of the sweep it was fitted to.
    pub sweep_rows: usize,
}

/// Fits `method`'s laws to a simulated calibration sweep of `joint`
/// ([`calibration_sweep`]). `switching` is what `calibrate wire` writes:
/// Eq. 4 with the threshold its search finds, kept only where a second
/// branch pays (otherwise the differential branch alone, Eq. 5's form);
/// `single` and `differential` force that method. The result is cached
/// for the process: the same joint and method give the same laws without
/// a second sweep (the sweep and fit are deterministic, so the cache
/// changes no result), and so is it between runs of the same program
/// ([`law_cache`]).
pub fn fitted(joint: &JointSpec, method: EstimatorMethod) -> anyhow::Result<Arc<FittedLaws>> {
    static CACHE: OnceLock<Mutex<HashMap<String, Arc<FittedLaws>>>> = OnceLock::new();
    // `{:?}` prints every f64 so that it reads back to the same value: two
    // joints share a key only when every parameter is the same.
    let key = format!("{joint:?}|{method:?}");
    let cache = CACHE.get_or_init(Default::default);
    if let Some(hit) = cache.lock().ok().and_then(|c| c.get(&key).cloned()) {
        return Ok(hit);
    }
    let kept = law_cache::dir().zip(law_cache::key(&key));
    let fit = match kept
        .as_ref()
        .and_then(|(dir, file_key)| law_cache::load(dir, file_key))
    {
        Some((calibration, sweep_rows)) => FittedLaws {
            calibration,
            sweep_rows,
        },
        None => {
            let fit = sweep_and_fit(joint, method)?;
            if let Some((dir, file_key)) = &kept {
                law_cache::store(dir, file_key, &fit.calibration, fit.sweep_rows);
            }
            fit
        }
    };
    let fit = Arc::new(fit);
    if let Ok(mut c) = cache.lock() {
        c.insert(key, fit.clone());
    }
    Ok(fit)
}

/// The sweep of `joint` and `method`'s fit to it, uncached.
fn sweep_and_fit(joint: &JointSpec, method: EstimatorMethod) -> anyhow::Result<FittedLaws> {
    let rows = calibration_sweep(joint)?;
    let fits = calibrate::fit(&rows)?;
    let calibration = match method {
        EstimatorMethod::Single => calibrate::calibration_with(&fits, calibrate::Method::Single)?,
        EstimatorMethod::Differential => {
            calibrate::calibration_with(&fits, calibrate::Method::Differential)?
        }
        _ => calibrate::calibration_of(&fits)?,
    };
    Ok(FittedLaws {
        calibration,
        sweep_rows: rows.len(),
    })
}
