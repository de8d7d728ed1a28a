//! `softjoint identify joint|plan|probe`: the joint's plant fitted to a
//! user's recording, and the plans to record one (placed from a probe's
//! log where the joint's drivers turn on away from the default).
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::atomic::AtomicUsize;

use anyhow::{bail, Context};
use clap::{Args, Subcommand, ValueEnum};
use host_tools::files::plant::{PlantFile, PlantParams};
use host_tools::joint::excite;
use host_tools::joint::identify_run::{self, Identified, RunError, BOARD_ESTIMATE_NOTE};
use host_tools::output;
use host_tools::plot::{line_charts, Chart, Series};
use host_tools::stop::{Stop, Stopped};
use plant_joint::identify::{
    self, ExcitationPlan, IdentifyOptions, LmOptions, PlaneReport, StopFlag, NEVER_FITTED,
};

#[derive(Subcommand)]
pub enum IdentifyCommand {
    /// Fit the joint's plant to an excitation log (`sim --excite`, `hil
    /// --excite`): thermal, driver, transformation temperatures and their
    /// stress slope, sponge, link inertia, wire jamming; with uncertainties,
    /// the parameters the log does not determine, and a held-out check.
    ///
    /// Ctrl-C, SIGTERM or SIGHUP stops the fit within one replay of the
    /// log and writes nothing (no plant file, no plot: a fit cut short is
    /// no plant); exit 130, 143 or 129.
    Joint(JointArgs),
    /// Print an excitation plan (TOML) to start from: the standard plan
    /// (steps, pulses, ramps, co-contraction, optional holds), within the
    /// firmware's thermal budget; with --probe, its levels placed from
    /// where each coil's driver was found to turn on.
    Plan(PlanArgs),
    /// Print the probe plan (TOML): each coil alone up a staircase of 13
    /// inputs from 1.4 to 2.6 V (1.5 s on, 3 s off), then a 3 V pulse,
    /// within the firmware's thermal budget (194 s). Record it like any
    /// plan (`sim --excite`, `hil --excite`, `console excite`), then
    /// `identify plan --probe LOG` places the plan's levels from it.
    Probe(ProbeArgs),
}

#[derive(Args)]
pub struct ProbeArgs {
    /// Which joint.
    #[arg(long, value_enum, default_value = "3d")]
    joint: JointArg,
}

#[derive(Clone, Copy, ValueEnum)]
pub enum JointArg {
    #[value(name = "2d")]
    TwoD,
    #[value(name = "3d")]
    ThreeD,
}

#[derive(Args)]
pub struct PlanArgs {
    /// Which joint [default: 3d; with --probe, the probe log's].
    #[arg(long, value_enum)]
    joint: Option<JointArg>,
    /// Length (s).
    #[arg(long, allow_negative_numbers = true, default_value_t = 600.0)]
    duration_s: f64,
    /// Add holds at ±8° under the controller.
    #[arg(long, conflicts_with = "probe")]
    holds: bool,
    /// A recorded probe log (`identify probe`, with the coil currents):
    /// each coil's sustained levels, ramp and warm antagonist are moved by
    /// its driver's turn-on, found from the currents, instead of being
    /// placed from the default 1.7 V. The plan's
    /// TOML then starts with what the probe found, and a coil whose
    /// levels the thermal budget only allows in pulses is named (its
    /// pulses carry the held level's mean power).
    #[arg(long, value_name = "LOG")]
    probe: Option<PathBuf>,
    /// With --probe: print the probe's findings, the pulsed coils, the
    /// notes and the plan as one JSON object instead of the TOML.
    #[arg(long, requires = "probe")]
    json: bool,
}

/// Where the angles that the mechanics stage fits come from.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AngleSource {
    /// The log's camera columns (`sim`, `hil`, a lab's camera).
    Camera,
    /// The board's own wire-based estimates (columns `est_alpha_deg`,
    /// `est_beta_deg` of a `console excite` log), one every 3rd row.
    #[value(name = "board-estimate")]
    BoardEstimate,
}

