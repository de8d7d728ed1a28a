//! The real thumbv7em firmware images under QEMU, in lockstep with the
//! simulated joint over QEMU's serial socket: the mps2-an386 image (`softjoint-fw`)
//! and the STM32F4 board image in its QEMU flavour on `netduinoplus2`
//! (`softjoint-stm32f4-qemu`: the Nucleo-F446RE image without clock setup
//! and timer I/O).
//!
//! These need QEMU and the images, so they are ignored in a plain
//! `cargo test`; `scripts/test-all.sh` installs QEMU, builds the images and
//! runs them with `--ignored`.
use std::path::PathBuf;
use std::time::Duration;

use firmware::protocol::{HilSensor, Message};
use firmware::supervisor::Faults;
use host_tools::board::hil::{self, HilOptions};
use host_tools::board::link::{HostLinkStats, Link, SerialDevice};
use host_tools::board::qemu::{Qemu, QemuBoard};
use host_tools::files::scenario::{Scenario, TargetStep};
use host_tools::run::record::Trace;
use host_tools::run::sim;
use host_tools::run::spec::RunSpec;

fn image(board: QemuBoard) -> PathBuf {
    // Tests run in the crate directory; the images are under the workspace.
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(board.default_image());
    assert!(
        p.exists(),
        "{} missing: run `{}`",
        p.display(),
        board.build_command()
    );
    p
}

/// QEMU running `board`'s image, and a link to the image once it has
/// answered a handshake.
///
/// The handshake may need retries while the image boots: bytes that reach
/// the STM32F4's USART before the image has enabled its receiver are
/// dropped, as on silicon (QEMU's USART model drops them too; the
/// mps2-an386 UART holds them back instead). A loaded host connects, sends
/// `Hello` and then waits while the image is still starting, so the first
/// `Hello` can vanish without a trace (CI, stop 36: `frames_received`
/// 30 016 of 30 017, the board's count short by the same frame). That is
/// what the handshake's retries are for; what the tests below count is the
/// link from then on. The board counts such a boot frame too: a `Hello`
/// whose first bytes were dropped reaches its decoder as a bad COBS frame
/// (CI, stop 48: one host retry at boot, the board's `cobs_errors` 1 at the
/// end of a clean run), so [`board_at_boot`] reads the board's counters once
/// booted, and the tests count from there on both sides of the link.
fn launch(board: QemuBoard, icount: bool) -> (Qemu, Link<SerialDevice>) {
    let mut qemu = Qemu::launch(board, &image(board), icount).expect("qemu");
    let mut link = Link::new(qemu.connect().expect("QEMU's serial socket"));
    if let Err(e) = host_tools::board::controller::handshake(&mut link) {
        panic!(
            "{board:?}: no handshake: {e:#}; QEMU printed {:?}",
            qemu.output()
        );
    }
    (qemu, link)
}

/// The booted board's own link counters (frames it dropped as corrupt
/// while it started), read with a status request.
fn board_at_boot(link: &mut Link<SerialDevice>) -> BoardCounters {
    let s = host_tools::board::controller::status(link).expect("the booted board's status");
    BoardCounters {
        crc_errors: s.crc_errors,
        cobs_errors: s.cobs_errors,
    }
}

/// The board's counters of corrupt frames.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct BoardCounters {
    crc_errors: u16,
    cobs_errors: u16,
}

/// The board's corrupt-frame counters at the end of `report`'s run less
/// those at `boot`: what the board dropped during the run.
fn board_since(report: &hil::HilReport, boot: BoardCounters) -> BoardCounters {
    assert!(report.board_counters_read, "the board's counters were read");
    let since = |end: u16, start: u16| {
        end.checked_sub(start).unwrap_or_else(|| {
            panic!(
                "the board's counters went back ({start} at boot, {end} at the end): it restarted ({} restarts)",
                report.board_restarts
            )
        })
    };
    BoardCounters {
        crc_errors: since(report.board_crc_errors, boot.crc_errors),
        cobs_errors: since(report.board_cobs_errors, boot.cobs_errors),
    }
}

/// `after` less `before`, counter by counter: what the link did in between.
fn link_since(after: HostLinkStats, before: HostLinkStats) -> HostLinkStats {
    HostLinkStats {
        frames_sent: after.frames_sent - before.frames_sent,
        frames_received: after.frames_received - before.frames_received,
        retries: after.retries - before.retries,
        crc_errors: after.crc_errors - before.crc_errors,
        cobs_errors: after.cobs_errors - before.cobs_errors,
        overfull: after.overfull - before.overfull,
        malformed: after.malformed - before.malformed,
        unexpected: after.unexpected - before.unexpected,
        telemetry_dropped: after.telemetry_dropped - before.telemetry_dropped,
    }
}

