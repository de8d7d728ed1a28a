//! `softjoint hil` with the firmware image under QEMU, as a user runs it:
//! the STM32F4 board image through `--board stm32f4`, QEMU killed mid-run,
//! `hil` itself stopped by SIGTERM or killed, images QEMU cannot run. Each must end with the trace up to the last step, a
//! message that names what happened, and no QEMU left running.
//!
//! They need QEMU and the thumbv7em image, so they are ignored in a plain
//! `cargo test`; `scripts/test-all.sh` runs them with `--ignored`.
use crate::common;

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{file, s, scratch, stderr, stdout};

fn image() -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(host_tools::board::qemu::DEFAULT_IMAGE);
    assert!(
        p.exists(),
        "{} missing: run `{}`",
        p.display(),
        host_tools::board::qemu::BUILD_IMAGE
    );
    p
}

/// The default 3D scenario with the paper's laws (no calibration sweep to
/// wait for): 30 s, 30,000 lockstep steps.
const SCENARIO: &str = "[estimator]\nmethod = \"paper\"\n";

/// Processes whose parent is `pid` (from /proc/*/stat).
pub fn children(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(p) = e.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else {
            continue;
        };
        // pid (comm) state ppid …; comm may hold spaces, so split after ')'.
        let after = stat.rsplit_once(')').map_or("", |(_, a)| a);
        if after.split_whitespace().nth(1) == Some(&pid.to_string()) {
            out.push(p);
        }
    }
    out
}

/// Whether `pid` still runs (a zombie waiting for its reaper does not).
pub fn running(pid: u32) -> bool {
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        Ok(stat) => {
            let after = stat.rsplit_once(')').map_or("", |(_, a)| a);
            !matches!(after.split_whitespace().next(), Some("Z" | "X"))
        }
        Err(_) => false,
    }
}

