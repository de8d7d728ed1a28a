//! Messages a user can act on without reading the source (issue 13,
//! "riddles"): files named with their lines, flags instead of internal
//! names, short excerpts instead of huge numbers and megabyte lines, and
//! flags that would be silently ignored refused as conflicts.
use crate::common;

use common::{file, ok, refused, s, scratch, softjoint, stderr, stdout};

/// `text` as Excel saves it: a UTF-8 byte-order mark and CRLF line ends.
fn excel(text: &str) -> String {
    format!("\u{feff}{}", text.replace('\n', "\r\n"))
}

/// A byte-order mark in a CSV header was kept as part of the first column's
/// name (`header must have columns d1_mm,… got \u{feff}d1_mm,…`): every CSV
/// reader takes Excel's files.
#[test]
fn every_csv_reader_accepts_a_byte_order_mark_and_crlf() {
    let dir = scratch("bom");
    // calibrate wire
    let mut sweep = String::from("d_mm,theta_deg\n");
    for i in 0..30 {
        let d = f64::from(i) * 0.2 - 3.0;
        sweep.push_str(&format!("{d},{}\n", 0.349 * d * d - 5.525 * d + 0.753));
    }
    let p = file(&dir, "sweep.csv", &excel(&sweep));
    let cal = dir.join("cal.toml");
    ok(&softjoint(&["calibrate", "wire", &p, "-o", s(&cal)]));
    // viscoelastic simulate, then fit its output
    let mut ramp = String::from("time_s,displacement\n");
    for k in 0..200 {
        let t = f64::from(k) * 0.005;
        ramp.push_str(&format!("{t},{}\n", 1e-3 * (t / 0.1).min(1.0)));
    }
    let ramp = file(&dir, "ramp.csv", &excel(&ramp));
    let o = softjoint(&[
        "viscoelastic",
        "simulate",
        &ramp,
        "--k1",
        "800",
        "--k2",
        "400",
        "--b",
        "60",
    ]);
    ok(&o);
    let trial = file(&dir, "trial.csv", &excel(&stdout(&o)));
    ok(&softjoint(&["viscoelastic", "fit", &trial]));
    // push --video
    let out = dir.join("gen");
    ok(&softjoint(&[
        "push",
        "simulate",
        "--ref-element-px",
        "30",
        "--nx",
        "3",
        "--ny",
        "2",
        "--cell-px",
        "8",
        "--out",
        s(&out),
    ]));
    let video = std::fs::read_to_string(out.join("video.csv")).unwrap();
    let video = file(&dir, "video.csv", &excel(&video));
    ok(&softjoint(&[
        "push",
        "simulate",
        "--video",
        &video,
        "--nx",
        "3",
        "--ny",
        "2",
        "--cell-px",
        "8",
        "--out",
        s(&dir.join("again")),
    ]));
}

/// A `duration_s` of 1e308 was printed with all its 309 digits; a TOML
/// line of 3 MB was echoed (twice) into 6 MB of stderr.
#[test]
fn huge_numbers_and_long_lines_are_quoted_short() {
    let dir = scratch("huge");
    let p = file(&dir, "d.toml", "duration_s = 1e308\n");
    let err = refused(&["sim", &p], &[&p, "duration_s", "1e308"]);
    assert!(err.len() < 300, "{err}");
    let p = file(
        &dir,
        "long.toml",
        &format!("name = \"{}\n", "x".repeat(3_000_000)),
    );
    let err = refused(&["sim", &p], &[&format!("{p}:1:")]);
    assert!(err.len() < 1000, "{} bytes of stderr", err.len());
    let p = file(
        &dir,
        "direction.toml",
        "duration_s = 2.0\n[[disturbances]]\nkind = \"weight\"\nmass_g = 10.0\n\
         direction = [1e-320, 0.0]\nfrom_s = 0.5\nto_s = 1.0\n",
    );
    let err = refused(&["sim", &p], &["1e-320"]);
    assert!(err.len() < 400, "{err}");
    // A push parameter out of range says its range, in short form.
    let params = file(
        &dir,
        "p.json",
        r#"{"k_length": 1, "k_damping": 1, "k_area": 1, "k_angle": 1, "max_force": 1,
            "yield_strain": 1, "creep": 1e308, "max_alpha": 0.5}"#,
    );
    let err = refused(
        &[
            "push",
            "simulate",
            "--params",
            &params,
            "--out",
            s(&dir.join("o")),
        ],
        &[&params, "creep", "1e308", "0..=1"],
    );
    assert!(err.len() < 300, "{err}");
}

/// `calibration has 1 angle(s), the scenario's joint has 2` named neither
/// file.
#[test]
fn a_calibration_for_the_wrong_joint_names_both_files() {
    let dir = scratch("cal_joint");
    let cal = file(
        &dir,
        "cal2d.toml",
        "[alpha]\nmethod = \"single\"\nsensor = 1\na = 0.349\nb = -5.525\nc = 0.753\n",
    );
    let sc = file(
        &dir,
        "s.toml",
        "duration_s = 1.0\n[estimator]\nmethod = \"single\"\ncalibration = \"cal2d.toml\"\n",
    );
    refused(
        &["sim", &sc],
        &[&sc, &cal, "1 angle(s)", "2D calibration", "joint = \"3d\""],
    );
}

