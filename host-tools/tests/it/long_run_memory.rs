//! Memory stays flat however long a run: a 2-hour simulated run with a CSV
//! trace and a plot peaks far below what keeping its 720,000 rows would
//! take. The run is `softjoint sim` as a user runs it, in a process of its
//! own (this test binary runs other tests in threads beside it, so its own
//! resident set says nothing about one run); the test follows the child's
//! peak resident set (`VmHWM` in /proc/PID/status) while it runs.
use std::io::Read as _;
use std::process::{Command, Stdio};
use std::time::Duration;

use host_tools::files::scenario::{
    EstimatorMethod, EstimatorSpec, JointKind, PlantSpec, Scenario, TargetStep,
};

/// Peak resident set size of process `pid` so far (MB), or `None` once it
/// has gone.
fn peak_rss_mb(pid: u32) -> Option<f64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let kb: f64 = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|v| v.parse().ok())?;
    Some(kb / 1024.0)
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
        estimator: EstimatorSpec {
            method: EstimatorMethod::Paper,
            calibration: None,
        },
        ..Scenario::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("two_hours.toml");
    std::fs::write(&scenario, toml::to_string(&s).unwrap()).unwrap();
    // The CSV goes into a FIFO that a thread drains: 70 MB of text on a
    // shared disk proves nothing more, and every row still goes through
    // the writer.
    let csv = dir.path().join("trace.csv");
    let made = Command::new("mkfifo").arg(&csv).status().expect("mkfifo");
    assert!(made.success(), "mkfifo {}", csv.display());
    let drain = {
        let csv = csv.clone();
        std::thread::spawn(move || {
            let mut f = std::fs::File::open(csv).expect("open the FIFO");
            let mut buf = vec![0u8; 1 << 16];
            let mut bytes = 0u64;
            loop {
                match f.read(&mut buf) {
                    Ok(0) => return bytes,
                    Ok(n) => bytes += n as u64,
                    Err(e) => panic!("reading the trace FIFO: {e}"),
                }
            }
        })
    };
    let plot = dir.path().join("plot.svg");
    let mut child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .arg("sim")
        .arg(&scenario)
        .arg("--csv")
        .arg(&csv)
        .arg("--plot")
        .arg(&plot)
        .arg("--json")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("softjoint sim");
    let mut peak = 0.0f64;
    let status = loop {
        if let Some(mb) = peak_rss_mb(child.id()) {
            peak = peak.max(mb);
        }
        match child.try_wait().expect("waiting for softjoint") {
            Some(status) => break status,
            None => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    let out = child.wait_with_output().expect("its output");
    assert!(
        status.success(),
        "{status}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON summary");
    assert!(summary.get("cut_short").is_none(), "{summary}");
    assert_eq!(summary["steps"], 720_000);
    assert_eq!(summary["trace"]["rows"], 720_000);
    let csv_bytes = drain.join().unwrap();
    assert!(csv_bytes > 30_000_000, "{csv_bytes} bytes of CSV");
    assert!(std::fs::metadata(&plot).unwrap().len() < 2_000_000);
    println!("peak RSS of `softjoint sim` {peak:.1} MB, {csv_bytes} bytes of CSV");
    assert!(peak > 1.0, "the child's resident set was never read");
    assert!(peak < 50.0, "peak RSS {peak:.1} MB for a 2-hour run");
}

/// `sim --excite` streams its log: a half-hour session at a 10 ms row
/// interval (180,000 rows) peaks far below what keeping it whole took
/// (88 MB at main 3919059, `/usr/bin/time -v softjoint sim … --excite`;
/// 17 MB streamed).
#[test]
#[cfg(target_os = "linux")]
fn a_half_hour_excitation_session_peaks_under_40_mb() {
    use crate::excite_stops::{HOUR_PLAN, SCENARIO_2D};
    let dir = tempfile::tempdir().unwrap();
    let scenario = dir.path().join("s.toml");
    std::fs::write(&scenario, SCENARIO_2D).unwrap();
    let plan = dir.path().join("plan.toml");
    std::fs::write(&plan, HOUR_PLAN.replace("3600", "1800")).unwrap();
    let log = dir.path().join("log.csv");
    let made = Command::new("mkfifo").arg(&log).status().expect("mkfifo");
    assert!(made.success(), "mkfifo {}", log.display());
    let drain = {
        let log = log.clone();
        std::thread::spawn(move || {
            let mut f = std::fs::File::open(log).expect("open the FIFO");
            let mut text = Vec::new();
            f.read_to_end(&mut text).expect("reading the log FIFO");
            let lines = text.iter().filter(|b| **b == b'\n').count();
            (text.len(), lines)
        })
    };
    let mut child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .arg("sim")
        .arg(&scenario)
        .arg("--excite")
        .arg(&plan)
        .arg("--log")
        .arg(&log)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("softjoint sim --excite");
    let mut peak = 0.0f64;
    let status = loop {
        if let Some(mb) = peak_rss_mb(child.id()) {
            peak = peak.max(mb);
        }
        match child.try_wait().expect("waiting for softjoint") {
            Some(status) => break status,
            None => std::thread::sleep(Duration::from_millis(20)),
        }
    };
    let out = child.wait_with_output().expect("its output");
    assert!(
        status.success(),
        "{status}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let (bytes, lines) = drain.join().unwrap();
    assert_eq!(lines, 180_001, "header and 180,000 rows");
    println!("peak RSS of `softjoint sim --excite` {peak:.1} MB, {bytes} bytes of log");
    assert!(peak > 1.0, "the child's resident set was never read");
    assert!(peak < 40.0, "peak RSS {peak:.1} MB for a half-hour session");
}
