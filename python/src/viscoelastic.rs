//! The 3-element viscoelastic model (seed 002, Eq. 3) from Python: what
//! `softjoint viscoelastic simulate` does — `plant_viscoelastic`'s
//! `simulate_table` on a CSV of `time_s,displacement` (m → force, N) or
//! `time_s,force` (N → displacement, m) — with the trace as NumPy arrays;
//! and what `softjoint viscoelastic fit` does — (k1, k2, b) fitted to a
//! trial by `host_tools::visco_fit`, the program's code, with its `--json`
//! summary and the fitted force; and `softjoint viscoelastic object`'s
//! run (`host_tools::visco_object`, the program's code) with its files'
//! columns as arrays.
use host_tools::output;
use host_tools::visco_fit::{fit_summary, fit_trial_text};
use host_tools::visco_object::{run_object, ObjectJob};
use numpy::{PyArray1, ToPyArray};
use plant_viscoelastic::experiment::trial::{simulate_table, ThreeElementParams};
use plant_viscoelastic::fit::{simulate_force, Weighting};
use plant_viscoelastic::io::read_table;
use pyo3::prelude::*;

use crate::arrays::{py_columns, PyColumns};
use crate::errors::{input, to_py};

/// Adds the viscoelastic functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(viscoelastic_simulate, m)?)?;
    m.add_function(wrap_pyfunction!(viscoelastic_fit, m)?)?;
    m.add_function(wrap_pyfunction!(viscoelastic_object, m)?)?;
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

/// Runs `softjoint viscoelastic object` on a mesh (`mesh`: an OBJ's text
/// and name; `None`: the shipped blob) with a probe script (`script`: a
/// CSV's text and name; `None`: 1 N down on the top vertex for 0.5 s).
/// Returns the printed figures as JSON text, haptic.csv's columns,
/// frames.csv's as `time_s` per frame and displacements and forces flat
/// (frame, vertex, x/y/z), and params.csv's columns.
#[pyfunction]
#[pyo3(signature = (mesh=None, script=None, duration_s=1.5, probe_every=10, seed=1, tensor=false))]
#[allow(clippy::type_complexity)]
fn viscoelastic_object<'py>(
    py: Python<'py>,
    mesh: Option<(String, String)>,
    script: Option<(String, String)>,
    duration_s: f64,
    probe_every: usize,
    seed: u64,
    tensor: bool,
) -> PyResult<(String, PyColumns<'py>, PyColumns<'py>, PyColumns<'py>)> {
    let job = ObjectJob {
        duration_s,
        probe_every,
        seed,
        tensor,
    };
    let o = py
        .detach(|| {
            run_object(
                mesh.as_ref().map(|(t, n)| (t.as_str(), n.as_str())),
                script.as_ref().map(|(t, n)| (t.as_str(), n.as_str())),
                &job,
                &mut |_| {},
            )
        })
        .map_err(input)?;
    let json = output::json("the object run's figures", &o.figures()).map_err(to_py)?;
    let run = &o.run;
    let mut haptic: Vec<(&'static str, Vec<f64>)> = [
        "time_s",
        "fx_n",
        "fy_n",
        "fz_n",
        "ux_m",
        "uy_m",
        "uz_m",
        "exact_ux_m",
        "exact_uy_m",
        "exact_uz_m",
    ]
    .into_iter()
    .map(|k| (k, Vec::with_capacity(run.samples.len())))
    .collect();
    for (s, e) in run.samples.iter().zip(&run.exact_samples) {
        let (f, u, x) = (
            s.force_n,
            s.contact_displacement_m,
            e.contact_displacement_m,
        );
        let row = [
            s.time_s, f[0], f[1], f[2], u[0], u[1], u[2], x[0], x[1], x[2],
        ];
        for ((_, col), v) in haptic.iter_mut().zip(row) {
            col.push(v);
        }
    }
    let mut frames: Vec<(&'static str, Vec<f64>)> = vec![
        ("time_s", Vec::new()),
        ("displacement_m", Vec::new()),
        ("force_n", Vec::new()),
    ];
    for fr in &run.frames {
        frames[0].1.push(fr.time_s);
        frames[1].1.extend(fr.displacement_m.iter().flatten());
        frames[2].1.extend(fr.force_n.iter().flatten());
    }
    let params = vec![
        (
            "fixed",
            o.dgfm
                .fixed()
                .iter()
                .map(|&f| f64::from(u8::from(f)))
                .collect(),
        ),
        (
            "damping_magnitude_n_s_per_m",
            o.identified.damping_per_vertex_n_s_per_m.clone(),
        ),
    ];
    Ok((
        json,
        py_columns(py, "the haptic trace", haptic)?,
        py_columns(py, "the display frames", frames)?,
        py_columns(py, "the per-vertex parameters", params)?,
    ))
}
