//! `softjoint contour`: periodic and closed smoothing splines (Fujioka &
//! Kano, seed 000) for tracked contours.
//!
//! * `fit` — read a CSV of contour points (per frame), fit each frame's
//!   contour (a signature r(θ) about the centroid, or a closed parametric
//!   curve) or the whole deforming contour as a surface over time, and
//!   write the fitted contours, areas (Eq. 40), smoothness (Eq. 41) and
//!   pictures of data and fit;
//! * `synth` — write the paper's test cases: the red-blood-cell surface of
//!   Eq. 38 sampled with noise, and a pulsating, translating contour movie.
//!
//! The splines live in `plant_contour`; this is argument handling,
//! files and pictures.
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use host_tools::output::{self, JsonObject};
use host_tools::plot::{self, Chart, Panel, Series, Shape, ShapeStyle};
use host_tools::{out, outln};
use plant_common::rng;
use plant_contour::fit::Solver;
use plant_contour::identify::data::{read_contour_csv, ContourData, FrameData};
use plant_contour::identify::gcv::{Lambda, LambdaReport};
use plant_contour::identify::movie::{PulsatingContour, TRUTH_POINTS};
use plant_contour::identify::paper::{self, rbc_surface, DOMAIN};
use plant_contour::identify::tracked::{
    fit_closed_curve, fit_movie, fit_signature, ContourOptions, MovieOptions, Point, Signature,
};
use serde::Serialize;

/// Arguments of `softjoint contour`.
#[derive(Args)]
pub struct ContourArgs {
    #[command(subcommand)]
    command: ContourCommand,
}

#[derive(Subcommand)]
enum ContourCommand {
    /// Fit smoothing splines to tracked contours in a CSV: columns
    /// `angle_rad,radius` (optionally `centre_x,centre_y`) or `x,y`, each
    /// optionally with `frame`; one row per contour point.
    Fit(FitArgs),
    /// Write one of the paper's test cases as CSV (and a picture).
    Synth(SynthArgs),
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum, Serialize)]
#[serde(rename_all = "lowercase")]
enum ModelArg {
    /// Per frame, the radius about the centroid as a periodic spline of
    /// the angle (the paper's signature; the contour must be star-shaped).
    Signature,
    /// Per frame, a closed parametric curve (x(t), y(t)) through the points
    /// in order (any contour shape).
    Curve,
    /// All frames at once: the signature as a surface over time and angle,
    /// periodic in the angle, and the centroid path as smoothing curves
    /// (the paper's jellyfish model).
    Surface,
}

#[derive(Clone, Copy, ValueEnum)]
enum SolverArg {
    /// Periodic ties eliminated, banded Cholesky.
    Reduced,
    /// The dense KKT system of Eq. 27 (minimum-norm solution; small fits).
    Kkt,
}

#[derive(Args)]
struct FitArgs {
    /// The CSV of contour points.
    input: PathBuf,
    /// What to fit. Default: `surface` for several frames, else
    /// `signature` for angle/radius data and `curve` for x/y points.
    #[arg(long, value_enum)]
    model: Option<ModelArg>,
    /// Knot intervals around the contour. Default: the fewest points of a
    /// frame, within 4–100 (4–40 for a surface).
    #[arg(allow_negative_numbers = true, long)]
    knots: Option<usize>,
    /// Knot intervals along time (surface). Default: frames − 1, within
    /// 3–50 (the paper: 10 for 11 frames).
    #[arg(allow_negative_numbers = true, long)]
    time_knots: Option<usize>,
    /// Smoothing parameter λ (> 0; the paper uses 1e-3 and 5e-4 with
    /// weights 1/N), or `gcv` to choose it by generalised cross-validation.
    #[arg(long, default_value = "gcv", allow_hyphen_values = true)]
    lambda: String,
    /// Linear solver.
    #[arg(long, value_enum, default_value = "reduced")]
    solver: SolverArg,
    /// Points per fitted contour in the output.
    #[arg(allow_negative_numbers = true, long, default_value_t = 200)]
    samples: usize,
    /// Output directory.
    #[arg(long, default_value = "contour-out")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum SynthCase {
    /// Eq. 38 (red blood cell) on an N × N grid of (time, angle) with
    /// Gaussian noise: a contour whose shape changes over "time" s.
    Rbc,
    /// A pulsating, translating three-lobed contour, 101 frames, observed
    /// as centroid and radii along rays (the paper's jellyfish set-up).
    Movie,
}