#[derive(Args)]
pub struct JointArgs {
    /// The log (CSV).
    log: PathBuf,
    /// A plant file to start from (and to keep the parameters not fitted
    /// from) instead of the defaults.
    #[arg(long)]
    prior: Option<PathBuf>,
    /// Write the identified plant file here.
    #[arg(short, long, default_value = "plant.toml")]
    output: PathBuf,
    /// Share of the log (from its start) to fit; the rest is held out.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0.75)]
    fit_fraction: f64,
    /// Minimiser iterations per stage at most.
    #[arg(long, allow_negative_numbers = true, default_value_t = 100, value_parser = clap::value_parser!(u32).range(1..=1000))]
    max_iterations: u32,
    /// Write recorded vs predicted angles (SVG).
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Print a machine-readable report instead of the table.
    #[arg(long)]
    json: bool,
    /// The angles the mechanics stage fits: the camera's, or, for a log
    /// recorded on a board without a camera (`console excite`), the
    /// board's own estimates from its wires — which carry the estimation
    /// law's error and the wires' jamming into the mechanics, and leave the
    /// jamming stage fitting the wires against an angle read off the wires.
    #[arg(long, value_enum, default_value = "camera")]
    angles: AngleSource,
    /// Exit 0 even when a plane fails its checks against the data (the
    /// result is still marked UNVERIFIED in the table, `--json` and the
    /// plant file); without it such a result exits 1.
    #[arg(long)]
    allow_unverified: bool,
    /// Run the mechanics stage's fits from its starting points on the Ray
    /// cluster at ADDRESS (`ray start --head` prints it), each start a
    /// task, through the Python package's driver (`python3 -m
    /// softjoint.ray_sweep identify-serve`; $SOFTJOINT_PYTHON names another
    /// Python). The selection and everything else run here; the plant
    /// file and report are the same as without it.
    #[arg(long, value_name = "ADDRESS")]
    ray: Option<String>,
    /// Take the mechanics stage's Jacobians by forward differences (one
    /// replay per fitted parameter, four secant updates between them), as
    /// before session 53, instead of from one replay carrying the
    /// derivatives with respect to every fitted parameter (the default:
    /// about a third less CPU on the twins, the same verdicts; the fits
    /// take other paths, so the estimates differ, by a median of 0.01–0.02
    /// of their 1σ on the twins).
    #[arg(long, conflicts_with = "derivative_jacobians")]
    differenced_jacobians: bool,
    /// The default since session 53 (kept so that session 52's commands
    /// still run).
    #[arg(long, hide = true)]
    derivative_jacobians: bool,
}

pub fn run(cmd: IdentifyCommand) -> anyhow::Result<()> {
    match cmd {
        IdentifyCommand::Plan(a) => {
            if !(a.duration_s.is_finite() && a.duration_s > 0.0 && a.duration_s <= 7200.0) {
                bail!(
                    "--duration-s must be in (0, 7200] s, got {}",
                    plant_common::short_number(a.duration_s)
                );
            }
            if let Some(log) = &a.probe {
                return adapted_plan(log, a.joint, a.duration_s, a.json);
            }
            let planes = a.joint.map_or(2, planes_of);
            let plan = ExcitationPlan::standard(planes, a.duration_s, a.holds);
            excite::check_budget(&plan)?;
            output::print_toml("", &plan)?;
            Ok(())
        }
        IdentifyCommand::Probe(a) => {
            let plan = ExcitationPlan::probe(planes_of(a.joint));
            let peak = excite::check_budget(&plan)?;
            let header = format!(
                "# The probe ({} s): record it (`softjoint sim --excite`, `hil --excite`, `console excite`),\n# then `softjoint identify plan --probe LOG` places the plan's levels from it.\n# Peak rise of the firmware's default thermal budget over it: {peak:.0} K (trip 95 K).\n",
                plant_common::short_number(plan.duration_s)
            );
            output::print_toml(&header, &plan)?;
            Ok(())
        }
        IdentifyCommand::Joint(a) => joint(a),
    }
}

