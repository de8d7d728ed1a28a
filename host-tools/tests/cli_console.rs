//! `softjoint console` against the firmware's board application on a pty:
//! scripted commands, error replies, and a telemetry stream to CSV.
mod common;

use std::process::Command;

use host_tools::pty_board::PtyBoard;

/// serialport opens ptys without close-on-exec, so a subprocess spawned by
/// one test can inherit (and hold the lock of) another test's pty; the
/// tests here take turns.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn console(port: &str, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["console", "--port", port])
        .args(args)
        .output()
        .expect("run softjoint")
}

#[test]
fn scripted_session_with_telemetry_to_csv() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    let path = board.host_path.clone();
    drop(host_end); // the subprocess opens the pty itself
    let dir = common::scratch("console");
    let script = dir.join("session.txt");
    std::fs::write(&script, "# a session\nhello\ntarget 0 5   # alpha\ngains 1 1.5 1.5 0 0\ntelemetry 50\nstream 0.4\ntelemetry 0\nstatus\n").unwrap();
    let csv = dir.join("telemetry.csv");
    let out = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["console", "--port", &path, "--script"])
        .arg(&script)
        .arg("--csv")
        .arg(&csv)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "stdout {stdout} stderr {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("protocol and schema match"), "{stdout}");
    assert!(
        stdout.contains("target α 5.00°"),
        "status shows the target: {stdout}"
    );
    let rows = std::fs::read_to_string(&csv).unwrap();
    let n = rows.lines().count() - 1;
    assert!(rows.starts_with("time_ms,alpha_deg"), "{rows}");
    assert!(
        (10..=30).contains(&n),
        "{n} telemetry rows in 0.4 s at 50 Hz"
    );
}

#[test]
fn refused_and_unknown_commands_fail_with_a_reason() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    let path = board.host_path.clone();
    drop(host_end);
    // Refused on the host, naming the board's range.
    let out = console(&path, &["target", "0", "90"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("DEG must be a finite number in -25..=25") && err.contains("command line"),
        "{err}"
    );
    // Refused by the board (a negative gain): the port, the request by
    // name and what the board accepts, no opcode.
    let out = console(&path, &["gains", "0", "-1", "1", "0", "0"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("the board on {path} refused SetGains"))
            && err.contains("Kp > 0")
            && !err.contains("0x11"),
        "{err}"
    );
    let out = console(&path, &["frobnicate"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown command"));
    let out = console("/dev/does-not-exist", &["status"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot open serial port"));
}
