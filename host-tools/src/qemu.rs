//! Starting the firmware image under QEMU with its UART on a pty, and
//! telling how it ended.
//!
//! QEMU dies with its parent however the parent ends: it is dropped (and
//! killed) when `softjoint` returns, including after SIGINT/SIGTERM (which
//! end the run cleanly, `crate::stop`); it runs in its own process group,
//! so a Ctrl-C in the terminal reaches `softjoint` (which ends the run and
//! then QEMU) rather than killing QEMU under a running lockstep; and on
//! Linux it gets `PR_SET_PDEATHSIG` = SIGKILL, so even a `softjoint` killed
//! with SIGKILL leaves no QEMU behind. (The death signal follows the
//! *thread* that started QEMU: start it from the thread that uses it.)
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};

/// Where `cargo build -p firmware --release --target thumbv7em-none-eabihf`
/// puts the image, relative to the workspace root.
pub const DEFAULT_IMAGE: &str = "target/thumbv7em-none-eabihf/release/softjoint-fw";

/// The command that builds the image.
pub const BUILD_IMAGE: &str =
    "cargo build -p firmware --release --target thumbv7em-none-eabihf --bin softjoint-fw";

/// Where to look for the image when `--image` is not given, best first:
/// beside the running program (`softjoint` in `target/<profile>/`, the
/// image in `target/thumbv7em-none-eabihf/release/`), the workspace this
/// program was built from, and the working directory. A relative default
/// alone made `hil` fail outside the repository.
pub fn image_candidates() -> Vec<PathBuf> {
    image_candidates_for(std::env::current_exe().ok().as_deref())
}

/// [`image_candidates`] for a program at `exe`.
pub fn image_candidates_for(exe: Option<&Path>) -> Vec<PathBuf> {
    let mut out = Vec::new();
    // target/<profile>/softjoint → target/
    if let Some(target) = exe.and_then(Path::parent).and_then(Path::parent) {
        out.push(target.join("thumbv7em-none-eabihf/release/softjoint-fw"));
    }
    if let Some(workspace) = Path::new(env!("CARGO_MANIFEST_DIR")).parent() {
        out.push(workspace.join(DEFAULT_IMAGE));
    }
    out.push(PathBuf::from(DEFAULT_IMAGE));
    out.dedup();
    out
}

/// The first of [`image_candidates`] that exists, or an error listing
/// where it looked and how to build the image or give one with `--image`.
pub fn default_image() -> anyhow::Result<PathBuf> {
    let candidates = image_candidates();
    if let Some(found) = candidates.iter().find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
    bail!(
        "no firmware image found (looked in {}); give one with --image PATH, or build it in the softjoint workspace with `{BUILD_IMAGE}`",
        looked.join(", ")
    )
}

/// A running QEMU; killed when dropped.
pub struct Qemu {
    child: Child,
    /// The pty QEMU connected the guest's UART0 to.
    pub pty: PathBuf,
    lines: mpsc::Receiver<String>,
    /// The last lines QEMU printed (its own error messages among them).
    tail: Vec<String>,
    /// QMP control socket (see [`Qemu::launch_with_control`]).
    qmp: Option<PathBuf>,
}

/// Lines of QEMU's output kept for messages.
const TAIL_LINES: usize = 5;

/// How a process ended, for a person: `exited with status 1`, `was killed
/// by signal 9 (SIGKILL)`.
pub fn describe_exit(status: ExitStatus) -> String {
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt as _;
        if let Some(sig) = status.signal() {
            let name = signal_hook::low_level::signal_name(sig).unwrap_or("unknown signal");
            return format!("was killed by signal {sig} ({name})");
        }
    }
    match status.code() {
        Some(c) => format!("exited with status {c}"),
        None => "ended".to_string(),
    }
}

/// Makes `cmd`'s process die with this thread (Linux: `PR_SET_PDEATHSIG`)
/// and puts it in its own process group.
fn die_with_parent(cmd: &mut Command) {
    #[cfg(unix)]
    {
        use std::os::unix::process::CommandExt as _;
        cmd.process_group(0);
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
                    return Err(std::io::Error::other("parent exited while starting qemu"));
                }
                Ok(())
            });
        }
    }
}

impl Qemu {
    /// Starts `qemu-system-arm` (machine mps2-an386, semihosting on, UART0
    /// on a pty) with `image`; `icount` adds `-icount shift=0` (one
    /// instruction per virtual ns, for instruction counting).
    pub fn launch(image: &Path, icount: bool) -> anyhow::Result<Self> {
        Self::start(image, icount, None)
    }

