//! Long runs and their outputs: a run stopped by a signal or ended by a
//! failure leaves its CSV trace complete to its last row and says where
//! and why in its summary and exit code; output that cannot be written is
//! a named error, never a panic, and a file the user keeps survives a
//! write that fails.
use crate::common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{file, s, scratch, softjoint, stderr, stdout};

/// A 2D run of two simulated hours at a 10 ms period (720,000 steps, about
/// 25 s in a debug build): long enough to be interrupted.
const LONG_2D: &str =
    "name = \"long\"\njoint = \"2d\"\nduration_s = 7200\ncontrol_period_us = 10000\n\
[estimator]\nmethod = \"paper\"\n[[targets]]\nt_s = 0\ndeg = [5.0]\n";

/// Checks that `csv` holds exactly `steps` rows, one per 10 ms period
/// from t = 0, each complete (7 cells, a newline at the end of the file).
fn assert_complete_trace(csv: &Path, steps: u64) {
    let text = std::fs::read_to_string(csv).expect("trace written");
    assert!(text.ends_with('\n'), "last row cut off");
    let mut lines = text.lines();
    assert!(lines
        .next()
        .is_some_and(|h| h.starts_with("t_s,theta_true_deg")));
    let mut n = 0u64;
    for (k, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').collect();
        assert_eq!(cells.len(), 7, "row {k}: `{line}`");
        let t: f64 = cells[0]
            .parse()
            .unwrap_or_else(|_| panic!("row {k}: `{line}`"));
        assert!((t - k as f64 * 0.01).abs() < 1e-6, "row {k} at t = {t}");
        n += 1;
    }
    assert_eq!(n, steps, "rows in the CSV vs steps run");
}

/// Starts a long `sim` with `--csv`, waits until rows reach the file,
/// sends `signal`, and returns (exit code, summary JSON, CSV path).
fn interrupted(signal: &str, test: &str) -> (Option<i32>, serde_json::Value, common::Scratch) {
    let dir = scratch(test);
    let scen = file(&dir, "long.toml", LONG_2D);
    let csv = dir.join("trace.csv");
    let child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["sim", &scen, "--json", "--csv", s(&csv)])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let until = Instant::now() + Duration::from_secs(60);
    while std::fs::metadata(&csv).map_or(0, |m| m.len()) < 200_000 {
        assert!(Instant::now() < until, "no rows reached the CSV");
        std::thread::sleep(Duration::from_millis(20));
    }
    common::kill(signal, child.id());
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    assert!(!err.contains("panicked"), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&stdout(&out))
        .unwrap_or_else(|e| panic!("summary JSON: {e}\n{}\n{err}", stdout(&out)));
    (out.status.code(), summary, dir)
}

#[test]
fn sigint_leaves_a_trace_complete_to_its_last_row_and_exits_130() {
    let (code, summary, dir) = interrupted("-INT", "sigint");
    assert_eq!(code, Some(130));
    let steps = summary["steps"].as_u64().unwrap();
    assert!(steps > 0 && steps < 720_000, "{summary}");
    assert_eq!(summary["planned_steps"], 720_000);
    let cut = &summary["cut_short"];
    assert_eq!(cut["signal"], "SIGINT", "{summary}");
    assert_eq!(cut["cause"], "signal");
    assert_eq!(cut["at_step"].as_u64(), Some(steps));
    assert_eq!(summary["trace"]["rows"].as_u64(), Some(steps));
    assert_eq!(summary["trace"]["complete"], false);
    assert_complete_trace(&dir.join("trace.csv"), steps);
}

#[test]
fn sigterm_ends_a_run_the_same_way_with_143() {
    let (code, summary, dir) = interrupted("-TERM", "sigterm");
    assert_eq!(code, Some(143));
    assert_eq!(summary["cut_short"]["signal"], "SIGTERM", "{summary}");
    assert_complete_trace(&dir.join("trace.csv"), summary["steps"].as_u64().unwrap());
}

/// SIGHUP (the terminal closed, an ssh session dropped) ends a run like
/// SIGINT and SIGTERM: whole rows to the last, exit 129 (it used to kill
/// the run with a half-written last row).
#[test]
fn sighup_ends_a_run_the_same_way_with_129() {
    let (code, summary, dir) = interrupted("-HUP", "sighup");
    assert_eq!(code, Some(129));
    assert_eq!(summary["cut_short"]["signal"], "SIGHUP", "{summary}");
    assert_complete_trace(&dir.join("trace.csv"), summary["steps"].as_u64().unwrap());
}

