//! Starting a firmware image under QEMU with its protocol UART on a Unix
//! socket, and telling how it ended.
//!
//! Two boards: the mps2-an386 image (`softjoint-fw`, CMSDK UART0) and the
//! STM32F4 board image in its QEMU flavour (`softjoint-stm32f4-qemu`) on
//! `netduinoplus2`, an STM32F405, whose USART2 is QEMU's second serial
//! port: `-serial null -serial unix:…`.
//!
//! The UART is a Unix socket QEMU listens on (`server=on,wait=off`), not a
//! pty. QEMU 7.2's pty backend, on this machine's kernel (Linux 6.18),
//! stops polling its end of the pty within seconds of the host opening
//! the other end when the line is idle, and now and then in the middle of
//! a lockstep run: the guest's UART then stays empty and every request goes
//! unanswered (`strace` of QEMU: the pty no longer in its poll set; a
//! connected socket stays in it). As with a pty, QEMU drops what the guest
//! writes before the host connects, so the host speaks first.
//!
//! QEMU dies with its parent however the parent ends: it is dropped (and
//! killed) when `softjoint` returns, including after SIGINT, SIGTERM or
//! SIGHUP (which end the run cleanly, `crate::stop`); it runs in its own
//! process group,
//! so a Ctrl-C in the terminal reaches `softjoint` (which ends the run and
//! then QEMU) rather than killing QEMU under a running lockstep; and on
//! Linux it gets `PR_SET_PDEATHSIG` = SIGKILL, so even a `softjoint` killed
//! with SIGKILL leaves no QEMU behind (`crate::stop::die_with_parent`; the
//! death signal follows the *thread* that started QEMU: start it from the
//! thread that uses it).
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};

use crate::board::link::{open_port, SerialDevice};

/// Where `cargo build -p firmware --release --target thumbv7em-none-eabihf`
/// puts the mps2-an386 image, relative to the workspace root.
pub const DEFAULT_IMAGE: &str = QemuBoard::Mps2An386.default_image();

/// The command that builds the mps2-an386 image.
pub const BUILD_IMAGE: &str = QemuBoard::Mps2An386.build_command();

/// A board image QEMU can run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum QemuBoard {
    /// QEMU's `mps2-an386` (Cortex-M4F FPGA image), image `softjoint-fw`.
    #[default]
    #[value(name = "mps2-an386")]
    Mps2An386,
    /// The STM32F4 board image (firmware/stm32f4) in its QEMU flavour on
    /// `netduinoplus2` (STM32F405), image `softjoint-stm32f4-qemu`.
    #[value(name = "stm32f4")]
    Stm32f4,
}

impl QemuBoard {
    /// The image's path relative to the workspace root.
    pub const fn default_image(self) -> &'static str {
        match self {
            QemuBoard::Mps2An386 => "target/thumbv7em-none-eabihf/release/softjoint-fw",
            QemuBoard::Stm32f4 => "target/thumbv7em-none-eabihf/release/softjoint-stm32f4-qemu",
        }
    }

    /// The command (from the workspace root) that builds the image.
    pub const fn build_command(self) -> &'static str {
        match self {
            QemuBoard::Mps2An386 => {
                "cargo build -p firmware --release --target thumbv7em-none-eabihf --bin softjoint-fw"
            }
            QemuBoard::Stm32f4 => {
                "(cd firmware/stm32f4 && cargo build --release --bin softjoint-stm32f4-qemu)"
            }
        }
    }

    /// The link-loss timeout (ms of the board's clock) `softjoint hil`
    /// sets on this board under QEMU, unless told otherwise. An emulated
    /// board's clock depends on host scheduling: both images sleep in WFI
    /// between interrupts, and under `-icount shift=0` QEMU then advances
    /// their clock with wall time (0.9× here, as a real board's), so 1 s
    /// is the slack against a stalled host. (The mps2-an386 image spun in
    /// its loop until issue 27's CI work, its clock then at 0.06–0.23×
    /// wall time, and this was 250 ms for it.)
    pub const fn hil_link_timeout_ms(self) -> u16 {
        match self {
            QemuBoard::Mps2An386 | QemuBoard::Stm32f4 => 1000,
        }
    }

    /// QEMU's machine and the serial ports before the board's protocol
    /// UART (on `null`); the protocol UART's `-serial` follows.
    pub const fn machine_args(self) -> &'static [&'static str] {
        match self {
            QemuBoard::Mps2An386 => &["-cpu", "cortex-m4", "-machine", "mps2-an386"],
            // USART1 is serial0, USART2 (the Nucleo's virtual COM port,
            // the image's protocol UART) serial1.
            QemuBoard::Stm32f4 => &["-machine", "netduinoplus2", "-serial", "null"],
        }
    }
}

