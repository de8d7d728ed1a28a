//! `softjoint hil` and `softjoint console`: the serial-line subcommands.
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Args;
use firmware::protocol::{
    Arm, Calibration, ClearFaults, Disarm, GetCalibration, HilStop, Message, SetCalibration,
    SetGains, SetLinkTimeout, SetTarget, SetTelemetry,
};
use host_tools::hil::{self, HilOptions};
use host_tools::link::{open_port, Link, Port};
use host_tools::qemu::{Qemu, QemuBoard};
use host_tools::scenario::Scenario;
use host_tools::sim::fault_names;
use host_tools::{
    calibrate::{CalibrationFile, LawSpec},
    report,
};

#[derive(Args)]
pub struct HilArgs {
    /// Scenario file (TOML); without it the built-in 3D default runs.
    scenario: Option<PathBuf>,
    /// A real board's serial device; without it the firmware image runs
    /// under QEMU on a pty.
    #[arg(long, conflicts_with_all = ["board", "image"])]
    port: Option<String>,
    /// Baud rate for --port.
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// The board image QEMU runs: mps2-an386 (`softjoint-fw`) or stm32f4
    /// (the STM32F4 board image's QEMU flavour on netduinoplus2).
    #[arg(long, value_enum, default_value_t = QemuBoard::Mps2An386)]
    board: QemuBoard,
    /// Firmware image for QEMU [default: the board's image under target/].
    #[arg(long)]
    image: Option<PathBuf>,
    /// Run QEMU without `-icount shift=0`. By default the guest's clock
    /// advances with executed instructions (1 ns each), so host scheduling
    /// cannot make the board's link watchdog see time jump; without it
    /// QEMU's clock follows the host's and catches up in bursts.
    #[arg(long)]
    no_icount: bool,
    /// Reply timeout per attempt (ms).
    #[arg(long, default_value_t = 100)]
    timeout_ms: u64,
    /// Fault injection: lose the first copy of every Nth sensor frame.
    #[arg(long)]
    lose_every: Option<u32>,
    /// Link-loss timeout to set on the board (ms of its clock)
    /// [default: 250; under QEMU the board's own: 250 for mps2-an386, 1000
    /// for stm32f4]. The board's built-in default is 50 ms; an emulated
    /// board's clock depends on host scheduling, so a loaded host needs
    /// more slack than a real board does.
    #[arg(long)]
    link_timeout_ms: Option<u16>,
    #[command(flatten)]
    output: report::OutputArgs,
}

pub fn hil(args: HilArgs) -> anyhow::Result<()> {
    let scenario = match &args.scenario {
        Some(p) => Scenario::load(p)?,
        None => Scenario::default(),
    };
    let opts = HilOptions {
        timeout: Duration::from_millis(args.timeout_ms.max(1)),
        lose_every: args.lose_every,
        link_timeout_ms: Some(args.link_timeout_ms.unwrap_or(match args.port {
            Some(_) => 250,
            None => args.board.hil_link_timeout_ms(),
        })),
        ..HilOptions::default()
    };
    let _qemu;
    let port = match &args.port {
        Some(p) => open_port(p, args.baud)?,
        None => {
            let image = args
                .image
                .clone()
                .unwrap_or_else(|| PathBuf::from(args.board.default_image()));
            let mut q = Qemu::launch(args.board, &image, !args.no_icount)?;
            let port = q.connect()?;
            _qemu = q;
            port
        }
    };
    let mut link = Link::new(port);
    let out = hil::run(&scenario, &mut link, opts)?;
    args.output.write_files(
        &format!("{} (HIL)", scenario.name),
        &out.report.summary,
        &out.trace,
    )?;
    if args.output.json {
        println!("{}", serde_json::to_string_pretty(&out.report)?);
    } else {
        print!("{}", report::table(&out.report.summary));
        let l = &out.report.link;
        println!(
            "link: {} frames sent, {} received, {} retries, {} CRC errors, {} unexpected; board saw {} frames, {} CRC errors",
            l.frames_sent, l.frames_received, l.retries, l.crc_errors, l.unexpected, out.report.board_frames_ok, out.report.board_crc_errors
        );
        println!("lockstep: {:.0} steps/s", out.report.lockstep_steps_per_s);
    }
    Ok(())
}