#[derive(Args)]
struct SynthArgs {
    /// Which case.
    #[arg(long, value_enum)]
    case: SynthCase,
    /// Rbc: N₁ = N₂ = N grid points (the paper: 5 and 40).
    #[arg(allow_negative_numbers = true, long, default_value_t = 40)]
    n: usize,
    /// Noise standard deviation (rbc: 0.3 as the paper; movie: 1 px).
    #[arg(long, allow_hyphen_values = true)]
    sigma: Option<f64>,
    /// Movie: keep every k-th frame (the paper: 10, i.e. 11 of 101).
    #[arg(allow_negative_numbers = true, long, default_value_t = 10)]
    every: usize,
    /// Movie: rays (angles) per frame (the paper: 10).
    #[arg(allow_negative_numbers = true, long, default_value_t = 10)]
    angles: usize,
    /// Seed of the noise.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Output directory.
    #[arg(long, default_value = "contour-synth")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
}

/// Runs `softjoint contour`.
pub fn run(args: ContourArgs) -> Result<()> {
    match args.command {
        ContourCommand::Fit(a) => fit_cmd(a),
        ContourCommand::Synth(a) => synth_cmd(a),
    }
}

fn parse_lambda(text: &str) -> Result<Lambda> {
    if text.trim().eq_ignore_ascii_case("gcv") {
        return Ok(Lambda::Gcv);
    }
    let v: f64 = text
        .trim()
        .parse()
        .with_context(|| format!("--lambda `{text}`: expected a number > 0 or `gcv`"))?;
    if !(v.is_finite() && v > 0.0) {
        bail!("--lambda {text}: λ must be a finite number > 0 (or `gcv`)");
    }
    Ok(Lambda::Fixed(v))
}

/// Writes a CSV or SVG through `host_tools::output`, which refuses
/// non-finite numbers.
fn write(path: &Path, text: &str) -> Result<()> {
    if path.extension().is_some_and(|e| e == "csv") {
        output::write_csv(path, text)
    } else {
        output::write_svg(path, text)
    }
}

/// Per-frame results.
#[derive(Serialize)]
struct FrameResult {
    frame: f64,
    points: usize,
    area: f64,
    centre_x: f64,
    centre_y: f64,
    /// Eq. 41 (signature and surface models), in the spline's parameter
    /// units.
    smoothness: Option<f64>,
    /// Length of the fitted contour (curve model).
    perimeter: Option<f64>,
    lambda: Option<f64>,
    gcv: Option<f64>,
    trace_hat: Option<f64>,
    rms_residual: Option<f64>,
}

#[derive(Serialize)]
struct FitSummary {
    input: String,
    model: ModelArg,
    solver: &'static str,
    knots: usize,
    time_knots: Option<usize>,
    frames: usize,
    /// The surface's λ report (surface model).
    surface_lambda: Option<LambdaSummary>,
    /// The centroid curves' λ report (surface model).
    centre_lambda: Option<LambdaSummary>,
    /// RMS radius residual of the surface (surface model).
    surface_rms_residual: Option<f64>,
    per_frame: Vec<FrameResult>,
    out: String,
    files: Vec<&'static str>,
}

