//! `softjoint dlo`: deformable linear objects (seed 000).
//!
//! * `rope` — the dynamic rope of Shi & Payandeh driven by a TOML scenario
//!   (scripted hands, pins, desk, topology checks); writes the node
//!   positions over time as CSV and a frame strip (top and side views);
//! * `solve` — the static wire or belt of Wakamatsu et al. from a TOML
//!   problem; writes the solved shape as CSV and its three views.
//!
//! Both print a short report, or with `--json` a machine-readable summary.
//! The models, the runs and the solves live in `plant_dlo`; this is
//! argument handling, files, reports and pictures.
use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use host_tools::dlo_solve::{solve_summary, unverified};
use host_tools::output::{self, JsonObject};
use host_tools::plot::{self, PanelStroke, ViewPanel};
use host_tools::{out, outln};
use plant_dlo::rope::script::{Frame, RopeScenario, RunResult};
use plant_dlo::rope::verify::RopeChecks;
use plant_dlo::rope::V3;
use plant_dlo::wire::belt::BeltShape;
use plant_dlo::wire::linear::SequenceStep;
use plant_dlo::wire::problem::{StaticProblem, StaticSolution};
use plant_dlo::wire::WireShape;
use serde::de::DeserializeOwned;

#[derive(Args)]
pub struct DloArgs {
    #[command(subcommand)]
    command: DloCommand,
}

#[derive(Subcommand)]
enum DloCommand {
    /// Run the dynamic rope (default: tie an overhand knot, pull it tight,
    /// untie it).
    Rope(RopeArgs),
    /// Solve a static wire, belt or end-distance sequence (Wakamatsu et
    /// al.) from a TOML problem.
    Solve(SolveArgs),
}

#[derive(Args)]
struct SolveArgs {
    /// Problem file (TOML): `model = "wire" | "belt" | "sequence"`.
    problem: PathBuf,
    /// Output directory for shape.csv and shape.svg.
    #[arg(long, default_value = "dlo-out")]
    out: PathBuf,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct RopeArgs {
    /// Scenario file (TOML); without it the built-in overhand-knot scenario
    /// runs.
    scenario: Option<PathBuf>,
    /// Output directory for rope_nodes.csv and rope_frames.svg.
    #[arg(long, default_value = "dlo-out")]
    out: PathBuf,
    /// Frames in the picture strip.
    #[arg(allow_negative_numbers = true, long, default_value_t = 12)]
    strip: usize,
    /// Print the built-in scenario as TOML and exit.
    #[arg(long)]
    print_default: bool,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
    /// Also run the scenario at half the time step and check that the
    /// shapes at the topology checks and at the end agree (the `time_step`
    /// check; about three times the run's cost).
    #[arg(long)]
    check_step: bool,
    /// Exit 0 even when the run fails its checks (it is still marked
    /// UNVERIFIED in the report, the JSON and the picture).
    #[arg(long)]
    allow_unverified: bool,
}

/// The built-in rope scenario (also `scenarios/dlo/overhand.toml`).
pub const OVERHAND_TOML: &str = include_str!("../../../scenarios/dlo/overhand.toml");

pub fn run(args: DloArgs) -> Result<()> {
    match args.command {
        DloCommand::Rope(a) => rope_cmd(a),
        DloCommand::Solve(a) => solve_cmd(a),
    }
}

/// Reads a TOML file into `T`; errors name the file (and the field, from
/// the TOML parser).
fn load_toml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let text =
        fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    toml::from_str(&text)
        .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().trim_end()))
}

