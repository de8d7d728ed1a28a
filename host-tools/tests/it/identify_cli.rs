//! `softjoint identify`, `tune`, `sim --excite` and the files between
//! them: the pipeline end to end in short form, the committed tuned gains
//! against the paper's on the hidden plant, and bad input.
use crate::common;

use common::{ok, s, scratch, softjoint, stderr, stdout};
use host_tools::files::gains::{Gains, GainsFile};
use host_tools::files::plant::{PlantFile, PlantParams};
use host_tools::files::JointKind;
use host_tools::joint::tune;
use host_tools::run::spec::RunSpec;
use plant_joint::identify::{hidden, ExcitationLog, ExcitationPlan};

fn write(path: &std::path::Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

pub fn hidden_2d_file(dir: &std::path::Path) -> std::path::PathBuf {
    let p = dir.join("hidden.toml");
    PlantFile::new(PlantParams::TwoD(hidden::joint_2d(5)), vec![])
        .save(&p, "# hidden\n")
        .unwrap();
    p
}

/// Record → identify → tune → load the gains, on the 2D joint, in short
/// form (a 24 s plan, 3 iterations per stage, 3 candidates × 2 plants):
/// the plumbing and the file formats, not the accuracy (that is
/// plant-models' `joint_identify`).
#[test]
fn record_identify_tune_and_load_the_gains() {
    let dir = scratch("identify-pipeline");
    hidden_2d_file(&dir);
    write(
        &dir.join("hidden.scenario.toml"),
        "name = \"hidden 2D\"\njoint = \"2d\"\nseed = 5\ntargets = [{ t_s = 0, deg = [0] }]\n[estimator]\nmethod = \"paper\"\n[plant]\nfile = \"hidden.toml\"\n",
    );
    let mut plan = ExcitationPlan::compact(1);
    plan.duration_s = 24.0;
    plan.drive.retain(|d| d.to_s <= 24.0);
    plan.hold.push(plant_joint::identify::plan::Hold {
        plane: 0,
        deg: 5.0,
        from_s: 12.0,
        to_s: 19.5,
    });
    write(
        &dir.join("plan.toml"),
        &toml::to_string_pretty(&plan).unwrap(),
    );
    let log = dir.join("log.csv");
    let o = softjoint(&[
        "sim",
        s(&dir.join("hidden.scenario.toml")),
        "--excite",
        s(&dir.join("plan.toml")),
        "--log",
        s(&log),
    ]);
    ok(&o);
    assert!(stdout(&o).contains("2400 rows"), "{}", stdout(&o));
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(text
        .starts_with("t_s,v1_v,v2_v,cam_capture_s,cam_theta_deg,d1_mm,i1_a,i2_a,r1_ohm,r2_ohm\n"));
    // The hold put the joint under the controller at 5°: the log shows
    // it moving there from ≈ 0° (the controller's own thermal budget, run
    // on its 5 V saturated outputs, may cut it short of the target).
    let angles: Vec<(f64, f64)> = text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (f[0], f[4])
        })
        .collect();
    let mean = |a: f64, b: f64| {
        let v: Vec<f64> = angles
            .iter()
            .filter(|x| (a..b).contains(&x.0))
            .map(|x| x.1)
            .collect();
        v.iter().sum::<f64>() / v.len() as f64
    };
    let (before, during) = (mean(11.0, 12.0), mean(16.0, 19.5));
    assert!(
        during > 2.5 && during - before > 3.0,
        "before the hold {before}°, during {during}°"
    );
    let plant = dir.join("plant.toml");
    let o = softjoint(&[
        "identify",
        "joint",
        s(&log),
        "-o",
        s(&plant),
        "--max-iterations",
        "3",
        // 24 s and 3 iterations: the plumbing, not a plant that passes
        // its checks (it says UNVERIFIED; the flag keeps exit 0).
        "--allow-unverified",
        "--plot",
        s(&dir.join("fit.svg")),
    ]);
    ok(&o);
    let out = stdout(&o);
    assert!(
        out.contains("link.inertia_kg_m2") && out.contains("held-out"),
        "{out}"
    );
    assert!(std::fs::read_to_string(dir.join("fit.svg"))
        .unwrap()
        .contains("<svg"));
    let file = PlantFile::load(&plant).unwrap();
    assert!(matches!(file.params().unwrap(), PlantParams::TwoD(_)));
    assert!(!file.uncertainty.is_empty());
    // The JSON form carries the same estimates.
    let o = softjoint(&[
        "identify",
        "joint",
        s(&log),
        "-o",
        s(&plant),
        "--max-iterations",
        "2",
        "--json",
        "--allow-unverified",
    ]);
    ok(&o);
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(j["planes"][0]["estimates"].as_array().unwrap().len() >= 10);
    // The verdict travels with the JSON: a flag, and the planes' reasons.
    let verified = j["verified"].as_bool().unwrap();
    let failures = j["planes"][0]["verdict"]["failures"].as_array().unwrap();
    assert_eq!(verified, failures.is_empty(), "{j}");
    assert_eq!(
        j["unverified_because"].as_array().unwrap().len(),
        failures.len()
    );
    // Without the flag, an unverified result exits 1 and says why.
    if !verified {
        let o = softjoint(&[
            "identify",
            "joint",
            s(&log),
            "-o",
            s(&dir.join("plant2.toml")),
            "--max-iterations",
            "2",
        ]);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("UNVERIFIED"), "{}", stderr(&o));
        assert!(std::fs::read_to_string(dir.join("plant2.toml"))
            .unwrap()
            .contains("# UNVERIFIED: theta: "));
    }

    let gains = dir.join("gains.toml");
    let o = softjoint(&[
        "tune",
        s(&plant),
        "--candidates",
        "3",
        "--plants",
        "2",
        "--search-v-offset",
        "--json",
        // 3 candidates × 2 plants: the plumbing; the winner may lose to
        // the paper's gains on the held-out steps.
        "--allow-unproven",
        "-o",
        s(&gains),
    ]);
    ok(&o);
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let proven = j["heldout_beats_or_ties_paper"].as_bool().unwrap();
    let g = GainsFile::load(&gains).unwrap();
    let heldout = g.tuning.as_ref().unwrap().heldout.as_ref().unwrap();
    assert_eq!(proven, heldout.beats_or_ties_paper);
    // Proven only if the tuned gains beat or tie the paper's on the steps
    // and on every other manoeuvre (2D: the load).
    let names: Vec<&str> = heldout.manoeuvres.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(names, ["load"]);
    for m in &heldout.manoeuvres {
        assert_eq!(
            m.beats_or_ties_paper,
            m.tuned.robust <= m.paper.robust * (1.0 + tune::HELDOUT_TIE),
            "{m:?}"
        );
    }
    assert_eq!(
        proven,
        heldout.score.robust <= heldout.paper.robust * (1.0 + tune::HELDOUT_TIE)
            && heldout.manoeuvres.iter().all(|m| m.beats_or_ties_paper),
        "{heldout:?}"
    );
    assert_eq!(g.joint, JointKind::TwoD);
    assert_eq!(g.controller.kp_v_per_deg.len(), 2);
    // v_offset searched, in its range (the scenario below runs with it).
    assert!(g.tuning.as_ref().is_some_and(|t| t.v_offset_searched));
    let (lo, hi) = host_tools::joint::tune::V_OFFSET_SEARCH_V;
    assert!((lo..=hi).contains(&g.controller.v_offset_v), "{g:?}");
    // A scenario runs with the tuned gains on the identified plant.
    write(
        &dir.join("tuned.scenario.toml"),
        "name = \"tuned\"\njoint = \"2d\"\nduration_s = 2.0\ntargets = [{ t_s = 0, deg = [3] }]\n[estimator]\nmethod = \"paper\"\n[plant]\nfile = \"plant.toml\"\n[controller]\ngains_file = \"gains.toml\"\n",
    );
    ok(&softjoint(&["sim", s(&dir.join("tuned.scenario.toml"))]));

    // The gains in use now (`--current`) are scored on the same held-out
    // manoeuvres and plants and compared with the new winner.
    let o = softjoint(&[
        "tune",
        s(&plant),
        "--candidates",
        "2",
        "--plants",
        "1",
        "--json",
        "--allow-unproven",
        "--current",
        s(&gains),
        "-o",
        s(&dir.join("gains2.toml")),
    ]);
    ok(&o);
    let j: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let rows = j["heldout_current"]
        .as_array()
        .expect("heldout_current rows");
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["manoeuvre"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["steps", "load"]);
    for r in rows {
        let (c, t) = (
            r["current_robust"].as_f64().unwrap(),
            r["tuned_robust"].as_f64().unwrap(),
        );
        assert!(c.is_finite() && t.is_finite(), "{r}");
        assert_eq!(
            r["tuned_beats_or_ties_current"].as_bool().unwrap(),
            t <= c * (1.0 + tune::HELDOUT_TIE),
            "{r}"
        );
    }
    // A 3D gains file for this 2D plant is refused before any search.
    let g3 = dir.join("gains3d.toml");
    let mut three = g.clone();
    three.joint = JointKind::ThreeD;
    three.controller.kp_v_per_deg = vec![2.0; 4];
    write(&g3, &toml::to_string(&three).unwrap());
    let o = softjoint(&[
        "tune",
        s(&plant),
        "--current",
        s(&g3),
        "-o",
        s(&dir.join("g4.toml")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains(&format!("--current {}: gains for a 3d joint", g3.display())),
        "{}",
        stderr(&o)
    );
}

/// The must-show in `sim`: the gains `softjoint tune` found on the plant
/// identified from the hidden 3D joint's 10-minute log (the committed
/// scenarios/identify files, made by the commands of the joint README)
/// beat the paper's gains on the hidden joint itself, without a fault.
///
/// The committed gains (tuned on the plant identified after the replay
/// stopped drawing its own stick events) cost 2.85 on the hidden joint
/// against the paper's 3.13. The gains tuned on the earlier plant, whose
/// jamming gain was 2.5–2.9 times the truth, lost (3.26 against 3.13):
/// joint README, "Tuned gains on the hidden joint".
#[test]
fn committed_tuned_gains_beat_the_paper_on_the_hidden_plant_in_sim() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let g = GainsFile::load(&root.join("scenarios/identify/gains.toml")).unwrap();
    let hidden = PlantParams::ThreeD(hidden::joint_3d(7));
    let tuned = tune::evaluate(
        &RunSpec::resolve(&tune::test_scenario(
            JointKind::ThreeD,
            &g.controller,
            hidden.clone(),
            1,
        ))
        .unwrap(),
    )
    .unwrap();
    let paper = tune::evaluate(
        &RunSpec::resolve(&tune::test_scenario(
            JointKind::ThreeD,
            &Gains::paper(4),
            hidden,
            1,
        ))
        .unwrap(),
    )
    .unwrap();
    eprintln!("on the hidden joint: tuned {tuned:?}\npaper {paper:?}");
    assert!(!tuned.fault, "{tuned:?}");
    assert!(tuned.cost < paper.cost, "tuned {tuned:?}\npaper {paper:?}");
}

