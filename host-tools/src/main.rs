//! `softjoint`: simulation, hardware-in-the-loop, board console, calibration
//! and model fitting for SMA-driven soft joints and deformable objects.
use std::io::Write as _;
use std::process::ExitCode;

use clap::Parser as _;

mod commands;

fn main() -> ExitCode {
    if let Err(e) = host_tools::stop::file_size_limit_is_an_error() {
        let _ = writeln!(std::io::stderr(), "warning: {e}");
    }
    let result = commands::exec(commands::Cli::parse())
        .and_then(|()| Ok(host_tools::output::flush_stdout()?));
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // A reader that went away early (`softjoint sim --json | head -1`)
            // ends the program quietly with the status a shell gives a
            // process killed by SIGPIPE (128 + 13), as other command-line
            // tools do. Any other failed output is an error like the rest.
            if e.downcast_ref::<host_tools::output::StdoutError>()
                .is_some_and(|s| s.is_broken_pipe())
            {
                return ExitCode::from(141);
            }
            let _ = writeln!(std::io::stderr(), "error: {e:#}");
            // A run cut short or a command stopped by a signal exits as the
            // signal would (130 for SIGINT), after what it kept was written.
            if let Some(cut) = e.downcast_ref::<host_tools::run::summary::RunCutShort>() {
                return ExitCode::from(cut.exit_code());
            }
            match e.downcast_ref::<host_tools::stop::Stopped>() {
                Some(stopped) => ExitCode::from(stopped.exit_code()),
                None => ExitCode::FAILURE,
            }
        }
    }
}
