//! One stage of a plane's identification: a Levenberg–Marquardt fit of
//! some of the plane's parameters, the uncertainty of each, and the
//! parameters the log does not determine put back to their prior and left
//! out of a second fit (the module docs of [`super`] say why and how).
//!
//! The stages' physics (which parameters, which residuals) is the
//! caller's; this module owns only the fitting and the bookkeeping.

use rayon::prelude::*;

use super::lm::{self, LmOptions, LmResult};
use super::units::{StartFits, StartUnit};
use super::{verify, Estimate, IdentifyError, IdentifyOptions, Param, PlaneModel, StageReport};

/// Errors a stage's data cannot average out, for the model at the fit:
/// one change of every residual per 1σ of each (see [`Stage`]).
pub(super) type Systematic<'a> =
    dyn Fn(&PlaneModel) -> Result<Vec<Vec<f64>>, IdentifyError> + Sync + 'a;

/// What a plane's identification has found so far: the model at the last
/// stage's fit, the estimates and the stages run, in order.
pub(super) struct Found {
    /// The plane's model.
    pub model: PlaneModel,
    /// The parameters estimated.
    pub estimates: Vec<Estimate>,
    /// The stages run.
    pub stages: Vec<StageReport>,
}

/// A stage: fits `free` (coordinates from the model found so far) with
/// `residuals`, drops the undetermined ones back to the prior and fits
/// again. A coordinate's 1σ is the larger of the white-noise one and the
/// block-robust one over the log segments `blocks` (one index per
/// residual; [`lm::block_robust_std`]), so residuals correlated in time
/// or a segment the model fits badly widen it, combined in quadrature
/// (and with the 1σ of `resampled`, whichever is largest; see there)
/// with the shift each of `systematic(model at the fit)` would cause (one
/// change of every residual per 1σ of an error the data cannot average
/// out; [`lm::systematic_shift`]). With `starts` (models that differ from
/// the model only in `free`), the first fit runs from each of them instead
/// and keeps the lowest cost (the first on a tie), so the result does not
/// depend on the thread count.
pub(super) struct Stage<'a, F> {
    /// Its name in the reports.
    pub name: &'a str,
    /// The parameters it fits.
    pub free: &'a [Param],
    /// The scaled residuals of a model.
    pub residuals: F,
    /// The log segment of each residual (another length than the
    /// residuals' falls back to the white-noise 1σ).
    pub blocks: &'a [usize],
    /// Errors the data cannot average out.
    pub systematic: &'a Systematic<'a>,
    /// Draws of the data's own randomness that the model averages over
    /// (the wire stage: the log's one draw of stick events), for the
    /// model at the fit: each a change of every residual, scaled so that
    /// the squared shifts they cause add up to the estimate's variance
    /// from that randomness (a linearised parametric bootstrap). Their
    /// 1σ is a third estimate of the log's noise beside the white-noise
    /// and the block-robust one, and the largest of the three is used.
    pub resampled: &'a Systematic<'a>,
    /// Starting points of the first fit (empty: the model found so far).
    pub starts: &'a [PlaneModel],
    /// Each residual's log segment in time order across all residuals
    /// (None: no halves check), so that the halves of the log can be
    /// checked against each other ([`verify::halves`]). The thermal and
    /// mechanics stages pass `blocks`; the wire stage's lag episodes are
    /// numbered sensor after sensor, so it passes the rows' fixed-time
    /// segments instead.
    pub halves: Option<&'a [usize]>,
    /// Where the first fit's starts run when there are several: here (on
    /// rayon's threads) without it, as work units elsewhere with it
    /// ([`super::units`]); the result is the same.
    pub elsewhere: Option<Elsewhere<'a>>,
    /// Whether its fits carry the Jacobian along by secant updates
    /// between forward differences (`opts.lm.secant_updates` of them;
    /// `opts.derivative_secant_updates` between the Jacobians of
    /// `jacobian` where it has one; without, every iteration takes a new
    /// Jacobian).
    pub secant: bool,
    /// The Jacobian of the residuals with respect to the coordinates of
    /// the parameters given, at a model, where it can be had otherwise
    /// than by forward differences (the mechanics stage's replay
    /// carrying derivatives); `None` for a parameter set it cannot take.
    pub jacobian: Option<&'a Jacobian<'a>>,
}

