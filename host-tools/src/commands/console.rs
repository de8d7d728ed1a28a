//! `softjoint hil` and `softjoint console`: the serial-line subcommands.
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use clap::Args;
use firmware::protocol::{
    Arm, Calibration, ClearFaults, Disarm, GetCalibration, HilStop, Message, SetCalibration,
    SetGains, SetLinkTimeout, SetTarget, SetTelemetry, Telemetry,
};
use host_tools::board::controller::name_the_board;
use host_tools::board::hil::{self};
use host_tools::board::link::{open_port, Link, Port};
use host_tools::files::calibration::{CalibrationFile, LawSpec};
use host_tools::outln;
use host_tools::output;
use host_tools::run::summary::fault_names;
use host_tools::stop::Stop;
use plant_common::csv_input::excerpt;
use plant_common::short_number;

#[derive(Args)]
pub struct ConsoleArgs {
    /// The board's serial device, or `unix:PATH` (QEMU's serial socket).
    #[arg(long)]
    port: String,
    /// Baud rate.
    #[arg(allow_negative_numbers = true, long, default_value_t = 115_200)]
    baud: u32,
    /// Read commands from this file (one per line, `#` comments).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Append streamed telemetry to this CSV.
    #[arg(long)]
    csv: Option<PathBuf>,
    /// Commands, e.g. `status`, `arm`, `target 0 5`, `stream 2`
    /// (see `softjoint console --port P help`). Everything after the
    /// first command word is the command's, negative numbers included.
    #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
    commands: Vec<String>,
}

const HELP: &str = "commands:
  hello                         handshake (protocol version, schema)
  status                        armed, mode, faults, estimates, outputs, counters
  arm | disarm | clear          outputs on/off; clear latched faults
  hil-stop                      leave lockstep mode (back to free-running)
  target PLANE DEG              desired angle (plane 0 = alpha, 1 = beta)
  gains PLANE KP_AG KP_ANT KI ILIM [VOFF]
                                VOFF: the law's v_offset (V, default 1.7)
  gains load FILE               every plane's gains from a gains file (softjoint tune)
  calibration get PLANE         print the plane's estimation law
  calibration set FILE          load a calibration file (softjoint calibrate wire)
  telemetry HZ                  stream telemetry at HZ (0 = off)
  link-timeout MS               link-loss timeout
  stream SECONDS                print (or --csv) telemetry for SECONDS
  excite PLAN.toml --log LOG.csv
                                run an excitation plan on the board (open-loop
                                drives, holds) and record the log that
                                `softjoint identify joint` reads; disarms at the
                                end, on an error and on Ctrl-C
  wait SECONDS                  pause";

