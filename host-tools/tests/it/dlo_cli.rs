//! `softjoint dlo` end to end through the built binary: a short rope
//! scenario with CSV, picture and JSON; the straight twisted wire against
//! its closed form; named errors for bad scenario and problem files.
use crate::common;

use common::{file, ok, refused, s, scratch, softjoint, stdout};

const SHORT_ROPE: &str = r#"
name = "short drop"
start_m = [0.0, 0.0, 0.3]
direction = [1.0, 0.0, 0.0]
pins = [0]
desk_height_m = 0.0
duration_s = 0.3
frame_interval_s = 0.1

[rope]
nodes = 20

[[hands]]
name = "right"
keys = [
  { t_s = 0.0, at_m = [5.0, 0.0, 0.3], action = "grasp", node = 19 },
  { t_s = 0.3, at_m = [4.8, 0.2, 0.5] },
]

[[checks]]
label = "end"
at_s = 0.3
"#;

#[test]
fn rope_writes_csv_picture_and_json() {
    let dir = scratch("dlo-rope");
    let scenario = file(&dir, "rope.toml", SHORT_ROPE);
    let out = dir.join("out");
    let o = softjoint(&["dlo", "rope", &scenario, "--out", s(&out), "--json"]);
    ok(&o);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["nodes"], 20);
    assert_eq!(json["steps"], 300);
    assert_eq!(json["checks"][0]["determinant"], 1);
    assert_eq!(json["checks"][0]["crossings"], 0);
    assert!(json["hands"][0]["max_coupling_force_n"].as_f64().unwrap() > 0.0);
    // Four frames (0, 0.1, 0.2, 0.3 s) of 20 nodes.
    let csv = std::fs::read_to_string(out.join("rope_nodes.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("time_s,node,x_m,y_m,z_m"));
    assert_eq!(lines.count(), 4 * 20);
    assert!(!csv.contains("NaN") && !csv.contains("inf"));
    let svg = std::fs::read_to_string(out.join("rope_frames.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("top · t = 0.3 s"));
}

#[test]
fn print_default_is_the_shipped_overhand_scenario() {
    let o = softjoint(&["dlo", "rope", "--print-default"]);
    ok(&o);
    let shipped = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/dlo/overhand.toml"
    ))
    .unwrap();
    assert_eq!(stdout(&o), shipped);
}

#[test]
fn twisted_wire_energy_is_the_closed_form() {
    let dir = scratch("dlo-solve");
    let problem = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/dlo/twist.toml");
    let out = dir.join("out");
    let o = softjoint(&["dlo", "solve", problem, "--out", s(&out), "--json"]);
    ok(&o);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let u = json["energy_j"].as_f64().unwrap();
    let exact = 2.3e-4 * std::f64::consts::PI.powi(2) / (2.0 * 0.871);
    assert!((u - exact).abs() < 1e-6 * exact, "{u} vs {exact}");
    assert_eq!(json["converged"], true);
    let csv = std::fs::read_to_string(out.join("shape.csv")).unwrap();
    assert!(csv.starts_with("shape,l_fraction,s_m,x_m"));
    assert_eq!(csv.lines().count(), 1 + 65);
    assert!(std::fs::read_to_string(out.join("shape.svg"))
        .unwrap()
        .contains("wire · top"));
}

#[test]
fn bad_rope_scenarios_are_refused_with_names() {
    let dir = scratch("dlo-bad");
    let out = dir.join("out");
    let unknown = file(
        &dir,
        "a.toml",
        &SHORT_ROPE.replace("pins = [0]", "pins = [0]\nwind = 3"),
    );
    refused(
        &["dlo", "rope", &unknown, "--out", s(&out)],
        &["a.toml", "wind"],
    );
    let bad_node = file(
        &dir,
        "b.toml",
        &SHORT_ROPE.replace("node = 19", "node = 99"),
    );
    refused(
        &["dlo", "rope", &bad_node, "--out", s(&out)],
        &["b.toml", "node 99"],
    );
    let bad_k = file(
        &dir,
        "c.toml",
        &SHORT_ROPE.replace("nodes = 20", "nodes = 20\nlinear_stiffness_n = -800"),
    );
    refused(
        &["dlo", "rope", &bad_k, "--out", s(&out)],
        &["c.toml", "linear_stiffness_n"],
    );
    let order = file(
        &dir,
        "d.toml",
        &SHORT_ROPE.replace("t_s = 0.3, at_m", "t_s = 0.0, at_m"),
    );
    refused(
        &["dlo", "rope", &order, "--out", s(&out)],
        &["d.toml", "right", "not after"],
    );
    let dt = file(
        &dir,
        "e.toml",
        &SHORT_ROPE.replace("nodes = 20", "nodes = 20\ndt_s = 1.0"),
    );
    refused(&["dlo", "rope", &dt, "--out", s(&out)], &["e.toml", "dt_s"]);
    refused(
        &[
            "dlo",
            "rope",
            s(&dir.join("missing.toml")),
            "--out",
            s(&out),
        ],
        &["missing.toml"],
    );
}

#[test]
fn unstable_rope_is_reported_by_name() {
    // A 100 µs spring period at a 10 ms step: the run must stop with a
    // named instability, not write NaN.
    let dir = scratch("dlo-unstable");
    let text = SHORT_ROPE.replace(
        "nodes = 20",
        "nodes = 20\ndt_s = 0.01\nlinear_stiffness_n = 1e7",
    );
    let f = file(&dir, "u.toml", &text);
    refused(
        &["dlo", "rope", &f, "--out", s(&dir.join("o"))],
        &["u.toml", "unstable"],
    );
}

#[test]
fn bad_solve_problems_are_refused_with_names() {
    let dir = scratch("dlo-bad-solve");
    let out = dir.join("out");
    let model = file(&dir, "m.toml", "model = \"cloth\"\n");
    refused(
        &["dlo", "solve", &model, "--out", s(&out)],
        &["m.toml", "cloth"],
    );
    let belt = file(
        &dir,
        "b.toml",
        "model = \"belt\"\n[problem]\nwidth_m = -0.1\n",
    );
    refused(
        &["dlo", "solve", &belt, "--out", s(&out)],
        &["b.toml", "width_m"],
    );
    let far = file(
        &dir,
        "f.toml",
        "model = \"belt\"\n[problem]\nend_m = [0.0, 1.5, 0.0]\n",
    );
    refused(
        &["dlo", "solve", &far, "--out", s(&out)],
        &["f.toml", "end_m"],
    );
    let twist = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/dlo/twist.toml"
    ))
    .unwrap();
    let neg = file(
        &dir,
        "w.toml",
        &twist.replace("length_m = 0.871", "length_m = -1"),
    );
    refused(
        &["dlo", "solve", &neg, "--out", s(&out)],
        &["w.toml", "length_m"],
    );
    // The range is stated (`harmonics` = 40 said "outside its allowed
    // range").
    let many = file(
        &dir,
        "h.toml",
        &twist.replace("harmonics = 4\n", "harmonics = 40\n"),
    );
    refused(
        &["dlo", "solve", &many, "--out", s(&out)],
        &["h.toml", "`harmonics` = 40: must be within 0..=12"],
    );
    let seq = file(
        &dir,
        "s.toml",
        "model = \"sequence\"\nfractions = []\nwire = { length_m = 1.0, flexural_rigidity_n_m2 = 1.0, torsional_rigidity_n_m2 = 1.0, radius_m = 0.001 }\n",
    );
    refused(
        &["dlo", "solve", &seq, "--out", s(&out)],
        &["s.toml", "fractions"],
    );
}
