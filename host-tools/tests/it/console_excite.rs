//! `softjoint console --port DEV excite PLAN --log LOG` against a board
//! wired to a simulated joint: the firmware's board application on a pty
//! whose coil outputs drive a `plant_models` 3D joint and whose wire
//! sensors read it (`PtyBoard::start_with_plant`). The plan runs on the
//! board in free-running mode (open-loop `Drive`s, holds under the board's
//! controller), and the log is the one `identify joint` reads. The
//! minute-long recording and identification on the hidden joint (the joint
//! README's figures) is the example `identify_from_board`.
use crate::common;

use std::process::{Command, Output};

use host_tools::board::pty::PtyBoard;
use plant_joint::{Joint3d, Joint3dParams};

/// One subprocess on a pty at a time (see `cli_console.rs`).
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn board() -> (PtyBoard, String) {
    let plant = Joint3d::new(Joint3dParams::default()).expect("default plant");
    let (board, host_end) = PtyBoard::start_with_plant(plant).expect("pty pair");
    let path = board.host_path.clone();
    drop(host_end); // the subprocess opens the pty itself
    (board, path)
}

fn excite(port: &str, plan: &str, log: &str) -> Output {
    Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["console", "--port", port, "excite", plan, "--log", log])
        .output()
        .expect("run softjoint")
}

/// `identify joint LOG --angles board-estimate -o PLANT` with `extra`.
fn identify_from_estimates(
    log: &std::path::Path,
    plant: &std::path::Path,
    extra: &[&str],
) -> Output {
    let mut args = vec![
        "identify",
        "joint",
        common::s(log),
        "--angles",
        "board-estimate",
        "-o",
        common::s(plant),
        // A few seconds of board estimates: the plumbing, not a verified
        // plant.
        "--allow-unverified",
    ];
    args.extend_from_slice(extra);
    common::softjoint(&args)
}

/// 8 s: a 2 s step on coil 1 (α's agonist), a co-contraction (coil 3
/// warm at 1.9 V, coil 1 pulsed on top), then α held at 5° by the board's
/// controller; β held at −4° throughout.
const PLAN: &str = r#"
name = "board session test"
duration_s = 8.0
log_interval_ms = 10

[[drive]]
coil = 1
from_s = 0.0
to_s = 2.0
volts = 3.0

[[drive]]
coil = 3
from_s = 2.5
to_s = 4.5
volts = 1.9

[[drive]]
coil = 1
from_s = 3.0
to_s = 3.5
volts = 3.0

[[hold]]
plane = 0
deg = 5.0
from_s = 4.5
to_s = 8.0

[[hold]]
plane = 1
deg = -4.0
from_s = 0.0
to_s = 8.0
"#;

