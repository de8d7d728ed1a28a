//! What `softjoint dlo solve` reports of a static wire, belt or
//! end-distance sequence (Wakamatsu et al., seed 000): its summary (the
//! `--json` fields but the solve's time and file names) and whether every
//! shape passed its checks. The program and the Python package both take
//! them from here.
use anyhow::Result;
use plant_dlo::wire::belt::{curve_top, BeltMethod, BeltShape};
use plant_dlo::wire::linear::SequenceStep;
use plant_dlo::wire::problem::StaticSolution;

use crate::output::JsonObject;

/// Why a solution is not verified (the failing checks of each shape), or
/// none when every shape passed all its checks.
pub fn unverified(solution: &StaticSolution) -> Option<String> {
    let why = |name: String, f: Vec<&'static str>| {
        (!f.is_empty()).then(|| format!("{name} fails {}", f.join(", ")))
    };
    let list: Vec<String> = match solution {
        StaticSolution::Wire { shape, .. } => why("the wire".into(), shape.checks.failures())
            .into_iter()
            .collect(),
        StaticSolution::Belt { shape, .. } => why("the belt".into(), shape.checks.failures())
            .into_iter()
            .collect(),
        StaticSolution::Sequence { steps, .. } => steps
            .iter()
            .flat_map(|st| {
                [
                    why(
                        format!("{:.2} L knot-free", st.l_fraction),
                        st.free.checks.failures(),
                    ),
                    why(
                        format!("{:.2} L one-knot", st.l_fraction),
                        st.knot.checks.failures(),
                    ),
                ]
            })
            .flatten()
            .collect(),
    };
    (!list.is_empty()).then(|| list.join("; "))
}

/// The summary of a solve (without its time and file names): energies and
/// the solve's evidence (constraint violation, convergence).
pub fn solve_summary(solution: &StaticSolution) -> Result<JsonObject> {
    match solution {
        StaticSolution::Wire { shape, .. } => JsonObject::new()
            .field("model", "wire")?
            .field("energy_j", &shape.energy_j)?
            .field("flexural_j", &shape.flexural_j)?
            .field("torsional_j", &shape.torsional_j)?
            .field("extensional_j", &shape.extensional_j)?
            .field("gravitational_j", &shape.gravitational_j)?
            .field("max_violation", &shape.max_violation)?
            .field("converged", &shape.verified())?
            .field("status", status(shape.verified()))?
            .field("failed_checks", &shape.checks.failures())?
            .field("checks", &shape.checks)?
            .field("crossings_m", &shape.crossings_m)?
            .field("min_self_distance_m", &shape.min_self_distance_m),
        StaticSolution::Belt { shape, method } => belt_json(shape, *method),
        StaticSolution::Sequence { steps, .. } => {
            let table = steps
                .iter()
                .map(sequence_step_json)
                .collect::<Result<Vec<JsonObject>>>()?;
            JsonObject::new()
                .field("model", "sequence")?
                .field("steps", &table)
        }
    }
}

fn belt_json(shape: &BeltShape, method: BeltMethod) -> Result<JsonObject> {
    let top = curve_top(&shape.spine_m);
    JsonObject::new()
        .field("model", "belt")?
        .field(
            "method",
            match method {
                BeltMethod::Segments => "segments",
                BeltMethod::Ritz => "ritz",
            },
        )?
        .field("energy_j", &shape.energy_j)?
        .field(
            "highest_surface_point_m",
            &[shape.highest_m.x, shape.highest_m.y, shape.highest_m.z],
        )?
        .field("highest_spine_point_m", &[top.x, top.y, top.z])?
        .field("paper_highest_point_lu", &[0.3, 0.4, -0.01])?
        .field("max_violation", &shape.max_violation)?
        .field("converged", &shape.verified())?
        .field("status", status(shape.verified()))?
        .field("failed_checks", &shape.checks.failures())?
        .field("checks", &shape.checks)
}

fn sequence_step_json(st: &SequenceStep) -> Result<JsonObject> {
    JsonObject::new()
        .field("l_fraction", &st.l_fraction)?
        .field("knot_free_j", &st.free.energy_j)?
        .field("one_knot_j", &st.knot.energy_j)?
        .field("one_knot_torsional_j", &st.knot.torsional_j)?
        .field("lower", st.lower())?
        .field("converged", &st.converged())?
        .field("status", status(st.converged()))?
        .field("knot_free_failed_checks", &st.free.checks.failures())?
        .field("one_knot_failed_checks", &st.knot.checks.failures())
}

/// The `status` field: "verified" when every check holds, else
/// "UNVERIFIED" (and the command exits 1).
fn status(verified: bool) -> &'static str {
    if verified {
        "verified"
    } else {
        "UNVERIFIED"
    }
}