/// An OBJ whose coordinates overflow areas was refused as `triangle 2 has
/// (near) zero area`, and a push video with contour points of 1e300 px as
/// `vertex 2 has a non-finite coordinate`, neither naming file or line.
#[test]
fn mesh_and_video_errors_name_the_file_and_line() {
    let dir = scratch("mesh_line");
    let obj = file(
        &dir,
        "big.obj",
        "# a tetrahedron\nv 0 0 0\nv 1e300 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    );
    let out = dir.join("out");
    refused(
        &[
            "viscoelastic",
            "object",
            "--mesh",
            &obj,
            "--out-dir",
            s(&out),
        ],
        &[&format!("{obj}:3:"), "1e300", "metres"],
    );
    let video = file(
        &dir,
        "video.csv",
        "frame,force_n,x_px,y_px\n0,0,10,10\n0,0,1e300,10\n0,0,10,20\n",
    );
    refused(
        &["push", "simulate", "--video", &video, "--out", s(&out)],
        &[&format!("{video}:3"), "x_px", "1e300"],
    );
    assert!(!out.exists());
}

/// The reference block's element size was called `element_size_px`.
#[test]
fn flags_are_named_as_the_user_typed_them() {
    let dir = scratch("flags");
    let out = dir.join("out");
    let err = refused(
        &[
            "push",
            "simulate",
            "--ref-element-px",
            "-1",
            "--out",
            s(&out),
        ],
        &["--ref-element-px -1"],
    );
    assert!(!err.contains("element_size_px"), "{err}");
    let err = refused(
        &[
            "push",
            "simulate",
            "--ref-element-px",
            "30",
            "--cell-px",
            "2000",
            "--out",
            s(&out),
        ],
        &["--cell-px 2000", "0.001..=1000"],
    );
    assert!(!err.contains("`cell_px`"), "{err}");
    // A negative number is a value, not a flag.
    let ramp = file(&dir, "r.csv", "time_s,displacement\n0,0\n0.01,0.001\n");
    refused(
        &[
            "viscoelastic",
            "simulate",
            &ramp,
            "--k1",
            "-1",
            "--k2",
            "1",
            "--b",
            "1",
        ],
        &["--k1 must be finite and > 0", "got -1"],
    );
}

/// `sim --calibration-sweep a.csv --csv b.csv --plot c.svg --json` ran the
/// sweep and silently ignored the other three.
#[test]
fn flags_that_would_be_ignored_are_refused_as_conflicts() {
    let dir = scratch("conflicts");
    let (a, b, c) = (dir.join("a.csv"), dir.join("b.csv"), dir.join("c.svg"));
    for extra in [
        &["--csv", s(&b)][..],
        &["--plot", s(&c)][..],
        &["--json"][..],
    ] {
        let mut args = vec!["sim", "--calibration-sweep", s(&a)];
        args.extend(extra);
        let o = softjoint(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("cannot be used with"), "{}", stderr(&o));
    }
    assert!(!a.exists() && !b.exists() && !c.exists());
    let o = softjoint(&["sim", "--print-default", "--json"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = softjoint(&["push", "simulate", "--video", s(&a), "--noise-seed", "3"]);
    assert!(stderr(&o).contains("cannot be used with"), "{}", stderr(&o));
    let o = softjoint(&["hil", "--baud", "9600"]);
    assert!(stderr(&o).contains("--port"), "{}", stderr(&o));
}

/// Parameter JSON files accepted unknown keys (a typo was ignored and the
/// default used) and duplicate keys (the last one won).
#[test]
fn parameter_files_refuse_unknown_and_duplicate_keys() {
    let dir = scratch("json_keys");
    let base = r#""k_length": 3034.48, "k_damping": 0.000237, "k_area": 103.568,
        "k_angle": 66.774, "max_force": 1218.81, "yield_strain": 0.000434973,
        "creep": 0.00890343, "max_alpha": 0.45204"#;
    let out = dir.join("out");
    let typo = file(&dir, "typo.json", &format!("{{{base}, \"k_lenght\": 5}}"));
    refused(
        &["push", "simulate", "--params", &typo, "--out", s(&out)],
        &[&typo, "unknown field `k_lenght`"],
    );
    let twice = file(
        &dir,
        "twice.json",
        &format!("{{{base},\n \"k_length\": 5}}"),
    );
    refused(
        &["push", "simulate", "--params", &twice, "--out", s(&out)],
        &[&format!("{twice}:4:"), "duplicate key `k_length`"],
    );
    let nested = file(
        &dir,
        "cal.json",
        &format!("{{\"best_params\": {{{base}}}, \"best_score\": 0.5, \"evaluations\": 1, \"history\": [], \"extra\": 1}}"),
    );
    refused(
        &["push", "simulate", "--params", &nested, "--out", s(&out)],
        &[&nested, "unknown field `extra`"],
    );
    assert!(!out.exists());
    // TOML inputs too (the parser refuses duplicates; the structs unknowns).
    let sc = file(&dir, "s.toml", "duration_s = 1.0\nduration_s = 2.0\n");
    refused(&["sim", &sc], &[&format!("{sc}:2:"), "duplicate key"]);
    let sc = file(&dir, "u.toml", "duraton_s = 1.0\n");
    refused(&["sim", &sc], &[&format!("{sc}:1:"), "duraton_s"]);
}