#[test]
fn bad_plans_logs_and_files_are_named() {
    let dir = scratch("identify-bad");
    let plan = dir.join("plan.toml");
    let scen = dir.join("s.toml");
    write(
        &scen,
        "joint = \"2d\"\ntargets = [{ t_s = 0, deg = [0] }]\n[estimator]\nmethod = \"paper\"\n",
    );
    let log = dir.join("log.csv");
    let run = |p: &str| {
        write(&plan, p);
        softjoint(&["sim", s(&scen), "--excite", s(&plan), "--log", s(&log)])
    };
    let o = run("name = \"x\"\nduration_s = 10\n[[drive]]\ncoil = 1\nfrom_s = 0\nto_s = 5\nvolts = 1.9\n[[drive]]\ncoil = 1\nfrom_s = 4\nto_s = 6\nvolts = 1.9\n");
    assert!(
        !o.status.success() && stderr(&o).contains("`drive[1]`: overlaps `drive[0]`"),
        "{}",
        stderr(&o)
    );
    let o = run(
        "name = \"x\"\nduration_s = 10\n[[drive]]\ncoil = 1\nfrom_s = 0\nto_s = 9\nvolts = 4.5\n",
    );
    assert!(
        stderr(&o).contains("would trip the board's thermal budget"),
        "{}",
        stderr(&o)
    );
    let o = run(
        "name = \"x\"\nduration_s = 10\n[[drive]]\ncoil = 3\nfrom_s = 0\nto_s = 9\nvolts = 1.8\n",
    );
    assert!(
        stderr(&o).contains("`drive[0]`.coil: must be 1..=2"),
        "{}",
        stderr(&o)
    );
    let o = run("name = \"x\"\nduration_s = 10\nspeed = 3\n");
    assert!(
        stderr(&o).contains("plan.toml:3:1") && stderr(&o).contains("speed"),
        "{}",
        stderr(&o)
    );
    assert!(!log.exists());
    // --excite needs --log (and --log needs --excite).
    let o = softjoint(&["sim", "--excite", s(&plan)]);
    assert!(
        !o.status.success() && stderr(&o).contains("--log"),
        "{}",
        stderr(&o)
    );

    write(&log, "t_s,v1_v,v2_v,cam_capture_s,d1_mm\n0,0,0,0,0\n");
    let o = softjoint(&["identify", "joint", s(&log)]);
    assert!(
        stderr(&o).contains("log.csv:1:")
            && stderr(&o).contains("missing column `cam_theta_deg` (a 2D log) or `cam_alpha_deg`"),
        "{}",
        stderr(&o)
    );
    let o = softjoint(&["identify", "joint", s(&log), "--fit-fraction", "0.1"]);
    assert!(
        stderr(&o).contains("--fit-fraction must be in 0.2..=1"),
        "{}",
        stderr(&o)
    );

    let plant = dir.join("plant.toml");
    write(&plant, "[joint2d]\nplane.coil.austenite_finish_c = 60.0\n");
    write(&scen, "joint = \"2d\"\ntargets = [{ t_s = 0, deg = [0] }]\n[estimator]\nmethod = \"paper\"\n[plant]\nfile = \"plant.toml\"\n");
    let o = softjoint(&["sim", s(&scen)]);
    assert!(
        stderr(&o).contains("plant.toml") && stderr(&o).contains("austenite_finish_c"),
        "{}",
        stderr(&o)
    );
    hidden_2d_file(&dir);
    write(&scen, "joint = \"3d\"\n[plant]\nfile = \"hidden.toml\"\n");
    let o = softjoint(&["sim", s(&scen)]);
    assert!(
        stderr(&o).contains("a 2D plant ([joint2d]) for `joint = \"3d\"`"),
        "{}",
        stderr(&o)
    );

    let gains = dir.join("gains.toml");
    write(&gains, "joint = \"3d\"\n[controller]\nkp_v_per_deg = [1, 2]\nki_v_per_deg_s = 0\nintegral_limit_v = 1\n");
    let o = softjoint(&["tune", s(&plant)]);
    assert!(!o.status.success(), "{}", stdout(&o));
    write(&scen, "[controller]\ngains_file = \"gains.toml\"\n");
    let o = softjoint(&["sim", s(&scen)]);
    assert!(
        stderr(&o).contains("kp_v_per_deg` needs 4 values"),
        "{}",
        stderr(&o)
    );
    // A v_offset at the supply is no law the board can run.
    write(&gains, "joint = \"3d\"\n[controller]\nkp_v_per_deg = [1, 2, 1, 2]\nki_v_per_deg_s = 0\nintegral_limit_v = 1\nv_offset_v = 5.0\n");
    let o = softjoint(&["sim", s(&scen)]);
    assert!(
        stderr(&o).contains("gains.toml")
            && stderr(&o).contains("`controller.v_offset_v` must be in 0..5 V"),
        "{}",
        stderr(&o)
    );
    write(&scen, "[controller]\nv_offset_v = -0.5\n");
    let o = softjoint(&["sim", s(&scen)]);
    assert!(
        stderr(&o).contains("field `controller.v_offset_v`: must be in 0..5 V"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn standard_and_compact_plans_stay_within_the_thermal_budget() {
    for (joint, holds) in [("2d", false), ("3d", true)] {
        let mut args = vec!["identify", "plan", "--joint", joint, "--duration-s", "600"];
        if holds {
            args.push("--holds");
        }
        let o = softjoint(&args);
        ok(&o);
        let plan: ExcitationPlan = toml::from_str(&stdout(&o)).unwrap();
        let planes = if joint == "2d" { 1 } else { 2 };
        plan.validate(planes).unwrap();
        let peak = host_tools::joint::excite::check_budget(&plan).unwrap();
        assert!(peak > 40.0 && peak < 95.0, "{joint}: peak rise {peak} K");
    }
    // The compact plan of the CI twin test too.
    for planes in [1, 2] {
        let plan = ExcitationPlan::compact(planes);
        plan.validate(planes).unwrap();
        let peak = host_tools::joint::excite::check_budget(&plan).unwrap();
        assert!(
            peak > 40.0 && peak < 95.0,
            "compact, {planes} planes: peak rise {peak} K"
        );
    }
}

/// The same plan through `hil` (the firmware's board application on a
/// pty, in lockstep) records the log `sim` records: the drives bypass the
/// board's outputs, and during the hold the board's own controller moves
/// the joint exactly as the in-process core does. A 3 s plan: a pulse on
/// α's agonist, then a hold of α at 4° under the board's controller.
#[test]
fn the_plan_through_hil_logs_what_sim_logs() {
    use host_tools::board::hil::HilOptions;
    use host_tools::board::link::Link;
    use host_tools::board::pty::PtyBoard;
    use host_tools::files::scenario::Scenario;
    use plant_joint::identify::plan::{Drive, Hold};

    let plan = ExcitationPlan {
        name: "pulse and hold".into(),
        duration_s: 3.0,
        log_interval_ms: 10,
        drive: vec![Drive {
            coil: 1,
            from_s: 0.0,
            to_s: 1.0,
            volts: Some(3.0),
            from_v: None,
            to_v: None,
        }],
        hold: vec![Hold {
            plane: 0,
            deg: 4.0,
            from_s: 1.5,
            to_s: 3.0,
        }],
    };
    let s = Scenario {
        seed: 3,
        ..Scenario::default()
    };
    let spec = RunSpec::resolve(&s).unwrap();
    let no_stop = host_tools::stop::Stop::never();
    let mut sim_log = ExcitationLog::default();
    let sim_summary =
        host_tools::joint::excite::run_sim(&plan, &spec, true, &mut sim_log, &no_stop).unwrap();
    let (board, host_end) = PtyBoard::start().expect("pty pair");
    let mut link = Link::new(host_end);
    // The pty board's clock is the host's: a loaded host needs a link
    // timeout with slack (the board's own 50 ms saw a link loss).
    let opts = HilOptions {
        link_timeout_ms: Some(2000),
        ..HilOptions::default()
    };
    let mut hil_log = ExcitationLog::default();
    let hil_summary = host_tools::joint::excite::run_hil(
        &plan,
        &spec,
        &mut link,
        opts,
        true,
        &mut hil_log,
        &no_stop,
    )
    .unwrap();
    drop(board);
    assert_eq!(hil_log.len(), 300);
    assert_eq!(hil_summary.faults_seen, sim_summary.faults_seen);
    // The hold moved α from the pulse's decay towards 4° (not only the
    // drives shaped the log), and the two logs agree row for row.
    let alpha_at = |t: f64| hil_log.cam_deg[(t * 100.0) as usize][0];
    assert!(
        (alpha_at(2.95) - 4.0).abs() < (alpha_at(1.5) - 4.0).abs(),
        "α {}° at 1.5 s, {}° at 2.95 s",
        alpha_at(1.5),
        alpha_at(2.95)
    );
    assert!(hil_log == sim_log, "hil and sim logs differ");
}

/// The probe, as a user runs it, on issue 28's off-plan twin (α's drivers
/// turn on at 2.0 V, above the standard plan's held levels; β's at 1.6 V):
/// `identify probe` → `sim --excite` → `identify plan --probe`. The
/// turn-ons come out of the log's currents; α's coils are named as
/// pulsed (their adapted levels lie above what the firmware's default
/// budget allows held), β's are not; the adapted plan is within the
/// budget and runs through `sim --excite`. A log that is no probe is
/// refused naming the file and the column, and writes nothing on stdout.
#[test]
fn a_probe_log_places_the_plan_and_names_the_coils_it_can_only_pulse() {
    let dir = scratch("identify-probe");
    PlantFile::new(PlantParams::ThreeD(hidden::off_plan_joint_3d(5)), vec![])
        .save(&dir.join("hidden.toml"), "# hidden\n")
        .unwrap();
    let scen = dir.join("hidden.scenario.toml");
    write(
        &scen,
        "joint = \"3d\"\nseed = 5\n[plant]\nfile = \"hidden.toml\"\n",
    );
    let o = softjoint(&["identify", "probe", "--joint", "3d"]);
    ok(&o);
    let probe_plan = dir.join("probe.toml");
    write(&probe_plan, &stdout(&o));
    let plan: ExcitationPlan = toml::from_str(&stdout(&o)).unwrap();
    assert_eq!(plan, ExcitationPlan::probe(2));
    let peak = host_tools::joint::excite::check_budget(&plan).unwrap();
    assert!(peak > 60.0 && peak < 95.0, "probe: peak rise {peak} K");
    // `sim --excite PLAN --log LOG` on the twin, and any other flags.
    let record = |plan: &std::path::Path, log: &std::path::Path, more: &[&str]| {
        let mut args = vec!["sim", s(&scen), "--excite", s(plan), "--log", s(log)];
        args.extend(more);
        ok(&softjoint(&args));
    };
    let log = dir.join("probe.csv");
    record(&probe_plan, &log, &[]);

    let adapted_plan = |json: bool| {
        let mut args = vec![
            "identify",
            "plan",
            "--probe",
            s(&log),
            "--duration-s",
            "240",
        ];
        if json {
            args.push("--json");
        }
        let o = softjoint(&args);
        ok(&o);
        o
    };
    let o = adapted_plan(true);
    let r: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    let turn_on = |coil: usize| r["probe"]["coils"][coil - 1]["turn_on_v"].as_f64().unwrap();
    for (coil, truth) in [(1, 2.0), (2, 1.6), (3, 2.0), (4, 1.6)] {
        assert!(
            (turn_on(coil) - truth).abs() < 0.02,
            "coil {coil}: {} V against {truth} V",
            turn_on(coil)
        );
    }
    assert_eq!(
        r["pulsed_coils"],
        serde_json::json!([1, 3]),
        "{}",
        r["notes"]
    );
    assert!(
        r["notes"][0]
            .as_str()
            .unwrap()
            .contains("coil 1 (plane α) turns on at 2.00 V")
            && r["notes"][0].as_str().unwrap().contains("up to 2.52 V"),
        "{}",
        r["notes"]
    );
    let adapted: ExcitationPlan = serde_json::from_value(r["plan"].clone()).unwrap();
    let found: plant_joint::identify::probe::ProbeReport =
        plant_joint::identify::probe::analyse(&host_tools::joint::excite::read_log(&log).unwrap())
            .unwrap();
    // (serde_json reads a float back within an ulp, not always exactly.)
    let expected = ExcitationPlan::adapted(2, 240.0, &found, false);
    assert_eq!(adapted.drive.len(), expected.drive.len());
    let near = |a: Option<f64>, b: Option<f64>| match (a, b) {
        (Some(x), Some(y)) => (x - y).abs() < 1e-12,
        (x, y) => x == y,
    };
    for (a, b) in adapted.drive.iter().zip(&expected.drive) {
        assert!(
            a.coil == b.coil
                && near(Some(a.from_s), Some(b.from_s))
                && near(Some(a.to_s), Some(b.to_s))
                && near(a.volts, b.volts)
                && near(a.from_v, b.from_v)
                && near(a.to_v, b.to_v),
            "{a:?} against {b:?}"
        );
    }
    let peak = r["budget_peak_rise_k"].as_f64().unwrap();
    assert!(peak > 40.0 && peak < 95.0, "adapted: peak rise {peak} K");

    // The TOML form: the findings and the notes in its header, the notes
    // on stderr too; it loads and runs as a plan (its first 12 s).
    let o = adapted_plan(false);
    let text = stdout(&o);
    assert!(
        text.contains("#   coil 2 (plane β): turns on at 1.6")
            && text.contains("# note: coil 3 (plane α)"),
        "{text}"
    );
    assert!(
        stderr(&o).contains("note: coil 1 (plane α)"),
        "{}",
        stderr(&o)
    );
    let mut short: ExcitationPlan = toml::from_str(&text).unwrap();
    assert_eq!(short, expected);
    short.duration_s = 12.0;
    short.drive.retain(|d| d.to_s <= 12.0);
    write(
        &dir.join("adapted.toml"),
        &toml::to_string_pretty(&short).unwrap(),
    );
    record(&dir.join("adapted.toml"), &dir.join("adapted.csv"), &[]);

    // A log that is no probe (the adapted plan's own): refused by name.
    let o = softjoint(&["identify", "plan", "--probe", s(&dir.join("adapted.csv"))]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    let e = stderr(&o);
    assert!(
        e.contains("adapted.csv") && e.contains("cannot place the plan") && e.contains("column `"),
        "{e}"
    );
    // A probe recorded without the coil currents (`sim --no-electrical`,
    // a lab without a current sense) cannot place the plan: refused by
    // the column it lacks.
    let bare = dir.join("probe-bare.csv");
    record(&probe_plan, &bare, &["--no-electrical"]);
    let o = softjoint(&["identify", "plan", "--probe", s(&bare)]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    assert!(stdout(&o).is_empty(), "{}", stdout(&o));
    assert!(
        stderr(&o).contains("probe-bare.csv has no current column `i1_a`"),
        "{}",
        stderr(&o)
    );
    // The joint asked for must be the log's.
    let o = softjoint(&["identify", "plan", "--probe", s(&log), "--joint", "2d"]);
    assert!(
        !o.status.success() && stderr(&o).contains("--joint 2d but the probe log"),
        "{}",
        stderr(&o)
    );
}
