//! Contours from tracked points, as the paper builds them (§IV-B): per
//! frame, the centroid o of the object and the "signature" — the distance
//! from o to the boundary at each angle θ — smoothed by a periodic spline
//! `r(θ)`; over frames, the signature as a surface periodic in θ and the
//! centroid path o(s) as smoothing curves (the jellyfish model, Fig. 4–5).
//! For contours that are not star-shaped about their centroid (a block
//! with a deep dent), a closed parametric curve `(x(t), y(t))` with t the
//! chord length, scaled to the knot count.
//!
//! Conventions (the paper's §IV: α = β = 1): an axis with m knot intervals
//! spans `[0, m]`; the angle axis maps θ = 2π t/m; the time axis maps the
//! first and last frame to s = 0 and s = m₁. Default weights are 1/N
//! (Eq. 29; the jellyfish used w = 1/(N₁N₂)).
use crate::error::{check_finite, ContourError, Result};
use crate::identify::gcv::{check_lambda, factor_with, Lambda, LambdaReport};
use crate::model::basis::{rem_period, Axis};
use crate::model::curve::{curve_problem, ClosedCurve, SplineCurve};
use crate::model::fit::{FitProblem, Solver};
use crate::model::surface::{surface_problem, SplineSurface};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;
use std::sync::Arc;

/// A point of the image plane (px, or any length unit).
pub type Point = (f64, f64);

/// Fewest points of one contour.
pub const MIN_CONTOUR_POINTS: usize = 3;

/// Area centroid and signed area (counter-clockwise positive) of a closed
/// polygon; `None` when the area is 0 or not finite.
pub fn polygon_centroid(points: &[Point]) -> Option<(Point, f64)> {
    let n = points.len();
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (x0, y0) = points[i];
        let (x1, y1) = points[(i + 1) % n];
        let c = x0 * y1 - x1 * y0;
        a += c;
        cx += (x0 + x1) * c;
        cy += (y0 + y1) * c;
    }
    a *= 0.5;
    if a == 0.0 || !a.is_finite() {
        return None;
    }
    Some(((cx / (6.0 * a), cy / (6.0 * a)), a))
}

/// One frame's signature: radii at angles about a centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Signature {
    /// The centre o (the object's centroid).
    pub centre: Point,
    /// Angles θ, rad, in [0, 2π).
    pub angles_rad: Vec<f64>,
    /// Distances from o to the boundary (noisy data may dip below 0).
    pub radii: Vec<f64>,
}

impl Signature {
    /// A signature from angles and radii about `centre` (angles are wrapped
    /// into [0, 2π)); checked (see [`validate`](Self::validate)).
    pub fn new(location: &str, centre: Point, angles_rad: &[f64], radii: &[f64]) -> Result<Self> {
        let s = Self {
            centre,
            angles_rad: angles_rad.iter().map(|a| a.rem_euclid(TAU)).collect(),
            radii: radii.to_vec(),
        };
        for (k, a) in angles_rad.iter().enumerate() {
            if !a.is_finite() {
                return Err(ContourError::NonFinite {
                    location: format!("{location}, point {k}"),
                    what: "angle_rad",
                    value: *a,
                });
            }
        }
        s.validate(location)?;
        Ok(s)
    }

