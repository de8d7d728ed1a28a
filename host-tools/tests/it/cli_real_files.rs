//! Inputs as real files bring them: every CSV (and the JSON, TOML and OBJ
//! files beside them; console scripts in cli_console.rs) saved by Excel or a Windows editor — a
//! UTF-8 byte-order mark and CRLF line endings — reads exactly like the
//! plain file; and inputs too large to be meant are refused by name
//! before they cost minutes.
use crate::common;

use std::path::Path;

use common::{file, ok, refused, s, scratch, softjoint, stdout};

/// The same text with a byte-order mark and CRLF line endings.
fn excel(text: &str) -> String {
    format!(
        "\u{feff}{}",
        text.replace("\r\n", "\n").replace('\n', "\r\n")
    )
}

/// Writes `text` as `name` and its Excel twin as `excel-name`.
fn twins(dir: &Path, name: &str, text: &str) -> (String, String) {
    (
        file(dir, name, text),
        file(dir, &format!("excel-{name}"), &excel(text)),
    )
}

#[test]
fn a_bom_and_crlf_read_like_the_plain_file_in_every_input() {
    let dir = scratch("excel");
    // Wire-sensor sweep → calibration: the same file either way.
    let sweep = dir.join("sweep.csv");
    ok(&softjoint(&["sim", "--calibration-sweep", s(&sweep)]));
    let (plain, bom) = twins(
        &dir,
        "sweep2.csv",
        &std::fs::read_to_string(&sweep).unwrap(),
    );
    let (cal_a, cal_b) = (dir.join("a.toml"), dir.join("b.toml"));
    ok(&softjoint(&["calibrate", "wire", &plain, "-o", s(&cal_a)]));
    ok(&softjoint(&["calibrate", "wire", &bom, "-o", s(&cal_b)]));
    assert_eq!(
        std::fs::read_to_string(&cal_a).unwrap(),
        std::fs::read_to_string(&cal_b).unwrap()
    );
    // A scenario and the calibration it names, both from Windows.
    let cal_excel = file(
        &dir,
        "cal-excel.toml",
        &excel(&std::fs::read_to_string(&cal_a).unwrap()),
    );
    let scen = file(
        &dir,
        "scenario.toml",
        &excel(&format!(
            "duration_s = 1.0\n[estimator]\nmethod = \"switching\"\ncalibration = \"{}\"\n",
            Path::new(&cal_excel).file_name().unwrap().to_string_lossy()
        )),
    );
    ok(&softjoint(&["sim", &scen, "--json"]));

    // Viscoelastic simulate and fit.
    let mut ramp = String::from("time_s,displacement\n");
    for k in 0..=200 {
        let t = f64::from(k) * 1e-3;
        ramp.push_str(&format!("{t},{}\n", (t * 20.0).min(1.0) * 1e-3));
    }
    let (plain, bom) = twins(&dir, "ramp.csv", &ramp);
    let model = ["--k1", "800", "--k2", "1200", "--b", "5"];
    let a = softjoint(&[&["viscoelastic", "simulate", &plain][..], &model].concat());
    let b = softjoint(&[&["viscoelastic", "simulate", &bom][..], &model].concat());
    ok(&a);
    assert_eq!(stdout(&a), stdout(&b));
    let (plain, bom) = twins(&dir, "trial.csv", &stdout(&a));
    let a = softjoint(&["viscoelastic", "fit", &plain, "--json"]);
    let b = softjoint(&["viscoelastic", "fit", &bom, "--json"]);
    ok(&a);
    assert_eq!(stdout(&a), stdout(&b));

    // (Probe scripts and OBJ meshes of `viscoelastic object` are read by
    // the same reader as `simulate` and `fit`; the mesh bound below reads
    // an OBJ from Windows.)

    // A tracked push video and a parameter file.
    let coarse = ["--ref-element-px", "30", "--cell-px", "8"];
    let first = dir.join("p1");
    ok(&softjoint(
        &[&["push", "simulate", "--out", s(&first)][..], &coarse].concat(),
    ));
    let (plain, bom) = twins(
        &dir,
        "video.csv",
        &std::fs::read_to_string(first.join("video.csv")).unwrap(),
    );
    let params = file(
        &dir,
        "params.json",
        &excel(
            r#"{"k_length": 3034.48, "k_damping": 0.000237, "k_area": 103.568,
 "k_angle": 66.774, "max_force": 1218.81, "yield_strain": 0.000434973,
 "creep": 0.00890343, "max_alpha": 0.45204}"#,
        ),
    );
    let (pa, pb) = (dir.join("pa"), dir.join("pb"));
    ok(&softjoint(&[
        "push",
        "simulate",
        "--video",
        &plain,
        "--cell-px",
        "8",
        "--out",
        s(&pa),
    ]));
    ok(&softjoint(&[
        "push",
        "simulate",
        "--video",
        &bom,
        "--params",
        &params,
        "--cell-px",
        "8",
        "--out",
        s(&pb),
    ]));
    assert_eq!(
        std::fs::read(pa.join("frames.csv")).unwrap(),
        std::fs::read(pb.join("frames.csv")).unwrap()
    );
}

