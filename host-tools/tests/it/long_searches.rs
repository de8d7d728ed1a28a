//! Long searches (issue 31, item 7): every output path is checked before
//! the search, not after it; a `tune` stopped by a signal keeps its best
//! candidate and its search state, and `--resume` goes on from there to
//! the gains an uninterrupted search finds. Signals go to a child process
//! this test started, never to the test's own process group.
use crate::common;

use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::{s, scratch, softjoint, stderr};
use host_tools::joint::tune::SearchState;

/// Starts the built `softjoint` with `args`, its output piped.
fn start(args: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("softjoint starts")
}

/// Waits for `child` to end within `limit`; a child still running then
/// (its search under way: the output check came after it) is killed and
/// the test fails.
fn ended_within(mut child: Child, limit: Duration, what: &str) -> Output {
    let until = Instant::now() + limit;
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > until {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {limit:?}: the output path was not checked before the search");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A refusal that names `needle`, exit 1, no panic.
fn assert_refused(o: &Output, needle: &str) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.contains(needle), "stderr lacks `{needle}`: {err}");
}

/// Names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Each search is given hours of work and an output it cannot write: it
/// must refuse at once, naming the path, and leave nothing behind.
#[test]
fn output_paths_are_checked_before_each_search() {
    let dir = scratch("search-paths");
    let plant = crate::identify_cli::hidden_2d_file(&dir);
    let missing = dir.join("no-such-dir").join("g.toml");
    // tune: a million candidates.
    let o = ended_within(
        start(&[
            "tune",
            s(&plant),
            "--candidates",
            "1000000",
            "-o",
            s(&missing),
        ]),
        Duration::from_secs(30),
        "tune",
    );
    assert_refused(&o, "no-such-dir/g.toml");
    // identify joint: a 5-minute standard excitation, a thousand
    // iterations a stage (over two minutes of fitting in a debug build).
    let plan_text = softjoint(&["identify", "plan", "--joint", "2d", "--duration-s", "300"]);
    common::ok(&plan_text);
    let plan = dir.join("plan.toml");
    std::fs::write(&plan, &plan_text.stdout).unwrap();
    let scen = common::file(&dir, "s.toml", crate::excite_stops::SCENARIO_2D);
    let log = dir.join("log.csv");
    common::ok(&softjoint(&[
        "sim",
        &scen,
        "--excite",
        s(&plan),
        "--log",
        s(&log),
    ]));
    let o = ended_within(
        start(&[
            "identify",
            "joint",
            s(&log),
            "--max-iterations",
            "1000",
            "-o",
            s(&missing),
        ]),
        Duration::from_secs(30),
        "identify joint",
    );
    assert_refused(&o, "no-such-dir/g.toml");
    // … and its --plot.
    let o = ended_within(
        start(&[
            "identify",
            "joint",
            s(&log),
            "--max-iterations",
            "1000",
            "-o",
            s(&dir.join("p.toml")),
            "--plot",
            s(&dir.join("no-such-dir/fit.svg")),
        ]),
        Duration::from_secs(30),
        "identify joint --plot",
    );
    assert_refused(&o, "no-such-dir/fit.svg");
    // rheology calibrate and push calibrate: a directory where a result
    // file goes.
    for (cmd, budget, file) in [
        (
            ["rheology", "calibrate"],
            ["--evaluations", "1000000"],
            "params.toml",
        ),
        (
            ["push", "calibrate"],
            ["--generations", "10000"],
            "params.json",
        ),
    ] {
        let out = dir.join(format!("{}-out", cmd[0]));
        std::fs::create_dir_all(out.join(file)).unwrap();
        let mut args = cmd.to_vec();
        args.extend(budget);
        args.extend(["--out", s(&out)]);
        let o = ended_within(start(&args), Duration::from_secs(30), cmd[0]);
        assert_refused(&o, &format!("{file}: it is a directory"));
        assert_eq!(names(&out), [file], "{} left files", cmd[0]);
    }
    assert!(!dir.join("no-such-dir").exists());
    assert!(!dir.join("p.toml").exists());
}

