//! `softjoint rheology` end to end through the built binary: the default
//! scenario round trip, simulate (lattice and reference) with its files,
//! scoring against a measured push, a short calibration whose parameters
//! `simulate` reads back, the instability report, and bad input named by
//! file, field, line or flag.
use crate::common;

use common::{file, ok, refused, s, scratch, softjoint, stdout};

/// A small, fast scenario (debug build): a 4 × 3 × 4 lattice at 20 ms,
/// a 2 s push, a 2 × 2 × 2-cube reference.
pub(crate) const SMALL: &str = r#"
[block]
size_cm = [6.0, 4.0, 6.0]
mass_g = 172.8
grid = [4, 3, 4]
[model]
dt_ms = 20.0
[plate]
footprint_cm = [3.0, 3.0]
depth_mm = [[0.0, 0.0], [0.5, 6.0], [1.5, 6.0], [2.0, 0.0]]
end_s = 2.0
[measure]
frame_times_s = [0.5, 1.5, 2.0]
force_window_s = [0.5, 1.5]
[reference]
cells = [2, 2, 2]
dt_ms = 20.0
points_per_frame = 100
"#;

fn json(o: &std::process::Output) -> serde_json::Value {
    serde_json::from_str(&stdout(o)).unwrap_or_else(|e| panic!("{e}: {}", stdout(o)))
}

fn no_non_finite(text: &str) {
    for bad in ["NaN", "nan", "inf"] {
        assert!(!text.contains(bad), "non-finite number in output:\n{text}");
    }
}

#[test]
fn the_printed_default_scenario_reads_back_and_simulates() {
    let dir = scratch("rheology-default");
    let o = softjoint(&["rheology", "simulate", "--print-default"]);
    ok(&o);
    let text = stdout(&o);
    assert!(text.contains("[reference.material]") && text.contains("depth_mm"));
    // Shrink it for a debug build, keep everything else as printed.
    let small = text
        // Cubic voxels (3 cm): a lattice of non-cubic voxels that positive
        // constants cannot make as stiff as cubic ones is refused (issue 29).
        .replace("size_cm = [10.0, 6.0, 10.0]", "size_cm = [6.0, 6.0, 6.0]")
        .replace("grid = [6, 4, 6]", "grid = [3, 3, 3]")
        .replace("dt_ms = 5.0\ngravity", "dt_ms = 50.0\ngravity");
    let path = file(&dir, "default.toml", &small);
    let out = dir.join("out");
    let o = softjoint(&["rheology", "simulate", &path, "--out", s(&out), "--json"]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["grid"], serde_json::json!([3, 3, 3]));
    assert_eq!(j["steps"], 100);
    assert!(j["peak_force_n"].as_f64().unwrap() > 0.0);
}

