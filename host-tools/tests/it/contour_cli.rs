//! `softjoint contour fit|synth`: files, JSON, the paper's cases through
//! the command line, and clean refusals of bad input.
use crate::common;
use common::{file, ok, refused, s, scratch, softjoint, stdout};
use std::f64::consts::{PI, TAU};

fn json(o: &std::process::Output) -> serde_json::Value {
    serde_json::from_str(&stdout(o)).expect("JSON on stdout")
}

#[test]
fn synth_rbc_then_fit_the_surface_as_the_paper() {
    let dir = scratch("contour-rbc");
    let out = dir.join("rbc");
    let o = softjoint(&[
        "contour",
        "synth",
        "--case",
        "rbc",
        "--n",
        "10",
        "--out",
        s(&out),
        "--json",
    ]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["frames"], 10);
    let data = std::fs::read_to_string(out.join("data.csv")).unwrap();
    assert_eq!(data.lines().count(), 1 + 100);
    assert!(std::fs::read_to_string(out.join("synth.svg"))
        .unwrap()
        .starts_with("<svg"));
    let fit = dir.join("fit");
    let o = softjoint(&[
        "contour",
        "fit",
        s(&out.join("data.csv")),
        "--model",
        "surface",
        "--time-knots",
        "10",
        "--knots",
        "10",
        "--lambda",
        "1e-3",
        "--out",
        s(&fit),
        "--json",
    ]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["model"], "surface");
    assert_eq!(j["surface_lambda"]["lambda"], 1e-3);
    assert_eq!(j["surface_lambda"]["by_gcv"], false);
    assert_eq!(j["per_frame"].as_array().unwrap().len(), 10);
    // Areas of the fitted contours are those of Eq. 38's egg shapes
    // (between about π·0.9² and π·1.6²).
    for f in j["per_frame"].as_array().unwrap() {
        let a = f["area"].as_f64().unwrap();
        assert!(a > 2.0 && a < 8.0, "area {a}");
    }
    for name in [
        "fit.csv",
        "frames.csv",
        "fit.json",
        "fit.svg",
        "functionals.svg",
    ] {
        let text = std::fs::read_to_string(fit.join(name)).unwrap();
        assert!(!text.contains("NaN") && !text.contains("inf"), "{name}");
    }
    assert_eq!(
        std::fs::read_to_string(fit.join("fit.csv"))
            .unwrap()
            .lines()
            .count(),
        1 + 10 * 200
    );
}

#[test]
fn synth_movie_then_fit_with_gcv_gives_the_model_at_every_frame() {
    let dir = scratch("contour-movie");
    let out = dir.join("mv");
    ok(&softjoint(&[
        "contour",
        "synth",
        "--case",
        "movie",
        "--out",
        s(&out),
    ]));
    let o = softjoint(&[
        "contour",
        "fit",
        s(&out.join("data.csv")),
        "--time-knots",
        "10",
        "--knots",
        "10",
        "--samples",
        "60",
        "--out",
        s(&dir.join("fit")),
        "--json",
    ]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["model"], "surface");
    assert_eq!(j["surface_lambda"]["by_gcv"], true);
    let frames = j["per_frame"].as_array().unwrap();
    assert_eq!(frames.len(), 101, "frames 0…100, 11 of them with data");
    assert_eq!(frames.iter().filter(|f| f["points"] == 10).count(), 11);
    assert!(dir.join("fit/gcv.svg").exists());
    // The centroid moves right by ≈ 1.2 px per frame (the movie's drift).
    let dx = frames[100]["centre_x"].as_f64().unwrap() - frames[0]["centre_x"].as_f64().unwrap();
    assert!((dx - 120.0).abs() < 5.0, "drift {dx}");
}