#[derive(Args)]
pub struct ConsoleArgs {
    /// The board's serial device (or QEMU's pty).
    #[arg(long)]
    port: String,
    /// Baud rate.
    #[arg(long, default_value_t = 115_200)]
    baud: u32,
    /// Read commands from this file (one per line, `#` comments).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Append streamed telemetry to this CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Commands, e.g. `status`, `arm`, `target 0 5`, `stream 2`
    /// (see `softjoint console --port P help`).
    commands: Vec<String>,
}

const HELP: &str = "commands:
  hello                         handshake (protocol version, schema)
  status                        armed, mode, faults, estimates, outputs, counters
  arm | disarm | clear          outputs on/off; clear latched faults
  hil-stop                      leave lockstep mode (back to free-running)
  target PLANE DEG              desired angle (plane 0 = alpha, 1 = beta)
  gains PLANE KP_AG KP_ANT KI ILIM
  calibration get PLANE         print the plane's estimation law
  calibration set FILE          load a calibration file (softjoint calibrate wire)
  telemetry HZ                  stream telemetry at HZ (0 = off)
  link-timeout MS               link-loss timeout
  stream SECONDS                print (or --csv) telemetry for SECONDS
  wait SECONDS                  pause";

pub fn console(args: ConsoleArgs) -> anyhow::Result<()> {
    let mut lines: Vec<(String, String)> = Vec::new();
    if let Some(path) = &args.script {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read script {}", path.display()))?;
        for (i, l) in text.lines().enumerate() {
            let l = l.split('#').next().unwrap_or("").trim();
            if !l.is_empty() {
                lines.push((format!("{}:{}", path.display(), i + 1), l.to_string()));
            }
        }
    }
    if !args.commands.is_empty() {
        lines.push(("command line".into(), args.commands.join(" ")));
    }
    if lines.iter().any(|(_, l)| l == "help") || lines.is_empty() {
        println!("{HELP}");
        return Ok(());
    }
    let port = open_port(&args.port, args.baud)?;
    let mut link = Link::new(port);
    link.send_raw(&[0])?;
    let mut csv = match &args.csv {
        Some(p) => Some(open_csv(p)?),
        None => None,
    };
    for (origin, line) in &lines {
        for cmd in line.split(';').map(str::trim).filter(|c| !c.is_empty()) {
            run_console_command(&mut link, cmd, csv.as_mut())
                .with_context(|| format!("{origin}: `{cmd}`"))?;
        }
    }
    Ok(())
}

fn open_csv(path: &Path) -> anyhow::Result<std::fs::File> {
    let new = !path.exists();
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
        .with_context(|| format!("cannot open {}", path.display()))?;
    if new {
        writeln!(
            f,
            "time_ms,alpha_deg,beta_deg,pair_alpha_mv,pair_beta_mv,faults"
        )?;
    }
    Ok(f)
}

const T: Duration = Duration::from_millis(300);

fn arg<T: std::str::FromStr>(words: &[&str], i: usize, what: &str) -> anyhow::Result<T> {
    let w = words
        .get(i)
        .ok_or_else(|| anyhow::anyhow!("missing {what}"))?;
    w.parse()
        .map_err(|_| anyhow::anyhow!("{what}: cannot parse `{w}`"))
}