#[derive(Serialize)]
struct LambdaSummary {
    lambda: f64,
    by_gcv: bool,
    at_scan_edge: bool,
    gcv: f64,
    trace_hat: f64,
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

/// A fitted frame ready for output.
struct FittedFrame {
    frame: f64,
    data: Vec<Point>,
    fit: Vec<Point>,
    /// Fitted radius per output point (signature-based models).
    radius: Option<Vec<f64>>,
    angle: Option<Vec<f64>>,
    result: FrameResult,
}

/// Most whole frames the surface model is written at.
const MAX_MODEL_FRAMES: usize = 5000;

fn default_knots(data: &ContourData, cap: usize) -> usize {
    let min_points = data.frames.iter().map(|f| f.1.len()).min().unwrap_or(4);
    min_points.clamp(4, cap)
}

fn signature_of(location: &str, f: &FrameData) -> Result<Signature> {
    Ok(match f {
        FrameData::Signature(s) => s.clone(),
        FrameData::Points(p) => Signature::from_points(location, p)?,
    })
}

fn fit_cmd(a: FitArgs) -> Result<()> {
    let lambda = parse_lambda(&a.lambda)?;
    if !(3..=100_000).contains(&a.samples) {
        bail!("--samples must be 3..=100000, got {}", a.samples);
    }
    let text =
        fs::read_to_string(&a.input).with_context(|| format!("reading {}", a.input.display()))?;
    let file = a.input.display().to_string();
    let data = read_contour_csv(&text, &file)?;
    let model = a.model.unwrap_or(if data.frames.len() > 1 {
        ModelArg::Surface
    } else {
        match data.frames[0].1 {
            FrameData::Signature(_) => ModelArg::Signature,
            FrameData::Points(_) => ModelArg::Curve,
        }
    });
    let solver = match a.solver {
        SolverArg::Reduced => Solver::Reduced,
        SolverArg::Kkt => Solver::Kkt,
    };
    let knots = a
        .knots
        .unwrap_or_else(|| default_knots(&data, if model == ModelArg::Surface { 40 } else { 100 }));
    let opts = ContourOptions {
        knots,
        lambda,
        solver,
    };
    let n = a.samples;
    let mut frames = Vec::new();
    let mut surface = None;
    // The fitted splines themselves (axes and coefficients), per frame or
    // the surface, for spline.json.
    let mut splines: Vec<JsonObject> = Vec::new();
    let mut time_knots = None;
    match model {
        ModelArg::Signature => {
            for (frame, f) in &data.frames {
                let loc = format!("{file}: frame {frame}");
                let sig = signature_of(&loc, f)?;
                let fit = fit_signature(&loc, &sig, &opts)?;
                splines.push(
                    JsonObject::new()
                        .field("frame", frame)?
                        .field("signature", &fit)?,
                );
                let angle: Vec<f64> = (0..n)
                    .map(|k| std::f64::consts::TAU * k as f64 / n as f64)
                    .collect();
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
            }
        }
        ModelArg::Curve => {
            for (frame, f) in &data.frames {
                let loc = format!("{file}: frame {frame}");
                let pts = f.points();
                let fit = fit_closed_curve(&loc, &pts, &opts)?;
                splines.push(
                    JsonObject::new()
                        .field("frame", frame)?
                        .field("closed_curve", &fit)?,
                );
                let area = fit.curve.signed_area();
                let centre = plant_contour::identify::tracked::polygon_centroid(
                    &fit.curve.sample(n.max(64)),
                )
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
            }
        }
        ModelArg::Surface => {
            if data.frames.len() < 2 {
                bail!(
                    "{file}: --model surface needs at least two frames (column `frame`), found one"
                );
            }
            let tk = a
                .time_knots
                .unwrap_or_else(|| (data.frames.len() - 1).clamp(3, 50));
            time_knots = Some(tk);
            let mut sigs = Vec::new();
            for (frame, f) in &data.frames {
                sigs.push((*frame, signature_of(&format!("{file}: frame {frame}"), f)?));
            }
            let fit = fit_movie(
                &sigs,
                &MovieOptions {
                    time_knots: tk,
                    angle_knots: knots,
                    lambda,
                    centre_lambda: lambda,
                    solver,
                },
            )?;
            // The model at every whole frame from the first to the last
            // (the frames between the data frames are the model's own).
            // (Over a span of more than MAX_MODEL_FRAMES frames: the data
            // frames only, to keep the files small.)
            let (f0, f1) = (fit.first_frame, fit.last_frame);
            let whole: Vec<f64> = if f1 - f0 <= MAX_MODEL_FRAMES as f64 {
                (f0.ceil() as i64..=f1.floor() as i64)
                    .map(|f| f as f64)
                    .collect()
            } else {
                sigs.iter().map(|s| s.0).collect()
            };
            for &frame in &whole {
                let data_frame = sigs.iter().find(|s| s.0 == frame);
                let angle: Vec<f64> = (0..n)
                    .map(|k| std::f64::consts::TAU * k as f64 / n as f64)
                    .collect();
                let radius: Vec<f64> = angle.iter().map(|&t| fit.radius_at(frame, t)).collect();
                let c = fit.centre_at(frame);
                frames.push(FittedFrame {
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
                });
            }
            splines.push(JsonObject::new().field("surface", &fit)?);
            surface = Some(fit);
        }
    }
    fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut files = vec![
        "fit.csv",
        "frames.csv",
        "fit.json",
        "spline.json",
        "fit.svg",
    ];
    output::write_json(
        &a.out.join("spline.json"),
        &JsonObject::new()
            .field("model", &model)?
            .field("splines", &splines)?,
    )?;
    write(&a.out.join("fit.csv"), &fit_csv(&frames))?;
    write(&a.out.join("frames.csv"), &frames_csv(&frames))?;
    write(
        &a.out.join("fit.svg"),
        &fit_picture(&file, model, &frames).finish(),
    )?;
    if let Some(fit) = &surface {
        files.push("functionals.svg");
        write(
            &a.out.join("functionals.svg"),
            &functionals_picture(&frames).finish(),
        )?;
        if fit.lambda.by_gcv {
            files.push("gcv.svg");
            write(
                &a.out.join("gcv.svg"),
                &gcv_picture("surface", &fit.lambda).finish(),
            )?;
        }
    }
    let summary = FitSummary {
        input: file.clone(),
        model,
        solver: solver.name(),
        knots,
        time_knots,
        frames: data.frames.len(),
        surface_lambda: surface.as_ref().map(|f| (&f.lambda).into()),
        centre_lambda: surface.as_ref().map(|f| (&f.centre_lambda).into()),
        surface_rms_residual: surface.as_ref().map(|f| f.rms_residual),
        per_frame: frames.into_iter().map(|f| f.result).collect(),
        out: a.out.display().to_string(),
        files,
    };
    output::write_json(&a.out.join("fit.json"), &summary)?;
    if a.json {
        output::print_json(&summary)?;
    } else {
        out!("{}", fit_report(&summary));
    }
    Ok(())
}

fn fit_report(s: &FitSummary) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}: {} model, {} frame(s), {} knot intervals around the contour{}",
        s.input,
        match s.model {
            ModelArg::Signature => "signature",
            ModelArg::Curve => "closed-curve",
            ModelArg::Surface => "surface",
        },
        s.frames,
        s.knots,
        s.time_knots
            .map(|t| format!(", {t} along time"))
            .unwrap_or_default()
    );
    if let Some(l) = &s.surface_lambda {
        let _ = writeln!(
            out,
            "surface: λ = {:.3e}{} (GCV {:.4e}, tr H = {:.1}), RMS residual {:.4}",
            l.lambda,
            if l.by_gcv { " by GCV" } else { "" },
            l.gcv,
            l.trace_hat,
            s.surface_rms_residual.unwrap_or(f64::NAN)
        );
        if l.at_scan_edge {
            let _ = writeln!(
                out,
                "note: GCV's minimum is at the end of its scan — fewer data than spline coefficients (try fewer knots) or no detectable signal; λ is not well determined"
            );
        }
    }
    let shown: Vec<&FrameResult> = if s.per_frame.len() > 12 {
        let step = s.per_frame.len().div_ceil(12);
        s.per_frame.iter().step_by(step).collect()
    } else {
        s.per_frame.iter().collect()
    };
    let _ = writeln!(out, "frame | points | area | centre | λ | RMS residual");
    for f in shown {
        let _ = writeln!(
            out,
            "{} | {} | {:.4} | ({:.2}, {:.2}) | {} | {}",
            f.frame,
            f.points,
            f.area,
            f.centre_x,
            f.centre_y,
            f.lambda.map(|v| format!("{v:.2e}")).unwrap_or("—".into()),
            f.rms_residual
                .map(|v| format!("{v:.4}"))
                .unwrap_or("—".into())
        );
    }
    let _ = writeln!(out, "wrote {} to {}", s.files.join(", "), s.out);
    out
}

