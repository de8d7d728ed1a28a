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
//! The splines, the fits and the test cases live in `plant_contour`; this
//! is argument handling, files and pictures.
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use host_tools::contour_synth;
use host_tools::output::{self, CheckedText, JsonObject};
use host_tools::plot::{self, Chart, Panel, Series, Shape, ShapeStyle};
use host_tools::{out, outln};
use plant_contour::fit::Solver;
use plant_contour::identify::checks::Status;
use plant_contour::identify::contours::{
    fit_contours, ContourFitReport, ContourFitSpec, ContourModel, FitFigures, FittedFrame,
    FittedSplines, FrameResult,
};
use plant_contour::identify::data::read_contour_csv;
use plant_contour::identify::gcv::{Lambda, LambdaReport, MAX_LAMBDA};
use plant_contour::identify::synth::{MovieCase, RbcFrame};
use plant_contour::identify::tracked::Point;
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

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
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
    /// Smoothing parameter λ (0 < λ ≤ 1e6; the paper uses 1e-3 and 5e-4
    /// with weights 1/N), or `gcv` to choose it by generalised
    /// cross-validation (guarded against interpolating the noise).
    #[arg(long, default_value = "gcv", allow_hyphen_values = true)]
    lambda: String,
    /// Radii are signed values (test data such as the paper's Eq. 38 with
    /// noise), not measured distances: negative ones are accepted.
    #[arg(long)]
    signed_radii: bool,
    /// Exit 0 even when a frame fails its checks (the frames are still
    /// marked `unverified` in every output).
    #[arg(long)]
    allow_unverified: bool,
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
    if !(v.is_finite() && v > 0.0 && v <= MAX_LAMBDA) {
        bail!(
            "--lambda {text}: λ must be a number > 0 and ≤ {MAX_LAMBDA:e} (or `gcv`); λ beyond 1e6 smooths any contour to its mean"
        );
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

impl From<ModelArg> for ContourModel {
    fn from(m: ModelArg) -> Self {
        match m {
            ModelArg::Signature => ContourModel::Signature,
            ModelArg::Curve => ContourModel::Curve,
            ModelArg::Surface => ContourModel::Surface,
        }
    }
}

impl From<SolverArg> for Solver {
    fn from(s: SolverArg) -> Self {
        match s {
            SolverArg::Reduced => Solver::Reduced,
            SolverArg::Kkt => Solver::Kkt,
        }
    }
}

/// The units of the per-frame figures (`length` is the data's unit, px
/// for tracked contours).
#[derive(Serialize)]
struct Units {
    area: &'static str,
    perimeter: &'static str,
    smoothness: &'static str,
    bending_energy: &'static str,
}

const UNITS: Units = Units {
    area: "length^2",
    perimeter: "length",
    smoothness: "length^2/rad^3 (Eq. 41 over the angle θ: ∫(d²r/dθ²)² dθ)",
    bending_energy: "1/length (∫κ² dl)",
};

/// What `fit` prints with `--json` and writes as fit.json: the fit's
/// own figures, then where they came from and went.
#[derive(Serialize)]
struct FitSummary<'a> {
    #[serde(flatten)]
    fit: FitFigures<'a>,
    units: Units,
    input: String,
    out: String,
    files: Vec<&'static str>,
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
    if a.model == Some(ModelArg::Surface) && data.frames.len() < 2 {
        bail!("{file}: --model surface needs at least two frames (column `frame`), found one");
    }
    let solver = Solver::from(a.solver);
    let spec = ContourFitSpec {
        model: a.model.map(ContourModel::from),
        knots: a.knots,
        time_knots: a.time_knots,
        lambda,
        solver,
        samples: a.samples,
        signed_radii: a.signed_radii,
    };
    let fit = fit_contours(&data, &spec)?;
    let summary = FitSummary {
        fit: fit.figures(data.frames.len(), solver),
        units: UNITS,
        input: file.clone(),
        out: a.out.display().to_string(),
        files: Vec::new(),
    };
    // Every file is rendered and checked before the first is written:
    // a result that cannot be written leaves nothing behind.
    let files = fit_files(&file, &fit, &summary)?;
    let summary = FitSummary {
        files: files
            .iter()
            .map(|f| f.0)
            .chain(std::iter::once("fit.json"))
            .collect(),
        ..summary
    };
    // Checked and rendered once: the file and `--json` are the same text.
    let summary_text = CheckedText::json("fit.json", &summary)?;
    output::create_dir(&a.out)?;
    // Flushed to disk side by side, then renamed one after another (a
    // device or FIFO among them written at its turn).
    let writes: Vec<(PathBuf, &CheckedText)> = files
        .iter()
        .map(|(name, text)| (a.out.join(name), text))
        .chain(std::iter::once((a.out.join("fit.json"), &summary_text)))
        .collect();
    output::write_checked_all(&writes)?;
    if a.json {
        outln!("{}", summary_text.as_str());
    } else {
        out!("{}", fit_report(&summary));
    }
    if summary.fit.status == Status::Unverified && !a.allow_unverified {
        bail!(
            "{} of {} fitted frame(s) UNVERIFIED (frames {}): their figures failed the fit's own checks (see `checks` in fit.json / frames.csv); the results were written with that mark to {} (give --allow-unverified to exit 0)",
            summary.fit.unverified_frames.len(),
            summary.fit.per_frame.len(),
            frame_list(&summary.fit.unverified_frames),
            summary.out
        );
    }
    Ok(())
}