    /// [`Qemu::launch`] with a QMP control socket at `qmp` (a Unix socket
    /// path), through which [`Qemu::reset`] resets the board.
    pub fn launch_with_control(image: &Path, icount: bool, qmp: &Path) -> anyhow::Result<Self> {
        Self::start(image, icount, Some(qmp))
    }

    fn start(image: &Path, icount: bool, qmp: Option<&Path>) -> anyhow::Result<Self> {
        if !image.exists() {
            bail!(
                "firmware image {} not found; check the --image path, or build the image in the softjoint workspace with `{BUILD_IMAGE}`",
                image.display()
            );
        }
        check_elf(image)?;
        let mut cmd = Command::new("qemu-system-arm");
        cmd.args([
            "-cpu",
            "cortex-m4",
            "-machine",
            "mps2-an386",
            "-nographic",
            "-monitor",
            "none",
        ])
        .args([
            "-semihosting-config",
            "enable=on,target=native",
            "-serial",
            "pty",
        ]);
        if icount {
            cmd.args(["-icount", "shift=0"]);
        }
        if let Some(q) = qmp {
            cmd.arg("-qmp")
                .arg(format!("unix:{},server=on,wait=off", q.display()));
        }
        die_with_parent(&mut cmd);
        cmd.arg("-kernel")
            .arg(image)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().context(
            "cannot start qemu-system-arm (is it installed? apt-get install qemu-system-arm)",
        )?;
        let stdout = child.stdout.take().context("qemu stdout")?;
        let stderr = child.stderr.take().context("qemu stderr")?;
        let (tx, rx) = mpsc::channel();
        let tx2 = tx.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                if tx2.send(line).is_err() {
                    break;
                }
            }
        });
        let mut seen: Vec<String> = Vec::new();
        let started = Instant::now();
        let pty = loop {
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(line) => {
                    // QEMU 7.2: "char device redirected to /dev/pts/N (label serial0)"
                    if let Some(rest) = line.split("redirected to ").nth(1) {
                        let path = rest.split_whitespace().next().unwrap_or_default();
                        break PathBuf::from(path);
                    }
                    seen.push(line);
                }
                Err(_) => {
                    if let Ok(Some(status)) = child.try_wait() {
                        // Its output threads may still hold its last lines.
                        seen.extend(rx.recv_timeout(Duration::from_millis(200)).ok());
                        seen.extend(rx.try_iter());
                        bail!(
                            "qemu-system-arm {} before reporting its pty{}",
                            describe_exit(status),
                            said(&seen)
                        );
                    }
                    if started.elapsed() >= Duration::from_secs(10) {
                        let _ = child.kill();
                        let _ = child.wait();
                        bail!(
                            "qemu-system-arm did not report its pty within 10 s{}",
                            said(&seen)
                        );
                    }
                }
            }
        };
        let mut q = Self {
            child,
            pty,
            lines: rx,
            tail: Vec::new(),
            qmp: qmp.map(Path::to_path_buf),
        };
        q.keep_tail(&seen);
        Ok(q)
    }

    /// Lines QEMU printed since the last call (semihosting output, errors).
    pub fn output(&mut self) -> Vec<String> {
        let new: Vec<String> = self.lines.try_iter().collect();
        self.keep_tail(&new);
        new
    }

    /// Keeps QEMU's own last messages (`qemu-system-arm: …`, `qemu: fatal:
    /// …`), not the register dumps that follow them.
    fn keep_tail(&mut self, new: &[String]) {
        self.tail.extend(
            new.iter()
                .filter(|l| l.starts_with("qemu") && !l.contains("redirected to"))
                .cloned(),
        );
        let extra = self.tail.len().saturating_sub(TAIL_LINES);
        self.tail.drain(..extra);
    }

    /// True while QEMU runs.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// The process id (tests look for it after its parent is gone).
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// If QEMU has ended, or ends within `wait` (a pty can report the hang
    /// up a moment before the process is gone), how — its exit status or
    /// signal and its last words, e.g. `qemu-system-arm was killed by
    /// signal 9 (SIGKILL)` or `… exited with status 1; it said: …could not
    /// load kernel…`.
    pub fn ended(&mut self, wait: Duration) -> Option<String> {
        let until = Instant::now() + wait;
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(status)) => break status,
                Ok(None) if Instant::now() < until => std::thread::sleep(Duration::from_millis(20)),
                _ => return None,
            }
        };
        let new: Vec<String> = self
            .lines
            .recv_timeout(Duration::from_millis(200))
            .ok()
            .into_iter()
            .chain(self.lines.try_iter())
            .collect();
        self.keep_tail(&new);
        let words: Vec<String> = self
            .tail
            .iter()
            .filter(|l| !l.contains("redirected to"))
            .cloned()
            .collect();
        Some(format!(
            "qemu-system-arm {}{}",
            describe_exit(status),
            said(&words)
        ))
    }

    /// Resets the emulated board (QMP `system_reset`) as a reset button
    /// would: the firmware starts again from its reset vector, the UART's
    /// pty stays open. Needs [`Qemu::launch_with_control`].
    #[cfg(unix)]
    pub fn reset(&mut self) -> anyhow::Result<()> {
        use std::io::Write as _;
        let path = self
            .qmp
            .as_ref()
            .context("qemu was started without a control socket")?;
        let stream = std::os::unix::net::UnixStream::connect(path)
            .with_context(|| format!("cannot connect to QMP at {}", path.display()))?;
        stream.set_read_timeout(Some(Duration::from_secs(5)))?;
        let mut reader = BufReader::new(stream.try_clone()?);
        let mut writer = stream;
        let mut line = String::new();
        reader.read_line(&mut line)?; // greeting
        for cmd in ["qmp_capabilities", "system_reset"] {
            writeln!(writer, "{{\"execute\": \"{cmd}\"}}")?;
            loop {
                line.clear();
                if reader.read_line(&mut line)? == 0 {
                    bail!("QMP closed while waiting for `{cmd}`");
                }
                if line.contains("\"return\"") {
                    break;
                }
                if line.contains("\"error\"") {
                    bail!("QMP refused `{cmd}`: {}", line.trim());
                }
            }
        }
        Ok(())
    }
}

