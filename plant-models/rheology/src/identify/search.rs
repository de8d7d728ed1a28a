//! What the searches share: budgets in evaluations or wall time, parallel
//! scoring of a batch of candidates (rayon, results in candidate order so
//! that a seeded search does not depend on the number of threads), the
//! best-so-far record and a history row per generation or cycle.
//!
//! A batch is scored through a [`BatchObjective`]: on this process's
//! threads ([`Local`]), or anywhere else a caller sends it (the Python
//! package's Ray driver). A batch is cut into work units of consecutive
//! candidates ([`units`]); the scores come back in candidate order and
//! the search's random draws and selection stay here, so where the units
//! run cannot change the result.
//!
//! Candidates are gene vectors in the units of [`ParamRange`]; the
//! searches work in the unit cube `u ∈ [0, 1]^p` (`gene = min + u·(max −
//! min)`, linear as the paper's intervals are printed). A candidate whose
//! simulation is unstable (or whose score is NaN) scores +∞ and is counted.
use std::ops::Range;
use std::time::Instant;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{bad_setting, Result, RheologyError};
use crate::params::ParamRange;

/// Scores batches of gene vectors (in the units of [`ParamRange`]).
pub trait BatchObjective {
    /// S of each gene vector of `batch`, in order; a non-finite S counts
    /// as an unstable candidate. An error (a remote worker that could not
    /// be reached, a cancelled sweep) ends the search with that error.
    fn scores(&mut self, batch: &[Vec<f64>]) -> std::result::Result<Vec<f64>, String>;
}

/// Candidates per work unit: one. An evaluation of the paper's block is
/// ≈ 0.12 CPU-s (issue 33: 10,000 in ≈ 20 CPU-minutes) and a Ray task
/// costs 0.7–0.9 ms on this project's 2-core machine (5.7 ms under a
/// load of 13–22; docs/benchmarks.md, "Sweeps on Ray"), so a unit of one
/// keeps the overhead near 1 % (5 % under that load), while a GA
/// generation of 40 children still spreads over 40 workers: with units
/// of 4 it could not use more than 10 (simulated there: 5.0× on 8
/// workers against 7.9× with units of 1).
pub const UNIT_CANDIDATES: usize = 1;

/// The work units of a batch of `n` candidates: consecutive index ranges
/// of `unit` candidates (the last may be shorter), in order.
pub fn units(n: usize, unit: usize) -> Vec<Range<usize>> {
    let unit = unit.max(1);
    (0..n.div_ceil(unit))
        .map(|k| k * unit..((k + 1) * unit).min(n))
        .collect()
}

/// The objective `f` scored on this process's threads: one rayon task per
/// work unit of `unit` candidates, each scored in order.
pub struct Local<'a, F> {
    pub f: &'a F,
    pub unit: usize,
}

impl<F: Fn(&[f64]) -> f64 + Sync> BatchObjective for Local<'_, F> {
    fn scores(&mut self, batch: &[Vec<f64>]) -> std::result::Result<Vec<f64>, String> {
        let f = self.f;
        let per_unit: Vec<Vec<f64>> = units(batch.len(), self.unit)
            .into_par_iter()
            .map(|r| batch[r].iter().map(|g| f(g)).collect())
            .collect();
        Ok(per_unit.concat())
    }
}

/// When a search stops: after this many evaluations and/or this much wall
/// time (whichever comes first; at least one must be set).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Budget {
    pub max_evaluations: Option<usize>,
    pub max_seconds: Option<f64>,
}

impl Budget {
    /// A budget of `n` evaluations.
    pub fn evaluations(n: usize) -> Self {
        Self {
            max_evaluations: Some(n),
            max_seconds: None,
        }
    }

    /// Checks that something bounds the search.
    pub fn validate(&self) -> Result<()> {
        match (self.max_evaluations, self.max_seconds) {
            (None, None) => Err(bad_setting(
                "budget",
                "give a number of evaluations or a wall time",
            )),
            (Some(0), _) => Err(bad_setting("budget", "at least one evaluation")),
            (_, Some(s)) if !(s.is_finite() && s > 0.0) => Err(bad_setting(
                "budget",
                "the wall time must be a finite number of seconds > 0",
            )),
            _ => Ok(()),
        }
    }
}

