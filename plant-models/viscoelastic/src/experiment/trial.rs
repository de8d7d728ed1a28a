//! One 1D trial (seed 002 Eq. 3): the 3-element model run on a table of
//! displacement or force against time, and a fit of (k1, k2, b) to a
//! measured trial that is accepted only when its numbers are finite and
//! determined by the data.
use plant_common::csv_input::{excerpt, Table};

use crate::error::{Result, VeError};
use crate::fit::{fit_trial, simulate_displacement, simulate_force, NelderMeadOptions, Weighting};
use crate::io::columns_of;

/// The 3-element model's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThreeElementParams {
    /// Delayed spring k1 (N/m).
    pub k1_n_per_m: f64,
    /// Series (instantaneous) spring k2 (N/m).
    pub k2_n_per_m: f64,
    /// Dashpot b (N·s/m).
    pub b_n_s_per_m: f64,
}

/// A 1D trace: displacement and force at times.
#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    pub time_s: Vec<f64>,
    pub displacement_m: Vec<f64>,
    pub force_n: Vec<f64>,
}

/// Runs the model on `table` (named `file` in errors): on its
/// `time_s,displacement` columns to give the force, or else on
/// `time_s,force` to give the displacement. A result that overflowed
/// (parameters or samples near the f64 range) is refused, naming the
/// first sample that did.
pub fn simulate_table(table: &Table, file: &str, p: ThreeElementParams) -> Result<Trace> {
    let (k1, k2, b) = (p.k1_n_per_m, p.k2_n_per_m, p.b_n_s_per_m);
    let trace = if table.has("displacement") {
        let c = columns_of(table, &["time_s", "displacement"], Some("time_s"))?;
        let (t, u) = (c.values[0].clone(), c.values[1].clone());
        let f = simulate_force(k1, k2, b, &t, &u)?;
        Trace {
            time_s: t,
            displacement_m: u,
            force_n: f,
        }
    } else if table.has("force") {
        let c = columns_of(table, &["time_s", "force"], Some("time_s"))?;
        let (t, f) = (c.values[0].clone(), c.values[1].clone());
        let u = simulate_displacement(k1, k2, b, &t, &f)?;
        Trace {
            time_s: t,
            displacement_m: u,
            force_n: f,
        }
    } else {
        return Err(VeError::Parse {
            file: file.to_string(),
            line: table.header_line,
            reason: format!(
                "missing column: need `displacement` or `force` beside `time_s` (the header has: {})",
                excerpt(&table.columns.join(", "))
            ),
        });
    };
    let (t, u, f) = (&trace.time_s, &trace.displacement_m, &trace.force_n);
    for k in 0..t.len() {
        if !(u[k].is_finite() && f[k].is_finite()) {
            return Err(VeError::Overflow {
                file: file.to_string(),
                time_s: t[k],
                displacement: u[k],
                force: f[k],
                k1,
                k2,
                b,
            });
        }
    }
    Ok(trace)
}

/// Fits (k1, k2, b) to one trial by Nelder–Mead with `weighting`; refuses
/// a fit whose force overflowed or whose parameters the trial does not
/// determine ([`crate::fit::TrialFit::check_determined`]).
pub fn fit_trial_checked(
    time_s: &[f64],
    displacement_m: &[f64],
    force_n: &[f64],
    weighting: Weighting,
) -> Result<crate::fit::TrialFit> {
    let r = fit_trial(
        time_s,
        displacement_m,
        force_n,
        weighting,
        NelderMeadOptions::default(),
    )?;
    if !(r.rms_residual_n.is_finite() && r.weighted_cost_n2.is_finite()) {
        return Err(VeError::FitOverflow {
            rms_residual_n: r.rms_residual_n,
        });
    }
    // Numbers the data do not determine are not a result.
    r.check_determined()?;
    Ok(r)
}
