//! `softjoint viscoelastic`: the 3-element model of seed 002 for users'
//! data (`simulate`, `fit`) and the measured-object pipeline on a mesh
//! (`object`). The physics and the experiments live in
//! `plant_viscoelastic`; the haptic model of `object` is the firmware's
//! real-time update (`host_tools::visco_core`). This is argument handling,
//! file I/O and reports.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use host_tools::outln;
use host_tools::output;
use host_tools::plot::{self, Anchor, Chart, Series, Stroke, Svg};
use host_tools::visco_fit::{fit_summary, fit_trial_text, weighting_name};
use host_tools::visco_object::{run_object, ObjectFigures, ObjectJob};
use plant_viscoelastic::experiment::pipeline::{Campaign, IdentifiedObject, ProbeRun};
use plant_viscoelastic::experiment::trial::{simulate_table, ThreeElementParams, Trace};
use plant_viscoelastic::fit::{simulate_force, TrialFit, Weighting};
use plant_viscoelastic::io::read_table;
use plant_viscoelastic::Vec3;
use plant_viscoelastic::{Dgfm, SurfaceMesh};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `softjoint viscoelastic`.
#[derive(Args)]
pub struct ViscoArgs {
    #[command(subcommand)]
    command: ViscoCommand,
}

#[derive(Subcommand)]
enum ViscoCommand {
    /// Run the 1D 3-element model (seed 002 Eq. 3) on a CSV of
    /// `time_s,displacement` (m) → force (N), or `time_s,force` (N) →
    /// displacement (m); writes `time_s,displacement,force`.
    Simulate(SimulateArgs),
    /// Fit (k1, k2, b) to a force-vs-time trial CSV
    /// `time_s,displacement,force` (s, m, N) by Nelder–Mead with the seed's
    /// weighting (tail ×100, 3 points around the peak ×1000).
    Fit(FitArgs),
    /// Build the DGFM object of a mesh (default: the shipped ~200-vertex
    /// blob), estimate its parameters from simulated probe trials, run a
    /// scripted probe at 1 kHz and write per-vertex displacement and force
    /// at 30 Hz, the contact trace, the parameters and a false-colour
    /// damping image.
    Object(ObjectArgs),
}

// (The subcommands' help comes from the variants' doc comments above.)
#[derive(Args)]
struct SimulateArgs {
    /// Input CSV with a header.
    input: PathBuf,
    /// Delayed spring k1 (N/m).
    #[arg(allow_negative_numbers = true, long)]
    k1: f64,
    /// Series (instantaneous) spring k2 (N/m).
    #[arg(allow_negative_numbers = true, long)]
    k2: f64,
    /// Dashpot b (N·s/m).
    #[arg(allow_negative_numbers = true, long)]
    b: f64,
    /// Output CSV (default: standard output).
    #[arg(short, long)]
    output: Option<PathBuf>,
}

#[derive(Args)]
struct FitArgs {
    /// Input CSV with a header.
    input: PathBuf,
    /// Weight every sample equally instead.
    #[arg(long)]
    uniform: bool,
    /// Write a plot of measured and fitted force (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Print a JSON object instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct ObjectArgs {
    /// Closed, star-shaped triangle mesh (OBJ, metres).
    #[arg(long)]
    mesh: Option<PathBuf>,
    /// Probe script CSV `time_s,vertex,fx_n,fy_n,fz_n` (vertex −1
    /// releases). Default: 1 N down on the top vertex for 0.5 s.
    #[arg(long)]
    script: Option<PathBuf>,
    /// Simulated duration (s).
    #[arg(allow_negative_numbers = true, long, default_value_t = 1.5)]
    duration_s: f64,
    /// Probe every N-th traction vertex in the simulated campaign.
    #[arg(allow_negative_numbers = true, long, default_value_t = 10)]
    probe_every: usize,
    /// Seed of the measurement noise.
    #[arg(allow_negative_numbers = true, long, default_value_t = 1)]
    seed: u64,
    /// Use general damping tensors instead of Rayleigh damping.
    #[arg(long)]
    tensor: bool,
    /// Also write every simulated probe trial as
    /// `trial_NNNN.csv` (`time_s,displacement,force`) plus `trials.csv`
    /// with the 1D parameters that generated each (for `fit`, Fig. 8).
    #[arg(long)]
    trials_dir: Option<PathBuf>,
    /// Output directory (created).
    #[arg(long)]
    out_dir: PathBuf,
}

/// Runs a `softjoint viscoelastic` subcommand.
pub fn run(args: ViscoArgs) -> Result<()> {
    match args.command {
        ViscoCommand::Simulate(a) => simulate(&a),
        ViscoCommand::Fit(a) => fit(&a),
        ViscoCommand::Object(a) => object(&a),
    }
}

