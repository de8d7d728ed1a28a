//! `softjoint hil` and `softjoint console`: the serial-line subcommands.
use std::path::PathBuf;
use std::time::Duration;

use anyhow::bail;
use clap::Args;
use host_tools::board::controller::name_the_board;
use host_tools::board::hil::{self, HilOptions};
use host_tools::board::link::{open_port, Link};
use host_tools::board::qemu::{Qemu, QemuBoard};
use host_tools::files::scenario::Scenario;
use host_tools::output;
use host_tools::run::joint::JointSpec;
use host_tools::run::report;
use host_tools::run::spec::RunSpec;
use host_tools::stop::Stop;
use host_tools::{out, outln};

#[derive(Args)]
pub struct HilArgs {
    /// Scenario file (TOML); without it the built-in 3D default runs.
    scenario: Option<PathBuf>,
    /// A real board's serial device; without it the firmware image runs
    /// under QEMU (its UART on a Unix socket).
    #[arg(long, conflicts_with_all = ["board", "image", "no_icount"])]
    port: Option<String>,
    /// Baud rate for --port.
    #[arg(
        allow_negative_numbers = true,
        long,
        default_value_t = 115_200,
        requires = "port"
    )]
    baud: u32,
    /// The board image QEMU runs: mps2-an386 (`softjoint-fw`) or stm32f4
    /// (the STM32F4 board image's QEMU flavour on netduinoplus2).
    #[arg(long, value_enum, default_value_t = QemuBoard::Mps2An386)]
    board: QemuBoard,
    /// Firmware image for QEMU [default: the board's image in the
    /// workspace's target/thumbv7em-none-eabihf/release/ (softjoint-fw,
    /// softjoint-stm32f4-qemu), found from the softjoint program's own
    /// location].
    #[arg(long)]
    image: Option<PathBuf>,
    /// Run QEMU without `-icount shift=0`. By default the guest's clock
    /// advances with executed instructions (1 ns each), so host scheduling
    /// cannot make the board's link watchdog see time jump; without it
    /// QEMU's clock follows the host's and catches up in bursts.
    #[arg(long)]
    no_icount: bool,
    /// Reply timeout per attempt (ms).
    #[arg(allow_negative_numbers = true, long, default_value_t = 100, value_parser = clap::value_parser!(u64).range(1..=60_000))]
    timeout_ms: u64,
    /// Fault injection: lose the first copy of every Nth sensor frame.
    #[arg(allow_negative_numbers = true, long)]
    lose_every: Option<u32>,
    /// Link-loss timeout to set on the board (ms of its clock)
    /// [default: 250 on a port; 1000 under QEMU, either image]. The
    /// board's built-in default is 50 ms; an emulated board's clock
    /// depends on host scheduling, so a loaded host needs more slack than
    /// a real board does.
    #[arg(allow_negative_numbers = true, long, value_parser = link_timeout_ms)]
    link_timeout_ms: Option<u16>,
    /// A board that restarts during the run is set up again and the run
    /// goes on (its controller state starts afresh); without this flag the
    /// run ends there, naming the restart.
    #[arg(long)]
    resume_after_restart: bool,
    #[command(flatten)]
    output: report::OutputArgs,
    #[command(flatten)]
    excite: crate::commands::sim::ExciteArgs,
}

/// The board's link-timeout range, checked before a board is involved.
fn link_timeout_ms(text: &str) -> Result<u16, String> {
    let range = firmware::app::LINK_TIMEOUT_MS;
    text.parse::<u16>()
        .ok()
        .filter(|v| range.contains(v))
        .ok_or_else(|| {
            format!(
                "must be a whole number of milliseconds in {}..={} (the board's range)",
                range.start(),
                range.end()
            )
        })
}

/// Runs `hil`.
pub fn run(args: HilArgs) -> anyhow::Result<()> {
    let scenario = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    let opts = HilOptions {
        timeout: Duration::from_millis(args.timeout_ms),
        lose_every: args.lose_every,
        link_timeout_ms: Some(args.link_timeout_ms.unwrap_or(match args.port {
            Some(_) => 250,
            None => args.board.hil_link_timeout_ms(),
        })),
        resume_after_restart: args.resume_after_restart,
        ..HilOptions::default()
    };
    let stop = Stop::on_signals()?;
    let plan = args.excite.plan(&scenario)?;
    // Output paths are checked (the CSV or the log created) before QEMU
    // starts.
    let mut log = match &plan {
        Some(_) => Some(args.excite.open_log(scenario.planes())?),
        None => None,
    };
    let mut files = args
        .output
        .open_trace(JointSpec::of(&scenario).angle_names())?;
    let spec = RunSpec::resolve(&scenario)?;
    let mut qemu = None;
    let (port, label) = match &args.port {
        Some(p) => (open_port(p, args.baud)?, p.clone()),
        None => {
            let image = match &args.image {
                Some(i) => i.clone(),
                None => host_tools::board::qemu::default_image(args.board)?,
            };
            let q = qemu.insert(Qemu::launch(args.board, &image, !args.no_icount)?);
            let port = q.connect()?;
            (
                port,
                format!("QEMU's serial socket {} ({})", q.port, image.display()),
            )
        }
    };
    let mut link = Link::new(port);
    if let (Some(plan), Some(mut log)) = (plan, log.take()) {
        let electrical = !args.excite.no_electrical;
        let session = host_tools::joint::excite::run_hil(
            &plan, &spec, &mut link, opts, electrical, &mut log, &stop,
        )
        .map_err(|e| name_the_board(e, &label, args.baud));
        return args.excite.finish(log, session);
    }
    let progress = args.output.progress("lockstep steps");
    let ctx = host_tools::run::sim::RunContext {
        stop: &stop,
        progress: &progress,
    };
    let run = hil::run_into(&spec, &mut link, opts, &mut files, &ctx);
    progress.finish_and_clear();
    // A QEMU that ended is the reason the link failed: say how it ended
    // (its exit status or signal and its last words) rather than only
    // what the serial line did.
    let ended =
        |qemu: &mut Option<Qemu>| qemu.as_mut().and_then(|q| q.ended(Duration::from_secs(2)));
    let mut report = match run {
        Ok(r) => r,
        Err(e) => match ended(&mut qemu) {
            // QEMU's own words say why; the link's view (a closed line)
            // would only repeat it.
            Some(how) => bail!("the emulated board ended before the run began: {how}"),
            None => return Err(name_the_board(e, &label, args.baud)),
        },
    };
    if let Some(cut) = &mut report.summary.cut_short {
        if cut.cause == host_tools::run::summary::CutCause::Controller {
            cut.reason = match ended(&mut qemu) {
                Some(how) => format!("the emulated board ended: {how}"),
                // Which board, as for a failure before the run.
                None => format!("{}, on {label}", cut.reason),
            };
        }
    }
    args.output.finish_trace(
        files,
        &format!("{} (HIL)", scenario.name),
        &mut report.summary,
    )?;
    if args.output.json {
        output::print_json(&report)?;
    } else {
        out!("{}", report::table(&report.summary));
        let l = &report.link;
        outln!(
            "link: {} frames sent, {} received, {} retries, {} CRC errors, {} unexpected; board saw {} frames, {} CRC errors",
            l.frames_sent, l.frames_received, l.retries, l.crc_errors, l.unexpected, report.board_frames_ok, report.board_crc_errors
        );
        outln!("lockstep: {:.0} steps/s", report.lockstep_steps_per_s);
    }
    match report.summary.cut_short {
        Some(cut) => Err(host_tools::run::summary::RunCutShort(cut).into()),
        None => Ok(()),
    }
}
