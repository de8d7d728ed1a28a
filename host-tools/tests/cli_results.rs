//! Results that used to leave with exit 0 although they were garbage
//! (issue 13, "silent garbage"): each is now refused, or reported for what
//! it is, and nothing non-finite reaches a file.
mod common;

use common::{file, ok, refused, s, scratch, softjoint, stdout};

/// Small and fast settings for the pushing commands.
const SMALL_PUSH: [&str; 8] = [
    "--ref-element-px",
    "30",
    "--nx",
    "3",
    "--ny",
    "2",
    "--cell-px",
    "8",
];

/// The seed's Fig. 14 sponge parameters, as a parameter file.
const SPONGE_JSON: &str = r#"{"k_length": 3034.48, "k_damping": 0.000237, "k_area": 103.568,
    "k_angle": 66.774, "max_force": 1218.81, "yield_strain": 0.000434973,
    "creep": 0.00890343, "max_alpha": 0.45204}"#;

/// Two identical models gave 0/0 frames won and `"winner": "a"`: the
/// first label won a tie.
#[test]
fn push_classify_reports_a_tie_as_a_tie() {
    let dir = scratch("tie");
    let p = file(&dir, "p.json", SPONGE_JSON);
    let out = dir.join("out");
    let (a, b) = (format!("a={p}"), format!("b={p}"));
    let mut args = vec![
        "push",
        "classify",
        "--model",
        &a,
        "--model",
        &b,
        "--out",
        s(&out),
        "--json",
    ];
    args.extend(SMALL_PUSH);
    let o = softjoint(&args);
    ok(&o);
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["winner"], serde_json::Value::Null, "{v}");
    assert_eq!(v["tie"], true);
    assert_eq!(v["leaders"], serde_json::json!(["a", "b"]));
    args.retain(|x| *x != "--json");
    let o = softjoint(&args);
    ok(&o);
    assert!(
        stdout(&o).contains("global vote: tie between a and b"),
        "{}",
        stdout(&o)
    );
}

/// Every parameter at 1e308 (each within its range) made the model blow up
/// from frame 9: `snapshots.svg` held NaN coordinates, the instability was
/// only on stdout, and the exit was 0.
#[test]
fn push_simulate_refuses_an_unstable_model_unless_allowed() {
    let dir = scratch("unstable");
    let p = file(
        &dir,
        "huge.json",
        r#"{"k_length": 1e308, "k_damping": 1e308, "k_area": 1e308, "k_angle": 1e308,
            "max_force": 1e308, "yield_strain": 1e308, "creep": 1, "max_alpha": 0.99}"#,
    );
    let out = dir.join("out");
    let mut args = vec!["push", "simulate", "--params", &p, "--out", s(&out)];
    args.extend(SMALL_PUSH);
    refused(
        &args,
        &["unstable at frame", "non-finite", "--allow-unstable"],
    );
    assert!(!out.exists(), "files were written for a refused run");
    args.push("--allow-unstable");
    let o = softjoint(&args);
    ok(&o);
    assert!(
        common::stderr(&o).contains("warning: the mass-spring model"),
        "{}",
        common::stderr(&o)
    );
    for f in [
        "snapshots.svg",
        "frames.csv",
        "f_per_frame.svg",
        "video.csv",
    ] {
        let text = std::fs::read_to_string(out.join(f)).unwrap();
        let low = text.to_lowercase();
        assert!(!low.contains("nan") && !low.contains("inf"), "{f}");
        // No coordinates of an exploded mesh either (the SVG writes
        // coordinates with one decimal, never in exponent form).
        if f.ends_with(".svg") {
            assert!(!text.contains("e+") && !text.contains("e2"), "{f}");
        }
    }
}
