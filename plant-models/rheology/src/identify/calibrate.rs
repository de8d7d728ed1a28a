//! Calibration of a lattice from a measured push: the problem (a scenario
//! that says which lattice and push, a parameter set, a measurement, the
//! objective S) and the run of one of the searches on it.
use std::sync::{Arc, OnceLock};

use serde::{Deserialize, Serialize};

use crate::error::{bad_setting, Result, RheologyError};
use crate::identify::ga::{self, GaSettings};
use crate::identify::measurement::Measurement;
use crate::identify::objective::{check_weights, score, Score};
use crate::identify::ra::{self, RaSettings};
use crate::identify::search::{
    self, BatchObjective, Budget, Local, Method, Progress, SearchResult, UNIT_CANDIDATES,
};
use crate::model::lattice::Lattice;
use crate::model::params::{LatticeParams, ParamSet};
use crate::model::scenario::{lattice_sim, run, Run, Scenario};

/// A lattice to calibrate against a measured push.
#[derive(Clone, Debug)]
pub struct Problem {
    /// The lattice, model variant, rig and plate schedule of the push.
    pub scenario: Scenario,
    pub set: ParamSet,
    pub measurement: Measurement,
    lattice: Lattice,
    frame_times: Vec<f64>,
    /// The first stable run whose weighted S was not a finite number
    /// while a search scored it ([`Self::s_of_genes`]); shared by the
    /// problem's clones, so that the search that scored it ends with it.
    objective_failure: Arc<OnceLock<RheologyError>>,
}

impl Problem {
    /// Checks that the measurement fits the scenario.
    pub fn new(scenario: Scenario, set: ParamSet, measurement: Measurement) -> Result<Self> {
        scenario.validate()?;
        if measurement.frames.is_empty() && scenario.objective.force_per_n == 0.0 {
            return Err(bad_setting(
                "measurement",
                "no surface-point frames to compare shapes with",
            ));
        }
        // Each point gives one distance: fewer than one per parameter
        // cannot determine them (issue 31: a single point was accepted).
        let points = measurement.point_count();
        if scenario.objective.shape_per_cm > 0.0 && points < set.len() {
            return Err(bad_setting(
                "surface_points.csv",
                format!(
                    "{points} surface point(s) for {} parameters; the shape term needs at least \
                     one point per parameter ({})",
                    set.len(),
                    set.len()
                ),
            ));
        }
        let end = scenario.plate.end_s;
        for (k, f) in measurement.frames.iter().enumerate() {
            if !(0.0..=end).contains(&f.t_s) {
                return Err(bad_setting(
                    &format!("measurement frame {k}"),
                    format!("time {} s lies outside the run (0–{end} s)", f.t_s),
                ));
            }
        }
        let lattice = scenario.lattice()?;
        check_weights(&lattice, &measurement, &scenario.objective)?;
        let frame_times = measurement.frame_times_s();
        Ok(Self {
            scenario,
            set,
            measurement,
            lattice,
            frame_times,
            objective_failure: Arc::default(),
        })
    }

    /// The lattice being calibrated.
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// Runs the lattice with `params` through the push (frames at the
    /// measured times).
    pub fn run(&self, params: &LatticeParams) -> Result<Run> {
        let mut sim = lattice_sim(&self.scenario, &self.lattice, params)?;
        Ok(run(&mut sim, self.scenario.plate.end_s, &self.frame_times))
    }

    /// S of `params` and the run it came from.
    pub fn score(&self, params: &LatticeParams) -> Result<(Score, Run)> {
        let r = self.run(params)?;
        let s = score(
            &self.lattice.surface,
            &r,
            &self.measurement,
            &self.scenario.objective,
            self.scenario.measure.force_window_s,
        )?;
        Ok((s, r))
    }

