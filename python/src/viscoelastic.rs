//! The 3-element viscoelastic model (seed 002, Eq. 3) from Python: what
//! `softjoint viscoelastic simulate` does — `plant_viscoelastic`'s
//! `simulate_table` on a CSV of `time_s,displacement` (m → force, N) or
//! `time_s,force` (N → displacement, m) — with the trace as NumPy arrays;
//! and what `softjoint viscoelastic fit` does — (k1, k2, b) fitted to a
//! trial by `host_tools::visco_fit`, the program's code, with its `--json`
//! summary and the fitted force.
use host_tools::output;
use host_tools::visco_fit::{fit_summary, fit_trial_text};
use numpy::{PyArray1, ToPyArray};
use plant_viscoelastic::experiment::trial::{simulate_table, ThreeElementParams};
use plant_viscoelastic::fit::{simulate_force, Weighting};
use plant_viscoelastic::io::read_table;
use pyo3::prelude::*;

use crate::errors::{input, to_py};

/// Adds the viscoelastic functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(viscoelastic_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(viscoelastic_fit, m)?)?;
    Ok(())
}

/// A model parameter as the program's flag takes it: finite and > 0 (or
/// ≥ 0 if `zero_ok`); the message names the argument.
fn check(name: &str, value: f64, zero_ok: bool, unit: &str) -> PyResult<()> {
    if value.is_finite() && (value > 0.0 || zero_ok && value == 0.0) {
        return Ok(());
    }
    let range = if zero_ok { ">= 0" } else { "> 0" };
    Err(input(anyhow::anyhow!(
        "{name} must be finite and {range} ({unit}), got {}",
        plant_common::short_number(value)
    )))
}

/// Runs the 3-element model (delayed spring `k1_n_per_m`, series spring
/// `k2_n_per_m`, dashpot `b_n_s_per_m`) on a CSV's text (`name` names it
/// in errors), as `softjoint viscoelastic simulate` does: returns
/// `(time_s, displacement_m, force_n)`.
#[pyfunction]
#[pyo3(signature = (text, k1_n_per_m, k2_n_per_m, b_n_s_per_m, name="trial.csv"))]
#[allow(clippy::type_complexity)]
fn viscoelastic_simulate<'py>(
    py: Python<'py>,
    text: &str,
    k1_n_per_m: f64,
    k2_n_per_m: f64,
    b_n_s_per_m: f64,
    name: &str,
) -> PyResult<(
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
)> {
    check("k1_n_per_m", k1_n_per_m, false, "N/m")?;
    check("k2_n_per_m", k2_n_per_m, false, "N/m")?;
    check("b_n_s_per_m", b_n_s_per_m, true, "N s/m")?;
    let text = plant_common::strip_bom(text);
    let table = read_table(text, name).map_err(|e| input(e.into()))?;
    let params = ThreeElementParams {
        k1_n_per_m,
        k2_n_per_m,
        b_n_s_per_m,
    };
    let trace = simulate_table(&table, name, params).map_err(|e| input(e.into()))?;
    output::check_value(
        "the viscoelastic trace",
        &(&trace.time_s, &trace.displacement_m, &trace.force_n),
    )
    .map_err(to_py)?;
    Ok((
        trace.time_s.to_pyarray(py),
        trace.displacement_m.to_pyarray(py),
        trace.force_n.to_pyarray(py),
    ))
}

/// Fits (k1, k2, b) to a trial CSV's text (`time_s,displacement,force`;
/// `name` names it in errors) as `softjoint viscoelastic fit` does
/// (`uniform`: every sample weighted alike, else the seed's weighting).
/// Returns the `--json` summary as JSON text and the fitted model's force
/// at the trial's samples (N), the curve of the program's `--plot`.
#[pyfunction]
#[pyo3(signature = (text, name="trial.csv", uniform=false))]
fn viscoelastic_fit<'py>(
    py: Python<'py>,
    text: &str,
    name: &str,
    uniform: bool,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>)> {
    let weighting = if uniform {
        Weighting::Uniform
    } else {
        Weighting::Seed
    };
    let (c, r) = py
        .detach(|| fit_trial_text(text, name, weighting))
        .map_err(input)?;
    let (t, u) = (&c.values[0], &c.values[1]);
    let summary = fit_summary(&r, weighting, t.len()).map_err(to_py)?;
    let json = output::json("the fit's summary", &summary).map_err(to_py)?;
    let fitted = simulate_force(r.k1_n_per_m, r.k2_n_per_m, r.b_n_s_per_m, t, u)
        .map_err(|e| input(e.into()))?;
    output::check_value("the fitted force", &fitted).map_err(to_py)?;
    Ok((json, fitted.to_pyarray(py)))
}