/// Up to 10 frame numbers, then how many more.
fn frame_list(frames: &[f64]) -> String {
    let mut s: Vec<String> = frames.iter().take(10).map(|f| f.to_string()).collect();
    if frames.len() > 10 {
        s.push(format!("and {} more", frames.len() - 10));
    }
    s.join(", ")
}

/// spline.json: the model and its splines, per frame or the surface.
fn splines_json(fit: &ContourFitReport) -> Result<JsonObject> {
    let splines: Vec<JsonObject> = match &fit.splines {
        FittedSplines::Signatures(fits) => fits
            .iter()
            .map(|(frame, s)| {
                JsonObject::new()
                    .field("frame", frame)?
                    .field("signature", s)
            })
            .collect::<Result<_>>()?,
        FittedSplines::Curves(fits) => fits
            .iter()
            .map(|(frame, c)| {
                JsonObject::new()
                    .field("frame", frame)?
                    .field("closed_curve", c)
            })
            .collect::<Result<_>>()?,
        FittedSplines::Surface(s) => vec![JsonObject::new().field("surface", s)?],
    };
    Ok(JsonObject::new()
        .field("model", &fit.model)?
        .objects("splines", splines))
}

/// spline.json, fit.csv, frames.csv and the pictures, rendered and
/// checked (finite numbers) but not written; fit.json is the summary.
fn fit_files(
    file: &str,
    fit: &ContourFitReport,
    summary: &FitSummary,
) -> Result<Vec<(&'static str, CheckedText)>> {
    // The four files rendered and checked side by side (each on its own;
    // a failure is reported in this order, as one after another would).
    let ((spline, fit_text), (frames, picture)) = rayon::join(
        || {
            rayon::join(
                || splines_json(fit).and_then(|s| CheckedText::json_object(&s)),
                || CheckedText::csv("fit.csv", fit_csv(&fit.frames)),
            )
        },
        || {
            rayon::join(
                || CheckedText::csv("frames.csv", frames_csv(&fit.frames)),
                || {
                    CheckedText::text(
                        "fit.svg",
                        fit_picture(file, fit.model, &fit.frames, summary).finish(),
                    )
                },
            )
        },
    );
    let mut files = vec![
        ("spline.json", spline?),
        ("fit.csv", fit_text?),
        ("frames.csv", frames?),
        ("fit.svg", picture?),
    ];
    if let Some(surface) = fit.surface() {
        files.push((
            "functionals.svg",
            CheckedText::text("functionals.svg", functionals_picture(&fit.frames).finish())?,
        ));
        if surface.lambda.by_gcv {
            files.push((
                "gcv.svg",
                CheckedText::text("gcv.svg", gcv_picture("surface", &surface.lambda).finish())?,
            ));
        }
    }
    Ok(files)
}

