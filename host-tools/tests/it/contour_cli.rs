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
        "--signed-radii",
        // σ = 0.3 on radii down to 0.46 at N = 10: some fitted contours
        // pass through their centre, and say so.
        "--allow-unverified",
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
        assert!(f["checks"]["status"].is_string());
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

/// 23 noisy points of an ellipse (a = 81.985, b = 53.842) at random
/// angles, from a probe of issue 29: before the guard GCV chose
/// λ = 2.5e-12 and `contour fit` reported area 74,174 (5.3× πab) and
/// perimeter 51,527 (120×), exit 0.
const SPARSE_ELLIPSE: &str = "x,y\n1.134,-152.733\n-5.550,-135.156\n-51.590,-108.155\n-53.174,-107.246\n-108.542,-110.551\n-112.555,-106.467\n-122.773,-114.126\n-123.709,-113.389\n-137.854,-123.608\n-151.844,-135.715\n-161.920,-154.940\n-161.284,-157.442\n-160.035,-164.440\n-158.318,-173.043\n-156.349,-182.331\n-152.141,-182.230\n-140.255,-199.337\n-100.136,-213.372\n-36.463,-206.963\n-30.871,-201.127\n-11.067,-185.987\n-4.193,-178.545\n3.119,-162.926\n";

/// Ramanujan's second approximation of an ellipse's perimeter.
fn ellipse_perimeter(a: f64, b: f64) -> f64 {
    let h = ((a - b) / (a + b)).powi(2);
    PI * (a + b) * (1.0 + 3.0 * h / (10.0 + (4.0 - 3.0 * h).sqrt()))
}

#[test]
fn a_sparse_noisy_ellipse_is_fitted_near_its_closed_form_and_verified() {
    let dir = scratch("contour-sparse");
    let p = file(&dir, "e.csv", SPARSE_ELLIPSE);
    let o = softjoint(&["contour", "fit", &p, "--out", s(&dir.join("o")), "--json"]);
    ok(&o);
    let j = json(&o);
    let f = &j["per_frame"][0];
    let (a, b) = (81.98488673794117, 53.84164107337456);
    let area = f["area"].as_f64().unwrap();
    let perimeter = f["perimeter"].as_f64().unwrap();
    assert!((area / (PI * a * b) - 1.0).abs() < 0.05, "area {area}");
    assert!(
        (perimeter / ellipse_perimeter(a, b) - 1.0).abs() < 0.05,
        "perimeter {perimeter}"
    );
    assert_eq!(j["status"], "verified");
    assert_eq!(f["checks"]["status"], "verified");
}