#[test]
#[ignore = "real time (the pty board steps the plant by the wall clock and sends telemetry at 100 Hz): tests sharing the CPU make it lose frames, so CI runs it one at a time after the other ignored checks (scripts/test-all.sh)"]
fn a_plan_runs_on_a_plant_backed_board_and_logs_what_identify_reads() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, port) = board();
    let dir = common::scratch("console_excite");
    let keep = std::env::var("KEEP_LOG").ok();
    let plan_path = common::file(&dir, "plan.toml", PLAN);
    let log_path = dir.join("board.csv");
    let out = excite(&port, &plan_path, common::s(&log_path));
    let (stdout, stderr) = (common::stdout(&out), common::stderr(&out));
    assert!(out.status.success(), "stdout {stdout} stderr {stderr}");
    let lag_ms = board.state.lock().unwrap().plant_lag_ms;
    // The plant kept up with the board's clock (it steps in the board's
    // thread; a lag would mean the board read stale wires).
    assert!(lag_ms < 20.0, "the plant lagged the clock by {lag_ms} ms");
    drop(board);

    // The log reads as identify reads it: rows every 10 ms from 0.
    if let Some(k) = &keep {
        std::fs::copy(&log_path, k).unwrap();
    }
    let log = host_tools::joint::excite::read_log(&log_path).expect("identify's reader takes it");
    assert_eq!(log.planes, 2);
    assert_eq!(log.len(), 800, "{stdout}");
    assert!((log.period_s - 0.01).abs() < 1e-9);
    let filled: usize = stdout
        .split(" rows filled")
        .next()
        .and_then(|s| s.rsplit("; ").next())
        .and_then(|n| n.trim().parse().ok())
        .unwrap_or_else(|| panic!("no `rows filled` in {stdout}"));
    // A few frames lost on a loaded machine are filled and counted (the
    // log says how many); more than 2 % would be a link that cannot keep
    // up. (At most 5 until a clean CI run of f42add1 lost 8 of 800 beside
    // the twins on the other CPU.)
    assert!(filled <= 16, "{filled} telemetry frames lost: {stdout}");

    // Coil columns are the plan's inputs on the driven coils (1 mV
    // quantisation; a row may lag one interval when a command met a slow
    // host, at most 2 % of them).
    let plan: plant_joint::identify::ExcitationPlan = toml::from_str(PLAN).unwrap();
    let mut off_plan = Vec::new();
    for k in 0..log.len() {
        let t = log.t_s[k];
        let want = plan.volts_at(2, t + 0.005);
        for (c, w) in want.iter().enumerate() {
            if let Some(w) = w {
                if (log.volts[k][c] - w).abs() > 1.5e-3 {
                    off_plan.push((t, c + 1, log.volts[k][c], *w));
                }
            }
        }
    }
    assert!(
        off_plan.len() <= 10,
        "{} coil inputs off the plan: {:?}",
        off_plan.len(),
        &off_plan[..off_plan.len().min(10)]
    );
    // Co-contraction: both coils of α on, 3.0–3.5 s.
    let both = (300..350)
        .filter(|&k| log.volts[k][0] > 2.9 && log.volts[k][2] > 1.8)
        .count();
    assert!(both >= 48, "α's coils both on in {both} of 50 rows");

    // The board's own estimates (extra columns) and the wires: coil 1
    // pulls α up (its wire 3 in, wire 1 out under Eq. 3's sign).
    let text = std::fs::read_to_string(&log_path).unwrap();
    let table = plant_common::csv_input::read_numeric(&text, "board.csv").unwrap();
    let est_a = table.values(table.column("est_alpha_deg").unwrap());
    let est_b = table.values(table.column("est_beta_deg").unwrap());
    let rise = est_a[200] - est_a[0];
    assert!(rise > 2.0, "α rose {rise}° under coil 1's step");
    assert!(
        log.wire_mm[200][2] - log.wire_mm[200][0] > log.wire_mm[0][2] - log.wire_mm[0][0],
        "the wires saw α rise"
    );
    // The holds settle near their targets (mean of the last 0.5 s).
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (a_end, b_end) = (mean(&est_a[750..]), mean(&est_b[750..]));
    assert!((a_end - 5.0).abs() < 1.0, "α held at {a_end}°, target 5°");
    assert!((b_end + 4.0).abs() < 1.0, "β held at {b_end}°, target −4°");
    // Held planes are not driven open loop: β's coils are its controller's
    // (never both on).
    for k in 0..log.len() {
        assert!(
            log.volts[k][1] == 0.0 || log.volts[k][3] == 0.0,
            "β co-contracted at {} s",
            log.t_s[k]
        );
    }
}

/// Ctrl-C during a session: the board is disarmed, the rows recorded up
/// to there are written, and the program exits as SIGINT would (130).
#[test]
#[ignore = "real time (the pty board steps the plant by the wall clock and sends telemetry at 100 Hz): tests sharing the CPU make it lose frames, so CI runs it one at a time after the other ignored checks (scripts/test-all.sh)"]
fn ctrl_c_disarms_the_board_and_keeps_the_rows() {
    stop_disarms_the_board_and_keeps_the_rows("-INT", "SIGINT", 130);
}

/// The same with SIGTERM, in the default suite: nothing here depends on
/// frames arriving on time (≈ 0.1 s of CPU, 1–2 s of waiting). On main
/// before the log was streamed, the rows were in memory until the end of
/// the session, none on disk while it ran.
#[test]
fn sigterm_disarms_the_board_and_keeps_the_rows_streamed_so_far() {
    stop_disarms_the_board_and_keeps_the_rows("-TERM", "SIGTERM", 143);
}

/// Starts a session, waits until the board drives and the log's rows
/// are on disk (in the temporary file beside the log, which they replace
/// at the end), sends `signal`: the board is disarmed, the log holds the
/// rows recorded up to there, the message says where, no temporary file
/// is left, and the program exits with `code`.
fn stop_disarms_the_board_and_keeps_the_rows(signal: &str, name: &str, code: i32) {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, port) = board();
    let dir = common::scratch("console_excite_stop");
    let plan_path = common::file(&dir, "plan.toml", PLAN);
    let log_path = dir.join("board.csv");
    let child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["console", "--port", &port, "excite", &plan_path, "--log"])
        .arg(&log_path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run softjoint");
    // Wait until the board drives (the session runs), then a second more.
    let t = std::time::Instant::now();
    while board.state.lock().unwrap().outputs[0][0].volts() == 0.0 {
        assert!(t.elapsed().as_secs() < 10, "the session never drove coil 1");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    std::thread::sleep(std::time::Duration::from_millis(1000));
    let on_disk = || {
        std::fs::read_dir(&*dir)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|x| x == "tmp"))
            .map(|p| {
                std::fs::read_to_string(p)
                    .unwrap_or_default()
                    .lines()
                    .count()
            })
            .sum::<usize>()
    };
    while on_disk() < 50 {
        assert!(
            t.elapsed().as_secs() < 10,
            "no rows on disk during the session"
        );
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    assert!(!log_path.exists(), "the log is replaced at the end only");
    common::kill(signal, child.id());
    let out = child.wait_with_output().unwrap();
    let (stdout, stderr) = (common::stdout(&out), common::stderr(&out));
    assert_eq!(
        out.status.code(),
        Some(code),
        "stdout {stdout} stderr {stderr}"
    );
    let log = host_tools::joint::excite::read_log(&log_path).expect("the rows up to the signal");
    assert!(
        stderr.contains(&format!("stopped by {name} at t = "))
            && stderr.contains("disarmed")
            && stderr.contains(&format!("board.csv holds its {} rows", log.len())),
        "{stderr}"
    );
    assert_eq!(on_disk(), 0, "a temporary file left beside the log");
    // At least the rows seen on disk, fewer than the plan's 800.
    assert!(
        (50..800).contains(&log.len()),
        "{} rows after about 1 s: {stdout}",
        log.len()
    );
    std::thread::sleep(std::time::Duration::from_millis(20));
    let st = board.state.lock().unwrap();
    assert!(
        st.outputs.iter().flatten().all(|v| v.volts() == 0.0),
        "still driven after {name}: {:?}",
        st.outputs
    );
}

