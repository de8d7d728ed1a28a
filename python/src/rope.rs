//! The dynamic rope (Shi & Payandeh, seed 000) from Python: what
//! `softjoint dlo rope` does — `plant_dlo`'s scripted rope scenario run
//! to its end — with every frame's node positions as one array and the
//! run's figures and topology checks.
use host_tools::output;
use numpy::{PyArray1, ToPyArray};
use plant_dlo::error::DloError;
use plant_dlo::rope::script::RopeScenario;
use plant_dlo::rope::verify::RopeChecks;
use pyo3::prelude::*;

use crate::errors::{input, UnstableError};

/// Adds the rope functions to the module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(rope_simulate, m)?)?;
    Ok(())
}

/// A rope error of the scenario `source`: an unstable run as
/// `UnstableError`, anything else as a refused input.
fn rope_error(source: &str, e: DloError) -> PyErr {
    let msg = format!("{source}: {e}");
    match e {
        DloError::Unstable { .. } => UnstableError::new_err(msg),
        _ => input(anyhow::anyhow!(msg)),
    }
}

/// The built-in rope scenario, the file `softjoint dlo rope` embeds.
const OVERHAND_TOML: &str = include_str!("../../scenarios/dlo/overhand.toml");

/// Runs a rope scenario's TOML text (`None`: the built-in overhand knot;
/// `name` names it in errors) as `softjoint dlo rope` does (with
/// `check_step`, as `--check-step`: again at dt/2 for the time-step
/// check). Returns the `--json` summary's figures as JSON text (status,
/// self-checks, figures, topology checks; without `step_time_us`, a
/// timing, and the file names), the frames' times (s), and their node
/// positions, frame by frame, node by node, x, y, z (m), flat.
#[pyfunction]
#[pyo3(signature = (text=None, name="built-in overhand scenario", check_step=false))]
#[allow(clippy::type_complexity)]
fn rope_simulate<'py>(
    py: Python<'py>,
    text: Option<&str>,
    name: &str,
    check_step: bool,
) -> PyResult<(String, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>)> {
    let scenario: RopeScenario = toml::from_str(text.unwrap_or(OVERHAND_TOML))
        .map_err(|e| input(anyhow::anyhow!("{name}: {}", e.to_string().trim_end())))?;
    scenario.validate().map_err(|e| rope_error(name, e))?;
    let mut time_s = Vec::new();
    let mut nodes_m = Vec::new();
    let (result, half) = py.detach(|| {
        let result = scenario
            .run(|f| {
                time_s.push(f.time_s);
                for p in &f.x {
                    nodes_m.extend([p.x, p.y, p.z]);
                }
            })
            .map_err(|e| rope_error(name, e))?;
        let half = if check_step {
            Some(
                scenario
                    .run_half_step()
                    .map_err(|e| rope_error(&format!("{name} at dt/2"), e))?,
            )
        } else {
            None
        };
        Ok::<_, PyErr>((result, half))
    })?;
    let checks = RopeChecks::of(&scenario, &result, half.as_ref());
    let summary = serde_json::json!({
        "scenario": scenario.name,
        "status": checks.status(),
        "failed_checks": checks.failures(),
        "checks": checks,
        "nodes": scenario.rope.nodes,
        "model": scenario.rope.model.number(),
        "duration_s": scenario.duration_s,
        "steps": result.steps,
        "max_penetration_m": result.max_penetration_m,
        "max_penetration_time_s": result.max_penetration_time_s,
        "penetration_tolerance_m": scenario.penetration_tolerance_m(),
        "contact_steps": result.contact_steps,
        "clamped_segments": result.clamped_segments,
        "max_internal_force_sum_n": result.max_internal_force_sum_n,
        "topology": result.topology,
        "hands": result.hands,
    });
    let json = output::json("the rope run's summary", &summary).map_err(crate::errors::to_py)?;
    output::check_value("the rope's nodes", &nodes_m).map_err(crate::errors::to_py)?;
    Ok((json, time_s.to_pyarray(py), nodes_m.to_pyarray(py)))
}
