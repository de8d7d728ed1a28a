//! Starting a firmware image under QEMU with its UART on a pty.
//!
//! Two boards: the mps2-an386 image (`softjoint-fw`, CMSDK UART0) and the
//! STM32F4 board image in its QEMU flavour (`softjoint-stm32f4-qemu`) on
//! `netduinoplus2`, an STM32F405, whose USART2 is QEMU's second serial
//! port: `-serial null -serial pty`.
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{bail, Context};

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

    /// QEMU's machine and the serial ports: the board's protocol UART on a
    /// pty, any UART before it on `null`.
    fn machine_args(self) -> &'static [&'static str] {
        match self {
            QemuBoard::Mps2An386 => &[
                "-cpu",
                "cortex-m4",
                "-machine",
                "mps2-an386",
                "-serial",
                "pty",
            ],
            // USART1 is serial0, USART2 (the Nucleo's virtual COM port,
            // the image's protocol UART) serial1.
            QemuBoard::Stm32f4 => &[
                "-machine",
                "netduinoplus2",
                "-serial",
                "null",
                "-serial",
                "pty",
            ],
        }
    }
}

/// A running QEMU; killed when dropped.
pub struct Qemu {
    child: Child,
    /// The pty QEMU connected the guest's protocol UART to.
    pub pty: PathBuf,
    lines: mpsc::Receiver<String>,
}

impl Qemu {
    /// Starts `qemu-system-arm` (the `board`'s machine, semihosting on,
    /// the protocol UART on a pty) with `image`; `icount` adds `-icount
    /// shift=0` (one instruction per virtual ns: the guest's clock then
    /// follows the instructions it executes, not the host's clock).
    pub fn launch(board: QemuBoard, image: &Path, icount: bool) -> anyhow::Result<Self> {
        if !image.exists() {
            bail!(
                "firmware image {} not found; build it with `{}`",
                image.display(),
                board.build_command()
            );
        }
        let mut cmd = Command::new("qemu-system-arm");
        cmd.args(board.machine_args())
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
        let mut seen = Vec::new();
        let pty = loop {
            match rx.recv_timeout(Duration::from_secs(10)) {
                Ok(line) => {
                    // QEMU 7.2: "char device redirected to /dev/pts/N (label
                    // serial0)"; a `null` port prints nothing.
                    if let Some(rest) = line.split("redirected to ").nth(1) {
                        let path = rest.split_whitespace().next().unwrap_or_default();
                        break PathBuf::from(path);
                    }
                    seen.push(line);
                }
                Err(_) => {
                    let _ = child.kill();
                    bail!(
                        "qemu did not report its pty within 10 s; it printed: {}",
                        seen.join(" | ")
                    );
                }
            }
        };
        Ok(Self {
            child,
            pty,
            lines: rx,
        })
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
    }
}