/// A running QEMU; killed when dropped (and its socket removed).
/// Where to look for the image when `--image` is not given, best first:
/// beside the running program (`softjoint` in `target/<profile>/`, the
/// image in `target/thumbv7em-none-eabihf/release/`), the workspace this
/// program was built from, and the working directory. A relative default
/// alone made `hil` fail outside the repository.
pub fn image_candidates(board: QemuBoard) -> Vec<PathBuf> {
    image_candidates_for(board, std::env::current_exe().ok().as_deref())
}

/// [`image_candidates`] for a program at `exe`.
pub fn image_candidates_for(board: QemuBoard, exe: Option<&Path>) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let relative = board.default_image();
    // target/<profile>/softjoint → target/
    if let (Some(target), Some(in_target)) = (
        exe.and_then(Path::parent).and_then(Path::parent),
        relative.strip_prefix("target/"),
    ) {
        out.push(target.join(in_target));
    }
    if let Some(workspace) = Path::new(env!("CARGO_MANIFEST_DIR")).parent() {
        out.push(workspace.join(relative));
    }
    out.push(PathBuf::from(relative));
    out.dedup();
    out
}

/// The first of [`image_candidates`] that exists, or an error listing
/// where it looked and how to build the image or give one with `--image`.
pub fn default_image(board: QemuBoard) -> anyhow::Result<PathBuf> {
    let candidates = image_candidates(board);
    if let Some(found) = candidates.iter().find(|p| p.is_file()) {
        return Ok(found.clone());
    }
    let looked: Vec<String> = candidates.iter().map(|p| p.display().to_string()).collect();
    bail!(
        "no firmware image found (looked in {}); give one with --image PATH, or build it in the softjoint workspace with `{}`",
        looked.join(", "),
        board.build_command()
    )
}

/// A running QEMU; killed when dropped (and its socket removed).
pub struct Qemu {
    child: Child,
    /// The guest's protocol UART, as a port for [`open_port`]: `unix:PATH`
    /// (see [`Qemu::connect`]).
    pub port: String,
    socket: PathBuf,
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

impl Qemu {
    /// Starts `qemu-system-arm` (the `board`'s machine, semihosting on,
    /// the protocol UART on a Unix socket) with `image`, and waits until the
    /// socket is there; `icount` adds `-icount shift=0` (one instruction
    /// per virtual ns: the guest's clock then follows the instructions it
    /// executes, not the host's clock). [`Qemu::connect`] connects to it.
    pub fn launch(board: QemuBoard, image: &Path, icount: bool) -> anyhow::Result<Self> {
        Self::start(board, image, icount, None)
    }

    /// [`Qemu::launch`] with a QMP control socket at `qmp` (a Unix socket
    /// path), through which [`Qemu::reset`] resets the board.
    pub fn launch_with_control(
        board: QemuBoard,
        image: &Path,
        icount: bool,
        qmp: &Path,
    ) -> anyhow::Result<Self> {
        Self::start(board, image, icount, Some(qmp))
    }

