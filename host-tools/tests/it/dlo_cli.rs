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
    assert_eq!(json["topology"][0]["determinant"], 1);
    assert_eq!(json["topology"][0]["crossings"], 0);
    // Issue 29: the run's own checks, each a number with its tolerance.
    assert_eq!(json["status"], "verified");
    assert_eq!(json["failed_checks"], serde_json::json!([]));
    for name in ["overlap", "force_balance", "stability"] {
        let c = &json["checks"][name];
        assert_eq!(c["passed"], true, "{name}: {c}");
        assert!(c["value"].as_f64().unwrap() <= c["tolerance"].as_f64().unwrap());
    }
    assert!(json["checks"].get("time_step").is_none(), "asked for only");
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

/// Issue 29: a rope whose free end a hand drags through the rope, with
/// the collision shift turned off, overlaps by about 2r against a
/// tolerance of 0.3 r. The command writes its files, says UNVERIFIED (text,
/// JSON, picture) and exits 1; `--allow-unverified` exits 0 with the same
/// marks. With Table I's four shift passes the same drag is verified.
#[test]
fn a_rope_dragged_through_itself_is_unverified_and_exits_1() {
    let dir = scratch("dlo-rope-overlap");
    // The shipped example of a run the tool must not call right.
    let through = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../scenarios/dlo/drag_through.toml"
    );
    let out = dir.join("out");
    let o = softjoint(&["dlo", "rope", through, "--out", s(&out), "--json"]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    assert!(
        common::stderr(&o).contains("drag_through.toml: UNVERIFIED: the run fails overlap"),
        "{}",
        common::stderr(&o)
    );
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["status"], "UNVERIFIED");
    assert_eq!(json["failed_checks"], serde_json::json!(["overlap"]));
    let overlap = &json["checks"]["overlap"];
    assert_eq!(overlap["passed"], false);
    assert!(overlap["value"].as_f64().unwrap() > 4.0 * overlap["tolerance"].as_f64().unwrap());
    let svg = std::fs::read_to_string(out.join("rope_frames.svg")).unwrap();
    assert!(svg.contains("UNVERIFIED: fails overlap"));
    assert!(svg.contains("top · t = 0.0 s · UNVERIFIED"));
    assert!(out.join("rope_nodes.csv").exists());
    let o = softjoint(&["dlo", "rope", through, "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stdout(&o).starts_with("UNVERIFIED: the run fails overlap"),
        "{}",
        stdout(&o)
    );
    let o = softjoint(&[
        "dlo",
        "rope",
        through,
        "--out",
        s(&out),
        "--allow-unverified",
    ]);
    ok(&o);
    assert!(stdout(&o).starts_with("UNVERIFIED"));
    let four_passes = std::fs::read_to_string(through)
        .unwrap()
        .replace("collision_passes = 0", "collision_passes = 4");
    let kept = file(&dir, "kept.toml", &four_passes);
    let o = softjoint(&["dlo", "rope", &kept, "--out", s(&out), "--json"]);
    ok(&o);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["status"], "verified");
    let svg = std::fs::read_to_string(out.join("rope_frames.svg")).unwrap();
    assert!(!svg.contains("UNVERIFIED"));
}

