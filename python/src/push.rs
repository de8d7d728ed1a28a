//! Deformable blocks under robotic pushing (Arriola-Rios & Wyatt, the
//! seed's system 001) from Python: the push prepared as `softjoint push` prepares it
//! (`host_tools::push`, the program's code: the ground truth recorded or
//! a video CSV read, the grid and settings checked), the mass-spring
//! model run on it and scored as `push simulate` does
//! (`plant_pushing::experiment`), and the fitness `push calibrate`'s
//! search maximises for one parameter set (`experiment::fitness`).
use host_tools::output;
use host_tools::push::{self, Material, ModelGrid, PushSource};
use numpy::{PyArray1, ToPyArray};
use plant_pushing::evaluate::PreparedVideo;
use plant_pushing::experiment::{self, ScoreKind, SimulateSpec, Tracking};
use plant_pushing::forces::MaterialParams;
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};
use pyo3::prelude::*;
use std::collections::BTreeMap;

use crate::errors::{input, to_py, NonFiniteError};

/// Adds the push class to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPushProblem>()?;
    Ok(())
}

/// Settings are named as the Python arguments are (`nx`, `ref_element_px`).
fn name(n: &str) -> String {
    n.to_string()
}

fn integrator(name: &str) -> PyResult<Integrator> {
    Integrator::from_name(name).ok_or_else(|| {
        input(anyhow::anyhow!(
            "integrator {name:?}: give \"customised\", \"euler\", \"verlet\" or \"customised-seq\""
        ))
    })
}

fn mode(name: &str) -> PyResult<DrivingMode> {
    [
        DrivingMode::CollisionOnly,
        DrivingMode::ForcesOnVertices,
        DrivingMode::CollisionAndForces,
    ]
    .into_iter()
    .find(|m| m.name() == name)
    .ok_or_else(|| {
        input(anyhow::anyhow!(
            "mode {name:?}: give \"collision\", \"forces\" or \"both\""
        ))
    })
}

fn score(name: &str) -> PyResult<ScoreKind> {
    match name {
        "f" => Ok(ScoreKind::F),
        "contour" => Ok(ScoreKind::Contour),
        _ => Err(input(anyhow::anyhow!(
            "score {name:?}: give \"f\" or \"contour\""
        ))),
    }
}

/// One push prepared for the model: the material pushed at a site (its
/// ground truth recorded, or a video CSV's contours and forces), the
/// model's grid and simulator settings, and the push's tracked contour.
#[pyclass(name = "PushProblem", module = "softjoint._native", frozen)]
pub struct PyPushProblem {
    material: Material,
    prep: PreparedVideo,
    tracking: Tracking,
    sim: SimConfig,
}

impl PyPushProblem {
    /// Parameters: `None` for the material's seed values, else JSON text
    /// (a bare parameter object or `calibrate`'s params.json) named `name`.
    fn params(&self, text: Option<&str>, name: &str) -> PyResult<MaterialParams> {
        match text {
            None => Ok(self.material.seed_params()),
            Some(t) => push::params_from_json(t, name).map_err(input),
        }
    }
}