/// Sizes nobody means are refused by name before any work: element sizes
/// that take minutes, contour points of 1e300 px, meshes whose DGFM takes
/// hours.
#[test]
fn inputs_too_large_to_be_meant_are_refused_by_name() {
    let dir = scratch("bounds");
    refused(
        &[
            "push",
            "simulate",
            "--ref-element-px",
            "1.5",
            "--out",
            s(&dir.join("o")),
        ],
        &["--ref-element-px", "at least 2"],
    );
    let video = file(
        &dir,
        "far.csv",
        "frame,force_n,x_px,y_px\n0,0,10,10\n0,0,1e300,10\n0,0,10,20\n",
    );
    refused(
        &[
            "push",
            "simulate",
            "--video",
            &video,
            "--out",
            s(&dir.join("o")),
        ],
        &[&format!("{video}:3"), "x_px", "1e300"],
    );
    // A UV sphere of 60 × 50 + 2 vertices (3,002), from Windows.
    let (rings, segs) = (50usize, 60usize);
    let mut obj = String::from("v 0 0 0.01\n");
    for r in 1..=rings {
        let th = std::f64::consts::PI * r as f64 / (rings + 1) as f64;
        for k in 0..segs {
            let ph = 2.0 * std::f64::consts::PI * k as f64 / segs as f64;
            obj.push_str(&format!(
                "v {} {} {}\n",
                0.01 * th.sin() * ph.cos(),
                0.01 * th.sin() * ph.sin(),
                0.01 * th.cos()
            ));
        }
    }
    obj.push_str("v 0 0 -0.01\n");
    let ring = |r: usize, k: usize| 2 + (r - 1) * segs + k % segs; // 1-based
    for k in 0..segs {
        obj.push_str(&format!("f 1 {} {}\n", ring(1, k), ring(1, k + 1)));
        for r in 1..rings {
            let (a, b, c, d) = (
                ring(r, k),
                ring(r + 1, k),
                ring(r + 1, k + 1),
                ring(r, k + 1),
            );
            obj.push_str(&format!("f {a} {b} {c}\nf {a} {c} {d}\n"));
        }
        let last = 2 + rings * segs;
        obj.push_str(&format!(
            "f {} {last} {}\n",
            ring(rings, k),
            ring(rings, k + 1)
        ));
    }
    let mesh = file(&dir, "sphere.obj", &excel(&obj));
    let started = std::time::Instant::now();
    refused(
        &[
            "viscoelastic",
            "object",
            "--mesh",
            &mesh,
            "--out-dir",
            s(&dir.join("v")),
        ],
        &[&mesh, "3002 vertices", "more than 3000"],
    );
    assert!(started.elapsed() < std::time::Duration::from_secs(20));
}