fn rope_cmd(a: RopeArgs) -> Result<()> {
    if a.print_default {
        out!("{OVERHAND_TOML}");
        return Ok(());
    }
    let (scenario, source): (RopeScenario, String) = match &a.scenario {
        Some(p) => (load_toml(p)?, p.display().to_string()),
        None => (
            toml::from_str(OVERHAND_TOML).context("built-in scenario")?,
            "built-in overhand scenario".into(),
        ),
    };
    scenario
        .validate()
        .map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    if a.strip == 0 || a.strip > 60 {
        anyhow::bail!("--strip: must be 1..=60, got {}", a.strip);
    }
    fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let csv_path = a.out.join("rope_nodes.csv");
    // The run is at most 600 s (the scenario's bound), so its frames are
    // kept and written, checked, at the end.
    let mut csv = String::from("time_s,node,x_m,y_m,z_m\n");
    let result = scenario
        .run(|f| rope_csv_rows(&mut csv, f))
        .map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    let started = std::time::Instant::now();
    let half = if a.check_step {
        Some(
            scenario
                .run_half_step()
                .map_err(|e| anyhow::anyhow!("{source} at dt/2: {e}"))?,
        )
    } else {
        None
    };
    let half_s = started.elapsed().as_secs_f64();
    let checks = RopeChecks::of(&scenario, &result, half.as_ref());
    output::write_csv(&csv_path, &csv)?;
    let svg_path = a.out.join("rope_frames.svg");
    output::write_svg(
        &svg_path,
        &rope_strip(&scenario, &result, &checks, a.strip).finish(),
    )?;
    if a.json {
        rope_json(&scenario, &result, &checks)?
            .field("csv", &csv_path)?
            .field("picture", &svg_path)?
            .print()?;
    } else {
        print_rope_report(&scenario, &result, &checks)?;
        if a.check_step {
            outln!("the run at dt/2 took {half_s:.2} s");
        }
        outln!("wrote {} and {}", csv_path.display(), svg_path.display());
    }
    if !checks.verified() && !a.allow_unverified {
        anyhow::bail!(
            "{source}: UNVERIFIED: the run fails {} (see \"checks\" in --json); the files were written with that mark (give --allow-unverified to exit 0)",
            checks.failures().join(", ")
        );
    }
    Ok(())
}

/// One frame's nodes as rows of rope_nodes.csv.
fn rope_csv_rows(csv: &mut String, f: &Frame) {
    for (i, p) in f.x.iter().enumerate() {
        let _ = writeln!(csv, "{:.4},{i},{:.6},{:.6},{:.6}", f.time_s, p.x, p.y, p.z);
    }
}

/// The `--json` summary of a rope run (without the file names): its
/// status and self-checks, figures, topology checks and hands.
fn rope_json(
    scenario: &RopeScenario,
    result: &RunResult,
    checks: &RopeChecks,
) -> Result<JsonObject> {
    JsonObject::new()
        .field("scenario", &scenario.name)?
        .field("status", checks.status())?
        .field("failed_checks", &checks.failures())?
        .field("checks", checks)?
        .field("nodes", &scenario.rope.nodes)?
        .field("model", &scenario.rope.model.number())?
        .field("duration_s", &scenario.duration_s)?
        .field("steps", &result.steps)?
        .field("step_time_us", &result.step_time_us())?
        .field("max_penetration_m", &result.max_penetration_m)?
        .field("max_penetration_time_s", &result.max_penetration_time_s)?
        .field(
            "penetration_tolerance_m",
            &scenario.penetration_tolerance_m(),
        )?
        .field("contact_steps", &result.contact_steps)?
        .field("clamped_segments", &result.clamped_segments)?
        .field("max_internal_force_sum_n", &result.max_internal_force_sum_n)?
        .field("topology", &result.topology)?
        .field("hands", &result.hands)
}

/// The text report of a rope run: the status (first, when UNVERIFIED),
/// the run, each self-check, each topology check and each hand.
fn print_rope_report(
    scenario: &RopeScenario,
    result: &RunResult,
    checks: &RopeChecks,
) -> Result<()> {
    if !checks.verified() {
        outln!(
            "UNVERIFIED: the run fails {} (its figures are not to be trusted)",
            checks.failures().join(", ")
        );
    }
    outln!(
        "{}: {} nodes, model {}, {} s in {} steps ({:.1} µs/step)",
        scenario.name,
        scenario.rope.nodes,
        scenario.rope.model.number(),
        scenario.duration_s,
        result.steps,
        result.step_time_us()
    );
    outln!(
        "deepest segment overlap {:.4} m at {:.2} s (tolerance {:.4} m), {} steps with self-contact",
        result.max_penetration_m,
        result.max_penetration_time_s,
        scenario.penetration_tolerance_m(),
        result.contact_steps
    );
    for (name, c) in [
        ("overlap", Some(&checks.overlap)),
        ("force_balance", Some(&checks.force_balance)),
        ("stability", Some(&checks.stability)),
        ("rest", checks.rest.as_ref()),
        ("time_step", checks.time_step.as_ref()),
    ] {
        let Some(c) = c else { continue };
        outln!(
            "check {name:>13}: {:.4e} {} (tolerance {:.4e}) {}{}",
            c.value,
            c.unit,
            c.tolerance,
            if c.passed { "passed" } else { "FAILED" },
            c.note
                .as_ref()
                .map(|n| format!(" ({n})"))
                .unwrap_or_default()
        );
    }
    if checks.time_step.is_none() {
        outln!("check     time_step: not made (--check-step runs the scenario at dt/2)");
    }
    outln!("status: {}", checks.status());
    for c in &result.topology {
        outln!(
            "topology {:>10} at {:6.2} s: {} crossings seen from above, knot determinant {}",
            c.label,
            c.time_s,
            c.crossings,
            c.determinant
                .map(|d| d.to_string())
                .unwrap_or_else(|| "undetermined".into())
        );
    }
    for h in &result.hands {
        outln!(
            "hand {:>6}: max coupling force {:.2} N, device force {:.3} N (Omni max 3.3 N){}",
            h.name,
            h.max_coupling_force_n,
            h.max_output_force_n,
            if h.missed_grasps_s.is_empty() {
                String::new()
            } else {
                format!(", missed grasps at {:?} s", h.missed_grasps_s)
            }
        );
    }
    Ok(())
}

