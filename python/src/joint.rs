//! The joint from Python: scenarios, the closed-loop run with its trace
//! as arrays (the columns of `softjoint sim --csv`), plant files, the
//! tuning cost of one candidate on one plant, and `tune` as a sweep of
//! work units (`host_tools::joint::tune::TuneSweep`).
use std::path::{Path, PathBuf};

use host_tools::files::gains::Gains;
use host_tools::files::plant::PlantFile;
use host_tools::files::scenario::Scenario;
use host_tools::files::JointKind;
use host_tools::joint::tune::{self, Scored, TuneRequest, TuneSweep, TuneUnit};
use host_tools::output;
use host_tools::run::record::Row;
use host_tools::run::spec::RunSpec;
use host_tools::run::summary::RunCutShort;
use host_tools::run::trace::{check_row, csv_header, RowSink};
use host_tools::stop::Stop;
use numpy::{PyArray1, ToPyArray};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde::{Deserialize, Serialize};

use crate::errors::{input, to_py, SweepError};

/// Adds the joint's classes and functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyScenario>()?;
    m.add_class::<PyPlantFile>()?;
    m.add_class::<PyTuneSweep>()?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(tune_cost, m)?)?;
    m.add_function(wrap_pyfunction!(candidate_gains, m)?)?;
    m.add_function(wrap_pyfunction!(write_gains, m)?)?;
    m.add("TUNE_UNIT_CANDIDATES", tune::UNIT_CANDIDATES)?;
    Ok(())
}

/// A scenario of the joint, as `softjoint sim` reads it.
#[pyclass(name = "Scenario", module = "softjoint._native", frozen)]
pub struct PyScenario {
    scenario: Scenario,
    /// The file it came from (errors name it).
    path: Option<PathBuf>,
}

#[pymethods]
impl PyScenario {
    /// The built-in default scenario (`softjoint sim` without a file).
    #[staticmethod]
    fn default() -> Self {
        Self {
            scenario: Scenario::default(),
            path: None,
        }
    }

    /// Reads and checks a scenario file (relative paths in it are read
    /// from the file's folder); InputError names the file and field.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let scenario = Scenario::load(&path).map_err(input)?;
        Ok(Self {
            scenario,
            path: Some(path),
        })
    }

    /// The scenario's name.
    #[getter]
    fn name(&self) -> String {
        self.scenario.name.clone()
    }

    /// The scenario as TOML (what `softjoint sim --print-default` prints
    /// for the default).
    fn to_toml(&self) -> PyResult<String> {
        output::toml("the scenario", "", &self.scenario).map_err(to_py)
    }

    /// The trace's column names, in the order of the CSV.
    fn columns(&self) -> Vec<String> {
        columns(&angle_names(&self.scenario))
    }
}

fn angle_names(s: &Scenario) -> Vec<String> {
    host_tools::run::joint::JointSpec::of(s)
        .angle_names()
        .iter()
        .map(|a| a.to_string())
        .collect()
}

fn columns(angles: &[String]) -> Vec<String> {
    csv_header(angles)
        .trim_end()
        .split(',')
        .map(str::to_string)
        .collect()
}

/// Rows kept for arrays, each checked as the CSV trace checks its rows.
struct CheckedRows {
    angles: Vec<String>,
    rows: Vec<Row>,
}

impl RowSink for CheckedRows {
    fn row(&mut self, row: &Row) -> anyhow::Result<()> {
        // Line numbers as in the CSV (line 1 is the header).
        let line = self.rows.len() as u64 + 2;
        check_row(Path::new("the trace"), line, &self.angles, row)?;
        self.rows.push(*row);
        Ok(())
    }
}