/// A stage's Jacobian at a model with respect to the coordinates of
/// `active`, or `None` where it has none for them ([`Stage::jacobian`]).
pub(super) type Jacobian<'a> =
    dyn Fn(&PlaneModel, &[Param]) -> Option<Result<Vec<Vec<f64>>, IdentifyError>> + Sync + 'a;

/// Fits from several starts run elsewhere: by `fits`, as units of plane
/// `plane`.
#[derive(Clone, Copy)]
pub(super) struct Elsewhere<'a> {
    pub fits: &'a dyn StartFits,
    pub plane: usize,
}

/// The 1σ of a fit's coordinates.
struct Spread {
    /// The 1σ reported: `statistical` combined in quadrature with the
    /// shifts of the systematic errors.
    used: Vec<f64>,
    /// The white-noise (Gauss–Newton) 1σ.
    white: Vec<f64>,
    /// The largest of the white-noise, the block-robust and the resampled
    /// 1σ ([`Stage::resampled`]): the noise
    /// of this log alone, which the checks of the data against
    /// themselves (halves, starts) judge by. A systematic error is common
    /// to both halves and to every start, so it does not widen them.
    statistical: Vec<f64>,
}

/// A parameter the log did not determine: its fit before it was put back.
struct Dropped {
    param: Param,
    fitted: f64,
    std: f64,
    white_std: f64,
    /// Why the log does not determine it.
    reason: String,
}

/// The best of a pass's fits, and what all of them cost.
struct BestFit {
    result: LmResult,
    /// Which starting point it ran from.
    start: usize,
    /// The other starts' minima: (coordinates, cost).
    others: Vec<(Vec<f64>, f64)>,
    iterations: usize,
    evaluations: usize,
    derivative_replays: usize,
}

/// `base` with the parameters `params` at the coordinates `x`.
pub(super) fn with_coords(base: &PlaneModel, params: &[Param], x: &[f64]) -> PlaneModel {
    let mut m = base.clone();
    for (p, v) in params.iter().zip(x) {
        p.set(&mut m, p.from_coord(*v));
    }
    m
}

/// The coordinates of `params` in `m`.
pub(super) fn coords(params: &[Param], m: &PlaneModel) -> Vec<f64> {
    params.iter().map(|p| p.to_coord(p.get(m))).collect()
}

