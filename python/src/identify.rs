//! The joint's identification from Python, as far as a sweep needs it:
//! the mechanics stage's fits from its starting points as work units
//! (issue 33). `softjoint identify joint --ray ADDRESS` sends each stage's
//! starts to the Ray driver, whose workers run them here
//! ([`plant_joint::identify::StartUnit::run`]) against the log and prior
//! they were built from, read as the program reads them
//! (`host_tools::joint::excite::log_from_text`, `PlantFile::from_text`).
use std::sync::Mutex;

use host_tools::files::plant::{PlantFile, PlantParams};
use host_tools::joint::{excite, identify_run};
use host_tools::output;
use plant_joint::identify::{
    self, ExcitationLog, IdentifyError, IdentifyOptions, LmOptions, StartFit, StartFits, StartUnit,
};
use plant_joint::{Joint2dParams, Joint3dParams};
use pyo3::prelude::*;

use crate::errors::{input, to_py, UnstableError};

/// Adds the identification class and function to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyIdentifyProblem>()?;
    m.add_function(wrap_pyfunction!(identify_joint, m)?)?;
    Ok(())
}

/// Start fits run by a Python callable (list of unit JSON texts → list of
/// answer JSON texts, as `IdentifyProblem.fit` answers), the first
/// exception it raised kept to be raised again once the identification
/// has returned.
struct PyFits {
    run: Py<PyAny>,
    raised: Mutex<Option<PyErr>>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
enum Answer {
    Fit(StartFit),
    Error(String),
}

impl StartFits for PyFits {
    fn fit(&self, units: &[StartUnit]) -> Result<Vec<Result<StartFit, String>>, IdentifyError> {
        let texts = units
            .iter()
            .map(|u| output::json_line("a start unit", u))
            .collect::<anyhow::Result<Vec<String>>>()
            .map_err(|e| IdentifyError::Remote(format!("{e:#}")))?;
        let answered: PyResult<Vec<String>> =
            Python::attach(|py| self.run.call1(py, (texts,))?.extract(py));
        let answers = match answered {
            Ok(a) => a,
            Err(e) => {
                let why = format!("the fits' runner raised {e}");
                self.raised
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .get_or_insert(e);
                return Err(IdentifyError::Remote(why));
            }
        };
        if answers.len() != units.len() {
            return Err(IdentifyError::Remote(format!(
                "the fits' runner gave {} answers for {} units",
                answers.len(),
                units.len()
            )));
        }
        answers
            .iter()
            .map(|a| match serde_json::from_str::<Answer>(a) {
                Ok(Answer::Fit(f)) => Ok(Ok(f)),
                Ok(Answer::Error(e)) => Ok(Err(e)),
                Err(e) => Err(IdentifyError::Remote(format!(
                    "the fits' runner answered {a:?}: {e}"
                ))),
            })
            .collect()
    }
}

/// `softjoint identify joint`: the joint identified from the log's CSV
/// text `log_text` (named `log_name`; with `board_estimates`, fitted to
/// the board's own angle estimates) from the prior plant file's text
/// (`None`: the defaults of the log's joint), with `fit_fraction` of the
/// log fitted and at most `max_iterations` per stage. With `fits` (a
/// callable: list of start-unit JSON texts → list of answer JSON texts),
/// the mechanics stage's starts run there (a Ray cluster,
/// `softjoint.ray_sweep`); the result is the same. Returns the `--json`
/// report's text (its `plant_file`: `plant_file`, where the caller writes
/// it; null: nowhere), the plant file's text
/// and whether every plane was verified.
#[pyfunction]
#[pyo3(signature = (log_text, log_name, prior_text=None, prior_name="prior", board_estimates=false, fit_fraction=0.75, max_iterations=100, plant_file=None, fits=None))]
#[allow(clippy::too_many_arguments)] // the command's flags
fn identify_joint(
    py: Python<'_>,
    log_text: &str,
    log_name: &str,
    prior_text: Option<&str>,
    prior_name: &str,
    board_estimates: bool,
    fit_fraction: f64,
    max_iterations: usize,
    plant_file: Option<&str>,
    fits: Option<Py<PyAny>>,
) -> PyResult<(String, String, bool)> {
    if !(fit_fraction.is_finite() && (0.2..=1.0).contains(&fit_fraction)) {
        return Err(input(anyhow::anyhow!(
            "fit_fraction must be in 0.2..=1, got {fit_fraction}"
        )));
    }
    if !(1..=1000).contains(&max_iterations) {
        return Err(input(anyhow::anyhow!(
            "max_iterations must be in 1..=1000, got {max_iterations}"
        )));
    }
    let log = excite::log_from_text(log_text, log_name, board_estimates).map_err(input)?;
    identify_run::check_angles(&log, log_name, board_estimates).map_err(input)?;
    let prior = prior_text
        .map(|t| PlantFile::from_text(t, prior_name).and_then(|f| f.params()))
        .transpose()
        .map_err(input)?;
    let opts = IdentifyOptions {
        fit_fraction,
        lm: LmOptions {
            max_iterations,
            ..IdentifyOptions::default().lm
        },
        ..IdentifyOptions::default()
    };
    let runner = fits.map(|run| PyFits {
        run,
        raised: Mutex::new(None),
    });
    let found = py.detach(|| {
        identify_run::identify(
            &log,
            prior,
            &opts,
            runner.as_ref().map(|r| r as &dyn StartFits),
        )
    });
    if let Some(e) = runner.and_then(|r| r.raised.into_inner().unwrap_or_else(|p| p.into_inner())) {
        return Err(e);
    }
    let found = found.map_err(|e| match e {
        identify_run::RunError::OtherJoint { log: joint } => input(anyhow::anyhow!(
            "{log_name}: a {joint} log, but {prior_name} is a plant file for the other joint"
        )),
        identify_run::RunError::Identify(e) => to_py(anyhow::anyhow!("{log_name}: {e}")),
    })?;
    let report = found
        .report(log_name, plant_file, board_estimates)
        .and_then(|r| r.text())
        .map_err(to_py)?;
    let text = found.plant_text(log_name).map_err(to_py)?;
    Ok((report, text, found.unverified().is_empty()))
}

enum Prior {
    TwoD(Box<Joint2dParams>),
    ThreeD(Box<Joint3dParams>),
}

/// A log and the prior its identification starts from, read once; runs
/// the mechanics stage's start units of that identification.
#[pyclass(name = "IdentifyProblem", module = "softjoint._native", frozen)]
pub struct PyIdentifyProblem {
    log: ExcitationLog,
    prior: Prior,
}

#[pymethods]
impl PyIdentifyProblem {
    /// The log's CSV text `log_text` (named `log_name` in errors; with
    /// `board_estimates`, its camera columns replaced by the board's
    /// estimates, as `--angles board-estimate`) and the prior's plant file
    /// text (`None`: the defaults of the log's joint).
    #[new]
    #[pyo3(signature = (log_text, log_name, prior_text=None, prior_name="prior", board_estimates=false))]
    fn new(
        log_text: &str,
        log_name: &str,
        prior_text: Option<&str>,
        prior_name: &str,
        board_estimates: bool,
    ) -> PyResult<Self> {
        let log = excite::log_from_text(log_text, log_name, board_estimates).map_err(input)?;
        let prior = match prior_text {
            None if log.planes == 1 => Prior::TwoD(Box::default()),
            None => Prior::ThreeD(Box::default()),
            Some(text) => match PlantFile::from_text(text, prior_name)
                .and_then(|f| f.params())
                .map_err(input)?
            {
                PlantParams::TwoD(p) if log.planes == 1 => Prior::TwoD(Box::new(p)),
                PlantParams::ThreeD(p) if log.planes == 2 => Prior::ThreeD(Box::new(p)),
                _ => {
                    return Err(input(anyhow::anyhow!(
                    "{log_name}: a {} log, but {prior_name} is a plant file for the other joint",
                    if log.planes == 1 { "2D" } else { "3D" }
                )))
                }
            },
        };
        Ok(Self { log, prior })
    }