/// The text report of a fit: the model, the surface's λ, up to 12 frames
/// and the files.
fn fit_report(s: &FitSummary) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{}: {} model, {} frame(s), {} knot intervals around the contour{}",
        s.input,
        match s.fit.model {
            ContourModel::Signature => "signature",
            ContourModel::Curve => "closed-curve",
            ContourModel::Surface => "surface",
        },
        s.fit.frames,
        s.fit.knots,
        s.fit
            .time_knots
            .map(|t| format!(", {t} along time"))
            .unwrap_or_default()
    );
    if let Some(l) = &s.fit.surface_lambda {
        let _ = writeln!(
            out,
            "surface: λ = {:.3e}{} (GCV {}, tr H = {:.1}), RMS residual {:.4}",
            l.lambda,
            if l.by_gcv { " by GCV" } else { "" },
            l.gcv
                .map_or("— (past its degrees-of-freedom bound)".into(), |v| format!(
                    "{v:.4e}"
                )),
            l.trace_hat,
            s.fit.surface_rms_residual.unwrap_or(f64::NAN)
        );
        if l.at_scan_edge {
            let _ = writeln!(
                out,
                "note: GCV's minimum is at the end of its scan — fewer data than spline coefficients (try fewer knots) or no detectable signal; λ is not well determined"
            );
        }
    }
    let _ = writeln!(
        out,
        "units: area {}, perimeter {}, smoothness {}, bending {} (length = the data's unit)",
        s.units.area, s.units.perimeter, s.units.smoothness, s.units.bending_energy
    );
    let shown: Vec<&&FrameResult> = if s.fit.per_frame.len() > 12 {
        let step = s.fit.per_frame.len().div_ceil(12);
        s.fit.per_frame.iter().step_by(step).collect()
    } else {
        s.fit.per_frame.iter().collect()
    };
    let _ = writeln!(
        out,
        "frame | points | area | perimeter | centre | λ | RMS residual | status"
    );
    for f in shown {
        let _ = writeln!(
            out,
            "{} | {} | {:.4} | {:.4} | ({:.2}, {:.2}) | {} | {} | {}",
            f.frame,
            f.points,
            f.area,
            f.perimeter,
            f.centre_x,
            f.centre_y,
            f.lambda.map(|v| format!("{v:.2e}")).unwrap_or("—".into()),
            f.rms_residual
                .map(|v| format!("{v:.4}"))
                .unwrap_or("—".into()),
            status_word(f.checks.status)
        );
    }
    for f in s.fit.per_frame.iter().filter(|f| !f.checks.verified()) {
        let why: Vec<&str> = f.checks.flags.iter().map(|g| g.describe()).collect();
        let _ = writeln!(out, "UNVERIFIED frame {}: {}", f.frame, why.join("; "));
    }
    let _ = writeln!(out, "wrote {} to {}", s.files.join(", "), s.out);
    if s.fit.status == Status::Unverified {
        let _ = writeln!(
            out,
            "UNVERIFIED: {} of {} frame(s) failed the fit's own checks; do not use their figures",
            s.fit.unverified_frames.len(),
            s.fit.per_frame.len()
        );
    }
    out
}

fn status_word(s: Status) -> &'static str {
    match s {
        Status::Verified => "verified",
        Status::Unverified => "UNVERIFIED",
    }
}

/// The failed checks of a frame, `;`-separated (empty when verified).
fn flag_names(r: &FrameResult) -> String {
    r.checks
        .flags
        .iter()
        .map(|f| {
            serde_json::to_value(f)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default()
        })
        .collect::<Vec<_>>()
        .join(";")
}

fn fit_csv(frames: &[FittedFrame]) -> String {
    let mut s = String::from("frame,k,x,y,angle_rad,radius\n");
    let mut k_digits = itoa::Buffer::new();
    for f in frames {
        // The frame's text once for all its rows (`{}` of an f64 is the
        // general float formatter, a thousand instructions a row).
        let frame = format!("{},", f.frame);
        for (k, p) in f.fit.iter().enumerate() {
            s.push_str(&frame);
            s.push_str(k_digits.format(k));
            s.push(',');
            output::push_fixed(&mut s, p.0, 6);
            s.push(',');
            output::push_fixed(&mut s, p.1, 6);
            s.push(',');
            if let (Some(a), Some(r)) = (&f.angle, &f.radius) {
                output::push_fixed(&mut s, a[k], 6);
                s.push(',');
                output::push_fixed(&mut s, r[k], 6);
            } else {
                s.push(',');
            }
            s.push('\n');
        }
    }
    s
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.filter(|v| v.is_finite())
        .map(|v| output::fixed(v, digits))
        .unwrap_or_default()
}

