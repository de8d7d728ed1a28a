//! Where results go: standard output that reports a failed write instead
//! of panicking, and files a user keeps written atomically.
//!
//! - [`outln!`](crate::outln) and [`out!`](crate::out) print like
//!   `println!`/`print!`, but a failed write (`> /dev/full`, a closed pipe)
//!   is an [`StdoutError`] returned with `?`, never a panic.
//! - [`AtomicFile`]: a file is written to a temporary file in the same
//!   directory and renamed over its target only when complete, so a write
//!   that fails (disk full, a file-size limit, an interrupted run) leaves
//!   the previous file as it was. Creating the temporary file is also the
//!   check that the path can be written: commands create it before a long
//!   computation and fill it after.
//!
//! Streamed traces (`sim`/`hil --csv`) are the exception: they are written
//! as the run goes (see `crate::trace`) and say whether they are complete.
use std::fmt;
use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// A write to standard output failed.
#[derive(Debug, thiserror::Error)]
#[error("cannot write to standard output: {0}")]
pub struct StdoutError(pub io::Error);

impl StdoutError {
    /// Whether the reader went away (`softjoint … | head -1`): shells
    /// report that as SIGPIPE, not as an error.
    pub fn is_broken_pipe(&self) -> bool {
        self.0.kind() == io::ErrorKind::BrokenPipe
    }
}

/// Writes formatted text to standard output (what [`outln!`](crate::outln)
/// and [`out!`](crate::out) expand to).
pub fn stdout(args: fmt::Arguments) -> Result<(), StdoutError> {
    io::stdout().lock().write_fmt(args).map_err(StdoutError)
}

/// Flushes standard output; a program calls it before it exits so that a
/// last line without a newline cannot fail unseen.
pub fn flush_stdout() -> Result<(), StdoutError> {
    io::stdout().lock().flush().map_err(StdoutError)
}

/// `println!` that returns a failed write with `?` instead of panicking.
#[macro_export]
macro_rules! outln {
    () => { $crate::output::stdout(format_args!("\n"))? };
    ($($arg:tt)*) => {
        $crate::output::stdout(format_args!("{}\n", format_args!($($arg)*)))?
    };
}

/// `print!` that returns a failed write with `?` instead of panicking.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::output::stdout(format_args!($($arg)*))? };
}

/// A file being written atomically: the temporary file exists from
/// [`AtomicFile::create`] on; [`AtomicFile::commit`] fills it, flushes it
/// to disk and renames it over the target. Dropped without a commit, it
/// removes the temporary file and leaves the target untouched.
#[derive(Debug)]
pub struct AtomicFile {
    target: PathBuf,
    temp: PathBuf,
    file: Option<File>,
}

/// Distinguishes temporary files of one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

impl AtomicFile {
    /// Creates the temporary file beside `target` (so the final rename
    /// stays on one file system). Fails, naming `target`, if its directory
    /// does not exist or cannot be written, or if `target` is a directory.
    pub fn create(target: &Path) -> anyhow::Result<Self> {
        let name = target
            .file_name()
            .ok_or_else(|| anyhow::anyhow!("cannot write {}: not a file name", target.display()))?;
        if target.is_dir() {
            anyhow::bail!("cannot write {}: it is a directory", target.display());
        }
        let dir = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let temp = dir.join(format!(
            ".{}.{}-{}.tmp",
            name.to_string_lossy(),
            std::process::id(),
            TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
        ));
        let file = fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&temp)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", target.display()))?;
        Ok(Self {
            target: target.to_path_buf(),
            temp,
            file: Some(file),
        })
    }

    /// The file this will replace.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Writes `bytes`, flushes them to disk and renames the temporary file
    /// over the target (keeping the target's permissions if it existed).
    pub fn commit(mut self, bytes: &[u8]) -> anyhow::Result<()> {
        let fail =
            |e: io::Error, target: &Path| anyhow::anyhow!("cannot write {}: {e}", target.display());
        let mut file = self
            .file
            .take()
            .ok_or_else(|| fail(io::ErrorKind::Other.into(), &self.target))?;
        file.write_all(bytes)
            .and_then(|()| file.sync_all())
            .map_err(|e| fail(e, &self.target))?;
        if let Ok(meta) = fs::metadata(&self.target) {
            // Best effort: a file the user made readable to others stays so.
            let _ = fs::set_permissions(&self.temp, meta.permissions());
        }
        drop(file);
        fs::rename(&self.temp, &self.target).map_err(|e| fail(e, &self.target))?;
        // Renamed: nothing left to clean up.
        self.temp = PathBuf::new();
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.temp.as_os_str().is_empty() {
            self.file = None;
            let _ = fs::remove_file(&self.temp);
        }
    }
}

/// Checks, before a long computation rather than after it, that files can
/// be written in the output directory `dir`: the directory or, if it does
/// not exist yet, its nearest existing ancestor must be a directory this
/// process can write in. Nothing is left behind (a refused run creates no
/// directory); [`create_dir`] makes it when the results are written.
pub fn check_dir(dir: &Path) -> anyhow::Result<()> {
    let mut probe = dir;
    while !probe.exists() {
        match probe.parent() {
            Some(p) if !p.as_os_str().is_empty() => probe = p,
            _ => {
                probe = Path::new(".");
                break;
            }
        }
    }
    if !probe.is_dir() {
        anyhow::bail!(
            "cannot write in {}: {} is not a directory",
            dir.display(),
            probe.display()
        );
    }
    drop(
        AtomicFile::create(&probe.join("write-check"))
            .map_err(|e| anyhow::anyhow!("cannot write in {}: {e:#}", dir.display()))?,
    );
    Ok(())
}

/// Creates the output directory `dir` (and its parents).
pub fn create_dir(dir: &Path) -> anyhow::Result<()> {
    fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))
}

/// Writes `bytes` to `path` atomically (see [`AtomicFile`]).
pub fn write_atomic(path: &Path, bytes: impl AsRef<[u8]>) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit(bytes.as_ref())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_commit_replaces_the_file_and_a_drop_leaves_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("keep.toml");
        fs::write(&p, "old").unwrap();
        let pending = AtomicFile::create(&p).unwrap();
        drop(pending);
        assert_eq!(fs::read_to_string(&p).unwrap(), "old");
        write_atomic(&p, "new").unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "new");
        // No temporary files left behind either way.
        let names: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("keep.toml")]);
    }

    #[test]
    fn unwritable_targets_are_refused_by_name_before_any_work() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no-such-dir").join("x.csv");
        let e = AtomicFile::create(&missing).unwrap_err().to_string();
        assert!(e.contains("no-such-dir/x.csv"), "{e}");
        let e = AtomicFile::create(dir.path()).unwrap_err().to_string();
        assert!(e.contains("is a directory"), "{e}");
    }
}