/// `identify joint` on a board log: without a camera it says what is
/// missing; with `--angles board-estimate` it fits to the board's own
/// estimates and says so (a short run: the figures are the ignored test's
/// below).
#[test]
fn identify_runs_on_a_board_log_with_the_boards_estimates() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, port) = board();
    let dir = common::scratch("console_excite_identify");
    // The first 3 s of the session plan: one step and its decay on α.
    let plan = PLAN.replace("duration_s = 8.0", "duration_s = 3.0");
    let plan = plan
        .split("[[drive]]\ncoil = 3")
        .next()
        .unwrap()
        .to_string();
    let plan_path = common::file(&dir, "plan.toml", &plan);
    let log = dir.join("board.csv");
    common::ok(&excite(&port, &plan_path, common::s(&log)));
    drop(board);
    let plant = dir.join("plant.toml");
    let no_camera = common::softjoint(&[
        "identify",
        "joint",
        common::s(&log),
        "-o",
        common::s(&plant),
    ]);
    assert!(!no_camera.status.success());
    let err = common::stderr(&no_camera);
    assert!(
        err.contains("no camera frame") && err.contains("--angles board-estimate"),
        "{err}"
    );
    let out = identify_from_estimates(&log, &plant, &["--max-iterations", "2"]);
    common::ok(&out);
    let text = common::stdout(&out);
    assert!(
        text.starts_with("angles: the board's wire-based estimates"),
        "{text}"
    );
    assert!(
        text.contains("plane alpha") && text.contains("plane beta"),
        "{text}"
    );
    assert!(plant.exists(), "a plant file is written");
    // The JSON report too, where a parameter the log does not determine
    // has no finite 1σ (null).
    let out = identify_from_estimates(&log, &plant, &["--max-iterations", "2", "--json"]);
    common::ok(&out);
    let report: serde_json::Value = serde_json::from_str(&common::stdout(&out)).unwrap();
    assert!(report["angles"]
        .as_str()
        .is_some_and(|a| a.contains("not a camera")));
    assert_eq!(report["rows"], 300);
    let estimates = report["planes"][0]["estimates"].as_array().unwrap();
    assert!(estimates
        .iter()
        .all(|e| e["std"].is_number() || e["identifiable"] == false));
}

/// 5 V on coil 1 for 2.9 s is inside the budget from cold (modelled rise
/// 86 K < 95 K, so the host's check lets it through), but not right after
/// the same pulse: the board's own budget model is still warm, trips the
/// coil and refuses the next drive by name; the console disarms and keeps
/// the rows up to there.
#[test]
fn the_boards_budget_refuses_an_over_budget_plan_by_name() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, port) = board();
    let dir = common::scratch("console_excite_budget");
    let plan_path = common::file(
        &dir,
        "hot.toml",
        "name = \"hot\"\nduration_s = 3.0\n[[drive]]\ncoil = 1\nfrom_s = 0.0\nto_s = 2.9\nvolts = 5.0\n",
    );
    let first = dir.join("first.csv");
    let out = excite(&port, &plan_path, common::s(&first));
    common::ok(&out);
    let second = dir.join("second.csv");
    let out = excite(&port, &plan_path, common::s(&second));
    let (stdout, stderr) = (common::stdout(&out), common::stderr(&out));
    assert!(!out.status.success(), "the warm coil ran: {stdout}");
    assert!(
        stderr.contains("refused Drive (OverBudget") && stderr.contains("disarmed"),
        "{stderr}"
    );
    assert!(stdout.contains("over-budget"), "{stdout}");
    let log = host_tools::joint::excite::read_log(&second).expect("the rows up to the refusal");
    assert!(
        log.len() > 10 && log.len() < 290,
        "{} rows before the refusal",
        log.len()
    );
    // Disarmed at the end: the board drives nothing.
    std::thread::sleep(std::time::Duration::from_millis(20));
    let st = board.state.lock().unwrap();
    assert!(st.outputs.iter().flatten().all(|v| v.volts() == 0.0));
}