#[test]
fn simulate_scores_against_a_measured_push_and_calibrate_writes_parameters_simulate_reads() {
    let dir = scratch("rheology-run");
    let sc = file(&dir, "small.toml", SMALL);
    // The reference block's push: a measurement.
    let meas = dir.join("measured");
    let o = softjoint(&[
        "rheology",
        "simulate",
        &sc,
        "--model",
        "reference",
        "--out",
        s(&meas),
        "--json",
    ]);
    ok(&o);
    let points = std::fs::read_to_string(meas.join("surface_points.csv")).unwrap();
    assert!(points.starts_with("frame,time_s,x_cm,y_cm,z_cm\n"));
    assert_eq!(json(&o)["frames"].as_array().unwrap().len(), 3);
    // The lattice scored against it.
    let sim = dir.join("sim");
    let o = softjoint(&[
        "rheology",
        "simulate",
        &sc,
        "--measured",
        s(&meas),
        "--out",
        s(&sim),
        "--json",
        "--section-times",
        "0,1,2",
    ]);
    ok(&o);
    let j = json(&o);
    let s_default = j["score"]["s"].as_f64().unwrap();
    assert!(s_default > 0.0 && j["score"]["points"].as_u64().unwrap() > 100);
    let forces = std::fs::read_to_string(sim.join("forces.csv")).unwrap();
    assert!(forces.starts_with("time_s,depth_mm,force_n,volume_cm3\n"));
    assert_eq!(forces.lines().count(), 1 + 100);
    no_non_finite(&forces);
    for svg in ["sections.svg", "force.svg"] {
        let t = std::fs::read_to_string(sim.join(svg)).unwrap();
        assert!(t.starts_with("<svg") && t.contains("</svg>"), "{svg}");
        no_non_finite(&t);
    }
    // Three panels in the sections picture.
    let t = std::fs::read_to_string(sim.join("sections.svg")).unwrap();
    assert_eq!(t.matches(">t = ").count(), 3);
    // A short calibration against the same measurement.
    let cal = dir.join("cal");
    let o = softjoint(&[
        "rheology",
        "calibrate",
        &sc,
        "--measured",
        s(&meas),
        "--method",
        "ga",
        "--params",
        "4",
        "--evaluations",
        "30",
        "--seed",
        "3",
        "--out",
        s(&cal),
        "--json",
    ]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["evaluations"], 30);
    assert!(j["calibrated"]["s"].as_f64().unwrap() <= j["default"]["s"].as_f64().unwrap());
    assert!((j["default"]["s"].as_f64().unwrap() - s_default).abs() < 1e-9 * s_default);
    let gens = std::fs::read_to_string(cal.join("generations.csv")).unwrap();
    assert!(gens.starts_with("generation,evaluations,best_s,"));
    assert!(std::fs::read_to_string(cal.join("s_per_generation.svg"))
        .unwrap()
        .starts_with("<svg"));
    // simulate reads the calibrated parameters back and finds the same S.
    let o = softjoint(&[
        "rheology",
        "simulate",
        &sc,
        "--measured",
        s(&meas),
        "--params",
        s(&cal.join("params.toml")),
        "--out",
        s(&dir.join("again")),
        "--json",
    ]);
    ok(&o);
    let again = json(&o)["score"]["s"].as_f64().unwrap();
    let best = j["calibrated"]["s"].as_f64().unwrap();
    assert!((again - best).abs() < 1e-6 * best, "{again} vs {best}");
}

#[test]
fn an_unstable_run_is_reported_by_name_and_writes_no_non_finite_numbers() {
    let dir = scratch("rheology-unstable");
    let sc = file(
        &dir,
        "euler.toml",
        &SMALL.replace(
            "dt_ms = 20.0\n[plate]",
            "dt_ms = 2.0\nintegrator = \"explicit_euler\"\n[plate]",
        ),
    );
    let out = dir.join("out");
    let err = refused(
        &["rheology", "simulate", &sc, "--out", s(&out)],
        &["unstable at t = ", "step"],
    );
    assert!(!err.contains("NaN"), "{err}");
    let forces = std::fs::read_to_string(out.join("forces.csv")).unwrap();
    no_non_finite(&forces);
}

