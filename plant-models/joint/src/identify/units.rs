//! The mechanics stage's fits from its starting points as work units
//! (issue 33): each fit from one start is a pure function of the log, the
//! prior plant and the unit ([`StartUnit`]), so it can run in another
//! process — a Ray worker — and come back as a [`StartFit`] that the
//! identification takes as if it had run here. The selection among the
//! starts, the final Jacobian of the fit kept and everything after stay
//! with the caller ([`super::identify_2d_with`],
//! [`super::identify_3d_with`]).
//!
//! Every number crosses as its `f64` bit pattern (a `u64`), so nothing is
//! rounded on the way, non-finite values included. Every fit that comes
//! back is checked as it arrives, not only the one kept (the others steer
//! the starts check): the residuals at its minimiser are recomputed here
//! and must give its cost to the last bit
//! ([`super::lm::Minimum::from_unit`]); a worker that computed something
//! else (another log, another prior, another build) is an error, not a
//! different answer.

use serde::{Deserialize, Serialize};

use super::lm::{self, LmOptions};
use super::replay::{PlaneMap, PlaneModel};
use super::stage::with_coords;
use super::{
    frames, mechanics_jacobian, mechanics_residuals, FitPart, IdentifyError, IdentifyOptions, Param,
};

/// A fit of the mechanics stage from one starting point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartUnit {
    /// The plane's index in the log (0: θ or α, 1: β).
    pub plane: usize,
    /// Which start of the stage (0-based, best-ranked first), for messages.
    pub start: usize,
    /// The model the fit moves from: every parameter whose value differs
    /// from the prior's, by field name ([`Param::field`]), as bits.
    pub base: Vec<(String, u64)>,
    /// The parameters fitted, by field name, in coordinate order.
    pub active: Vec<String>,
    /// The starting coordinates, as bits.
    pub x0: Vec<u64>,
    /// Share of the log fitted ([`IdentifyOptions::fit_fraction`]), bits.
    pub fit_fraction: u64,
    /// The replays' substep (s), bits.
    pub substep_s: u64,
    /// A priori angle noise (deg), bits.
    pub angle_sigma_deg: u64,
    /// A priori resistance noise (Ω), bits.
    pub resistance_sigma_ohm: u64,
    /// The minimiser's iterations at most.
    pub max_iterations: usize,
    /// Its relative cost decrease to stop at, bits.
    pub ftol: u64,
    /// Its forward-difference step, bits.
    pub step: u64,
    /// Its secant updates between Jacobians (differenced or derived).
    pub secant_updates: usize,
    /// Jacobians from a replay carrying derivatives
    /// ([`IdentifyOptions::derivative_jacobians`]).
    #[serde(default)]
    pub derivative_jacobians: bool,
}

/// Where a fit from one start ended: what [`lm::minimise`] returns, less
/// the residuals and Jacobian there (recomputed by the caller, bit for
/// bit the same: the residuals for every fit, the Jacobian for the one it
/// keeps).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartFit {
    /// The minimiser, bits.
    pub x: Vec<u64>,
    /// `‖r‖²` there, bits.
    pub cost: u64,
    /// Iterations taken.
    pub iterations: usize,
    /// Residual evaluations.
    pub evaluations: usize,
    /// Jacobians from a replay carrying derivatives.
    #[serde(default)]
    pub derivative_replays: usize,
    /// Ran out of iterations.
    pub stopped_by_budget: bool,
    /// The minimiser had the Jacobian at `x` (so the caller recomputes it
    /// without counting it, as the minimiser's own would not have been).
    pub jacobian_known: bool,
}

/// Runs a stage's fits from several starting points somewhere else (a
/// Ray cluster): the answers in the order of `units`, each the fit or the
/// message of the error it ended with. An error of the whole call (the
/// workers cannot be reached, a stop) ends the identification.
pub trait StartFits: Sync {
    /// The fits of `units`.
    fn fit(&self, units: &[StartUnit]) -> Result<Vec<Result<StartFit, String>>, IdentifyError>;
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

fn floats(v: &[u64]) -> Vec<f64> {
    v.iter().map(|&b| f64::from_bits(b)).collect()
}

fn param(field: &str) -> Result<Param, IdentifyError> {
    Param::from_field(field)
        .ok_or_else(|| IdentifyError::Log(format!("a start unit names no parameter {field:?}")))
}

/// `prior` with the parameters of `base` set (a unit's model).
fn model_of(prior: &PlaneModel, base: &[(String, u64)]) -> Result<PlaneModel, IdentifyError> {
    let mut m = prior.clone();
    for (field, b) in base {
        param(field)?.set(&mut m, f64::from_bits(*b));
    }
    Ok(m)
}

impl StartUnit {
    /// The unit of a fit of `active` from `x0` around `base` (plane
    /// `plane`, start `start`), or an error when `base` differs from
    /// `prior` in anything but the parameters (it could not be rebuilt
    /// from the prior where the unit runs).
    #[allow(clippy::too_many_arguments)] // the unit's own fields
    pub(super) fn new(
        plane: usize,
        start: usize,
        prior: &PlaneModel,
        base: &PlaneModel,
        active: &[Param],
        x0: &[f64],
        opts: &IdentifyOptions,
        lm: LmOptions,
    ) -> Result<Self, IdentifyError> {
        let base_values: Vec<(String, u64)> = Param::ALL
            .iter()
            .filter(|p| p.get(base).to_bits() != p.get(prior).to_bits())
            .map(|p| (p.field().to_string(), p.get(base).to_bits()))
            .collect();
        if model_of(prior, &base_values)? != *base
            || prior.substep_s.to_bits() != opts.substep_s.to_bits()
        {
            return Err(IdentifyError::Log(
                "the mechanics start differs from the prior in more than its parameters; it cannot run as a unit elsewhere".into(),
            ));
        }
        Ok(Self {
            plane,
            start,
            base: base_values,
            active: active.iter().map(|p| p.field().to_string()).collect(),
            x0: bits(x0),
            fit_fraction: opts.fit_fraction.to_bits(),
            substep_s: opts.substep_s.to_bits(),
            angle_sigma_deg: opts.angle_sigma_deg.to_bits(),
            resistance_sigma_ohm: opts.resistance_sigma_ohm.to_bits(),
            max_iterations: lm.max_iterations,
            ftol: lm.ftol.to_bits(),
            step: lm.step.to_bits(),
            secant_updates: lm.secant_updates,
            derivative_jacobians: opts.derivative_jacobians,
        })
    }

