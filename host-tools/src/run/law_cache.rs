//! Fitted laws kept between runs. A scenario with `estimator = "switching"`
//! (the main job's default) and no calibration file fits its laws to an
//! 80 s simulated calibration sweep of its joint: ≈ 750 M of the main
//! job's ≈ 870 M instructions (issue 34). The sweep and fit are
//! deterministic, so the laws are a function of the joint, the method and
//! the program that computed them; this module keeps them in a file named
//! by that function's arguments and reads them back on the next run.
//!
//! What makes an entry valid: its `key` is the whole text of the joint's
//! parameters (every `f64` printed so that it reads back to the same
//! value), the method, and the size and modification time of the
//! `softjoint` executable, so a rebuilt program (whose plant or fit may
//! have changed) never reads laws an earlier build computed. The file name
//! is a hash of the key, the key itself is stored in the file and compared
//! in full, so a hash collision or a hand-edited key is a miss. A miss, an
//! unreadable or malformed entry, or a cache directory that cannot be
//! written all fall back to the sweep: the cache can only save time.
//!
//! Where: `$SOFTJOINT_CACHE_DIR`, else `$XDG_CACHE_HOME/softjoint`, else
//! `$HOME/.cache/softjoint`. `SOFTJOINT_CACHE_DIR=` (empty) turns it off.
use std::hash::{Hash, Hasher};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::files::calibration::CalibrationFile;

/// One kept fit, as written to the cache file.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Entry {
    /// What the laws were computed from (see the module's doc).
    key: String,
    /// Rows of the sweep they were fitted to.
    sweep_rows: usize,
    /// The laws.
    calibration: CalibrationFile,
}

/// The cache directory, or `None` when caching is off or no place for it
/// is known.
pub fn dir() -> Option<PathBuf> {
    dir_from(|name| std::env::var_os(name))
}

fn dir_from(var: impl Fn(&str) -> Option<std::ffi::OsString>) -> Option<PathBuf> {
    if let Some(d) = var("SOFTJOINT_CACHE_DIR") {
        return (!d.is_empty()).then(|| PathBuf::from(d));
    }
    if let Some(d) = var("XDG_CACHE_HOME").filter(|d| !d.is_empty()) {
        return Some(PathBuf::from(d).join("softjoint"));
    }
    var("HOME")
        .filter(|d| !d.is_empty())
        .map(|h| PathBuf::from(h).join(".cache").join("softjoint"))
}

/// The executable's identity: its size and modification time, or `None`
/// when it cannot be read (then nothing is cached: an entry could not be
/// told from one an older build wrote).
fn program_identity() -> Option<String> {
    let exe = std::env::current_exe().ok()?;
    let meta = std::fs::metadata(exe).ok()?;
    let modified = meta
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?;
    Some(format!(
        "program {} B, modified {}.{:09}",
        meta.len(),
        modified.as_secs(),
        modified.subsec_nanos()
    ))
}

/// The full key for the joint's `description` (its parameters and method),
/// or `None` when the program's identity is unknown.
pub fn key(description: &str) -> Option<String> {
    Some(format!("{description}|{}", program_identity()?))
}

fn file_for(dir: &Path, key: &str) -> PathBuf {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    key.hash(&mut h);
    dir.join(format!("laws-{:016x}.toml", h.finish()))
}

/// The laws kept for `key` in `dir`, if an entry with exactly that key is
/// there and reads as a valid calibration.
pub fn load(dir: &Path, key: &str) -> Option<(CalibrationFile, usize)> {
    let path = file_for(dir, key);
    parse(&std::fs::read_to_string(&path).ok()?, key)
}

/// The laws of an entry's text when its key is exactly `key` and its
/// calibration is valid (a cache file's or the built-in entry's).
pub fn parse(text: &str, key: &str) -> Option<(CalibrationFile, usize)> {
    let entry: Entry = toml::from_str(text).ok()?;
    if entry.key != key || entry.calibration.check().is_err() {
        return None;
    }
    Some((entry.calibration, entry.sweep_rows))
}

/// An entry's text as [`store`] writes it, after `header`.
pub fn entry_text(
    header: &str,
    key: &str,
    calibration: &CalibrationFile,
    sweep_rows: usize,
) -> anyhow::Result<String> {
    let entry = Entry {
        key: key.to_string(),
        sweep_rows,
        calibration: calibration.clone(),
    };
    crate::output::toml("the built-in laws", header, &entry)
}

