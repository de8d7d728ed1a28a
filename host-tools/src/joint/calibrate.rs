//! Calibrating the wire-sensor laws against reference angles, as the paper
//! did against camera images (seed 000, last paper, Fig. 14, 20, 22).
//!
//! Input: a sweep of insertions and reference angles (CSV). For each angle
//! the tool fits, with the core's least-squares accumulators
//! ([`firmware::fit::PolyFit`]):
//! - the single-sensor quadratic (Eq. 2) on the sensor that is *pulled out*
//!   on the low side (d3 for α, d4 for β, the only sensor in 2D);
//! - the differential linear law (Eq. 3) on d3 − d1 (α) or d4 − d2 (β);
//! - threshold switching (Eq. 4): for each candidate threshold on a 0.1°
//!   grid the quadratic is fitted to the rows below it and the linear law to
//!   the rows at or above it, the switching estimator (as the firmware runs
//!   it, hysteresis included, over the sweep in order) is evaluated on every
//!   row, and the threshold with the smallest worst-case error wins.
//!
//! The chosen estimator is the one with the smallest worst-case error.

use std::fmt::Write as _;

use anyhow::bail;
use firmware::estimate::{PlaneEstimator, PlaneLaw, DEFAULT_HYSTERESIS_DEG};
use firmware::fit::PolyFit;
use plant_common::short_number as short;
use serde::{Deserialize, Serialize};

use crate::files::calibration::{describe, CalibrationFile, LawSpec};
use crate::files::sweep::SweepRow;

/// Max and RMS error of one method over the sweep (deg).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Worst-case |estimate − reference|.
    pub max_error_deg: f64,
    /// Root mean square error.
    pub rms_error_deg: f64,
}

/// The fits of one angle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlaneFit {
    /// "alpha", "beta" or "theta".
    pub angle: String,
    /// Single-sensor quadratic over the whole sweep, and its errors.
    pub single: (LawSpec, ErrorStats),
    /// Differential law over the whole sweep (3D only).
    pub differential: Option<(LawSpec, ErrorStats)>,
    /// Threshold switching (3D only).
    pub switching: Option<(LawSpec, ErrorStats)>,
    /// The method with the smallest worst-case error.
    pub chosen: LawSpec,
    /// Its errors.
    pub chosen_errors: ErrorStats,
}

/// Runs an estimator over the rows in order and returns its errors.
fn evaluate<const S: usize>(law: PlaneLaw, rows: &[SweepRow], plane: usize) -> Option<ErrorStats> {
    let mut est = PlaneEstimator::<S>::new(law).ok()?;
    let (mut max, mut sq) = (0.0f64, 0.0f64);
    for r in rows {
        let d: [f32; S] =
            core::array::from_fn(|k| r.d_mm.get(k).copied().unwrap_or(f64::NAN) as f32);
        let e = f64::from(est.estimate(&d).angle_deg) - r.angle_deg[plane];
        max = max.max(e.abs());
        sq += e * e;
    }
    Some(ErrorStats {
        max_error_deg: max,
        rms_error_deg: (sq / rows.len().max(1) as f64).sqrt(),
    })
}

fn fit_quadratic(rows: impl Iterator<Item = (f64, f64)>) -> Option<[f64; 3]> {
    let mut f = PolyFit::quadratic(0.0);
    rows.for_each(|(x, y)| f.add(x, y));
    f.solve().ok()
}

fn fit_linear(rows: impl Iterator<Item = (f64, f64)>) -> Option<[f64; 3]> {
    let mut f = PolyFit::linear(0.0);
    rows.for_each(|(x, y)| f.add(x, y));
    f.solve().ok()
}

