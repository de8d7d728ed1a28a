//! The contours of a data file fitted as `softjoint contour fit` fits them:
//! frame by frame (a signature r(θ) about the centroid, or a closed
//! parametric curve) or all frames at once as the signature surface over
//! time with its centroid path (the paper's jellyfish model). The report
//! gives, per fitted frame, the data and fitted contour and the frame's
//! figures (area, Eq. 40; centre; smoothness, Eq. 41; λ and its GCV
//! evidence), and the fitted splines themselves.
//!
//! Every frame carries its checks ([`crate::identify::checks`]): a frame
//! that fails one is `unverified`, with the reasons.
//!
//! Units: lengths are the data's (px for tracked contours); areas
//! length², perimeters length, Eq. 41's smoothness in the angle's units
//! (length²/rad³, independent of the knot count), the bending energy
//! `∫κ² dl` in 1/length.
//!
//! The knots default from the data (the fewest points of a frame, within
//! 4–100, or 4–40 for a surface; frames − 1 along time, within 3–50). A
//! surface is reported at every whole frame from the first to the last
//! (the frames between the data frames are the model's own).
use std::f64::consts::TAU;

use serde::Serialize;

use crate::error::{ContourError, Result};
use crate::fit::FitProblem;
use crate::fit::Solver;
use crate::identify::checks::{
    jumps, polygon_self_intersects, DenseContour, Flag, FrameChecks, Status,
};
use crate::identify::data::{ContourData, FrameData};
use crate::identify::gcv::{Lambda, LambdaReport};
use crate::identify::tracked::{
    self, chord_parameters, fit_closed_curve, fit_movie, polygon_centroid, ClosedCurveFit,
    ContourOptions, MovieFit, MovieOptions, Point, Signature, SignatureFit,
};
use crate::model::curve::sample_sites;
use rayon::prelude::*;
use std::sync::atomic::{AtomicUsize, Ordering};

/// What is fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ContourModel {
    /// Per frame, the radius about the centroid as a periodic spline of
    /// the angle (the contour must be star-shaped).
    Signature,
    /// Per frame, a closed parametric curve through the points in order.
    Curve,
    /// All frames at once: the signature surface over time and angle, and
    /// the centroid path.
    Surface,
}

impl ContourModel {
    /// The model for `data` when none is asked for: `surface` for several
    /// frames, else `signature` for angle/radius data and `curve` for
    /// points.
    pub fn default_for(data: &ContourData) -> Self {
        if data.frames.len() > 1 {
            return ContourModel::Surface;
        }
        match data.frames.first().map(|f| &f.1) {
            Some(FrameData::Points(_)) => ContourModel::Curve,
            _ => ContourModel::Signature,
        }
    }
}

/// How the contours of a file are fitted.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContourFitSpec {
    /// The model; `None` chooses by [`ContourModel::default_for`].
    pub model: Option<ContourModel>,
    /// Knot intervals around the contour; `None` from the data.
    pub knots: Option<usize>,
    /// Knot intervals along time (surface); `None` from the frames.
    pub time_knots: Option<usize>,
    /// λ or GCV (the surface's and its centroid curves').
    pub lambda: Lambda,
    /// Linear solver.
    pub solver: Solver,
    /// Points per fitted contour in the report.
    pub samples: usize,
    /// Whether signature radii may be negative (the paper's Eq. 38 test
    /// data with noise); measured distances may not.
    pub signed_radii: bool,
}

/// Most whole frames a surface is reported at; over a longer span, the
/// data frames only (to keep the output small).
pub const MAX_MODEL_FRAMES: usize = 5000;

/// The figures of one fitted frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameResult {
    pub frame: f64,
    /// Data points of the frame (0 for a surface's frame between data).
    pub points: usize,
    /// Enclosed area (Eq. 40; Green's for a closed curve), length².
    pub area: f64,
    pub centre_x: f64,
    pub centre_y: f64,
    /// Eq. 41 in the angle's units, `∫₀^{2π} (d²r/dθ²)² dθ`,
    /// length²/rad³ (signature and surface models; independent of the
    /// knot count).
    pub smoothness: Option<f64>,
    /// Length of the fitted contour.
    pub perimeter: f64,
    /// Bending energy `∫ κ² dl` of the fitted contour, 1/length (a circle
    /// of radius R: 2π/R); every model, independent of the knot count.
    pub bending_energy: f64,
    pub lambda: Option<f64>,
    pub gcv: Option<f64>,
    pub trace_hat: Option<f64>,
    pub rms_residual: Option<f64>,
    /// The frame's checks: verified or not, and why.
    pub checks: FrameChecks,
}

