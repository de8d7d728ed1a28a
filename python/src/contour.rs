//! Contour fits from Python: what `softjoint contour fit` does — periodic
//! or closed smoothing splines (Fujioka & Kano, seed 000) fitted to
//! tracked contour points by `plant_contour`'s `fit_contours` — with the
//! fit's own checks (verified or not and why, λ, GCV) handed back beside
//! the fitted contours; and the test cases `softjoint contour synth`
//! writes (`host_tools::contour_synth`, the program's). Files and
//! pictures stay the program's.
use host_tools::contour_synth as synth;
use host_tools::output;
use numpy::{PyArray1, ToPyArray};
use plant_contour::fit::Solver;
use plant_contour::identify::contours::{fit_contours, ContourFitSpec, ContourModel};
use plant_contour::identify::data::read_contour_csv;
use plant_contour::identify::gcv::{Lambda, MAX_LAMBDA};
use pyo3::prelude::*;

use crate::arrays::{py_columns, PyColumns};
use crate::errors::{input, to_py};

/// Adds the contour functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(contour_fit, m)?)?;
    m.add_function(wrap_pyfunction!(contour_synth, m)?)?;
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

/// The test case `case` (`"rbc"`: Eq. 38 on an `n` × `n` grid; `"movie"`:
/// the pulsating contour observed along `angles` rays every `every`-th
/// frame) with noise `sigma` (`None`: the case's default) seeded by
/// `seed`, as `softjoint contour synth` writes it. Returns the summary's
/// figures as JSON text (`case`, `frames`, `points_per_frame`, `sigma`,
/// `seed`), data.csv's columns and truth.csv's.
#[pyfunction]
#[pyo3(signature = (case, n=40, sigma=None, every=10, angles=10, seed=1))]
#[allow(clippy::type_complexity)]
fn contour_synth<'py>(
    py: Python<'py>,
    case: &str,
    n: usize,
    sigma: Option<f64>,
    every: usize,
    angles: usize,
    seed: u64,
) -> PyResult<(String, PyColumns<'py>, PyColumns<'py>)> {
    let (figures, data, truth) = match case {
        "rbc" => {
            let (figures, frames) = synth::rbc(n, sigma, seed).map_err(input)?;
            let polar =
                |of: &dyn Fn(&plant_contour::identify::synth::RbcFrame) -> &Vec<(f64, f64)>| {
                    let mut c = (Vec::new(), Vec::new(), Vec::new());
                    for (i, f) in frames.iter().enumerate() {
                        for (th, r) in of(f) {
                            c.0.push(i as f64);
                            c.1.push(*th);
                            c.2.push(*r);
                        }
                    }
                    vec![("frame", c.0), ("angle_rad", c.1), ("radius", c.2)]
                };
            (figures, polar(&|f| &f.data), polar(&|f| &f.truth))
        }
        "movie" => {
            let (figures, mc) = synth::movie(every, angles, sigma, seed).map_err(input)?;
            let (mut d, mut t) = (vec![Vec::new(); 5], vec![Vec::new(); 3]);
            for f in &mc.frames {
                let frame = f.frame as f64;
                for p in &f.truth {
                    t[0].push(frame);
                    t[1].push(p.0);
                    t[2].push(p.1);
                }
                if let Some(sig) = &f.observed {
                    for (th, r) in sig.angles_rad.iter().zip(&sig.radii) {
                        for (col, v) in
                            d.iter_mut()
                                .zip([frame, sig.centre.0, sig.centre.1, *th, *r])
                        {
                            col.push(v);
                        }
                    }
                }
            }
            let names = ["frame", "centre_x", "centre_y", "angle_rad", "radius"];
            (
                figures,
                names.into_iter().zip(d).collect(),
                ["frame", "x", "y"].into_iter().zip(t).collect(),
            )
        }
        _ => {
            return Err(input(anyhow::anyhow!(
                "case {case:?}: give \"rbc\" or \"movie\""
            )))
        }
    };
    let json = output::json("the synth's summary", &figures).map_err(to_py)?;
    Ok((
        json,
        py_columns(py, "the synth's data", data)?,
        py_columns(py, "the synth's truth", truth)?,
    ))
}