/// Fits every method for every angle of the sweep.
pub fn fit(rows: &[SweepRow]) -> anyhow::Result<Vec<PlaneFit>> {
    let Some(first) = rows.first() else {
        bail!("no rows")
    };
    if first.d_mm.len() == 1 {
        return Ok(vec![fit_plane::<1>(rows, 0, "theta", 0, None)?]);
    }
    // α: d3 − d1, single on d3; β: d4 − d2, single on d4 (0-based indices).
    Ok(vec![
        fit_plane::<4>(rows, 0, "alpha", 2, Some(0))?,
        fit_plane::<4>(rows, 1, "beta", 3, Some(1))?,
    ])
}

/// Smallest span of reference angles a sweep must cover (deg). Below it a
/// law would fit the reference's noise (the camera's ≈ 0.03°) and the
/// wires' stick-slip, not the joint: a constant angle gave a = b = 0 with
/// 0.000° error as the "chosen" law. The paper sweeps ±20° (estimate).
pub const MIN_SWEEP_SPAN_DEG: f64 = 1.0;

/// Step of the threshold search (deg).
const THRESHOLD_GRID_DEG: f64 = 0.1;
/// Most thresholds the search tries (a 10 000° span at 0.1°).
const MAX_THRESHOLD_CANDIDATES: f64 = 100_000.0;

/// One angle of a sweep being fitted: the rows, which angle, and the
/// sensors its laws read (0-based: `plus` is pulled out on the low side,
/// `minus` its opposite, absent in 2D).
struct PlaneSweep<'a, const S: usize> {
    rows: &'a [SweepRow],
    plane: usize,
    name: &'a str,
    plus: usize,
    minus: Option<usize>,
}

