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
/// `--allow-unproven`: the search's size is however many candidates the
/// stopped run scored before its signal (load-dependent), and a small one
/// may lose to the paper's gains on the held-out steps; what is compared
/// here is the resumed search against the unbroken one, not the gains'
/// quality (that is `tune`'s own tests').
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
        "--allow-unproven",
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

/// Borrowed arguments.
fn args(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// Runs `softjoint args` to its end (exit 0); how long it took.
fn timed(args: &[&str]) -> Duration {
    let t = Instant::now();
    common::ok(&softjoint(args));
    t.elapsed()
}

/// Starts `softjoint args`, sends `signal` after `after` (the search
/// still running then) and returns its output.
fn signalled(args: &[&str], after: Duration, signal: &str) -> Output {
    try_signalled(args, after, signal).expect("the search ended before the signal")
}

/// [`signalled`], or `None` when the program ended before the signal.
fn try_signalled(args: &[&str], after: Duration, signal: &str) -> Option<Output> {
    let mut child = start(args);
    std::thread::sleep(after);
    if child.try_wait().unwrap().is_some() {
        return None;
    }
    common::kill(signal, child.id());
    Some(child.wait_with_output().unwrap())
}

/// How many times a timed stop is tried: a machine under load may be
/// slower or faster than the times measured just before (the signal
/// then comes before the search or after it), so a stop that missed the
/// search is tried again with the signal later or the search longer.
const ATTEMPTS: u32 = 4;

/// Whether `out` holds a search state with no candidate in it (the
/// signal came before the search).
fn stopped_before_the_search(out: &Path) -> bool {
    let path = out.join("params.search.toml");
    path.exists() && scored(&toml_state(&path)).is_empty()
}

/// A stopped calibration's state file, as TOML.
fn toml_state(path: &Path) -> toml::Table {
    let text = std::fs::read_to_string(path).expect("search state written");
    toml::from_str(&text).unwrap()
}

/// The `scored` list of a state: (genes, score) in the order they came in.
fn scored(state: &toml::Table) -> Vec<(Vec<f64>, Option<f64>)> {
    state["scored"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| {
            let genes = e["genes"]
                .as_array()
                .unwrap()
                .iter()
                .map(|g| g.as_float().unwrap())
                .collect();
            (genes, e.get("score").and_then(|v| v.as_float()))
        })
        .collect()
}

/// `generations.csv` without its wall-time column (the last).
fn generations_without_time(path: &Path) -> Vec<String> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').map_or(l, |(head, _)| head).to_string())
        .collect()
}

/// The checks every stopped calibration passes: exit status, the message,
/// no result file, a state whose best is the best of its scores
/// (`lower_is_better` for S, higher for μ(F)). Returns the state.
fn assert_stopped_calibration(
    o: &Output,
    code: i32,
    signal: &str,
    out: &Path,
    result_file: &str,
    lower_is_better: bool,
) -> toml::Table {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(code), "{err}");
    assert!(
        err.contains(&format!("stopped by {signal}"))
            && err.contains("--resume")
            && err.contains("best so far"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    assert!(
        !out.join(result_file).exists(),
        "a result file from an unfinished search"
    );
    let state = toml_state(&out.join("params.search.toml"));
    let list = scored(&state);
    assert!(!list.is_empty(), "stopped before any candidate: {err}");
    let evaluations = state["evaluations"].as_integer().unwrap() as usize;
    assert!(evaluations >= list.len(), "{evaluations} < {}", list.len());
    assert!(err.contains(&format!(
        "{evaluations} evaluations ({} candidates simulated)",
        list.len()
    )));
    let scores = list.iter().filter_map(|(_, s)| *s);
    let want = if lower_is_better {
        scores.fold(f64::INFINITY, f64::min)
    } else {
        scores.fold(f64::NEG_INFINITY, f64::max)
    };
    let best = state["best"].as_table().expect("a best candidate");
    let got = best
        .get("s")
        .or(best.get("score"))
        .and_then(|v| v.as_float())
        .unwrap();
    // μ(F) is kept as the search's fitness; S as it is.
    assert_eq!(got, want, "best so far is not the best of the scores");
    state
}

/// The repository's small rheology scenario (a 3 × 3 × 3 lattice).
const SMALL_RHEOLOGY: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenarios/rheology/small.toml"
);

