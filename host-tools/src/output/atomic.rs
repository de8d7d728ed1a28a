//! Files a user keeps, written atomically: to a temporary file in the same
//! directory, renamed over the target only when complete, so a write that
//! fails (disk full, a file-size limit, an interrupted run) leaves the
//! previous file as it was. Creating the temporary file is also the check
//! that the path can be written: commands create it before a long
//! computation and fill it after.
//!
//! Only a regular file (or a new path) is replaced by a rename. A symbolic
//! link is followed and the file it points to is written atomically, the
//! link left as it is; a device or a FIFO is written through (opened for
//! writing, never renamed over: `-o /dev/null` discards, a FIFO feeds its
//! reader); a socket or a directory is refused by name.
//!
//! The contents are checked before they are written: an [`AtomicFile`] is
//! filled only through the checked `commit_*` methods (CSV, SVG/text,
//! JSON, TOML), which refuse a non-finite number; its raw byte commit is
//! private to this module.
use std::fs::{self, File};
use std::io::{self, Write};
#[cfg(unix)]
use std::os::unix::fs::FileTypeExt as _;
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
    /// The path as the user gave it (for messages).
    target: PathBuf,
    /// Where the contents go.
    how: How,
    file: Option<File>,
    /// A regular file's contents are in its temporary file, flushed to
    /// disk ([`AtomicFile::stage`]): the address and length of the text
    /// staged. The commit, given that very text, only renames it.
    staged: Option<(usize, usize)>,
}

/// How an [`AtomicFile`] reaches its target.
#[derive(Debug)]
enum How {
    /// A regular file or a new path (`resolved`: the target with every
    /// symbolic link followed): written to `temp` beside it, renamed over
    /// it. `temp` is empty once renamed.
    Replace { resolved: PathBuf, temp: PathBuf },
    /// A device, written through (`file` open from the start, which
    /// checked the permission).
    Device,
    /// A FIFO, opened at the commit: opening it blocks until it has a
    /// reader, which a command need not wait for before its work.
    Fifo { path: PathBuf },
}

/// What is at a path, with symbolic links followed.
enum Existing {
    /// Nothing yet, or a regular file.
    FileOrNew,
    Directory,
    Device,
    Fifo,
    Socket,
}

/// `target` with every symbolic link followed (the last link's target may
/// not exist yet: it is the file to create).
fn resolve_links(target: &Path) -> io::Result<PathBuf> {
    let mut path = target.to_path_buf();
    // The kernel's own limit (ELOOP).
    for _ in 0..40 {
        match fs::symlink_metadata(&path) {
            Ok(meta) if meta.file_type().is_symlink() => {
                let link = fs::read_link(&path)?;
                path = match path.parent() {
                    Some(dir) if link.is_relative() => dir.join(link),
                    _ => link,
                };
            }
            _ => return Ok(path),
        }
    }
    Err(io::Error::other("too many levels of symbolic links"))
}

/// What is at `path` (links already followed).
fn existing(path: &Path) -> Existing {
    let Ok(meta) = fs::metadata(path) else {
        return Existing::FileOrNew;
    };
    let kind = meta.file_type();
    if kind.is_dir() {
        return Existing::Directory;
    }
    #[cfg(unix)]
    {
        if kind.is_char_device() || kind.is_block_device() {
            return Existing::Device;
        }
        if kind.is_fifo() {
            return Existing::Fifo;
        }
        if kind.is_socket() {
            return Existing::Socket;
        }
    }
    Existing::FileOrNew
}

/// Distinguishes temporary files of one process.
static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