fn fit_csv(frames: &[FittedFrame]) -> String {
    let mut s = String::from("frame,k,x,y,angle_rad,radius\n");
    for f in frames {
        for (k, p) in f.fit.iter().enumerate() {
            let (a, r) = match (&f.angle, &f.radius) {
                (Some(a), Some(r)) => (format!("{:.6}", a[k]), format!("{:.6}", r[k])),
                _ => (String::new(), String::new()),
            };
            let _ = writeln!(s, "{},{k},{:.6},{:.6},{a},{r}", f.frame, p.0, p.1);
        }
    }
    s
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map(|v| format!("{v:.digits$}"))
        .unwrap_or_default()
}

fn frames_csv(frames: &[FittedFrame]) -> String {
    let mut s = String::from(
        "frame,points,area,centre_x,centre_y,smoothness,perimeter,lambda,gcv,trace_hat,rms_residual\n",
    );
    for f in frames {
        let r = &f.result;
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{}",
            r.frame,
            r.points,
            opt(Some(r.area), 6),
            opt(Some(r.centre_x), 4),
            opt(Some(r.centre_y), 4),
            opt(r.smoothness, 6),
            opt(r.perimeter, 4),
            r.lambda.map(|v| format!("{v:.4e}")).unwrap_or_default(),
            r.gcv
                .filter(|v| v.is_finite())
                .map(|v| format!("{v:.4e}"))
                .unwrap_or_default(),
            opt(r.trace_hat, 3),
            opt(r.rms_residual, 6),
        );
    }
    s
}

