//! `softjoint sim` and `softjoint calibrate wire` through the built binary
//! (issue 3): the `--json` summary fields, errors that name the file and the
//! field or line with a non-zero exit, `--csv` / `--plot` outputs, and the
//! calibration workflow end to end (simulated sweep → calibrate → a scenario
//! that loads the calibration file).
use crate::common;

use common::{ok, s, scratch, softjoint, stderr, stdout};
use serde_json::Value;
use std::path::Path;

fn numbers(v: &Value, key: &str) -> Vec<f64> {
    v[key]
        .as_array()
        .unwrap_or_else(|| panic!("`{key}` is not an array in {v}"))
        .iter()
        .map(|x| {
            x.as_f64()
                .unwrap_or_else(|| panic!("`{key}` holds a non-number: {x}"))
        })
        .collect()
}

/// The README's one command: no scenario, the built-in 3D default.
#[test]
fn sim_json_of_the_default_scenario_has_the_summary_fields() {
    let o = softjoint(&["sim", "--json"]);
    ok(&o);
    let v: Value = serde_json::from_str(&stdout(&o))
        .unwrap_or_else(|e| panic!("not JSON ({e}):\n{}", stdout(&o)));
    let sse = numbers(&v, "steady_state_error_deg");
    let est = numbers(&v, "max_estimation_error_deg");
    assert_eq!(
        sse.len(),
        2,
        "one steady-state error per controlled angle (α, β): {sse:?}"
    );
    assert_eq!(est.len(), 2, "{est:?}");
    // The default converges (measured 0.42°, 0.44°; estimation 0.35°, 0.36°).
    assert!(
        sse.iter().all(|e| e.is_finite() && *e < 1.0),
        "steady-state error {sse:?}"
    );
    assert!(
        est.iter().all(|e| e.is_finite() && *e < 1.0),
        "estimation error {est:?}"
    );
    assert_eq!(v["sim_seconds"].as_f64(), Some(30.0), "{v}");
    let rtf = v["realtime_factor"]
        .as_f64()
        .expect("realtime_factor is a number");
    assert!(rtf.is_finite() && rtf > 1.0, "realtime_factor {rtf}");
    assert!(
        v["faults_seen"].as_array().is_some_and(|f| f.is_empty()),
        "faults: {}",
        v["faults_seen"]
    );
}

#[test]
fn sim_without_json_prints_a_readable_table() {
    let dir = scratch("table");
    let scen = dir.join("short.toml");
    std::fs::write(
        &scen,
        "joint = \"3d\"\nduration_s = 2.0\n[estimator]\nmethod = \"paper\"\n",
    )
    .unwrap();
    let o = softjoint(&["sim", s(&scen)]);
    ok(&o);
    let out = stdout(&o);
    for needle in [
        "steady-state error",
        "estimation error",
        "alpha",
        "beta",
        "real time",
    ] {
        assert!(out.contains(needle), "table lacks `{needle}`:\n{out}");
    }
}

#[test]
fn malformed_scenarios_name_the_file_and_field_and_fail() {
    let dir = scratch("malformed");
    let cases = [
        // TOML type error, found by the parser.
        ("type.toml", "joint = \"2d\"\nduration_s = \"ten\"\n", "duration_s"),
        // Unknown field.
        ("unknown.toml", "durration_s = 10.0\n", "durration_s"),
        // Parses, fails validation.
        (
            "range.toml",
            "joint = \"2d\"\n[estimator]\nmethod = \"paper\"\n[[targets]]\nt_s = 0.0\ndeg = [40.0]\n",
            "targets[0].deg[0]",
        ),
        ("gains.toml", "[controller]\nkp_v_per_deg = [1.0, 2.0, 3.0]\n", "controller.kp_v_per_deg"),
    ];
    for (name, text, field) in cases {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let o = softjoint(&["sim", s(&path), "--json"]);
        assert!(
            !o.status.success(),
            "{name}: exit 0 for a malformed scenario"
        );
        let err = stderr(&o);
        assert!(
            err.contains(s(&path)),
            "{name}: error does not name the file:\n{err}"
        );
        assert!(
            err.contains(field),
            "{name}: error does not name `{field}`:\n{err}"
        );
        assert!(
            stdout(&o).is_empty(),
            "{name}: printed a summary anyway:\n{}",
            stdout(&o)
        );
    }
    // A missing file is an error naming it, too.
    let missing = dir.join("missing.toml");
    let o = softjoint(&["sim", s(&missing)]);
    assert!(
        !o.status.success() && stderr(&o).contains(s(&missing)),
        "{}",
        stderr(&o)
    );
}