fn planes_of(j: JointArg) -> usize {
    match j {
        JointArg::TwoD => 1,
        JointArg::ThreeD => 2,
    }
}

/// Plane names of a joint with `planes` angles.
fn plane_name(planes: usize, plane: usize) -> &'static str {
    match (planes, plane) {
        (1, _) => "θ",
        (_, 0) => "α",
        _ => "β",
    }
}

/// What `identify plan --probe --json` prints.
#[derive(serde::Serialize)]
struct AdaptedPlanReport<'a> {
    probe_log: String,
    probe: &'a identify::probe::ProbeReport,
    /// Coils whose unsaturated levels the budget allows only in pulses.
    pulsed_coils: Vec<usize>,
    /// What the plan does differently for them, a line each.
    notes: Vec<String>,
    budget_peak_rise_k: f64,
    plan: &'a ExcitationPlan,
}

/// `identify plan --probe LOG`: the probe log analysed, the standard
/// plan's levels moved by each coil's turn-on, checked against the
/// firmware's default budget; the TOML's header (or the JSON) says what
/// the probe found and which coils are only pulsed.
fn adapted_plan(
    log_path: &std::path::Path,
    joint: Option<JointArg>,
    duration_s: f64,
    json: bool,
) -> anyhow::Result<()> {
    use identify::probe::{self, BUDGET_SUSTAINED_ABOVE_OFFSET_V, FIRMWARE_DEFAULT_OFFSET_V};
    let log = excite::read_log(log_path)?;
    if let Some(j) = joint {
        if planes_of(j) != log.planes {
            bail!(
                "--joint {} but the probe log {} is of the {} joint ({} angle column(s))",
                if planes_of(j) == 1 { "2d" } else { "3d" },
                log_path.display(),
                if log.planes == 1 { "2D" } else { "3D" },
                log.planes
            );
        }
    }
    let found = probe::analyse(&log).map_err(|e| {
        anyhow::anyhow!(
            "the probe log {} cannot place the plan: {e}",
            log_path.display()
        )
    })?;
    // Without currents the anchor would be where motion starts, which
    // this staircase does not measure reliably (heat builds up over it:
    // 2.6–3 V on a twin whose drivers turn on at 2.0 and 1.6 V).
    if let Some(c) = found.coils.iter().find(|c| c.turn_on_v.is_none()) {
        bail!(
            "the probe log {} has no current column `i{}_a`: the probe finds a coil's turn-on from its currents, and where the plane starts to move in the staircase is no substitute (heat builds up from step to step); record the probe with the coil currents, or use the standard plan (`identify plan` without --probe)",
            log_path.display(),
            c.coil
        );
    }
    let plan = ExcitationPlan::adapted(log.planes, duration_s, &found, false);
    let peak = excite::check_budget(&plan)?;
    let pulsed = ExcitationPlan::pulsed_coils(&found, false);
    let sustained_limit = FIRMWARE_DEFAULT_OFFSET_V + BUDGET_SUSTAINED_ABOVE_OFFSET_V;
    let mut notes = Vec::new();
    let mut header = format!(
        "# Adapted from the probe log {} (levels moved by each coil's turn-on from 1.7 V + 0.1 V; the standard's for turn-ons of 1.63-1.73 V):\n",
        log_path.display()
    );
    for c in &found.coils {
        let how = match (c.turn_on_v, c.current_bracket_v) {
            (Some(v), Some((lo, hi))) => format!(
                "turns on at {v:.3} V (no current at {}, current at {} V)",
                plant_common::short_number(lo),
                plant_common::short_number(hi)
            ),
            (Some(v), None) => format!("turns on at {v:.3} V"),
            _ => "no currents logged".to_string(),
        };
        let _ = writeln!(
            header,
            "#   coil {} (plane {}): {how}; the {} V pulse moved it {:+.2}°",
            c.coil,
            plane_name(log.planes, c.plane),
            plant_common::short_number(c.top_v),
            c.top_travel_deg
        );
        if pulsed.contains(&c.coil) {
            // The highest level below the coil's saturated pulses.
            let peaks = || {
                plan.drive
                    .iter()
                    .filter(|d| d.coil == c.coil)
                    .map(|d| d.peak_v())
            };
            let pulse = peaks().fold(0.0, f64::max);
            let top = peaks().filter(|&v| v < pulse).fold(0.0, f64::max);
            notes.push(format!(
                "coil {} (plane {}) turns on at {:.2} V: its levels lie above the {sustained_limit:.2} V the firmware's default thermal budget allows held, so the plan pulses them (1 s on, 2 s off, up to {top:.2} V: √3 × the held level's distance above the turn-on, the same mean power); `identify joint` says whether the log determines the plane",
                c.coil,
                plane_name(log.planes, c.plane),
                c.anchor_v,
            ));
        }
    }
    for w in &notes {
        let _ = writeln!(header, "# note: {w}");
    }
    let _ = writeln!(
        header,
        "# Peak rise of the firmware's default thermal budget over the plan: {peak:.0} K (trip 95 K)."
    );
    if json {
        return output::print_json(&AdaptedPlanReport {
            probe_log: log_path.display().to_string(),
            probe: &found,
            pulsed_coils: pulsed,
            notes,
            budget_peak_rise_k: peak,
            plan: &plan,
        });
    }
    for w in &notes {
        eprintln!("note: {w}");
    }
    output::print_toml(&header, &plan)
}