fn run_console_command<P: Port>(
    link: &mut Link<P>,
    cmd: &str,
    csv: Option<&mut std::fs::File>,
) -> anyhow::Result<()> {
    let words: Vec<&str> = cmd.split_whitespace().collect();
    match words.as_slice() {
        ["hello"] => {
            hil::handshake(link)?;
            println!("hello: protocol and schema match");
        }
        ["status"] => {
            let s = hil::status(link)?;
            println!(
                "armed {} mode {} faults [{}] latched [{}] estimate α {:.2}° β {:.2}° target α {:.2}° β {:.2}° outputs {} mV / {} mV t {} ms | frames {} crc {} cobs {} overfull {} malformed {}",
                s.armed,
                if s.mode == 1 { "lockstep" } else { "free-running" },
                fault_names(u16::from(s.faults)).join(","),
                fault_names(u16::from(s.latched)).join(","),
                s.estimate_deg[0], s.estimate_deg[1], s.target_deg[0], s.target_deg[1],
                s.pair_mv[0], s.pair_mv[1], s.time_ms, s.frames_ok, s.crc_errors, s.cobs_errors, s.overfull, s.malformed
            );
        }
        ["arm"] => ack(link, Arm {})?,
        ["disarm"] => ack(link, Disarm {})?,
        ["clear"] => ack(link, ClearFaults {})?,
        ["hil-stop"] => ack(link, HilStop {})?,
        ["target", ..] => ack(
            link,
            SetTarget {
                plane: arg(&words, 1, "PLANE")?,
                target_deg: arg(&words, 2, "DEG")?,
            },
        )?,
        ["gains", ..] => ack(
            link,
            SetGains {
                plane: arg(&words, 1, "PLANE")?,
                kp_agonist: arg(&words, 2, "KP_AG")?,
                kp_antagonist: arg(&words, 3, "KP_ANT")?,
                ki: arg(&words, 4, "KI")?,
                integral_limit_v: arg(&words, 5, "ILIM")?,
            },
        )?,
        ["calibration", "get", ..] => {
            let plane: u8 = arg(&words, 2, "PLANE")?;
            let r = link.request(&GetCalibration { plane }.into(), T, 5, |m| {
                matches!(m, Message::Calibration(_))
            })?;
            if let Message::Calibration(Calibration { plane, law }) = r {
                println!(
                    "plane {plane}: {}",
                    host_tools::calibrate::describe(&LawSpec::from_law(&law))
                );
            }
        }
        ["calibration", "set", file] => {
            let cal = CalibrationFile::load(Path::new(file))?;
            for (p, law) in cal.laws()?.into_iter().enumerate() {
                ack(
                    link,
                    SetCalibration {
                        plane: p as u8,
                        law,
                    },
                )?;
            }
        }
        ["telemetry", ..] => ack(
            link,
            SetTelemetry {
                rate_hz: arg(&words, 1, "HZ")?,
            },
        )?,
        ["link-timeout", ..] => ack(
            link,
            SetLinkTimeout {
                timeout_ms: arg(&words, 1, "MS")?,
            },
        )?,
        ["stream", ..] => {
            let secs: f64 = arg(&words, 1, "SECONDS")?;
            if !(secs.is_finite() && secs >= 0.0) {
                bail!("SECONDS must be ≥ 0");
            }
            let end = Instant::now() + Duration::from_secs_f64(secs);
            let mut csv = csv;
            let mut n = 0u64;
            while let Some(m) = link.recv_until(end)? {
                if let Message::Telemetry(t) = m {
                    n += 1;
                    let line = format!(
                        "{},{:.3},{:.3},{},{},{}",
                        t.time_ms,
                        t.estimate_deg[0],
                        t.estimate_deg[1],
                        t.pair_mv[0],
                        t.pair_mv[1],
                        t.faults
                    );
                    match csv.as_deref_mut() {
                        Some(f) => writeln!(f, "{line}")?,
                        None => println!("{line}"),
                    }
                }
            }
            eprintln!("{n} telemetry frames in {secs} s");
        }
        ["wait", ..] => std::thread::sleep(Duration::from_secs_f64(
            arg::<f64>(&words, 1, "SECONDS")?.clamp(0.0, 3600.0),
        )),
        _ => bail!("unknown command; try `help`\n{HELP}"),
    }
    Ok(())
}

fn ack<P: Port>(link: &mut Link<P>, msg: impl Into<Message>) -> anyhow::Result<()> {
    link.command(&msg.into(), T, 5)?;
    println!("ok");
    Ok(())
}
