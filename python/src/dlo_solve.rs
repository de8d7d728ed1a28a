//! Static wires and belts (Wakamatsu et al., seed 000) from Python: what
//! `softjoint dlo solve` does — `plant_dlo`'s `StaticProblem::solve` on a
//! TOML problem — with the solve's summary and checks
//! (`host_tools::dlo_solve`, the program's) and each solved shape's
//! columns, shape.csv's, as NumPy arrays.
use std::collections::BTreeMap;

use host_tools::dlo_solve::{solve_summary, unverified};
use host_tools::output;
use numpy::{PyArray1, ToPyArray};
use plant_dlo::wire::belt::BeltShape;
use plant_dlo::wire::problem::{StaticProblem, StaticSolution};
use plant_dlo::wire::WireShape;
use pyo3::prelude::*;

use crate::errors::{input, to_py, SoftjointError};

/// Adds the solve to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(dlo_solve, m)?)?;
    Ok(())
}

/// A solved shape: its name (`wire`, `belt`, or `knot_free` / `one_knot`
/// of a sequence), the end distance of a sequence's step (fraction of
/// L), and shape.csv's columns.
type PyShape<'py> = (
    &'static str,
    Option<f64>,
    BTreeMap<&'static str, Bound<'py, PyArray1<f64>>>,
);

/// Columns as shape.csv names them.
type Columns = Vec<(&'static str, Vec<f64>)>;

fn wire_columns(sh: &WireShape) -> Columns {
    let x = |k: usize| sh.x_m.iter().map(|p| [p.x, p.y, p.z][k]).collect();
    let e = |k: usize| sh.euler_rad.iter().map(|a| a[k]).collect();
    vec![
        ("s_m", sh.s_m.clone()),
        ("x_m", x(0)),
        ("y_m", x(1)),
        ("z_m", x(2)),
        ("phi_rad", e(0)),
        ("theta_rad", e(1)),
        ("psi_rad", e(2)),
        ("strain", sh.strain.clone()),
    ]
}

fn belt_columns(b: &BeltShape) -> Columns {
    let of = |v: &[plant_dlo::rope::V3], k: usize| v.iter().map(|p| [p.x, p.y, p.z][k]).collect();
    vec![
        ("u_m", b.u_m.clone()),
        ("spine_x_m", of(&b.spine_m, 0)),
        ("spine_y_m", of(&b.spine_m, 1)),
        ("spine_z_m", of(&b.spine_m, 2)),
        ("edge1_x_m", of(&b.edges_m[0], 0)),
        ("edge1_y_m", of(&b.edges_m[0], 1)),
        ("edge1_z_m", of(&b.edges_m[0], 2)),
        ("edge2_x_m", of(&b.edges_m[1], 0)),
        ("edge2_y_m", of(&b.edges_m[1], 1)),
        ("edge2_z_m", of(&b.edges_m[1], 2)),
        ("beta", b.beta.clone()),
    ]
}

/// Solves a problem's TOML text (`name` names it in errors) as `softjoint
/// dlo solve` does. Returns the `--json` summary as JSON text (without
/// `solve_s`, a timing, and the file names), why the answer is not
/// verified (`None` when every shape passed its checks; the program then
/// exits 1), and the solved shapes.
#[pyfunction]
#[pyo3(signature = (text, name="problem.toml"))]
fn dlo_solve<'py>(
    py: Python<'py>,
    text: &str,
    name: &str,
) -> PyResult<(String, Option<String>, Vec<PyShape<'py>>)> {
    let problem: StaticProblem = toml::from_str(plant_common::strip_bom(text))
        .map_err(|e| input(anyhow::anyhow!("{name}: {}", e.to_string().trim_end())))?;
    let solution = py
        .detach(|| problem.solve())
        .map_err(|e| solve_error(name, e))?;
    let summary = solve_summary(&solution).map_err(to_py)?;
    let json = output::json("the solve's summary", &summary).map_err(to_py)?;
    let shapes: Vec<(&'static str, Option<f64>, Columns)> = match &solution {
        StaticSolution::Wire { shape, .. } => vec![("wire", None, wire_columns(shape))],
        StaticSolution::Belt { shape, .. } => vec![("belt", None, belt_columns(shape))],
        StaticSolution::Sequence { steps, .. } => steps
            .iter()
            .flat_map(|st| {
                [
                    ("knot_free", Some(st.l_fraction), wire_columns(&st.free)),
                    ("one_knot", Some(st.l_fraction), wire_columns(&st.knot)),
                ]
            })
            .collect(),
    };
    let mut out = Vec::with_capacity(shapes.len());
    for (shape, l, columns) in shapes {
        output::check_value("the solved shape", &columns).map_err(to_py)?;
        let arrays = columns
            .into_iter()
            .map(|(k, v)| (k, v.to_pyarray(py)))
            .collect();
        out.push((shape, l, arrays));
    }
    let why = unverified(&solution).map(|why| format!("{name}: UNVERIFIED: {why}"));
    Ok((json, why, out))
}

/// A solve's error: a refused problem (a field, a parameter) as
/// `InputError`, a solve that did not converge as `SoftjointError`.
fn solve_error(name: &str, e: plant_dlo::error::DloError) -> PyErr {
    let msg = format!("{name}: {e}");
    match e {
        plant_dlo::error::DloError::NotConverged(_) => SoftjointError::new_err(msg),
        _ => input(anyhow::anyhow!(msg)),
    }
}