fn joint(a: JointArgs) -> anyhow::Result<()> {
    // A signal stops the fit within one replay of the log; nothing is
    // written then (a fit cut short is no plant). Caught from the start,
    // so a signal while the log is read stops the fit as it begins.
    let stop = Stop::on_signals()?;
    if !(a.fit_fraction.is_finite() && (0.2..=1.0).contains(&a.fit_fraction)) {
        bail!(
            "--fit-fraction must be in 0.2..=1, got {}",
            plant_common::short_number(a.fit_fraction)
        );
    }
    // The plant file and the plot can be written: checked before the
    // fit, not after it.
    output::check_file(&a.output)?;
    if let Some(p) = &a.plot {
        output::check_file(p)?;
    }
    let board_estimates = a.angles == AngleSource::BoardEstimate;
    let log_text = std::fs::read_to_string(&a.log)
        .with_context(|| format!("cannot read log {}", a.log.display()))?;
    let log = excite::log_from_text(&log_text, &a.log.display().to_string(), board_estimates)?;
    drop(log_text);
    identify_run::check_angles(&log, &a.log.display().to_string(), board_estimates)?;
    let prior = match &a.prior {
        Some(p) => Some(PlantFile::load(p)?.params()?),
        None => None,
    };
    let flag: &'static AtomicUsize = Box::leak(Box::new(stop.flag()));
    let opts = IdentifyOptions {
        fit_fraction: a.fit_fraction,
        lm: LmOptions {
            max_iterations: a.max_iterations as usize,
            stop: Some(StopFlag(flag)),
            ..IdentifyOptions::default().lm
        },
        // (The two flags conflict: at most one is given.)
        derivative_jacobians: a.derivative_jacobians || !a.differenced_jacobians,
        ..IdentifyOptions::default()
    };
    // Tens of seconds for a 10-minute log: a spinner with the time so far
    // on a terminal (nothing on a pipe or with --json).
    let spinner = host_tools::progress::spinner(
        &format!(
            "identifying the plant from {} ({} rows, {:.0} s of log)",
            a.log.display(),
            log.len(),
            log.len() as f64 * log.period_s
        ),
        a.json,
    );
    let found = fit(&a, &log, prior, &opts, &stop);
    spinner.finish_and_clear();
    let found = found?;
    if let Some(signal) = stop.requested() {
        // Late in the fit: a stage may have been cut short.
        return Err(Stopped {
            signal,
            what: stopped_fit(&a),
        }
        .into());
    }
    let log_name = a.log.display().to_string();
    let unverified = found.unverified();
    found
        .plant_file()
        .save(&a.output, &found.header(&log_name))?;
    if let Some(p) = &a.plot {
        write_plot(p, &found.reports)?;
    }
    if a.json {
        found
            .report(
                &log_name,
                Some(&a.output.display().to_string()),
                board_estimates,
            )?
            .print()?;
    } else {
        if board_estimates {
            host_tools::outln!("{BOARD_ESTIMATE_NOTE}");
        }
        host_tools::out!("{}", table(&found.reports));
        host_tools::outln!("plant file written to {}", a.output.display());
    }
    if !unverified.is_empty() {
        let why = unverified.join("\n  ");
        if a.allow_unverified {
            eprintln!("UNVERIFIED (kept by --allow-unverified):\n  {why}");
        } else {
            bail!("the identified plant is UNVERIFIED (written to {} all the same; --allow-unverified exits 0):\n  {why}", a.output.display());
        }
    }
    Ok(())
}

