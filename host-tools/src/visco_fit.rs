//! What `softjoint viscoelastic fit` does with a trial's CSV: the
//! columns read and their ranges checked, (k1, k2, b) of the 3-element
//! model (seed 002, Eq. 3) fitted by Nelder–Mead and refused when the
//! trial does not determine them, and the `--json` summary of the fit.
//! The program and the Python package both take them from here.
use anyhow::{bail, Context, Result};
use plant_viscoelastic::experiment::trial::fit_trial_checked;
use plant_viscoelastic::fit::{TrialFit, Weighting};
use plant_viscoelastic::io::{read_columns, Columns};

use crate::output::JsonObject;

/// A trial's forces and displacements within what a trial of a soft
/// material records, and a stiffness scale (largest force over largest
/// displacement) a fit can represent: a force a million times too large,
/// or displacements in the wrong unit, are refused by line, not fitted to
/// a stiffness of `inf`.
pub fn check_trial_ranges(c: &Columns, name: &str) -> Result<()> {
    use plant_viscoelastic::io::{check_magnitude, MAX_TRIAL_DISPLACEMENT_M, MAX_TRIAL_FORCE_N};
    check_magnitude(
        c,
        name,
        "force",
        MAX_TRIAL_FORCE_N,
        "N",
        "a soft material's trial",
    )?;
    check_magnitude(
        c,
        name,
        "displacement",
        MAX_TRIAL_DISPLACEMENT_M,
        "m",
        "a soft material's trial",
    )?;
    let peak = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (f, u) = (peak(&c.values[2]), peak(&c.values[1]));
    // Steel in contact is ≈ 1e9 N/m; a soft object is many decades below.
    let stiffness = f / u;
    if f > 0.0 && stiffness > 1e12 {
        bail!(
            "{name}: forces up to {} N against displacements of at most {} m (a stiffness of {} N/m) — beyond any soft material; is the displacement column in metres?",
            plant_common::short_number(f),
            plant_common::short_number(u),
            plant_common::short_number(stiffness)
        );
    }
    Ok(())
}

/// Reads the `time_s,displacement,force` columns of a trial's CSV `text`
/// (`name` names it in errors), checks their ranges and fits (k1, k2, b)
/// with `weighting`: the columns and the fit.
pub fn fit_trial_text(text: &str, name: &str, weighting: Weighting) -> Result<(Columns, TrialFit)> {
    let c = read_columns(
        plant_common::strip_bom(text),
        name,
        &["time_s", "displacement", "force"],
        Some("time_s"),
    )?;
    check_trial_ranges(&c, name)?;
    let (t, u, f) = (&c.values[0], &c.values[1], &c.values[2]);
    let r = fit_trial_checked(t, u, f, weighting).with_context(|| format!("fitting {name}"))?;
    Ok((c, r))
}

/// The weighting's name in summaries: `seed` (tail ×100, 3 points around
/// the peak ×1000) or `uniform`.
pub fn weighting_name(w: Weighting) -> &'static str {
    match w {
        Weighting::Uniform => "uniform",
        Weighting::Seed => "seed",
    }
}

/// The `--json` summary of a fit of `samples` samples, each field checked
/// finite.
pub fn fit_summary(r: &TrialFit, weighting: Weighting, samples: usize) -> Result<JsonObject> {
    JsonObject::new()
        .field("k1_n_per_m", &r.k1_n_per_m)?
        .field("k2_n_per_m", &r.k2_n_per_m)?
        .field("b_n_s_per_m", &r.b_n_s_per_m)?
        .field("rms_residual_n", &r.rms_residual_n)?
        .field("weighted_cost_n2", &r.weighted_cost_n2)?
        .field("uncertainty_factor", &r.uncertainty_factor())?
        .field("evaluations", &r.evaluations)?
        .field("weighting", weighting_name(weighting))?
        .field("samples", &samples)
}
