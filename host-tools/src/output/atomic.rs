//! Files a user keeps, written atomically: to a temporary file in the same
//! directory, renamed over the target only when complete, so a write that
//! fails (disk full, a file-size limit, an interrupted run) leaves the
//! previous file as it was. Creating the temporary file is also the check
//! that the path can be written: commands create it before a long
//! computation and fill it after.
//!
//! The contents are checked before they are written: an [`AtomicFile`] is
//! filled only through the checked `commit_*` methods (CSV, SVG/text,
//! JSON, TOML), which refuse a non-finite number; its raw byte commit is
//! private to this module.
use std::fs::{self, File};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use serde::Serialize;

/// A file being written atomically: the temporary file exists from
/// [`AtomicFile::create`] on; a `commit_*` method checks the contents,
/// writes them, flushes them to disk and renames the file over the target.
/// Dropped without a commit, it removes the temporary file and leaves the
/// target untouched.
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

    /// The target's name for an error message.
    fn name(&self) -> String {
        self.target.display().to_string()
    }

    /// Commits CSV text after [`super::check_csv`].
    pub fn commit_csv(self, text: &str) -> anyhow::Result<()> {
        super::check_csv(&self.name(), text)?;
        self.commit(text.as_bytes())
    }

    /// Commits an SVG (or other text) after [`super::check_text`].
    pub fn commit_svg(self, text: &str) -> anyhow::Result<()> {
        super::check_text(&self.name(), text)?;
        self.commit(text.as_bytes())
    }

    /// Commits `value` as pretty JSON after [`super::check_value`].
    pub fn commit_json<T: Serialize + ?Sized>(self, value: &T) -> anyhow::Result<()> {
        let text = super::json(&self.name(), value)?;
        self.commit(text.as_bytes())
    }

    /// Commits `value` as TOML after `header` (comment lines), after
    /// [`super::check_value`].
    pub fn commit_toml<T: Serialize + ?Sized>(self, header: &str, value: &T) -> anyhow::Result<()> {
        let text = super::toml(&self.name(), header, value)?;
        self.commit(text.as_bytes())
    }

    /// Writes `bytes` (already checked by the caller), flushes them to
    /// disk and renames the temporary file over the target (keeping the
    /// target's permissions if it existed).
    fn commit(mut self, bytes: &[u8]) -> anyhow::Result<()> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<std::ffi::OsString> {
        fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect()
    }

    #[test]
    fn a_commit_replaces_the_file_and_a_drop_leaves_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("keep.csv");
        fs::write(&p, "old").unwrap();
        let pending = AtomicFile::create(&p).unwrap();
        drop(pending);
        assert_eq!(fs::read_to_string(&p).unwrap(), "old");
        AtomicFile::create(&p)
            .unwrap()
            .commit_csv("a,b\n1,2\n")
            .unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "a,b\n1,2\n");
        // No temporary files left behind either way.
        assert_eq!(
            names(dir.path()),
            vec![std::ffi::OsString::from("keep.csv")]
        );
    }

    #[test]
    fn a_refused_commit_leaves_the_previous_file_and_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("keep.csv");
        fs::write(&p, "a,b\n1,2\n").unwrap();
        let e = AtomicFile::create(&p)
            .unwrap()
            .commit_csv("a,b\n1,NaN\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("keep.csv") && e.contains("column `b`"), "{e}");
        assert_eq!(fs::read_to_string(&p).unwrap(), "a,b\n1,2\n");
        let e = AtomicFile::create(&p)
            .unwrap()
            .commit_json(&[1.0, f64::INFINITY])
            .unwrap_err()
            .to_string();
        assert!(e.contains("field `[1]`"), "{e}");
        assert_eq!(
            names(dir.path()),
            vec![std::ffi::OsString::from("keep.csv")]
        );
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