#[test]
fn a_frame_that_fails_its_checks_is_unverified_everywhere_and_exits_non_zero() {
    let dir = scratch("contour-unverified");
    // A figure eight: the fitted closed curve crosses itself.
    let mut text = String::from("x,y\n");
    for k in 0..48 {
        let t = TAU * k as f64 / 48.0;
        text += &format!("{},{}\n", 10.0 * t.cos(), 10.0 * t.sin() * t.cos());
    }
    let p = file(&dir, "eight.csv", &text);
    let out = dir.join("o");
    let o = softjoint(&["contour", "fit", &p, "--lambda", "1e-6", "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    let (text_out, err) = (stdout(&o), common::stderr(&o));
    assert!(
        text_out.contains("UNVERIFIED frame 0") && text_out.contains("crosses itself"),
        "{text_out}"
    );
    assert!(
        err.contains("UNVERIFIED") && err.contains("--allow-unverified"),
        "{err}"
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fit.json")).unwrap()).unwrap();
    assert_eq!(j["status"], "unverified");
    assert_eq!(j["unverified_frames"][0], 0.0);
    let frames = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let row = frames.lines().find(|l| l.starts_with("0,")).unwrap();
    assert!(
        row.contains("unverified") && row.contains("self_intersection"),
        "{row}"
    );
    assert!(std::fs::read_to_string(out.join("fit.svg"))
        .unwrap()
        .contains("UNVERIFIED"));
    // Asked for, the same run exits 0 and still says unverified.
    let o = softjoint(&[
        "contour",
        "fit",
        &p,
        "--lambda",
        "1e-6",
        "--allow-unverified",
        "--json",
        "--out",
        s(&out),
    ]);
    ok(&o);
    assert_eq!(json(&o)["status"], "unverified");
}

/// r(θ) of an ellipse a = 3, b = 2 about its centre at 128 angles.
fn ellipse_signature_csv() -> String {
    let (a, b) = (3.0_f64, 2.0_f64);
    let mut text = String::from("angle_rad,radius\n");
    for k in 0..128 {
        let t = TAU * k as f64 / 128.0;
        let r = a * b / ((b * t.cos()).powi(2) + (a * t.sin()).powi(2)).sqrt();
        text += &format!("{t:.12},{r:.12}\n");
    }
    text
}

#[test]
fn smoothness_does_not_depend_on_the_knots_and_states_its_units() {
    let dir = scratch("contour-smooth");
    let p = file(&dir, "e.csv", &ellipse_signature_csv());
    // Reference: Eq. 41 over the angle, ∫(d²r/dθ²)² dθ, of the closed form
    // r(θ) = ab/√(b²cos²θ + a²sin²θ), by central differences and Simpson.
    let (a, b) = (3.0_f64, 2.0_f64);
    let r = |t: f64| a * b / ((b * t.cos()).powi(2) + (a * t.sin()).powi(2)).sqrt();
    let (n, h) = (4000, 1e-4);
    let step = TAU / n as f64;
    let c_ref: f64 = (0..=n)
        .map(|k| {
            let t = step * k as f64;
            let w = if k == 0 || k == n {
                1.0
            } else if k % 2 == 1 {
                4.0
            } else {
                2.0
            };
            w * ((r(t + h) - 2.0 * r(t) + r(t - h)) / (h * h)).powi(2)
        })
        .sum::<f64>()
        * step
        / 3.0;
    for knots in ["16", "64"] {
        let o = softjoint(&[
            "contour",
            "fit",
            &p,
            "--knots",
            knots,
            "--lambda",
            "1e-9",
            "--json",
            "--out",
            s(&dir.join(knots)),
        ]);
        ok(&o);
        let j = json(&o);
        let c = j["per_frame"][0]["smoothness"].as_f64().unwrap();
        assert!(
            (c / c_ref - 1.0).abs() < 0.03,
            "--knots {knots}: C {c} vs {c_ref}"
        );
        assert!(j["units"]["smoothness"].as_str().unwrap().contains("rad^3"));
        let frames = std::fs::read_to_string(dir.join(knots).join("frames.csv")).unwrap();
        assert!(frames.contains("smoothness_len2_per_rad3"));
    }
}

/// Runs `args`, failing the test if the run takes more than 60 s.
fn within_a_minute(args: &[&str]) -> std::process::Output {
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_softjoint"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{args:?} still running after 60 s (killed)");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn an_absurd_lambda_is_refused_at_once_and_negative_radii_by_name() {
    let dir = scratch("contour-absurd");
    let p = file(&dir, "e.csv", &ellipse_signature_csv());
    let o = within_a_minute(&[
        "contour",
        "fit",
        &p,
        "--lambda",
        "1e308",
        "--out",
        s(&dir.join("o")),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = common::stderr(&o);
    assert!(err.contains("--lambda") && err.contains("1e6"), "{err}");
    assert!(!dir.join("o").exists());
    let neg = file(
        &dir,
        "neg.csv",
        "frame,angle_rad,radius\n3,0,1\n3,2,-0.25\n3,4,1\n",
    );
    refused(
        &["contour", "fit", &neg, "--out", s(&dir.join("n"))],
        &["neg.csv", "frame 3, point 1", "negative", "--signed-radii"],
    );
    assert!(!dir.join("n").exists());
    let o = softjoint(&[
        "contour",
        "fit",
        &neg,
        "--signed-radii",
        "--lambda",
        "1e-3",
        "--allow-unverified",
        "--out",
        s(&dir.join("n")),
    ]);
    ok(&o);
}

#[test]
fn degenerate_input_is_refused_before_any_file_is_written() {
    let dir = scratch("contour-degenerate");
    let p = file(&dir, "line.csv", "x,y\n0,0\n1,0\n2,0\n3,0\n");
    let out = dir.join("o");
    refused(
        &["contour", "fit", &p, "--out", s(&out)],
        &["line.csv", "frame 0", "encloses no area"],
    );
    assert!(!out.exists(), "files were left in {}", out.display());
}
