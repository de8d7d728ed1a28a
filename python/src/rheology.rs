//! The rheology lattice from Python: the calibration problem of
//! `softjoint rheology calibrate` (scenario file, measured push or the
//! reference block's recording, parameter set), its objective S for one
//! parameter set, and its calibration with each batch of candidates
//! scored by a Python callable (the Ray driver's fan-out) or on this
//! process's threads.
use std::path::PathBuf;

use host_tools::files::rheology::ScenarioFile;
use host_tools::output;
use plant_rheology::identify::calibrate::{CalibrationSettings, Problem};
use plant_rheology::identify::experiment::{self, CalibrationSpec};
use plant_rheology::identify::measurement::Measurement;
use plant_rheology::identify::search::{self, BatchObjective, Budget, Local, Method};
use plant_rheology::params::ParamSet;
use pyo3::prelude::*;

use crate::errors::{input, rheology_to_py, to_py};

/// Adds the rheology classes and functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyRheologyProblem>()?;
    m.add_function(wrap_pyfunction!(rheology_units, m)?)?;
    m.add("RHEOLOGY_UNIT_CANDIDATES", search::UNIT_CANDIDATES)?;
    Ok(())
}

/// The work units of a batch of `n` candidates, `size` each, as
/// `(start, end)` (the same cut `softjoint rheology calibrate` makes).
#[pyfunction]
#[pyo3(signature = (n, size=search::UNIT_CANDIDATES))]
fn rheology_units(n: usize, size: usize) -> Vec<(usize, usize)> {
    search::units(n, size)
        .into_iter()
        .map(|r| (r.start, r.end))
        .collect()
}

fn method(name: &str) -> PyResult<Method> {
    match name {
        "ga" => Ok(Method::Ga),
        "ra" => Ok(Method::Ra),
        "uniform" => Ok(Method::Uniform),
        _ => Err(input(anyhow::anyhow!(
            "method {name:?}: give \"ga\", \"ra\" or \"uniform\""
        ))),
    }
}

/// A calibration problem of `softjoint rheology calibrate SCENARIO
/// [--measured DIR] --params N`.
#[pyclass(name = "RheologyProblem", module = "softjoint._native", frozen)]
pub struct PyRheologyProblem {
    file: ScenarioFile,
    measured: Option<Measurement>,
    set: ParamSet,
    problem: Problem,
}

impl PyRheologyProblem {
    fn spec(&self, settings: CalibrationSettings) -> CalibrationSpec {
        CalibrationSpec {
            scenario: self.file.scenario(),
            reference: self.file.reference.clone(),
            measured: self.measured.clone(),
            set: self.set,
            settings,
            unseen: None,
        }
    }
}

/// A Python callable that scores a batch (a list of gene lists) and
/// returns a list of S; a Python exception it raises is kept and raised
/// again when the search has stopped.
struct PyBatch<'py> {
    f: Bound<'py, PyAny>,
    raised: Option<PyErr>,
}

impl BatchObjective for PyBatch<'_> {
    fn scores(&mut self, batch: &[Vec<f64>]) -> Result<Vec<f64>, String> {
        let r = self
            .f
            .call1((batch.to_vec(),))
            .and_then(|v| v.extract::<Vec<f64>>());
        r.map_err(|e| {
            let msg = e.to_string();
            self.raised = Some(e);
            msg
        })
    }
}

#[pymethods]
impl PyRheologyProblem {
    /// The problem of a scenario file's text (`None`: the built-in
    /// default), against a measured push given as the texts of its
    /// `surface_points.csv` and `forces.csv` (`None`: the reference
    /// block pushed as the scenario says and recorded, seeded), with 4, 8
    /// or 16 parameters. `scenario_name` names the text in errors.
    #[new]
    #[pyo3(signature = (scenario_text=None, measured=None, params=4, scenario_name="scenario"))]
    fn new(
        py: Python<'_>,
        scenario_text: Option<String>,
        measured: Option<(String, String)>,
        params: usize,
        scenario_name: &str,
    ) -> PyResult<Self> {
        let file = match scenario_text {
            Some(t) => ScenarioFile::from_text(&t, &PathBuf::from(scenario_name)).map_err(input)?,
            None => ScenarioFile::default(),
        };
        let set =
            ParamSet::from_count(params).map_err(|e| input(anyhow::anyhow!("params: {e}")))?;
        let measured = match measured {
            Some((points, forces)) => Some(
                Measurement::from_csv(&points, "surface_points.csv", &forces, "forces.csv")
                    .map_err(|e| input(e.into()))?,
            ),
            None => None,
        };
        let spec = CalibrationSpec {
            scenario: file.scenario(),
            reference: file.reference.clone(),
            measured: measured.clone(),
            set,
            settings: CalibrationSettings::new(Method::Ga, Budget::evaluations(1), 1),
            unseen: None,
        };
        let problem = py
            .detach(|| experiment::calibration_problem(&spec, &mut |_| {}))
            .map_err(|e| rheology_to_py(Some(&e), e.to_string()))?;
        Ok(Self {
            file,
            measured,
            set,
            problem,
        })
    }