/// A fitted frame: its data, the fitted contour and its figures.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedFrame {
    pub frame: f64,
    /// The frame's data points (empty for a surface's frame between data).
    pub data: Vec<Point>,
    /// The fitted contour at the report's sample points.
    pub fit: Vec<Point>,
    /// Fitted radius per sample point (signature-based models).
    pub radius: Option<Vec<f64>>,
    /// Angle per sample point (signature-based models), rad.
    pub angle: Option<Vec<f64>>,
    pub result: FrameResult,
}

/// A λ report's figures without its scan.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LambdaSummary {
    pub lambda: f64,
    pub by_gcv: bool,
    pub at_scan_edge: bool,
    pub at_dof_bound: bool,
    pub gcv: Option<f64>,
    pub trace_hat: f64,
}

impl From<&LambdaReport> for LambdaSummary {
    fn from(r: &LambdaReport) -> Self {
        Self {
            lambda: r.lambda,
            by_gcv: r.by_gcv,
            at_scan_edge: r.at_scan_edge,
            at_dof_bound: r.at_dof_bound,
            gcv: r.gcv,
            trace_hat: r.trace_hat,
        }
    }
}

/// The fitted splines themselves (axes and coefficients).
#[derive(Debug, Clone, PartialEq)]
pub enum FittedSplines {
    /// Per frame number, its signature.
    Signatures(Vec<(f64, SignatureFit)>),
    /// Per frame number, its closed curve.
    Curves(Vec<(f64, ClosedCurveFit)>),
    /// The surface over all frames.
    Surface(Box<MovieFit>),
}

/// The fit of a file's contours.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourFitReport {
    pub model: ContourModel,
    /// Knot intervals around the contour.
    pub knots: usize,
    /// Knot intervals along time (surface).
    pub time_knots: Option<usize>,
    /// The fitted frames (for a surface: every whole frame, see
    /// [`MAX_MODEL_FRAMES`]).
    pub frames: Vec<FittedFrame>,
    pub splines: FittedSplines,
}

/// Sample points per knot interval of the self-intersection test (at
/// least [`MIN_CHECK_SAMPLES`] in all).
pub const CHECK_SAMPLES_PER_KNOT: usize = 16;
/// Fewest sample points of the self-intersection test.
pub const MIN_CHECK_SAMPLES: usize = 256;

fn check_samples(knots: usize) -> usize {
    (CHECK_SAMPLES_PER_KNOT * knots).max(MIN_CHECK_SAMPLES)
}

impl ContourFitReport {
    /// The surface fit (surface model).
    pub fn surface(&self) -> Option<&MovieFit> {
        match &self.splines {
            FittedSplines::Surface(fit) => Some(fit),
            _ => None,
        }
    }

    /// The frames that failed a check.
    pub fn unverified(&self) -> impl Iterator<Item = &FittedFrame> {
        self.frames.iter().filter(|f| !f.result.checks.verified())
    }

    /// What the fit reports about itself (`softjoint contour fit`'s
    /// fit.json and the Python binding's summary): `data_frames` frames
    /// fitted with `solver`.
    pub fn figures(&self, data_frames: usize, solver: Solver) -> FitFigures<'_> {
        let surface = self.surface();
        let unverified: Vec<f64> = self.unverified().map(|f| f.frame).collect();
        FitFigures {
            status: if unverified.is_empty() {
                Status::Verified
            } else {
                Status::Unverified
            },
            unverified_frames: unverified,
            model: self.model,
            solver: solver.name(),
            knots: self.knots,
            time_knots: self.time_knots,
            frames: data_frames,
            surface_lambda: surface.map(|f| (&f.lambda).into()),
            centre_lambda: surface.map(|f| (&f.centre_lambda).into()),
            surface_rms_residual: surface.map(|f| f.rms_residual),
            per_frame: self.frames.iter().map(|f| &f.result).collect(),
        }
    }
}