    /// The signature of an ordered contour about its area centroid (the
    /// paper's centroid of the binary image). The contour must be
    /// star-shaped about it: the angle must turn one way round along the
    /// points, or the radius is not a function of the angle.
    pub fn from_points(location: &str, points: &[Point]) -> Result<Self> {
        check_points(location, points)?;
        let (centre, _) = polygon_centroid(points).ok_or_else(|| ContourError::MalformedInput {
            location: location.to_string(),
            reason: "the contour encloses no area (all points on a line?)".into(),
        })?;
        let mut angles = Vec::with_capacity(points.len());
        let mut radii = Vec::with_capacity(points.len());
        for &(x, y) in points {
            let (dx, dy) = (x - centre.0, y - centre.1);
            angles.push(dy.atan2(dx).rem_euclid(TAU));
            radii.push(dx.hypot(dy));
        }
        // Star-shaped: every step of the angle along the contour has the
        // same sign (wrapped to (−π, π]).
        let n = angles.len();
        let steps: Vec<f64> = (0..n)
            .map(|i| {
                let d = angles[(i + 1) % n] - angles[i];
                (d + std::f64::consts::PI).rem_euclid(TAU) - std::f64::consts::PI
            })
            .collect();
        let turn: f64 = steps.iter().sum();
        let sign = turn.signum();
        if let Some(i) = steps.iter().position(|s| s * sign <= 0.0) {
            return Err(ContourError::MalformedInput {
                location: format!("{location}, point {}", (i + 1) % n),
                reason: "the contour is not star-shaped about its centroid (the angle turns back here), so it has no signature r(θ); fit it as a closed parametric curve instead".into(),
            });
        }
        Self::new(location, centre, &angles, &radii)
    }

    /// Checks: ≥ 3 points, finite values, no two equal angles. A radius
    /// may be negative: measured distances are not, but noisy data (Eq. 38
    /// with σ = 0.3 near r ≈ 0.46) can be, and the fit does not mind.
    pub fn validate(&self, location: &str) -> Result<()> {
        if self.angles_rad.len() != self.radii.len() {
            return Err(ContourError::LengthMismatch {
                what: "radii",
                got: self.radii.len(),
                expected: self.angles_rad.len(),
            });
        }
        let n = self.radii.len();
        if n < MIN_CONTOUR_POINTS {
            return Err(ContourError::TooFewPoints {
                location: location.to_string(),
                got: n,
                needed: MIN_CONTOUR_POINTS,
                why: "a closed contour",
            });
        }
        for (what, v) in [("centre_x", self.centre.0), ("centre_y", self.centre.1)] {
            if !v.is_finite() {
                return Err(ContourError::NonFinite {
                    location: location.to_string(),
                    what,
                    value: v,
                });
            }
        }
        for (k, (&a, &r)) in self.angles_rad.iter().zip(&self.radii).enumerate() {
            for (what, v) in [("angle_rad", a), ("radius", r)] {
                if !v.is_finite() {
                    return Err(ContourError::NonFinite {
                        location: format!("{location}, point {k}"),
                        what,
                        value: v,
                    });
                }
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| self.angles_rad[a].total_cmp(&self.angles_rad[b]));
        for w in 0..n {
            let (i, j) = (order[w], order[(w + 1) % n]);
            let mut gap = self.angles_rad[j] - self.angles_rad[i];
            if w + 1 == n {
                gap += TAU;
            }
            if gap.abs() < DUPLICATE_ANGLE_RAD {
                return Err(ContourError::DuplicateParameter {
                    location: location.to_string(),
                    axis: "angle",
                    value: self.angles_rad[i],
                    first: i.min(j),
                    second: i.max(j),
                });
            }
        }
        Ok(())
    }

    /// The contour points `o + r(cos θ, sin θ)`.
    pub fn points(&self) -> Vec<Point> {
        self.angles_rad
            .iter()
            .zip(&self.radii)
            .map(|(a, r)| (self.centre.0 + r * a.cos(), self.centre.1 + r * a.sin()))
            .collect()
    }
}

/// Two angles closer than this (rad) are the same angle.
pub const DUPLICATE_ANGLE_RAD: f64 = 1e-9;

fn check_points(location: &str, points: &[Point]) -> Result<()> {
    if points.len() < MIN_CONTOUR_POINTS {
        return Err(ContourError::TooFewPoints {
            location: location.to_string(),
            got: points.len(),
            needed: MIN_CONTOUR_POINTS,
            why: "a closed contour",
        });
    }
    for (k, &(x, y)) in points.iter().enumerate() {
        for (what, v) in [("x", x), ("y", y)] {
            if !v.is_finite() {
                return Err(ContourError::NonFinite {
                    location: format!("{location}, point {k}"),
                    what,
                    value: v,
                });
            }
        }
    }
    Ok(())
}

/// How a contour is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ContourOptions {
    /// Knot intervals m around the contour.
    pub knots: usize,
    /// λ or GCV.
    pub lambda: Lambda,
    /// Linear solver.
    pub solver: Solver,
}

