//! What a run prints and writes: the summary table, the CSV time series and
//! the SVG plot.
use std::fmt::Write as _;
use std::path::Path;

use crate::sim::{Summary, Trace};

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
    /// Whether a file that needs the time series (CSV, plot) is asked for.
    pub fn wants_trace(&self) -> bool {
        self.csv.is_some() || self.plot.is_some()
    }

    /// Writes the CSV and the plot if asked for.
    pub fn write_files(&self, title: &str, summary: &Summary, trace: &Trace) -> anyhow::Result<()> {
        if let Some(p) = &self.csv {
            write_csv(p, &summary.angles, trace)?;
        }
        if let Some(p) = &self.plot {
            write_plot(p, title, &summary.angles, trace)?;
        }
        Ok(())
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
        let _ = writeln!(out, "{line}");
    }
    let _ = writeln!(out);
    for (p, a) in s.angles.iter().enumerate() {
        let _ = writeln!(
            out,
            "{a:<6} worst steady-state error {:.3}°, max estimation error {:.3}°",
            s.steady_state_error_deg[p], s.max_estimation_error_deg[p]
        );
    }
    let temps: Vec<String> = s
        .peak_coil_temperature_c
        .iter()
        .map(|t| format!("{t:.0}"))
        .collect();
    let _ = writeln!(out, "peak coil temperatures (°C): {}", temps.join(", "));
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
    out
}

/// Writes the time series as CSV.
pub fn write_csv(path: &Path, angles: &[String], trace: &Trace) -> anyhow::Result<()> {
    let mut s = String::from("t_s");
    for a in angles {
        let _ = write!(s, ",{a}_true_deg,{a}_estimate_deg,{a}_desired_deg");
    }
    let coils = 2 * trace.planes;
    for c in 1..=coils {
        let _ = write!(s, ",v{c}_V");
    }
    s.push_str(",faults\n");
    for r in &trace.rows {
        let _ = write!(s, "{:.4}", r.t_s);
        for p in 0..angles.len() {
            let _ = write!(
                s,
                ",{:.4},{},{:.4}",
                r.true_deg[p],
                crate::output::estimate_field(r.estimate_deg[p], 4),
                r.desired_deg[p]
            );
        }
        for v in r.coil_volts.iter().take(coils) {
            let _ = write!(s, ",{v:.3}");
        }
        let _ = writeln!(s, ",{}", r.faults);
    }
    crate::output::write_csv(path, &s)
}

/// Writes an SVG of angles (true, estimated, desired) and coil voltages
/// against time.
pub fn write_plot(
    path: &Path,
    title: &str,
    angles: &[String],
    trace: &Trace,
) -> anyhow::Result<()> {
    // Thin the series to ≤ 4000 points per line; plots need no more.
    let stride = (trace.rows.len() / 4000).max(1);
    let rows: Vec<_> = trace.rows.iter().step_by(stride).collect();
    let t: Vec<f64> = rows.iter().map(|r| r.t_s).collect();
    let colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
    let column =
        |f: &dyn Fn(&crate::sim::Row) -> f64| rows.iter().map(|r| f(r)).collect::<Vec<_>>();
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
    let coils = 2 * trace.planes;
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
    crate::output::write_svg(path, &line_charts(&charts).finish())
}