#[test]
fn a_stopped_rheology_calibration_keeps_its_best_and_resumes_to_the_result_of_an_unbroken_one() {
    let dir = scratch("rheology-stop");
    let measured = dir.join("measured");
    common::ok(&softjoint(&[
        "rheology",
        "simulate",
        SMALL_RHEOLOGY,
        "--model",
        "reference",
        "--out",
        s(&measured),
    ]));
    let calibrate = |evaluations: &str, out: &Path| -> Vec<String> {
        [
            "rheology",
            "calibrate",
            SMALL_RHEOLOGY,
            "--measured",
            s(&measured),
            "--evaluations",
            evaluations,
            "--out",
            s(out),
        ]
        .map(String::from)
        .to_vec()
    };
    // What comes before the search (and after it), timed on a search of
    // one candidate: the signal comes half a second into the search.
    let warm = timed(&args(&calibrate("1", &dir.join("warm"))));
    let mut after = warm + Duration::from_millis(500);
    // Ctrl-C: exit 130, the state in the output directory, no params.toml.
    let out = dir.join("stopped");
    let mut o = signalled(&args(&calibrate("1000000", &out)), after, "-INT");
    for _ in 1..ATTEMPTS {
        if !stopped_before_the_search(&out) {
            break;
        }
        after *= 2;
        o = signalled(&args(&calibrate("1000000", &out)), after, "-INT");
    }
    let first = assert_stopped_calibration(&o, 130, "SIGINT", &out, "params.toml", true);
    let state_path = out.join("params.search.toml");
    let a = scored(&first);
    // Resumed, then SIGHUP: exit 129, the state file updated in place,
    // its candidates first, in order, and more after them.
    let mut resumed = calibrate("1000000", &out);
    resumed.extend(["--resume".into(), s(&state_path).into()]);
    let mut o = signalled(&args(&resumed), after, "-HUP");
    for _ in 1..ATTEMPTS {
        if state_path.exists() && scored(&toml_state(&state_path)).len() > a.len() {
            break;
        }
        after *= 2;
        o = signalled(&args(&resumed), after, "-HUP");
    }
    let second = assert_stopped_calibration(&o, 129, "SIGHUP", &out, "params.toml", true);
    let b = scored(&second);
    assert!(
        b.len() > a.len(),
        "the resumed search simulated nothing new"
    );
    assert_eq!(b[..a.len()], a[..]);
    // A resume that asks another search is refused by name.
    let mut other = resumed.clone();
    other.extend(["--seed".into(), "2".into()]);
    assert_refused(&softjoint(&args(&other)), "--seed 1, this one asks 2");
    // Resumed to the end of a search a little longer than the stopped
    // one: the very parameters and history of the same search unbroken.
    let n = (second["evaluations"].as_integer().unwrap() + 24).to_string();
    let mut to_end = calibrate(&n, &out);
    to_end.extend(["--resume".into(), s(&state_path).into(), "--json".into()]);
    let o = softjoint(&args(&to_end));
    common::ok(&o);
    let j: serde_json::Value = serde_json::from_str(&common::stdout(&o)).unwrap();
    // Every candidate kept lies on the path of the first n evaluations
    // (the stopped search's, up to its last batch): each is taken back.
    assert!(
        j["resumed"]["candidates_taken"].as_u64().unwrap() >= b.len() as u64,
        "{j}"
    );
    let straight = dir.join("straight");
    timed(&args(&calibrate(&n, &straight)));
    assert_eq!(
        std::fs::read_to_string(out.join("params.toml")).unwrap(),
        std::fs::read_to_string(straight.join("params.toml")).unwrap()
    );
    assert_eq!(
        generations_without_time(&out.join("generations.csv")),
        generations_without_time(&straight.join("generations.csv"))
    );
}