#[test]
fn calibrate_wire_names_the_line_of_a_bad_row() {
    let dir = scratch("badrow");
    let mut csv = String::from("d_mm,theta_deg\n");
    for k in 0..12 {
        csv.push_str(&format!("{:.3},{:.3}\n", 0.1 * k as f64, -0.5 * k as f64));
    }
    // Line 14 (1-based, header is line 1): a cell that is not a number.
    csv.push_str("0.5,abc\n");
    csv.push_str("0.6,-3.0\n");
    let path = dir.join("sweep.csv");
    std::fs::write(&path, csv).unwrap();
    let out = dir.join("cal.toml");
    let o = softjoint(&["calibrate", "wire", s(&path), "-o", s(&out)]);
    assert!(!o.status.success(), "exit 0 for a bad row");
    let err = stderr(&o);
    assert!(
        err.contains(&format!("{}:14:", s(&path))),
        "error does not name line 14:\n{err}"
    );
    assert!(
        err.contains(s(&path)),
        "error does not name the file:\n{err}"
    );
    assert!(
        !out.exists(),
        "a calibration file was written from a bad sweep"
    );

    // A short row, too.
    let path2 = dir.join("short.csv");
    std::fs::write(&path2, "d_mm,theta_deg\n0.1,1.0\n0.2\n").unwrap();
    let o = softjoint(&["calibrate", "wire", s(&path2), "-o", s(&out)]);
    assert!(
        !o.status.success() && stderr(&o).contains("short.csv:3: 1 fields"),
        "{}",
        stderr(&o)
    );
}

/// The workflow a user of a real prototype follows, on the simulated joint:
/// sweep (camera-referenced), calibrate, then a scenario that loads the
/// calibration file by a path relative to itself.
#[test]
fn calibration_sweep_then_calibrate_then_sim_with_the_file() {
    let dir = scratch("workflow");
    let sweep = dir.join("sweep.csv");
    let o = softjoint(&["sim", "--calibration-sweep", s(&sweep)]);
    ok(&o);
    let text = std::fs::read_to_string(&sweep).expect("sweep written");
    assert!(
        text.starts_with("d1_mm,d2_mm,d3_mm,d4_mm,alpha_deg,beta_deg"),
        "{}",
        &text[..text.len().min(200)]
    );
    // 80 s at the camera's 30 frames/s.
    let rows = text.lines().count() - 1;
    assert!((2300..=2450).contains(&rows), "{rows} sweep rows");

    let cal = dir.join("cal.toml");
    let o = softjoint(&["calibrate", "wire", s(&sweep), "-o", s(&cal), "--json"]);
    ok(&o);
    let v: Value = serde_json::from_str(&stdout(&o))
        .unwrap_or_else(|e| panic!("not JSON ({e}):\n{}", stdout(&o)));
    let angles = v["angles"].as_array().expect("angles");
    assert_eq!(angles.len(), 2);
    for a in angles {
        let max = a["max_error_deg"].as_f64().expect("max_error_deg");
        assert!(
            max < 1.0,
            "{}: chosen estimator off by {max}° on its own sweep",
            a["angle"]
        );
        assert!(a.get("threshold_deg").is_some(), "no threshold_deg: {a}");
        assert!(a["chosen"].is_object(), "no coefficients: {a}");
    }
    assert!(cal.exists(), "calibration file not written");

    let scen = dir.join("with_cal.toml");
    std::fs::write(
        &scen,
        "joint = \"3d\"\nduration_s = 12.0\nseed = 5\n[estimator]\nmethod = \"switching\"\ncalibration = \"cal.toml\"\n\
         [[targets]]\nt_s = 0.0\ndeg = [0.0, 0.0]\n[[targets]]\nt_s = 4.0\ndeg = [10.0, -10.0]\n",
    )
    .unwrap();
    let o = softjoint(&["sim", s(&scen), "--json"]);
    ok(&o);
    let v: Value = serde_json::from_str(&stdout(&o)).expect("JSON");
    let estimator = v["estimator"].as_str().expect("estimator");
    assert!(
        estimator.contains(s(&cal)),
        "the scenario did not use the calibration file: {estimator}"
    );
    let est = numbers(&v, "max_estimation_error_deg");
    assert!(
        est.iter().all(|e| *e < 1.0),
        "estimation error with the calibration {est:?}"
    );
    let sse = numbers(&v, "steady_state_error_deg");
    assert!(
        sse.iter().all(|e| *e < 1.0),
        "steady-state error with the calibration {sse:?}"
    );
}