#[pymethods]
impl PyPushProblem {
    /// The push of `softjoint push simulate` with the same flags:
    /// `material` (`sponge`, `plasticine`), `site` (`middle-long`,
    /// `corner`, `middle-short`), `video` as `(text, name)` of a
    /// `frame,force_n,x_px,y_px` CSV (else the ground truth recorded with
    /// `ref_element_px` elements and `noise_seed`), the model's `nx` ×
    /// `ny` mesh, the F-score's `cell_px`, `integrator`, `mode` and
    /// `repair`.
    #[new]
    #[pyo3(signature = (material="sponge", site="middle-long", video=None, ref_element_px=8.0,
                        noise_seed=1, integrator="customised", mode="both", nx=20, ny=10,
                        cell_px=1.0, repair=true))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        material: &str,
        site: &str,
        video: Option<(String, String)>,
        ref_element_px: f64,
        noise_seed: u64,
        integrator: &str,
        mode: &str,
        nx: usize,
        ny: usize,
        cell_px: f64,
        repair: bool,
    ) -> PyResult<Self> {
        let material = Material::from_name(material).ok_or_else(|| {
            input(anyhow::anyhow!(
                "material {material:?}: give \"sponge\" or \"plasticine\""
            ))
        })?;
        let site = push::site_from_name(site).ok_or_else(|| {
            input(anyhow::anyhow!(
                "site {site:?}: give \"middle-long\", \"corner\" or \"middle-short\""
            ))
        })?;
        let sim = push::sim_config(self::integrator(integrator)?, self::mode(mode)?, repair);
        let src = PushSource {
            material,
            site,
            video: video.as_ref().map(|(t, n)| (t.as_str(), n.as_str())),
            ref_element_px,
            noise_seed,
        };
        let grid = ModelGrid { nx, ny, cell_px };
        let (prep, tracking) = py
            .detach(|| -> anyhow::Result<_> {
                let prep = push::prepare(&src, &grid, &name, true)?;
                let tracking = Tracking::of(&prep)?;
                Ok((prep, tracking))
            })
            .map_err(input)?;
        Ok(Self {
            material,
            prep,
            tracking,
            sim,
        })
    }

    /// Frames of the push.
    fn frames(&self) -> usize {
        self.prep.frame_count()
    }

    /// Runs the model with `params` (JSON text named `params_name`;
    /// `None`: the material's seed values) through the push and scores it
    /// as `softjoint push simulate` does, driven by the sensed forces or,
    /// with `predicted_forces`, by the force predictor learned on the push.
    /// Returns the `--json` summary as JSON text (without `out`), each
    /// frame's phase, and frames.csv's numeric columns.
    #[pyo3(signature = (params=None, params_name="params", predicted_forces=false))]
    #[allow(clippy::type_complexity)]
    fn simulate<'py>(
        &self,
        py: Python<'py>,
        params: Option<&str>,
        params_name: &str,
        predicted_forces: bool,
    ) -> PyResult<(
        String,
        Vec<&'static str>,
        BTreeMap<&'static str, Bound<'py, PyArray1<f64>>>,
    )> {
        let spec = SimulateSpec {
            params: self.params(params, params_name)?,
            sim: self.sim,
            predicted_forces,
        };
        let report = py
            .detach(|| -> anyhow::Result<_> {
                let run = experiment::run_model(&self.prep, &spec, &mut |_| {})?;
                Ok(experiment::assess(&self.prep, &spec, run)?)
            })
            .map_err(input)?;
        let json = output::json("the push simulation's summary", &report).map_err(to_py)?;
        let table = push::frame_table(&self.prep, &report);
        output::check_value("the push's frame table", &table.columns).map_err(to_py)?;
        let columns = table
            .columns
            .into_iter()
            .map(|(k, v)| (k, v.to_pyarray(py)))
            .collect();
        Ok((json, table.phase, columns))
    }

    /// The fitness `softjoint push calibrate --score SCORE` maximises for
    /// `params` (JSON text named `params_name`): μ(F) for `"f"`, minus the
    /// mean contour distance in the finger's reach (px) for `"contour"`.
    /// A run that cannot be scored raises `NonFiniteError` (the search
    /// counts it failed).
    #[pyo3(signature = (params, score="f", params_name="params"))]
    fn objective(
        &self,
        py: Python<'_>,
        params: &str,
        score: &str,
        params_name: &str,
    ) -> PyResult<f64> {
        let kind = self::score(score)?;
        let p = self.params(Some(params), params_name)?;
        let v = py
            .detach(|| experiment::fitness(&self.prep, &self.tracking.target, kind, &self.sim, &p));
        if !v.is_finite() {
            return Err(NonFiniteError::new_err(format!(
                "the push's fitness ({score}) for {params_name} is {v}: the model's run could not be scored"
            )));
        }
        Ok(v)
    }

    /// The fitness `softjoint push calibrate --score SCORE` maximises for
    /// each gene vector of `genes` (the eight parameters in params.json's
    /// order: k_d, k_L, k_A, k_φ, max(F), max α, yield, creep), in order,
    /// as the program scores a generation's candidates: a run that cannot
    /// be scored gives NaN (the search ranks it last), not an error. What
    /// `softjoint push calibrate --ray` has its Ray tasks run.
    #[pyo3(signature = (genes, score="f"))]
    fn scores(&self, py: Python<'_>, genes: Vec<Vec<f64>>, score: &str) -> PyResult<Vec<f64>> {
        let kind = self::score(score)?;
        let mut params = Vec::with_capacity(genes.len());
        for (i, g) in genes.iter().enumerate() {
            let Ok(a) = <[f64; 8]>::try_from(g.as_slice()) else {
                return Err(input(anyhow::anyhow!(
                    "genes[{i}]: {} values, the push's candidates have 8",
                    g.len()
                )));
            };
            params.push(MaterialParams::from_array(a));
        }
        Ok(py.detach(|| {
            params
                .iter()
                .map(|p| {
                    let v =
                        experiment::fitness(&self.prep, &self.tracking.target, kind, &self.sim, p);
                    if v.is_finite() {
                        v
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        }))
    }
}