#[test]
fn a_stopped_push_calibration_keeps_its_best_and_resumes_to_the_result_of_an_unbroken_one() {
    let dir = scratch("push-stop");
    // A small mesh on a recorded push (no ground truth made per run).
    let grid = ["--nx", "4", "--ny", "2", "--cell-px", "16"];
    let recorded = dir.join("recorded");
    let mut sim = vec!["push", "simulate", "--ref-element-px", "32"];
    sim.extend(grid);
    sim.extend(["--out", s(&recorded)]);
    common::ok(&softjoint(&sim));
    let video = recorded.join("video.csv");
    let calibrate = |generations: &str, out: &Path| -> Vec<String> {
        let mut v: Vec<String> = ["push", "calibrate", "--video", s(&video)]
            .into_iter()
            .chain(grid)
            .map(String::from)
            .collect();
        v.extend(["--generations", generations, "--out", s(out)].map(String::from));
        v
    };
    // The generations of one search of about 1 s (σ falls over them, so
    // the stopped, resumed and unbroken searches all ask the same count),
    // from the time of 1 and 31 generations (20 to 200 of them); the
    // signal comes 40 % of the way into the search.
    let one = timed(&args(&calibrate("1", &dir.join("warm"))));
    let more = timed(&args(&calibrate("31", &dir.join("warm"))));
    let mut per_generation = (more.saturating_sub(one) / 30).max(Duration::from_millis(1));
    let mut generations = (1.0 / per_generation.as_secs_f64()).clamp(20.0, 200.0) as u32;
    // SIGTERM: exit 143, the state in the output directory, no params.json.
    let out = dir.join("stopped");
    let mut attempt = 1;
    let o = loop {
        let _ = std::fs::remove_dir_all(&out);
        let after = one + per_generation * (generations * 2 / 5);
        let o = try_signalled(
            &args(&calibrate(&generations.to_string(), &out)),
            after,
            "-TERM",
        );
        // The search ended before the signal, or during the work after
        // it: a search twice as long, the signal at the same time. The
        // signal came before the search: the signal later.
        let (ended_early, too_soon) = match &o {
            None => (true, false),
            Some(_) if out.join("params.json").exists() => (true, false),
            Some(_) => (false, stopped_before_the_search(&out)),
        };
        if !(ended_early || too_soon) || attempt == ATTEMPTS {
            break o.expect("the search ended before the signal");
        }
        attempt += 1;
        if ended_early {
            generations *= 2;
            per_generation /= 2;
        } else {
            per_generation *= 2;
        }
    };
    let generations = generations.to_string();
    let first = assert_stopped_calibration(&o, 143, "SIGTERM", &out, "params.json", false);
    let state_path = out.join("params.search.toml");
    // Another --generations is another search: refused by name.
    let mut other = calibrate("7", &out);
    other.extend(["--resume".into(), s(&state_path).into()]);
    assert_refused(
        &softjoint(&args(&other)),
        &format!("--generations {generations}, this one asks 7"),
    );
    // Resumed to the end: the very parameters and history of the same
    // search unbroken, every candidate kept taken back, none run again.
    let mut to_end = calibrate(&generations, &out);
    to_end.extend(["--resume".into(), s(&state_path).into()]);
    let o = softjoint(&args(&to_end));
    common::ok(&o);
    let kept = scored(&first).len();
    let text = common::stdout(&o);
    let taken: usize = text
        .split_once(": ")
        .and_then(|_| text.split(" candidates' scores taken from it").next())
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no resume line: {text}"));
    assert!(taken >= kept, "{taken} < {kept}: {text}");
    let straight = dir.join("straight");
    timed(&args(&calibrate(&generations, &straight)));
    for f in ["params.json", "generations.csv"] {
        assert_eq!(
            std::fs::read_to_string(out.join(f)).unwrap(),
            std::fs::read_to_string(straight.join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn a_stopped_identification_ends_at_once_and_writes_nothing() {
    let dir = scratch("identify-stop");
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
    let before = names(&dir);
    let (plant, plot) = (dir.join("p.toml"), dir.join("fit.svg"));
    // A fit of a 5-minute log, a thousand iterations a stage (tens of
    // seconds even optimised), stopped a second in.
    let started = Instant::now();
    let o = signalled(
        &[
            "identify",
            "joint",
            s(&log),
            "--max-iterations",
            "1000",
            "-o",
            s(&plant),
            "--plot",
            s(&plot),
        ],
        Duration::from_secs(1),
        "-INT",
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(130), "{err}");
    assert!(
        err.contains("stopped by SIGINT") && err.contains("nothing was written"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    // Within one replay of the log, not at the end of the fit.
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "{:?}",
        started.elapsed()
    );
    assert_eq!(names(&dir), before, "files left by a stopped fit");
}

/// A stand-in for `python3 -m softjoint.ray_sweep` (the real driver
/// needs Ray; python/tests/test_ray.py stops it on a cluster): it notes
/// that it runs, waits, and on SIGINT hands back the units it "finished"
/// (`driver.sh.units`: candidate 0 failed, candidate 1 scored) as the
/// real one does, exit 130.
const FAKE_DRIVER: &str = r#"#!/bin/sh
while [ $# -gt 0 ]; do
    if [ "$1" = --units-out ]; then units=$2; fi
    shift
done
trap 'cat "$0.units" > "$units"; exit 130' INT
touch "$0.started"
while :; do sleep 0.05; done
"#;

const FAKE_UNITS: &str = "[[scored]]
index = 0

[[scored]]
index = 1

[scored.score]
mean = 2.5
std = 0.5
robust = 3.0

[scored.score.nominal]
settling_s = 1.0
overshoot_deg = 0.1
steady_state_error_deg = 0.01
peak_coil_c = 40.0
budget_margin_k = 50.0
fault = false
cost = 2.5
";

/// SIGTERM to `tune --ray` alone (not its process group): the program
/// passes the stop on to its driver as SIGINT, and writes the units the
/// driver finished as its search state (best so far, resumable), exit
/// 143, at once. On main before this, the driver never heard of the
/// signal (the program waited out its whole sweep, here a minute's
/// sleep) and the state kept nothing.
#[test]
fn a_stopped_tune_on_ray_stops_its_driver_and_keeps_the_units_it_finished() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = scratch("tune-ray-stop");
    let plant = crate::identify_cli::hidden_2d_file(&dir);
    let driver = dir.join("driver.sh");
    std::fs::write(&driver, FAKE_DRIVER).unwrap();
    std::fs::set_permissions(&driver, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::write(dir.join("driver.sh.units"), FAKE_UNITS).unwrap();
    let gains = dir.join("g.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["tune", s(&plant), "--candidates", "4", "--plants", "1"])
        .args(["--ray", "127.0.0.1:1", "-o", s(&gains)])
        .env("SOFTJOINT_PYTHON", &driver)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("softjoint starts");
    let until = Instant::now() + Duration::from_secs(20);
    while !dir.join("driver.sh.started").exists() {
        assert!(Instant::now() < until, "the driver never started");
        std::thread::sleep(Duration::from_millis(20));
    }
    common::kill("-TERM", child.id());
    let until = Instant::now() + Duration::from_secs(20);
    while child.try_wait().unwrap().is_none() {
        if Instant::now() > until {
            let _ = child.kill();
            let _ = child.wait();
            panic!("tune --ray still running 20 s after SIGTERM: its driver was not stopped");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(143), "{err}");
    assert!(
        err.contains("stopped by SIGTERM: 2 of 4 candidates scored, best so far: candidate 1 (robust cost 3.000"),
        "{err}"
    );
    let kept = state(&dir.join("g.search.toml"));
    let units: host_tools::joint::tune::ScoredFile = toml::from_str(FAKE_UNITS).unwrap();
    assert_eq!(kept.scored, units.scored);
    assert_eq!(kept.best.as_ref().map(|b| b.index), Some(1));
    assert!(!gains.exists() && !dir.join("g.ray-units.toml").exists());
}
