//! Sizes refused before allocation: a command that would allocate in
//! proportion to a size the user gives (voxels, squares) estimates the
//! memory first and refuses, naming the flag, the estimate and the memory
//! there is, instead of aborting in the allocator (SIGABRT) or swapping
//! for minutes.
//!
//! "The memory there is" is the least of what the system reports free for
//! new work (`MemAvailable` in /proc/meminfo) and the process's own limits
//! (`ulimit -v`, `ulimit -d`); where none is known the estimate is not
//! judged. The estimates are measured peaks with their command, not
//! derived counts of every buffer: they are meant to refuse sizes that
//! are many times too large, not to fit a run into the last megabyte.

/// The memory a new allocation can have (bytes), if it is known.
pub fn available_bytes() -> Option<u64> {
    let mut least: Option<u64> = None;
    let mut take = |v: u64| least = Some(least.map_or(v, |l| l.min(v)));
    if let Some(v) = mem_available() {
        take(v);
    }
    #[cfg(target_os = "linux")]
    for resource in [libc::RLIMIT_AS, libc::RLIMIT_DATA] {
        let mut lim = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: getrlimit writes the struct it is given and nothing else.
        #[allow(unsafe_code)]
        let ok = unsafe { libc::getrlimit(resource, &mut lim) } == 0;
        if ok && lim.rlim_cur != libc::RLIM_INFINITY {
            take(lim.rlim_cur);
        }
    }
    least
}

/// `MemAvailable` of /proc/meminfo (bytes).
fn mem_available() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let kb: u64 = text
        .lines()
        .find_map(|l| l.strip_prefix("MemAvailable:"))?
        .split_whitespace()
        .next()?
        .parse()
        .ok()?;
    kb.checked_mul(1024)
}

/// Refuses `need_bytes` (what `what` would take, e.g. "--dims
/// 1024x1024x1024") when more than the memory there is; the error names
/// both in MB.
pub fn check_fits(what: &str, need_bytes: u64) -> anyhow::Result<()> {
    check_fits_in(what, need_bytes, available_bytes())
}

/// [`check_fits`] against a given amount of memory (`None`: unknown, not
/// judged).
pub fn check_fits_in(what: &str, need_bytes: u64, available: Option<u64>) -> anyhow::Result<()> {
    match available {
        Some(have) if need_bytes > have => anyhow::bail!(
            "{what} needs about {} MB of memory, and {} MB are available (the least of free memory and this process's limits); give a smaller size",
            need_bytes / 1_000_000,
            have / 1_000_000
        ),
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_size_beyond_the_memory_is_refused_by_name() {
        let e = check_fits_in("--dims 9x9x9", 3_000_000_000, Some(2_000_000_000)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--dims 9x9x9 needs about 3000 MB of memory, and 2000 MB are available (the least of free memory and this process's limits); give a smaller size"
        );
        assert!(check_fits_in("x", 1_000, Some(2_000)).is_ok());
        assert!(check_fits_in("x", u64::MAX, None).is_ok());
    }

    /// The system's figure is read (this test runs on Linux in CI).
    #[test]
    #[cfg(target_os = "linux")]
    fn the_available_memory_is_known_on_linux() {
        let have = available_bytes().expect("MemAvailable or a limit");
        assert!(have > 1_000_000, "{have} bytes");
    }
}