/// The fit of `log` from `prior` (the defaults without one), its starts
/// on Ray with `--ray`; a fit a signal stopped is the error [`Stopped`].
fn fit(
    a: &JointArgs,
    log: &identify::ExcitationLog,
    prior: Option<PlantParams>,
    opts: &IdentifyOptions,
    stop: &Stop,
) -> anyhow::Result<Identified> {
    let ray = match &a.ray {
        Some(address) => {
            let (mut cmd, who) = host_tools::ray::serve_command("identify-serve", address);
            cmd.arg(&a.log);
            if let Some(p) = &a.prior {
                cmd.arg("--prior").arg(p);
            }
            if a.angles == AngleSource::BoardEstimate {
                cmd.args(["--angles", "board-estimate"]);
            }
            let driver = host_tools::ray::Driver::start(cmd, who, stop.clone(), f64::NAN)?;
            Some(host_tools::ray::RayStartFits::new(driver))
        }
        None => None,
    };
    let elsewhere = ray.as_ref().map(|r| r as &dyn identify::StartFits);
    identify_run::identify(log, prior, opts, elsewhere).map_err(|e| match (e, stop.requested()) {
        (_, Some(signal)) => Stopped {
            signal,
            what: stopped_fit(a),
        }
        .into(),
        (RunError::OtherJoint { log: joint }, None) => anyhow::anyhow!(
            "{}: a {joint} log, but --prior is a plant file for the other joint",
            a.log.display()
        ),
        (RunError::Identify(e), None) => anyhow::anyhow!("{}: {e}", a.log.display()),
    })
}

/// What a fit stopped by a signal says: nothing written, how to fit again.
fn stopped_fit(a: &JointArgs) -> String {
    let plot = a
        .plot
        .as_ref()
        .map(|p| format!(" nor {}", p.display()))
        .unwrap_or_default();
    format!(
        "the fit of {} was cut short, so nothing was written (neither {}{plot}); run it again to fit from the start (a fit keeps no state to resume from)",
        a.log.display(),
        a.output.display()
    )
}