/// Issue 29: a run the step stops (soft springs whipping at dt = 5 ms)
/// is the failed stability check with the step's reason, its frames up to
/// there written; `--check-step` adds the time-step check, which fails too.
#[test]
fn a_rope_that_blows_up_is_unverified_with_its_reason() {
    let dir = scratch("dlo-rope-unstable");
    let scenario = file(
        &dir,
        "whip.toml",
        "name = \"whip\"\nstart_m = [0.0, 0.0, 2.0]\ndirection = [1.0, 0.0, 0.0]\npins = [0]\nduration_s = 1.0\n[rope]\nnodes = 12\nlength_m = 1.1\nradius_m = 0.01\ndt_s = 0.005\nlinear_stiffness_n = 20.0\ntorsional_stiffness_n_m = 0.1\n",
    );
    let out = dir.join("out");
    let o = softjoint(&[
        "dlo",
        "rope",
        &scenario,
        "--out",
        s(&out),
        "--json",
        "--check-step",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(
        json["failed_checks"],
        serde_json::json!(["stability", "time_step"])
    );
    let note = json["checks"]["stability"]["note"].as_str().unwrap();
    assert!(
        note.contains("the run stopped") && note.contains("rest lengths"),
        "{note}"
    );
    let csv = std::fs::read_to_string(out.join("rope_nodes.csv")).unwrap();
    assert!(csv.lines().count() > 12 && !csv.contains("NaN"));
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

/// A clamped wire with both ends on the z axis, the far end at `l_m`.
fn clamped_wire(extra_wire: &str, constraints_end: &str) -> String {
    format!(
        r#"model = "wire"
[problem]
wire = {{ length_m = 0.871, flexural_rigidity_n_m2 = 6.6e-4, torsional_rigidity_n_m2 = 2.3e-4, radius_m = 1e-3{extra_wire} }}
constraints = [
  {{ kind = "orientation", s_m = 0.0, euler_rad = [0.0, 0.0, 0.0] }},
{constraints_end}]
"#
    )
}

/// Issue 29: a heavy cantilever on the paper's 4 harmonics moves by 2 % of
/// its energy on a grid twice as fine. The answer is written, but the
/// report, the JSON, the picture and the exit status say it is unverified.
#[test]
fn a_coarse_heavy_cantilever_is_reported_unverified_and_exits_1() {
    let dir = scratch("dlo-unverified");
    let problem = file(
        &dir,
        "cantilever.toml",
        &clamped_wire(", weight_n_per_m = 1.0e-2", ""),
    );
    let out = dir.join("out");
    let o = softjoint(&["dlo", "solve", &problem, "--out", s(&out), "--json"]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    assert!(
        common::stderr(&o).contains("cantilever.toml: UNVERIFIED: the wire fails discretisation")
    );
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["converged"], false);
    assert_eq!(json["status"], "UNVERIFIED");
    assert_eq!(json["failed_checks"][0], "discretisation");
    let change = json["checks"]["discretisation_energy"].as_f64().unwrap();
    assert!(change > 0.01, "{change}");
    let svg = std::fs::read_to_string(out.join("shape.svg")).unwrap();
    assert!(svg.contains("UNVERIFIED: fails discretisation"));
    // The text report says so on its first line.
    let o = softjoint(&["dlo", "solve", &problem, "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stdout(&o).starts_with("UNVERIFIED"), "{}", stdout(&o));
}

/// Issue 29: the paper's belt on 30 segments moves by 2.9 % of its length
/// against 15 (the independent reference, scripts/belt_reference.py, moves
/// its top by 2.6 % from 30 to 60 segments). The answer is written, but
/// the report, the JSON, the picture and the exit status say it is
/// unverified; the other checks pass.
#[test]
fn a_coarse_belt_is_reported_unverified_and_exits_1() {
    let dir = scratch("dlo-belt-unverified");
    let problem = file(
        &dir,
        "belt.toml",
        "model = \"belt\"\n[problem]\nintervals = 30\n",
    );
    let out = dir.join("out");
    let o = softjoint(&["dlo", "solve", &problem, "--out", s(&out), "--json"]);
    assert_eq!(o.status.code(), Some(1), "{}", common::stderr(&o));
    assert!(
        common::stderr(&o).contains("belt.toml: UNVERIFIED: the belt fails discretisation"),
        "{}",
        common::stderr(&o)
    );
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["converged"], false);
    assert_eq!(json["status"], "UNVERIFIED");
    assert_eq!(json["failed_checks"], serde_json::json!(["discretisation"]));
    let moved = json["checks"]["discretisation_position"].as_f64().unwrap();
    assert!(moved > 0.01, "{moved}");
    assert!(json["checks"]["kkt_residual"].as_f64().unwrap() < 1e-5);
    let svg = std::fs::read_to_string(out.join("shape.svg")).unwrap();
    assert!(svg.contains("UNVERIFIED: fails discretisation"));
    assert!(svg.contains("belt (b) front · UNVERIFIED"));
    let o = softjoint(&["dlo", "solve", &problem, "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stdout(&o).starts_with("UNVERIFIED"), "{}", stdout(&o));
}

/// Issue 29: the paper's wire clamped at both ends with the ends at 0.7 L
/// (main reported 0.678 J, 70× the elastica, with exit 0). The elastica by
/// elliptic integrals (plant-models/dlo/tests/it/elastica_ref.rs) gives
/// 9.734829e-3 J.
#[test]
#[ignore = "a minute in a debug build: CI runs it in ci-opt"]
fn clamped_wire_at_0_7_l_is_the_elastica_through_the_cli() {
    let dir = scratch("dlo-elastica");
    let end = "  { kind = \"position\", s_a_m = 0.0, s_b_m = 0.871, l_m = [0.0, 0.0, 0.6097] },\n  { kind = \"orientation\", s_m = 0.871, euler_rad = [0.0, 0.0, 0.0] },\n";
    let problem = file(&dir, "clamped.toml", &clamped_wire("", end));
    let out = dir.join("out");
    let o = softjoint(&["dlo", "solve", &problem, "--out", s(&out), "--json"]);
    ok(&o);
    let json: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(json["status"], "verified");
    let u = json["energy_j"].as_f64().unwrap();
    assert!((u - 9.734829e-3).abs() < 1e-3 * 9.734829e-3, "{u}");
}