/// Runs the scenario's closed loop (the firmware core in process, as
/// `softjoint sim`) and returns `(columns, summary_json)`: a dict of
/// NumPy arrays named as the CSV trace's columns (a missing estimate is
/// NaN where the CSV has an empty field; `faults` is uint16) and the
/// `--json` summary as text. A run that ends early (the plant's
/// instability checks, a trace row that fails its finite check) raises
/// RunCutShortError; a non-finite summary raises NonFiniteError.
#[pyfunction]
fn simulate<'py>(py: Python<'py>, scenario: &PyScenario) -> PyResult<(Bound<'py, PyDict>, String)> {
    let in_scenario = |e: anyhow::Error| match &scenario.path {
        Some(p) => e.context(format!("scenario {}", p.display())),
        None => e,
    };
    let angles = angle_names(&scenario.scenario);
    let mut sink = CheckedRows {
        angles: angles.clone(),
        rows: Vec::new(),
    };
    let summary = py
        .detach(|| -> anyhow::Result<_> {
            let spec = RunSpec::resolve(&scenario.scenario).map_err(in_scenario)?;
            let stop = Stop::never();
            let bar = indicatif::ProgressBar::hidden();
            host_tools::run::sim::run_into(&spec, &mut sink, &stop, &bar).map_err(in_scenario)
        })
        .map_err(to_py)?;
    if let Some(cut) = summary.cut_short.clone() {
        return Err(to_py(anyhow::Error::new(RunCutShort(cut))));
    }
    let json = output::json("the run's summary", &summary).map_err(to_py)?;
    let rows = &sink.rows;
    let d = PyDict::new(py);
    let col = |f: &dyn Fn(&Row) -> f64| -> Bound<'py, PyArray1<f64>> {
        rows.iter().map(f).collect::<Vec<f64>>().to_pyarray(py)
    };
    d.set_item("t_s", col(&|r| r.t_s))?;
    for (p, a) in angles.iter().enumerate() {
        d.set_item(format!("{a}_true_deg"), col(&|r| r.true_deg[p]))?;
        d.set_item(format!("{a}_estimate_deg"), col(&|r| r.estimate_deg[p]))?;
        d.set_item(format!("{a}_desired_deg"), col(&|r| r.desired_deg[p]))?;
    }
    for c in 0..2 * angles.len() {
        d.set_item(format!("v{}_V", c + 1), col(&|r| r.coil_volts[c]))?;
    }
    let faults: Vec<u16> = rows.iter().map(|r| r.faults).collect();
    d.set_item("faults", faults.to_pyarray(py))?;
    Ok((d, json))
}

/// A plant file (`softjoint identify joint` writes one).
#[pyclass(name = "PlantFile", module = "softjoint._native", frozen)]
pub struct PyPlantFile {
    file: PlantFile,
    name: String,
    text: String,
}

#[pymethods]
impl PyPlantFile {
    /// Reads and checks a plant file; InputError names the file and field.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let text = std::fs::read_to_string(&path).map_err(|e| {
            input(anyhow::anyhow!(
                "cannot read plant file {}: {e}",
                path.display()
            ))
        })?;
        Self::from_text(text, path.display().to_string())
    }

    /// Reads and checks a plant file's text; errors name `name`.
    #[staticmethod]
    fn from_text(text: String, name: String) -> PyResult<Self> {
        let file = PlantFile::from_text(&text, &name).map_err(input)?;
        Ok(Self { file, name, text })
    }

    /// The name errors and gains files give it (its path when loaded).
    #[getter]
    fn name(&self) -> String {
        self.name.clone()
    }

    /// The file's text (what a sweep ships to its workers).
    #[getter]
    fn text(&self) -> String {
        self.text.clone()
    }

    /// Writes the file's text to `path` as the program writes its files
    /// (atomically: replaced whole or not at all; a symbolic link is
    /// followed, a device or FIFO written through).
    fn save(&self, path: PathBuf) -> PyResult<()> {
        output::write_text(&path, &self.text).map_err(to_py)
    }
}

/// Writes a gains file (`gains`: its table as JSON text, as `tune`
/// returns it under `gains`) to `path` as `softjoint tune -o` writes one:
/// the same header and TOML, checked as a scenario or the console loads
/// it (InputError naming the file and field otherwise), atomically.
#[pyfunction]
pub fn write_gains(path: PathBuf, gains: &str) -> PyResult<()> {
    let g: host_tools::files::gains::GainsFile = serde_json::from_str(gains)
        .map_err(|e| input(anyhow::anyhow!("gains for {}: {e}", path.display())))?;
    let text = output::toml(
        &path.display().to_string(),
        host_tools::files::gains::GAINS_HEADER,
        &g,
    )
    .map_err(to_py)?;
    host_tools::files::gains::GainsFile::from_text(&text, &path).map_err(input)?;
    output::write_text(&path, &text).map_err(to_py)
}

