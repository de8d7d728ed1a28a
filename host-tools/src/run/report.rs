//! What a run prints and writes: the output flags, the summary table and
//! the SVG plot (the CSV time series streams through `crate::run::trace`).
use std::fmt::Write as _;

use crate::run::sim::{Row, Summary};

/// The output flags shared by `sim` and `hil`.
#[derive(clap::Args, Debug, Clone, Default)]
pub struct OutputArgs {
    /// Write the time series as CSV.
    #[arg(long)]
    pub csv: Option<std::path::PathBuf>,
    /// Write a plot of angles and voltages against time (SVG).
    #[arg(long)]
    pub plot: Option<std::path::PathBuf>,
    /// Print a machine-readable summary instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl OutputArgs {
    /// Opens the trace files asked for (the CSV with its header, the
    /// plot's temporary file) before the run, so an unwritable path is
    /// refused before any work.
    pub fn open_trace(&self, angles: &[String]) -> anyhow::Result<crate::run::trace::TraceFiles> {
        crate::run::trace::TraceFiles::open(self.csv.as_deref(), self.plot.as_deref(), angles)
    }

    /// Writes what the trace files still wait for (the CSV's last rows,
    /// the plot) after the run — early end or not — and records the CSV in
    /// the summary.
    pub fn finish_trace(
        &self,
        files: crate::run::trace::TraceFiles,
        title: &str,
        summary: &mut Summary,
    ) -> anyhow::Result<()> {
        let title = match &summary.cut_short {
            Some(c) => format!("{title} — cut short at t = {:.3} s", c.at_t_s),
            None => title.to_string(),
        };
        summary.trace = files.finish(&title, &summary.angles, summary.planned_steps)?;
        Ok(())
    }

    /// The progress bar of a run of `steps` control periods: drawn on
    /// stderr when it is a terminal and the output is not `--json`.
    pub fn progress(&self, what: &str) -> indicatif::ProgressBar {
        crate::progress::bar(what, self.json)
    }
}
use crate::plot::{line_charts, Chart, Series};

/// The human-readable summary.
pub fn table(s: &Summary) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "scenario   {}", s.scenario);
    let _ = writeln!(out, "estimator  {}", s.estimator);
    let _ = writeln!(out);
    let mut head = format!("{:>8} {:>8}", "from s", "to s");
    for a in &s.angles {
        let _ = write!(
            head,
            " {:>10} {:>10} {:>11}",
            format!("{a} target"),
            "ss err",
            "overshoot"
        );
    }
    let _ = writeln!(out, "{head}");
    for g in &s.segments {
        let mut line = format!("{:>8.1} {:>8.1}", g.from_s, g.to_s);
        for p in 0..s.angles.len() {
            let _ = write!(
                line,
                " {:>9.2}° {:>9.3}° {:>10.3}°",
                g.desired_deg[p], g.steady_state_error_deg[p], g.overshoot_deg[p]
            );
        }
        if !g.complete {
            line.push_str("  (run cut short in this segment: error at its last row)");
        }
        let _ = writeln!(out, "{line}");
    }
    let _ = writeln!(out);
    let any_complete = s.segments.iter().any(|g| g.complete);
    for (p, a) in s.angles.iter().enumerate() {
        let sse = if any_complete {
            format!("{:.3}°", s.steady_state_error_deg[p])
        } else {
            "— (no target segment completed)".to_string()
        };
        let _ = writeln!(
            out,
            "{a:<6} worst steady-state error {sse}, max estimation error {:.3}°",
            s.max_estimation_error_deg[p]
        );
    }
    let temps: Vec<String> = s
        .peak_coil_temperature_c
        .iter()
        .map(|t| format!("{t:.0}"))
        .collect();
    let temps = if temps.is_empty() {
        "none (no step ran)".to_string()
    } else {
        temps.join(", ")
    };
    let _ = writeln!(out, "peak coil temperatures (°C): {temps}");
    let faults = if s.faults_seen.is_empty() {
        "none".to_string()
    } else {
        s.faults_seen.join(", ")
    };
    let _ = writeln!(out, "faults seen: {faults}");
    let _ = writeln!(
        out,
        "{:.1} s simulated in {:.3} s wall ({} steps): {:.0}× real time",
        s.sim_seconds, s.wall_seconds, s.steps, s.realtime_factor
    );
    if let Some(t) = &s.trace {
        let _ = writeln!(
            out,
            "trace: {} rows in {}{}",
            t.rows,
            t.csv.display(),
            if t.complete {
                ""
            } else {
                " (not the whole run)"
            }
        );
    }
    if let Some(cut) = &s.cut_short {
        let _ = writeln!(
            out,
            "CUT SHORT after {} of {} steps (t = {:.3} s): {}",
            s.steps, s.planned_steps, cut.at_t_s, cut.reason
        );
    }
    out
}

/// An SVG of angles (true, estimated, desired) and coil voltages against
/// time, from `rows` (a decimated copy of the run: `trace::Decimated`).
pub fn plot_svg(title: &str, angles: &[String], rows: &[Row]) -> String {
    let t: Vec<f64> = rows.iter().map(|r| r.t_s).collect();
    let colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
    let column = |f: &dyn Fn(&crate::run::sim::Row) -> f64| rows.iter().map(f).collect::<Vec<_>>();
    let mut angle_series = Vec::new();
    for (p, a) in angles.iter().enumerate() {
        let c = colours[p % colours.len()];
        angle_series.push(Series::over(
            format!("{a} true"),
            c,
            false,
            &t,
            &column(&|r| r.true_deg[p]),
        ));
        angle_series.push(Series::over(
            format!("{a} estimate"),
            c,
            true,
            &t,
            &column(&|r| r.estimate_deg[p]),
        ));
        angle_series.push(Series::over(
            format!("{a} desired"),
            "#555555",
            true,
            &t,
            &column(&|r| r.desired_deg[p]),
        ));
    }
    let coils = 2 * angles.len();
    let volt_series = (0..coils)
        .map(|c| {
            Series::over(
                format!("v{}", c + 1),
                colours[c % colours.len()],
                false,
                &t,
                &column(&|r| r.coil_volts[c]),
            )
        })
        .collect();
    let charts = [
        Chart {
            title: format!("{title} — angles"),
            x_label: "time (s)".into(),
            y_label: "angle (deg)".into(),
            series: angle_series,
        },
        Chart {
            title: "driver input voltages".into(),
            x_label: "time (s)".into(),
            y_label: "voltage (V)".into(),
            series: volt_series,
        },
    ];
    line_charts(&charts).finish()
}
