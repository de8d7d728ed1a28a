//! `softjoint dlo`: deformable linear objects (seed 000).
//!
//! * `rope` — the dynamic rope of Shi & Payandeh driven by a TOML scenario
//!   (scripted hands, pins, desk, topology checks); writes the node
//!   positions over time as CSV and a frame strip (top and side views);
//! * `solve` — the static wire or belt of Wakamatsu et al. from a TOML
//!   problem; writes the solved shape as CSV and its three views.
//!
//! Both print a short report, or with `--json` a machine-readable summary.
use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use host_tools::plot::{self, Panel, PanelStroke};
use plant_models::dlo::rope::script::{Frame, RopeScenario, RunResult};
use plant_models::dlo::rope::V3;
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
    #[arg(long, default_value_t = 12)]
    strip: usize,
    /// Print the built-in scenario as TOML and exit.
    #[arg(long)]
    print_default: bool,
    /// Print a machine-readable summary.
    #[arg(long)]
    json: bool,
}

/// The built-in rope scenario (also `scenarios/dlo/overhand.toml`).
pub const OVERHAND_TOML: &str = include_str!("../../scenarios/dlo/overhand.toml");

pub fn run(args: DloArgs) -> Result<()> {
    match args.command {
        DloCommand::Rope(a) => rope_cmd(a),
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
        print!("{OVERHAND_TOML}");
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
    let mut csv = std::io::BufWriter::new(
        fs::File::create(&csv_path).with_context(|| format!("creating {}", csv_path.display()))?,
    );
    writeln!(csv, "time_s,node,x_m,y_m,z_m")?;
    let mut write_err = None;
    let result = scenario
        .run(|f| {
            if write_err.is_some() {
                return;
            }
            let mut s = String::new();
            for (i, p) in f.x.iter().enumerate() {
                let _ = writeln!(s, "{:.4},{i},{:.6},{:.6},{:.6}", f.time_s, p.x, p.y, p.z);
            }
            if let Err(e) = csv.write_all(s.as_bytes()) {
                write_err = Some(e);
            }
        })
        .map_err(|e| anyhow::anyhow!("{source}: {e}"))?;
    if let Some(e) = write_err {
        return Err(e).with_context(|| format!("writing {}", csv_path.display()));
    }
    csv.flush()?;
    let svg_path = a.out.join("rope_frames.svg");
    fs::write(&svg_path, rope_strip(&scenario, &result, a.strip).finish())
        .with_context(|| format!("writing {}", svg_path.display()))?;
    let step_us = 1e6 * result.wall_s / result.steps.max(1) as f64;
    if a.json {
        let summary = serde_json::json!({
            "scenario": scenario.name,
            "nodes": scenario.rope.nodes,
            "model": scenario.rope.model.number(),
            "duration_s": scenario.duration_s,
            "steps": result.steps,
            "step_time_us": step_us,
            "max_penetration_m": result.max_penetration_m,
            "max_penetration_time_s": result.max_penetration_time_s,
            "penetration_tolerance_m": penetration_tolerance_m(&scenario),
            "contact_steps": result.contact_steps,
            "clamped_segments": result.clamped_segments,
            "max_internal_force_sum_n": result.max_internal_force_sum_n,
            "checks": result.checks,
            "hands": result.hands,
            "csv": csv_path,
            "picture": svg_path,
        });
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "{}: {} nodes, model {}, {} s in {} steps ({:.1} µs/step)",
            scenario.name,
            scenario.rope.nodes,
            scenario.rope.model.number(),
            scenario.duration_s,
            result.steps,
            step_us
        );
        println!(
            "deepest segment overlap {:.4} m at {:.2} s (tolerance {:.4} m), {} steps with self-contact",
            result.max_penetration_m,
            result.max_penetration_time_s,
            penetration_tolerance_m(&scenario),
            result.contact_steps
        );
        for c in &result.checks {
            println!(
                "check {:>10} at {:6.2} s: {} crossings seen from above, knot determinant {}",
                c.label,
                c.time_s,
                c.crossings,
                c.determinant
                    .map(|d| d.to_string())
                    .unwrap_or_else(|| "undetermined".into())
            );
        }
        for h in &result.hands {
            println!(
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
        println!("wrote {} and {}", csv_path.display(), svg_path.display());
    }
    Ok(())
}

/// The stated bound on segment overlap: 0.3 r (centre lines never closer
/// than 1.7 r; passing through would need 2r).
pub fn penetration_tolerance_m(s: &RopeScenario) -> f64 {
    0.3 * s.rope.radius_m
}

/// Strokes of a rope seen along one axis pair: one stroke per segment, in
/// order of depth so that the upper strand is drawn last, coloured from
/// blue (node 0) to red (last node).
fn rope_strokes(
    x: &[V3],
    radius_m: f64,
    project: impl Fn(&V3) -> (f64, f64, f64),
) -> Vec<PanelStroke> {
    let n = x.len();
    let mut segs: Vec<(f64, PanelStroke)> = (0..n.saturating_sub(1))
        .map(|i| {
            let (a, b) = (project(&x[i]), project(&x[i + 1]));
            let (r, g, bl) = plot::false_colour(i as f64 / (n - 2).max(1) as f64);
            (
                0.5 * (a.2 + b.2),
                PanelStroke {
                    points: vec![(a.0, a.1), (b.0, b.1)],
                    colour: format!("rgb({r},{g},{bl})"),
                    width: 2.0 * radius_m,
                    width_in_px: false,
                    halo: true,
                },
            )
        })
        .collect();
    segs.sort_by(|a, b| a.0.total_cmp(&b.0));
    segs.into_iter().map(|s| s.1).collect()
}

fn rope_panel(s: &RopeScenario, f: &Frame, title: String, top: bool) -> Panel {
    let project = |p: &V3| {
        if top {
            (p.x, p.y, p.z)
        } else {
            (p.x, p.z, -p.y)
        }
    };
    let mut panel = Panel {
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
fn rope_strip(s: &RopeScenario, r: &RunResult, count: usize) -> plot::Svg {
    let frames = &r.frames;
    let mut picks: Vec<usize> = (0..count)
        .map(|k| (k * (frames.len() - 1)) / (count - 1).max(1))
        .collect();
    for c in &r.checks {
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
            .checks
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
    let mut panels = Vec::new();
    for chunk in picks.chunks(columns) {
        for &i in chunk {
            panels.push(rope_panel(
                s,
                &frames[i],
                format!("top · {}", label(&frames[i])),
                true,
            ));
        }
        for _ in chunk.len()..columns {
            panels.push(Panel::default());
        }
        for &i in chunk {
            panels.push(rope_panel(s, &frames[i], "side".into(), false));
        }
        for _ in chunk.len()..columns {
            panels.push(Panel::default());
        }
    }
    plot::panel_grid(&panels, columns, 300.0, (1.0, "1 m"), true)
}