/// Strokes of a rope seen along one axis pair: one stroke per segment, in
/// order of depth so that the upper strand is drawn last, coloured from
/// blue (node 0) to red (last node).
fn rope_strokes(
    x: &[V3],
    radius_m: f64,
    project: impl Fn(&V3) -> (f64, f64, f64),
) -> Vec<PanelStroke> {
    // Pieces of consecutive points at least six diameters long, each drawn
    // with a halo over its middle, in order of depth: the upper strand cuts
    // the lower one at a crossing while the pieces join without gaps.
    let n = x.len();
    let mut pieces: Vec<(f64, PanelStroke)> = Vec::new();
    let mut start = 0;
    while start + 1 < n {
        let mut end = start + 1;
        let mut len = (x[end] - x[start]).norm();
        while end + 1 < n && len < 12.0 * radius_m {
            len += (x[end + 1] - x[end]).norm();
            end += 1;
        }
        let pts: Vec<(f64, f64, f64)> = x[start..=end].iter().map(&project).collect();
        let depth = pts.iter().map(|p| p.2).sum::<f64>() / pts.len() as f64;
        let (r, g, b) = plot::false_colour(start as f64 / (n - 2).max(1) as f64);
        pieces.push((
            depth,
            PanelStroke {
                points: pts.iter().map(|p| (p.0, p.1)).collect(),
                colour: format!("rgb({r},{g},{b})"),
                width: 2.0 * radius_m,
                width_in_px: false,
                halo: true,
            },
        ));
        start = end;
    }
    pieces.sort_by(|a, b| a.0.total_cmp(&b.0));
    pieces.into_iter().map(|s| s.1).collect()
}

fn rope_panel(s: &RopeScenario, f: &Frame, title: String, top: bool) -> ViewPanel {
    let project = |p: &V3| {
        if top {
            (p.x, p.y, p.z)
        } else {
            (p.x, p.z, -p.y)
        }
    };
    let mut panel = ViewPanel {
        title,
        axes: if top {
            ("x (m)".into(), "y (m)".into())
        } else {
            ("x (m)".into(), "z (m)".into())
        },
        strokes: rope_strokes(&f.x, s.rope.radius_m, project),
        markers: Vec::new(),
    };
    if !top {
        if let Some(h) = s.desk_height_m {
            let (x0, x1) =
                f.x.iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                        (a.min(p.x), b.max(p.x))
                    });
            panel.strokes.insert(
                0,
                PanelStroke {
                    points: vec![(x0 - 0.3, h), (x1 + 0.3, h)],
                    colour: "#8a6d3b".into(),
                    width: 3.0,
                    width_in_px: true,
                    halo: false,
                },
            );
        }
    }
    for (k, hand) in f.hands_m.iter().enumerate() {
        let (a, b, _) = project(hand);
        let name = s.hands.get(k).map(|h| h.name.as_str()).unwrap_or("hand");
        let colour = if f.held[k].is_some() {
            "#1a9850"
        } else {
            "#999"
        };
        panel
            .markers
            .push(((a, b), colour.into(), name.to_string()));
    }
    panel
}