/// Reads a text input (CSV, OBJ), without a leading byte-order mark.
fn read_text(path: &Path) -> Result<String> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(plant_common::strip_bom(&text).to_string())
}

/// Checks a model parameter flag: finite and > 0 (or ≥ 0 if `zero_ok`).
fn check_flag(flag: &str, value: f64, zero_ok: bool, unit: &str) -> Result<()> {
    let ok = value.is_finite() && (value > 0.0 || zero_ok && value == 0.0);
    if !ok {
        let range = if zero_ok { ">= 0" } else { "> 0" };
        bail!(
            "{flag} must be finite and {range} ({unit}), got {}",
            plant_common::short_number(value)
        );
    }
    Ok(())
}

fn simulate(a: &SimulateArgs) -> Result<()> {
    check_flag("--k1", a.k1, false, "N/m")?;
    check_flag("--k2", a.k2, false, "N/m")?;
    check_flag("--b", a.b, true, "N s/m")?;
    let text = read_text(&a.input)?;
    let name = a.input.display().to_string();
    let table = read_table(&text, &name)?;
    let params = ThreeElementParams {
        k1_n_per_m: a.k1,
        k2_n_per_m: a.k2,
        b_n_s_per_m: a.b,
    };
    let trace = simulate_table(&table, &name, params)?;
    let csv = trace_csv(&trace);
    match &a.output {
        Some(p) => output::write_csv(p, &csv),
        None => output::print_csv(&csv),
    }
}

/// `time_s,displacement,force` rows of a trace.
fn trace_csv(trace: &Trace) -> String {
    let mut s = String::from("time_s,displacement,force\n");
    for k in 0..trace.time_s.len() {
        let _ = writeln!(
            s,
            "{},{},{}",
            trace.time_s[k], trace.displacement_m[k], trace.force_n[k]
        );
    }
    s
}

fn fit(a: &FitArgs) -> Result<()> {
    let text = read_text(&a.input)?;
    let name = a.input.display().to_string();
    let weighting = if a.uniform {
        Weighting::Uniform
    } else {
        Weighting::Seed
    };
    let (c, r) = fit_trial_text(&text, &name, weighting)?;
    let (t, u, f) = (&c.values[0], &c.values[1], &c.values[2]);
    let weighting_name = weighting_name(weighting);
    if let Some(p) = &a.plot {
        let fitted = simulate_force(r.k1_n_per_m, r.k2_n_per_m, r.b_n_s_per_m, t, u)?;
        let caption = format!(
            "{name}: k1 = {:.4e} N/m, k2 = {:.4e} N/m, b = {:.4e} N s/m ({weighting_name} weighting)",
            r.k1_n_per_m, r.k2_n_per_m, r.b_n_s_per_m,
        );
        output::write_svg(p, &fit_plot(t, f, &fitted, &caption))?;
    }
    if a.json {
        fit_summary(&r, weighting, t.len())?.print()
    } else {
        print_fit(&r, t.len(), weighting_name)
    }
}

/// The text report of a fit: each parameter with how well the trial
/// determines it, and the residual.
fn print_fit(r: &TrialFit, samples: usize, weighting_name: &str) -> Result<()> {
    let factor = r.uncertainty_factor();
    let spread = |k: usize| {
        if factor[k] < 2.0 {
            format!("±{:.1} %", 100.0 * (factor[k] - 1.0))
        } else {
            format!("within a factor of {:.1}", factor[k])
        }
    };
    outln!("k1 = {:.6e} N/m ({})", r.k1_n_per_m, spread(0));
    outln!("k2 = {:.6e} N/m ({})", r.k2_n_per_m, spread(1));
    outln!("b  = {:.6e} N s/m ({})", r.b_n_s_per_m, spread(2));
    outln!(
        "rms residual = {:.4e} N over {samples} samples ({weighting_name} weighting, {} evaluations)",
        r.rms_residual_n,
        r.evaluations
    );
    Ok(())
}

fn object(a: &ObjectArgs) -> Result<()> {
    let job = ObjectJob {
        duration_s: a.duration_s,
        probe_every: a.probe_every,
        seed: a.seed,
        tensor: a.tensor,
    };
    job.check("--")?;
    // The outputs are checked before the long part, not after it.
    output::check_dir(&a.out_dir)?;
    if let Some(dir) = &a.trials_dir {
        output::check_dir(dir)?;
    }
    let mesh = read_named(a.mesh.as_deref())?;
    let script = read_named(a.script.as_deref())?;
    let phase = host_tools::progress::spinner("building the DGFM (FEM)", false);
    let o = run_object(named(&mesh), named(&script), &job, &mut |what| {
        phase.set_message(what.to_string())
    })?;
    phase.finish_and_clear();
    if let Some(dir) = &a.trials_dir {
        write_trials(dir, &o.campaign)?;
    }
    write_object_files(&a.out_dir, &o.dgfm, &o.campaign, &o.identified, &o.run)?;
    print_object_summary(&a.out_dir, &o.figures())
}

