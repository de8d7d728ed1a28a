//! `softjoint conform`'s suite against both firmware images under QEMU —
//! the mps2-an386 image (`softjoint-fw`) and the STM32F4 image's QEMU
//! flavour on `netduinoplus2` — as a user runs it (`softjoint conform
//! --board …`): every check passes, and only the check that needs live
//! sensors is skipped (the QEMU boards have none, so a free-running board
//! latches sensor-stale and no open-loop drive can be shown, §7). The pty
//! board and the deliberately broken board are host-tools' `conform_suite`
//! tests.
//!
//! Ignored in a plain `cargo test`: they need QEMU and the images, which
//! `scripts/test-all.sh` installs and builds before running them with
//! `--ignored` (≈ 20 s each).
use std::path::PathBuf;

use host_tools::board::conform::{self, report, Options, Outcome};
use host_tools::board::link::Link;
use host_tools::board::qemu::{Qemu, QemuBoard};

fn conform_on(board: QemuBoard) {
    let image = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(board.default_image());
    assert!(
        image.exists(),
        "{} missing: run `{}`",
        image.display(),
        board.build_command()
    );
    // As `softjoint conform --board …` starts it: fresh from reset, its
    // clock following wall time (no -icount), as a real board's.
    let mut qemu = Qemu::launch(board, &image, false).expect("qemu");
    let mut link = Link::new(qemu.connect().expect("QEMU's serial socket"));
    let opts = Options {
        safe: false,
        fresh: true,
    };
    let r = conform::run(&mut link, &image.display().to_string(), opts);
    assert!(
        qemu.ended(std::time::Duration::ZERO).is_none(),
        "the emulated board ended during the suite"
    );
    assert!(r.ok(), "{}", report::text(&r));
    let skipped: Vec<&str> = r
        .checks
        .iter()
        .filter(|c| matches!(c.outcome, Outcome::Skip(_)))
        .map(|c| c.id)
        .collect();
    assert_eq!(skipped, ["drive.hold"], "{}", report::text(&r));
    assert_eq!(r.passed, r.checks.len() - 1);
}

#[test]
#[ignore = "needs qemu-system-arm and the mps2-an386 image (scripts/test-all.sh)"]
fn conform_passes_on_the_mps2_an386_image() {
    conform_on(QemuBoard::Mps2An386);
}

#[test]
#[ignore = "needs qemu-system-arm and the STM32F4 QEMU image (scripts/test-all.sh)"]
fn conform_passes_on_the_stm32f4_image_on_netduinoplus2() {
    conform_on(QemuBoard::Stm32f4);
}