/// The frame strip: `count` frames evenly spread over the run (the check
/// times among them), top view above side view.
fn rope_strip(s: &RopeScenario, r: &RunResult, checks: &RopeChecks, count: usize) -> plot::Svg {
    let frames = &r.frames;
    let mut picks: Vec<usize> = (0..count)
        .map(|k| (k * (frames.len() - 1)) / (count - 1).max(1))
        .collect();
    for c in &r.topology {
        if let Some(i) = frames
            .iter()
            .position(|f| (f.time_s - c.time_s).abs() < 0.5 * s.frame_interval_s + 1e-9)
        {
            picks.push(i);
        }
    }
    picks.sort_unstable();
    picks.dedup();
    let label = |f: &Frame| {
        let check = r
            .topology
            .iter()
            .find(|c| (f.time_s - c.time_s).abs() < 0.5 * s.frame_interval_s + 1e-9);
        match check {
            Some(c) => format!(
                "t = {:.1} s · {} (det {})",
                f.time_s,
                c.label,
                c.determinant.map(|d| d.to_string()).unwrap_or("?".into())
            ),
            None => format!("t = {:.1} s", f.time_s),
        }
    };
    let columns = 4;
    let mark = if checks.verified() {
        ""
    } else {
        " · UNVERIFIED"
    };
    let mut panels = Vec::new();
    for chunk in picks.chunks(columns) {
        for &i in chunk {
            panels.push(rope_panel(
                s,
                &frames[i],
                format!("top · {}{mark}", label(&frames[i])),
                true,
            ));
        }
        for _ in chunk.len()..columns {
            panels.push(ViewPanel::default());
        }
        for &i in chunk {
            panels.push(rope_panel(s, &frames[i], format!("side{mark}"), false));
        }
        for _ in chunk.len()..columns {
            panels.push(ViewPanel::default());
        }
    }
    let mut svg = plot::panel_grid(&panels, columns, 300.0, (1.0, "1 m"), true);
    // panel_grid's layout: rows of 300 px panels with a 22 px head and an
    // 18 px foot, and 24 px below for the scale bar.
    let rows = panels.len().div_ceil(columns).max(1) as f64;
    unverified_note_at(
        &mut svg,
        &checks.failures(),
        columns as f64 * 300.0 - 10.0,
        (300.0 + 22.0 + 18.0) * rows + 24.0 - 8.0,
    );
    svg
}

fn solve_cmd(a: SolveArgs) -> Result<()> {
    let problem: StaticProblem = load_toml(&a.problem)?;
    let src = a.problem.display().to_string();
    fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let csv_path = a.out.join("shape.csv");
    let svg_path = a.out.join("shape.svg");
    let started = std::time::Instant::now();
    let solution = problem.solve().map_err(|e| anyhow::anyhow!("{src}: {e}"))?;
    let wall = started.elapsed().as_secs_f64();
    let (csv, svg) = solution_files(&solution);
    output::write_csv(&csv_path, &csv)?;
    output::write_svg(&svg_path, &svg)?;
    let summary = solve_summary(&solution)?.field("solve_s", &wall)?;
    if a.json {
        summary
            .field("csv", &csv_path)?
            .field("picture", &svg_path)?
            .print()?;
    } else {
        print_solve_report(&summary)?;
        outln!("wrote {} and {}", csv_path.display(), svg_path.display());
    }
    match unverified(&solution) {
        None => Ok(()),
        Some(why) => anyhow::bail!(
            "{src}: UNVERIFIED: {why}; the files were written for inspection (see \"checks\" in --json)"
        ),
    }
}

/// shape.csv and shape.svg of a solution.
fn solution_files(solution: &StaticSolution) -> (String, String) {
    match solution {
        StaticSolution::Wire { shape, radius_m } => {
            let failures = shape.checks.failures();
            let note = (!failures.is_empty()).then(|| "UNVERIFIED".to_string());
            let panels = three_views("wire", &shape.x_m, *radius_m, note);
            let mut svg = plot::panel_grid(&panels, 3, 320.0, (0.1, "0.1 m"), false);
            unverified_note(&mut svg, &failures);
            (wire_csv(&[("wire", None, shape)]), svg.finish())
        }
        StaticSolution::Belt { shape, .. } => {
            let mut svg = belt_views(shape);
            unverified_note(&mut svg, &shape.checks.failures());
            (belt_csv(shape), svg.finish())
        }
        StaticSolution::Sequence { steps, radius_m } => {
            let rows: Vec<(&str, Option<f64>, &WireShape)> = steps
                .iter()
                .flat_map(|st| {
                    [
                        ("knot_free", Some(st.l_fraction), &st.free),
                        ("one_knot", Some(st.l_fraction), &st.knot),
                    ]
                })
                .collect();
            (wire_csv(&rows), sequence_views(steps, *radius_m).finish())
        }
    }
}

