//! `softjoint viscoelastic`: the 3-element model of seed 002 for users'
//! data (`simulate`, `fit`) and the measured-object pipeline on a mesh
//! (`object`). The physics lives in `plant_viscoelastic`; this is
//! argument handling, file I/O and reports.
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use host_tools::outln;
use host_tools::output;
use host_tools::plot::{self, Anchor, Chart, Series, Stroke, Svg};
use host_tools::visco_core::CoreObject;
use plant_viscoelastic::dgfm::{support_below, Dgfm, DEFAULT_SUPPORT_HEIGHT_FRACTION};
use plant_viscoelastic::error::VeError;
use plant_viscoelastic::estimate::{estimate_all, spread_columns};
use plant_viscoelastic::fem::{LinearElastic, DEFAULT_SHELL_SCALES};
use plant_viscoelastic::fit::{
    fit_trial, fit_trials, simulate_displacement, simulate_force, NelderMeadOptions, Weighting,
};
use plant_viscoelastic::io::{columns_of, read_columns, read_probe_script, read_table};
use plant_viscoelastic::measure::{simulate_campaign, ProbeProtocol, Trial, VertexTruth};
use plant_viscoelastic::object::HapticSample;
use plant_viscoelastic::object::{run_script, Contact, ProbeEvent, HAPTIC_PERIOD_S};
use plant_viscoelastic::Vec3;
use plant_viscoelastic::{HapticLoop, SurfaceMesh, ViscoObject};
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
    Simulate {
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
    },
    /// Fit (k1, k2, b) to a force-vs-time trial CSV
    /// `time_s,displacement,force` (s, m, N) by Nelder–Mead with the seed's
    /// weighting (tail ×100, 3 points around the peak ×1000).
    Fit {
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
    },
    /// Build the DGFM object of a mesh (default: the shipped ~200-vertex
    /// blob), estimate its parameters from simulated probe trials, run a
    /// scripted probe at 1 kHz and write per-vertex displacement and force
    /// at 30 Hz, the contact trace, the parameters and a false-colour
    /// damping image.
    Object {
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
    },
}

