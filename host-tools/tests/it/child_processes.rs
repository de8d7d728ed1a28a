//! Processes a command starts die with it (issue 31, item 2): `tetmsd
//! pair` orphaned both site processes on TERM, INT, KILL or HUP (they ran
//! on under PID 1) and left `/tmp/softjoint-tetmsd-PID.toml` behind. The
//! signals go to the `pair` process this test started, never to the
//! test's own process group.
use crate::common;
use crate::hil_qemu_cli::{children, running};

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{s, scratch};

fn wait_until(what: &str, limit: Duration, mut done: impl FnMut() -> bool) {
    let until = Instant::now() + limit;
    while !done() {
        assert!(Instant::now() < until, "{what}: not within {limit:?}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn tetmsd_pair_sites_die_with_it_and_leave_no_scenario_file() {
    for signal in ["-TERM", "-INT", "-HUP", "-KILL"] {
        let dir = scratch("tetmsd-orphans");
        let mut pair = Command::new(env!("CARGO_BIN_EXE_softjoint"))
            .args(["tetmsd", "pair", "--level", "3", "--duration-s", "60"])
            .args(["--out-dir", s(&dir)])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let temp = std::env::temp_dir().join(format!("softjoint-tetmsd-{}.toml", pair.id()));
        let mut sites = Vec::new();
        wait_until("both sites started", Duration::from_secs(30), || {
            sites = children(pair.id());
            sites.len() == 2
        });
        // Both sites report their port once they have read the scenario;
        // then the file goes.
        wait_until("the scenario file removed", Duration::from_secs(30), || {
            !temp.exists()
        });
        assert!(
            sites.iter().all(|p| running(*p)),
            "{signal}: a site ended early"
        );
        common::kill(signal, pair.id());
        let status = pair.wait().unwrap();
        // INT, TERM and HUP end it through its handler (also when it was
        // started with SIGINT ignored, as a background job is) with the
        // signal's status; KILL is a kill.
        let want = match signal {
            "-INT" => Some(130),
            "-TERM" => Some(143),
            "-HUP" => Some(129),
            _ => None,
        };
        assert_eq!(status.code(), want, "{signal}: {status}");
        wait_until(
            &format!("sites gone after kill {signal} of pair"),
            Duration::from_secs(5),
            || sites.iter().all(|p| !running(*p)),
        );
        assert!(!temp.exists(), "{signal}: {} left", temp.display());
    }
}