/// Which search.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's genetic algorithm (L1757–1772, L1816–1821).
    Ga,
    /// The paper's randomized algorithm: steepest descent with random
    /// walks out of local minima (L1746–1755).
    Ra,
    /// Plain uniform sampling of the intervals (a baseline).
    Uniform,
}

impl Method {
    /// Snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            Method::Ga => "ga",
            Method::Ra => "ra",
            Method::Uniform => "uniform",
        }
    }
}

/// One row of a search's history.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct HistoryRow {
    /// Generation (GA, uniform batches) or descent/walk cycle (RA), from 1.
    pub generation: usize,
    /// Evaluations so far.
    pub evaluations: usize,
    /// Best S so far.
    pub best_s: f64,
    /// Best and mean (finite scores only) S of this generation's batch.
    pub batch_best_s: f64,
    pub batch_mean_s: f64,
    /// Wall time so far (s).
    pub elapsed_s: f64,
}

/// Progress reported after every batch (for progress bars).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Progress {
    pub evaluations: usize,
    pub best_s: f64,
    pub generation: usize,
    pub elapsed_s: f64,
}

/// The outcome of a search.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SearchResult {
    pub method: Method,
    pub best_genes: Vec<f64>,
    pub best_s: f64,
    pub evaluations: usize,
    /// Candidates whose simulation was unstable.
    pub unstable: usize,
    pub history: Vec<HistoryRow>,
    pub elapsed_s: f64,
    /// "evaluations" or "wall time".
    pub stopped_by: &'static str,
}

/// Book-keeping of a running search. An objective that fails ends the
/// search: [`Tracker::allowed`] says 0 from then on, [`Tracker::evaluate`]
/// scores nothing, and [`Tracker::finish`] returns the failure.
pub(crate) struct Tracker<'a> {
    objective: &'a mut dyn BatchObjective,
    failed: Option<String>,
    ranges: &'a [ParamRange],
    budget: Budget,
    start: Instant,
    evaluations: usize,
    unstable: usize,
    best: (Vec<f64>, f64),
    history: Vec<HistoryRow>,
    on_progress: &'a mut dyn FnMut(&Progress),
    stopped_by: &'static str,
}

impl<'a> Tracker<'a> {
    pub(crate) fn new(
        objective: &'a mut dyn BatchObjective,
        ranges: &'a [ParamRange],
        budget: Budget,
        on_progress: &'a mut dyn FnMut(&Progress),
    ) -> Result<Self> {
        budget.validate()?;
        if ranges.is_empty() {
            return Err(bad_setting("params", "nothing to search"));
        }
        Ok(Self {
            objective,
            failed: None,
            ranges,
            budget,
            start: Instant::now(),
            evaluations: 0,
            unstable: 0,
            best: (Vec::new(), f64::INFINITY),
            history: Vec::new(),
            on_progress,
            stopped_by: "evaluations",
        })
    }

    /// History rows so far.
    pub(crate) fn history_len(&self) -> usize {
        self.history.len()
    }

    /// Dimension of the search.
    pub(crate) fn dim(&self) -> usize {
        self.ranges.len()
    }

    /// How many of `want` evaluations the budget still allows (0 when
    /// spent).
    pub(crate) fn allowed(&mut self, want: usize) -> usize {
        if self.failed.is_some() {
            return 0;
        }
        if let Some(s) = self.budget.max_seconds {
            if self.start.elapsed().as_secs_f64() >= s {
                self.stopped_by = "wall time";
                return 0;
            }
        }
        match self.budget.max_evaluations {
            Some(n) => want.min(n.saturating_sub(self.evaluations)),
            None => want,
        }
    }

    /// The genes of a point of the unit cube.
    pub(crate) fn genes(&self, u: &[f64]) -> Vec<f64> {
        u.iter()
            .zip(self.ranges)
            .map(|(&u, r)| r.min + u.clamp(0.0, 1.0) * (r.max - r.min))
            .collect()
    }

