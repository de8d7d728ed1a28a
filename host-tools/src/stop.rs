//! Ending a run when the user asks, and ending what a command started
//! with it.
//!
//! SIGINT (Ctrl-C), SIGTERM and SIGHUP (the terminal went away) set a flag
//! that a long command reads at its clean points (every control period of
//! a run, every log row of an excitation session, every candidate of a
//! search). The command then ends like any early end — keeping what it has
//! (a trace complete to the last row, the log so far, the best candidate
//! and the search state so far) and saying where and why it stopped — and
//! the program exits with 128 + the signal number (130 for SIGINT, 143 for
//! SIGTERM, 129 for SIGHUP), as a shell reports a process ended by that
//! signal. A second signal of the same kind ends the program at once. Only
//! commands that read the flag install it ([`Stop::on_signals`]); the
//! others keep the default (the signal ends them).
//!
//! A process a command starts (QEMU for `hil`, the two sites of `tetmsd
//! pair`) dies with it ([`die_with_parent`]): it runs in its own process
//! group, so a Ctrl-C in the terminal reaches `softjoint` alone, which ends
//! it at a clean point; and on Linux it gets `PR_SET_PDEATHSIG` = SIGKILL,
//! so even a `softjoint` killed with SIGKILL leaves none behind.
//!
//! Also here: SIGXFSZ (a file-size limit, `ulimit -f`) is turned into a
//! failed write (`EFBIG`, reported with the file's name) instead of killing
//! the program mid-write.
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM, SIGXFSZ};

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
    /// SIGHUP (the terminal closed, an ssh session dropped).
    #[serde(rename = "SIGHUP")]
    Hangup,
}

impl StopSignal {
    /// Every signal a run stops on.
    pub const ALL: [StopSignal; 3] = [
        StopSignal::Interrupt,
        StopSignal::Terminate,
        StopSignal::Hangup,
    ];

    /// The name, e.g. `SIGINT`.
    pub fn name(self) -> &'static str {
        match self {
            StopSignal::Interrupt => "SIGINT",
            StopSignal::Terminate => "SIGTERM",
            StopSignal::Hangup => "SIGHUP",
        }
    }

    /// The signal's number.
    fn number(self) -> i32 {
        match self {
            StopSignal::Interrupt => SIGINT,
            StopSignal::Terminate => SIGTERM,
            StopSignal::Hangup => SIGHUP,
        }
    }

    /// The exit status a shell gives a process ended by this signal
    /// (128 + its number: 130, 143, 129).
    pub fn exit_code(self) -> u8 {
        match self {
            StopSignal::Interrupt => 130,
            StopSignal::Terminate => 143,
            StopSignal::Hangup => 129,
        }
    }
}

impl Stop {
    /// A flag no signal sets (library callers, tests); [`Stop::request`]
    /// still sets it.
    pub fn never() -> Self {
        Self::default()
    }