/// Bottom right of a row of three 320-px panels, beside the scale bar, in
/// red: why the answer is unverified (nothing when `failures` is empty).
fn unverified_note(svg: &mut plot::Svg, failures: &[&str]) {
    unverified_note_at(
        svg,
        failures,
        3.0 * 320.0 - 10.0,
        320.0 + 22.0 + 18.0 + 24.0 - 8.0,
    );
}

/// The red UNVERIFIED line, ending at `x` on the baseline `y` (px).
fn unverified_note_at(svg: &mut plot::Svg, failures: &[&str], x: f64, y: f64) {
    if failures.is_empty() {
        return;
    }
    svg.text_styled(
        x,
        y,
        14.0,
        plot::Anchor::End,
        r##"fill="#d62728" font-weight="bold""##,
        &format!("UNVERIFIED: fails {}", failures.join(", ")),
    );
}

/// The text report of a solve: the sequence as a table, any other model
/// as its summary's fields.
fn print_solve_report(summary: &JsonObject) -> Result<()> {
    // Every field was checked finite as it was added.
    let summary = serde_json::to_value(summary)?;
    match summary["model"].as_str() {
        Some("sequence") => {
            outln!("end distance   knot-free (J)   one-knot (J)   lower       status");
            for st in summary["steps"].as_array().into_iter().flatten() {
                outln!(
                    "{:>10.2} L   {:>12.4e}   {:>12.4e}   {:<10}  {}",
                    st["l_fraction"].as_f64().unwrap_or(f64::NAN),
                    st["knot_free_j"].as_f64().unwrap_or(f64::NAN),
                    st["one_knot_j"].as_f64().unwrap_or(f64::NAN),
                    st["lower"].as_str().unwrap_or("?"),
                    st["status"].as_str().unwrap_or("?")
                );
            }
        }
        _ => {
            if summary["status"].as_str() == Some("UNVERIFIED") {
                outln!(
                    "UNVERIFIED: the answer fails {} (it is not converged)",
                    summary["failed_checks"]
                );
            }
            for (k, v) in summary.as_object().into_iter().flatten() {
                outln!("{k:>26}: {v}");
            }
        }
    }
    Ok(())
}

fn wire_csv(rows: &[(&str, Option<f64>, &WireShape)]) -> String {
    let mut s = String::from("shape,l_fraction,s_m,x_m,y_m,z_m,phi_rad,theta_rad,psi_rad,strain\n");
    for (name, l, sh) in rows {
        for k in 0..sh.s_m.len() {
            let (x, e) = (sh.x_m[k], sh.euler_rad[k]);
            let _ = writeln!(
                s,
                "{name},{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.3e}",
                l.map(|v| v.to_string()).unwrap_or_default(),
                sh.s_m[k],
                x.x,
                x.y,
                x.z,
                e[0],
                e[1],
                e[2],
                sh.strain[k]
            );
        }
    }
    s
}

fn belt_csv(b: &BeltShape) -> String {
    let mut s = String::from(
        "u_m,spine_x_m,spine_y_m,spine_z_m,edge1_x_m,edge1_y_m,edge1_z_m,edge2_x_m,edge2_y_m,edge2_z_m,beta\n",
    );
    for k in 0..b.u_m.len() {
        let (p, e1, e2) = (b.spine_m[k], b.edges_m[0][k], b.edges_m[1][k]);
        let _ = writeln!(
            s,
            "{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
            b.u_m[k], p.x, p.y, p.z, e1.x, e1.y, e1.z, e2.x, e2.y, e2.z, b.beta[k]
        );
    }
    s
}

/// A named view: title, axis names, projection with depth.
type View3 = (
    &'static str,
    (&'static str, &'static str),
    fn(&V3) -> (f64, f64, f64),
);
/// A named view: title, axis names, projection.
type View2 = (
    &'static str,
    (&'static str, &'static str),
    fn(&V3) -> (f64, f64),
);