impl<F> Stage<'_, F>
where
    F: Fn(&PlaneModel) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    /// Runs the stage on `found` (at most three passes, each without the
    /// parameters the one before could not determine) and adds its report
    /// and estimates.
    pub fn run(
        &self,
        found: &mut Found,
        prior: &PlaneModel,
        opts: &IdentifyOptions,
    ) -> Result<(), IdentifyError> {
        let model = &mut found.model;
        let mut active: Vec<Param> = self.free.to_vec();
        let mut dropped: Vec<Dropped> = Vec::new();
        let mut iterations = 0;
        let mut evaluations = 0;
        let mut derivative_replays = 0;
        let mut last: Option<LmResult> = None;
        let mut kept = None;
        let mut best_start = 0;
        for pass in 0..3 {
            if active.is_empty() {
                break;
            }
            let base = model.clone();
            let x0s: Vec<Vec<f64>> = if pass == 0 && !self.starts.is_empty() {
                self.starts.iter().map(|m| coords(&active, m)).collect()
            } else {
                vec![coords(&active, model)]
            };
            let fit = self.best_of(&base, &active, &x0s, prior, opts)?;
            iterations += fit.iterations;
            evaluations += fit.evaluations;
            derivative_replays += fit.derivative_replays;
            if pass == 0 {
                best_start = fit.start;
            }
            let r = fit.result;
            *model = with_coords(&base, &active, &r.x);
            let spread = self.spread(&r, model)?;
            let (sd, white) = (&spread.used, &spread.white);
            let reasons = self.undetermined(&active, &r, &spread, &fit.others);
            let bad: Vec<usize> = (0..active.len())
                .filter(|&j| reasons[j].is_some())
                .collect();
            if bad.is_empty() {
                last = Some(r);
                kept = Some(spread);
                break;
            }
            for &j in bad.iter().rev() {
                let p = active.remove(j);
                let v = p.get(model);
                dropped.push(Dropped {
                    param: p,
                    fitted: v,
                    std: p.value_std(v, sd[j]),
                    white_std: p.value_std(v, white[j]),
                    reason: reasons[j].clone().unwrap_or_default(),
                });
                p.set(model, p.get(prior));
            }
            last = Some(r);
        }
        let r =
            last.ok_or_else(|| IdentifyError::Log(format!("stage {}: nothing to fit", self.name)))?;
        found.stages.push(StageReport {
            name: self.name.into(),
            iterations,
            evaluations,
            derivative_replays,
            residuals: r.m,
            rms_scaled: (r.cost / r.m.max(1) as f64).sqrt(),
            stopped_by_budget: r.stopped_by_budget,
            starts: self.starts.len().max(1),
            best_start,
        });
        // The last pass's spread where it kept every parameter (the model
        // is the one it was computed at), otherwise at the model now.
        let spread = match kept {
            Some(spread) => spread,
            None => self.spread(&r, &found.model)?,
        };
        self.report(found, prior, &active, &spread.used, &spread.white, dropped);
        Ok(())
    }

    /// The fits from `x0s` run as units by `e` ([`super::units`]): every
    /// fit that came back is replayed here once at its minimiser (in
    /// parallel) and must reproduce its cost — one that does not ends the
    /// stage, since it would decide the selection and the starts check.
    #[allow(clippy::too_many_arguments)] // what a unit is built from
    #[allow(clippy::type_complexity)] // one fit's result per start
    fn fits_elsewhere<G>(
        &self,
        e: Elsewhere<'_>,
        base: &PlaneModel,
        active: &[Param],
        x0s: &[Vec<f64>],
        prior: &PlaneModel,
        opts: &IdentifyOptions,
        lm_opts: LmOptions,
        f: &G,
    ) -> Result<Vec<Result<lm::Minimum, IdentifyError>>, IdentifyError>
    where
        G: Fn(&[f64]) -> Result<Vec<f64>, IdentifyError> + Sync,
    {
        let units = x0s
            .iter()
            .enumerate()
            .map(|(k, x0)| StartUnit::new(e.plane, k, prior, base, active, x0, opts, lm_opts))
            .collect::<Result<Vec<_>, _>>()?;
        let answers = e.fits.fit(&units)?;
        if answers.len() != units.len() {
            return Err(IdentifyError::Remote(format!(
                "{} answers for {} fits of the {} stage",
                answers.len(),
                units.len(),
                self.name
            )));
        }
        let taken: Vec<Result<Result<lm::Minimum, IdentifyError>, IdentifyError>> = answers
            .into_par_iter()
            .map(|a| match a {
                Ok(fit) => lm::Minimum::from_unit(&fit, f, lm_opts).map(Ok),
                Err(why) => Ok(Err(IdentifyError::Remote(why))),
            })
            .collect();
        taken.into_iter().collect()
    }

    /// Fits `active` from each of `x0s` (coordinates around `base`) and
    /// keeps the lowest cost, the first on a tie; the first error when no
    /// fit succeeded. Only the fit kept gets its final Jacobian (should it
    /// fail there, the next best is kept).
    fn best_of(
        &self,
        base: &PlaneModel,
        active: &[Param],
        x0s: &[Vec<f64>],
        prior: &PlaneModel,
        opts: &IdentifyOptions,
    ) -> Result<BestFit, IdentifyError> {
        // Secant updates between Jacobians: fewer between differenced ones
        // (nine replays each) than between derived ones (about 4.3), as
        // measured (identify::SECANT_UPDATES, DERIVATIVE_SECANT_UPDATES).
        let lm_opts = LmOptions {
            secant_updates: match (self.secant, self.jacobian.is_some()) {
                (false, _) => 0,
                (true, false) => opts.lm.secant_updates,
                (true, true) => opts.derivative_secant_updates,
            },
            ..opts.lm
        };
        let f = |x: &[f64]| (self.residuals)(&with_coords(base, active, x));
        let f = lm_opts.stoppable(&f);
        let differenced = lm::differences(&f, lm_opts.step);
        // The stage's own Jacobian where it has one for these parameters
        // (a replay carrying derivatives: one evaluation), differences
        // otherwise.
        let jac = |x: &[f64], r0: &[f64]| -> Result<lm::Costed, IdentifyError> {
            match self
                .jacobian
                .and_then(|j| j(&with_coords(base, active, x), active))
            {
                Some(columns) => Ok((columns?, lm::JacobianCost::DerivativeReplay)),
                None => differenced(x, r0),
            }
        };
        let mut minima: Vec<(usize, lm::Minimum)> = Vec::new();
        let mut iterations = 0;
        let mut evaluations = 0;
        let mut first_error = None;
        // The starts run in parallel, here or elsewhere; their results are
        // taken in order.
        let fits: Vec<Result<lm::Minimum, IdentifyError>> =
            match self.elsewhere.filter(|_| x0s.len() > 1) {
                Some(e) => self.fits_elsewhere(e, base, active, x0s, prior, opts, lm_opts, &f)?,
                None => x0s
                    .par_iter()
                    .map(|x0| lm::minimise_with(&f, &jac, x0, lm_opts))
                    .collect(),
            };
        // A fit the caller stopped ends the stage: the other starts' best
        // is not the stage's answer.
        if fits
            .iter()
            .any(|f| matches!(f, Err(IdentifyError::Stopped)))
        {
            return Err(IdentifyError::Stopped);
        }
        let mut derivative_replays = 0;
        for (k, fit) in fits.into_iter().enumerate() {
            match fit {
                Ok(r) => {
                    iterations += r.iterations;
                    evaluations += r.evaluations;
                    derivative_replays += r.derivative_replays;
                    minima.push((k, r));
                }
                Err(e) => {
                    first_error.get_or_insert((k, e));
                }
            }
        }
        // The lowest cost, the first on a tie; one whose final Jacobian
        // fails is no candidate, as if its fit had failed.
        while let Some(best) = (0..minima.len()).reduce(|b, i| {
            if minima[i].1.cost < minima[b].1.cost {
                i
            } else {
                b
            }
        }) {
            let (k, minimum) = minima.remove(best);
            let before = (minimum.evaluations, minimum.derivative_replays);
            match minimum.finish_with(&jac, lm_opts) {
                Ok(result) => {
                    evaluations += result.evaluations - before.0;
                    derivative_replays += result.derivative_replays - before.1;
                    let others = minima.iter().map(|(_, o)| (o.x.clone(), o.cost)).collect();
                    return Ok(BestFit {
                        result,
                        start: k,
                        others,
                        iterations,
                        evaluations,
                        derivative_replays,
                    });
                }
                Err(e) => {
                    if first_error.as_ref().is_none_or(|(j, _)| k < *j) {
                        first_error = Some((k, e));
                    }
                }
            }
        }
        Err(first_error.map(|(_, e)| e).unwrap_or_else(|| {
            IdentifyError::Log(format!("stage {}: no starting point", self.name))
        }))
    }

    /// Why each of `active` is not determined by the fit `r` (its 1σ
    /// `spread`, in coordinates), None where it is: its 1σ used above the
    /// parameter's threshold; the halves of the log disagreeing on it
    /// ([`verify::halves`]); another start's equally good minimum far
    /// from it ([`verify::starts_disagree`]). The last two judge by the
    /// statistical 1σ ([`Spread`]).
    fn undetermined(
        &self,
        active: &[Param],
        r: &LmResult,
        spread: &Spread,
        others: &[(Vec<f64>, f64)],
    ) -> Vec<Option<String>> {
        let sd = &spread.used;
        let ratio: Vec<f64> = spread
            .statistical
            .iter()
            .zip(&spread.white)
            .map(|(s, w)| s / w)
            .collect();
        let halves = if let Some(segments) = self.halves.filter(|b| b.len() == r.m) {
            verify::halves(&r.jacobian, &r.residuals, segments, &ratio)
        } else {
            vec![(0.0, 0.0, 0.0); active.len()]
        };
        let starts = verify::starts_disagree(&r.x, r.cost, others, &spread.statistical, r.m);
        let short = plant_common::short_number;
        (0..active.len())
            .map(|j| {
                let p = active[j];
                let v = p.from_coord(r.x[j]);
                if !p.determined(sd[j]) {
                    let s = p.value_std(v, sd[j]);
                    let s = match p.scale() {
                        super::Scale::Log { .. } => format!("{:.0} %", 100.0 * sd[j]),
                        super::Scale::Linear { .. } => format!("{s:.3e} {}", p.unit()),
                    };
                    return Some(if sd[j].is_finite() {
                        format!(
                            "1σ {s} is above the threshold of {} (the log barely moves the fit along it)",
                            threshold(p)
                        )
                    } else {
                        "the fit does not depend on it (the log does not excite it)".into()
                    });
                }
                let (a, b, z) = halves[j];
                if z > verify::HALVES_MAX_Z {
                    return Some(format!(
                        "the two halves of the fitted log disagree: {} against {} {} ({:.1} σ of their difference); a model error elsewhere, or a part of the log that does not excite it",
                        short(p.from_coord(r.x[j] + a)),
                        short(p.from_coord(r.x[j] + b)),
                        p.unit(),
                        z
                    ));
                }
                if let Some((x, dchi2)) = starts[j] {
                    return Some(format!(
                        "another starting point reached an equally good fit (Δχ² {:.1}) at {} {}",
                        dchi2,
                        short(p.from_coord(x)),
                        p.unit()
                    ));
                }
                None
            })
            .collect()
    }

    /// The 1σ of each coordinate of the fit `r` at `at`.
    fn spread(&self, r: &LmResult, at: &PlaneModel) -> Result<Spread, IdentifyError> {
        if self.blocks.len() != r.m {
            return Ok(Spread {
                used: r.std.clone(),
                white: r.std.clone(),
                statistical: r.std.clone(),
            });
        }
        let inverse = lm::NormalInverse::new(&r.jacobian, r.m);
        let robust = lm::block_robust_std_with(&inverse, &r.jacobian, &r.residuals, self.blocks);
        let mut statistical: Vec<f64> = r.std.iter().zip(&robust).map(|(w, b)| w.max(*b)).collect();
        let mut drawn = vec![0.0f64; statistical.len()];
        for draw in (self.resampled)(at)?.iter().filter(|s| s.len() == r.m) {
            let dx = lm::systematic_shift_with(&inverse, &r.jacobian, draw);
            for (d, x) in drawn.iter_mut().zip(dx) {
                *d = d.hypot(x);
            }
        }
        for (s, d) in statistical.iter_mut().zip(drawn) {
            *s = s.max(d);
        }
        let mut used = statistical.clone();
        for shift in (self.systematic)(at)?.iter().filter(|s| s.len() == r.m) {
            let dx = lm::systematic_shift_with(&inverse, &r.jacobian, shift);
            for (u, d) in used.iter_mut().zip(dx) {
                *u = u.hypot(d);
            }
        }
        Ok(Spread {
            used,
            white: r.std.clone(),
            statistical,
        })
    }

    /// Adds the stage's estimates to `found`: the parameters it
    /// determined (`active`, with their 1σ used and white-noise 1σ in
    /// coordinates), then those it `dropped`, at their prior.
    fn report(
        &self,
        found: &mut Found,
        prior: &PlaneModel,
        active: &[Param],
        sd: &[f64],
        white: &[f64],
        dropped: Vec<Dropped>,
    ) {
        for (j, p) in active.iter().enumerate() {
            let v = p.get(&found.model);
            let at = |s: &[f64]| p.value_std(v, s.get(j).copied().unwrap_or(f64::INFINITY));
            found.estimates.push(Estimate {
                param: *p,
                field: p.field().into(),
                unit: p.unit().into(),
                value: v,
                fitted: v,
                prior: p.get(prior),
                std: at(sd),
                white_std: at(white),
                identifiable: true,
                stage: self.name.into(),
                reason: None,
                verified: true,
                pull_sigma: 0.0,
            });
        }
        for d in dropped {
            let p = d.param;
            found.estimates.push(Estimate {
                param: p,
                field: p.field().into(),
                unit: p.unit().into(),
                value: p.get(&found.model),
                fitted: d.fitted,
                prior: p.get(prior),
                std: d.std,
                white_std: d.white_std,
                identifiable: false,
                stage: self.name.into(),
                reason: Some(d.reason),
                verified: true,
                pull_sigma: 0.0,
            });
        }
    }
}

/// A parameter's identifiability threshold in words.
fn threshold(p: Param) -> String {
    match p.scale() {
        super::Scale::Log { max_rel } => {
            format!("{} %", plant_common::short_number(100.0 * max_rel))
        }
        super::Scale::Linear { max_abs } => {
            format!("{} {}", plant_common::short_number(max_abs), p.unit())
        }
    }
}