/// Runs `console`.
pub fn run(args: ConsoleArgs) -> anyhow::Result<()> {
    let mut lines: Vec<(String, String)> = Vec::new();
    if let Some(path) = &args.script {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read script {}", path.display()))?;
        for (i, l) in plant_common::strip_bom(&text).lines().enumerate() {
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
        outln!("{HELP}");
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
            run_console_command(&mut link, cmd, csv.as_mut(), &args.port)
                .map_err(|e| name_the_board(e, &args.port, args.baud))
                .with_context(|| format!("{origin}: `{}`", excerpt(cmd)))?;
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
        writeln!(f, "{TELEMETRY_HEADER}")?;
    }
    Ok(f)
}

const T: Duration = Duration::from_millis(300);

/// An estimate on the console's status line: the core reports "no
/// estimate yet" (before every sensor a law reads has delivered) as NaN,
/// which the line says in words rather than as `NaN°`.
fn status_estimate(estimate_deg: f32) -> String {
    if estimate_deg.is_nan() {
        "none yet".into()
    } else {
        format!("{estimate_deg:.2}°")
    }
}

/// Columns of the console's telemetry CSV (an estimate is empty while the
/// board has none).
const TELEMETRY_HEADER: &str =
    "time_ms,alpha_deg,beta_deg,v1_mv,v2_mv,v3_mv,v4_mv,count1,count2,count3,count4,faults";

/// A wire count for a CSV field: empty when the sensor gave no reading
/// (`i32::MIN` on the wire).
fn count_field(c: i32) -> String {
    if c == i32::MIN {
        String::new()
    } else {
        c.to_string()
    }
}

fn arg<T: std::str::FromStr>(words: &[&str], i: usize, what: &str) -> anyhow::Result<T> {
    let w = words
        .get(i)
        .ok_or_else(|| anyhow::anyhow!("missing {what}"))?;
    w.parse()
        .map_err(|_| anyhow::anyhow!("{what}: cannot parse `{}`", excerpt(w)))
}

/// A number argument that must lie in `lo..=hi` (the board's range, or
/// the console's), named in the error.
fn arg_in(
    words: &[&str],
    i: usize,
    what: &str,
    lo: f64,
    hi: f64,
    unit: &str,
) -> anyhow::Result<f64> {
    let v: f64 = arg(words, i, what)?;
    if !(v.is_finite() && (lo..=hi).contains(&v)) {
        bail!(
            "{what} must be a finite number in {}..={} {unit}, got {}",
            short_number(lo),
            short_number(hi),
            short_number(v)
        );
    }
    Ok(v)
}

/// A plane number: 0 (α) or 1 (β).
fn plane_arg(words: &[&str], i: usize) -> anyhow::Result<u8> {
    let p: u8 = arg(words, i, "PLANE")?;
    if p > 1 {
        bail!("PLANE must be 0 (α) or 1 (β), got {p}");
    }
    Ok(p)
}

/// Longest `wait` or `stream` (s): a day (a telemetry stream goes to its
/// CSV row by row, so a long one costs no memory).
const MAX_CONSOLE_SECONDS: f64 = 86_400.0;

/// A duration in seconds from the user (`wait`, `stream`), checked by
/// [`arg_in`] before it becomes a `Duration`: not a number, negative,
/// infinite or longer than a day is refused by name instead of panicking
/// in the conversion or in the clock arithmetic.
fn seconds(words: &[&str], i: usize) -> anyhow::Result<Duration> {
    let secs = arg_in(words, i, "SECONDS", 0.0, MAX_CONSOLE_SECONDS, "s")?;
    Duration::try_from_secs_f64(secs).map_err(|e| anyhow::anyhow!("SECONDS: {e}"))
}

/// Runs one console command on the board (see [`HELP`]): the command word
/// picks its step, each of which parses its own arguments and names the
/// bad one.
fn run_console_command<P: Port>(
    link: &mut Link<P>,
    cmd: &str,
    csv: Option<&mut std::fs::File>,
    port: &str,
) -> anyhow::Result<()> {
    let words: Vec<&str> = cmd.split_whitespace().collect();
    match words.as_slice() {
        ["hello"] => {
            hil::handshake(link)?;
            outln!("hello: protocol and schema match");
        }
        ["status"] => print_status(link)?,
        ["arm"] => ack(link, Arm {})?,
        ["disarm"] => ack(link, Disarm {})?,
        ["clear"] => ack(link, ClearFaults {})?,
        ["hil-stop"] => ack(link, HilStop {})?,
        ["target", ..] => ack(link, target_request(&words)?)?,
        ["gains", "load", file] => load_gains(link, Path::new(file))?,
        ["gains", ..] => ack(link, gains_request(&words)?)?,
        ["calibration", "get", ..] => print_calibration(link, plane_arg(&words, 2)?)?,
        ["calibration", "set", file] => load_calibration(link, Path::new(file))?,
        ["telemetry", ..] => ack(link, telemetry_request(&words)?)?,
        ["link-timeout", ..] => ack(link, link_timeout_request(&words)?)?,
        ["stream", ..] => stream_telemetry(link, seconds(&words, 1)?, csv, port)?,
        ["wait", ..] => std::thread::sleep(seconds(&words, 1)?),
        ["excite", plan, "--log", log] => excite_on_board(link, Path::new(plan), Path::new(log))?,
        ["excite", ..] => bail!("usage: excite PLAN.toml --log LOG.csv"),
        _ => bail!("unknown command; try `help`\n{HELP}"),
    }
    Ok(())
}

/// `status`: the board's status on one line.
fn print_status<P: Port>(link: &mut Link<P>) -> anyhow::Result<()> {
    let s = hil::status(link)?;
    outln!(
        "armed {} mode {} faults [{}] latched [{}] estimate α {} β {} target α {:.2}° β {:.2}° outputs {} mV / {} mV coils {} mV drive [{}] t {} ms | frames {} crc {} cobs {} overfull {} malformed {}",
        s.armed,
        if s.mode == 1 { "lockstep" } else { "free-running" },
        fault_names(u16::from(s.faults)).join(","),
        fault_names(u16::from(s.latched)).join(","),
        status_estimate(s.estimate_deg[0]), status_estimate(s.estimate_deg[1]),
        s.target_deg[0], s.target_deg[1],
        s.pair_mv[0], s.pair_mv[1],
        s.coil_mv.map(|m| m.to_string()).join("/"),
        drive_planes(s.drive_planes),
        s.time_ms, s.frames_ok, s.crc_errors, s.cobs_errors, s.overfull, s.malformed
    );
    Ok(())
}

/// `target PLANE DEG`, within the board's target range.
fn target_request(words: &[&str]) -> anyhow::Result<SetTarget> {
    let max = f64::from(firmware::joint::DEFAULT_MAX_TARGET_DEG);
    Ok(SetTarget {
        plane: plane_arg(words, 1)?,
        target_deg: arg_in(words, 2, "DEG", -max, max, "deg (the board's range)")? as f32,
    })
}

/// `gains PLANE KP_AG KP_ANT KI ILIM [VOFF]` (VOFF: the paper's by
/// default).
fn gains_request(words: &[&str]) -> anyhow::Result<SetGains> {
    Ok(SetGains {
        plane: plane_arg(words, 1)?,
        kp_agonist: arg(words, 2, "KP_AG")?,
        kp_antagonist: arg(words, 3, "KP_ANT")?,
        ki: arg(words, 4, "KI")?,
        integral_limit_v: arg(words, 5, "ILIM")?,
        v_offset_v: match words.get(6) {
            Some(_) => arg(words, 6, "VOFF")?,
            None => firmware::control::PAPER_V_OFFSET_V,
        },
    })
}

/// `gains load FILE`: every plane's gains from a gains file, plane by
/// plane.
fn load_gains<P: Port>(link: &mut Link<P>, file: &Path) -> anyhow::Result<()> {
    let g = host_tools::files::gains::GainsFile::load(file)?;
    for (plane, [kp_agonist, kp_antagonist]) in g.pair_gains().into_iter().enumerate() {
        ack(
            link,
            SetGains {
                plane: plane as u8,
                kp_agonist,
                kp_antagonist,
                ki: g.controller.ki_v_per_deg_s as f32,
                integral_limit_v: g.controller.integral_limit_v as f32,
                v_offset_v: g.controller.v_offset_v as f32,
            },
        )?;
    }
    Ok(())
}

/// `calibration get PLANE`: the plane's estimation law, described.
fn print_calibration<P: Port>(link: &mut Link<P>, plane: u8) -> anyhow::Result<()> {
    let r = link.request(&GetCalibration { plane }.into(), T, 5, |m| {
        matches!(m, Message::Calibration(_))
    })?;
    if let Message::Calibration(Calibration { plane, law }) = r {
        outln!(
            "plane {plane}: {}",
            host_tools::files::calibration::describe(&LawSpec::from_law(&law))
        );
    }
    Ok(())
}

/// `calibration set FILE`: every plane's law from a calibration file.
fn load_calibration<P: Port>(link: &mut Link<P>, file: &Path) -> anyhow::Result<()> {
    let cal = CalibrationFile::load(file)?;
    for (p, law) in cal.laws()?.into_iter().enumerate() {
        ack(
            link,
            SetCalibration {
                plane: p as u8,
                law,
            },
        )?;
    }
    Ok(())
}

/// `telemetry HZ`, within the board's rate range (0 = off).
fn telemetry_request(words: &[&str]) -> anyhow::Result<SetTelemetry> {
    Ok(SetTelemetry {
        rate_hz: arg_in(
            words,
            1,
            "HZ",
            0.0,
            f64::from(firmware::app::MAX_TELEMETRY_HZ),
            "Hz (the board's range; 0 = off)",
        )? as u16,
    })
}

/// `link-timeout MS`, within the board's range.
fn link_timeout_request(words: &[&str]) -> anyhow::Result<SetLinkTimeout> {
    let range = firmware::app::LINK_TIMEOUT_MS;
    Ok(SetLinkTimeout {
        timeout_ms: arg_in(
            words,
            1,
            "MS",
            f64::from(*range.start()),
            f64::from(*range.end()),
            "ms (the board's range)",
        )? as u16,
    })
}

/// `stream SECONDS`: the telemetry that arrives within `span`, one CSV
/// line per frame to `csv` (or standard output), and the count on
/// standard error. No telemetry at all in a non-empty span is an error
/// that says what did arrive from `port`.
fn stream_telemetry<P: Port>(
    link: &mut Link<P>,
    span: Duration,
    mut csv: Option<&mut std::fs::File>,
    port: &str,
) -> anyhow::Result<()> {
    let secs = span.as_secs_f64();
    let end = Instant::now() + span;
    let mut n = 0u64;
    while let Some(m) = link.recv_until(end)? {
        if let Message::Telemetry(t) = m {
            n += 1;
            let line = telemetry_line(&t);
            output::check_csv("the telemetry", &format!("{TELEMETRY_HEADER}\n{line}"))?;
            match csv.as_deref_mut() {
                Some(f) => writeln!(f, "{line}")?,
                None => outln!("{line}"),
            }
        }
    }
    eprintln!("{n} telemetry frames in {secs} s");
    if n == 0 && secs > 0.0 {
        let st = link.stats();
        let noise = st.crc_errors + st.cobs_errors + st.overfull + st.malformed;
        let heard = if noise > 0 || st.frames_received > 0 {
            format!(
                "it sent {} frame(s) of other kinds and {noise} that did not decode (CRC {}, COBS {}, oversized {}, malformed {})",
                st.frames_received, st.crc_errors, st.cobs_errors, st.overfull, st.malformed
            )
        } else {
            "nothing at all arrived".into()
        };
        bail!(
            "no telemetry from {port} in {secs} s: {heard}; turn it on first (`telemetry 10; stream {secs}`), and check that a board running softjoint-fw is on {port} at the right --baud"
        );
    }
    Ok(())
}

/// One telemetry frame as a row of [`TELEMETRY_HEADER`].
fn telemetry_line(t: &Telemetry) -> String {
    format!(
        "{},{},{},{},{},{}",
        t.time_ms,
        output::estimate_field(f64::from(t.estimate_deg[0]), 3),
        output::estimate_field(f64::from(t.estimate_deg[1]), 3),
        t.coil_mv.map(|m| m.to_string()).join(","),
        t.counts.map(count_field).join(","),
        t.faults
    )
}

/// The planes of a `drive_planes` byte, by name.
fn drive_planes(mask: u8) -> String {
    let names: Vec<&str> = [(1u8, "α"), (2, "β")]
        .iter()
        .filter(|(b, _)| mask & b != 0)
        .map(|(_, n)| *n)
        .collect();
    names.join(",")
}

/// `excite PLAN --log LOG`: the plan on the board (3D, free-running), the
/// log written with the board's estimates and fault byte as extra columns.
/// The rows go to a temporary file beside LOG as they arrive (memory stays
/// flat however long the plan) and replace LOG at the end, also when the
/// session ended early (a signal, a lost link, a refusal): whatever was
/// recorded is kept, and a session with no row leaves LOG as it was.
fn excite_on_board<P: Port>(link: &mut Link<P>, plan: &Path, log: &Path) -> anyhow::Result<()> {
    use host_tools::joint::excite::{run_board, LogFile};
    let plan = host_tools::joint::excite::load_plan(plan, 2)?;
    // The log's file is opened before the board moves.
    let mut file = LogFile::create_board(log)?;
    let stop = Stop::on_signals()?;
    let run = run_board(&plan, link, &stop, &mut file);
    let s = &run.summary;
    // Renamed over LOG only with rows in it; dropped, it leaves LOG alone.
    let kept = (s.rows > 0).then(|| file.finish());
    let (where_to, kept) = match kept {
        None => ("nothing written".to_string(), Ok(())),
        Some(Ok(_)) => (log.display().to_string(), Ok(())),
        Some(Err(e)) => ("nothing written".to_string(), Err(e)),
    };
    outln!(
        "excite `{}`: {} rows ({} s of {} s) to {where_to}; {} rows filled (telemetry lost); faults seen [{}]; peak coil inputs {} mV",
        s.plan,
        s.rows,
        short_number(s.recorded_s),
        short_number(s.planned_s),
        s.rows_filled,
        s.faults_seen.join(","),
        s.peak_coil_mv.map(|m| m.to_string()).join("/")
    );
    let held = if s.rows > 0 && kept.is_ok() {
        format!("{} holds its {} rows up to there", log.display(), s.rows)
    } else {
        format!("nothing was written to {}", log.display())
    };
    match (run.error, kept) {
        (None, kept) => kept,
        (Some(e), kept) => {
            if let Err(k) = kept {
                eprintln!("error: {k:#}");
            }
            Err(e.context(format!(
                "the session ended at t = {} s of {} s (the board is disarmed; {held})",
                short_number(s.recorded_s),
                short_number(s.planned_s)
            )))
        }
    }
}

fn ack<P: Port>(link: &mut Link<P>, msg: impl Into<Message>) -> anyhow::Result<()> {
    link.command(&msg.into(), T, 5)?;
    outln!("ok");
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::status_estimate;

    /// `status` printed `estimate α NaN°` before the sensors had delivered.
    #[test]
    fn a_missing_estimate_is_said_in_words_on_the_status_line() {
        assert_eq!(status_estimate(f32::NAN), "none yet");
        assert_eq!(status_estimate(1.234), "1.23°");
        assert_eq!(status_estimate(-0.5), "-0.50°");
    }
}