    /// The options the unit's fit runs with.
    fn options(&self) -> IdentifyOptions {
        IdentifyOptions {
            fit_fraction: f64::from_bits(self.fit_fraction),
            substep_s: f64::from_bits(self.substep_s),
            angle_sigma_deg: f64::from_bits(self.angle_sigma_deg),
            resistance_sigma_ohm: f64::from_bits(self.resistance_sigma_ohm),
            lm: LmOptions {
                max_iterations: self.max_iterations,
                ftol: f64::from_bits(self.ftol),
                step: f64::from_bits(self.step),
                secant_updates: self.secant_updates,
                stop: None,
            },
            derivative_jacobians: self.derivative_jacobians,
            ..IdentifyOptions::default()
        }
    }

    /// The fit, where the unit runs: `log` and `prior` (the prior's model
    /// of the unit's plane, [`super::prior_models`]) must be those the
    /// identification started from.
    pub fn run(
        &self,
        log: &super::ExcitationLog,
        prior: &PlaneModel,
    ) -> Result<StartFit, IdentifyError> {
        if self.plane >= log.planes {
            return Err(IdentifyError::Log(format!(
                "a start unit for plane {} of a log with {} plane(s)",
                self.plane, log.planes
            )));
        }
        let opts = self.options();
        let mut prior = prior.clone();
        prior.substep_s = opts.substep_s;
        let base = model_of(&prior, &self.base)?;
        let active = self
            .active
            .iter()
            .map(|f| param(f))
            .collect::<Result<Vec<_>, _>>()?;
        let part = FitPart::new(log, PlaneMap::of(log.planes, self.plane), opts.fit_fraction)?;
        let fit_frames = frames(log, self.plane, part.rows);
        let mech = mechanics_residuals(&part, &opts, &fit_frames);
        let mech_jacobian = mechanics_jacobian(&part, &opts, &fit_frames);
        let f = |x: &[f64]| mech(&with_coords(&base, &active, x));
        let f = opts.lm.stoppable(&f);
        let differenced = lm::differences(&f, opts.lm.step);
        // As the stage's own fits take their Jacobian (stage::Stage::jacobian).
        let jac = |x: &[f64], r0: &[f64]| -> Result<lm::Costed, IdentifyError> {
            let derived = opts
                .derivative_jacobians
                .then(|| mech_jacobian(&with_coords(&base, &active, x), &active))
                .flatten();
            match derived {
                Some(columns) => Ok((columns?, lm::JacobianCost::DerivativeReplay)),
                None => differenced(x, r0),
            }
        };
        let m = lm::minimise_with(&f, &jac, &floats(&self.x0), opts.lm)?;
        Ok(StartFit {
            x: bits(&m.x),
            cost: m.cost.to_bits(),
            iterations: m.iterations,
            evaluations: m.evaluations,
            derivative_replays: m.derivative_replays,
            stopped_by_budget: m.stopped_by_budget,
            jacobian_known: m.jacobian_known(),
        })
    }
}

/// The mechanics stage's cost of plane `plane` of `log` (the sum of
/// squares of its scaled residuals: camera angles over the fitted part,
/// and the coil resistances where logged, as [`StartUnit::run`] fits
/// them) for `prior` (the prior's model of that plane,
/// [`super::prior_model_2d`], [`super::prior_model_3d`]) with the
/// parameters `values` set (by field name, [`Param::field`]), and the
/// residuals' count. What an identification's mechanics fit minimises,
/// for a model a caller chooses.
pub fn mechanics_cost(
    log: &super::ExcitationLog,
    prior: &PlaneModel,
    plane: usize,
    values: &[(String, f64)],
    opts: &IdentifyOptions,
) -> Result<(f64, usize), IdentifyError> {
    if plane >= log.planes {
        return Err(IdentifyError::Log(format!(
            "plane {plane} of a log with {} plane(s)",
            log.planes
        )));
    }
    let mut m = prior.clone();
    m.substep_s = opts.substep_s;
    for (field, v) in values {
        param(field)?.set(&mut m, *v);
    }
    let part = FitPart::new(log, PlaneMap::of(log.planes, plane), opts.fit_fraction)?;
    let fit_frames = frames(log, plane, part.rows);
    let r = mechanics_residuals(&part, opts, &fit_frames)(&m)?;
    Ok((r.iter().map(|x| x * x).sum(), r.len()))
}

impl StartFit {
    /// The minimiser's coordinates.
    pub fn x(&self) -> Vec<f64> {
        floats(&self.x)
    }
}