fn short_default() -> Scenario {
    Scenario {
        name: "short 3D default".into(),
        duration_s: 6.0,
        targets: vec![
            TargetStep {
                t_s: 0.0,
                deg: vec![0.0, 0.0],
            },
            TargetStep {
                t_s: 1.0,
                deg: vec![5.0, 5.0],
            },
            TargetStep {
                t_s: 3.5,
                deg: vec![10.0, 10.0],
            },
        ],
        ..Scenario::default()
    }
}

/// Same control core, same inputs, same plant: the lockstep trace `got` is
/// `expected` (the simulation's) step for step, trajectory, outputs and
/// faults alike. Estimates travel in centidegrees (±0.005°), rounded in f32
/// (≈ 1e-6 at 10°), hence 1e-5 of slack on top.
fn assert_same_trajectory(got: &Trace, expected: &Trace) {
    assert_eq!(got.rows.len(), expected.rows.len());
    for (k, (h, e)) in got.rows.iter().zip(&expected.rows).enumerate() {
        assert_eq!(h.true_deg, e.true_deg, "true angles differ at step {k}");
        assert_eq!(
            h.coil_volts, e.coil_volts,
            "coil voltages differ at step {k}"
        );
        assert_eq!(h.faults, e.faults, "faults differ at step {k}");
        for p in 0..2 {
            assert!(
                (h.estimate_deg[p] - e.estimate_deg[p]).abs() <= 0.005 + 1e-5,
                "estimate {p} at step {k}: {} vs {}",
                h.estimate_deg[p],
                e.estimate_deg[p]
            );
        }
    }
}

/// `scenario` through `board`'s image gives the trajectory of
/// `softjoint sim`.
fn lockstep_reproduces_the_simulation(board: QemuBoard, scenario: Scenario) {
    let s = RunSpec::resolve(&scenario).expect("the scenario resolves");
    let expected = sim::run(&s).expect("sim");
    let (mut qemu, mut link) = launch(board, true);
    let board_booted = board_at_boot(&mut link);
    let booted = link.stats();
    // What is compared is the control, not the link watchdog (the dead-link
    // tests check that): a link timeout of 10 s of the board's clock keeps
    // a host stalled on a loaded machine from latching link loss mid-run.
    // Likewise the host's reply timeout: at the CLI's 100 ms, a host
    // stalled that long once in 30 000 round trips re-sends a frame (two
    // cores with three busy processes beside the run: 3 retries and 3 late
    // replies in one run here), which says how loaded the host was, not
    // how the link behaves. At 2 s a retry means a frame the image lost or
    // never answered, and fails.
    let opts = HilOptions {
        link_timeout_ms: Some(10_000),
        timeout: Duration::from_secs(2),
        ..HilOptions::default()
    };
    let got = match hil::run(&s, &mut link, opts) {
        Ok(got) => got,
        Err(e) => panic!(
            "hil run: {e:#}; QEMU still running: {}; it printed: {:?}",
            qemu.is_running(),
            qemu.output()
        ),
    };
    assert_same_trajectory(&got.trace, &expected.trace);
    // The run did something: the joint reached its targets.
    assert!(
        got.report
            .summary
            .steady_state_error_deg
            .iter()
            .all(|e| *e < 0.5),
        "{:?}",
        got.report.summary
    );
    println!(
        "{board:?} lockstep: {:.0} steps/s, {:?}",
        got.report.lockstep_steps_per_s, got.report.link
    );
    // From the booted board on, every frame answered once, at the first
    // try, and nothing corrupted either way; all counters are printed
    // whichever fails.
    let l = link_since(got.report.link, booted);
    let r = &got.report;
    let b = board_since(&got.report, board_booted);
    let seen = format!(
        "{l:?} (boot: {booted:?}); board: at boot {board_booted:?}, frames ok {}, crc {}, cobs {}, overfull {}, malformed {}, stale seqs {}, restarts {}",
        r.board_frames_ok,
        r.board_crc_errors,
        r.board_cobs_errors,
        r.board_overfull,
        r.board_malformed,
        r.board_stale_seqs,
        r.board_restarts
    );
    assert_eq!((l.retries, l.unexpected), (0, 0), "{seen}");
    assert_eq!(l.frames_received, l.frames_sent, "{seen}");
    assert_eq!(
        (b.crc_errors, b.cobs_errors, l.crc_errors, l.cobs_errors),
        (0, 0, 0, 0),
        "{seen}"
    );
}

