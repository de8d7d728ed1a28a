//! The bad-input probe of issue 31, kept as a test: each case runs the
//! real `softjoint` binary as a user would, in a scratch directory that
//! holds a file of the user's (`keep.txt`) and, where the case writes one,
//! a result file from an earlier run; the harness checks the exit code,
//! the message, that no panic or abort happened, that no file was
//! clobbered (every file there before is there after, byte for byte) and
//! that nothing was left (no new file, no process, no temporary file).
//!
//! Every case is refused at once or stopped by a signal within seconds, so
//! the whole table is the CI form. `cargo test -p host-tools --test it
//! probe -- --nocapture` prints the table that docs/probe.md shows.
use crate::common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::s;

/// How a case is run.
enum Run {
    /// To its end (a refusal).
    Plain,
    /// Under `ulimit -v` (KB): the memory there is, whatever the machine.
    Limited(u64),
    /// Stopped by `signal` once `ready` holds (the run is under way);
    /// every process it started must be gone afterwards.
    Signal {
        signal: &'static str,
        ready: fn(&Path, u32) -> bool,
    },
}

/// One bad case.
struct Case {
    /// Issue 31's item.
    item: &'static str,
    /// What is wrong, for the table.
    what: &'static str,
    /// Arguments; `$D` is the scratch directory, `$F` the fixtures'.
    args: &'static [&'static str],
    run: Run,
    /// The exit code expected.
    code: i32,
    /// Words the message must hold.
    needle: &'static str,
    /// Files the case may leave (besides those there before).
    leaves: &'static [&'static str],
    /// Whether the case feeds an absurd value (exit 0 is then an absurd
    /// value accepted).
    absurd: bool,
}

/// What a case did.
#[derive(Default)]
struct Verdict {
    code: Option<i32>,
    panicked: bool,
    message_ok: bool,
    clobbered: Vec<String>,
    left: Vec<String>,
    orphans: usize,
}

impl Verdict {
    fn passed(&self, c: &Case) -> bool {
        self.code == Some(c.code)
            && !self.panicked
            && self.message_ok
            && self.clobbered.is_empty()
            && self.left.is_empty()
            && self.orphans == 0
    }
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let t = e.file_type().unwrap();
            if t.is_dir() {
                out.insert(p.clone(), b"<dir>".to_vec());
                stack.push(p);
            } else {
                out.insert(p.clone(), std::fs::read(&p).unwrap_or_default());
            }
        }
    }
    out
}

fn expand(a: &str, dir: &Path, fixtures: &Path) -> String {
    a.replace("$D", s(dir)).replace("$F", s(fixtures))
}

/// The temporary files a command could leave in the system's temporary
/// directory (tetmsd's scenario file).
fn temp_left(pid: u32) -> Vec<String> {
    let p = std::env::temp_dir().join(format!("softjoint-tetmsd-{pid}.toml"));
    if p.exists() {
        vec![p.display().to_string()]
    } else {
        Vec::new()
    }
}