/// Top (x–y), front (x–z) and side (y–z) views of a curve drawn at its
/// thickness, upper strands over lower ones.
fn three_views(title: &str, x: &[V3], radius_m: f64, note: Option<String>) -> Vec<ViewPanel> {
    let views: [View3; 3] = [
        ("top", ("x (m)", "y (m)"), |p| (p.x, p.y, p.z)),
        ("front", ("x (m)", "z (m)"), |p| (p.x, p.z, -p.y)),
        ("side", ("y (m)", "z (m)"), |p| (p.y, p.z, p.x)),
    ];
    views
        .iter()
        .map(|(name, axes, proj)| ViewPanel {
            title: match &note {
                Some(n) => format!("{title} · {name} · {n}"),
                None => format!("{title} · {name}"),
            },
            axes: (axes.0.into(), axes.1.into()),
            strokes: rope_strokes(x, radius_m.max(1e-3), proj),
            markers: vec![{
                let q = proj(&x[0]);
                ((q.0, q.1), "#333".into(), "s = 0".into())
            }],
        })
        .collect()
}

fn belt_views(b: &BeltShape) -> plot::Svg {
    let views: [View2; 3] = [
        ("(a) top", ("y", "x"), |p| (p.y, p.x)),
        ("(b) front", ("y", "z"), |p| (p.y, p.z)),
        ("(c) side", ("z", "x"), |p| (p.z, p.x)),
    ];
    let top = b.highest_m;
    let mark = if b.verified() { "" } else { " · UNVERIFIED" };
    let panels: Vec<ViewPanel> = views
        .iter()
        .map(|(name, axes, proj)| {
            let mut strokes = Vec::new();
            // Rib lines every few points, then the edges and the spine.
            for k in (0..b.u_m.len()).step_by(4) {
                strokes.push(PanelStroke {
                    points: vec![proj(&b.edges_m[0][k]), proj(&b.edges_m[1][k])],
                    colour: "#9ecae1".into(),
                    width: 1.0,
                    width_in_px: true,
                    halo: false,
                });
            }
            for (edge, colour) in [
                (&b.edges_m[0], "#3182bd"),
                (&b.edges_m[1], "#3182bd"),
                (&b.spine_m, "#d62728"),
            ] {
                strokes.push(PanelStroke {
                    points: edge.iter().map(proj).collect(),
                    colour: colour.into(),
                    width: 2.0,
                    width_in_px: true,
                    halo: false,
                });
            }
            ViewPanel {
                title: if name.starts_with("(a)") {
                    format!("belt {name} · orange: paper's top{mark}")
                } else {
                    format!("belt {name}{mark}")
                },
                axes: (format!("{} (m)", axes.0), format!("{} (m)", axes.1)),
                strokes,
                markers: vec![
                    (
                        proj(&top),
                        "#2ca02c".into(),
                        format!("highest [{:.3}, {:.3}, {:.3}]", top.x, top.y, top.z),
                    ),
                    // The paper's highest point (L1058), in units of L_u.
                    (
                        proj(&(V3::new(0.3, 0.4, -0.01) * b.u_m.last().copied().unwrap_or(1.0))),
                        "#ff7f0e".into(),
                        String::new(),
                    ),
                ],
            }
        })
        .collect();
    plot::panel_grid(&panels, 3, 320.0, (0.1, "0.1 m"), false)
}

fn sequence_views(steps: &[SequenceStep], radius_m: f64) -> plot::Svg {
    // Each end distance: the knot-free and the one-knot shape seen along y
    // (the x–z plane of the paper's Fig. 2) and along x.
    let mut panels = Vec::new();
    for st in steps {
        for (name, sh) in [("knot-free", &st.free), ("one-knot", &st.knot)] {
            let lower = if (name == "one-knot") == st.knot_is_lower() {
                " ✓"
            } else {
                ""
            };
            for (view, axes, proj) in [
                (
                    "∥y",
                    ("x (m)", "z (m)"),
                    (|p: &V3| (p.x, p.z, -p.y)) as fn(&V3) -> (f64, f64, f64),
                ),
                ("∥x", ("y (m)", "z (m)"), |p: &V3| (p.y, p.z, p.x)),
            ] {
                let mark = if sh.verified() { "" } else { " UNVERIFIED" };
                panels.push(ViewPanel {
                    title: format!(
                        "{:.2}L {name} {view} {:.2e} J{lower}{mark}",
                        st.l_fraction, sh.energy_j
                    ),
                    axes: (axes.0.into(), axes.1.into()),
                    strokes: rope_strokes(&sh.x_m, radius_m.max(2e-3), proj),
                    markers: Vec::new(),
                });
            }
        }
    }
    plot::panel_grid(&panels, 4, 280.0, (0.1, "0.1 m"), false)
}
