//! `softjoint conform`: the protocol conformance suite against a board.
use std::path::PathBuf;

use anyhow::bail;
use clap::Args;
use host_tools::board::conform::{self, report, Options};
use host_tools::board::link::{open_port, Link};
use host_tools::board::pty::PtyBoard;
use host_tools::board::qemu::{Qemu, QemuBoard};
use host_tools::board::seeded::SeededFault;
use host_tools::{out, output};

#[derive(Args)]
pub struct ConformArgs {
    /// The board's serial device, or `unix:PATH` (a QEMU serial socket);
    /// without it (and without --pty-board) the suite starts QEMU with
    /// --board's image.
    #[arg(long, conflicts_with_all = ["board", "image", "pty_board"])]
    port: Option<String>,
    /// Baud rate for --port.
    #[arg(
        allow_negative_numbers = true,
        long,
        default_value_t = 115_200,
        requires = "port"
    )]
    baud: u32,
    /// The image QEMU runs: mps2-an386 (`softjoint-fw`) or stm32f4 (the
    /// STM32F4 image's QEMU flavour on netduinoplus2).
    #[arg(long, value_enum, default_value_t = QemuBoard::Mps2An386)]
    board: QemuBoard,
    /// Firmware image for QEMU [default: --board's image in the
    /// workspace's target/thumbv7em-none-eabihf/release/].
    #[arg(long)]
    image: Option<PathBuf>,
    /// The pty board: the firmware's board application on a
    /// pseudo-terminal in this process, wired to a simulated joint.
    #[arg(long, conflicts_with_all = ["board", "image"])]
    pty_board: bool,
    /// Break the pty board on purpose (repeatable), to see the suite's
    /// checks fail: each seeded fault must be caught by a named check.
    #[arg(long, value_enum, requires = "pty_board")]
    seed_fault: Vec<SeededFault>,
    /// For a board with real coils: never ask for a coil input that
    /// passes current (docs/protocol.md §8.4), skip the thermal trip.
    #[arg(long)]
    safe: bool,
    /// The board on --port was just reset: check its boot state too
    /// (always checked on a board the suite starts).
    #[arg(long, requires = "port")]
    fresh: bool,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Also write the report as JUnit XML to this file.
    #[arg(long)]
    junit: Option<PathBuf>,
}

/// Runs `conform`: exits non-zero if any check failed.
pub fn run(args: ConformArgs) -> anyhow::Result<()> {
    if let Some(path) = &args.junit {
        // Refuse an unwritable place before minutes of checks.
        output::AtomicFile::create(path)?;
    }
    let opts = Options {
        safe: args.safe,
        fresh: args.fresh || args.port.is_none(),
    };
    let report = if let Some(port) = &args.port {
        let mut link = Link::new(open_port(port, args.baud)?);
        conform::run(&mut link, port, opts)
    } else if args.pty_board {
        let plant = plant_joint::Joint3d::new(plant_joint::Joint3dParams::default())?;
        let (_board, host) = PtyBoard::start_seeded(Some(plant), &args.seed_fault)?;
        let mut link = Link::new(host);
        let name = if args.seed_fault.is_empty() {
            "the pty board".to_string()
        } else {
            let names: Vec<&str> = args.seed_fault.iter().map(|f| f.name()).collect();
            format!("the pty board with seeded faults {}", names.join(", "))
        };
        conform::run(&mut link, &name, opts)
    } else {
        let image = match &args.image {
            Some(i) => i.clone(),
            None => host_tools::board::qemu::default_image(args.board)?,
        };
        // Without -icount: the board's clock then follows wall time, as a
        // real board's does, and QEMU's UART reads several times faster
        // (the counter check sends 128 KiB).
        let mut q = Qemu::launch(args.board, &image, false)?;
        let mut link = Link::new(q.connect()?);
        let name = format!(
            "{} under QEMU ({})",
            image.display(),
            board_name(args.board)
        );
        let r = conform::run(&mut link, &name, opts);
        if let Some(how) = q.ended(std::time::Duration::ZERO) {
            bail!("the emulated board ended during the suite: {how}");
        }
        r
    };
    if let Some(path) = &args.junit {
        output::write_svg(path, &report::junit(&report))?;
    }
    if args.json {
        output::print_json(&report)?;
    } else {
        out!("{}", report::text(&report));
    }
    if report.ok() {
        Ok(())
    } else {
        bail!(
            "{} of {} checks failed against {}",
            report.failed,
            report.checks.len(),
            report.board
        )
    }
}

fn board_name(b: QemuBoard) -> &'static str {
    match b {
        QemuBoard::Mps2An386 => "mps2-an386",
        QemuBoard::Stm32f4 => "netduinoplus2",
    }
}
