//! `sim --excite` and `hil --excite` stopped by a signal (issue 31, item
//! 3): the session stops at a clean point, its log holds every whole row
//! up to there (streamed as it ran, so also readable while it runs), and
//! the program exits as the signal would (130, 143, 129). The signals go
//! to a child process this test started, never to the test's own group.
use crate::common;

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{file, s, scratch, stderr};

/// The 2D joint at a 10 ms control period with the paper's laws.
pub const SCENARIO_2D: &str = "name = \"long\"\njoint = \"2d\"\ncontrol_period_us = 10000\n\
[estimator]\nmethod = \"paper\"\n[[targets]]\nt_s = 0\ndeg = [0.0]\n";

/// An hour-long plan: θ held at 3°, one pulse on coil 1; a row per 10 ms.
pub const HOUR_PLAN: &str = "name = \"hour\"\nduration_s = 3600\nlog_interval_ms = 10\n\
[[drive]]\ncoil = 1\nfrom_s = 0\nto_s = 1\nvolts = 2.0\n\
[[hold]]\nplane = 0\ndeg = 3.0\nfrom_s = 2\nto_s = 3600\n";

/// Waits until `path` holds at least `bytes` (the log streams as the
/// session runs).
pub fn wait_for_bytes(path: &Path, bytes: u64, child: &mut Child) {
    let until = Instant::now() + Duration::from_secs(60);
    while std::fs::metadata(path).map_or(0, |m| m.len()) < bytes {
        if let Some(status) = child.try_wait().unwrap() {
            let mut err = String::new();
            if let Some(mut e) = child.stderr.take() {
                let _ = std::io::Read::read_to_string(&mut e, &mut err);
            }
            panic!(
                "ended ({status}) before {} held {bytes} bytes: {err}",
                path.display()
            );
        }
        assert!(
            Instant::now() < until,
            "{} never reached {bytes} bytes: the log is not streamed",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Waits until `path` holds more than `rows` whole rows after its header.
pub fn wait_for_rows(path: &Path, rows: usize, child: &mut Child) {
    let until = Instant::now() + Duration::from_secs(120);
    loop {
        let text = std::fs::read_to_string(path).unwrap_or_default();
        if text.matches('\n').count() > rows + 1 {
            return;
        }
        assert!(
            child.try_wait().unwrap().is_none(),
            "ended before {} held {rows} rows",
            path.display()
        );
        assert!(
            Instant::now() < until,
            "{} never held {rows} rows",
            path.display()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Checks that `log` reads back (identify's own reader) as `rows` whole,
/// evenly spaced rows.
pub fn assert_whole_log(log: &Path, rows: usize) {
    let text = std::fs::read_to_string(log).unwrap();
    assert!(text.ends_with('\n'), "last row cut off");
    let read = host_tools::joint::excite::read_log(log).expect("identify reads the log kept");
    assert_eq!(read.len(), rows, "rows in {}", log.display());
}

/// The row count in a message "… holds its N rows …".
fn rows_said(err: &str) -> usize {
    let after = err
        .split("holds its ")
        .nth(1)
        .unwrap_or_else(|| panic!("{err}"));
    after
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{err}"))
}

#[test]
fn sim_excite_stopped_by_int_term_or_hup_keeps_its_log_so_far() {
    for (signal, code, name) in [
        ("-INT", 130, "SIGINT"),
        ("-TERM", 143, "SIGTERM"),
        ("-HUP", 129, "SIGHUP"),
    ] {
        let dir = scratch("excite-stop");
        let scen = file(&dir, "s.toml", SCENARIO_2D);
        let plan = file(&dir, "plan.toml", HOUR_PLAN);
        let log = dir.join("log.csv");
        let mut child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
            .args(["sim", &scen, "--excite", &plan, "--log", s(&log)])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_bytes(&log, 100_000, &mut child);
        common::kill(signal, child.id());
        let out = child.wait_with_output().unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(code), "{signal}: {err}");
        assert!(
            err.contains(&format!("stopped by {name}")) && err.contains("of 3600 s"),
            "{err}"
        );
        let rows = rows_said(&err);
        assert!(rows > 1000 && rows < 360_000, "{rows} rows: {err}");
        assert_whole_log(&log, rows);
    }
}

/// A session that completes writes the same file as before streaming: the
/// whole log formatted at once by `log_csv`, byte for byte.
#[test]
fn a_streamed_log_is_the_whole_log_written_at_once() {
    use host_tools::joint::excite::{log_csv, run_sim, LogFile};
    let dir = scratch("excite-stream");
    let scenario: host_tools::files::scenario::Scenario = toml::from_str(SCENARIO_2D).unwrap();
    let spec = host_tools::run::spec::RunSpec::resolve(&scenario).unwrap();
    let mut plan: plant_joint::identify::ExcitationPlan = toml::from_str(HOUR_PLAN).unwrap();
    // 1,200 rows: more than two of the pieces a session hands on.
    plan.duration_s = 12.0;
    plan.hold[0].to_s = 12.0;
    let stop = host_tools::stop::Stop::never();
    let mut whole = plant_joint::identify::ExcitationLog::default();
    let a = run_sim(&plan, &spec, true, &mut whole, &stop).unwrap();
    let path = dir.join("log.csv");
    let mut streamed = LogFile::create(&path, 1, true).unwrap();
    let b = run_sim(&plan, &spec, true, &mut streamed, &stop).unwrap();
    assert_eq!(streamed.finish().unwrap(), 1200);
    assert_eq!(a, b);
    assert_eq!(whole.len(), 1200);
    assert_eq!(std::fs::read_to_string(&path).unwrap(), log_csv(&whole));
}

/// A stop asked before the session's first period: no rows, the summary
/// names the signal (the library's view of what the command reports).
#[test]
fn a_stop_request_ends_the_session_and_the_summary_names_it() {
    use host_tools::stop::{Stop, StopSignal};
    let scenario: host_tools::files::scenario::Scenario = toml::from_str(SCENARIO_2D).unwrap();
    let spec = host_tools::run::spec::RunSpec::resolve(&scenario).unwrap();
    let plan: plant_joint::identify::ExcitationPlan = toml::from_str(HOUR_PLAN).unwrap();
    let stop = Stop::never();
    stop.request(StopSignal::Hangup);
    let mut log = plant_joint::identify::ExcitationLog::default();
    let summary = host_tools::joint::excite::run_sim(&plan, &spec, true, &mut log, &stop).unwrap();
    assert_eq!(summary.stopped_by, Some(StopSignal::Hangup));
    assert_eq!((summary.rows, log.len()), (0, 0));
    assert_eq!(summary.planned_s, 3600.0);
}
