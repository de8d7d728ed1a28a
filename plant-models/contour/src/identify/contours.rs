//! The contours of a data file fitted as `softjoint contour fit` fits them:
//! frame by frame (a signature r(θ) about the centroid, or a closed
//! parametric curve) or all frames at once as the signature surface over
//! time with its centroid path (the paper's jellyfish model). The report
//! gives, per fitted frame, the data and fitted contour and the frame's
//! figures (area, Eq. 40; centre; smoothness, Eq. 41; λ and its GCV
//! evidence), and the fitted splines themselves.
//!
//! The knots default from the data (the fewest points of a frame, within
//! 4–100, or 4–40 for a surface; frames − 1 along time, within 3–50). A
//! surface is reported at every whole frame from the first to the last
//! (the frames between the data frames are the model's own).
use std::f64::consts::TAU;

use serde::Serialize;

use crate::error::Result;
use crate::fit::Solver;
use crate::identify::data::{ContourData, FrameData};
use crate::identify::gcv::{Lambda, LambdaReport};
use crate::identify::tracked::{
    fit_closed_curve, fit_movie, fit_signature, polygon_centroid, ClosedCurveFit, ContourOptions,
    MovieFit, MovieOptions, Point, Signature, SignatureFit,
};

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
    /// Enclosed area (Eq. 40).
    pub area: f64,
    pub centre_x: f64,
    pub centre_y: f64,
    /// Eq. 41 (signature and surface models), in the spline's parameter
    /// units.
    pub smoothness: Option<f64>,
    /// Length of the fitted contour (curve model).
    pub perimeter: Option<f64>,
    pub lambda: Option<f64>,
    pub gcv: Option<f64>,
    pub trace_hat: Option<f64>,
    pub rms_residual: Option<f64>,
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
    pub gcv: f64,
    pub trace_hat: f64,
}

impl From<&LambdaReport> for LambdaSummary {
    fn from(r: &LambdaReport) -> Self {
        Self {
            lambda: r.lambda,
            by_gcv: r.by_gcv,
            at_scan_edge: r.at_scan_edge,
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

impl ContourFitReport {
    /// The surface fit (surface model).
    pub fn surface(&self) -> Option<&MovieFit> {
        match &self.splines {
            FittedSplines::Surface(fit) => Some(fit),
            _ => None,
        }
    }
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
    let (frames, splines) = match model {
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
    Ok(ContourFitReport {
        model,
        knots,
        time_knots,
        frames,
        splines,
    })
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
    let (mut frames, mut fits) = (Vec::new(), Vec::new());
    for (frame, f) in &data.frames {
        let loc = format!("{}: frame {frame}", data.file);
        let sig = signature_of(&loc, f)?;
        let fit = fit_signature(&loc, &sig, opts)?;
        let angle = sample_angles(n);
        let radius: Vec<f64> = angle.iter().map(|&t| fit.radius_at(t)).collect();
        frames.push(FittedFrame {
            frame: *frame,
            data: sig.points(),
            fit: fit.points(n),
            radius: Some(radius),
            angle: Some(angle),
            result: FrameResult {
                frame: *frame,
                points: f.len(),
                area: fit.area(),
                centre_x: fit.centre.0,
                centre_y: fit.centre.1,
                smoothness: Some(fit.radius.roughness()),
                perimeter: None,
                lambda: Some(fit.lambda.lambda),
                gcv: Some(fit.lambda.gcv),
                trace_hat: Some(fit.lambda.trace_hat),
                rms_residual: Some(fit.rms_residual),
            },
        });
        fits.push((*frame, fit));
    }
    Ok((frames, FittedSplines::Signatures(fits)))
}

/// Each frame's closed parametric curve.
fn fit_curves(
    data: &ContourData,
    opts: &ContourOptions,
    n: usize,
) -> Result<(Vec<FittedFrame>, FittedSplines)> {
    let (mut frames, mut fits) = (Vec::new(), Vec::new());
    for (frame, f) in &data.frames {
        let loc = format!("{}: frame {frame}", data.file);
        let pts = f.points();
        let fit = fit_closed_curve(&loc, &pts, opts)?;
        let area = fit.curve.signed_area();
        let centre = polygon_centroid(&fit.curve.sample(n.max(64)))
            .map(|c| c.0)
            .unwrap_or((f64::NAN, f64::NAN));
        frames.push(FittedFrame {
            frame: *frame,
            data: pts,
            fit: fit.curve.sample(n),
            radius: None,
            angle: None,
            result: FrameResult {
                frame: *frame,
                points: f.len(),
                area: area.abs(),
                centre_x: centre.0,
                centre_y: centre.1,
                smoothness: None,
                perimeter: Some(fit.curve.length(4)),
                lambda: Some(fit.lambda.lambda),
                gcv: Some(fit.lambda.gcv),
                trace_hat: Some(fit.lambda.trace_hat),
                rms_residual: Some(fit.rms_residual),
            },
        });
        fits.push((*frame, fit));
    }
    Ok((frames, FittedSplines::Curves(fits)))
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
    FittedFrame {
        frame,
        data: data_frame.map(|s| s.1.points()).unwrap_or_default(),
        fit: fit.contour_at(frame, n),
        radius: Some(radius),
        angle: Some(angle),
        result: FrameResult {
            frame,
            points: data_frame.map_or(0, |s| s.1.radii.len()),
            area: fit.area_at(frame),
            centre_x: c.0,
            centre_y: c.1,
            smoothness: Some(fit.smoothness_at(frame)),
            perimeter: None,
            lambda: None,
            gcv: None,
            trace_hat: None,
            rms_residual: None,
        },
    }
}