    /// The genes' names and ranges, in gene order: `(name, min, max)`.
    fn ranges(&self) -> Vec<(String, f64, f64)> {
        self.set
            .ranges()
            .into_iter()
            .map(|r| (r.name, r.min, r.max))
            .collect()
    }

    /// S of one parameter set (genes in [`ranges`](Self::ranges) order):
    /// InputError for genes the model refuses, UnstableError for a
    /// lattice that goes unstable, NonFiniteError for an S that is not a
    /// number.
    fn objective(&self, py: Python<'_>, genes: Vec<f64>) -> PyResult<f64> {
        let problem = &self.problem;
        let score = py.detach(|| -> plant_rheology::Result<_> {
            let p = problem.set.to_lattice(&genes)?;
            let (s, run) = problem.score(&p)?;
            match run.instability {
                Some(e) => Err(e),
                None => Ok(s),
            }
        });
        let s = score.map_err(|e| rheology_to_py(Some(&e), e.to_string()))?;
        output::check_value("the objective S", &s.s).map_err(to_py)?;
        Ok(s.s)
    }

    /// S of each gene list as the searches score them: +inf for genes the
    /// model refuses or that make it unstable (the search counts them).
    /// This is the work of one unit. InputError, naming the weight, if a
    /// stable run's S is not a finite number (a weight too large for the
    /// measurement, not an unstable candidate).
    fn scores(&self, py: Python<'_>, batch: Vec<Vec<f64>>) -> PyResult<Vec<f64>> {
        let problem = &self.problem;
        let s = py.detach(|| {
            let f = |g: &[f64]| problem.s_of_genes(g);
            let mut local = Local { f: &f, unit: 1 };
            local.scores(&batch).unwrap_or_default()
        });
        match problem.objective_failure() {
            Some(e) => Err(rheology_to_py(Some(e), e.to_string())),
            None => Ok(s),
        }
    }

    /// Calibrates as `softjoint rheology calibrate --method METHOD
    /// --evaluations N --seed SEED` does, and returns its `--json`
    /// summary as text (its `elapsed_s` is this run's). With
    /// `evaluate_batch` (a callable: list of gene lists → list of S, as
    /// [`scores`](Self::scores)), each batch the search asks for is
    /// scored by it — the Ray driver fans the batch out there; the draws
    /// and the selection stay here. An exception it raises stops the
    /// search and is raised again.
    #[pyo3(signature = (method="ga", evaluations=1000, seed=1, evaluate_batch=None))]
    fn calibrate(
        &self,
        py: Python<'_>,
        method: &str,
        evaluations: usize,
        seed: u64,
        evaluate_batch: Option<Bound<'_, PyAny>>,
    ) -> PyResult<String> {
        let mut settings = CalibrationSettings::new(
            self::method(method)?,
            Budget::evaluations(evaluations),
            seed,
        );
        settings.ga = self.file.ga;
        settings.ra = self.file.ra;
        let spec = self.spec(settings);
        let report = match evaluate_batch {
            Some(f) => {
                let mut obj = PyBatch { f, raised: None };
                let r = experiment::calibrate_problem(
                    &spec,
                    self.problem.clone(),
                    &mut obj,
                    &mut |_| {},
                );
                if let Some(e) = obj.raised {
                    return Err(e);
                }
                r
            }
            None => {
                let problem = &self.problem;
                py.detach(|| {
                    let f = |g: &[f64]| problem.s_of_genes(g);
                    let mut local = Local {
                        f: &f,
                        unit: search::UNIT_CANDIDATES,
                    };
                    experiment::calibrate_problem(&spec, problem.clone(), &mut local, &mut |_| {})
                })
            }
        }
        .map_err(|e| rheology_to_py(Some(&e), e.to_string()))?;
        output::json("the calibration's summary", &report).map_err(to_py)
    }
}