#[test]
fn bad_input_is_refused_with_the_file_field_line_or_flag() {
    let dir = scratch("rheology-bad");
    let sc = file(&dir, "small.toml", SMALL);
    let unknown = file(
        &dir,
        "unknown.toml",
        "[block]\ngrid = [6, 4, 6]\ncolour = 3\n",
    );
    refused(
        &["rheology", "simulate", &unknown],
        &["unknown.toml", "colour", "line 3"],
    );
    let grid = file(&dir, "grid.toml", "[block]\ngrid = [1, 4, 6]\n");
    refused(&["rheology", "simulate", &grid], &["grid.toml", "grid.x"]);
    let dt = file(&dir, "dt.toml", "[model]\ndt_ms = -5.0\n");
    refused(&["rheology", "simulate", &dt], &["dt.toml", "model.dt_ms"]);
    let deep = file(
        &dir,
        "deep.toml",
        "[plate]\ndepth_mm = [[0.0, 0.0], [1.0, 70.0]]\n",
    );
    refused(
        &["rheology", "simulate", &deep],
        &["deep.toml", "plate.depth_mm", "table"],
    );
    let order = file(
        &dir,
        "order.toml",
        "[plate]\ndepth_mm = [[0.0, 0.0], [2.0, 5.0], [1.0, 5.0]]\n",
    );
    refused(
        &["rheology", "simulate", &order],
        &["plate.depth_mm[2]", "increase"],
    );
    let a = file(&dir, "a.toml", "[model.params.all]\nk_gf_per_cm2 = 500.0\nc1_gfs_per_cm2 = 2000.0\nc2_gfs_per_cm2 = 2000.0\na = 1.5\n");
    refused(
        &["rheology", "simulate", &a],
        &["a.toml", "model.params.surface_on.a"],
    );
    refused(
        &["rheology", "simulate", "/nonexistent/x.toml"],
        &["cannot read scenario /nonexistent/x.toml"],
    );
    refused(
        &[
            "rheology",
            "simulate",
            &sc,
            "--section-times",
            "-1,1",
            "--out",
            s(&dir.join("o")),
        ],
        &["--section-times", "-1"],
    );
    refused(
        &["rheology", "calibrate", &sc, "--params", "5"],
        &["--params", "4, 8 or 16"],
    );
    refused(
        &["rheology", "calibrate", &sc, "--evaluations", "0"],
        &["--evaluations"],
    );
    refused(
        &["rheology", "calibrate", &sc, "--seconds", "-2"],
        &["--seconds", "-2"],
    );
    // A measured push with a bad row: file and line.
    let meas = dir.join("meas");
    std::fs::create_dir_all(&meas).unwrap();
    file(
        &meas,
        "surface_points.csv",
        "frame,time_s,x_cm,y_cm,z_cm\n0,0.5,1,2,3\n0,0.5,1,x,3\n",
    );
    file(&meas, "forces.csv", "time_s,force_n\n0.1,1\n0.2,2\n");
    refused(
        &["rheology", "calibrate", &sc, "--measured", s(&meas)],
        &["surface_points.csv:3", "y_cm"],
    );
    // A single surface point for 4 parameters (issue 31): refused with
    // the minimum, before any search.
    let one = dir.join("one");
    std::fs::create_dir_all(&one).unwrap();
    file(
        &one,
        "surface_points.csv",
        "frame,time_s,x_cm,y_cm,z_cm\n0,0.5,1,2,3\n",
    );
    file(&one, "forces.csv", "time_s,force_n\n0.1,1\n0.2,2\n");
    refused(
        &["rheology", "calibrate", &sc, "--measured", s(&one)],
        &[
            "surface_points.csv",
            "1 surface point(s) for 4 parameters",
            "(4)",
        ],
    );
    refused(
        &[
            "rheology",
            "calibrate",
            &sc,
            "--measured",
            s(&meas),
            "--validate-depth-mm",
            "5",
        ],
        &["--validate-depth-mm", "--measured"],
    );
    let bad_params = file(
        &dir,
        "p.toml",
        "[all]\nk_gf_per_cm2 = -1.0\nc1_gfs_per_cm2 = 1.0\nc2_gfs_per_cm2 = 1.0\na = 0.5\n",
    );
    refused(
        &[
            "rheology",
            "simulate",
            &sc,
            "--params",
            &bad_params,
            "--out",
            s(&dir.join("o")),
        ],
        &["p.toml", "k_gf_per_cm2"],
    );
}

#[test]
fn an_objective_weight_for_which_s_can_overflow_is_refused_by_file_and_field() {
    // Issue 31: `shape_per_cm = 1e308` made a stable run's S = ∞:
    // simulate printed `"s": null` with exit 0, and calibrate counted
    // every stable candidate as unstable. Refused before any run.
    let dir = scratch("rheology-heavy-weight");
    let sc = file(
        &dir,
        "heavy.toml",
        &format!("{SMALL}\n[objective]\nshape_per_cm = 1e308\n"),
    );
    let meas = dir.join("meas");
    std::fs::create_dir_all(&meas).unwrap();
    let points: String = (0..8).map(|i| format!("0,0.5,{i}.5,4.5,3\n")).collect();
    file(
        &meas,
        "surface_points.csv",
        &format!("frame,time_s,x_cm,y_cm,z_cm\n{points}"),
    );
    file(&meas, "forces.csv", "time_s,force_n\n0.1,1\n0.2,2\n");
    let needles = [
        "heavy.toml",
        "`objective.shape_per_cm` = 1e308",
        "overflows",
    ];
    let out = dir.join("o");
    refused(
        &[
            "rheology",
            "simulate",
            &sc,
            "--measured",
            s(&meas),
            "--out",
            s(&out),
            "--json",
        ],
        &needles,
    );
    refused(
        &[
            "rheology",
            "calibrate",
            &sc,
            "--measured",
            s(&meas),
            "--evaluations",
            "8",
            "--out",
            s(&out),
        ],
        &needles,
    );
    // Nothing written, not even an empty output folder.
    assert!(!out.exists(), "a refused run made {}", out.display());
}