/// A fit's own figures: whether every frame passed its checks, the
/// model and its sizes, the λ reports and each frame's figures with its
/// checks.
#[derive(Debug, Serialize)]
pub struct FitFigures<'a> {
    /// `verified` when every frame passed its checks.
    pub status: Status,
    /// Frames that failed a check (their `checks` say why).
    pub unverified_frames: Vec<f64>,
    pub model: ContourModel,
    pub solver: &'static str,
    pub knots: usize,
    pub time_knots: Option<usize>,
    /// Frames in the data.
    pub frames: usize,
    /// The surface's λ report (surface model).
    pub surface_lambda: Option<LambdaSummary>,
    /// The centroid curves' λ report (surface model).
    pub centre_lambda: Option<LambdaSummary>,
    /// RMS radius residual of the surface (surface model).
    pub surface_rms_residual: Option<f64>,
    pub per_frame: Vec<&'a FrameResult>,
}

/// Fits the contours of `data` as `spec` says.
pub fn fit_contours(data: &ContourData, spec: &ContourFitSpec) -> Result<ContourFitReport> {
    let model = spec
        .model
        .unwrap_or_else(|| ContourModel::default_for(data));
    let knots = spec.knots.unwrap_or_else(|| {
        default_knots(
            data,
            if model == ContourModel::Surface {
                40
            } else {
                100
            },
        )
    });
    let opts = ContourOptions {
        knots,
        lambda: spec.lambda,
        solver: spec.solver,
    };
    let n = spec.samples;
    let mut time_knots = None;
    if !spec.signed_radii {
        refuse_negative_radii(data)?;
    }
    let (mut frames, splines) = match model {
        ContourModel::Signature => fit_signatures(data, &opts, n)?,
        ContourModel::Curve => fit_curves(data, &opts, n)?,
        ContourModel::Surface => {
            let tk = spec
                .time_knots
                .unwrap_or_else(|| (data.frames.len().max(1) - 1).clamp(3, 50));
            time_knots = Some(tk);
            fit_surface(data, &opts, tk, n)?
        }
    };
    if model != ContourModel::Surface {
        flag_jumps(&mut frames);
    }
    Ok(ContourFitReport {
        model,
        knots,
        time_knots,
        frames,
        splines,
    })
}