/// A plant that goes unstable mid-run (a weight far beyond the joint) ends
/// the run there: the trace holds every step before, the summary and the
/// exit status say so.
#[test]
fn an_unstable_plant_leaves_its_trace_up_to_the_failing_step() {
    let dir = scratch("unstable");
    let scen = file(
        &dir,
        "heavy.toml",
        "joint = \"2d\"\nduration_s = 4.0\ncontrol_period_us = 10000\n[estimator]\nmethod = \"paper\"\n\
         [[targets]]\nt_s = 0\ndeg = [5.0]\n\
         [[disturbances]]\nkind = \"weight\"\nmass_g = 1e6\nfrom_s = 1.0\nto_s = 3.0\n",
    );
    let csv = dir.join("trace.csv");
    let out = softjoint(&["sim", &scen, "--json", "--csv", s(&csv)]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("run cut short at step") && err.contains("plant"),
        "{err}"
    );
    let summary: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(summary["cut_short"]["cause"], "plant", "{summary}");
    let steps = summary["steps"].as_u64().unwrap();
    assert!((100..400).contains(&steps), "{summary}");
    assert_complete_trace(&csv, steps);
}

#[test]
fn output_to_a_full_device_is_an_error_not_a_panic() {
    let dir = scratch("full");
    // A private full device (1:7), never the machine's own /dev/full:
    // `mknod` needs root, as CI runs.
    let full = dir.join("full");
    let made = Command::new("mknod")
        .arg(&full)
        .args(["c", "1", "7"])
        .stderr(std::process::Stdio::null())
        .status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("not run: mknod needs root");
        return;
    }
    let sweep = dir.join("sweep.csv");
    let short = file(
        &dir,
        "short.toml",
        "duration_s = 1.0\n[estimator]\nmethod = \"paper\"\n",
    );
    for args in [
        vec!["sim", &short, "--json"],
        vec!["sim", &short],
        vec!["sim", "--print-default"],
        vec!["sim", "--calibration-sweep", s(&sweep)],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_softjoint"))
            .args(&args)
            .stdout(std::fs::OpenOptions::new().write(true).open(&full).unwrap())
            .output()
            .unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            err.contains("cannot write to standard output") && err.contains("No space left"),
            "{args:?}: {err}"
        );
    }
    // A trace file on a full device: named, before the run.
    let out = softjoint(&["sim", &short, "--csv", s(&full)]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!("cannot write {}: No space left", full.display())),
        "{err}"
    );
    // Results kept atomically go through to the device: the plot and a
    // calibration file are refused for the full device, which stays a
    // device (a rename would have replaced it by a regular file).
    for flag in ["--plot", "--calibration-sweep"] {
        let out = softjoint(&["sim", &short, flag, s(&full)]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{flag}: {err}");
        assert!(err.contains("No space left"), "{flag}: {err}");
        use std::os::unix::fs::FileTypeExt as _;
        assert!(
            std::fs::metadata(&full)
                .unwrap()
                .file_type()
                .is_char_device(),
            "{flag} replaced the device"
        );
    }
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn output_paths_are_checked_before_the_run() {
    let dir = scratch("paths");
    let scen = file(&dir, "long.toml", LONG_2D);
    let started = Instant::now();
    for (flag, path) in [
        ("--csv", dir.join("missing-dir").join("t.csv")),
        ("--plot", dir.join("missing-dir").join("p.svg")),
        ("--csv", dir.to_path_buf()),
    ] {
        let out = softjoint(&["sim", &scen, flag, s(&path)]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(s(&path)), "{flag}: {err}");
    }
    // Refused at once: the 25 s run never started.
    assert!(started.elapsed() < Duration::from_secs(10));
}

/// A write that fails part-way (here a file-size limit of 0 bytes: the first write fails) must
/// leave the user's previous calibration as it was, and no partial file.
#[test]
fn a_calibration_write_that_fails_leaves_the_previous_file_intact() {
    let dir = scratch("atomic");
    let sweep = dir.join("sweep.csv");
    let o = softjoint(&["sim", "--calibration-sweep", s(&sweep)]);
    common::ok(&o);
    let keep = dir.join("keep.toml");
    let previous = "# my calibration from last week\n".repeat(40);
    std::fs::write(&keep, &previous).unwrap();
    let out = Command::new("sh")
        .arg("-c")
        .arg("ulimit -f 0; exec \"$@\"")
        .arg("sh")
        .arg(env!("CARGO_BIN_EXE_softjoint"))
        .args(["calibrate", "wire", s(&sweep), "-o", s(&keep)])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains(s(&keep)) && err.contains("too large"), "{err}");
    assert_eq!(std::fs::read_to_string(&keep).unwrap(), previous);
    // The sweep itself, rewritten under the same limit, is kept too.
    let before = std::fs::read(&sweep).unwrap();
    let out = Command::new("sh")
        .arg("-c")
        .arg("ulimit -f 0; exec \"$@\"")
        .arg("sh")
        .arg(env!("CARGO_BIN_EXE_softjoint"))
        .args(["sim", "--calibration-sweep", s(&sweep)])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert_eq!(std::fs::read(&sweep).unwrap(), before);
    let names: Vec<String> = std::fs::read_dir(&*dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(
        names.iter().all(|n| !n.ends_with(".tmp")),
        "temporary files left: {names:?}"
    );
    // Without the limit the same command replaces the file.
    common::ok(&softjoint(&[
        "calibrate",
        "wire",
        s(&sweep),
        "-o",
        s(&keep),
    ]));
    assert!(std::fs::read_to_string(&keep).unwrap().contains("[alpha]"));
}

/// Runs `softjoint ARGS` with its stderr on a terminal (a pty) and returns
/// what it drew there.
#[cfg(unix)]
fn stderr_on_a_terminal(args: &[&str]) -> String {
    use serialport::SerialPort as _;
    use std::io::Read as _;
    let (mut master, slave, slave_path) = host_tools::board::pty::pty_pair().expect("pty pair");
    let term = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&slave_path)
        .unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::from(term))
        .spawn()
        .unwrap();
    master.set_timeout(Duration::from_millis(50)).unwrap();
    let mut seen = Vec::new();
    let mut buf = [0u8; 4096];
    let until = Instant::now() + Duration::from_secs(60);
    loop {
        match master.read(&mut buf) {
            Ok(n) => seen.extend_from_slice(&buf[..n]),
            Err(_) => {
                if child.try_wait().unwrap().is_some() || Instant::now() > until {
                    break;
                }
            }
        }
    }
    let _ = child.kill();
    drop(slave);
    String::from_utf8_lossy(&seen).into_owned()
}

