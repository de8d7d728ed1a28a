//! Contour fits from Python: what `softjoint contour fit` does — periodic
//! or closed smoothing splines (Fujioka & Kano, seed 000) fitted to
//! tracked contour points by `plant_contour`'s `fit_contours` — with the
//! fit's own checks (verified or not and why, λ, GCV) handed back beside
//! the fitted contours. Files and pictures stay the program's.
use host_tools::output;
use numpy::{PyArray1, ToPyArray};
use plant_contour::fit::Solver;
use plant_contour::identify::contours::{fit_contours, ContourFitSpec, ContourModel};
use plant_contour::identify::data::read_contour_csv;
use plant_contour::identify::gcv::{Lambda, MAX_LAMBDA};
use pyo3::prelude::*;

use crate::errors::{input, to_py};

/// Adds the contour functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(contour_fit, m)?)?;
    Ok(())
}

/// One fitted frame as NumPy arrays: `(frame, x, y, angle_rad, radius)`
/// (angle and radius `None` for a closed curve).
type PyFrame<'py> = (
    f64,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Option<Bound<'py, PyArray1<f64>>>,
    Option<Bound<'py, PyArray1<f64>>>,
);

fn model(name: Option<&str>) -> PyResult<Option<ContourModel>> {
    match name {
        None => Ok(None),
        Some("signature") => Ok(Some(ContourModel::Signature)),
        Some("curve") => Ok(Some(ContourModel::Curve)),
        Some("surface") => Ok(Some(ContourModel::Surface)),
        Some(m) => Err(input(anyhow::anyhow!(
            "model {m:?}: give \"signature\", \"curve\" or \"surface\""
        ))),
    }
}

fn solver(name: &str) -> PyResult<Solver> {
    match name {
        "reduced" => Ok(Solver::Reduced),
        "kkt" => Ok(Solver::Kkt),
        _ => Err(input(anyhow::anyhow!(
            "solver {name:?}: give \"reduced\" or \"kkt\""
        ))),
    }
}

/// `None` is GCV; a number must be as `--lambda` takes it.
fn lambda(value: Option<f64>) -> PyResult<Lambda> {
    match value {
        None => Ok(Lambda::Gcv),
        Some(v) if v.is_finite() && v > 0.0 && v <= MAX_LAMBDA => Ok(Lambda::Fixed(v)),
        Some(v) => Err(input(anyhow::anyhow!(
            "lambda {v}: λ must be a number > 0 and ≤ {MAX_LAMBDA:e} (or None for GCV)"
        ))),
    }
}

/// Fits the contour points of a CSV's text (`name` names it in errors)
/// as `softjoint contour fit` does with the same options, and returns
/// the fit's figures as JSON text (the fields of fit.json: `status`,
/// `unverified_frames`, λ and GCV reports, `per_frame` with each frame's
/// `checks`) and the fitted frames as arrays.
#[pyfunction]
#[pyo3(signature = (text, name="contour.csv", model=None, knots=None, time_knots=None,
                    lambda_=None, solver="reduced", samples=200, signed_radii=false))]
#[allow(clippy::too_many_arguments)]
fn contour_fit<'py>(
    py: Python<'py>,
    text: &str,
    name: &str,
    model: Option<&str>,
    knots: Option<usize>,
    time_knots: Option<usize>,
    lambda_: Option<f64>,
    solver: &str,
    samples: usize,
    signed_radii: bool,
) -> PyResult<(String, Vec<PyFrame<'py>>)> {
    let spec = ContourFitSpec {
        model: self::model(model)?,
        knots,
        time_knots,
        lambda: lambda(lambda_)?,
        solver: self::solver(solver)?,
        samples,
        signed_radii,
    };
    if !(3..=100_000).contains(&samples) {
        return Err(input(anyhow::anyhow!(
            "samples must be 3..=100000, got {samples}"
        )));
    }
    let data = read_contour_csv(text, name).map_err(|e| input(e.into()))?;
    if spec.model == Some(ContourModel::Surface) && data.frames.len() < 2 {
        return Err(input(anyhow::anyhow!(
            "{name}: model surface needs at least two frames (column `frame`), found one"
        )));
    }
    let fit = py
        .detach(|| fit_contours(&data, &spec))
        .map_err(|e| input(e.into()))?;
    // fit.json's figures (the command adds its units, input and files).
    let summary = fit.figures(data.frames.len(), spec.solver);
    let json = output::json("the contour fit's summary", &summary).map_err(to_py)?;
    let mut frames = Vec::with_capacity(fit.frames.len());
    for f in &fit.frames {
        let (x, y): (Vec<f64>, Vec<f64>) = f.fit.iter().map(|p| (p.0, p.1)).unzip();
        output::check_value("the fitted contour", &(&x, &y, &f.angle, &f.radius)).map_err(to_py)?;
        frames.push((
            f.frame,
            x.to_pyarray(py),
            y.to_pyarray(py),
            f.angle.as_ref().map(|a| a.to_pyarray(py)),
            f.radius.as_ref().map(|r| r.to_pyarray(py)),
        ));
    }
    Ok((json, frames))
}