/// Starts a long search (`--candidates 100000`, one plant, one thread),
/// lets it score for `secs`, sends `signal` and returns its output.
fn stopped_tune(plant: &Path, gains: &Path, resume: Option<&Path>, signal: &str) -> Output {
    let mut args = vec![
        "tune",
        s(plant),
        "--candidates",
        "100000",
        "--plants",
        "1",
        "--threads",
        "1",
        "-o",
        s(gains),
    ];
    if let Some(r) = resume {
        args.extend(["--resume", s(r)]);
    }
    let mut child = start(&args);
    std::thread::sleep(Duration::from_secs(4));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the search ended early"
    );
    common::kill(signal, child.id());
    child.wait_with_output().unwrap()
}

/// The search state a stopped search wrote.
fn state(path: &Path) -> SearchState {
    toml::from_str(&std::fs::read_to_string(path).expect("search state written")).unwrap()
}

/// Runs `tune` to its end with `extra` arguments (one plant, one thread).
fn tune_to_end(plant: &Path, candidates: usize, gains: &Path, extra: &[&str]) {
    let n = candidates.to_string();
    let mut args = vec![
        "tune",
        s(plant),
        "--candidates",
        &n,
        "--plants",
        "1",
        "--threads",
        "1",
        "-o",
        s(gains),
    ];
    args.extend(extra);
    common::ok(&softjoint(&args));
}

#[test]
fn a_stopped_tune_keeps_its_best_and_resumes_to_the_gains_of_an_unbroken_search() {
    let dir = scratch("tune-stop");
    let plant = crate::identify_cli::hidden_2d_file(&dir);
    let gains = dir.join("g.toml");
    let state_path = dir.join("g.search.toml");
    // Ctrl-C: exit 130, the state beside the gains file, no gains file.
    let o = stopped_tune(&plant, &gains, None, "-INT");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert!(
        err.contains("stopped by SIGINT")
            && err.contains("--resume")
            && err.contains("best so far"),
        "{err}"
    );
    assert!(!gains.exists(), "a gains file from an unfinished search");
    let first = state(&state_path);
    let k = first.scored.len();
    assert!(
        err.contains(&format!("{k} of 100000 candidates scored")),
        "{err}"
    );
    assert!(first.scored.windows(2).all(|w| w[0].index < w[1].index));
    if k > 0 {
        let best = first.best.as_ref().expect("a best candidate");
        let min = first
            .scored
            .iter()
            .filter_map(|s| s.score.as_ref().map(|x| x.robust))
            .fold(f64::INFINITY, f64::min);
        assert_eq!(best.robust_cost, min);
    }
    // Resumed, then SIGHUP: exit 129, the state file updated in place with
    // every candidate it had and more.
    let o = stopped_tune(&plant, &gains, Some(&state_path), "-HUP");
    assert_eq!(o.status.code(), Some(129), "{}", stderr(&o));
    let second = state(&state_path);
    assert!(second.scored.len() >= k, "{} < {k}", second.scored.len());
    for s0 in &first.scored {
        assert!(second.scored.contains(s0), "candidate {} lost", s0.index);
    }
    // A resume that asks another search is refused by name.
    let o = softjoint(&[
        "tune",
        s(&plant),
        "--plants",
        "2",
        "-o",
        s(&gains),
        "--resume",
        s(&state_path),
    ]);
    assert_refused(&o, "--plants 1, this one asks 2");
    // Resumed to the end of a short search: the very gains file of the
    // same search never stopped.
    let n = second.scored.len() + 2;
    tune_to_end(&plant, n, &gains, &["--resume", s(&state_path)]);
    let straight = dir.join("straight.toml");
    tune_to_end(&plant, n, &straight, &[]);
    assert_eq!(
        std::fs::read_to_string(&gains).unwrap(),
        std::fs::read_to_string(&straight).unwrap()
    );
}