    /// Scores unit-cube points through the objective (at most what the
    /// budget allows: the returned vector may be shorter than `batch`,
    /// and empty once the objective has failed).
    pub(crate) fn evaluate(&mut self, batch: &[Vec<f64>]) -> Vec<f64> {
        let n = self.allowed(batch.len());
        let genes: Vec<Vec<f64>> = batch[..n].iter().map(|u| self.genes(u)).collect();
        let scores = match self.objective.scores(&genes) {
            Ok(s) if s.len() == n => s,
            Ok(s) => {
                self.failed = Some(format!(
                    "the objective returned {} scores for {n} candidates",
                    s.len()
                ));
                return Vec::new();
            }
            Err(e) => {
                self.failed = Some(e);
                return Vec::new();
            }
        };
        let scores: Vec<f64> = scores
            .into_iter()
            .map(|s| if s.is_finite() { s } else { f64::INFINITY })
            .collect();
        self.evaluations += n;
        for (g, &s) in genes.into_iter().zip(&scores) {
            if !s.is_finite() {
                self.unstable += 1;
            } else if s < self.best.1 {
                self.best = (g, s);
            }
        }
        scores
    }

    /// Closes a generation: a history row and a progress report.
    pub(crate) fn record(&mut self, generation: usize, batch: &[f64]) {
        let finite: Vec<f64> = batch.iter().copied().filter(|s| s.is_finite()).collect();
        let row = HistoryRow {
            generation,
            evaluations: self.evaluations,
            best_s: self.best.1,
            batch_best_s: finite.iter().copied().fold(f64::INFINITY, f64::min),
            batch_mean_s: if finite.is_empty() {
                f64::INFINITY
            } else {
                finite.iter().sum::<f64>() / finite.len() as f64
            },
            elapsed_s: self.start.elapsed().as_secs_f64(),
        };
        self.history.push(row);
        (self.on_progress)(&Progress {
            evaluations: self.evaluations,
            best_s: self.best.1,
            generation,
            elapsed_s: row.elapsed_s,
        });
    }

    pub(crate) fn finish(self, method: Method) -> Result<SearchResult> {
        if let Some(reason) = self.failed {
            return Err(RheologyError::Evaluation { reason });
        }
        let best_genes = if self.best.0.is_empty() {
            self.genes(&vec![0.5; self.dim()])
        } else {
            self.best.0.clone()
        };
        Ok(SearchResult {
            method,
            best_genes,
            best_s: self.best.1,
            evaluations: self.evaluations,
            unstable: self.unstable,
            history: self.history,
            elapsed_s: self.start.elapsed().as_secs_f64(),
            stopped_by: self.stopped_by,
        })
    }
}

/// Uniform random sampling of the intervals in batches of `batch`.
pub fn uniform<F: Fn(&[f64]) -> f64 + Sync>(
    f: &F,
    ranges: &[ParamRange],
    budget: Budget,
    seed: u64,
    batch: usize,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<SearchResult> {
    let mut local = Local {
        f,
        unit: UNIT_CANDIDATES,
    };
    uniform_with(&mut local, ranges, budget, seed, batch, on_progress)
}

/// [`uniform`] with its batches scored by `objective`.
pub fn uniform_with(
    objective: &mut dyn BatchObjective,
    ranges: &[ParamRange],
    budget: Budget,
    seed: u64,
    batch: usize,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<SearchResult> {
    use rand::Rng;
    let mut tr = Tracker::new(objective, ranges, budget, on_progress)?;
    let mut rng = plant_common::rng::stream(seed, plant_common::rng::RHEOLOGY_SEARCH);
    let batch = batch.max(1);
    let mut generation = 0;
    while tr.allowed(batch) > 0 {
        let points: Vec<Vec<f64>> = (0..batch)
            .map(|_| (0..tr.dim()).map(|_| rng.gen::<f64>()).collect())
            .collect();
        let scores = tr.evaluate(&points);
        generation += 1;
        tr.record(generation, &scores);
    }
    tr.finish(Method::Uniform)
}