fn run_case(c: &Case, fixtures: &Path) -> (Verdict, String) {
    let dir = common::scratch("probe");
    std::fs::write(dir.join("keep.txt"), "the user's own file\n").unwrap();
    std::fs::write(dir.join("result.toml"), "# an earlier result\n").unwrap();
    std::fs::create_dir(dir.join("out-rheology")).unwrap();
    std::fs::create_dir(dir.join("out-rheology/params.toml")).unwrap();
    let before = snapshot(&dir);
    let args: Vec<String> = c.args.iter().map(|a| expand(a, &dir, fixtures)).collect();
    let shown = format!("softjoint {}", c.args.join(" "));
    let exe = env!("CARGO_BIN_EXE_softjoint");
    let mut cmd = match c.run {
        Run::Limited(kb) => {
            let mut sh = Command::new("sh");
            sh.arg("-c")
                .arg(format!("ulimit -v {kb} && exec \"$0\" \"$@\""))
                .arg(exe);
            sh
        }
        _ => Command::new(exe),
    };
    cmd.args(&args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let mut v = Verdict::default();
    let mut child = cmd.spawn().unwrap();
    let pid = child.id();
    let mut started = Vec::new();
    if let Run::Signal { signal, ready } = c.run {
        let until = Instant::now() + Duration::from_secs(60);
        while !ready(&dir, pid) {
            assert!(Instant::now() < until, "{shown}: never under way");
            assert!(child.try_wait().unwrap().is_none(), "{shown}: ended early");
            std::thread::sleep(Duration::from_millis(20));
        }
        started = crate::hil_qemu_cli::children(pid);
        common::kill(signal, pid);
    }
    let out: Output = child.wait_with_output().unwrap();
    let err = common::stderr(&out);
    v.code = out.status.code();
    // A panic, or an abort or crash (SIGABRT from the allocator, SIGSEGV).
    let crashed = {
        use std::os::unix::process::ExitStatusExt as _;
        matches!(out.status.signal(), Some(6 | 7 | 11)) || out.status.code() == Some(134)
    };
    v.panicked = err.contains("panicked") || crashed;
    v.message_ok = err.contains(c.needle);
    let until = Instant::now() + Duration::from_secs(5);
    while started.iter().any(|p| crate::hil_qemu_cli::running(*p)) && Instant::now() < until {
        std::thread::sleep(Duration::from_millis(20));
    }
    v.orphans = started
        .iter()
        .filter(|p| crate::hil_qemu_cli::running(**p))
        .count();
    let after = snapshot(&dir);
    for (p, bytes) in &before {
        if after.get(p) != Some(bytes) {
            v.clobbered.push(p.display().to_string());
        }
    }
    for p in after.keys() {
        let name = p.strip_prefix(&*dir).unwrap().display().to_string();
        if !before.contains_key(p) && !c.leaves.contains(&name.as_str()) {
            v.left.push(name);
        }
    }
    v.left.extend(temp_left(pid));
    (v, shown)
}

/// A file under the scratch directory holds at least `n` bytes.
fn log_has_rows(dir: &Path, _pid: u32) -> bool {
    std::fs::metadata(dir.join("log.csv")).map_or(0, |m| m.len()) > 20_000
}

/// Both tetmsd sites run and their scenario file is gone.
fn sites_running(_dir: &Path, pid: u32) -> bool {
    crate::hil_qemu_cli::children(pid).len() == 2
        && !std::env::temp_dir()
            .join(format!("softjoint-tetmsd-{pid}.toml"))
            .exists()
}

/// A tune search under way (its first seconds).
fn after_two_seconds(_dir: &Path, pid: u32) -> bool {
    static START: std::sync::Mutex<Option<(u32, Instant)>> = std::sync::Mutex::new(None);
    let mut s = START.lock().unwrap();
    match *s {
        Some((p, t)) if p == pid => t.elapsed() > Duration::from_secs(2),
        _ => {
            *s = Some((pid, Instant::now()));
            false
        }
    }
}

fn cases() -> Vec<Case> {
    use Run::*;
    let refuse = |item, what, args, needle, absurd| Case {
        item,
        what,
        args,
        run: Plain,
        code: 1,
        needle,
        leaves: &[],
        absurd,
    };
    vec![
        refuse(
            "5",
            "sweep row at 1e30°",
            &[
                "calibrate",
                "wire",
                "$F/outlier_sweep.csv",
                "-o",
                "$D/result.toml",
            ],
            "outlier_sweep.csv:9: column `theta_deg`",
            true,
        ),
        refuse(
            "5",
            "probe force 1e300 N",
            &[
                "viscoelastic",
                "object",
                "--script",
                "$F/probe_1e300.csv",
                "--out-dir",
                "$D/obj",
            ],
            "probe_1e300.csv:3: column `fz_n`",
            true,
        ),
        refuse(
            "5",
            "trial forces ×1e160",
            &["viscoelastic", "fit", "$F/trial_1e160.csv"],
            "trial_1e160.csv:13: column `force`",
            true,
        ),
        refuse(
            "5",
            "trial displacements in the wrong unit (k1 = inf before)",
            &["viscoelastic", "fit", "$F/trial_tiny_u.csv"],
            "beyond any soft material",
            true,
        ),
        refuse(
            "5",
            "identification log: a camera angle of 1e30°",
            &[
                "identify",
                "joint",
                "$F/log_outlier.csv",
                "-o",
                "$D/result.toml",
            ],
            "log_outlier.csv:101: column `cam_theta_deg`",
            true,
        ),
        refuse(
            "7",
            "tune: output in a missing directory, a million candidates",
            &[
                "tune",
                "$F/hidden.toml",
                "--candidates",
                "1000000",
                "-o",
                "$D/missing/g.toml",
            ],
            "missing/g.toml",
            false,
        ),
        refuse(
            "7",
            "identify joint: output in a missing directory",
            &[
                "identify",
                "joint",
                "$F/log.csv",
                "--max-iterations",
                "1000",
                "-o",
                "$D/missing/p.toml",
            ],
            "missing/p.toml",
            false,
        ),
        refuse(
            "7",
            "rheology calibrate: params.toml is a directory",
            &[
                "rheology",
                "calibrate",
                "--evaluations",
                "1000000",
                "--out",
                "$D/out-rheology",
            ],
            "params.toml: it is a directory",
            false,
        ),
        refuse(
            "7",
            "tune --resume of another search (--plants)",
            &[
                "tune",
                "$F/hidden.toml",
                "--plants",
                "3",
                "-o",
                "$D/result.toml",
                "--resume",
                "$F/state.toml",
            ],
            "--plants 1, this one asks 3",
            false,
        ),
        refuse(
            "8",
            "push --nx 5000 (the video is not even read)",
            &[
                "push",
                "simulate",
                "--nx",
                "5000",
                "--video",
                "$D/none.csv",
                "--out",
                "$D/push",
            ],
            "--nx 5000: must be 1..=2000",
            true,
        ),
        Case {
            run: Limited(1_500_000),
            ..refuse(
                "8",
                "push --nx 2000 --ny 2000 under 1.5 GB",
                &[
                    "push",
                    "calibrate",
                    "--nx",
                    "2000",
                    "--ny",
                    "2000",
                    "--out",
                    "$D/push",
                ],
                "needs about 2832 MB",
                true,
            )
        },
        Case {
            run: Limited(4_000_000),
            ..refuse(
                "8",
                "tissue field --dims 1024³ under 4 GB",
                &[
                    "tissue",
                    "field",
                    "--synthetic",
                    "--dims",
                    "1024x1024x1024",
                    "--out-dir",
                    "$D/tissue",
                ],
                "needs about 128881 MB",
                true,
            )
        },
        refuse(
            "3",
            "sim --excite: log in a missing directory (refused before the session)",
            &[
                "sim",
                "$F/s2d.toml",
                "--excite",
                "$F/hour.toml",
                "--log",
                "$D/missing/log.csv",
            ],
            "missing/log.csv",
            false,
        ),
        Case {
            run: Signal {
                signal: "-TERM",
                ready: log_has_rows,
            },
            code: 143,
            leaves: &["log.csv"],
            ..refuse(
                "3",
                "sim --excite stopped by SIGTERM",
                &[
                    "sim",
                    "$F/s2d.toml",
                    "--excite",
                    "$F/hour.toml",
                    "--log",
                    "$D/log.csv",
                ],
                "holds its",
                false,
            )
        },
        Case {
            run: Signal {
                signal: "-HUP",
                ready: log_has_rows,
            },
            code: 129,
            leaves: &["log.csv"],
            ..refuse(
                "3/9",
                "sim --excite stopped by SIGHUP",
                &[
                    "sim",
                    "$F/s2d.toml",
                    "--excite",
                    "$F/hour.toml",
                    "--log",
                    "$D/log.csv",
                ],
                "stopped by SIGHUP",
                false,
            )
        },
        Case {
            run: Signal {
                signal: "-INT",
                ready: after_two_seconds,
            },
            code: 130,
            leaves: &["g.search.toml"],
            ..refuse(
                "7",
                "tune stopped by Ctrl-C",
                &[
                    "tune",
                    "$F/hidden.toml",
                    "--candidates",
                    "100000",
                    "--plants",
                    "1",
                    "--threads",
                    "1",
                    "-o",
                    "$D/g.toml",
                ],
                "search state in",
                false,
            )
        },
        Case {
            run: Signal {
                signal: "-TERM",
                ready: sites_running,
            },
            code: -1,
            ..refuse(
                "2",
                "tetmsd pair killed by SIGTERM",
                &[
                    "tetmsd",
                    "pair",
                    "--level",
                    "3",
                    "--duration-s",
                    "60",
                    "--out-dir",
                    "$D",
                ],
                "",
                false,
            )
        },
        Case {
            run: Signal {
                signal: "-KILL",
                ready: sites_running,
            },
            code: -1,
            ..refuse(
                "2",
                "tetmsd pair killed by SIGKILL",
                &[
                    "tetmsd",
                    "pair",
                    "--level",
                    "3",
                    "--duration-s",
                    "60",
                    "--out-dir",
                    "$D",
                ],
                "",
                false,
            )
        },
        refuse(
            "5",
            "rheology: a shape weight of 1e308 per cm (S past the largest double)",
            &[
                "rheology",
                "simulate",
                "$F/heavy_shape.toml",
                "--measured",
                "$F/meas",
                "--out",
                "$D/rheology",
            ],
            "`objective.shape_per_cm` = 1e308",
            true,
        ),
        refuse(
            "5",
            "rheology calibrate: a force weight of 1e308 per N (the term overflows on a stable run)",
            &[
                "rheology",
                "calibrate",
                "$F/heavy_force.toml",
                "--measured",
                "$F/meas",
                "--evaluations",
                "8",
                "--out",
                "$D/rheology",
            ],
            "`objective.force_per_n`",
            true,
        ),
    ]
}

/// The fixtures the cases read, made once.
fn fixtures(dir: &Path) {
    let w = |name: &str, text: &str| std::fs::write(dir.join(name), text).unwrap();
    let mut sweep = String::from("d_mm,theta_deg\n");
    for i in 0..21 {
        let d = (f64::from(i) - 10.0) * 0.3;
        let deg = if i == 7 { 1e30 } else { 7.0 * d };
        sweep.push_str(&format!("{d},{deg}\n"));
    }
    w("outlier_sweep.csv", &sweep);
    w(
        "probe_1e300.csv",
        "time_s,vertex,fx_n,fy_n,fz_n\n0,0,0,0,-1\n0.2,0,0,0,-1e300\n0.4,-1,0,0,0\n",
    );
    let trial = |scale_f: f64, step_m: f64| {
        let mut t = String::from("time_s,displacement,force\n");
        for i in 0..100 {
            let ts = f64::from(i) * 0.01;
            let (d, f) = if ts > 0.1 {
                (step_m, scale_f * (0.5 + (-(ts - 0.1) / 0.3).exp()))
            } else {
                (0.0, 0.0)
            };
            t.push_str(&format!("{ts},{d:e},{f:e}\n"));
        }
        t
    };
    w("trial_1e160.csv", &trial(1e160, 1e-3));
    w("trial_tiny_u.csv", &trial(1.0, 1e-300));
    w("s2d.toml", crate::excite_stops::SCENARIO_2D);
    w("hour.toml", crate::excite_stops::HOUR_PLAN);
    w(
        "short.toml",
        "name = \"short\"\nduration_s = 3\n[[drive]]\ncoil = 1\nfrom_s = 0\nto_s = 1\nvolts = 2.0\n",
    );
    let log = dir.join("log.csv");
    common::ok(&common::softjoint(&[
        "sim",
        s(&dir.join("s2d.toml")),
        "--excite",
        s(&dir.join("short.toml")),
        "--log",
        s(&log),
    ]));
    let text = std::fs::read_to_string(&log).unwrap();
    let cam = text
        .lines()
        .next()
        .unwrap()
        .split(',')
        .position(|c| c == "cam_theta_deg")
        .unwrap();
    let bad: String = text
        .lines()
        .enumerate()
        .map(|(k, l)| {
            let mut cells: Vec<&str> = l.split(',').collect();
            if k == 100 {
                cells[cam] = "1e30";
            }
            cells.join(",") + "\n"
        })
        .collect();
    w("log_outlier.csv", &bad);
    let plant = crate::identify_cli::hidden_2d_file(dir);
    let bytes = std::fs::read(&plant).unwrap();
    // A search state of --plants 1 on this plant (none scored yet).
    let st = host_tools::joint::tune::SearchState::new(
        s(&plant),
        &bytes,
        host_tools::joint::tune::TuneRequest {
            candidates: 1,
            plants: 1,
            seed: 1,
            search_v_offset: false,
        },
        2,
        Vec::new(),
    );
    w("state.toml", &toml::to_string(&st).unwrap());
    // A measured push for the rheology scenario (eight surface points, two
    // force samples of 1 kN in the force window).
    let small = crate::rheology_cli::SMALL;
    w(
        "heavy_shape.toml",
        &format!("{small}\n[objective]\nshape_per_cm = 1e308\n"),
    );
    w(
        "heavy_force.toml",
        &format!("{small}\n[objective]\nshape_per_cm = 0\nforce_per_n = 1e308\n"),
    );
    std::fs::create_dir_all(dir.join("meas")).unwrap();
    let points: String = (0..8).map(|i| format!("0,0.5,{i}.5,4.5,3\n")).collect();
    w(
        "meas/surface_points.csv",
        &format!("frame,time_s,x_cm,y_cm,z_cm\n{points}"),
    );
    w("meas/forces.csv", "time_s,force_n\n0.6,1000\n1.0,1000\n");
}

#[test]
fn the_probe_table_has_no_clobbered_file_orphan_absurd_value_or_panic() {
    let fx = common::scratch("probe-fixtures");
    fixtures(&fx);
    let mut table = String::from(
        "| # | item | case | command | expected | verdict |\n|---|---|---|---|---|---|\n",
    );
    let (mut failed, mut clobbered, mut orphans, mut absurd, mut panics) = (0, 0, 0, 0, 0);
    for (k, c) in cases().iter().enumerate() {
        let (v, shown) = run_case(c, &fx);
        // A case killed by a signal it does not handle (tetmsd pair) has
        // no exit code; what counts is what it left.
        let code_ok = c.code < 0 || v.code == Some(c.code);
        let ok = if c.code < 0 {
            !v.panicked && v.clobbered.is_empty() && v.left.is_empty() && v.orphans == 0
        } else {
            v.passed(c)
        };
        clobbered += v.clobbered.len();
        orphans += v.orphans;
        panics += usize::from(v.panicked);
        absurd += usize::from(c.absurd && v.code == Some(0));
        let expected = if c.code < 0 {
            "no site left, no temporary file".to_string()
        } else {
            format!("exit {}, says “{}”", c.code, c.needle)
        };
        let verdict = if ok {
            "pass".to_string()
        } else {
            failed += 1;
            format!(
                "FAIL: exit {:?}{}{}{}{}{}",
                v.code,
                if code_ok { "" } else { " (code)" },
                if v.message_ok || c.code < 0 {
                    ""
                } else {
                    ", message"
                },
                if v.clobbered.is_empty() {
                    String::new()
                } else {
                    format!(", clobbered {:?}", v.clobbered)
                },
                if v.left.is_empty() {
                    String::new()
                } else {
                    format!(", left {:?}", v.left)
                },
                if v.orphans == 0 {
                    String::new()
                } else {
                    format!(", {} orphans", v.orphans)
                },
            )
        };
        table.push_str(&format!(
            "| {} | {} | {} | `{}` | {} | {} |\n",
            k + 1,
            c.item,
            c.what,
            shown.replace('|', "\\|"),
            expected.replace('|', "\\|"),
            verdict
        ));
    }
    println!("{table}");
    println!(
        "clobbered files {clobbered}, orphaned processes {orphans}, absurd values accepted {absurd}, panics or aborts {panics}, cases failed {failed}"
    );
    assert_eq!(
        (failed, clobbered, orphans, absurd, panics),
        (0, 0, 0, 0, 0),
        "\n{table}"
    );
}