/// A fitted signature `r(θ)` about a centre.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SignatureFit {
    /// The centre o.
    pub centre: Point,
    /// r as a periodic spline of t ∈ [0, m), θ = 2π t/m.
    pub radius: SplineCurve,
    /// λ and its GCV score.
    pub lambda: LambdaReport,
    /// Root-mean-square of the fit's residuals r̂ − r at the data.
    pub rms_residual: f64,
}

impl SignatureFit {
    /// Spline parameter of angle θ.
    pub fn t_of_angle(&self, angle_rad: f64) -> f64 {
        self.radius.axis.length() * rem_period(angle_rad, TAU) / TAU
    }

    /// r̂(θ).
    pub fn radius_at(&self, angle_rad: f64) -> f64 {
        self.radius.value(self.t_of_angle(angle_rad))
    }

    /// The fitted contour at `n` equally spaced angles.
    pub fn points(&self, n: usize) -> Vec<Point> {
        let circle = super::circle::turn(n);
        (0..n)
            .zip(circle.iter())
            .map(|(k, &(cos, sin))| {
                let r = self.radius_at(super::circle::turn_angle(k, n));
                (self.centre.0 + r * cos, self.centre.1 + r * sin)
            })
            .collect()
    }

    /// Enclosed area (Eq. 40 for one frame).
    pub fn area(&self) -> f64 {
        self.radius.signature_area()
    }
}

/// Fits a signature (the paper's periodic contour spline).
pub fn fit_signature(
    location: &str,
    sig: &Signature,
    opts: &ContourOptions,
) -> Result<SignatureFit> {
    Ok(fit_signature_with_problem(location, sig, opts)?.0)
}

/// [`fit_signature`] and the quadratic problem it solved (at `sig`'s
/// angles), from which the halves check takes its halves' rows.
pub(crate) fn fit_signature_with_problem(
    location: &str,
    sig: &Signature,
    opts: &ContourOptions,
) -> Result<(SignatureFit, Arc<FitProblem>)> {
    let (axis, problem) = signature_problem(location, sig, opts.knots)?;
    let (fitter, report) = factor_with(&problem, opts.lambda, opts.solver, &[&sig.radii])?;
    let tau = fitter.solve(&sig.radii)?;
    let rms = rms(&fitter.fitted(&tau), &sig.radii);
    let fit = SignatureFit {
        centre: sig.centre,
        radius: SplineCurve::new(axis, tau)?,
        lambda: report,
        rms_residual: rms,
    };
    Ok((fit, problem))
}

/// The spline [`fit_signature`] fits for a given λ, without what it
/// reports beside it (the GCV score, tr H, the residual): the halves
/// check needs only the curves, and tr H was most of a half's fit.
pub fn fit_signature_curve(
    location: &str,
    sig: &Signature,
    knots: usize,
    lambda: f64,
    solver: Solver,
) -> Result<SplineCurve> {
    check_lambda(lambda)?;
    let (axis, problem) = signature_problem(location, sig, knots)?;
    let tau = problem.fitter(lambda, solver)?.solve(&sig.radii)?;
    SplineCurve::new(axis, tau)
}