#[test]
fn csv_and_plot_are_written() {
    let dir = scratch("outputs");
    let scen = dir.join("s.toml");
    std::fs::write(
        &scen,
        "joint = \"2d\"\nduration_s = 3.0\nfeedback = \"camera\"\n[controller]\nmode = \"single\"\n\
         [estimator]\nmethod = \"paper\"\n[[targets]]\nt_s = 0.0\ndeg = [10.0]\n",
    )
    .unwrap();
    let (csv, svg) = (dir.join("trace.csv"), dir.join("plot.svg"));
    let o = softjoint(&["sim", s(&scen), "--csv", s(&csv), "--plot", s(&svg)]);
    ok(&o);
    let text = std::fs::read_to_string(&csv).expect("CSV written");
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("t_s,theta_true_deg,theta_estimate_deg,theta_desired_deg,v1_V,v2_V,faults"),
        "CSV header"
    );
    // An estimate the core does not have yet (before the first camera
    // frame) is an empty cell; every other cell is a finite number.
    let rows: Vec<Vec<f64>> = lines
        .map(|l| {
            l.split(',')
                .enumerate()
                .map(|(k, c)| {
                    if c.is_empty() && k == 2 {
                        f64::NAN
                    } else {
                        c.parse::<f64>()
                            .ok()
                            .filter(|v| v.is_finite())
                            .unwrap_or_else(|| panic!("bad cell in `{l}`"))
                    }
                })
                .collect()
        })
        .collect();
    let first_estimate = rows.iter().position(|r| !r[2].is_nan()).unwrap();
    assert!(first_estimate < 100, "no estimate for {first_estimate} ms");
    assert!(rows[first_estimate..].iter().all(|r| !r[2].is_nan()));
    assert_eq!(rows.len(), 3000, "one row per 1 ms control period");
    assert!(rows.iter().all(|r| r.len() == 7));
    assert_eq!(
        rows.last().map(|r| r[3]),
        Some(10.0),
        "desired angle column"
    );
    // The joint has moved towards the target by the end (it starts at 0°).
    assert!(
        rows.last().is_some_and(|r| r[1] > 5.0),
        "true angle at 3 s: {:?}",
        rows.last()
    );

    let plot = std::fs::read_to_string(&svg).expect("plot written");
    assert!(
        plot.contains("<svg") && plot.trim_end().ends_with("</svg>"),
        "not an SVG document"
    );
    assert!(
        plot.contains("theta true") && plot.contains("v1"),
        "plot lacks the angle or voltage series"
    );
}

/// The scenario files shipped in `scenarios/` (the README's benchmark runs)
/// load and validate, so the README's commands keep working.
#[test]
fn shipped_scenarios_load() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).expect("scenarios/ exists") {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            host_tools::files::scenario::Scenario::load(&path)
                .unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
            n += 1;
        }
    }
    assert!(
        n >= 2,
        "expected the benchmark scenarios in {}",
        dir.display()
    );
}