/// A file's text and name as borrowed strings.
fn named(f: &Option<(String, String)>) -> Option<(&str, &str)> {
    f.as_ref().map(|(t, n)| (t.as_str(), n.as_str()))
}

/// A file's text (without a byte-order mark) and its name, if given.
fn read_named(path: Option<&Path>) -> Result<Option<(String, String)>> {
    path.map(|p| Ok((read_text(p)?, p.display().to_string())))
        .transpose()
}

/// Every simulated trial as `trial_NNNN.csv` and the index `trials.csv`
/// with the 1D parameters that generated each.
fn write_trials(dir: &Path, campaign: &Campaign) -> Result<()> {
    output::create_dir(dir)?;
    let mut index = String::from(
        "file,vertex,speed_m_per_s,ux,uy,uz,true_k1_n_per_m,true_k2_n_per_m,true_b_n_s_per_m\n",
    );
    for (k, t) in campaign.trials.iter().enumerate() {
        let name = format!("trial_{k:04}.csv");
        let mut s = String::from("time_s,displacement,force\n");
        for i in 0..t.time_s.len() {
            let _ = writeln!(
                s,
                "{},{:e},{:e}",
                t.time_s[i], t.displacement_m[i], t.force_n[i]
            );
        }
        output::write_csv(&dir.join(&name), &s)?;
        let (k1, k2, b) = campaign.trial_scalars(t).context("trial without truth")?;
        let d = t.direction;
        let _ = writeln!(
            index,
            "{name},{},{},{},{},{},{k1:e},{k2:e},{b:e}",
            t.vertex, t.speed_m_per_s, d[0], d[1], d[2]
        );
    }
    output::write_csv(&dir.join("trials.csv"), &index)
}

/// frames.csv, haptic.csv, params.csv and damping.svg of an `object` run.
fn write_object_files(
    out_dir: &Path,
    dgfm: &Dgfm,
    campaign: &Campaign,
    identified: &IdentifiedObject,
    run: &ProbeRun,
) -> Result<()> {
    output::create_dir(out_dir)?;
    let nv = dgfm.mesh().len();
    let mut frames = String::from("time_s,vertex,ux_m,uy_m,uz_m,fx_n,fy_n,fz_n\n");
    for fr in &run.frames {
        for v in 0..nv {
            let (u, f) = (fr.displacement_m[v], fr.force_n[v]);
            let _ = writeln!(
                frames,
                "{},{v},{:e},{:e},{:e},{:e},{:e},{:e}",
                fr.time_s, u[0], u[1], u[2], f[0], f[1], f[2]
            );
        }
    }
    output::write_csv(&out_dir.join("frames.csv"), &frames)?;
    output::write_csv(&out_dir.join("haptic.csv"), &haptic_csv(run))?;
    let per_vertex = &identified.damping_per_vertex_n_s_per_m;
    let mut ps = String::from("vertex,fixed,damping_magnitude_n_s_per_m\n");
    for (v, (&fixed, damping)) in dgfm.fixed().iter().zip(per_vertex).enumerate() {
        let _ = writeln!(ps, "{v},{},{damping:e}", u8::from(fixed));
    }
    output::write_csv(&out_dir.join("params.csv"), &ps)?;
    let caption = format!(
        "damping magnitude ({} trials, {} vertices estimated)",
        campaign.trials.len(),
        identified.estimates.len()
    );
    output::write_svg(
        &out_dir.join("damping.svg"),
        &false_colour_mesh(dgfm.mesh(), per_vertex, [0.3, 1.0, -0.5], &caption),
    )
}

/// haptic.csv: force and contact displacement per step, beside the exact
/// reference's displacement.
fn haptic_csv(run: &ProbeRun) -> String {
    let mut hs =
        String::from("time_s,fx_n,fy_n,fz_n,ux_m,uy_m,uz_m,exact_ux_m,exact_uy_m,exact_uz_m\n");
    for (s, e) in run.samples.iter().zip(&run.exact_samples) {
        let (f, u, x) = (
            s.force_n,
            s.contact_displacement_m,
            e.contact_displacement_m,
        );
        let _ = writeln!(
            hs,
            "{},{},{},{},{:e},{:e},{:e},{:e},{:e},{:e}",
            s.time_s, f[0], f[1], f[2], u[0], u[1], u[2], x[0], x[1], x[2]
        );
    }
    hs
}