/// A run of a few seconds shows its progress on a terminal, and nothing
/// when stderr is a file or a pipe, or with `--json`.
#[test]
#[cfg(unix)]
fn progress_is_shown_on_a_terminal_only() {
    let dir = scratch("progress");
    let scen = file(
        &dir,
        "ten_minutes.toml",
        "joint = \"2d\"\nduration_s = 600\ncontrol_period_us = 10000\n[estimator]\nmethod = \"paper\"\n[[targets]]\nt_s = 0\ndeg = [5.0]\n",
    );
    let drawn = stderr_on_a_terminal(&["sim", &scen]);
    assert!(drawn.contains("/60,000 steps"), "{drawn:?}");
    let drawn = stderr_on_a_terminal(&["sim", &scen, "--json"]);
    assert!(!drawn.contains("steps"), "{drawn:?}");
    let out = softjoint(&["sim", &scen]);
    common::ok(&out);
    assert_eq!(stderr(&out), "", "progress drawn into a pipe");
}

/// A model unstable from its first frames (stiff springs at the seed's
/// step) is refused with exit 1 and nothing written, unless asked to keep
/// going (`--allow-unstable`, the one flag for every unstable push model
/// since issues 12 and 13 were merged).
#[test]
fn a_push_unstable_from_the_start_exits_non_zero_unless_asked_to_keep_going() {
    let dir = scratch("unstable-push");
    let params = file(
        &dir,
        "stiff.json",
        r#"{"k_length": 1e7, "k_damping": 0.5, "k_area": 1.0, "k_angle": 1.0, "max_force": 1e4, "yield_strain": 0.5, "creep": 0.0, "max_alpha": 0.0}"#,
    );
    let out_dir = dir.join("out");
    // A coarse ground truth and raster keep the debug build quick.
    let args = [
        "push",
        "simulate",
        "--params",
        &params,
        "--ref-element-px",
        "30",
        "--cell-px",
        "8",
        "--out",
        s(&out_dir),
    ];
    let o = softjoint(&args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("became unstable at frame") && err.contains("--allow-unstable"),
        "{err}"
    );
    assert!(!out_dir.exists(), "files written for a refused run");
    let o = softjoint(&[&args[..], &["--allow-unstable"]].concat());
    common::ok(&o);
    assert!(
        stderr(&o).contains("warning: the mass-spring model"),
        "{}",
        stderr(&o)
    );
    assert!(out_dir.join("snapshots.svg").exists());
}