fn table(reports: &[PlaneReport]) -> String {
    let mut s = String::new();
    for r in reports {
        let _ = writeln!(s, "plane {}", r.plane);
        let _ = writeln!(
            s,
            "  {:32} {:>14} {:>12} {:>14}  {:11} unit",
            "parameter", "value", "± 1σ", "prior", "stage"
        );
        let _ = writeln!(
            s,
            "  (1σ: the larger of the white-noise and the segment-robust one, with the wire coder's half count; JSON gives both)"
        );
        for e in &r.estimates {
            let sd = if e.std.is_finite() {
                format!("{:.3e}", e.std)
            } else {
                "∞".into()
            };
            let _ = writeln!(
                s,
                "  {:32} {:>14.6} {:>12} {:>14.6}  {:11} {}{}",
                e.field,
                e.value,
                sd,
                e.prior,
                e.stage,
                e.unit,
                if !e.identifiable {
                    format!(
                        "  NOT IDENTIFIABLE from this log (the fit found {:.4e}): kept at the prior; {}",
                        e.fitted,
                        e.reason.as_deref().unwrap_or("")
                    )
                } else if !e.verified {
                    format!("  UNVERIFIED: {}", e.reason.as_deref().unwrap_or(""))
                } else if e.pull_sigma.abs() > 3.0 {
                    format!("  ({:+.1}σ from the prior)", e.pull_sigma)
                } else {
                    String::new()
                }
            );
        }
        let v = &r.validation;
        let prior = v
            .prior_heldout_rms_deg
            .map(|p| format!("{p:.3}°"))
            .unwrap_or_else(|| "unstable".into());
        let _ = writeln!(
            s,
            "  angle error: fit rms {:.3}°; held-out (from {:.1} s) rms {:.3}°, max {:.3}° (prior plant: rms {prior})",
            v.fit_rms_deg, v.heldout_from_s, v.heldout_rms_deg, v.heldout_max_deg
        );
        let noise = r
            .verdict
            .camera_noise_deg
            .map_or("unknown".into(), |n| format!("{n:.3}°"));
        let _ = writeln!(
            s,
            "  checks: camera noise {noise} (from the frames); fit within {}×, held-out within {}× of it and not above the prior's{}",
            r.verdict.fit_margin,
            r.verdict.heldout_margin,
            r.verdict.driver.as_ref().map_or(String::new(), |d| format!(
                "; driver vs logged currents {:.1} mA rms (noise {:.1} mA)",
                1e3 * d.rms_error_a,
                1e3 * d.noise_a
            ))
        );
        if r.verdict.verified {
            let _ = writeln!(s, "  verdict: verified against the log's own data");
        } else {
            for f in &r.verdict.failures {
                let _ = writeln!(s, "  verdict: UNVERIFIED: {f}");
            }
        }
        for st in &r.stages {
            let _ = writeln!(
                s,
                "  stage {:12} {:>3} iterations{}, {:>4} replays, {:>7} residuals, rms {:.3}{}",
                st.name,
                st.iterations,
                if st.starts > 1 {
                    format!(" from {} starts", st.starts)
                } else {
                    String::new()
                },
                st.evaluations,
                st.residuals,
                st.rms_scaled,
                if st.stopped_by_budget {
                    "  STOPPED BY --max-iterations: not converged, the estimates may be off by more than their 1σ; raise it"
                } else {
                    ""
                }
            );
        }
    }
    let _ = writeln!(
        s,
        "never fitted (kept from the prior): {}",
        NEVER_FITTED.join("; ")
    );
    s
}

fn write_plot(path: &std::path::Path, reports: &[PlaneReport]) -> anyhow::Result<()> {
    let mut charts = Vec::new();
    for r in reports {
        let f = &r.validation.frames;
        let stride = (f.len() / 3000).max(1);
        let pts: Vec<_> = f.iter().step_by(stride).collect();
        let t: Vec<f64> = pts.iter().map(|x| x.t_s).collect();
        let rec: Vec<f64> = pts.iter().map(|x| x.recorded_deg).collect();
        let pred: Vec<f64> = pts.iter().map(|x| x.predicted_deg).collect();
        let err: Vec<f64> = pts
            .iter()
            .map(|x| x.predicted_deg - x.recorded_deg)
            .collect();
        charts.push(Chart {
            title: format!(
                "{}: recorded vs predicted (held out from {:.0} s: rms {:.3}°)",
                r.plane, r.validation.heldout_from_s, r.validation.heldout_rms_deg
            ),
            x_label: "time (s)".into(),
            y_label: "angle (deg)".into(),
            series: vec![
                Series::over("camera".to_string(), "#1f77b4", false, &t, &rec),
                Series::over("identified plant".to_string(), "#d62728", true, &t, &pred),
            ],
        });
        charts.push(Chart {
            title: format!("{}: prediction error", r.plane),
            x_label: "time (s)".into(),
            y_label: "error (deg)".into(),
            series: vec![Series::over(
                "predicted − recorded".to_string(),
                "#2ca02c",
                false,
                &t,
                &err,
            )],
        });
    }
    output::write_svg(path, &line_charts(&charts).finish())
}