    fn start(
        board: QemuBoard,
        image: &Path,
        icount: bool,
        qmp: Option<&Path>,
    ) -> anyhow::Result<Self> {
        if !image.exists() {
            bail!(
                "firmware image {} not found; check the --image path, or build the image in the softjoint workspace with `{}`",
                image.display(),
                board.build_command()
            );
        }
        check_elf(image, board.build_command())?;
        static LAUNCHED: AtomicU32 = AtomicU32::new(0);
        let socket = std::env::temp_dir().join(format!(
            "softjoint-qemu-{}-{}.sock",
            std::process::id(),
            LAUNCHED.fetch_add(1, Ordering::Relaxed)
        ));
        let _ = std::fs::remove_file(&socket);
        let mut cmd = Command::new("qemu-system-arm");
        cmd.args(board.machine_args())
            .arg("-serial")
            .arg(format!("unix:{},server=on,wait=off", socket.display()))
            .args(["-nographic", "-monitor", "none"])
            .args(["-semihosting-config", "enable=on,target=native"]);
        if icount {
            cmd.args(["-icount", "shift=0"]);
        }
        if let Some(q) = qmp {
            cmd.arg("-qmp")
                .arg(format!("unix:{},server=on,wait=off", q.display()));
        }
        crate::stop::die_with_parent(&mut cmd);
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
        let mut q = Self {
            child,
            port: format!("unix:{}", socket.display()),
            socket,
            lines: rx,
            tail: Vec::new(),
            qmp: qmp.map(Path::to_path_buf),
        };
        // QEMU creates the socket once it has parsed its options and
        // opened its devices; an image or option it cannot use ends it
        // before that.
        let started = Instant::now();
        while !q.socket.exists() {
            if let Some(how) = q.ended(Duration::ZERO) {
                bail!("{how} before opening its serial socket");
            }
            if started.elapsed() >= Duration::from_secs(10) {
                let seen = q.output();
                bail!(
                    "qemu-system-arm did not open its serial socket {} within 10 s{}",
                    q.socket.display(),
                    said(&seen)
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(q)
    }

    /// Connects to the guest's UART. QEMU creates its socket before it
    /// listens on it, so a refused connection is tried again for up to
    /// 10 s while QEMU runs.
    pub fn connect(&mut self) -> anyhow::Result<SerialDevice> {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            match open_port(&self.port, 0) {
                Ok(port) => return Ok(port),
                Err(e) => {
                    if let Some(how) = self.ended(Duration::ZERO) {
                        return Err(e.context(how));
                    }
                    if Instant::now() > deadline {
                        let seen = self.output();
                        return Err(e.context(format!(
                            "QEMU runs but does not accept connections{}",
                            said(&seen)
                        )));
                    }
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        }
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

    /// If QEMU has ended, or ends within `wait` (the serial line can report
    /// the hang up a moment before the process is gone), how — its exit status or
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
    /// socket stays connected. Needs [`Qemu::launch_with_control`].
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
fn check_elf(image: &Path, build: &str) -> anyhow::Result<()> {
    if image.is_dir() {
        bail!(
            "firmware image {} is a directory, not an ELF file; build the image with `{build}`",
            image.display()
        );
    }
    let bytes = std::fs::read(image)
        .with_context(|| format!("cannot read firmware image {}", image.display()))?;
    let head = bytes.get(..4).unwrap_or(&bytes);
    if head != b"\x7fELF" {
        bail!(
            "firmware image {} is not an ELF file (it starts with `{}`); build the image with `{build}`",
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
            "firmware image {} is an ELF file for another machine (not 32-bit little-endian ARM); build the image with `{build}`",
            image.display()
        );
    }
    let cut = |what: &str| {
        anyhow::anyhow!(
            "firmware image {} is cut short ({what} past its {} bytes); build the image again with `{build}`",
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
        let _ = std::fs::remove_file(&self.socket);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_image_is_looked_for_beside_the_program_first() {
        let exe = Path::new("/opt/sj/target/release/softjoint");
        for (board, name) in [
            (QemuBoard::Mps2An386, "softjoint-fw"),
            (QemuBoard::Stm32f4, "softjoint-stm32f4-qemu"),
        ] {
            let c = image_candidates_for(board, Some(exe));
            assert_eq!(
                c[0],
                Path::new("/opt/sj/target/thumbv7em-none-eabihf/release").join(name)
            );
            // Then the workspace it was built from (absolute), then the
            // working directory.
            assert!(
                c[1].is_absolute() && c[1].ends_with(board.default_image()),
                "{c:?}"
            );
            assert_eq!(c.last().unwrap(), Path::new(board.default_image()));
        }
    }
}