/// Radii are distances: a negative one is refused, naming the frame and
/// point, unless the data are declared signed.
fn refuse_negative_radii(data: &ContourData) -> Result<()> {
    for (frame, f) in &data.frames {
        if let FrameData::Signature(s) = f {
            if let Some(k) = s.radii.iter().position(|r| *r < 0.0) {
                return Err(ContourError::MalformedInput {
                    location: format!(
                        "{}: frame {}, point {k}",
                        data.file,
                        plant_common::short_number(*frame)
                    ),
                    reason: format!(
                        "radius {} is negative; a radius is a distance from the centre (give --signed-radii for signed test data such as the paper's Eq. 38 with noise)",
                        plant_common::short_number(s.radii[k])
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Flags the frames whose fitted area or perimeter jumps against their
/// neighbours' (relative to each frame's data polygon).
fn flag_jumps(frames: &mut [FittedFrame]) {
    let area: Vec<f64> = frames.iter().map(|f| f.result.area).collect();
    let data_area: Vec<Option<f64>> = frames.iter().map(|f| f.result.checks.data_area).collect();
    let perimeter: Vec<f64> = frames.iter().map(|f| f.result.perimeter).collect();
    let data_perimeter: Vec<Option<f64>> = frames
        .iter()
        .map(|f| f.result.checks.data_perimeter)
        .collect();
    for i in jumps(&area, &data_area) {
        frames[i].result.checks.flag(Flag::AreaJump);
    }
    for i in jumps(&perimeter, &data_perimeter) {
        frames[i].result.checks.flag(Flag::PerimeterJump);
    }
}

/// The fewest points of a frame, within 4..=`cap`.
fn default_knots(data: &ContourData, cap: usize) -> usize {
    let min_points = data.frames.iter().map(|f| f.1.len()).min().unwrap_or(4);
    min_points.clamp(4, cap)
}

/// A frame's data as a signature (points about their centroid).
fn signature_of(location: &str, f: &FrameData) -> Result<Signature> {
    Ok(match f {
        FrameData::Signature(s) => s.clone(),
        FrameData::Points(p) => Signature::from_points(location, p)?,
    })
}

/// `n` equally spaced angles around the circle, rad.
fn sample_angles(n: usize) -> Vec<f64> {
    (0..n).map(|k| TAU * k as f64 / n as f64).collect()
}

/// Each frame's signature spline.
fn fit_signatures(
    data: &ContourData,
    opts: &ContourOptions,
    n: usize,
) -> Result<(Vec<FittedFrame>, FittedSplines)> {
    let (frames, fits) = each_frame(data, |frame, f| {
        let loc = format!("{}: frame {frame}", data.file);
        let sig = signature_of(&loc, f)?;
        let (fit, problem) = tracked::fit_signature_with_problem(&loc, &sig, opts)?;
        let angle = sample_angles(n);
        let radius: Vec<f64> = angle.iter().map(|&t| fit.radius_at(t)).collect();
        let (area, perimeter) = (fit.area(), fit.radius.signature_perimeter());
        let data_points = f.points();
        let (dense, crosses_centre) = signature_dense(&fit, check_samples(opts.knots));
        let mut checks = FrameChecks::of_frame(
            Some(&fit.lambda),
            crosses_centre,
            area,
            perimeter,
            &data_points,
        );
        checks.halves(
            (area, perimeter),
            signature_halves(&loc, &sig, &problem, opts, fit.lambda.lambda),
        );
        let (gap_points, gap_t) = signature_gap_data(&sig, &fit);
        checks.gap(&gap_points, &gap_t, &dense, fit.rms_residual, area);
        let fitted = FittedFrame {
            frame,
            data: sig.points(),
            fit: fit.points(n),
            radius: Some(radius),
            angle: Some(angle),
            result: FrameResult {
                frame,
                points: f.len(),
                area,
                centre_x: fit.centre.0,
                centre_y: fit.centre.1,
                smoothness: Some(fit.radius.signature_smoothness()),
                perimeter,
                bending_energy: fit.radius.signature_bending_energy(),
                lambda: Some(fit.lambda.lambda),
                gcv: fit.lambda.gcv,
                trace_hat: Some(fit.lambda.trace_hat),
                rms_residual: Some(fit.rms_residual),
                checks,
            },
        };
        Ok((fitted, (frame, fit)))
    })?;
    Ok((frames, FittedSplines::Signatures(fits)))
}

/// Each frame's figures and checks, and its fit by frame number.
type FramesAndFits<F> = (Vec<FittedFrame>, Vec<(f64, F)>);

/// `fit` of every frame, the frames side by side on rayon's threads (each
/// frame's fit and checks depend on its data alone, so the results are
/// those of one frame after another), in frame order; the first frame
/// that fails gives the error, as it would one after another.
fn each_frame<F>(
    data: &ContourData,
    fit: impl Fn(f64, &FrameData) -> Result<(FittedFrame, (f64, F))> + Sync,
) -> Result<FramesAndFits<F>>
where
    F: Send,
{
    // Once a frame fails, the frames after it are not fitted (their
    // results could not be returned: the first failing frame's error is).
    let first_failed = AtomicUsize::new(usize::MAX);
    let results: Vec<_> = data
        .frames
        .par_iter()
        .enumerate()
        .map(|(i, (frame, f))| {
            if i > first_failed.load(Ordering::Relaxed) {
                return None;
            }
            let r = fit(*frame, f);
            if r.is_err() {
                first_failed.fetch_min(i, Ordering::Relaxed);
            }
            Some(r)
        })
        .collect();
    let mut out: FramesAndFits<F> = (Vec::new(), Vec::new());
    for r in results {
        // A frame skipped comes after one that failed, whose error has
        // been returned by then.
        let Some(r) = r else { break };
        let (fitted, fit) = r?;
        out.0.push(fitted);
        out.1.push(fit);
    }
    Ok(out)
}

/// Each frame's closed parametric curve.
fn fit_curves(
    data: &ContourData,
    opts: &ContourOptions,
    n: usize,
) -> Result<(Vec<FittedFrame>, FittedSplines)> {
    let (frames, fits) = each_frame(data, |frame, f| {
        let loc = format!("{}: frame {frame}", data.file);
        let pts = f.points();
        let fit = fit_closed_curve(&loc, &pts, opts)?;
        let area = fit.curve.signed_area().abs();
        let dense = fit.curve.sample(check_samples(opts.knots));
        let centre = polygon_centroid(&dense).map(|c| c.0).ok_or_else(|| {
            ContourError::Unsolvable(format!(
                "{loc}: the fitted curve encloses no area (all points on a line?)"
            ))
        })?;
        let perimeter = fit.curve.length(4);
        let mut checks = FrameChecks::of_frame(
            Some(&fit.lambda),
            polygon_self_intersects(&dense),
            area,
            perimeter,
            &pts,
        );
        checks.halves(
            (area, perimeter),
            curve_halves(&loc, &pts, opts, fit.lambda.lambda),
        );
        checks.gap(
            &pts,
            &chord_parameters(&loc, &pts, opts.knots)?,
            &curve_dense(&fit, check_samples(opts.knots)),
            fit.rms_residual,
            area,
        );
        let fitted = FittedFrame {
            frame,
            data: pts,
            fit: fit.curve.sample(n),
            radius: None,
            angle: None,
            result: FrameResult {
                frame,
                points: f.len(),
                area,
                centre_x: centre.0,
                centre_y: centre.1,
                smoothness: None,
                perimeter,
                bending_energy: fit.curve.bending_energy(),
                lambda: Some(fit.lambda.lambda),
                gcv: fit.lambda.gcv,
                trace_hat: Some(fit.lambda.trace_hat),
                rms_residual: Some(fit.rms_residual),
                checks,
            },
        };
        Ok((fitted, (frame, fit)))
    })?;
    Ok((frames, FittedSplines::Curves(fits)))
}

/// A signature's data points in order of angle and their parameters on
/// the fit (the gap check's input).
fn signature_gap_data(sig: &Signature, fit: &SignatureFit) -> (Vec<Point>, Vec<f64>) {
    let mut order: Vec<usize> = (0..sig.radii.len()).collect();
    order.sort_by(|&a, &b| sig.angles_rad[a].total_cmp(&sig.angles_rad[b]));
    let pts = sig.points();
    order
        .into_iter()
        .map(|k| (pts[k], fit.t_of_angle(sig.angles_rad[k])))
        .unzip()
}

/// A fitted signature sampled at `n` equally spaced parameters.
/// Also whether r ≤ 0 at any of the samples (those
/// [`signature_crosses_centre`] takes: the same sites), with r and the
/// curvature from one location of each sample's interval.
fn signature_dense(fit: &SignatureFit, n: usize) -> (DenseContour, bool) {
    let axis = &fit.radius.axis;
    let t = sample_sites(axis, n);
    let (mut points, mut kappa) = (Vec::with_capacity(n), Vec::with_capacity(n));
    let mut crosses_centre = false;
    let circle = super::circle::sites(axis, n);
    for (&t, &(cos, sin)) in t.iter().zip(circle.iter()) {
        let (r, curvature) = fit.radius.signature_radius_and_curvature(t);
        points.push((fit.centre.0 + r * cos, fit.centre.1 + r * sin));
        kappa.push(curvature);
        crosses_centre |= r <= 0.0;
    }
    let dense = DenseContour {
        period: axis.length(),
        t,
        points,
        kappa,
    };
    (dense, crosses_centre)
}

/// A fitted closed curve sampled at `n` equally spaced parameters.
fn curve_dense(fit: &ClosedCurveFit, n: usize) -> DenseContour {
    let t = sample_sites(&fit.curve.x.axis, n);
    DenseContour {
        period: fit.curve.x.axis.length(),
        points: t.iter().map(|&t| fit.curve.point(t)).collect(),
        kappa: t.iter().map(|&t| fit.curve.curvature(t)).collect(),
        t,
    }
}

/// Indices of every other point, starting at `first` (0 or 1).
fn half(n: usize, first: usize) -> impl Iterator<Item = usize> {
    (first..n).step_by(2)
}

/// Area and perimeter of the signatures fitted to each half of `sig`'s
/// points (every other one in angle order) with the knots and `lambda`
/// of the full fit; None when a half has fewer than 3 points or fails.
fn signature_halves(
    loc: &str,
    sig: &Signature,
    problem: &FitProblem,
    opts: &ContourOptions,
    lambda: f64,
) -> Option<[(f64, f64); 2]> {
    let n = sig.radii.len();
    if n < 6 {
        return None;
    }
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&a, &b| sig.angles_rad[a].total_cmp(&sig.angles_rad[b]));
    let fit_half = |first: usize| -> Option<(f64, f64)> {
        let idx: Vec<usize> = half(n, first).map(|k| order[k]).collect();
        let r = tracked::fit_signature_curve_at(
            loc,
            sig,
            &idx,
            problem,
            opts.knots,
            lambda,
            opts.solver,
        )
        .ok()?;
        Some((r.signature_area(), r.signature_perimeter()))
    };
    Some([fit_half(0)?, fit_half(1)?])
}

/// The same for a closed curve's points (every other one along it).
fn curve_halves(
    loc: &str,
    pts: &[Point],
    opts: &ContourOptions,
    lambda: f64,
) -> Option<[(f64, f64); 2]> {
    if pts.len() < 6 {
        return None;
    }
    let opts = ContourOptions {
        lambda: Lambda::Fixed(lambda),
        ..*opts
    };
    let fit_half = |first: usize| -> Option<(f64, f64)> {
        let h: Vec<Point> = half(pts.len(), first).map(|k| pts[k]).collect();
        let f = fit_closed_curve(loc, &h, &opts).ok()?;
        Some((f.curve.signed_area().abs(), f.curve.length(4)))
    };
    Some([fit_half(0)?, fit_half(1)?])
}

/// Whether a signature's radius reaches 0 or below anywhere (sampled at
/// [`check_samples`] points): its contour then passes through or behind
/// its centre and crosses itself. A positive signature is a simple,
/// star-shaped contour.
fn signature_crosses_centre(radius: &crate::model::curve::SplineCurve, knots: usize) -> bool {
    radius
        .sample(check_samples(knots))
        .iter()
        .any(|&(_, r)| r <= 0.0)
}

/// The signature surface over all frames, reported at every whole frame
/// (or at the data frames over a span of more than [`MAX_MODEL_FRAMES`]).
fn fit_surface(
    data: &ContourData,
    opts: &ContourOptions,
    time_knots: usize,
    n: usize,
) -> Result<(Vec<FittedFrame>, FittedSplines)> {
    let mut sigs = Vec::new();
    for (frame, f) in &data.frames {
        let loc = format!("{}: frame {frame}", data.file);
        sigs.push((*frame, signature_of(&loc, f)?));
    }
    let fit = fit_movie(
        &sigs,
        &MovieOptions {
            time_knots,
            angle_knots: opts.knots,
            lambda: opts.lambda,
            centre_lambda: opts.lambda,
            solver: opts.solver,
        },
    )?;
    let (f0, f1) = (fit.first_frame, fit.last_frame);
    let whole: Vec<f64> = if f1 - f0 <= MAX_MODEL_FRAMES as f64 {
        (f0.ceil() as i64..=f1.floor() as i64)
            .map(|f| f as f64)
            .collect()
    } else {
        sigs.iter().map(|s| s.0).collect()
    };
    let frames = whole
        .iter()
        .map(|&frame| surface_frame(&fit, &sigs, frame, n))
        .collect();
    Ok((frames, FittedSplines::Surface(Box::new(fit))))
}

/// The surface at one frame, with that frame's data if it has any.
fn surface_frame(fit: &MovieFit, sigs: &[(f64, Signature)], frame: f64, n: usize) -> FittedFrame {
    let data_frame = sigs.iter().find(|s| s.0 == frame);
    let angle = sample_angles(n);
    let radius: Vec<f64> = angle.iter().map(|&t| fit.radius_at(frame, t)).collect();
    let c = fit.centre_at(frame);
    let contour = fit.surface.curve_at(fit.s_of_frame(frame));
    let (area, perimeter) = (fit.area_at(frame), contour.signature_perimeter());
    let data_points = data_frame.map(|s| FrameData::Signature(s.1.clone()).points());
    let checks = FrameChecks::of_frame(
        Some(&fit.lambda),
        signature_crosses_centre(&contour, fit.surface.t_axis.intervals),
        area,
        perimeter,
        data_points.as_deref().unwrap_or_default(),
    );
    FittedFrame {
        frame,
        data: data_frame.map(|s| s.1.points()).unwrap_or_default(),
        fit: fit.contour_at(frame, n),
        radius: Some(radius),
        angle: Some(angle),
        result: FrameResult {
            frame,
            points: data_frame.map_or(0, |s| s.1.radii.len()),
            area,
            centre_x: c.0,
            centre_y: c.1,
            smoothness: Some(contour.signature_smoothness()),
            perimeter,
            bending_energy: contour.signature_bending_energy(),
            lambda: None,
            gcv: None,
            trace_hat: None,
            rms_residual: None,
            checks,
        },
    }
}
