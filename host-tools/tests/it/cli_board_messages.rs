//! What `console` and `hil` say when the board is not there, says
//! nothing, sends garbage, or is asked for something out of its range
//! (issue 13): the option, its range and the port, never an opcode; and a
//! stream that received nothing is a failure, not "0 frames" with exit 0.
use crate::common;

use std::io::Write;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use serialport::TTYPort;

/// Tests take turns: serialport opens ptys without close-on-exec.
static SERIAL: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn console(port: &str, args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["console", "--port", port])
        .args(args)
        .output()
        .expect("run softjoint")
}

/// A pty with nobody on the far end; the returned master keeps it open.
fn silent_port() -> (TTYPort, String) {
    // Opened close-on-exec: not inherited by the processes other tests
    // start meanwhile.
    let (master, slave, path) = host_tools::board::pty::pty_pair().expect("pty pair");
    drop(slave);
    (master, path)
}

#[test]
fn stream_on_a_silent_port_fails_and_names_the_port() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (_master, path) = silent_port();
    let o = console(&path, &["stream 0.3"]);
    let err = common::stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains(&format!("no telemetry from {path} in 0.3 s"))
            && err.contains("nothing at all arrived")
            && err.contains("telemetry 10"),
        "{err}"
    );
}

#[test]
fn stream_on_a_port_of_garbage_fails_and_counts_it() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (mut master, path) = silent_port();
    let stop = Arc::new(AtomicBool::new(false));
    let noise = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let mut x = 0x2545_F491u32;
            while !stop.load(Ordering::Relaxed) {
                let mut buf = [0u8; 64];
                for b in &mut buf {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    *b = x as u8;
                }
                let _ = master.write_all(&buf);
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
        })
    };
    let o = console(&path, &["stream 0.5"]);
    stop.store(true, Ordering::Relaxed);
    noise.join().unwrap();
    let err = common::stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains(&format!("no telemetry from {path}")) && err.contains("did not decode"),
        "{err}"
    );
}

#[test]
fn no_reply_names_the_port_and_what_to_check() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (_master, path) = silent_port();
    let o = console(&path, &["hello"]);
    let err = common::stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains(&format!("no reply from {path} to Hello after 10 attempts"))
            && err.contains("--baud")
            && !err.contains("0x01"),
        "{err}"
    );
}

#[test]
fn console_numbers_out_of_range_are_refused_with_the_range() {
    let _turn = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (_master, path) = silent_port();
    for (cmd, needle) in [
        // `wait inf` quietly became 3600 s; NaN and 1e20 panicked.
        (
            "wait inf",
            "SECONDS must be a finite number in 0..=86400 s, got inf",
        ),
        (
            "wait NaN",
            "SECONDS must be a finite number in 0..=86400 s, got NaN",
        ),
        (
            "stream 1e20",
            "SECONDS must be a finite number in 0..=86400 s, got 1e20",
        ),
        ("target 0 1e30", "DEG must be a finite number in -25..=25"),
        ("target 2 0", "PLANE must be 0 (α) or 1 (β), got 2"),
        (
            "link-timeout 0",
            "MS must be a finite number in 1..=60000 ms",
        ),
        (
            "telemetry 5000",
            "HZ must be a finite number in 0..=1000 Hz",
        ),
    ] {
        let o = console(&path, &[cmd]);
        let err = common::stderr(&o);
        assert!(!o.status.success(), "{cmd}: {err}");
        assert!(err.contains(needle), "{cmd}: {err}");
        assert!(!err.contains("panicked"), "{cmd}: {err}");
    }
    // A command a megabyte long is quoted in part, not echoed whole.
    let dir = common::scratch("long_cmd");
    let script = common::file(&dir, "s.txt", &format!("status {}\n", "y".repeat(1 << 20)));
    let o = console(&path, &["--script", &script]);
    let err = common::stderr(&o);
    assert!(!o.status.success());
    assert!(err.len() < 2000, "{} bytes of stderr", err.len());
}

#[test]
fn hil_refuses_a_link_timeout_outside_the_boards_range_before_starting() {
    let o = common::softjoint(&["hil", "--link-timeout-ms", "0"]);
    let err = common::stderr(&o);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("--link-timeout-ms") && err.contains("1..=60000"),
        "{err}"
    );
    // --port runs no QEMU: an image or icount flag would be ignored.
    let o = common::softjoint(&["hil", "--port", "/dev/null", "--image", "x"]);
    let err = common::stderr(&o);
    assert!(
        !o.status.success() && err.contains("cannot be used with"),
        "{err}"
    );
}

#[test]
fn hil_names_a_missing_image_and_the_flag_to_give_one() {
    // (Where the default image is looked for is a unit test of
    // host_tools::board::qemu: beside the program first, not the working
    // directory.)
    let dir = common::scratch("hil_cwd");
    let missing = dir.join("nope.elf");
    let o = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .current_dir(&*dir)
        .args(["hil", "--image"])
        .arg(&missing)
        .output()
        .unwrap();
    let err = common::stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("--image") && err.contains("nope.elf"), "{err}");
}