    /// Runs one start unit (its JSON text, as `identify joint --ray`
    /// sends it) and returns the answer's JSON text: `{"fit": ...}` or
    /// `{"error": "the identification's error"}`.
    fn fit(&self, py: Python<'_>, unit: &str) -> PyResult<String> {
        let unit: StartUnit =
            serde_json::from_str(unit).map_err(|e| input(anyhow::anyhow!("a start unit: {e}")))?;
        let opts = IdentifyOptions {
            substep_s: f64::from_bits(unit.substep_s),
            ..IdentifyOptions::default()
        };
        let prior = match &self.prior {
            Prior::TwoD(p) => identify::prior_model_2d(p, &opts),
            Prior::ThreeD(p) => identify::prior_model_3d(p, unit.plane.min(1), &opts),
        };
        let answer = py.detach(|| match unit.run(&self.log, &prior) {
            Ok(fit) => serde_json::json!({ "fit": fit }),
            Err(e) => serde_json::json!({ "error": e.to_string() }),
        });
        serde_json::to_string(&answer).map_err(|e| to_py(e.into()))
    }

    /// The mechanics stage's cost of plane `plane` (0: θ or α, 1: β) with
    /// the parameters `values` (`{field: value}`, fields as the plant file
    /// names them under the plane, e.g. `"coil.convection_w_m2_k"`) set in
    /// the prior: what an identification's mechanics fit minimises (the
    /// sum of squares of the scaled residuals over the first
    /// `fit_fraction` of the log). Returns `(cost, residuals)`.
    #[pyo3(signature = (plane, values, fit_fraction=0.75))]
    fn cost(
        &self,
        py: Python<'_>,
        plane: usize,
        values: std::collections::BTreeMap<String, f64>,
        fit_fraction: f64,
    ) -> PyResult<(f64, usize)> {
        let opts = IdentifyOptions {
            fit_fraction,
            ..IdentifyOptions::default()
        };
        let prior = match &self.prior {
            Prior::TwoD(p) => identify::prior_model_2d(p, &opts),
            Prior::ThreeD(p) => identify::prior_model_3d(p, plane.min(1), &opts),
        };
        let values: Vec<(String, f64)> = values.into_iter().collect();
        py.detach(|| identify::mechanics_cost(&self.log, &prior, plane, &values, &opts))
            .map_err(|e| match e {
                IdentifyError::Unstable(_) => UnstableError::new_err(e.to_string()),
                e => input(anyhow::anyhow!("{e}")),
            })
    }

    /// Planes of the log (1: the 2D joint, 2: the 3D joint).
    #[getter]
    fn planes(&self) -> usize {
        self.log.planes
    }
}