#[test]
fn single_frames_fit_as_signature_or_closed_curve() {
    let dir = scratch("contour-single");
    // A circle of radius 2 as a signature: area 4π.
    let mut text = String::from("angle_rad,radius\n");
    for k in 0..12 {
        text += &format!("{},2\n", TAU * k as f64 / 12.0);
    }
    let p = file(&dir, "circle.csv", &text);
    let o = softjoint(&[
        "contour",
        "fit",
        &p,
        "--lambda",
        "1e-3",
        "--out",
        s(&dir.join("a")),
        "--json",
    ]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["model"], "signature");
    let area = j["per_frame"][0]["area"].as_f64().unwrap();
    assert!((area - 4.0 * PI).abs() < 1e-9, "area {area}");
    // A rounded square as x, y points: closed curve by default; its area
    // is close to the polygon's.
    let mut text = String::from("# a rounded square\nx,y\n");
    let mut poly = Vec::new();
    for k in 0..40 {
        let a = TAU * k as f64 / 40.0;
        let (c, s_) = (a.cos(), a.sin());
        let r = 1.0 / (c.abs().powi(4) + s_.abs().powi(4)).powf(0.25);
        poly.push((3.0 * r * c, 3.0 * r * s_));
        text += &format!("{},{}\n", 3.0 * r * c, 3.0 * r * s_);
    }
    let poly_area = 0.5
        * (0..40)
            .map(|i| {
                let (a, b) = (poly[i], poly[(i + 1) % 40]);
                a.0 * b.1 - b.0 * a.1
            })
            .sum::<f64>();
    let p = file(&dir, "square.csv", &text);
    let o = softjoint(&["contour", "fit", &p, "--out", s(&dir.join("b")), "--json"]);
    ok(&o);
    let j = json(&o);
    assert_eq!(j["model"], "curve");
    let area = j["per_frame"][0]["area"].as_f64().unwrap();
    assert!(
        (area / poly_area - 1.0).abs() < 0.02,
        "{area} vs polygon {poly_area}"
    );
    // The text report names the model and the files.
    let o = softjoint(&[
        "contour",
        "fit",
        &p,
        "--model",
        "signature",
        "--out",
        s(&dir.join("c")),
    ]);
    ok(&o);
    assert!(stdout(&o).contains("signature model") && stdout(&o).contains("fit.svg"));
}

#[test]
fn bad_input_is_refused_with_a_named_error() {
    let dir = scratch("contour-bad");
    let out = dir.join("o");
    let o = s(&out);
    let few = file(
        &dir,
        "few.csv",
        "frame,angle_rad,radius\n0,0,1\n0,1,1\n0,2,1\n1,0,1\n1,1,1\n",
    );
    refused(
        &["contour", "fit", &few, "--out", o],
        &["few.csv", "frame 1", "too few points"],
    );
    let dup = file(
        &dir,
        "dup.csv",
        "angle_rad,radius\n0,1\n1.5,1\n3,1\n1.5,1.2\n",
    );
    refused(
        &["contour", "fit", &dup, "--out", o],
        &["dup.csv:5", "duplicate angle", "line 3"],
    );
    let nan = file(&dir, "nan.csv", "x,y\n0,0\n1,NaN\n1,1\n");
    refused(
        &["contour", "fit", &nan, "--out", o],
        &["nan.csv:3", "`y`", "not finite"],
    );
    let cols = file(&dir, "cols.csv", "u,v\n0,0\n1,0\n1,1\n");
    refused(
        &["contour", "fit", &cols, "--out", o],
        &["cols.csv:1", "angle_rad,radius", "x,y"],
    );
    let one = file(&dir, "one.csv", "angle_rad,radius\n0,1\n2,1\n4,1\n");
    refused(
        &["contour", "fit", &one, "--model", "surface", "--out", o],
        &["two frames"],
    );
    refused(
        &["contour", "fit", &one, "--lambda", "-1", "--out", o],
        &["--lambda", "> 0"],
    );
    refused(
        &["contour", "fit", &one, "--lambda", "abc", "--out", o],
        &["--lambda `abc`"],
    );
    refused(
        &["contour", "fit", &one, "--knots", "2", "--out", o],
        &["intervals"],
    );
    refused(
        &["contour", "fit", s(&dir.join("missing.csv")), "--out", o],
        &["reading", "missing.csv"],
    );
    let u = file(
        &dir,
        "u.csv",
        "x,y\n0,0\n3,0\n3,3\n2,3\n2,0.5\n1,0.5\n1,3\n0,3\n",
    );
    refused(
        &["contour", "fit", &u, "--model", "signature", "--out", o],
        &["not star-shaped", "closed parametric curve"],
    );
    refused(
        &["contour", "synth", "--case", "rbc", "--n", "1", "--out", o],
        &["--n"],
    );
    refused(
        &[
            "contour", "synth", "--case", "movie", "--sigma", "-2", "--out", o,
        ],
        &["--sigma"],
    );
    // A usage error (clap's exit 2) lists the solvers there are.
    let e = softjoint(&["contour", "fit", &one, "--solver", "lu", "--out", o]);
    assert!(!e.status.success() && common::stderr(&e).contains("reduced, kkt"));
    // Too large for the dense KKT solver: a named error, not an allocation.
    let mut big = String::from("frame,angle_rad,radius\n");
    for f in 0..60 {
        for k in 0..40 {
            big += &format!("{f},{},1\n", TAU * k as f64 / 40.0);
        }
    }
    let big = file(&dir, "big.csv", &big);
    refused(
        &[
            "contour", "fit", &big, "--solver", "kkt", "--lambda", "1e-3", "--out", o,
        ],
        &["KKT", "reduced solver"],
    );
}
