//! Absurd physical values (issue 31, item 5): each is refused by the file,
//! line and column that hold it, with the range a real probe, trial or
//! joint has, before any work — never run to `inf`/`NaN` results or a
//! riddle about a fitted parameter.
use crate::common;

use common::{file, refused, s, scratch, softjoint};

/// A probe force of 1e300 N in `viscoelastic object --script` ran, exit
/// 0, printing `|Δu| inf m (NaN %…)`.
#[test]
fn a_probe_force_no_probe_can_make_is_refused_by_line() {
    let dir = scratch("absurd-probe");
    let script = file(
        &dir,
        "script.csv",
        "time_s,vertex,fx_n,fy_n,fz_n\n0,0,0,0,-1\n0.2,0,0,0,-1e300\n0.4,-1,0,0,0\n",
    );
    let out = dir.join("out");
    refused(
        &[
            "viscoelastic",
            "object",
            "--script",
            &script,
            "--out-dir",
            s(&out),
        ],
        &[&format!("{script}:3"), "fz_n", "beyond any probe's force"],
    );
    assert!(!out.exists(), "output written for a refused script");
}

/// A trial whose forces are ×1e160 gave "invalid parameter `k1` = inf";
/// now the line is named. Displacements in the wrong unit (1e-300 m: a
/// stiffness no soft material has) name the cause instead of a fitted
/// `inf`.
#[test]
fn trial_forces_that_would_fit_an_infinite_stiffness_are_named() {
    let dir = scratch("absurd-trial");
    let trial = |scale_f: f64, step_m: f64| {
        let mut t = String::from("time_s,displacement,force\n");
        for i in 0..100 {
            let ts = f64::from(i) * 0.01;
            let (d, f) = if ts > 0.1 {
                (step_m, scale_f * (0.5 + (-(ts - 0.1) / 0.3).exp()))
            } else {
                (0.0, 0.0)
            };
            t.push_str(&format!("{ts},{d:e},{f:e}\n"));
        }
        t
    };
    let big = file(&dir, "big.csv", &trial(1e160, 1e-3));
    // Row 12 (t = 0.11 s, line 13) is the first with a force.
    refused(
        &["viscoelastic", "fit", &big],
        &[
            &format!("{big}:13"),
            "column `force`",
            "beyond a soft material's trial",
        ],
    );
    let tiny = file(&dir, "tiny.csv", &trial(1.0, 1e-300));
    let err = refused(
        &["viscoelastic", "fit", &tiny],
        &[&tiny, "stiffness of", "beyond any soft material"],
    );
    assert!(!err.contains("= inf"), "{err}");
    // A trial in range still fits.
    let fine = file(&dir, "fine.csv", &trial(1.0, 1e-3));
    common::ok(&softjoint(&["viscoelastic", "fit", &fine]));
}

/// One outlier in an `identify joint` log (a camera angle of 1e30°) was
/// reported as "NOT IDENTIFIABLE" without naming the line.
#[test]
fn an_outlier_in_an_identification_log_is_refused_by_line() {
    let dir = scratch("absurd-log");
    let scen = file(&dir, "s.toml", crate::excite_stops::SCENARIO_2D);
    let plan = file(
        &dir,
        "plan.toml",
        "name = \"short\"\nduration_s = 3\n[[drive]]\ncoil = 1\nfrom_s = 0\nto_s = 1\nvolts = 2.0\n",
    );
    let log = dir.join("log.csv");
    common::ok(&softjoint(&[
        "sim",
        &scen,
        "--excite",
        &plan,
        "--log",
        s(&log),
    ]));
    let text = std::fs::read_to_string(&log).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let cam = header.iter().position(|c| *c == "cam_theta_deg").unwrap();
    let d1 = header.iter().position(|c| *c == "d1_mm").unwrap();
    for (col, value, needle) in [
        (cam, "1e30", "beyond any bend of the joint"),
        (d1, "-4e5", "beyond a wire's insertion"),
    ] {
        // Line 101: row 99 (t = 0.99 s).
        let bad: String = text
            .lines()
            .enumerate()
            .map(|(k, l)| {
                if k == 100 {
                    let mut cells: Vec<&str> = l.split(',').collect();
                    cells[col] = value;
                    cells.join(",") + "\n"
                } else {
                    format!("{l}\n")
                }
            })
            .collect();
        let p = file(&dir, "bad.csv", &bad);
        let out = dir.join("p.toml");
        refused(
            &["identify", "joint", &p, "-o", s(&out)],
            &[&format!("{p}:101"), header[col], needle],
        );
        assert!(!out.exists());
    }
}