/// [`fit_signature_curve`] for the signature of `sig`'s points `keep`
/// (in that order), whose rows it takes from `full`, the problem at all
/// of `sig`'s angles ([`fit_signature_with_problem`]): the same curve to
/// the bit, without evaluating the basis at those angles again. The
/// points' signature is validated as [`Signature::new`] validates it.
pub(crate) fn fit_signature_curve_at(
    location: &str,
    sig: &Signature,
    keep: &[usize],
    full: &FitProblem,
    knots: usize,
    lambda: f64,
    solver: Solver,
) -> Result<SplineCurve> {
    check_lambda(lambda)?;
    let angles: Vec<f64> = keep.iter().map(|&k| sig.angles_rad[k]).collect();
    let radii: Vec<f64> = keep.iter().map(|&k| sig.radii[k]).collect();
    let part = Signature::new(location, sig.centre, &angles, &radii)?;
    let axis = Axis::over(0.0, knots as f64, knots, true)?;
    // `full` must be the problem on this axis (its coefficients tell).
    if full.coefficients() != axis.coefficients() {
        return Err(ContourError::LengthMismatch {
            what: "the full problem's coefficients",
            got: full.coefficients(),
            expected: axis.coefficients(),
        });
    }
    let problem = full
        .samples_at(keep)
        .ok_or(ContourError::InvalidParameter {
            name: "sample index",
            value: keep.iter().copied().max().unwrap_or(0) as f64,
            reason: "a part's samples must be some of the full problem's",
        })?;
    let tau = Arc::new(problem)
        .fitter(lambda, solver)?
        .solve(&part.radii)?;
    SplineCurve::new(axis, tau)
}

/// The periodic axis of `knots` intervals over the angle and the fit's
/// quadratic problem at the signature's angles.
fn signature_problem(
    location: &str,
    sig: &Signature,
    knots: usize,
) -> Result<(Axis, Arc<FitProblem>)> {
    sig.validate(location)?;
    let axis = Axis::over(0.0, knots as f64, knots, true)?;
    let sites: Vec<f64> = sig
        .angles_rad
        .iter()
        .map(|a| axis.length() * a / TAU)
        .collect();
    Ok((axis, curve_problem(&axis, &sites, None)?))
}

fn rms(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().max(1) as f64;
    (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n).sqrt()
}

/// A fitted closed parametric curve.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClosedCurveFit {
    /// (x(t), y(t)), t ∈ [0, m).
    pub curve: ClosedCurve,
    /// λ and its GCV score (x and y share λ).
    pub lambda: LambdaReport,
    /// Root-mean-square distance between data points and their fitted
    /// points.
    pub rms_residual: f64,
}

/// Chord-length parameters of an ordered closed contour, scaled to
/// `[0, m)`; refuses repeated consecutive points.
pub fn chord_parameters(location: &str, points: &[Point], m: usize) -> Result<Vec<f64>> {
    let n = points.len();
    let mut cum = Vec::with_capacity(n);
    let mut total = 0.0;
    for i in 0..n {
        cum.push(total);
        let (a, b) = (points[i], points[(i + 1) % n]);
        let d = (b.0 - a.0).hypot(b.1 - a.1);
        if d == 0.0 {
            return Err(ContourError::DuplicateParameter {
                location: location.to_string(),
                axis: "point",
                value: i as f64,
                first: i,
                second: (i + 1) % n,
            });
        }
        total += d;
    }
    Ok(cum.into_iter().map(|c| m as f64 * c / total).collect())
}

/// Fits a closed parametric curve to points in order along the contour.
pub fn fit_closed_curve(
    location: &str,
    points: &[Point],
    opts: &ContourOptions,
) -> Result<ClosedCurveFit> {
    check_points(location, points)?;
    let axis = Axis::over(0.0, opts.knots as f64, opts.knots, true)?;
    let sites = chord_parameters(location, points, opts.knots)?;
    let xs: Vec<f64> = points.iter().map(|p| p.0).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.1).collect();
    let problem = curve_problem(&axis, &sites, None)?;
    let (fitter, report) = factor_with(&problem, opts.lambda, opts.solver, &[&xs, &ys])?;
    let (tx, ty) = (fitter.solve(&xs)?, fitter.solve(&ys)?);
    let (fx, fy) = (fitter.fitted(&tx), fitter.fitted(&ty));
    let n = points.len() as f64;
    let rms = (points
        .iter()
        .zip(fx.iter().zip(&fy))
        .map(|(p, (x, y))| (p.0 - x).powi(2) + (p.1 - y).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    Ok(ClosedCurveFit {
        curve: ClosedCurve {
            x: SplineCurve::new(axis, tx)?,
            y: SplineCurve::new(axis, ty)?,
        },
        lambda: report,
        rms_residual: rms,
    })
}

/// How a deforming contour (contour × time) is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MovieOptions {
    /// Knot intervals m₁ along time (s ∈ [0, m₁] spans first to last frame).
    pub time_knots: usize,
    /// Knot intervals m₂ around the contour (t ∈ [0, m₂), θ = 2πt/m₂).
    pub angle_knots: usize,
    /// λ of the surface, or GCV.
    pub lambda: Lambda,
    /// λ of the centroid path's smoothing curves, or GCV.
    pub centre_lambda: Lambda,
    /// Linear solver.
    pub solver: Solver,
}