impl<const S: usize> PlaneSweep<'_, S> {
    fn angle(&self, r: &SweepRow) -> f64 {
        r.angle_deg[self.plane]
    }

    /// Smallest and largest of `f` over the rows.
    fn range(&self, f: &dyn Fn(&SweepRow) -> f64) -> (f64, f64) {
        self.rows
            .iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    }

    /// Sensors of the joint: 1 (2D) or 4 (3D).
    fn sensors(&self) -> usize {
        if S == 1 {
            1
        } else {
            4
        }
    }

    /// Refuses a sweep that does not move the joint through
    /// [`MIN_SWEEP_SPAN_DEG`].
    fn check_span(&self) -> anyhow::Result<()> {
        let name = self.name;
        let (lo_deg, hi_deg) = self.range(&|r| self.angle(r));
        // (NaN spans cannot occur: the reader refuses non-finite values.)
        if hi_deg - lo_deg < MIN_SWEEP_SPAN_DEG {
            bail!(
                "{name}: the sweep's `{name}_deg` only spans {}° to {}° over its {} rows; a calibration needs the joint moved through at least {MIN_SWEEP_SPAN_DEG}° (the paper sweeps ±20°), or the law fits noise",
                short(lo_deg),
                short(hi_deg),
                self.rows.len()
            );
        }
        Ok(())
    }

    /// The errors of `law` over the sweep, if it is a usable law whose
    /// estimates stay finite.
    fn usable(&self, law: &LawSpec) -> Option<ErrorStats> {
        law.check(self.sensors()).ok()?;
        let e = evaluate::<S>(law.to_law().ok()?, self.rows, self.plane)?;
        (e.max_error_deg.is_finite() && e.rms_error_deg.is_finite()).then_some(e)
    }

    /// Why the fitted `law` (the `what` fit over input `x` spanning
    /// `x_lo..x_hi` mm) cannot be used, with the data range behind it.
    fn unusable(
        &self,
        what: &str,
        law: &LawSpec,
        x: &str,
        (x_lo, x_hi): (f64, f64),
    ) -> anyhow::Error {
        let name = self.name;
        let (a_lo, a_hi) = self.range(&|r| self.angle(r));
        let beyond_f32 = law
            .number_fields()
            .iter()
            .any(|&(_, v)| !(v as f32).is_finite());
        let (why, hint) = match law.check(self.sensors()) {
            Err(e) => (e.to_string(), beyond_f32),
            Ok(()) => (
                "its estimates are not finite in f32 on the sweep".into(),
                true,
            ),
        };
        let hint = if hint {
            ": angles this large over insertions this small need coefficients beyond f32"
        } else {
            ""
        };
        anyhow::anyhow!(
            "{name}: the {what} fit cannot be used: {why}; the sweep's {name} runs from {}° to {}° over {x} from {} to {} mm{hint}",
            short(a_lo),
            short(a_hi),
            short(x_lo),
            short(x_hi)
        )
    }

    /// The single-sensor quadratic (Eq. 2) on `plus`, and its errors.
    fn single(&self) -> anyhow::Result<(LawSpec, ErrorStats)> {
        let (name, plus) = (self.name, self.plus);
        let [a, b, c] = fit_quadratic(self.rows.iter().map(|r| (r.d_mm[plus], self.angle(r))))
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "{name}: the insertions do not determine a quadratic (sweep too narrow?)"
                )
            })?;
        let single = LawSpec::Single {
            sensor: plus as u8 + 1,
            a,
            b,
            c,
        };
        let e = self.usable(&single).ok_or_else(|| {
            self.unusable(
                "single-sensor quadratic (Eq. 2)",
                &single,
                &format!("d{}", plus + 1),
                self.range(&|r| r.d_mm[plus]),
            )
        })?;
        Ok((single, e))
    }

    /// The differential linear law (Eq. 3) on `plus − minus`, and its
    /// errors.
    fn differential(&self, minus: usize) -> anyhow::Result<(LawSpec, ErrorStats)> {
        let (name, plus) = (self.name, self.plus);
        let diff = |r: &SweepRow| r.d_mm[plus] - r.d_mm[minus];
        let [_, gain, offset] = fit_linear(self.rows.iter().map(|r| (diff(r), self.angle(r))))
            .ok_or_else(|| anyhow::anyhow!("{name}: the insertions do not determine a line"))?;
        let d = LawSpec::Differential {
            plus: plus as u8 + 1,
            minus: minus as u8 + 1,
            gain,
            offset,
        };
        let e = self.usable(&d).ok_or_else(|| {
            self.unusable(
                "differential (Eq. 3)",
                &d,
                &format!("d{} − d{}", plus + 1, minus + 1),
                self.range(&diff),
            )
        })?;
        Ok((d, e))
    }

    /// Threshold switching (Eq. 4): the threshold on a 0.1° grid within the
    /// sweep's range with the smallest worst-case error, keeping at least
    /// 15 % of the rows on each side (a branch fitted to a sliver of the
    /// range extrapolates wildly: the selector is the differential law, so
    /// such a branch would only be used there, but its coefficients would
    /// mean nothing).
    fn switching(&self, minus: usize) -> anyhow::Result<Option<(LawSpec, ErrorStats)>> {
        let (name, plus) = (self.name, self.plus);
        let diff = |r: &SweepRow| r.d_mm[plus] - r.d_mm[minus];
        let mut sorted: Vec<f64> = self.rows.iter().map(|r| self.angle(r)).collect();
        sorted.sort_by(f64::total_cmp);
        let margin = sorted.len() * 15 / 100;
        let lo = sorted[margin];
        let hi = sorted[sorted.len() - 1 - margin];
        // Beyond this many candidates the search would take hours, and
        // beyond 2^53 · 0.1° `th += 0.1` no longer moves: it never ends.
        if (hi - lo) / THRESHOLD_GRID_DEG > MAX_THRESHOLD_CANDIDATES {
            bail!(
                "{name}: the threshold search would try every {THRESHOLD_GRID_DEG}° from {}° to {}°, more than {MAX_THRESHOLD_CANDIDATES} candidates: a joint sweep spans tens of degrees (is `{name}_deg` in degrees?)",
                short(lo),
                short(hi)
            );
        }
        let mut best: Option<(LawSpec, ErrorStats)> = None;
        let mut th = (lo * 10.0).ceil() / 10.0;
        while th <= hi {
            let below = self.rows.iter().filter(|r| self.angle(r) < th);
            let above = self.rows.iter().filter(|r| self.angle(r) >= th);
            if let (Some([qa, qb, qc]), Some([_, g, o])) = (
                fit_quadratic(below.map(|r| (r.d_mm[plus], self.angle(r)))),
                fit_linear(above.map(|r| (diff(r), self.angle(r)))),
            ) {
                let s = LawSpec::Switching {
                    plus: plus as u8 + 1,
                    minus: minus as u8 + 1,
                    gain: g,
                    offset: o,
                    sensor: plus as u8 + 1,
                    a: qa,
                    b: qb,
                    c: qc,
                    threshold_deg: th,
                    hysteresis_deg: f64::from(DEFAULT_HYSTERESIS_DEG),
                };
                if let Some(e) = s
                    .to_law()
                    .ok()
                    .and_then(|l| evaluate::<S>(l, self.rows, self.plane))
                {
                    if best
                        .as_ref()
                        .is_none_or(|(_, b)| e.max_error_deg < b.max_error_deg)
                    {
                        best = Some((s, e));
                    }
                }
            }
            th += THRESHOLD_GRID_DEG;
        }
        Ok(best)
    }
}