/// Runs a `softjoint viscoelastic` subcommand.
pub fn run(args: ViscoArgs) -> Result<()> {
    match args.command {
        ViscoCommand::Simulate {
            input,
            k1,
            k2,
            b,
            output,
        } => simulate(&input, k1, k2, b, output.as_deref()),
        ViscoCommand::Fit {
            input,
            uniform,
            plot,
            json,
        } => fit(&input, uniform, plot.as_deref(), json),
        ViscoCommand::Object {
            mesh,
            script,
            duration_s,
            probe_every,
            seed,
            tensor,
            trials_dir,
            out_dir,
        } => {
            let o = ObjectRun {
                duration_s,
                every: probe_every,
                seed,
                tensor,
            };
            object(
                mesh.as_deref(),
                script.as_deref(),
                &o,
                trials_dir.as_deref(),
                &out_dir,
            )
        }
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

fn simulate(input: &Path, k1: f64, k2: f64, b: f64, output: Option<&Path>) -> Result<()> {
    check_flag("--k1", k1, false, "N/m")?;
    check_flag("--k2", k2, false, "N/m")?;
    check_flag("--b", b, true, "N s/m")?;
    let text = read_text(input)?;
    let name = input.display().to_string();
    let table = read_table(&text, &name)?;
    let (t, u, f) = if table.has("displacement") {
        let c = columns_of(&table, &["time_s", "displacement"], Some("time_s"))?;
        let (t, u) = (c.values[0].clone(), c.values[1].clone());
        let f = simulate_force(k1, k2, b, &t, &u)?;
        (t, u, f)
    } else if table.has("force") {
        let c = columns_of(&table, &["time_s", "force"], Some("time_s"))?;
        let (t, f) = (c.values[0].clone(), c.values[1].clone());
        let u = simulate_displacement(k1, k2, b, &t, &f)?;
        (t, u, f)
    } else {
        bail!(
            "{name}:{}: missing column: need `displacement` or `force` beside `time_s` (the header has: {})",
            table.header_line,
            plant_common::csv_input::excerpt(&table.columns.join(", "))
        );
    };
    // Parameters or samples near the f64 range overflow the model; a NaN or
    // infinite result is refused rather than written.
    for k in 0..t.len() {
        if !(u[k].is_finite() && f[k].is_finite()) {
            bail!(
                "{name}: the model overflowed at the sample at time_s = {} (displacement {}, force {}): k1 = {k1:e}, k2 = {k2:e}, b = {b:e} and the input are too large together",
                t[k],
                u[k],
                f[k]
            );
        }
    }
    let mut s = String::from("time_s,displacement,force\n");
    for k in 0..t.len() {
        let _ = writeln!(s, "{},{},{}", t[k], u[k], f[k]);
    }
    match output {
        Some(p) => output::write_csv(p, &s),
        None => output::print_csv(&s),
    }
}

fn fit(input: &Path, uniform: bool, plot: Option<&Path>, json: bool) -> Result<()> {
    let text = read_text(input)?;
    let name = input.display().to_string();
    let c = read_columns(
        &text,
        &name,
        &["time_s", "displacement", "force"],
        Some("time_s"),
    )?;
    let (t, u, f) = (&c.values[0], &c.values[1], &c.values[2]);
    let weighting = if uniform {
        Weighting::Uniform
    } else {
        Weighting::Seed
    };
    let r = fit_trial(t, u, f, weighting, NelderMeadOptions::default())
        .with_context(|| format!("fitting {name}"))?;
    if !(r.rms_residual_n.is_finite() && r.weighted_cost_n2.is_finite()) {
        bail!(
            "fitting {name}: the model's force overflowed (rms residual {} N): displacements and forces this large cannot be fitted",
            plant_common::short_number(r.rms_residual_n)
        );
    }
    // Numbers the data do not determine are not a result.
    r.check_determined()
        .with_context(|| format!("fitting {name}"))?;
    if let Some(p) = plot {
        let fitted = simulate_force(r.k1_n_per_m, r.k2_n_per_m, r.b_n_s_per_m, t, u)?;
        let caption = format!(
            "{name}: k1 = {:.4e} N/m, k2 = {:.4e} N/m, b = {:.4e} N s/m ({} weighting)",
            r.k1_n_per_m,
            r.k2_n_per_m,
            r.b_n_s_per_m,
            if uniform { "uniform" } else { "seed" }
        );
        output::write_svg(p, &fit_plot(t, f, &fitted, &caption))?;
    }
    // How far each parameter could move before the fit changes by its
    // own misfit: a factor (1.05 is ±5 %).
    let factor = r.ln_uncertainty.map(f64::exp);
    let spread = |k: usize| {
        if factor[k] < 2.0 {
            format!("±{:.1} %", 100.0 * (factor[k] - 1.0))
        } else {
            format!("within a factor of {:.1}", factor[k])
        }
    };
    if json {
        output::JsonObject::new()
            .field("k1_n_per_m", &r.k1_n_per_m)?
            .field("k2_n_per_m", &r.k2_n_per_m)?
            .field("b_n_s_per_m", &r.b_n_s_per_m)?
            .field("rms_residual_n", &r.rms_residual_n)?
            .field("weighted_cost_n2", &r.weighted_cost_n2)?
            .field("uncertainty_factor", &factor)?
            .field("evaluations", &r.evaluations)?
            .field("weighting", if uniform { "uniform" } else { "seed" })?
            .field("samples", &t.len())?
            .print()?;
    } else {
        outln!("k1 = {:.6e} N/m ({})", r.k1_n_per_m, spread(0));
        outln!("k2 = {:.6e} N/m ({})", r.k2_n_per_m, spread(1));
        outln!("b  = {:.6e} N s/m ({})", r.b_n_s_per_m, spread(2));
        outln!(
            "rms residual = {:.4e} N over {} samples ({} weighting, {} evaluations)",
            r.rms_residual_n,
            t.len(),
            if uniform { "uniform" } else { "seed" },
            r.evaluations
        );
    }
    Ok(())
}

/// Synthetic ground truth of the default pipeline: Rayleigh b larger in the
/// middle of the object than at its ends (like the seed's triceratops,
/// Fig. 9), ratio from the seed's Fig. 8 fit. Estimates, not measurements.
fn synthetic_truth(dgfm: &Dgfm, every: usize) -> Result<Vec<VertexTruth>> {
    let mesh = dgfm.mesh();
    let x_max = mesh
        .vertices_m
        .iter()
        .map(|v| v[0].abs())
        .fold(0.0, f64::max)
        .max(1e-12);
    let mut out = Vec::new();
    for j in (0..dgfm.len()).step_by(every.max(1)) {
        let x = mesh.vertices_m[dgfm.traction_vertices()[j]][0].abs() / x_max;
        out.push(VertexTruth::from_dgfm(
            dgfm,
            j,
            0.29,
            0.1 + 0.4 * (1.0 - x),
        )?);
    }
    Ok(out)
}

/// Longest `object` run: every haptic step and every 30 Hz frame of every
/// vertex is kept in memory before it is written. Estimate for the default
/// ~200-vertex mesh at this length: 0.2 GB of frames, 0.5 GB of CSV text.
const MAX_OBJECT_DURATION_S: f64 = 600.0;

/// Most surface vertices `object` takes: its time grows about as n³
/// (1,982 vertices took 30 s, a 19,462-vertex sphere ran past 60 s with no
/// end in sight); 3,000 vertices is about two minutes.
const MAX_OBJECT_VERTICES: usize = 3000;

/// Scalar options of `object`.
struct ObjectRun {
    duration_s: f64,
    every: usize,
    seed: u64,
    tensor: bool,
}

fn write_trials(dir: &Path, trials: &[Trial], truths: &[VertexTruth]) -> Result<()> {
    output::create_dir(dir)?;
    let mut index = String::from(
        "file,vertex,speed_m_per_s,ux,uy,uz,true_k1_n_per_m,true_k2_n_per_m,true_b_n_s_per_m\n",
    );
    for (k, t) in trials.iter().enumerate() {
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
        let truth = truths
            .iter()
            .find(|v| v.vertex == t.vertex)
            .context("trial without truth")?;
        let (k1, k2, b) = truth.trial_scalars(t.direction);
        let d = t.direction;
        let _ = writeln!(
            index,
            "{name},{},{},{},{},{},{k1:e},{k2:e},{b:e}",
            t.vertex, t.speed_m_per_s, d[0], d[1], d[2]
        );
    }
    output::write_csv(&dir.join("trials.csv"), &index)
}

fn object(
    mesh_path: Option<&Path>,
    script: Option<&Path>,
    run: &ObjectRun,
    trials_dir: Option<&Path>,
    out_dir: &Path,
) -> Result<()> {
    let ObjectRun {
        duration_s,
        every,
        seed,
        tensor,
    } = *run;
    if !(duration_s.is_finite() && (HAPTIC_PERIOD_S..=MAX_OBJECT_DURATION_S).contains(&duration_s))
    {
        bail!(
            "--duration-s must be between one haptic period ({HAPTIC_PERIOD_S} s) and {MAX_OBJECT_DURATION_S} s, got {duration_s:e}"
        );
    }
    if every == 0 {
        bail!("--probe-every must be at least 1 (probe every N-th traction vertex)");
    }
    // The outputs are checked before the long part, not after it.
    output::check_dir(out_dir)?;
    if let Some(dir) = trials_dir {
        output::check_dir(dir)?;
    }
    let mesh = match mesh_path {
        Some(p) => SurfaceMesh::from_obj_str(&read_text(p)?, &p.display().to_string())?,
        None => SurfaceMesh::default_object(),
    };
    let n = mesh.vertices_m.len();
    if n > MAX_OBJECT_VERTICES {
        // Measured: 872 vertices 4 s, 1,982 vertices 30 s (release build):
        // about n³, so the estimate scales the latter.
        let minutes = 0.5 * (n as f64 / 1982.0).powi(3);
        bail!(
            "{}: {n} vertices is more than {MAX_OBJECT_VERTICES}: the DGFM and its fits take time growing as the cube of the vertex count (about {} minutes for this mesh; 1,982 vertices took 30 s); simplify the mesh (the seed's object has 193 vertices)",
            mesh_path.map_or("the mesh".into(), |p| p.display().to_string()),
            plant_common::short_number(minutes.round())
        );
    }
    let phase =
        host_tools::progress::spinner(&format!("building the DGFM of {n} vertices (FEM)"), false);
    let fixed = support_below(&mesh, DEFAULT_SUPPORT_HEIGHT_FRACTION);
    let dgfm = Dgfm::from_mesh(mesh, LinearElastic::default(), fixed, &DEFAULT_SHELL_SCALES)?;
    // Measure (simulated), fit, estimate and spread, as in seed §4.
    phase.set_message("simulating and fitting the probe campaign");
    let truths = synthetic_truth(&dgfm, every)?;
    let protocol = ProbeProtocol {
        speeds_m_per_s: vec![20.0e-3],
        ..ProbeProtocol::default()
    };
    let trials = simulate_campaign(&dgfm, &truths, &protocol, seed)?;
    if let Some(dir) = trials_dir {
        write_trials(dir, &trials, &truths)?;
    }
    let fits = fit_trials(&trials, Weighting::Seed, NelderMeadOptions::default());
    let estimates = estimate_all(&dgfm, &trials, &fits)?;
    let params = spread_columns(dgfm.len(), &estimates, 1.0, tensor)?;
    let magnitude = params.damping_magnitude_n_s_per_m(&dgfm);
    let nv = dgfm.mesh().len();
    let mut per_vertex = vec![0.0; nv];
    for (j, &v) in dgfm.traction_vertices().iter().enumerate() {
        per_vertex[v] = magnitude[j];
    }
    let script_text = script.map(read_text).transpose()?;
    let (events, event_lines) = match (script, &script_text) {
        (Some(p), Some(text)) => {
            let s = read_probe_script(text, &p.display().to_string(), nv)?;
            (s.events, s.lines)
        }
        _ => {
            let top = (0..nv)
                .filter(|&v| !dgfm.fixed()[v])
                .max_by(|&a, &b| {
                    dgfm.mesh().vertices_m[a][2].total_cmp(&dgfm.mesh().vertices_m[b][2])
                })
                .context("no traction vertex")?;
            let default = vec![
                ProbeEvent {
                    time_s: 0.0,
                    contact: Some(Contact::Vertex(top)),
                    force_n: [0.0, 0.0, -1.0],
                },
                ProbeEvent {
                    time_s: 0.5,
                    contact: None,
                    force_n: [0.0; 3],
                },
            ];
            (default, Vec::new())
        }
    };
    let mesh_for_image = dgfm.mesh().clone();
    let fixed_flags = dgfm.fixed().to_vec();
    // The haptic device runs the firmware's real-time update (seed §5);
    // the plant's exact reference runs the same script beside it.
    let name_script_error = |e: VeError| {
        // An event of the user's script is named by its file and line.
        match (&e, script) {
            (VeError::ProbeEvent { index, error, .. }, Some(p)) => match event_lines.get(*index) {
                Some(line) => anyhow::anyhow!("{}:{line}: {error}", p.display()),
                None => anyhow::Error::new(e),
            },
            _ => anyhow::Error::new(e),
        }
    };
    phase.set_message("running the probe script at 1 kHz");
    let reference = ViscoObject::new(dgfm.clone(), params.clone(), HAPTIC_PERIOD_S)?;
    let mut exact = HapticLoop::new(reference)?;
    let exact_samples = run_script(&mut exact, &events, duration_s).map_err(name_script_error)?;
    let core = CoreObject::new(dgfm, &params, HAPTIC_PERIOD_S)?;
    let mut haptic = HapticLoop::new(core)?;
    let samples = run_script(&mut haptic, &events, duration_s).map_err(name_script_error)?;
    let difference = CoreDifference::of(&samples, &exact_samples, &haptic.frames, &exact.frames);
    phase.finish_and_clear();
    output::create_dir(out_dir)?;
    let mut frames = String::from("time_s,vertex,ux_m,uy_m,uz_m,fx_n,fy_n,fz_n\n");
    for fr in &haptic.frames {
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
    let mut hs =
        String::from("time_s,fx_n,fy_n,fz_n,ux_m,uy_m,uz_m,exact_ux_m,exact_uy_m,exact_uz_m\n");
    for (s, e) in samples.iter().zip(&exact_samples) {
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
    output::write_csv(&out_dir.join("haptic.csv"), &hs)?;
    let mut ps = String::from("vertex,fixed,damping_magnitude_n_s_per_m\n");
    for v in 0..nv {
        let _ = writeln!(ps, "{v},{},{:e}", u8::from(fixed_flags[v]), per_vertex[v]);
    }
    output::write_csv(&out_dir.join("params.csv"), &ps)?;
    let caption = format!(
        "damping magnitude ({} trials, {} vertices estimated)",
        trials.len(),
        estimates.len()
    );
    output::write_svg(
        &out_dir.join("damping.svg"),
        &false_colour_mesh(&mesh_for_image, &per_vertex, [0.3, 1.0, -0.5], &caption),
    )?;
    outln!(
        "{} vertices ({} traction), {} trials fitted, {} vertices estimated; {} haptic steps, {} display frames written to {}",
        nv,
        fixed_flags.iter().filter(|f| !**f).count(),
        trials.len(),
        estimates.len(),
        samples.len(),
        haptic.frames.len(),
        out_dir.display()
    );
    outln!(
        "firmware update vs exact reference: contact max |Δu| {:.3e} m ({:.3} % of max |u|), all vertices over the display frames {:.3e} m ({:.3} %)",
        difference.contact_m,
        100.0 * difference.contact_rel,
        difference.frames_m,
        100.0 * difference.frames_rel
    );
    Ok(())
}

/// How far the firmware's real-time update is from the plant's exact
/// reference over a run.
struct CoreDifference {
    contact_m: f64,
    contact_rel: f64,
    frames_m: f64,
    frames_rel: f64,
}

impl CoreDifference {
    fn of(
        core: &[HapticSample],
        exact: &[HapticSample],
        core_frames: &[plant_viscoelastic::object::DisplayFrame],
        exact_frames: &[plant_viscoelastic::object::DisplayFrame],
    ) -> Self {
        let dist = |a: [f64; 3], b: [f64; 3]| {
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        };
        let norm = |a: [f64; 3]| dist(a, [0.0; 3]);
        let (mut contact_m, mut contact_max) = (0.0f64, 0.0f64);
        for (c, e) in core.iter().zip(exact) {
            contact_m = contact_m.max(dist(c.contact_displacement_m, e.contact_displacement_m));
            contact_max = contact_max.max(norm(e.contact_displacement_m));
        }
        let (mut frames_m, mut frames_max) = (0.0f64, 0.0f64);
        for (c, e) in core_frames.iter().zip(exact_frames) {
            for (a, b) in c.displacement_m.iter().zip(&e.displacement_m) {
                frames_m = frames_m.max(dist(*a, *b));
                frames_max = frames_max.max(norm(*b));
            }
        }
        let rel = |d: f64, m: f64| if m > 0.0 { d / m } else { 0.0 };
        CoreDifference {
            contact_m,
            contact_rel: rel(contact_m, contact_max),
            frames_m,
            frames_rel: rel(frames_m, frames_max),
        }
    }
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