/// Up to 12 panels: the frames with data (all fitted frames if none has).
fn fit_picture(file: &str, model: ModelArg, frames: &[FittedFrame]) -> plot::Svg {
    let with_data: Vec<&FittedFrame> = frames.iter().filter(|f| !f.data.is_empty()).collect();
    let pool = if with_data.is_empty() {
        frames.iter().collect()
    } else {
        with_data
    };
    let step = pool.len().div_ceil(12).max(1);
    let panels: Vec<Panel> = pool
        .iter()
        .step_by(step)
        .map(|f| Panel {
            caption: format!("frame {}: area {:.4}", f.frame, f.result.area),
            shapes: vec![
                Shape {
                    points: f.fit.clone(),
                    colour: "#1f5fbf",
                    style: ShapeStyle::Closed {
                        width: 1.5,
                        dashed: false,
                    },
                },
                Shape {
                    points: f.data.clone(),
                    colour: "#d22",
                    style: ShapeStyle::Dots { radius: 2.2 },
                },
                Shape {
                    points: vec![(f.result.centre_x, f.result.centre_y)],
                    colour: "#555",
                    style: ShapeStyle::Dots { radius: 1.5 },
                },
            ],
        })
        .collect();
    let what = match model {
        ModelArg::Signature => "periodic signature splines r(θ)",
        ModelArg::Curve => "closed parametric splines (x(t), y(t))",
        ModelArg::Surface => "the contour × time surface",
    };
    plot::shape_panels(
        &format!("{file}: {what}"),
        &panels,
        4,
        true,
        "red dots: data · blue: fitted contour · grey dot: centre",
    )
}

/// Area and smoothness over frames, and the (C, S) curve of Fig. 7.
fn functionals_picture(frames: &[FittedFrame]) -> plot::Svg {
    let t: Vec<f64> = frames.iter().map(|f| f.frame).collect();
    let area: Vec<f64> = frames.iter().map(|f| f.result.area).collect();
    let smooth: Vec<f64> = frames
        .iter()
        .map(|f| f.result.smoothness.unwrap_or(f64::NAN))
        .collect();
    let data_t: Vec<f64> = frames
        .iter()
        .filter(|f| !f.data.is_empty())
        .map(|f| f.frame)
        .collect();
    let data_area: Vec<f64> = frames
        .iter()
        .filter(|f| !f.data.is_empty())
        .map(|f| f.result.area)
        .collect();
    plot::line_charts(&[
        Chart {
            title: "Area S (Eq. 40) over frames".into(),
            x_label: "frame".into(),
            y_label: "area".into(),
            series: vec![
                Series::over("model", "#1f5fbf", false, &t, &area),
                Series::over("at data frames", "#d22", true, &data_t, &data_area),
            ],
        },
        Chart {
            title: "Smoothness C (Eq. 41) over frames".into(),
            x_label: "frame".into(),
            y_label: "C = ∫(∂²x/∂t²)² dt".into(),
            series: vec![Series::over("model", "#1f5fbf", false, &t, &smooth)],
        },
        Chart {
            title: "(C(s), S(s)) as in the paper's Fig. 7".into(),
            x_label: "smoothness C".into(),
            y_label: "area S".into(),
            series: vec![Series::over("model", "#2a2", false, &smooth, &area)],
        },
    ])
}