fn fit_plane<const S: usize>(
    rows: &[SweepRow],
    plane: usize,
    name: &str,
    plus: usize,
    minus: Option<usize>,
) -> anyhow::Result<PlaneFit> {
    let sweep = PlaneSweep::<S> {
        rows,
        plane,
        name,
        plus,
        minus,
    };
    sweep.check_span()?;
    let (single, single_err) = sweep.single()?;
    let mut candidates = vec![(single.clone(), single_err)];
    let (mut differential, mut switching) = (None, None);
    if let Some(minus) = sweep.minus {
        let d = sweep.differential(minus)?;
        differential = Some(d.clone());
        candidates.push(d);
        switching = sweep.switching(minus)?;
    }
    // The simplest law wins unless switching lowers the worst-case error by
    // at least 5 %: two branches and a threshold are worth it only for a
    // real improvement, not a fitting artefact.
    let (mut chosen, mut chosen_errors) = candidates
        .into_iter()
        .min_by(|x, y| x.1.max_error_deg.total_cmp(&y.1.max_error_deg))
        .ok_or_else(|| anyhow::anyhow!("{name}: no method could be fitted"))?;
    if let Some((law, e)) = &switching {
        if e.max_error_deg < 0.95 * chosen_errors.max_error_deg {
            (chosen, chosen_errors) = (law.clone(), *e);
        }
    }
    Ok(PlaneFit {
        angle: name.into(),
        single: (single, single_err),
        differential,
        switching,
        chosen,
        chosen_errors,
    })
}

/// The calibration file of a set of fits (the chosen law per angle).
pub fn calibration_of(fits: &[PlaneFit]) -> anyhow::Result<CalibrationFile> {
    let Some(first) = fits.first() else {
        bail!("no fits")
    };
    Ok(CalibrationFile {
        alpha: first.chosen.clone(),
        beta: fits.get(1).map(|f| f.chosen.clone()),
    })
}

/// An estimation method of the calibration (Eq. 2, Eq. 3, Eq. 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// One sensor, quadratic (Eq. 2).
    Single,
    /// Two sensors, linear in their difference (Eq. 3).
    Differential,
    /// Threshold switching between the two (Eq. 4).
    Switching,
}

impl Method {
    /// The name used in tables and files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Single => "single",
            Method::Differential => "differential",
            Method::Switching => "switching",
        }
    }
}