/// The deforming contour: the signature surface x(s, t) and the centroid
/// path o(s) (paper Fig. 4–5).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MovieFit {
    /// Radius over time s and angle parameter t.
    pub surface: SplineSurface,
    /// Centroid x over s.
    pub centre_x: SplineCurve,
    /// Centroid y over s.
    pub centre_y: SplineCurve,
    /// Frame number at s = 0.
    pub first_frame: f64,
    /// Frame number at s = m₁.
    pub last_frame: f64,
    /// λ of the surface.
    pub lambda: LambdaReport,
    /// λ of the centroid curves.
    pub centre_lambda: LambdaReport,
    /// RMS of the radius residuals at the data.
    pub rms_residual: f64,
}

impl MovieFit {
    /// s of a frame number.
    pub fn s_of_frame(&self, frame: f64) -> f64 {
        let a = &self.surface.s_axis;
        a.start + a.length() * (frame - self.first_frame) / (self.last_frame - self.first_frame)
    }

    /// The centroid at a frame.
    pub fn centre_at(&self, frame: f64) -> Point {
        let s = self.s_of_frame(frame);
        (self.centre_x.value(s), self.centre_y.value(s))
    }

    /// The fitted signature at a frame, as a [`SignatureFit`] without data
    /// statistics.
    pub fn radius_at(&self, frame: f64, angle_rad: f64) -> f64 {
        let t = self.surface.t_axis.length() * angle_rad.rem_euclid(TAU) / TAU;
        self.surface.value(self.s_of_frame(frame), t)
    }

    /// The contour at a frame, `n` equally spaced angles.
    pub fn contour_at(&self, frame: f64, n: usize) -> Vec<Point> {
        let c = self.centre_at(frame);
        (0..n)
            .map(|k| {
                let a = TAU * k as f64 / n as f64;
                let r = self.radius_at(frame, a);
                (c.0 + r * a.cos(), c.1 + r * a.sin())
            })
            .collect()
    }

    /// Area at a frame (Eq. 40).
    pub fn area_at(&self, frame: f64) -> f64 {
        self.surface.area(self.s_of_frame(frame))
    }

    /// Smoothness at a frame (Eq. 41), in the units of the t axis.
    pub fn smoothness_at(&self, frame: f64) -> f64 {
        self.surface.smoothness(self.s_of_frame(frame))
    }
}

