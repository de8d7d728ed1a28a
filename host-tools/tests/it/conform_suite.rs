//! `softjoint conform` against the pty board: the board application
//! passes every check, and a deliberately broken board — each seeded
//! protocol fault of `host_tools::board::seeded` alone — fails the check
//! named for it (and nothing passes that should not). The CLI's reports:
//! JSON, JUnit XML, `--safe`, and the exit status. The same suite against
//! both QEMU images is in `tests/tests/it/qemu_hil.rs`.
use crate::common;

use host_tools::board::conform::{self, report, Options, Outcome, Report};
use host_tools::board::link::Link;
use host_tools::board::pty::PtyBoard;
use host_tools::board::seeded::SeededFault;
use plant_joint::{Joint3d, Joint3dParams};

fn suite(faults: &[SeededFault], opts: Options) -> Report {
    let plant = Joint3d::new(Joint3dParams::default()).expect("default plant");
    let (_board, host) = PtyBoard::start_seeded(Some(plant), faults).expect("pty pair");
    let mut link = Link::new(host);
    conform::run(&mut link, "the pty board", opts)
}

fn failed(r: &Report) -> Vec<&'static str> {
    r.checks
        .iter()
        .filter(|c| matches!(c.outcome, Outcome::Fail(_)))
        .map(|c| c.id)
        .collect()
}

/// The check each seeded fault must fail.
fn caught_by(f: SeededFault) -> &'static str {
    match f {
        SeededFault::WrongSchema => "handshake.hello",
        SeededFault::NakCrcErrors => "framing.crc-error",
        SeededFault::AnswerStaleSeqs => "lockstep.stale-seq",
        SeededFault::NoLinkWatchdog => "lockstep.link-loss",
        SeededFault::AckDisarmedDrive => "drive.refusals",
        SeededFault::DoubleTelemetry => "telemetry.rate",
        SeededFault::WrappingCounters => "counters.saturate",
    }
}

const FRESH: Options = Options {
    safe: false,
    fresh: true,
};

#[test]
fn the_pty_board_passes_every_check() {
    let r = suite(&[], FRESH);
    assert!(r.ok(), "{}", report::text(&r));
    // A plant-backed board has sensors: nothing is skipped.
    assert_eq!(
        (r.passed, r.skipped),
        (r.checks.len(), 0),
        "{}",
        report::text(&r)
    );
    // Every check cites a section of the page, and the page has it.
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md"))
        .unwrap();
    for c in &r.checks {
        let section = c.section.split([',', ' ']).next().unwrap();
        let top = section.trim_start_matches('§').split('.').next().unwrap();
        assert!(
            page.contains(&format!("\n## {top}. ")),
            "{} cites {section}, which docs/protocol.md does not have",
            c.id
        );
    }
}

#[test]
fn safe_mode_passes_without_asking_for_current() {
    // The suite watches every reply in safe mode and fails the check that
    // saw a coil input above 1.7 V (§8.4); a plant-backed board moves, so
    // arming it under the default law (1.7 V offset) would be caught.
    let r = suite(
        &[],
        Options {
            safe: true,
            fresh: true,
        },
    );
    assert!(r.ok(), "{}", report::text(&r));
    let skipped: Vec<&str> = r
        .checks
        .iter()
        .filter(|c| matches!(c.outcome, Outcome::Skip(_)))
        .map(|c| c.id)
        .collect();
    assert_eq!(skipped, ["thermal.trip"], "{}", report::text(&r));
}

#[test]
fn every_seeded_fault_is_caught_by_its_named_check() {
    let reports: Vec<(SeededFault, Report)> = std::thread::scope(|scope| {
        let runs: Vec<_> = SeededFault::ALL
            .iter()
            .map(|&f| scope.spawn(move || (f, suite(&[f], FRESH))))
            .collect();
        runs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for (fault, r) in &reports {
        let failed = failed(r);
        assert!(
            failed.contains(&caught_by(*fault)),
            "seeded {}: {} did not fail\n{}",
            fault.name(),
            caught_by(*fault),
            report::text(r)
        );
        assert!(!r.ok());
    }
}

#[test]
fn the_cli_reports_as_json_and_junit_and_exits_non_zero_on_a_failure() {
    let dir = common::scratch("conform");
    let xml = dir.join("conform.xml");
    let o = common::softjoint(&[
        "conform",
        "--pty-board",
        "--seed-fault",
        "wrong-schema",
        "--safe",
        "--json",
        "--junit",
        xml.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    assert!(
        common::stderr(&o).contains("1 of 22 checks failed"),
        "{}",
        common::stderr(&o)
    );
    let json: serde_json::Value = serde_json::from_str(&common::stdout(&o)).unwrap();
    assert_eq!(json["failed"], 1);
    assert_eq!(json["safe"], true);
    let checks = json["checks"].as_array().unwrap();
    let by_id = |id: &str| checks.iter().find(|c| c["id"] == id).unwrap().clone();
    assert_eq!(by_id("handshake.hello")["outcome"], "fail");
    // Safe mode skips the check that heats a coil to its trip level, and
    // says why.
    let thermal = by_id("thermal.trip");
    assert_eq!(thermal["outcome"], "skip");
    assert!(thermal["detail"].as_str().unwrap().contains("--safe"));
    let junit = std::fs::read_to_string(&xml).unwrap();
    assert!(
        junit.contains("tests=\"22\" failures=\"1\" errors=\"0\" skipped=\"1\""),
        "{junit}"
    );
    assert_eq!(junit.matches("<testcase ").count(), 22);
    assert!(junit.contains("name=\"handshake.hello\"") && junit.contains("<failure message="));
}

/// The page's "Physical layer" (§1) tells a user how to build and start
/// each QEMU image; it must say what the tools do: the build command, the
/// image's path and the machine's serial ports.
#[test]
fn the_protocol_page_builds_and_starts_each_qemu_image_as_the_tools_do() {
    use host_tools::board::qemu::QemuBoard;
    let page = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md"))
        .unwrap();
    // The page wraps long commands with `\` and indents the rest.
    let flat = page
        .replace("\\\n", " ")
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ");
    for board in [QemuBoard::Mps2An386, QemuBoard::Stm32f4] {
        let build = board.build_command();
        let build = build.split(" --bin ").next().unwrap();
        assert!(flat.contains(build), "the page lacks `{build}`");
        assert!(
            flat.contains(&format!("-kernel {}", board.default_image())),
            "the page does not start {}",
            board.default_image()
        );
        let machine = board.machine_args().join(" ");
        assert!(flat.contains(&machine), "the page lacks `{machine}`");
    }
}
