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
    let fit = match law_cache::parse(BUILT_IN, &key).or_else(|| {
        kept.as_ref()
            .and_then(|(dir, file_key)| law_cache::load(dir, file_key))
    }) {
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

/// The default scenario's laws (`softjoint sim` with no scenario: the 3D
/// joint's defaults, seed and the switching method), fitted once to its
/// 80 s sweep and kept in the source, so that the main job's first run
/// does not sweep either (issue 34: the sweep and fit were ≈ 700 M of a
/// first run's ≈ 814 M instructions). Used only under its exact key, the
/// same text as the process cache's (every parameter of the joint and the
/// method), and held to the fit by
/// `tests::the_built_in_laws_are_the_default_joints_own_fit`, which
/// sweeps and fits anew and fails on any difference (after a change to the
/// plant, the firmware or the fit: regenerate with
/// `SOFTJOINT_BLESS_LAWS=1 cargo test -p host-tools --lib built_in_laws`).
const BUILT_IN: &str = include_str!("default_laws.toml");

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

#[cfg(test)]
mod tests {
    use super::*;

    /// The default scenario's joint and its key, as [`fitted`] forms it.
    fn default_key() -> (JointSpec, EstimatorMethod, String) {
        let s = Scenario::default();
        let joint = JointSpec::of(&s);
        let method = s.estimator.method;
        let key = format!("{joint:?}|{method:?}");
        (joint, method, key)
    }

    /// The built-in entry is the default joint's own sweep and fit, key and
    /// laws alike: a change to the plant, the firmware, the sweep or the
    /// fit that moves any digit of the laws fails here (an 80 s sweep,
    /// ≈ 0.5 CPU-s in an optimised build).
    #[test]
    fn the_built_in_laws_are_the_default_joints_own_fit() {
        let (joint, method, key) = default_key();
        let fit = sweep_and_fit(&joint, method).expect("the default joint sweeps and fits");
        let header =
            "# The default scenario's laws (`softjoint sim` with no scenario), fitted to\n\
                      # its simulated calibration sweep; see `run::laws::BUILT_IN`. Generated:\n\
                      # SOFTJOINT_BLESS_LAWS=1 cargo test -p host-tools --lib built_in_laws\n";
        let text = law_cache::entry_text(header, &key, &fit.calibration, fit.sweep_rows)
            .expect("the entry serialises");
        if std::env::var_os("SOFTJOINT_BLESS_LAWS").is_some() {
            std::fs::write(
                concat!(env!("CARGO_MANIFEST_DIR"), "/src/run/default_laws.toml"),
                &text,
            )
            .expect("the built-in entry is written");
            return;
        }
        let built_in = law_cache::parse(BUILT_IN, &key).expect(
            "the built-in entry is not the default joint's (another key or invalid laws); \
             regenerate it with SOFTJOINT_BLESS_LAWS=1 (see `BUILT_IN`)",
        );
        assert_eq!(
            built_in,
            (fit.calibration.clone(), fit.sweep_rows),
            "the built-in laws are not the default joint's fit; regenerate them with \
             SOFTJOINT_BLESS_LAWS=1 (see `BUILT_IN`)"
        );
        // Read back from the text the test itself makes, too: the entry
        // round-trips every digit.
        assert_eq!(
            law_cache::parse(&text, &key),
            Some((fit.calibration, fit.sweep_rows))
        );
    }

    /// Only the exact key reads the built-in entry: another seed of the
    /// same joint, or another method, is a miss.
    #[test]
    fn the_built_in_laws_serve_only_their_own_key() {
        let (joint, method, key) = default_key();
        assert!(law_cache::parse(BUILT_IN, &key).is_some());
        let other_seed = joint.with_seed(joint.seed + 1);
        assert!(law_cache::parse(BUILT_IN, &format!("{other_seed:?}|{method:?}")).is_none());
        let other_method = format!("{joint:?}|{:?}", EstimatorMethod::Differential);
        assert!(law_cache::parse(BUILT_IN, &other_method).is_none());
    }
}
