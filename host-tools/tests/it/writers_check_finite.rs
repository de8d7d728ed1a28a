//! Every file `softjoint` writes and everything it prints goes through
//! `host_tools::output`, which refuses non-finite numbers, writes the
//! files a user keeps atomically, and prints without panicking. These
//! tests read the program's source and fail when a write or a print
//! bypasses it, so a new writer cannot forget the check.
use std::path::Path;

/// Calls that write a file or serialise a result outside `output`.
const BYPASSES: [&str; 7] = [
    "fs::write(",
    "File::create(",
    "serde_json::to_string",
    "serde_json::json!",
    "toml::to_string",
    "to_writer",
    "OpenOptions",
];

/// The checked writers whose names hold the plain `File::create(` above:
/// the atomic file of `host_tools::output` (its contents can only be
/// committed through the checked `commit_*` methods), and the streamed
/// row files (`run::trace::RowFile`, the excitation log's `LogFile` on it),
/// whose own `File::create(` is among [`ALLOWED`] and whose values are
/// checked as [`STREAMED`] requires.
const CHECKED: [&str; 3] = [
    "AtomicFile::create(",
    "RowFile::create(",
    "LogFile::create(",
];

/// Uses that are not results, each with the reason.
const ALLOWED: [(&str, &str, &str); 3] = [
    (
        "rheology.rs",
        "toml::to_string",
        "rheology simulate --print-default prints the built-in scenario, an input, not a result, in compact TOML (one-line arrays such as grid = [6, 4, 6]), which output::print_toml's pretty form does not give",
    ),
    (
        "console.rs",
        "OpenOptions",
        "the console appends telemetry rows to a CSV as they arrive; each row is checked with output::check_csv first",
    ),
    (
        "trace.rs",
        "File::create(",
        "the streamed --csv trace of sim/hil is written as the run goes (not atomically, it says whether it is complete); every value of a row is checked with output::check_number before it is formatted",
    ),
];

/// The streamed writers among [`ALLOWED`], each with the check of
/// `host_tools::output` its code must call.
const STREAMED: [(&str, &str); 3] = [
    ("console.rs", "output::check_csv("),
    ("trace.rs", "check_number("),
    ("excite.rs", "check_number("),
];

fn sources(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// A program source outside `host_tools::output`: its name and the code
/// before its unit tests (which may write their own inputs).
struct Source {
    path: std::path::PathBuf,
    name: String,
    code: String,
}

/// Every source of the program but `host_tools::output`'s own.
fn program_sources() -> Vec<Source> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    assert!(files.len() > 10, "found {} sources", files.len());
    files
        .into_iter()
        .filter(|f| !f.starts_with(src.join("output")))
        .map(|path| {
            let text = std::fs::read_to_string(&path).unwrap();
            Source {
                name: path.file_name().unwrap().to_str().unwrap().to_string(),
                code: text.split("#[cfg(test)]").next().unwrap_or("").to_string(),
                path,
            }
        })
        .collect()
}

/// The lines of `sources` (comments left out) for which `offends` holds,
/// as `file:line: text`.
fn offences(sources: &[Source], offends: impl Fn(&Source, &str) -> bool) -> Vec<String> {
    let mut out = Vec::new();
    for f in sources {
        for (i, line) in f.code.lines().enumerate() {
            if !line.trim_start().starts_with("//") && offends(f, line) {
                out.push(format!("{}:{}: {}", f.path.display(), i + 1, line.trim()));
            }
        }
    }
    out
}

#[test]
fn every_writer_goes_through_the_finite_check() {
    let files = program_sources();
    let offences = offences(&files, |f, line| {
        let line = CHECKED
            .iter()
            .fold(line.to_string(), |l, c| l.replace(c, ""));
        BYPASSES
            .iter()
            .any(|b| line.contains(b) && !ALLOWED.iter().any(|(n, a, _)| *n == f.name && a == b))
    });
    assert!(
        offences.is_empty(),
        "writes that bypass host_tools::output (and its non-finite check):\n{}",
        offences.join("\n")
    );
    // The writers allowed to stream must still check what they write.
    for (name, check) in STREAMED {
        let f = files
            .iter()
            .find(|f| f.name == name)
            .unwrap_or_else(|| panic!("{name} not found"));
        assert!(f.code.contains(check), "{name} streams without `{check}`");
    }
}

/// Whether `line` calls the macro `name` (`println` matches `println!(`
/// but not `eprintln!(`).
fn calls(line: &str, name: &str) -> bool {
    let call = format!("{name}!(");
    line.match_indices(&call).any(|(at, _)| {
        !line[..at]
            .chars()
            .next_back()
            .is_some_and(|c| c.is_alphanumeric() || c == '_')
    })
}

/// Standard output is written with `outln!`/`out!` (or output's print
/// functions), which return a failed write as an error: `println!` and
/// `print!` panic when standard output is full or closed.
#[test]
fn every_print_goes_through_the_checked_stdout() {
    assert!(calls("    println!(\"x\");", "println") && !calls("eprintln!(\"x\")", "println"));
    let offences = offences(&program_sources(), |_, line| {
        calls(line, "println") || calls(line, "print")
    });
    assert!(
        offences.is_empty(),
        "prints that panic on a failed write (use outln!/out!):\n{}",
        offences.join("\n")
    );
}
