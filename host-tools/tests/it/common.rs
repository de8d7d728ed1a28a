//! Scaffolding shared by the tests of the `softjoint` binary: running it,
//! reading its output, scratch directories that delete themselves, and
//! clean refusals. Each test binary uses a subset.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the built `softjoint` with `args`. Its cache of fitted laws
/// (`run::law_cache`) is kept under the build's own temporary directory,
/// shared by the tests, never in the user's home.
pub fn softjoint(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(args)
        .env("SOFTJOINT_CACHE_DIR", test_cache_dir())
        .output()
        .expect("binary runs")
}

/// The law cache the tests' runs share.
pub fn test_cache_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("softjoint-cache")
}

/// Standard output as text.
pub fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Asserts a successful run, showing both streams otherwise.
pub fn ok(o: &Output) {
    assert!(
        o.status.success(),
        "exit {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        stdout(o),
        stderr(o)
    );
}

/// A scratch directory, deleted with everything in it when dropped; it
/// dereferences to its path.
pub struct Scratch(tempfile::TempDir);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        self.0.path()
    }
}

/// A fresh scratch directory (`test` names it, to find it while it lives).
pub fn scratch(test: &str) -> Scratch {
    Scratch(
        tempfile::Builder::new()
            .prefix(&format!("softjoint-{test}-"))
            .tempdir()
            .expect("scratch dir"),
    )
}

/// A path as text.
pub fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// Writes `text` to `dir/name` and returns the path as text.
pub fn file(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    s(&p).to_string()
}

/// Runs `args`, checks a clean refusal (exit 1, no panic) whose stderr
/// holds every needle, and returns that stderr.
pub fn refused(args: &[&str], needles: &[&str]) -> String {
    let o = softjoint(args);
    let err = stderr(&o);
    assert!(
        !o.status.success(),
        "{args:?}: exit 0\nstdout:\n{}\nstderr:\n{err}",
        stdout(&o)
    );
    assert_eq!(
        o.status.code(),
        Some(1),
        "{args:?}: not an error exit:\n{err}"
    );
    assert!(!err.contains("panicked"), "{args:?}: panic:\n{err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: stderr lacks `{n}`:\n{err}");
    }
    err
}

/// Sends `signal` (e.g. `-TERM`) to process `pid` with kill(1).
pub fn kill(signal: &str, pid: u32) {
    let ok = Command::new("kill")
        .args([signal, &pid.to_string()])
        .status()
        .expect("kill runs");
    assert!(ok.success(), "kill {signal} {pid} failed");
}