    /// A flag set by SIGINT, SIGTERM and SIGHUP; a second one of the same
    /// kind ends the program at once with its status.
    pub fn on_signals() -> anyhow::Result<Self> {
        let stop = Self::default();
        for s in StopSignal::ALL {
            let (signal, code) = (s.number(), i32::from(s.exit_code()));
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
        self.signal.store(
            usize::try_from(signal.number()).unwrap_or(usize::MAX),
            Ordering::SeqCst,
        );
    }

    /// The signal that asked the run to stop, if one did.
    #[inline]
    pub fn requested(&self) -> Option<StopSignal> {
        match self.signal.load(Ordering::Relaxed) {
            0 => None,
            s if s == SIGTERM as usize => Some(StopSignal::Terminate),
            s if s == SIGHUP as usize => Some(StopSignal::Hangup),
            _ => Some(StopSignal::Interrupt),
        }
    }
}

/// A command stopped by a signal at a clean point, as an error: what it
/// kept is written (and said) first; the program then exits with
/// [`Stopped::exit_code`].
#[derive(Clone, Debug, thiserror::Error)]
#[error("stopped by {}: {what}", signal.name())]
pub struct Stopped {
    /// The signal.
    pub signal: StopSignal,
    /// Where it stopped and what it kept, for a person.
    pub what: String,
}

impl Stopped {
    /// 128 + the signal's number.
    pub fn exit_code(&self) -> u8 {
        self.signal.exit_code()
    }
}

/// Makes `cmd`'s process die with this thread (Linux: `PR_SET_PDEATHSIG`
/// = SIGKILL; the signal follows the *thread* that starts the process, so
/// start it from the thread that outlives it) and puts it in its own
/// process group (a Ctrl-C in the terminal reaches `softjoint`, which ends
/// the process at a clean point, not the process under it).
///
/// The process starts with SIGINT at its default action, whatever this
/// program inherited: a shell starts a background job (`softjoint … &`,
/// `nohup`, a CI script's job) with SIGINT ignored, an ignored signal
/// stays ignored across exec, and a process that ignores it cannot be
/// stopped cleanly by [`interrupt`] (a shell cannot even trap it, and
/// Python then raises no KeyboardInterrupt).
pub fn die_with_parent(cmd: &mut Command) {
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt as _;
        cmd.process_group(0);
        // SAFETY: the closure runs in the forked child before exec and only
        // calls signal(2), which is async-signal-safe; it allocates nothing.
        #[allow(unsafe_code)]
        unsafe {
            cmd.pre_exec(|| {
                if libc::signal(libc::SIGINT, libc::SIG_DFL) == libc::SIG_ERR {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
    #[cfg(target_os = "linux")]
    {
        use std::os::unix::process::CommandExt as _;
        let parent = std::process::id();
        // SAFETY: the closure runs in the forked child before exec and only
        // calls prctl and getppid, both async-signal-safe; it allocates
        // nothing and touches no lock.
        #[allow(unsafe_code)]
        unsafe {
            cmd.pre_exec(move || {
                if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL, 0, 0, 0) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                // The parent may have died before prctl: then no signal
                // would come.
                if u32::try_from(libc::getppid()).ok() != Some(parent) {
                    return Err(std::io::Error::other("parent exited while starting"));
                }
                Ok(())
            });
        }
    }
}

/// Sends SIGINT to `child` (a process started with [`die_with_parent`],
/// out of the terminal's process group, that ends at a clean point on
/// Ctrl-C): how a command passes its own stop on. Call it only while the
/// child is not yet waited for (`try_wait` saw it running).
pub fn interrupt(child: &std::process::Child) {
    #[cfg(unix)]
    if let Ok(pid) = i32::try_from(child.id()) {
        // SAFETY: kill(2) on a child not reaped yet: the pid is still
        // this child's, and kill touches no memory of ours.
        #[allow(unsafe_code)]
        unsafe {
            libc::kill(pid, libc::SIGINT);
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

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;
    use std::os::unix::process::CommandExt as _;

    /// Whether the process whose `/proc/PID/status` is `status` ignores
    /// SIGINT (its bit in the `SigIgn` mask).
    fn ignores_sigint(status: &str) -> bool {
        let mask = status
            .lines()
            .find_map(|l| l.strip_prefix("SigIgn:"))
            .and_then(|m| u64::from_str_radix(m.trim(), 16).ok())
            .expect("a SigIgn line");
        mask & (1 << (libc::SIGINT - 1)) != 0
    }

    /// `cat /proc/self/status` started as a shell starts a background job:
    /// SIGINT ignored before exec; `started` may add more.
    fn status_of_a_background_child(started: impl FnOnce(&mut Command)) -> String {
        let mut cmd = Command::new("cat");
        cmd.arg("/proc/self/status");
        // SAFETY: signal(2) only, in the forked child (async-signal-safe).
        #[allow(unsafe_code)]
        unsafe {
            cmd.pre_exec(|| {
                libc::signal(libc::SIGINT, libc::SIG_IGN);
                Ok(())
            });
        }
        started(&mut cmd);
        let out = cmd.output().expect("cat runs");
        assert!(out.status.success());
        String::from_utf8(out.stdout).unwrap()
    }

    #[test]
    fn a_child_can_be_interrupted_even_when_this_program_runs_in_the_background() {
        // The set-up does what it says: without die_with_parent the child
        // inherits SIGINT ignored, and interrupt() would not reach it.
        assert!(ignores_sigint(&status_of_a_background_child(|_| {})));
        assert!(!ignores_sigint(&status_of_a_background_child(
            die_with_parent
        )));
    }
}