/// A 2D scenario file that writes no targets and no name runs the default
/// steps on its one angle, under its file's name (it was refused for the
/// 3D default's two angles it never wrote, and reported as the 3D default).
#[test]
fn a_2d_file_without_targets_runs_the_default_steps_under_its_own_name() {
    let dir = scratch("no_targets");
    let path = dir.join("plain2d.toml");
    std::fs::write(
        &path,
        "joint = \"2d\"\nduration_s = 2.0\n[estimator]\nmethod = \"paper\"\n",
    )
    .unwrap();
    let o = softjoint(&["sim", s(&path), "--json"]);
    ok(&o);
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["joint"], "2d");
    assert_eq!(v["scenario"], s(&path));
    assert_eq!(v["segments"][0]["desired_deg"], serde_json::json!([0.0]));
}

/// The laws fitted to a joint's sweep are kept between runs
/// (`run::law_cache`): the second run reads them instead of sweeping and
/// prints the same summary; an entry is used only under its own key. (A
/// joint other than the default's, whose laws are built in.)
#[test]
fn fitted_laws_are_kept_between_runs_and_used_only_under_their_key() {
    let dir = scratch("law-cache");
    let scenario = dir.join("seed2.toml");
    std::fs::write(&scenario, "joint = \"3d\"\nseed = 2\n").unwrap();
    let run = |cache: &Path| {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_softjoint"))
            .args(["sim", s(&scenario), "--json"])
            .env("SOFTJOINT_CACHE_DIR", cache)
            .output()
            .expect("binary runs");
        ok(&o);
        let mut v: Value = serde_json::from_str(&stdout(&o)).expect("JSON");
        // Wall-clock figures differ between any two runs.
        v.as_object_mut().unwrap().remove("realtime_factor");
        v.as_object_mut().unwrap().remove("wall_seconds");
        v
    };
    let cold = run(&dir);
    let entries: Vec<_> = std::fs::read_dir(&*dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p != &scenario)
        .collect();
    assert_eq!(entries.len(), 1, "one kept fit: {entries:?}");
    let kept = std::fs::read_to_string(&entries[0]).unwrap();
    assert!(
        kept.contains("key = ") && kept.contains("[calibration.alpha]"),
        "{kept}"
    );
    assert_eq!(
        run(&dir),
        cold,
        "a run from the kept laws differs from the sweep's"
    );

    // The entry is really read: laws edited in it (same key) change the run.
    let offset_line = kept
        .lines()
        .find(|l| l.starts_with("offset = "))
        .expect("a differential offset in the kept laws");
    let edited = kept.replacen(offset_line, "offset = 40.0", 1);
    std::fs::write(&entries[0], &edited).unwrap();
    assert_ne!(run(&dir), cold, "the edited entry was not read");

    // Under another key (a rebuilt program, another joint) it is a miss:
    // the run sweeps again, gives the original summary and rewrites it.
    std::fs::write(
        &entries[0],
        edited.replacen("key = \"", "key = \"other ", 1),
    )
    .unwrap();
    assert_eq!(run(&dir), cold, "an entry under another key was used");
    assert_eq!(std::fs::read_to_string(&entries[0]).unwrap(), kept);
}

/// The default scenario's laws are built into the program
/// (`run::laws::BUILT_IN`): its first run neither sweeps nor writes a
/// cache entry, and says where its laws come from exactly as a swept run
/// does (the same summary as with the cache turned off is asserted by
/// `run::laws`'s test that the built-in entry is the fit).
#[test]
fn the_default_runs_first_time_from_its_built_in_laws() {
    let dir = scratch("law-cache-default");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(["sim", "--json"])
        .env("SOFTJOINT_CACHE_DIR", &*dir)
        .output()
        .expect("binary runs");
    ok(&o);
    let v: Value = serde_json::from_str(&stdout(&o)).expect("JSON");
    assert_eq!(
        std::fs::read_dir(&*dir).unwrap().count(),
        0,
        "the default run swept and kept its fit"
    );
    let estimator = v["estimator"].as_str().unwrap_or_default();
    assert!(
        estimator.contains("fitted to a simulated sweep (2399 rows)"),
        "{v}"
    );
}
