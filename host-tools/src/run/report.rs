//! What a run prints: the output flags shared by `sim` and `hil` and the
//! summary table (the CSV time series and the SVG plot are written by
//! `crate::run::trace` as the run goes).
use std::fmt::Write as _;

use crate::run::summary::Summary;

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
    pub fn open_trace(&self, angles: &[&str]) -> anyhow::Result<crate::run::trace::TraceFiles> {
        let angles: Vec<String> = angles.iter().map(|a| a.to_string()).collect();
        crate::run::trace::TraceFiles::open(self.csv.as_deref(), self.plot.as_deref(), &angles)
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