/// Keeps the laws for `key` in `dir` (created if missing), atomically so
/// that two runs writing the same entry at once leave one whole file.
/// Failing to write is not an error of the run: the next run sweeps again.
pub fn store(dir: &Path, key: &str, calibration: &CalibrationFile, sweep_rows: usize) {
    if std::fs::create_dir_all(dir).is_err() {
        return;
    }
    let entry = Entry {
        key: key.to_string(),
        sweep_rows,
        calibration: calibration.clone(),
    };
    if let Ok(file) = crate::output::AtomicFile::create(&file_for(dir, key)) {
        let header =
            "# Laws fitted by `softjoint` to a simulated calibration sweep, kept so that the\n\
                      # next run of the same joint skips the sweep. Safe to delete.\n";
        let _ = file.commit_toml(header, &entry);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::calibration::LawSpec;

    fn env<'a>(
        pairs: &'a [(&'a str, &'a str)],
    ) -> impl Fn(&str) -> Option<std::ffi::OsString> + 'a {
        move |name| {
            pairs
                .iter()
                .find(|(n, _)| *n == name)
                .map(|(_, v)| std::ffi::OsString::from(*v))
        }
    }

    #[test]
    fn the_directory_follows_the_variables_in_order() {
        let all = [
            ("SOFTJOINT_CACHE_DIR", "/a"),
            ("XDG_CACHE_HOME", "/x"),
            ("HOME", "/h"),
        ];
        assert_eq!(dir_from(env(&all)), Some(PathBuf::from("/a")));
        assert_eq!(
            dir_from(env(&all[1..])),
            Some(PathBuf::from("/x/softjoint"))
        );
        assert_eq!(
            dir_from(env(&all[2..])),
            Some(PathBuf::from("/h/.cache/softjoint"))
        );
        assert_eq!(
            dir_from(env(&[("SOFTJOINT_CACHE_DIR", ""), ("HOME", "/h")])),
            None
        );
        assert_eq!(dir_from(env(&[])), None);
    }

    /// A 2D calibration (Eq. 2 on d1).
    fn calibration(c: f64) -> CalibrationFile {
        CalibrationFile {
            alpha: LawSpec::Single {
                sensor: 1,
                a: 1.0e-3,
                b: -7.123456789012345,
                c,
            },
            beta: None,
        }
    }

    #[test]
    fn an_entry_reads_back_to_the_bit_and_only_under_its_own_key() {
        let dir = tempfile::tempdir().unwrap();
        let c = calibration(0.1 + 0.2);
        store(dir.path(), "joint A", &c, 80_001);
        assert_eq!(load(dir.path(), "joint A"), Some((c, 80_001)));
        assert_eq!(load(dir.path(), "joint B"), None);
    }

    #[test]
    fn a_malformed_or_foreign_entry_is_a_miss() {
        let dir = tempfile::tempdir().unwrap();
        store(dir.path(), "joint A", &calibration(1.0), 10);
        let path = file_for(dir.path(), "joint A");
        let text = std::fs::read_to_string(&path).unwrap();
        // The same file name holding another key (a collision) is a miss.
        std::fs::write(&path, text.replace("joint A", "joint Z")).unwrap();
        assert_eq!(load(dir.path(), "joint A"), None);
        // So is a cut-short file.
        std::fs::write(&path, &text[..text.len() / 2]).unwrap();
        assert_eq!(load(dir.path(), "joint A"), None);
        // And a law the core would refuse (a 2D joint has sensor d1 only).
        assert!(text.contains("sensor = 1"), "{text}");
        std::fs::write(&path, text.replace("sensor = 1", "sensor = 3")).unwrap();
        assert_eq!(load(dir.path(), "joint A"), None);
    }

    #[test]
    fn an_unwritable_directory_only_skips_the_cache() {
        let dir = tempfile::tempdir().unwrap();
        let blocker = dir.path().join("file");
        std::fs::write(&blocker, "x").unwrap();
        // A directory below a regular file cannot be created.
        store(&blocker.join("sub"), "joint A", &calibration(1.0), 10);
        assert_eq!(load(&blocker.join("sub"), "joint A"), None);
    }
}