/// Fits the deforming contour to signatures at frame numbers (at least
/// two distinct frames).
pub fn fit_movie(frames: &[(f64, Signature)], opts: &MovieOptions) -> Result<MovieFit> {
    let mut distinct: Vec<f64> = frames.iter().map(|f| f.0).collect();
    for (k, f) in distinct.iter().enumerate() {
        check_finite("frame", *f).map_err(|_| ContourError::NonFinite {
            location: format!("frame entry {k}"),
            what: "frame",
            value: *f,
        })?;
    }
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() < 2 {
        return Err(ContourError::TooFewPoints {
            location: "time axis".into(),
            got: distinct.len(),
            needed: 2,
            why: "a contour over time needs two frames",
        });
    }
    let (f0, f1) = (distinct[0], distinct[distinct.len() - 1]);
    let s_axis = Axis::over(0.0, opts.time_knots as f64, opts.time_knots, false)?;
    let t_axis = Axis::over(0.0, opts.angle_knots as f64, opts.angle_knots, true)?;
    let s_of = |f: f64| s_axis.length() * (f - f0) / (f1 - f0);
    let mut sites = Vec::new();
    let mut d = Vec::new();
    let mut centre_s = Vec::new();
    let (mut cx, mut cy) = (Vec::new(), Vec::new());
    for (frame, sig) in frames {
        sig.validate(&format!("frame {}", plant_common::short_number(*frame)))?;
        let s = s_of(*frame);
        for (a, r) in sig.angles_rad.iter().zip(&sig.radii) {
            sites.push((s, t_axis.length() * a / TAU));
            d.push(*r);
        }
        centre_s.push(s);
        cx.push(sig.centre.0);
        cy.push(sig.centre.1);
    }
    let problem = surface_problem(&s_axis, &t_axis, &sites, None)?;
    let (fitter, report) = factor_with(&problem, opts.lambda, opts.solver, &[&d])?;
    let tau = fitter.solve(&d)?;
    let rms_residual = rms(&fitter.fitted(&tau), &d);
    let cproblem = curve_problem(&s_axis, &centre_s, None)?;
    let (cfit, creport) = factor_with(&cproblem, opts.centre_lambda, opts.solver, &[&cx, &cy])?;
    Ok(MovieFit {
        surface: SplineSurface::new(s_axis, t_axis, tau)?,
        centre_x: SplineCurve::new(s_axis, cfit.solve(&cx)?)?,
        centre_y: SplineCurve::new(s_axis, cfit.solve(&cy)?)?,
        first_frame: f0,
        last_frame: f1,
        lambda: report,
        centre_lambda: creport,
        rms_residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// A half's curve from the full problem's rows is the curve fitted to
    /// the half's own signature, to the bit: random signatures (uneven
    /// angles, any order), random subsets, both solvers.
    #[test]
    fn a_curve_from_the_full_problems_rows_is_the_halfs_own_fit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(34);
        for case in 0..60 {
            let n = rng.gen_range(12..80);
            let mut angles: Vec<f64> = (0..n)
                .map(|k| (k as f64 + rng.gen_range(-0.3..0.3)) * TAU / n as f64)
                .collect();
            // Some angles given outside [0, 2π): the signature wraps them.
            for a in angles.iter_mut().filter(|_| rng.gen_bool(0.1)) {
                *a += TAU;
            }
            let radii: Vec<f64> = angles
                .iter()
                .map(|a| 30.0 + 5.0 * (2.0 * a).cos() + rng.gen_range(-0.5..0.5))
                .collect();
            let sig = Signature::new("case", (1.0, -2.0), &angles, &radii).unwrap();
            let knots = rng.gen_range(4..12);
            let solver = if case % 2 == 0 {
                Solver::Reduced
            } else {
                Solver::Kkt
            };
            let opts = ContourOptions {
                knots,
                lambda: crate::identify::gcv::Lambda::Fixed(1e-3),
                solver,
            };
            let (_, full) = fit_signature_with_problem("case", &sig, &opts).unwrap();
            let mut keep: Vec<usize> = (0..n).filter(|_| rng.gen_bool(0.5)).collect();
            if keep.len() < 8 {
                continue;
            }
            // Any order: the rows follow `keep`.
            keep.reverse();
            let lambda = 10f64.powf(rng.gen_range(-6.0..0.0));
            let got =
                fit_signature_curve_at("case", &sig, &keep, &full, knots, lambda, solver).unwrap();
            let a: Vec<f64> = keep.iter().map(|&k| sig.angles_rad[k]).collect();
            let r: Vec<f64> = keep.iter().map(|&k| sig.radii[k]).collect();
            let own = Signature::new("case", sig.centre, &a, &r).unwrap();
            let want = fit_signature_curve("case", &own, knots, lambda, solver).unwrap();
            // Debug text: every digit of every coefficient (and ±0).
            assert_eq!(format!("{got:?}"), format!("{want:?}"), "case {case}");
        }
    }
}
