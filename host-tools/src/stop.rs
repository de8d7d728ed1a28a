//! Ending a run when the user asks: SIGINT (Ctrl-C) and SIGTERM set a flag
//! that the run loop reads every control period. The run then ends like
//! any early end — its trace complete to the last row, a summary that says
//! where and why it stopped — and the program exits with 128 + the signal
//! number (130 for SIGINT, 143 for SIGTERM), as a shell reports a process
//! ended by that signal. A second signal of the same kind ends the program
//! at once. Only commands that read the flag install it ([`Stop::on_signals`]);
//! the others keep the default (the signal ends them).
//!
//! Also here: SIGXFSZ (a file-size limit, `ulimit -f`) is turned into a
//! failed write (`EFBIG`, reported with the file's name) instead of killing
//! the program mid-write.
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use signal_hook::consts::{SIGINT, SIGTERM, SIGXFSZ};

/// Whether, and by which signal, a run was asked to stop.
#[derive(Clone, Debug, Default)]
pub struct Stop {
    signal: Arc<AtomicUsize>,
}

/// The signal that stopped a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum StopSignal {
    /// SIGINT (Ctrl-C).
    #[serde(rename = "SIGINT")]
    Interrupt,
    /// SIGTERM (`kill`, a service manager).
    #[serde(rename = "SIGTERM")]
    Terminate,
}

impl StopSignal {
    /// The name, e.g. `SIGINT`.
    pub fn name(self) -> &'static str {
        match self {
            StopSignal::Interrupt => "SIGINT",
            StopSignal::Terminate => "SIGTERM",
        }
    }

    /// The exit status a shell gives a process ended by this signal.
    pub fn exit_code(self) -> u8 {
        match self {
            StopSignal::Interrupt => 130,
            StopSignal::Terminate => 143,
        }
    }
}

impl Stop {
    /// A flag no signal sets (library callers, tests); [`Stop::request`]
    /// still sets it.
    pub fn never() -> Self {
        Self::default()
    }

    /// A flag set by SIGINT and SIGTERM; a second one of either ends the
    /// program at once with its status.
    pub fn on_signals() -> anyhow::Result<Self> {
        let stop = Self::default();
        for (signal, code) in [(SIGINT, 130), (SIGTERM, 143)] {
            let again = Arc::new(AtomicBool::new(false));
            // Order matters: the shutdown check sees the flag set by an
            // earlier signal before this one sets it.
            signal_hook::flag::register_conditional_shutdown(signal, code, again.clone())?;
            signal_hook::flag::register(signal, again)?;
            let value = usize::try_from(signal).unwrap_or(usize::MAX);
            signal_hook::flag::register_usize(signal, stop.signal.clone(), value)?;
        }
        Ok(stop)
    }

    /// The flag itself (0 while no stop is asked; otherwise the signal's
    /// number), for a library that polls a plain atomic.
    pub fn flag(&self) -> Arc<AtomicUsize> {
        self.signal.clone()
    }

    /// Asks the run to stop as if `signal` had arrived.
    pub fn request(&self, signal: StopSignal) {
        let s = match signal {
            StopSignal::Interrupt => SIGINT,
            StopSignal::Terminate => SIGTERM,
        };
        self.signal
            .store(usize::try_from(s).unwrap_or(usize::MAX), Ordering::SeqCst);
    }

    /// The signal that asked the run to stop, if one did.
    #[inline]
    pub fn requested(&self) -> Option<StopSignal> {
        match self.signal.load(Ordering::Relaxed) {
            0 => None,
            s if s == SIGTERM as usize => Some(StopSignal::Terminate),
            _ => Some(StopSignal::Interrupt),
        }
    }
}

/// Makes a file-size limit (`ulimit -f`) fail the write that exceeds it
/// with `EFBIG` instead of killing the program (SIGXFSZ's default), so the
/// write is reported with its file's name and a partial temporary file is
/// removed.
pub fn file_size_limit_is_an_error() -> anyhow::Result<()> {
    signal_hook::flag::register(SIGXFSZ, Arc::new(AtomicBool::new(false)))?;
    Ok(())
}