fn request(candidates: usize, plants: usize, seed: u64, search_v_offset: bool) -> TuneRequest {
    TuneRequest {
        candidates,
        plants,
        seed,
        search_v_offset,
    }
}

/// Candidate `index` of `tune`'s seeded sequence (0: the paper's gains)
/// as `(kp_v_per_deg, ki_v_per_deg_s, integral_limit_v, v_offset_v)`.
#[pyfunction]
#[pyo3(signature = (plant, index, seed=1, search_v_offset=false))]
fn candidate_gains(
    plant: &PyPlantFile,
    index: usize,
    seed: u64,
    search_v_offset: bool,
) -> PyResult<(Vec<f64>, f64, f64, f64)> {
    let coils = coils(&plant.file)?;
    let g = tune::candidates(coils, index + 1, seed, search_v_offset).swap_remove(index);
    Ok((
        g.kp_v_per_deg,
        g.ki_v_per_deg_s,
        g.integral_limit_v,
        g.v_offset_v,
    ))
}

fn coils(file: &PlantFile) -> PyResult<usize> {
    Ok(match file.params().map_err(input)? {
        host_tools::files::plant::PlantParams::TwoD(_) => 2,
        host_tools::files::plant::PlantParams::ThreeD(_) => 4,
    })
}

/// The cost of one run of `tune`'s step test with these gains on plant
/// `plant_index` of the `plants` that a search with `seed` draws (0: the
/// identified plant), as a dict of the gains file's `RunCost` fields.
#[pyfunction]
#[pyo3(signature = (plant, kp_v_per_deg, ki_v_per_deg_s, integral_limit_v, v_offset_v, plant_index=0, plants=1, seed=1))]
#[allow(clippy::too_many_arguments)]
fn tune_cost(
    py: Python<'_>,
    plant: &PyPlantFile,
    kp_v_per_deg: Vec<f64>,
    ki_v_per_deg_s: f64,
    integral_limit_v: f64,
    v_offset_v: f64,
    plant_index: usize,
    plants: usize,
    seed: u64,
) -> PyResult<String> {
    let gains = Gains {
        kp_v_per_deg,
        ki_v_per_deg_s,
        integral_limit_v,
        v_offset_v,
    };
    if gains.kp_v_per_deg.len() != coils(&plant.file)? {
        return Err(input(anyhow::anyhow!(
            "kp_v_per_deg: {} values for a joint of {} coils",
            gains.kp_v_per_deg.len(),
            coils(&plant.file)?
        )));
    }
    if plant_index >= plants.max(1) {
        return Err(input(anyhow::anyhow!(
            "plant_index {plant_index}: a search with plants = {plants} has plants 0–{}",
            plants.max(1) - 1
        )));
    }
    let file = &plant.file;
    let cost = py
        .detach(|| -> anyhow::Result<_> {
            let drawn = tune::sample_plants(file, plants.max(1), seed)?;
            let joint = match drawn[plant_index] {
                host_tools::files::plant::PlantParams::TwoD(_) => JointKind::TwoD,
                host_tools::files::plant::PlantParams::ThreeD(_) => JointKind::ThreeD,
            };
            let scenario = tune::test_scenario(joint, &gains, drawn[plant_index].clone(), seed);
            tune::evaluate(&RunSpec::resolve(&scenario)?)
        })
        .map_err(to_py)?;
    output::json("the run's cost", &cost).map_err(to_py)
}

/// A unit's scored candidates as TOML text: Rust's float text reads back
/// as the same bits, so a reduction on another machine sees the scores
/// the unit made.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct UnitScores {
    unit: usize,
    #[serde(default)]
    scored: Vec<Scored>,
}

/// `softjoint tune` as a sweep: its work units and its reduction.
#[pyclass(name = "TuneSweep", module = "softjoint._native", frozen)]
pub struct PyTuneSweep {
    sweep: TuneSweep,
    plant_name: String,
    /// The plant file's text (a search state's fingerprint is of it).
    plant_text: String,
}

