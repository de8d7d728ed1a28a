//! Starting a firmware image under QEMU with its protocol UART on a Unix
//! socket.
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
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context};

use crate::link::{open_port, SerialDevice};

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
    /// board's clock depends on host scheduling, and the two images spend
    /// their waiting time differently: the mps2-an386 image spins, so
    /// under `-icount shift=0` its clock advances only with the
    /// instructions QEMU manages to execute (0.06–0.23× wall time here),
    /// and 250 ms of its clock is 1–4 s of a stalled host; the STM32F4
    /// image sleeps in WFI between interrupts, and QEMU then advances its
    /// clock with wall time (0.9× here, as a real board's), so the same
    /// slack against a stalled host needs about 1 s.
    pub const fn hil_link_timeout_ms(self) -> u16 {
        match self {
            QemuBoard::Mps2An386 => 250,
            QemuBoard::Stm32f4 => 1000,
        }
    }

    /// QEMU's machine and the serial ports before the board's protocol
    /// UART (on `null`); the protocol UART's `-serial` follows.
    fn machine_args(self) -> &'static [&'static str] {
        match self {
            QemuBoard::Mps2An386 => &["-cpu", "cortex-m4", "-machine", "mps2-an386"],
            // USART1 is serial0, USART2 (the Nucleo's virtual COM port,
            // the image's protocol UART) serial1.
            QemuBoard::Stm32f4 => &["-machine", "netduinoplus2", "-serial", "null"],
        }
    }
}

/// A running QEMU; killed when dropped (and its socket removed).
pub struct Qemu {
    child: Child,
    /// The guest's protocol UART, as a port for [`open_port`]: `unix:PATH`
    /// (see [`Qemu::connect`]).
    pub port: String,
    socket: PathBuf,
    lines: mpsc::Receiver<String>,
}

impl Qemu {
    /// Starts `qemu-system-arm` (the `board`'s machine, semihosting on,
    /// the protocol UART on a Unix socket) with `image`, and waits until the
    /// socket is there; `icount` adds `-icount shift=0` (one instruction
    /// per virtual ns: the guest's clock then follows the instructions it
    /// executes, not the host's clock).
    pub fn launch(board: QemuBoard, image: &Path, icount: bool) -> anyhow::Result<Self> {
        if !image.exists() {
            bail!(
                "firmware image {} not found; build it with `{}`",
                image.display(),
                board.build_command()
            );
        }
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
        let mut qemu = Self {
            child,
            port: format!("unix:{}", socket.display()),
            socket,
            lines: rx,
        };
        let deadline = Instant::now() + Duration::from_secs(10);
        while !qemu.socket.exists() {
            if !qemu.is_running() || Instant::now() > deadline {
                bail!(
                    "qemu did not open its socket {} within 10 s; it printed: {}",
                    qemu.socket.display(),
                    qemu.output().join(" | ")
                );
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        Ok(qemu)
    }

    /// Connects to the guest's UART. QEMU creates its socket before it
    /// listens on it, so a refused connection is tried again for up to
    /// 10 s while QEMU runs.
    pub fn connect(&mut self) -> anyhow::Result<SerialDevice> {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            match open_port(&self.port, 0) {
                Ok(port) => return Ok(port),
                Err(e) if Instant::now() > deadline || !self.is_running() => {
                    return Err(e.context(format!("QEMU printed: {}", self.output().join(" | "))))
                }
                Err(_) => std::thread::sleep(Duration::from_millis(10)),
            }
        }
    }

    /// Lines QEMU printed since the last call (semihosting output, errors).
    pub fn output(&self) -> Vec<String> {
        self.lines.try_iter().collect()
    }

    /// True while QEMU runs.
    pub fn is_running(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.socket);
    }
}