fn wait_until(what: &str, limit: Duration, mut done: impl FnMut() -> bool) {
    let until = Instant::now() + limit;
    while !done() {
        assert!(Instant::now() < until, "{what}: not within {limit:?}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Starts `hil` with a CSV trace; returns it, its QEMU's pid and the CSV
/// path once the lockstep has written rows.
fn start_hil(dir: &Path) -> (Child, u32, PathBuf) {
    let scen = file(dir, "s.toml", SCENARIO);
    let csv = dir.join("trace.csv");
    let child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["hil", &scen, "--json", "--csv", s(&csv), "--image"])
        .arg(image())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut qemu = Vec::new();
    wait_until("QEMU started", Duration::from_secs(30), || {
        qemu = children(child.id());
        !qemu.is_empty()
    });
    wait_until("lockstep rows in the CSV", Duration::from_secs(60), || {
        std::fs::read_to_string(&csv).is_ok_and(|t| t.lines().count() > 100)
    });
    (child, qemu[0], csv)
}

/// The CSV's rows are exactly the steps run: `steps` complete rows whose
/// true angles and coil voltages are those of `softjoint sim` of the same
/// scenario (the lockstep reproduces the simulation exactly, see
/// tests/tests/qemu_hil.rs), step for step.
fn assert_rows_are_the_steps_run(csv: &Path, steps: u64) {
    assert_rows_are_the_steps_of(csv, SCENARIO, steps);
}

/// [`assert_rows_are_the_steps_run`] for the scenario `scenario_toml`.
fn assert_rows_are_the_steps_of(csv: &Path, scenario_toml: &str, steps: u64) {
    let text = std::fs::read_to_string(csv).unwrap();
    assert!(text.ends_with('\n'), "last row cut off");
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len() as u64, steps, "rows in the CSV vs steps run");
    let scenario: host_tools::files::scenario::Scenario = toml::from_str(scenario_toml).unwrap();
    let sim =
        host_tools::run::sim::run(&host_tools::run::spec::RunSpec::resolve(&scenario).unwrap())
            .unwrap();
    let angles = ["alpha".to_string(), "beta".to_string()];
    for (k, (got, want)) in rows.iter().zip(&sim.trace.rows).enumerate() {
        let mut line = String::new();
        host_tools::run::trace::push_csv_row(&mut line, csv, k as u64 + 2, &angles, want).unwrap();
        let want: Vec<&str> = line.trim_end().split(',').collect();
        let got: Vec<&str> = got.split(',').collect();
        assert_eq!(got.len(), 12, "row {k}");
        // t, α true, α desired, β true, β desired, v1..v4, faults; the
        // estimates travel in centidegrees and may differ in the last digit.
        for c in [0, 1, 3, 4, 6, 7, 8, 9, 10, 11] {
            assert_eq!(got[c], want[c], "row {k} column {c}");
        }
    }
}

/// `softjoint hil --board stm32f4` finds the STM32F4 image's QEMU flavour
/// by itself, runs it on netduinoplus2 and writes the trace of `softjoint
/// sim` (a 2 s scenario: 2,000 lockstep steps through the board's USART2).
#[test]
#[ignore = "needs qemu-system-arm and the STM32F4 image; run by scripts/test-all.sh"]
fn hil_board_stm32f4_runs_the_board_image_in_lockstep() {
    let dir = scratch("hil-stm32f4");
    let toml = format!("duration_s = 2.0\n{SCENARIO}");
    let scen = file(&dir, "s.toml", &toml);
    let csv = dir.join("trace.csv");
    let child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["hil", &scen, "--board", "stm32f4", "--json", "--csv"])
        .arg(&csv)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The QEMU it started runs the STM32F4 image on netduinoplus2.
    // (A child between fork and exec still has softjoint's command line.)
    let cmdline = |pid: u32| {
        let raw = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        String::from_utf8_lossy(&raw).replace('\0', " ")
    };
    let mut cmd = String::new();
    wait_until("QEMU started", Duration::from_secs(30), || {
        cmd = children(child.id())
            .into_iter()
            .map(cmdline)
            .find(|c| c.starts_with("qemu-system-arm"))
            .unwrap_or_default();
        !cmd.is_empty()
    });
    let cmdline = cmd;
    assert!(
        cmdline.contains("netduinoplus2") && cmdline.contains("softjoint-stm32f4-qemu"),
        "{cmdline}"
    );
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(summary["steps"].as_u64(), Some(2000), "{summary}");
    assert!(summary["cut_short"].is_null(), "{summary}");
    assert_rows_are_the_steps_of(&csv, &toml, 2000);
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn qemu_killed_mid_run_leaves_the_steps_run_and_names_its_signal() {
    let dir = scratch("hil-qemu-killed");
    let (child, qemu, csv) = start_hil(&dir);
    common::kill("-KILL", qemu);
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("run cut short at step"), "{err}");
    assert!(err.contains("killed by signal 9 (SIGKILL)"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    let summary: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    let steps = summary["steps"].as_u64().unwrap();
    assert!(steps > 100 && steps < 30_000, "{summary}");
    assert_eq!(summary["cut_short"]["cause"], "controller", "{summary}");
    assert_eq!(summary["trace"]["rows"].as_u64(), Some(steps));
    assert_rows_are_the_steps_run(&csv, steps);
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn sigterm_to_hil_leaves_no_qemu_behind() {
    let dir = scratch("hil-sigterm");
    let (child, qemu, csv) = start_hil(&dir);
    assert!(running(qemu));
    common::kill("-TERM", child.id());
    let out = child.wait_with_output().unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(143), "{err}");
    assert!(err.contains("stopped by SIGTERM"), "{err}");
    wait_until("QEMU gone after hil ended", Duration::from_secs(5), || {
        !running(qemu)
    });
    let summary: serde_json::Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_rows_are_the_steps_run(&csv, summary["steps"].as_u64().unwrap());
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn sigkill_and_sigint_to_hil_leave_no_qemu_behind() {
    for signal in ["-KILL", "-INT"] {
        let dir = scratch("hil-sigkill");
        let (mut child, qemu, _csv) = start_hil(&dir);
        common::kill(signal, child.id());
        let status = child.wait().unwrap();
        if signal == "-INT" {
            assert_eq!(status.code(), Some(130));
        }
        // SIGKILL runs no cleanup in hil: QEMU's parent-death signal ends it.
        wait_until(
            &format!("QEMU gone after kill {signal} of hil"),
            Duration::from_secs(5),
            || !running(qemu),
        );
    }
}

/// `hil --excite` stopped by SIGTERM, SIGINT (one Ctrl-C) or SIGHUP: the
/// session stops at a clean point, the board leaves lockstep, the log holds
/// its whole rows up to there, the exit status is the signal's and no QEMU
/// is left (it used to run to the plan's end on SIGTERM and on the first
/// Ctrl-C, exit 0).
#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn hil_excite_stopped_by_a_signal_keeps_its_log_and_leaves_no_qemu() {
    use crate::excite_stops::{assert_whole_log, wait_for_rows, HOUR_PLAN};
    for (signal, code, name) in [
        ("-TERM", 143, "SIGTERM"),
        ("-INT", 130, "SIGINT"),
        ("-HUP", 129, "SIGHUP"),
    ] {
        let dir = scratch("hil-excite-stop");
        let scen = file(&dir, "s.toml", SCENARIO);
        let plan = file(&dir, "plan.toml", HOUR_PLAN);
        let log = dir.join("log.csv");
        let mut child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
            .args(["hil", &scen, "--excite", &plan, "--log", s(&log)])
            .args(["--timeout-ms", "1000", "--image"])
            .arg(image())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut qemu = Vec::new();
        wait_until("QEMU started", Duration::from_secs(30), || {
            qemu = children(child.id());
            !qemu.is_empty()
        });
        // The header is written before QEMU starts; rows reach the file
        // at least once a second once the session runs (identify's reader
        // takes a log of at least 10 rows).
        wait_for_rows(&log, 12, &mut child);
        common::kill(signal, child.id());
        let out = child.wait_with_output().unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(code), "{signal}: {err}");
        assert!(err.contains(&format!("stopped by {name}")), "{err}");
        let rows: usize = err
            .split("holds its ")
            .nth(1)
            .and_then(|a| a.split_whitespace().next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{err}"));
        assert!(rows > 0, "{rows} rows: {err}");
        assert_whole_log(&log, rows);
        wait_until(
            "QEMU gone after hil --excite ended",
            Duration::from_secs(5),
            || !running(qemu[0]),
        );
    }
}

/// The real image with its reset and HardFault vectors zeroed: QEMU loads
/// it, the core faults at its first instruction, the fault escalates to a
/// lockup and QEMU aborts at once.
fn image_that_locks_up(dir: &Path) -> PathBuf {
    let mut elf = std::fs::read(image()).unwrap();
    let u32_at = |b: &[u8], o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap()) as usize;
    let u16_at =
        |b: &[u8], o: usize| usize::from(u16::from_le_bytes(b[o..o + 2].try_into().unwrap()));
    let (phoff, phentsize, phnum) = (u32_at(&elf, 0x1C), u16_at(&elf, 0x2A), u16_at(&elf, 0x2C));
    // The loadable segment at address 0 holds the vector table.
    let table = (0..phnum)
        .map(|k| phoff + k * phentsize)
        .find(|&ph| u32_at(&elf, ph) == 1 && u32_at(&elf, ph + 12) == 0)
        .map(|ph| u32_at(&elf, ph + 4))
        .expect("vector table segment");
    for entry in [1, 3] {
        elf[table + 4 * entry..table + 4 * entry + 4].fill(0);
    }
    let p = dir.join("lockup.elf");
    std::fs::write(&p, elf).unwrap();
    p
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn images_qemu_cannot_run_are_named() {
    let dir = scratch("hil-images");
    let not_elf = file(&dir, "notes.txt", "not firmware\n");
    let real = std::fs::read(image()).unwrap();
    let cut = dir.join("cut.elf");
    std::fs::write(&cut, &real[..3000]).unwrap();
    for (img, needle) in [
        (s(&dir).to_string(), "is a directory".to_string()),
        (not_elf, "is not an ELF file".to_string()),
        (s(&cut).to_string(), format!("{} is cut short", s(&cut))),
        // QEMU runs it and aborts: its exit and its own message are the
        // error, not the serial line's "broken pipe".
        (
            s(&image_that_locks_up(&dir)).to_string(),
            "qemu-system-arm was killed by signal 6 (SIGABRT); it said: qemu".to_string(),
        ),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_softjoint"))
            .args(["hil", "--image", &img])
            .output()
            .unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{img}: {err}");
        assert!(err.contains(&needle), "{img}: {err}");
        assert!(!err.contains("Broken pipe"), "{img}: {err}");
    }
}