/// A calibration file that forces one method for every angle (for
/// comparing methods in simulation).
pub fn calibration_with(fits: &[PlaneFit], method: Method) -> anyhow::Result<CalibrationFile> {
    let pick = |f: &PlaneFit| -> anyhow::Result<LawSpec> {
        let fitted = match method {
            Method::Single => Some(&f.single),
            Method::Differential => f.differential.as_ref(),
            Method::Switching => f.switching.as_ref(),
        };
        fitted
            .map(|(law, _)| law.clone())
            .ok_or_else(|| anyhow::anyhow!("{}: no {} fit", f.angle, method.name()))
    };
    let Some(first) = fits.first() else {
        bail!("no fits")
    };
    Ok(CalibrationFile {
        alpha: pick(first)?,
        beta: fits.get(1).map(pick).transpose()?,
    })
}

/// A human-readable table of the fits.
pub fn table(fits: &[PlaneFit]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<7} {:<13} {:>12} {:>12}  coefficients",
        "angle", "method", "max err (°)", "rms err (°)"
    );
    for f in fits {
        let mut rows = vec![(Method::Single.name(), &f.single)];
        if let Some(d) = &f.differential {
            rows.push((Method::Differential.name(), d));
        }
        if let Some(w) = &f.switching {
            rows.push((Method::Switching.name(), w));
        }
        for (name, (law, e)) in rows {
            let chosen = if *law == f.chosen { " ← chosen" } else { "" };
            let _ = writeln!(
                s,
                "{:<7} {:<13} {:>12.3} {:>12.3}  {}{}",
                f.angle,
                name,
                e.max_error_deg,
                e.rms_error_deg,
                describe(law),
                chosen
            );
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_2d_data_recovers_eq2() {
        let rows: Vec<SweepRow> = (0..200)
            .map(|i| {
                let d = -3.5 + 7.0 * f64::from(i) / 199.0;
                SweepRow {
                    d_mm: vec![d],
                    angle_deg: vec![0.349 * d * d - 5.525 * d + 0.753],
                }
            })
            .collect();
        let fits = fit(&rows).unwrap();
        let LawSpec::Single { a, b, c, .. } = fits[0].chosen else {
            panic!("2D must choose single")
        };
        assert!((a - 0.349).abs() < 1e-6 && (b + 5.525).abs() < 1e-6 && (c - 0.753).abs() < 1e-6);
        assert!(fits[0].chosen_errors.max_error_deg < 1e-5);
    }

    #[test]
    fn switching_beats_both_methods_on_two_sided_jamming() {
        // A synthetic α plane: the differential law is exact except where
        // wire 1 jams (α < −7: it under-reads being pushed in), the
        // quadratic on d3 is exact except where wire 3 jams (α > 0).
        let rows: Vec<SweepRow> = (0..400)
            .map(|i| {
                let alpha = -20.0 + 40.0 * f64::from(i) / 399.0;
                let mut d3 = alpha / 5.454;
                let mut d1 = -alpha / 5.454;
                if alpha > 0.0 {
                    d3 -= 0.02 * alpha; // wire 3 jams while pushed in
                }
                if alpha < -7.0 {
                    d1 -= 0.05 * (-7.0 - alpha); // wire 1 jams
                    d3 += 0.0;
                }
                // β sweeps too (clean), so its fit is determined.
                let beta = 0.5 * alpha;
                SweepRow {
                    d_mm: vec![d1, -beta / 5.34, d3, beta / 5.34],
                    angle_deg: vec![alpha, beta],
                }
            })
            .collect();
        let f = &fit(&rows).unwrap()[0];
        let sw = f.switching.as_ref().unwrap().1.max_error_deg;
        assert!(
            sw < f.single.1.max_error_deg && sw < f.differential.as_ref().unwrap().1.max_error_deg,
            "{}",
            table(std::slice::from_ref(f))
        );
        assert!(matches!(f.chosen, LawSpec::Switching { .. }));
        // Between −7° and 0° both branches are exact, so the threshold must
        // land in or near that interval (grid 0.1°).
        let th = f.chosen.threshold_deg().unwrap();
        assert!((-7.5..=0.1).contains(&th), "threshold {th}");
    }
}
