//! Memory stays flat however long a run: a 2-hour simulated run with a CSV
//! trace and a plot peaks far below what keeping its 720,000 rows would
//! take. The test reads its own peak resident set (`VmHWM` in
//! /proc/self/status), so it is alone in this test binary: nothing else
//! runs in the process while it measures.
use host_tools::files::scenario::{JointKind, PlantSpec, Scenario, TargetStep};
use host_tools::run::sim::{self, angle_names};
use host_tools::run::trace::TraceFiles;
use host_tools::stop::Stop;

/// Peak resident set size of this process (MB), from /proc/self/status.
fn peak_rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("/proc/self/status");
    let kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())
        .expect("VmHWM line");
    kb / 1024.0
}

#[test]
#[cfg(target_os = "linux")]
fn a_two_hour_run_with_a_csv_trace_peaks_under_50_mb() {
    // 2 h at a 10 ms control period: 720,000 rows. The 2D rigid-bearing
    // joint is the cheapest plant to step (≈ 10 s in a debug build); kept
    // in memory the rows alone would be ≈ 70 MB and their CSV text 40 MB.
    let s = Scenario {
        name: "two hours".into(),
        joint: JointKind::TwoD,
        duration_s: 7200.0,
        control_period_us: 10_000,
        targets: vec![TargetStep {
            t_s: 0.0,
            deg: vec![5.0],
        }],
        plant: PlantSpec {
            rigid_bearing: true,
            ..PlantSpec::default()
        },
        estimator: host_tools::files::scenario::EstimatorSpec {
            method: host_tools::files::scenario::EstimatorMethod::Paper,
            calibration: None,
        },
        ..Scenario::default()
    };
    let before = peak_rss_mb();
    let dir = tempfile::tempdir().unwrap();
    let plot = dir.path().join("plot.svg");
    // The CSV goes to /dev/null: 70 MB of text on a shared disk proves
    // nothing more; every row still goes through the writer.
    let angles = angle_names(&s);
    let mut files = TraceFiles::open(
        Some(std::path::Path::new("/dev/null")),
        Some(&plot),
        &angles,
    )
    .unwrap();
    let mut summary = sim::run_into(
        &s,
        &mut files,
        &Stop::never(),
        &host_tools::progress::hidden(),
    )
    .unwrap();
    summary.trace = files
        .finish("two hours", &angles, summary.planned_steps)
        .unwrap();
    assert!(summary.cut_short.is_none(), "{:?}", summary.cut_short);
    assert_eq!(summary.steps, 720_000);
    assert_eq!(summary.trace.as_ref().map(|t| t.rows), Some(720_000));
    assert!(std::fs::metadata(&plot).unwrap().len() < 2_000_000);
    let peak = peak_rss_mb();
    println!("peak RSS {peak:.1} MB (before the run {before:.1} MB)");
    assert!(peak < 50.0, "peak RSS {peak:.1} MB for a 2-hour run");
}