    /// S of a gene vector (+∞ for parameters the model refuses or that
    /// make it unstable). A stable run whose weighted S is not a finite
    /// number is not an unstable candidate but a weight too large for this
    /// measurement: it scores +∞ here too, and the error naming the weight
    /// is kept ([`Self::objective_failure`]), which ends the search that
    /// asked ([`calibrate_with`]).
    pub fn s_of_genes(&self, genes: &[f64]) -> f64 {
        let Ok(run) = self.set.to_lattice(genes).and_then(|p| self.run(&p)) else {
            return f64::INFINITY;
        };
        match score(
            &self.lattice.surface,
            &run,
            &self.measurement,
            &self.scenario.objective,
            self.scenario.measure.force_window_s,
        ) {
            Ok(s) => s.s,
            Err(e) => {
                // The first one is kept; the others say the same of the
                // same weight.
                let _ = self.objective_failure.set(e);
                f64::INFINITY
            }
        }
    }

    /// The error of the first stable run [`Self::s_of_genes`] could not
    /// score (the weight whose term overflowed), if any.
    pub fn objective_failure(&self) -> Option<&RheologyError> {
        self.objective_failure.get()
    }
}

/// `inner`, ending the search at the first batch in which a stable
/// candidate's S overflowed ([`Problem::objective_failure`]) instead of
/// counting that candidate as unstable.
struct Checked<'a> {
    inner: &'a mut dyn BatchObjective,
    problem: &'a Problem,
}

impl BatchObjective for Checked<'_> {
    fn scores(&mut self, batch: &[Vec<f64>]) -> std::result::Result<Vec<f64>, String> {
        let s = self.inner.scores(batch)?;
        match self.problem.objective_failure() {
            Some(e) => Err(e.to_string()),
            None => Ok(s),
        }
    }
}

/// Which search, how long, and its settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CalibrationSettings {
    pub method: Method,
    pub budget: Budget,
    pub seed: u64,
    pub ga: GaSettings,
    pub ra: RaSettings,
}

impl CalibrationSettings {
    /// The paper's settings of `method` with `budget` and `seed`.
    pub fn new(method: Method, budget: Budget, seed: u64) -> Self {
        Self {
            method,
            budget,
            seed,
            ga: GaSettings::default(),
            ra: RaSettings::default(),
        }
    }
}

/// The outcome of a calibration.
#[derive(Clone, Debug, Serialize)]
pub struct Calibration {
    pub search: SearchResult,
    pub best_params: LatticeParams,
}

/// Runs the chosen search on `problem`, scoring on this process's
/// threads.
pub fn calibrate(
    problem: &Problem,
    settings: &CalibrationSettings,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<Calibration> {
    let f = |g: &[f64]| problem.s_of_genes(g);
    let mut local = Local {
        f: &f,
        unit: UNIT_CANDIDATES,
    };
    calibrate_with(problem, settings, &mut local, on_progress)
}

/// Runs the chosen search on `problem` with its batches scored by
/// `objective`, which must score a gene vector as
/// [`Problem::s_of_genes`] does (the Python package's Ray driver scores
/// them on a cluster's workers, each with the same problem).
pub fn calibrate_with(
    problem: &Problem,
    settings: &CalibrationSettings,
    objective: &mut dyn BatchObjective,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<Calibration> {
    let ranges = problem.set.ranges();
    let objective = &mut Checked {
        inner: objective,
        problem,
    };
    let outcome = match settings.method {
        Method::Ga => ga::run_with(
            objective,
            &ranges,
            &settings.ga,
            settings.budget,
            settings.seed,
            on_progress,
        ),
        Method::Ra => ra::run_with(
            objective,
            &ranges,
            &settings.ra,
            settings.budget,
            settings.seed,
            on_progress,
        ),
        Method::Uniform => search::uniform_with(
            objective,
            &ranges,
            settings.budget,
            settings.seed,
            settings.ga.population,
            on_progress,
        ),
    };
    // Reported as what it is: the weight and the term, not "the search's
    // objective failed".
    if let Some(e) = problem.objective_failure() {
        return Err(e.clone());
    }
    let search = outcome?;
    let best_params = problem.set.to_lattice(&search.best_genes)?;
    Ok(Calibration {
        search,
        best_params,
    })
}