fn print_object_summary(out_dir: &Path, f: &ObjectFigures) -> Result<()> {
    outln!(
        "{} vertices ({} traction), {} trials fitted, {} vertices estimated; {} haptic steps, {} display frames written to {}",
        f.vertices,
        f.traction_vertices,
        f.trials,
        f.estimated_vertices,
        f.haptic_steps,
        f.display_frames,
        out_dir.display()
    );
    outln!(
        "firmware update vs exact reference: contact max |Δu| {:.3e} m ({:.3} % of max |u|), all vertices over the display frames {:.3e} m ({:.3} %)",
        f.contact_difference_m,
        100.0 * f.contact_difference_rel,
        f.frames_difference_m,
        100.0 * f.frames_difference_rel
    );
    Ok(())
}

/// Measured and fitted force against time.
fn fit_plot(time_s: &[f64], measured_n: &[f64], fitted_n: &[f64], caption: &str) -> String {
    plot::line_charts(&[Chart {
        title: caption.to_string(),
        x_label: "time (s)".into(),
        y_label: "force (N)".into(),
        series: vec![
            Series::over("measured", "#888", false, time_s, measured_n),
            Series::over("fitted", "#d00", false, time_s, fitted_n),
        ],
    }])
    .finish()
}

/// False-colour image of `value` (one per mesh vertex) over the mesh (the
/// seed's Fig. 9: red high, blue low), orthographic view from `view_dir`
/// (towards the object), painter's algorithm, back faces culled. Colour
/// scale from 0 to the largest finite value.
fn false_colour_mesh(
    mesh: &SurfaceMesh,
    value: &[f64],
    view_dir: [f64; 3],
    caption: &str,
) -> String {
    let (w, h): (f64, f64) = (640.0, 520.0);
    let d = Vec3::from(view_dir).normalize();
    // Screen axes: right = d × z (or x if looking along z), up = right × d.
    let mut right = d.cross(&Vec3::z());
    if right.norm_squared() < 1e-12 {
        right = Vec3::x();
    }
    let right = right.normalize();
    let up = right.cross(&d);
    let proj: Vec<(f64, f64, f64)> = mesh
        .vertices_m
        .iter()
        .map(|p| {
            let p = Vec3::from(*p);
            (p.dot(&right), p.dot(&up), p.dot(&d))
        })
        .collect();
    let (xmin, xmax, ymin, ymax) = proj.iter().fold(
        (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ),
        |(a, b, c, e), &(x, y, _)| (a.min(x), b.max(x), c.min(y), e.max(y)),
    );
    let scale = ((w - 80.0) / (xmax - xmin).max(1e-12)).min((h - 120.0) / (ymax - ymin).max(1e-12));
    let sx = |x: f64| 40.0 + (x - xmin) * scale;
    let sy = |y: f64| h - 80.0 - (y - ymin) * scale;
    let vmax = value
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0, f64::max);
    let mut tris: Vec<(f64, usize)> = mesh
        .triangles
        .iter()
        .enumerate()
        .filter(|(_, t)| {
            let [a, b, c] = t.map(|i| Vec3::from(mesh.vertices_m[i]));
            (b - a).cross(&(c - a)).dot(&d) < 0.0 // facing the viewer
        })
        .map(|(k, t)| (t.iter().map(|&i| proj[i].2).sum::<f64>(), k))
        .collect();
    tris.sort_by(|a, b| b.0.total_cmp(&a.0)); // far first
    let mut svg = Svg::new(w, h);
    let rgb = |(r, g, b): (u8, u8, u8)| format!("rgb({r},{g},{b})");
    for (_, k) in tris {
        let t = mesh.triangles[k];
        let v = t
            .iter()
            .map(|&i| value.get(i).copied().unwrap_or(0.0))
            .sum::<f64>()
            / 3.0;
        let fill = rgb(plot::false_colour(if vmax > 0.0 { v / vmax } else { 0.0 }));
        let pts: Vec<(f64, f64)> = t.iter().map(|&i| (sx(proj[i].0), sy(proj[i].1))).collect();
        svg.polygon(&pts, &fill, Stroke::solid("#333", 0.3));
    }
    for k in 0..10 {
        let fill = rgb(plot::false_colour(k as f64 / 9.0));
        svg.rect(40.0 + 30.0 * k as f64, h - 50.0, 30.0, 14.0, &fill, None);
    }
    svg.text(40.0, h - 22.0, 12.0, Anchor::Start, "0");
    svg.text(
        340.0,
        h - 22.0,
        12.0,
        Anchor::Start,
        &format!("{vmax:.4e} N·s/m"),
    );
    svg.text(40.0, 24.0, 14.0, Anchor::Start, caption);
    svg.finish()
}
