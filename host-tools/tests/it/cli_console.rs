//! `softjoint console` against the firmware's board application on a pty:
//! scripted commands, error replies, and a telemetry stream to CSV.
use crate::common;

use std::process::Command;

use host_tools::board::pty::PtyBoard;

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

/// Runs `softjoint console --port PORT ARGS…`, killing it if it has not
/// finished within `limit` (a console that spins never would).
fn console_within(port: &str, args: &[&str], limit: std::time::Duration) -> std::process::Output {
    let child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["console", "--port", port])
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run softjoint");
    let pid = child.id();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(child.wait_with_output());
    });
    match rx.recv_timeout(limit) {
        Ok(out) => out.expect("console output"),
        Err(_) => {
            common::kill("-KILL", pid);
            panic!("console {args:?} did not finish within {limit:?} (spinning on telemetry?)");
        }
    }
}

#[test]
fn requests_are_answered_while_the_board_streams_telemetry() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    let path = board.host_path.clone();
    drop(host_end);
    // 1 kHz telemetry piles up in the pty during the wait, so the status
    // request reads telemetry before its reply: the frames must be set
    // aside, not read again and again until the end of time.
    let out = console_within(
        &path,
        &["telemetry 1000; wait 0.05; status; telemetry 0; status"],
        std::time::Duration::from_secs(20),
    );
    let stdout = common::stdout(&out);
    assert!(out.status.success(), "{stdout}\n{}", common::stderr(&out));
    assert_eq!(stdout.matches("armed ").count(), 2, "{stdout}");
    assert_eq!(stdout.matches("ok").count(), 2, "{stdout}");
    // Later consoles on the same board are not stuck either.
    let out = console_within(&path, &["status"], std::time::Duration::from_secs(10));
    assert!(out.status.success(), "{}", common::stderr(&out));
}

#[test]
fn durations_are_checked_not_converted_with_a_panic() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    let path = board.host_path.clone();
    drop(host_end);
    for cmd in [
        "wait NaN",
        "stream 1e20",
        "wait -1",
        "stream inf",
        "wait 1e400",
    ] {
        let out = console_within(&path, &[cmd], std::time::Duration::from_secs(10));
        let err = common::stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{cmd}: {err}");
        assert!(!err.contains("panicked"), "{cmd}: {err}");
        assert!(
            err.contains("SECONDS must be a finite number in 0..=86400 s"),
            "{cmd}: {err}"
        );
    }
}

/// A script saved by a Windows editor (byte-order mark, CRLF) runs like a
/// plain one.
#[test]
fn a_console_script_from_windows_runs() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    drop(host_end);
    let dir = common::scratch("excel-console");
    let script = dir.join("session.txt");
    std::fs::write(&script, "\u{feff}# from notepad\r\nhello\r\nstatus\r\n").unwrap();
    let out = console(&board.host_path, &["--script", script.to_str().unwrap()]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    assert!(common::stdout(&out).contains("protocol and schema match"));
}

/// The board's pty is created close-on-exec (no window in which a process
/// another test starts inherits it) and holds no lock: while a long-lived
/// process started right after it runs, a console still opens the port.
/// With `TTYPort::pair` plus a later `close_on_exec`, a process spawned in
/// between kept the host end's flock and the console failed with "Unable
/// to acquire exclusive lock" (CI, stop 36).
#[test]
fn the_boards_pty_is_not_inherited_nor_locked() {
    use std::os::fd::AsRawFd as _;
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    let flags = unsafe_free_fd_flags(host_end.as_raw_fd());
    assert!(
        flags & libc::FD_CLOEXEC != 0,
        "host end inheritable: {flags:#x}"
    );
    // A child started now must not see the host end's descriptor.
    let fd = host_end.as_raw_fd();
    let mut child = std::process::Command::new("sh")
        .args(["-c", &format!("readlink /proc/$$/fd/{fd}; sleep 2")])
        .stdout(std::process::Stdio::piped())
        .spawn()
        .expect("sh");
    // What an inherited copy would be: a second descriptor on the same
    // open file, alive after the test's own is closed. Had the host end
    // kept a lock, the copy would keep it and the console would fail.
    let copy = host_end.try_clone_native().expect("dup");
    drop(host_end);
    let out = console_within(
        &board.host_path,
        &["status"],
        std::time::Duration::from_secs(10),
    );
    let _ = child.kill();
    let child_out = child.wait_with_output().expect("sh output");
    assert!(out.status.success(), "{}", common::stderr(&out));
    drop(copy);
    let seen = String::from_utf8_lossy(&child_out.stdout).to_string();
    assert!(
        !seen.contains(&board.host_path),
        "the child inherited the pty: {seen}"
    );
}

/// `fcntl(fd, F_GETFD)` through /proc: the descriptor's close-on-exec flag
/// without unsafe code in a test.
fn unsafe_free_fd_flags(fd: i32) -> i32 {
    let info = std::fs::read_to_string(format!("/proc/self/fdinfo/{fd}")).expect("fdinfo");
    let flags = info
        .lines()
        .find_map(|l| l.strip_prefix("flags:"))
        .map(|v| i32::from_str_radix(v.trim(), 8).expect("octal flags"))
        .expect("flags line");
    // O_CLOEXEC is reported in the open flags; map it to FD_CLOEXEC.
    if flags & libc::O_CLOEXEC != 0 {
        libc::FD_CLOEXEC
    } else {
        0
    }
}
