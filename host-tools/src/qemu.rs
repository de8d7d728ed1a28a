//! Starting the firmware image under QEMU with its UART on a pty.
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

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
}

impl Qemu {
    /// Starts `qemu-system-arm` (machine mps2-an386, semihosting on, UART0
    /// on a pty) with `image`; `icount` adds `-icount shift=0` (one
    /// instruction per virtual ns, for instruction counting).
    pub fn launch(image: &Path, icount: bool) -> anyhow::Result<Self> {
        if !image.exists() {
            bail!(
                "firmware image {} not found; check the --image path, or build the image in the softjoint workspace with `{BUILD_IMAGE}`",
                image.display()
            );
        }
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
                    // QEMU 7.2: "char device redirected to /dev/pts/N (label serial0)"
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
