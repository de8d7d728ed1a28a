//! Sizes (issue 31, item 8): a size the user gives is refused before any
//! allocation or work, by an estimate of the memory it needs against the
//! memory there is, naming the flag — never an abort in the allocator
//! (SIGABRT) or seconds of work first. The memory there is includes the
//! process's own limit, so the tests set one (`ulimit -v`) on the child
//! they start and do not depend on the machine's memory.
use crate::common;

use std::process::{Command, Output};

use common::{s, scratch, stderr};

/// Runs `softjoint args` under `ulimit -v limit_kb`.
fn limited(limit_kb: u64, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {limit_kb} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_softjoint"))
        .args(args)
        .output()
        .expect("sh runs")
}

fn assert_refused(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{:?}: {err}", o.status);
    assert!(
        !err.contains("panicked") && !err.contains("memory allocation"),
        "{err}"
    );
    for n in needles {
        assert!(err.contains(n), "stderr lacks `{n}`: {err}");
    }
}

/// `tissue field --dims 1024x1024x1024` aborted with an allocation
/// failure (SIGABRT); it is refused by its estimate (≈ 129 GB) and creates
/// nothing.
#[test]
fn tissue_dims_beyond_the_memory_are_refused_before_allocation() {
    let dir = scratch("sizes-tissue");
    let out = dir.join("out");
    let o = limited(
        4_000_000,
        &[
            "tissue",
            "field",
            "--synthetic",
            "--dims",
            "1024x1024x1024",
            "--out-dir",
            s(&out),
        ],
    );
    assert_refused(
        &o,
        &[
            "--dims 1024x1024x1024",
            "needs about 128881 MB",
            "available",
        ],
    );
    assert!(!out.exists());
}

/// `push --nx 2000 --ny 2000` used 2.2 GB and most of a minute before
/// failing; under a 1.5 GB limit it is refused by its estimate at once.
/// A side beyond the model's 2,000 squares is refused before the video is
/// even read (it used to be checked after the ground truth's seconds of
/// finite elements): here the video file does not exist, and the error is
/// about `--nx`.
#[test]
fn push_mesh_sizes_are_checked_before_any_work() {
    let dir = scratch("sizes-push");
    let out = dir.join("out");
    for cmd in ["simulate", "calibrate"] {
        let o = limited(
            1_500_000,
            &[
                "push",
                cmd,
                "--nx",
                "2000",
                "--ny",
                "2000",
                "--out",
                s(&out),
            ],
        );
        assert_refused(
            &o,
            &["--nx 2000 --ny 2000 (4000000 squares) needs about 2832 MB"],
        );
        let o = common::softjoint(&[
            "push",
            cmd,
            "--nx",
            "5000",
            "--video",
            s(&dir.join("missing.csv")),
            "--out",
            s(&out),
        ]);
        assert_refused(&o, &["--nx 5000: must be 1..=2000 squares"]);
    }
    assert!(!out.exists());
}