/// The main job in full: the built-in default scenario (30 s, 30 000
/// lockstep steps) through the mps2-an386 image.
#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn image_in_lockstep_reproduces_the_simulation() {
    lockstep_reproduces_the_simulation(QemuBoard::Mps2An386, Scenario::default());
}

/// The STM32F4 image runs the same application and protocol as the
/// mps2-an386 image, which the test above holds to the main job in full;
/// what is its own is the board layer (USART2's receive interrupt and
/// queue, WFI between SysTicks), which every one of 6 000 round trips of
/// the short default (both planes stepped twice) goes through. The full
/// 30 s took 40 s of QEMU's CPU per CI run for no path the short run does
/// not take. By hand: `softjoint hil --board stm32f4` prints `softjoint
/// sim`'s table but for the maximum estimation error (the estimates
/// travel in centidegrees).
#[test]
#[ignore = "needs qemu-system-arm and the STM32F4 image; run by scripts/test-all.sh"]
fn stm32f4_image_in_lockstep_reproduces_the_simulation() {
    lockstep_reproduces_the_simulation(QemuBoard::Stm32f4, short_default());
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn lost_frames_are_retried_through_qemu() {
    lost_frames_are_retried(QemuBoard::Mps2An386);
}

#[test]
#[ignore = "needs qemu-system-arm and the STM32F4 image; run by scripts/test-all.sh"]
fn lost_frames_are_retried_through_the_stm32f4_image() {
    lost_frames_are_retried(QemuBoard::Stm32f4);
}

/// Lost sensor frames are re-sent with the same seq and answered once, and
/// the run is the simulation's all the same.
fn lost_frames_are_retried(board: QemuBoard) {
    let s = RunSpec::resolve(&Scenario {
        duration_s: 1.5,
        ..short_default()
    })
    .expect("resolves");
    let expected = sim::run(&s).expect("sim");
    let (_qemu, mut link) = launch(board, true);
    let board_booted = board_at_boot(&mut link);
    let booted = link.stats();
    let opts = HilOptions {
        lose_every: Some(100),
        // Generous against a loaded host, as in the lockstep comparison:
        // what is checked is the retry, not the link watchdog.
        link_timeout_ms: Some(10_000),
        timeout: Duration::from_millis(200),
        ..HilOptions::default()
    };
    let got = hil::run(&s, &mut link, opts).expect("hil run with losses");
    // Each of the 15 lost frames (1500 steps / 100) costs at least one
    // retry; a loaded host can add a few more (a reply later than 200 ms).
    let l = link_since(got.report.link, booted);
    assert!(l.retries >= 15, "{l:?}");
    // 15 frames were never written; every written frame is answered once.
    // A reply still in flight when the run ends can only belong to a
    // retry beyond the 15 (a late reply re-requested).
    let written = l.frames_sent - 15;
    assert!(
        l.frames_received <= written && l.frames_received + (l.retries - 15) >= written,
        "{l:?}"
    );
    let b = board_since(&got.report, board_booted);
    assert_eq!((l.crc_errors, b.crc_errors), (0, 0), "{l:?}; board {b:?}");
    assert!(
        got.report.summary.faults_seen.is_empty(),
        "{:?}",
        got.report.summary.faults_seen
    );
    // A retried step is answered from the board's cache, not stepped again:
    // the trajectory is the simulation's.
    assert_same_trajectory(&got.trace, &expected.trace);
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn dead_link_zeroes_the_image_outputs() {
    dead_link_zeroes_the_outputs(QemuBoard::Mps2An386);
}

#[test]
#[ignore = "needs qemu-system-arm and the STM32F4 image; run by scripts/test-all.sh"]
fn dead_link_zeroes_the_stm32f4_image_outputs() {
    dead_link_zeroes_the_outputs(QemuBoard::Stm32f4);
}

/// The board's own link watchdog: a host that stops talking in lockstep
/// leaves the outputs at zero and link loss latched.
fn dead_link_zeroes_the_outputs(board: QemuBoard) {
    // Without -icount the guest clock follows the host's; a link timeout of
    // 500 ms (not the board's 50 ms default) keeps a loaded host's pause
    // between the steps below from being taken for a dead link.
    const LINK_TIMEOUT_MS: u16 = 500;
    let (_qemu, mut link) = launch(board, false);
    let t = Duration::from_millis(300);
    integration_tests::start_lockstep(&mut link, Some(LINK_TIMEOUT_MS), 10.0, t);
    let mut last = None;
    for seq in 0..10u16 {
        let r = link
            .request(
                &HilSensor {
                    seq,
                    counts: [0, 0, -6, -2],
                }
                .into(),
                t,
                5,
                |m| matches!(m, Message::HilActuator(_)),
            )
            .unwrap();
        last = Some(r);
    }
    match last {
        Some(Message::HilActuator(a)) => {
            assert!(a.pair_mv[0] > 0, "driving before the link dies: {a:?}")
        }
        other => panic!("{other:?}"),
    }
    // The host goes silent. The board's clock, not the host's, is the
    // judge: on a loaded host QEMU can run the guest's clock slower than
    // wall time (timer ticks it was too late for are merged), so the test
    // waits in rounds of 3 s and asks for the status (a frame, which feeds
    // the watchdog again) after each. A round in which the board's own
    // clock advanced by more than 4 × the link timeout without link loss
    // latched is a failure; a shorter one (a starved QEMU) is waited out.
    let mut before = hil::status(&mut link).unwrap().time_ms;
    for _round in 0..8 {
        std::thread::sleep(Duration::from_millis(3000));
        let s = hil::status(&mut link).unwrap();
        if Faults::from_bits(u16::from(s.latched)).contains(Faults::LINK_LOSS) {
            assert_eq!(s.pair_mv, [0, 0], "outputs zero after link loss");
            return;
        }
        let silent_ms = s.time_ms.wrapping_sub(before);
        assert!(
            silent_ms <= 4 * u32::from(LINK_TIMEOUT_MS),
            "{silent_ms} ms of the board's clock without a frame and no link loss: {s:?}"
        );
        before = s.time_ms;
    }
    panic!("the board's clock did not advance by the link timeout in 8 rounds of 3 s");
}

/// The images take the open-loop `Drive` of protocol v3 and refuse it by
/// name as the board application does: disarmed, with a fault latched
/// (QEMU has no sensors: sensor-stale latches 50 ms after boot) and in
/// lockstep.
fn images_refuse_drive_by_name(board: QemuBoard) {
    use firmware::protocol::{Arm, ClearFaults, Disarm, Drive, ErrorCode, HilStart, HilStop};
    use host_tools::board::controller::{handshake, CMD_ATTEMPTS, CMD_TIMEOUT};
    use host_tools::board::link::LinkError;
    let (_qemu, mut link) = launch(board, true);
    handshake(&mut link).expect("handshake");
    let drive: Message = Drive {
        planes: 1,
        coil_mv: [3000, 0, 1900, 0],
        hold_ms: 100,
    }
    .into();
    let refused =
        |link: &mut Link<SerialDevice>| match link.command(&drive, CMD_TIMEOUT, CMD_ATTEMPTS) {
            Err(LinkError::Refused { code, .. }) => code,
            other => panic!("{board:?}: Drive not refused: {other:?}"),
        };
    let cmd = |link: &mut Link<SerialDevice>, m: Message| {
        link.command(&m, CMD_TIMEOUT, CMD_ATTEMPTS).unwrap()
    };
    cmd(&mut link, Disarm {}.into());
    assert_eq!(refused(&mut link), ErrorCode::Disarmed, "{board:?}");
    cmd(&mut link, Arm {}.into());
    // Sensor-stale latches 50 ms of the *board's* clock after boot; under
    // -icount on a loaded host that can take longer than 50 ms of wall
    // time, so wait for the board to say so (at most 10 s).
    let mut latched = false;
    for _ in 0..100 {
        if hil::status(&mut link).unwrap().latched != 0 {
            latched = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    assert!(
        latched,
        "{board:?}: no fault latched after 10 s without sensors"
    );
    assert_eq!(refused(&mut link), ErrorCode::Latched, "{board:?}");
    cmd(&mut link, HilStart { period_us: 1000 }.into());
    cmd(&mut link, ClearFaults {}.into());
    assert_eq!(refused(&mut link), ErrorCode::WrongMode, "{board:?}");
    cmd(&mut link, HilStop {}.into());
    cmd(&mut link, Disarm {}.into());
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn the_image_refuses_drive_by_name() {
    images_refuse_drive_by_name(QemuBoard::Mps2An386);
}

#[test]
#[ignore = "needs qemu-system-arm and the STM32F4 image; run by scripts/test-all.sh"]
fn the_stm32f4_image_refuses_drive_by_name() {
    images_refuse_drive_by_name(QemuBoard::Stm32f4);
}