/// The scored candidates of units' results (any order), in index order.
/// The held-out units' results (TOML text each, as `run_heldout_unit`
/// returns them).
fn heldout_of(units: &[String]) -> PyResult<Vec<tune::HeldOutScored>> {
    units
        .iter()
        .enumerate()
        .map(|(k, text)| {
            toml::from_str(text)
                .map_err(|e| SweepError::new_err(format!("held-out unit result {k}: {e}")))
        })
        .collect()
}

fn scored_of(units: &[String]) -> PyResult<Vec<Scored>> {
    let mut scored = Vec::new();
    for (k, text) in units.iter().enumerate() {
        let u: UnitScores = toml::from_str(text)
            .map_err(|e| SweepError::new_err(format!("unit result {k}: {e}")))?;
        scored.extend(u.scored);
    }
    scored.sort_by_key(|s| s.index);
    Ok(scored)
}

impl PyTuneSweep {
    /// The search state of the units' results (see `state`).
    fn search_state(&self, units: &[String]) -> PyResult<tune::SearchState> {
        let coils = match self.sweep.joint() {
            JointKind::TwoD => 2,
            JointKind::ThreeD => 4,
        };
        Ok(tune::SearchState::new(
            &self.plant_name,
            self.plant_text.as_bytes(),
            self.sweep.request(),
            coils,
            scored_of(units)?,
        ))
    }
}

#[pymethods]
impl PyTuneSweep {
    /// The sweep of `candidates` gains on `plants` plants of `plant`
    /// (`softjoint tune PLANT --candidates --plants --seed
    /// [--search-v-offset]`).
    #[new]
    #[pyo3(signature = (plant, candidates, plants, seed=1, search_v_offset=false))]
    fn new(
        plant: &PyPlantFile,
        candidates: usize,
        plants: usize,
        seed: u64,
        search_v_offset: bool,
    ) -> PyResult<Self> {
        if candidates == 0 || plants == 0 {
            return Err(input(anyhow::anyhow!(
                "candidates and plants must be at least 1 (got {candidates}, {plants})"
            )));
        }
        let req = request(candidates, plants, seed, search_v_offset);
        let sweep = TuneSweep::new(&plant.file, req).map_err(input)?;
        Ok(Self {
            sweep,
            plant_name: plant.name.clone(),
            plant_text: plant.text.clone(),
        })
    }

    /// The request: `(candidates, plants, seed, search_v_offset)`.
    fn request(&self) -> (usize, usize, u64, bool) {
        let r = self.sweep.request();
        (r.candidates, r.plants, r.seed, r.search_v_offset)
    }

    /// The work units of `size` candidates as `(index, start, end)`.
    #[pyo3(signature = (size=tune::UNIT_CANDIDATES))]
    fn units(&self, size: usize) -> Vec<(usize, usize, usize)> {
        self.sweep
            .units(size)
            .into_iter()
            .map(|u| (u.index, u.start, u.end))
            .collect()
    }

    /// Scores unit `(index, start, end)`'s candidates; returns them as
    /// text for [`reduce`](Self::reduce).
    fn run_unit(&self, py: Python<'_>, index: usize, start: usize, end: usize) -> PyResult<String> {
        let unit = TuneUnit { index, start, end };
        if start >= end || end > self.sweep.request().candidates.max(1) {
            return Err(input(anyhow::anyhow!(
                "unit {index} ({start}..{end}) is not within the sweep's {} candidates",
                self.sweep.request().candidates
            )));
        }
        let sweep = &self.sweep;
        let scored = py.detach(|| sweep.run_unit(unit, &|_| false, &Stop::never()));
        toml::to_string(&UnitScores {
            unit: index,
            scored,
        })
        .map_err(|e| SweepError::new_err(format!("unit {index}: {e}")))
    }

    /// The search's winner among the units' results (any order): the
    /// candidate index the held-out units are run for.
    fn best_index(&self, units: Vec<String>) -> PyResult<usize> {
        let scored = scored_of(&units)?;
        self.sweep
            .best_index(&scored)
            .map_err(|e| SweepError::new_err(format!("{e:#}")))
    }