impl AtomicFile {
    /// Opens `target` for an atomic write. For a regular file or a new
    /// path this creates the temporary file beside the file (so the final
    /// rename stays on one file system); for a device it opens the device;
    /// a FIFO is opened at the commit. Fails, naming `target`, if its
    /// directory does not exist or cannot be written, or if `target` is a
    /// directory or a socket.
    pub fn create(target: &Path) -> anyhow::Result<Self> {
        let cannot =
            |e: &dyn std::fmt::Display| anyhow::anyhow!("cannot write {}: {e}", target.display());
        if target.file_name().is_none() {
            return Err(cannot(&"not a file name"));
        }
        let resolved = resolve_links(target).map_err(|e| cannot(&e))?;
        let (how, file) = match existing(&resolved) {
            Existing::Directory => return Err(cannot(&"it is a directory")),
            Existing::Socket => {
                return Err(cannot(&"it is a socket; give a file, a device or a FIFO"))
            }
            Existing::Device => {
                let file = fs::OpenOptions::new()
                    .write(true)
                    .open(&resolved)
                    .map_err(|e| cannot(&e))?;
                (How::Device, Some(file))
            }
            Existing::Fifo => (How::Fifo { path: resolved }, None),
            Existing::FileOrNew => {
                let (temp, file) = temporary_beside(&resolved).map_err(|e| cannot(&e))?;
                (How::Replace { resolved, temp }, Some(file))
            }
        };
        Ok(Self {
            target: target.to_path_buf(),
            how,
            file,
            staged: None,
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

    /// Commits text that passed its check ([`super::CheckedText`]).
    pub fn commit_checked(self, text: &super::CheckedText) -> anyhow::Result<()> {
        self.commit(text.text.as_bytes())
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

    /// The file a streaming writer appends to before
    /// [`keep_streamed`](Self::keep_streamed): the temporary file, the
    /// device, or the FIFO (opened here, at the first write). Crate-private
    /// like [`commit`](Self::commit): the one streaming writer,
    /// `run::trace::RowFile`, checks every value before it writes it.
    pub(crate) fn streamed(&mut self) -> io::Result<&mut File> {
        if self.file.is_none() {
            if let How::Fifo { path } = &self.how {
                self.file = Some(fs::OpenOptions::new().write(true).open(path)?);
            }
        }
        self.file
            .as_mut()
            .ok_or_else(|| io::Error::other("the file was already committed"))
    }

    /// Keeps what was written through [`streamed`](Self::streamed):
    /// flushed to disk and renamed over the target, as a commit does.
    pub(crate) fn keep_streamed(self) -> anyhow::Result<()> {
        self.commit(&[])
    }

    /// Writes `bytes` (already checked by the caller): into the temporary
    /// file, flushed to disk and renamed over the target (keeping the
    /// target's permissions if it existed), or through to the device or
    /// FIFO.
    fn commit(mut self, bytes: &[u8]) -> anyhow::Result<()> {
        if let Some(staged) = self.staged {
            // Staged text is checked text; a commit of other contents
            // would bypass its own check. The same buffer is the same
            // text (it is borrowed from staging to commit).
            if (bytes.as_ptr() as usize, bytes.len()) != staged {
                return Err(anyhow::anyhow!(
                    "cannot write {}: other contents than those staged",
                    self.target.display()
                ));
            }
            return self.commit_staged();
        }
        if self.replaces() {
            self.write_temp(bytes)?;
            return self.commit_staged();
        }
        let target = self.target.clone();
        let fail = |e: io::Error| anyhow::anyhow!("cannot write {}: {e}", target.display());
        let file = self.file.take();
        match &mut self.how {
            How::Device => {
                let mut file = file.ok_or_else(|| fail(io::ErrorKind::Other.into()))?;
                file.write_all(bytes)
                    .and_then(|()| file.flush())
                    .map_err(fail)
            }
            How::Fifo { path } => {
                let mut file = match file {
                    // Opened already by a stream's first write.
                    Some(file) => file,
                    None => fs::OpenOptions::new()
                        .write(true)
                        .open(&*path)
                        .map_err(fail)?,
                };
                file.write_all(bytes)
                    .and_then(|()| file.flush())
                    .map_err(fail)
            }
            How::Replace { .. } => Err(fail(io::Error::other("a regular file is renamed"))),
        }
    }
}

impl AtomicFile {
    /// Whether this replaces a regular file (or makes a new one), rather
    /// than writing through to a device or FIFO.
    pub(super) fn replaces(&self) -> bool {
        matches!(self.how, How::Replace { .. })
    }

    /// For a regular file (or a new path), writes `text` into the
    /// temporary file and flushes it to disk now; the commit, given the
    /// same text ([`Self::commit_checked`]), then only renames it. A device
    /// or a FIFO is left to the commit. Several files staged side by side
    /// flush to disk at the same time ([`super::write_checked_all`]).
    pub(super) fn stage(&mut self, text: &super::CheckedText) -> anyhow::Result<()> {
        if !self.replaces() || self.staged.is_some() {
            return Ok(());
        }
        self.write_temp(text.as_str().as_bytes())
    }

    /// A regular file's `bytes` into its temporary file, flushed to disk.
    fn write_temp(&mut self, bytes: &[u8]) -> anyhow::Result<()> {
        let target = self.target.clone();
        let file = self.file.as_mut().ok_or_else(|| {
            anyhow::anyhow!("cannot write {}: already committed", target.display())
        })?;
        file.write_all(bytes)
            .and_then(|()| file.sync_all())
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", target.display()))?;
        self.staged = Some((bytes.as_ptr() as usize, bytes.len()));
        Ok(())
    }

    /// The commit of a staged regular file: the rename (keeping the
    /// target's permissions if it existed).
    fn commit_staged(mut self) -> anyhow::Result<()> {
        let target = self.target.clone();
        let fail = |e: io::Error| anyhow::anyhow!("cannot write {}: {e}", target.display());
        let How::Replace { resolved, temp } = &mut self.how else {
            return Err(fail(io::Error::other("only a regular file is staged")));
        };
        if let Ok(meta) = fs::metadata(&*resolved) {
            // Best effort: a file the user made readable to others stays
            // so.
            let _ = fs::set_permissions(&*temp, meta.permissions());
        }
        self.file = None;
        fs::rename(&*temp, &*resolved).map_err(fail)?;
        // Renamed: nothing left to clean up.
        *temp = PathBuf::new();
        Ok(())
    }
}

/// A new temporary file beside `path`, named after it and this process.
fn temporary_beside(path: &Path) -> io::Result<(PathBuf, File)> {
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::other("not a file name"))?;
    let dir = match path.parent() {
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
        .open(&temp)?;
    Ok((temp, file))
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if let How::Replace { temp, .. } = &self.how {
            if !temp.as_os_str().is_empty() {
                self.file = None;
                let _ = fs::remove_file(temp);
            }
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

/// Checks that `path` can be written (as [`AtomicFile::create`] would,
/// leaving nothing behind and the file as it was), before the long work
/// whose result goes there rather than after it.
pub fn check_file(path: &Path) -> anyhow::Result<()> {
    drop(AtomicFile::create(path)?);
    Ok(())
}

/// Checks, before the long work, that `dir` can be made or written and
/// that each of `names` in it could be ([`check_file`]).
pub fn check_files_in(dir: &Path, names: &[&str]) -> anyhow::Result<()> {
    check_dir(dir)?;
    if dir.is_dir() {
        for n in names {
            check_file(&dir.join(n))?;
        }
    }
    Ok(())
}

/// Creates the output directory `dir` (and its parents).
pub fn create_dir(dir: &Path) -> anyhow::Result<()> {
    fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("cannot create {}: {e}", dir.display()))
}

/// Test support: a FIFO at `path` (in the test's own temporary folder,
/// never the machine's /dev), and a thread that reads it to its end.
#[cfg(test)]
pub(crate) fn fifo_and_reader(path: &Path) -> std::thread::JoinHandle<String> {
    let made = std::process::Command::new("mkfifo")
        .arg(path)
        .status()
        .unwrap();
    assert!(made.success());
    let path = path.to_path_buf();
    // Opening a FIFO to read waits for its writer, so the reader can start
    // before the file under test is opened.
    std::thread::spawn(move || fs::read_to_string(path).unwrap())
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

    /// The names in `dir`, sorted, as text.
    fn sorted_names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = names(dir)
            .into_iter()
            .map(|n| n.to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
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

    #[test]
    fn a_symlink_is_followed_and_the_file_it_names_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real.csv");
        fs::write(&real, "old").unwrap();
        let link = dir.path().join("link.csv");
        std::os::unix::fs::symlink("real.csv", &link).unwrap();
        AtomicFile::create(&link)
            .unwrap()
            .commit_csv("a\n1\n")
            .unwrap();
        assert!(fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(fs::read_to_string(&real).unwrap(), "a\n1\n");
        // A link to a file not made yet: the file is made, the link kept.
        let dangling = dir.path().join("later.csv");
        std::os::unix::fs::symlink("made.csv", &dangling).unwrap();
        AtomicFile::create(&dangling)
            .unwrap()
            .commit_csv("b\n2\n")
            .unwrap();
        assert!(fs::symlink_metadata(&dangling)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(
            fs::read_to_string(dir.path().join("made.csv")).unwrap(),
            "b\n2\n"
        );
    }

    /// A set of files: with a FIFO among them, written one after another
    /// (the FIFO through, at its turn); a set with a target that cannot be
    /// created replaces none of them, not even those before it (written
    /// one by one, the first would have been); regular files only, staged
    /// side by side and renamed (their old contents gone, no temporary
    /// left).
    #[test]
    fn a_set_of_files_is_written_whole_or_not_at_all() {
        use super::super::{write_checked_all, CheckedText};
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.svg"));
        fs::write(&a, "old").unwrap();
        let fifo = dir.path().join("pipe");
        let reader = fifo_and_reader(&fifo);
        let texts = [
            CheckedText::csv("a.csv", "x\n1\n".into()).unwrap(),
            CheckedText::text("pipe", "through\n".into()).unwrap(),
            CheckedText::text("b.svg", "<svg/>\n".into()).unwrap(),
        ];
        let set: Vec<(PathBuf, &CheckedText)> = [&a, &fifo, &b]
            .into_iter()
            .cloned()
            .zip(texts.iter())
            .collect();
        write_checked_all(&set).unwrap();
        assert_eq!(fs::read_to_string(&a).unwrap(), "x\n1\n");
        assert_eq!(fs::read_to_string(&b).unwrap(), "<svg/>\n");
        assert_eq!(reader.join().unwrap(), "through\n");
        assert_eq!(sorted_names(dir.path()), ["a.csv", "b.svg", "pipe"]);

        // A directory where the last file should go: refused by name, and
        // the first file keeps what it had.
        let sub = dir.path().join("c.csv");
        fs::create_dir(&sub).unwrap();
        let set = vec![(a.clone(), &texts[2]), (sub, &texts[0])];
        let e = write_checked_all(&set).unwrap_err().to_string();
        assert!(e.contains("c.csv") && e.contains("directory"), "{e}");
        assert_eq!(fs::read_to_string(&a).unwrap(), "x\n1\n");
        assert_eq!(
            sorted_names(dir.path()),
            ["a.csv", "b.svg", "c.csv", "pipe"]
        );

        // Regular files only: staged side by side, then renamed.
        let set = vec![(a.clone(), &texts[2]), (b.clone(), &texts[0])];
        write_checked_all(&set).unwrap();
        assert_eq!(fs::read_to_string(&a).unwrap(), "<svg/>\n");
        assert_eq!(fs::read_to_string(&b).unwrap(), "x\n1\n");
        assert_eq!(
            sorted_names(dir.path()),
            ["a.csv", "b.svg", "c.csv", "pipe"]
        );
    }

    /// A staged file commits only the text it staged: another text (one
    /// its own check would refuse, or one of the same length) is an
    /// error, the target untouched.
    #[test]
    fn a_staged_file_refuses_other_contents() {
        use super::super::CheckedText;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.csv");
        fs::write(&p, "old").unwrap();
        let text = CheckedText::csv("s.csv", "x\n1\n".into()).unwrap();
        let mut file = AtomicFile::create(&p).unwrap();
        file.stage(&text).unwrap();
        let e = file.commit_svg("other\n").unwrap_err().to_string();
        assert!(e.contains("s.csv") && e.contains("staged"), "{e}");
        let mut file = AtomicFile::create(&p).unwrap();
        file.stage(&text).unwrap();
        let same_length = CheckedText::csv("s.csv", "y\n2\n".into()).unwrap();
        let e = file.commit_checked(&same_length).unwrap_err().to_string();
        assert!(e.contains("s.csv") && e.contains("staged"), "{e}");
        assert_eq!(fs::read_to_string(&p).unwrap(), "old");
        assert_eq!(names(dir.path()), vec![std::ffi::OsString::from("s.csv")]);
        let mut file = AtomicFile::create(&p).unwrap();
        file.stage(&text).unwrap();
        file.commit_checked(&text).unwrap();
        assert_eq!(fs::read_to_string(&p).unwrap(), "x\n1\n");
    }

    #[test]
    fn a_fifo_is_written_through_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        let reader = fifo_and_reader(&fifo);
        let pending = AtomicFile::create(&fifo).unwrap();
        pending.commit_csv("a\n1\n").unwrap();
        assert_eq!(reader.join().unwrap(), "a\n1\n");
        assert!(fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
        assert_eq!(names(dir.path()), vec![std::ffi::OsString::from("pipe")]);
    }

    /// A private device node (never the machine's own /dev): `mknod`
    /// needs root, as CI runs; elsewhere the test says it did not run.
    fn device(dir: &Path, name: &str, minor: &str) -> Option<PathBuf> {
        let path = dir.join(name);
        let made = std::process::Command::new("mknod")
            .arg(&path)
            .args(["c", "1", minor])
            .stderr(std::process::Stdio::null())
            .status()
            .ok()?;
        made.success().then_some(path)
    }

    #[test]
    fn a_device_is_written_through_not_replaced() {
        let dir = tempfile::tempdir().unwrap();
        // 1:3 is the null device, 1:7 the full one.
        let (Some(null), Some(full)) = (
            device(dir.path(), "null", "3"),
            device(dir.path(), "full", "7"),
        ) else {
            eprintln!("not run: mknod needs root");
            return;
        };
        AtomicFile::create(&null)
            .unwrap()
            .commit_csv("a\n1\n")
            .unwrap();
        assert!(fs::metadata(&null).unwrap().file_type().is_char_device());
        let e = AtomicFile::create(&full)
            .unwrap()
            .commit_csv("a\n1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("full") && e.contains("No space left"), "{e}");
        assert!(fs::metadata(&full).unwrap().file_type().is_char_device());
        let mut left = names(dir.path());
        left.sort();
        assert_eq!(left, vec![std::ffi::OsString::from("full"), "null".into()]);
    }

    #[test]
    fn a_socket_is_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sock");
        let _listener = std::os::unix::net::UnixListener::bind(&path).unwrap();
        let e = AtomicFile::create(&path).unwrap_err().to_string();
        assert!(e.contains("sock") && e.contains("is a socket"), "{e}");
        assert!(fs::symlink_metadata(&path).unwrap().file_type().is_socket());
    }
}