fn frames_csv(frames: &[FittedFrame]) -> String {
    let mut s = String::from(
        "# lengths in the data's unit (length); smoothness = Eq. 41 over the angle θ, ∫(d²r/dθ²)² dθ; bending = ∫κ² dl\n\
         frame,status,flags,points,area_len2,centre_x,centre_y,smoothness_len2_per_rad3,perimeter_len,bending_per_len,data_area_len2,data_perimeter_len,lambda,gcv,trace_hat,rms_residual\n",
    );
    for f in frames {
        let r = &f.result;
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{:.6e},{},{},{},{},{},{}",
            r.frame,
            status_word(r.checks.status).to_lowercase(),
            flag_names(r),
            r.points,
            opt(Some(r.area), 6),
            opt(Some(r.centre_x), 4),
            opt(Some(r.centre_y), 4),
            opt(r.smoothness, 6),
            opt(Some(r.perimeter), 4),
            r.bending_energy,
            opt(r.checks.data_area, 6),
            opt(r.checks.data_perimeter, 4),
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
fn fit_picture(
    file: &str,
    model: ContourModel,
    frames: &[FittedFrame],
    summary: &FitSummary,
) -> plot::Svg {
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
            caption: format!(
                "frame {}: area {:.4}{}",
                f.frame,
                f.result.area,
                if f.result.checks.verified() {
                    ""
                } else {
                    " — UNVERIFIED"
                }
            ),
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
        ContourModel::Signature => "periodic signature splines r(θ)",
        ContourModel::Curve => "closed parametric splines (x(t), y(t))",
        ContourModel::Surface => "the contour × time surface",
    };
    let title = if summary.fit.status == Status::Unverified {
        format!(
            "{file}: {what} — UNVERIFIED: {} of {} frame(s) failed their checks",
            summary.fit.unverified_frames.len(),
            summary.fit.per_frame.len()
        )
    } else {
        format!("{file}: {what}")
    };
    plot::shape_panels(
        &title,
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
            title: "Smoothness C (Eq. 41 over the angle) over frames".into(),
            x_label: "frame".into(),
            y_label: "C = ∫(∂²r/∂θ²)² dθ, length²/rad³".into(),
            series: vec![Series::over("model", "#1f5fbf", false, &t, &smooth)],
        },
        Chart {
            title: "(C(s), S(s)) as in the paper's Fig. 7".into(),
            x_label: "smoothness C, length²/rad³".into(),
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

/// What `synth` prints (with `--json` as JSON): the case's figures,
/// where it wrote what, and a command that fits the data.
#[derive(Serialize)]
struct SynthSummary {
    #[serde(flatten)]
    figures: contour_synth::SynthFigures,
    out: String,
    files: Vec<&'static str>,
    /// A command that fits the data as the paper does.
    fit_command: String,
}

fn synth_cmd(a: SynthArgs) -> Result<()> {
    fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let summary = match a.case {
        SynthCase::Rbc => synth_rbc(&a)?,
        SynthCase::Movie => synth_movie(&a)?,
    };
    if a.json {
        output::print_json(&summary)?;
    } else {
        outln!(
            "{}: {} frames × {} points, σ = {}, seed {}; wrote {} to {}",
            summary.figures.case,
            summary.figures.frames,
            summary.figures.points_per_frame,
            summary.figures.sigma,
            summary.figures.seed,
            summary.files.join(", "),
            summary.out
        );
        outln!("fit it as the paper does: {}", summary.fit_command);
    }
    Ok(())
}

/// Eq. 38 (red blood cell): data.csv, truth.csv and synth.svg.
fn synth_rbc(a: &SynthArgs) -> Result<SynthSummary> {
    let (figures, frames) = contour_synth::rbc(a.n, a.sigma, a.seed).map_err(as_flag)?;
    let sigma = figures.sigma;
    let data_path = a.out.join("data.csv");
    write(&data_path, &polar_csv(&frames, |f| &f.data))?;
    write(&a.out.join("truth.csv"), &polar_csv(&frames, |f| &f.truth))?;
    write(
        &a.out.join("synth.svg"),
        &rbc_picture(&frames, a.n, sigma).finish(),
    )?;
    Ok(SynthSummary {
        figures,
        out: a.out.display().to_string(),
        files: vec!["data.csv", "truth.csv", "synth.svg"],
        fit_command: format!(
            "softjoint contour fit {} --model surface --time-knots 10 --knots 10 --lambda 1e-3{}",
            data_path.display(),
            // Eq. 38 with noise can dip below 0 near r ≈ 0.46.
            if frames.iter().any(|f| f.data.iter().any(|p| p.1 < 0.0)) {
                " --signed-radii"
            } else {
                ""
            }
        ),
    })
}

/// A refused synth argument in the command line's words (`--n`, not `n`).
fn as_flag(e: anyhow::Error) -> anyhow::Error {
    match e.downcast_ref::<contour_synth::SynthArgError>() {
        Some(a) => anyhow::anyhow!("--{a}"),
        None => e,
    }
}

/// `frame,angle_rad,radius` rows of the (θ, r) pairs `of` each frame.
fn polar_csv(frames: &[RbcFrame], of: impl Fn(&RbcFrame) -> &Vec<(f64, f64)>) -> String {
    let mut csv = String::from("frame,angle_rad,radius\n");
    for (i, f) in frames.iter().enumerate() {
        for (th, r) in of(f) {
            let _ = writeln!(csv, "{i},{th:.9},{r:.9}");
        }
    }
    csv
}

/// (θ, r) pairs as points.
fn polar_points(pairs: &[(f64, f64)]) -> Vec<Point> {
    pairs
        .iter()
        .map(|(th, r)| (r * th.cos(), r * th.sin()))
        .collect()
}

/// Up to 8 frames: the true contour and the noisy data.
fn rbc_picture(frames: &[RbcFrame], n: usize, sigma: f64) -> plot::Svg {
    let step = frames.len().div_ceil(8).max(1);
    let shown: Vec<Panel> = frames
        .iter()
        .enumerate()
        .step_by(step)
        .map(|(i, f)| {
            truth_and_data_panel(
                format!("frame {i} (s = {:.2})", f.s),
                polar_points(&f.truth),
                polar_points(&f.data),
            )
        })
        .collect();
    plot::shape_panels(
        &format!("Eq. 38 (red blood cell), N = {n}, σ = {sigma}"),
        &shown,
        4,
        true,
        "grey: true contour f(s, ·) in polar form (Eq. 39) · red: noisy data",
    )
}

/// A panel of a true contour (grey line) and data (red dots).
fn truth_and_data_panel(caption: String, truth: Vec<Point>, data: Vec<Point>) -> Panel {
    Panel {
        caption,
        shapes: vec![
            Shape {
                points: truth,
                colour: "#555",
                style: ShapeStyle::Closed {
                    width: 1.2,
                    dashed: false,
                },
            },
            Shape {
                points: data,
                colour: "#d22",
                style: ShapeStyle::Dots { radius: 2.0 },
            },
        ],
    }
}

/// The pulsating contour movie: data.csv, truth.csv and synth.svg.
fn synth_movie(a: &SynthArgs) -> Result<SynthSummary> {
    let (figures, case) =
        contour_synth::movie(a.every, a.angles, a.sigma, a.seed).map_err(as_flag)?;
    let sigma = figures.sigma;
    let data_path = a.out.join("data.csv");
    let (data, truth) = movie_csv(&case);
    write(&data_path, &data)?;
    write(&a.out.join("truth.csv"), &truth)?;
    write(
        &a.out.join("synth.svg"),
        &movie_picture(&case, a.every, a.angles, sigma).finish(),
    )?;
    Ok(SynthSummary {
        figures,
        out: a.out.display().to_string(),
        files: vec!["data.csv", "truth.csv", "synth.svg"],
        fit_command: format!(
            "softjoint contour fit {} --model surface --time-knots 10 --knots 10 --lambda 5e-4",
            data_path.display()
        ),
    })
}

/// data.csv (the tracked centroid and radii of the kept frames) and
/// truth.csv (the true contour of every frame).
fn movie_csv(case: &MovieCase) -> (String, String) {
    let mut data = String::from("frame,centre_x,centre_y,angle_rad,radius\n");
    let mut truth = String::from("frame,x,y\n");
    for f in &case.frames {
        let n = f.frame;
        for p in &f.truth {
            let _ = writeln!(truth, "{n},{:.4},{:.4}", p.0, p.1);
        }
        if let Some(sig) = &f.observed {
            for (th, r) in sig.angles_rad.iter().zip(&sig.radii) {
                let _ = writeln!(
                    data,
                    "{n},{:.4},{:.4},{th:.9},{r:.4}",
                    sig.centre.0, sig.centre.1
                );
            }
        }
    }
    (data, truth)
}

/// Every kept frame: the true contour and what the tracker saw.
fn movie_picture(case: &MovieCase, every: usize, angles: usize, sigma: f64) -> plot::Svg {
    let panels: Vec<Panel> = case
        .frames
        .iter()
        .filter_map(|f| {
            let sig = f.observed.as_ref()?;
            Some(truth_and_data_panel(
                format!("frame {}", f.frame),
                f.truth.clone(),
                sig.points(),
            ))
        })
        .collect();
    plot::shape_panels(
        &format!(
            "pulsating, translating contour: every {every}th of {} frames, {angles} rays, σ = {sigma} px",
            case.movie.frames
        ),
        &panels,
        4,
        true,
        "grey: true contour · red: tracked centroid + radii along rays",
    )
}