    /// The held-out check's units (the Monte Carlo over plants drawn
    /// anew from the plant file's uncertainty) as `(manoeuvre, gains)`:
    /// each manoeuvre, the tuned gains (0) and the paper's (1).
    fn heldout_units(&self) -> Vec<(usize, usize)> {
        self.sweep
            .heldout_units()
            .into_iter()
            .map(|u| (u.manoeuvre, u.gains))
            .collect()
    }

    /// Runs held-out unit `(manoeuvre, gains)` for the winner `best`;
    /// returns its score as text for `reduce(units, heldout)` and
    /// `merge(units, heldout)`.
    fn run_heldout_unit(
        &self,
        py: Python<'_>,
        best: usize,
        manoeuvre: usize,
        gains: usize,
    ) -> PyResult<String> {
        let sweep = &self.sweep;
        let unit = tune::HeldOutUnit { manoeuvre, gains };
        let h = py
            .detach(|| sweep.run_heldout_unit(best, unit))
            .map_err(|e| SweepError::new_err(format!("{e:#}")))?;
        toml::to_string(&h).map_err(|e| SweepError::new_err(format!("held-out unit: {e}")))
    }

    /// The units' results (any order) merged into one scored-candidates
    /// file (`host_tools::joint::tune::ScoredFile`, TOML) for `softjoint
    /// tune --ray` to reduce.
    #[pyo3(signature = (units, heldout=Vec::new()))]
    fn merge(&self, units: Vec<String>, heldout: Vec<String>) -> PyResult<String> {
        let scored = scored_of(&units)?;
        let heldout = heldout_of(&heldout)?;
        toml::to_string(&tune::ScoredFile { scored, heldout })
            .map_err(|e| SweepError::new_err(format!("the merged units: {e}")))
    }

    /// The search state of a sweep stopped with these units' results
    /// (any order) finished, as TOML: the file `softjoint tune` writes
    /// when stopped (`host_tools::joint::tune::SearchState`: the plant
    /// file's name and fingerprint, the request, the best so far with its
    /// gains, every candidate scored), which `softjoint tune PLANT
    /// --resume FILE` goes on from.
    fn state(&self, units: Vec<String>) -> PyResult<String> {
        let state = self.search_state(&units)?;
        output::toml("the search state", tune::STATE_HEADER, &state).map_err(to_py)
    }

    /// Writes [`state`](Self::state) to `path` as the program writes its
    /// files (atomically: a file is replaced whole or not at all; a
    /// symbolic link is followed, a device or FIFO written through).
    /// Returns what it holds for a message: `(candidates scored, best
    /// candidate's index, its robust cost)` (`None`s: none scored).
    fn write_state(
        &self,
        units: Vec<String>,
        path: PathBuf,
    ) -> PyResult<(usize, Option<usize>, Option<f64>)> {
        let state = self.search_state(&units)?;
        output::write_toml(&path, tune::STATE_HEADER, &state).map_err(to_py)?;
        let best = state.best.as_ref();
        Ok((
            state.scored.len(),
            best.map(|b| b.index),
            best.map(|b| b.robust_cost),
        ))
    }

    /// The reduction of the units' results (any order): returns the
    /// `--json` output of `softjoint tune` without its wall time, as text
    /// (`gains`, `failed_candidates`, `rejected_early`,
    /// `heldout_beats_or_ties_paper`). With `heldout` (every held-out
    /// unit's result for the winner), the held-out check is taken from
    /// them; without it, it runs here.
    #[pyo3(signature = (units, heldout=None))]
    fn reduce(
        &self,
        py: Python<'_>,
        units: Vec<String>,
        heldout: Option<Vec<String>>,
    ) -> PyResult<String> {
        let scored = scored_of(&units)?;
        let heldout = heldout.map(|h| heldout_of(&h)).transpose()?;
        let sweep = &self.sweep;
        let r = py
            .detach(|| sweep.reduce_with(&scored, heldout.as_deref()))
            .map_err(|e| SweepError::new_err(format!("{e:#}")))?;
        let g = r.gains_file(&self.plant_name, sweep.joint(), sweep.request());
        let out = serde_json::json!({
            "gains": g,
            "failed_candidates": r.failed,
            "rejected_early": r.rejected,
            "heldout_beats_or_ties_paper": r.heldout.beats_or_ties_paper,
        });
        output::json("the sweep's result", &out).map_err(to_py)
    }
}