/// Refuses an image QEMU would not run as firmware: a directory, an
/// unreadable file, a file that is not a 32-bit little-endian ARM ELF
/// (QEMU loads any other file as a raw binary at address 0 and runs the
/// bytes, which then never answer), or one cut short (a segment that ends
/// past the end of the file: a copy or build that did not finish).
fn check_elf(image: &Path) -> anyhow::Result<()> {
    if image.is_dir() {
        bail!(
            "firmware image {} is a directory, not an ELF file; build the image with `{BUILD_IMAGE}`",
            image.display()
        );
    }
    let bytes = std::fs::read(image)
        .with_context(|| format!("cannot read firmware image {}", image.display()))?;
    let head = bytes.get(..4).unwrap_or(&bytes);
    if head != b"\x7fELF" {
        bail!(
            "firmware image {} is not an ELF file (it starts with `{}`); build the image with `{BUILD_IMAGE}`",
            image.display(),
            head.escape_ascii()
        );
    }
    let u16_at = |o: usize| {
        bytes
            .get(o..o + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
    };
    let u32_at = |o: usize| {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
    };
    // ELF32 header: class 1 (32-bit), data 1 (little endian), e_machine 40
    // (ARM) at 0x12; program headers at e_phoff (0x1C), e_phentsize (0x2A)
    // bytes each, e_phnum (0x2C) of them.
    if bytes.get(4..6) != Some(&[1, 1]) || u16_at(0x12) != Some(40) {
        bail!(
            "firmware image {} is an ELF file for another machine (not 32-bit little-endian ARM); build the image with `{BUILD_IMAGE}`",
            image.display()
        );
    }
    let cut = |what: &str| {
        anyhow::anyhow!(
            "firmware image {} is cut short ({what} past its {} bytes); build the image again with `{BUILD_IMAGE}`",
            image.display(),
            bytes.len()
        )
    };
    let (Some(phoff), Some(phentsize), Some(phnum)) = (u32_at(0x1C), u16_at(0x2A), u16_at(0x2C))
    else {
        return Err(cut("its header runs"));
    };
    for k in 0..usize::from(phnum) {
        let ph = phoff + k * usize::from(phentsize);
        let (Some(offset), Some(filesz)) = (u32_at(ph + 4), u32_at(ph + 16)) else {
            return Err(cut("its program headers run"));
        };
        if offset + filesz > bytes.len() {
            return Err(cut(&format!("segment {k} runs")));
        }
    }
    Ok(())
}

/// `; it said: a | b` for QEMU's lines, or nothing.
fn said(lines: &[String]) -> String {
    if lines.is_empty() {
        String::new()
    } else {
        format!("; it said: {}", lines.join(" | "))
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_image_is_looked_for_beside_the_program_first() {
        let c = image_candidates_for(Some(Path::new("/opt/sj/target/release/softjoint")));
        assert_eq!(
            c[0],
            Path::new("/opt/sj/target/thumbv7em-none-eabihf/release/softjoint-fw")
        );
        // Then the workspace it was built from (absolute), then the
        // working directory.
        assert!(c[1].is_absolute() && c[1].ends_with(DEFAULT_IMAGE), "{c:?}");
        assert_eq!(c.last().unwrap(), Path::new(DEFAULT_IMAGE));
    }
}