fn gcv_picture(what: &str, r: &LambdaReport) -> plot::Svg {
    let (x, y): (Vec<f64>, Vec<f64>) = r
        .scanned
        .iter()
        .filter(|p| p.1.is_finite())
        .map(|p| (p.0.log10(), p.1.log10()))
        .unzip();
    plot::line_charts(&[Chart {
        title: format!("GCV score of the {what}: minimum at λ = {:.3e}", r.lambda),
        x_label: "log10 λ".into(),
        y_label: "log10 V(λ)".into(),
        series: vec![
            Series::over("V(λ)", "#1f5fbf", false, &x, &y),
            Series::over(
                "chosen",
                "#d22",
                true,
                &[r.lambda.log10(), r.lambda.log10()],
                &[
                    y.iter().copied().fold(f64::INFINITY, f64::min),
                    y.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ],
            ),
        ],
    }])
}

#[derive(Serialize)]
struct SynthSummary {
    case: &'static str,
    frames: usize,
    points_per_frame: usize,
    sigma: f64,
    seed: u64,
    out: String,
    files: Vec<&'static str>,
    /// A command that fits the data as the paper does.
    fit_command: String,
}

fn synth_cmd(a: SynthArgs) -> Result<()> {
    fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut noise = rng::stream(a.seed, rng::CONTOUR_SYNTH_NOISE);
    let data_path = a.out.join("data.csv");
    let summary = match a.case {
        SynthCase::Rbc => {
            let sigma = a.sigma.unwrap_or(paper::SIGMA);
            if !(sigma.is_finite() && sigma >= 0.0) {
                bail!("--sigma must be finite and ≥ 0, got {sigma}");
            }
            if !(2..=1000).contains(&a.n) {
                bail!("--n must be 2..=1000 (the paper: 5 and 40), got {}", a.n);
            }
            // Frame i ↔ s = 10 i/(N − 1); angle θ(t_j) = 2π j/N.
            let mut data = String::from("frame,angle_rad,radius\n");
            let mut truth = String::from("frame,angle_rad,radius\n");
            let mut panels = Vec::new();
            for (i, (s, frame)) in paper::rbc_frames(a.n, sigma, &mut noise)
                .into_iter()
                .enumerate()
            {
                let mut pts = Vec::new();
                for (th, r) in frame {
                    let _ = writeln!(data, "{i},{th:.9},{r:.9}");
                    pts.push((r * th.cos(), r * th.sin()));
                }
                let mut true_pts = Vec::new();
                for j in 0..200 {
                    let t = DOMAIN * j as f64 / 200.0;
                    let (r, th) = (rbc_surface(s, t), paper::theta(t));
                    let _ = writeln!(truth, "{i},{th:.9},{r:.9}");
                    true_pts.push((r * th.cos(), r * th.sin()));
                }
                panels.push(Panel {
                    caption: format!("frame {i} (s = {s:.2})"),
                    shapes: vec![
                        Shape {
                            points: true_pts,
                            colour: "#555",
                            style: ShapeStyle::Closed {
                                width: 1.2,
                                dashed: false,
                            },
                        },
                        Shape {
                            points: pts,
                            colour: "#d22",
                            style: ShapeStyle::Dots { radius: 2.0 },
                        },
                    ],
                });
            }
            write(&data_path, &data)?;
            write(&a.out.join("truth.csv"), &truth)?;
            let step = panels.len().div_ceil(8).max(1);
            let shown: Vec<Panel> = panels.into_iter().step_by(step).collect();
            write(
                &a.out.join("synth.svg"),
                &plot::shape_panels(
                    &format!("Eq. 38 (red blood cell), N = {}, σ = {sigma}", a.n),
                    &shown,
                    4,
                    true,
                    "grey: true contour f(s, ·) in polar form (Eq. 39) · red: noisy data",
                )
                .finish(),
            )?;
            SynthSummary {
                case: "rbc",
                frames: a.n,
                points_per_frame: a.n,
                sigma,
                seed: a.seed,
                out: a.out.display().to_string(),
                files: vec!["data.csv", "truth.csv", "synth.svg"],
                fit_command: format!(
                    "softjoint contour fit {} --model surface --time-knots 10 --knots 10 --lambda 1e-3",
                    data_path.display()
                ),
            }
        }
        SynthCase::Movie => {
            let sigma = a.sigma.unwrap_or(1.0);
            if !(sigma.is_finite() && sigma >= 0.0) {
                bail!("--sigma must be finite and ≥ 0 (px), got {sigma}");
            }
            if !(3..=100_000).contains(&a.angles) {
                bail!("--angles must be 3..=100000, got {}", a.angles);
            }
            if !(1..=100).contains(&a.every) {
                bail!("--every must be 1..=100, got {}", a.every);
            }
            let movie = PulsatingContour::default();
            let mut data = String::from("frame,centre_x,centre_y,angle_rad,radius\n");
            let mut truth = String::from("frame,x,y\n");
            let mut panels = Vec::new();
            let mut kept = 0;
            for f in 0..movie.frames {
                let true_pts = movie.contour(f as f64, 180);
                for p in &true_pts {
                    let _ = writeln!(truth, "{f},{:.4},{:.4}", p.0, p.1);
                }
                if f % a.every != 0 {
                    continue;
                }
                kept += 1;
                let sig = movie.observe(f, a.angles, sigma, &mut noise)?;
                for (th, r) in sig.angles_rad.iter().zip(&sig.radii) {
                    let _ = writeln!(
                        data,
                        "{f},{:.4},{:.4},{th:.9},{r:.4}",
                        sig.centre.0, sig.centre.1
                    );
                }
                panels.push(Panel {
                    caption: format!("frame {f}"),
                    shapes: vec![
                        Shape {
                            points: movie.contour(f as f64, TRUTH_POINTS / 4),
                            colour: "#555",
                            style: ShapeStyle::Closed {
                                width: 1.2,
                                dashed: false,
                            },
                        },
                        Shape {
                            points: sig.points(),
                            colour: "#d22",
                            style: ShapeStyle::Dots { radius: 2.0 },
                        },
                    ],
                });
            }
            write(&data_path, &data)?;
            write(&a.out.join("truth.csv"), &truth)?;
            write(
                &a.out.join("synth.svg"),
                &plot::shape_panels(
                    &format!(
                        "pulsating, translating contour: every {}th of {} frames, {} rays, σ = {sigma} px",
                        a.every, movie.frames, a.angles
                    ),
                    &panels,
                    4,
                    true,
                    "grey: true contour · red: tracked centroid + radii along rays",
                )
                .finish(),
            )?;
            SynthSummary {
                case: "movie",
                frames: kept,
                points_per_frame: a.angles,
                sigma,
                seed: a.seed,
                out: a.out.display().to_string(),
                files: vec!["data.csv", "truth.csv", "synth.svg"],
                fit_command: format!(
                    "softjoint contour fit {} --model surface --time-knots 10 --knots 10 --lambda 5e-4",
                    data_path.display()
                ),
            }
        }
    };
    if a.json {
        output::print_json(&summary)?;
    } else {
        outln!(
            "{}: {} frames × {} points, σ = {}, seed {}; wrote {} to {}",
            summary.case,
            summary.frames,
            summary.points_per_frame,
            summary.sigma,
            summary.seed,
            summary.files.join(", "),
            summary.out
        );
        outln!("fit it as the paper does: {}", summary.fit_command);
    }
    Ok(())
}
