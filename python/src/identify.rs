//! The joint's identification from Python, as far as a sweep needs it:
//! the mechanics stage's fits from its starting points as work units
//! (issue 33). `softjoint identify joint --ray ADDRESS` sends each stage's
//! starts to the Ray driver, whose workers run them here
//! ([`plant_joint::identify::StartUnit::run`]) against the log and prior
//! they were built from, read as the program reads them
//! (`host_tools::joint::excite::log_from_text`, `PlantFile::from_text`).
use host_tools::files::plant::{PlantFile, PlantParams};
use host_tools::joint::excite;
use plant_joint::identify::{self, ExcitationLog, IdentifyOptions, StartUnit};
use plant_joint::{Joint2dParams, Joint3dParams};
use pyo3::prelude::*;

use crate::errors::{input, to_py};

/// Adds the identification class to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyIdentifyProblem>()?;
    Ok(())
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

    /// Planes of the log (1: the 2D joint, 2: the 3D joint).
    #[getter]
    fn planes(&self) -> usize {
        self.log.planes
    }
}
