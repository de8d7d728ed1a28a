//! Issue 28's adaptive plan on its off-plan twin
//! (`identify::hidden::off_plan_joint_3d`, α's driver turning on at 2.0 V,
//! above the standard plan's levels): the probe recorded, analysed, the
//! plan adapted to what it found, that plan recorded and identified. It
//! prints what the probe found per coil and, per plane, the verdict and
//! every estimate's distance from the truth in its own 1σ.
//!
//! `cargo run --profile ci-opt -p plant-joint --example identify_probe -- [SECONDS] [SEED] [BUDGET]`
//! (default 240 s, seed 5: the tests' twin; ≈ 20–40 s of CPU). BUDGET 0
//! (default): the adapted plan keeps within the firmware's default
//! thermal budget (driver offset 1.7 V); 1: within a budget whose driver
//! offset is each coil's probed turn-on. PROBE_STANDARD=1 records the
//! standard plan instead, for comparison.
//! Exits 1 when a plane is unverified or a parameter called identifiable
//! lies more than 2σ from the truth, 2 on a bad argument or a failed run.
use plant_joint::identify::{
    self, hidden, probe, twin, ElectricalNoise, ExcitationPlan, IdentifyOptions,
};
use plant_joint::Joint3dParams;

/// The twin tests' electrical noise (2 mA, 0.02 Ω).
const NOISE: ElectricalNoise = ElectricalNoise {
    current_a: 0.002,
    resistance_ohm: 0.02,
};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parse = |i: usize, default: f64| -> f64 {
        args.get(i).map_or(default, |s| {
            s.parse().unwrap_or_else(|_| {
                eprintln!("argument {i}: not a number: {s}");
                std::process::exit(2)
            })
        })
    };
    let seconds = parse(1, 240.0);
    let seed = parse(2, 5.0) as u64;
    let from_probe = parse(3, 0.0) != 0.0;
    let fail = |e: &dyn std::fmt::Display| -> ! {
        eprintln!("{e}");
        std::process::exit(2)
    };
    let h = hidden::off_plan_joint_3d(seed);
    let probe_plan = ExcitationPlan::probe(2);
    let probe_log = twin::record_3d(&h, &probe_plan, true, NOISE).unwrap_or_else(|e| fail(&e));
    let found = probe::analyse(&probe_log).unwrap_or_else(|e| fail(&e));
    println!("probe ({} s):", probe_plan.duration_s);
    for c in &found.coils {
        println!(
            "  coil {}: turn-on {:?} V (bracket {:?}), motion from {:.2} V, anchor {:.2} V, top {:.1} V travel {:+.2}°, rise {:.2} s, fall {:?} s",
            c.coil, c.turn_on_v.map(|v| (v * 1000.0).round() / 1000.0), c.current_bracket_v, c.motion_from_v, c.anchor_v,
            c.top_v, c.top_travel_deg, c.rise_63_s, c.fall_37_s
        );
    }
    let plan = if std::env::var("PROBE_STANDARD").is_ok() {
        ExcitationPlan::standard(2, seconds, false)
    } else {
        ExcitationPlan::adapted(2, seconds, &found, from_probe)
    };
    println!("plan: {} ({} drives)", plan.name, plan.drive.len());
    let log = twin::record_3d(&h, &plan, true, NOISE).unwrap_or_else(|e| fail(&e));
    for p in 0..2 {
        let most = log.cam_deg.iter().map(|a| a[p].abs()).fold(0.0, f64::max);
        println!("plane {p}: largest camera angle in the log {most:.2}°");
    }
    let (_, reports) =
        identify::identify_3d(&log, &Joint3dParams::default(), &IdentifyOptions::default())
            .unwrap_or_else(|e| fail(&e));
    let mut bad = false;
    for (p, r) in reports.iter().enumerate() {
        let truth = hidden::plane_truth(&h, p);
        println!(
            "{}: {}; fit rms {:.3}°, held-out rms {:.3}°",
            r.plane,
            if r.verdict.verified {
                "verified".to_string()
            } else {
                format!("UNVERIFIED ({})", r.verdict.failures.join("; "))
            },
            r.validation.fit_rms_deg,
            r.validation.heldout_rms_deg
        );
        bad |= !r.verdict.verified;
        for e in &r.estimates {
            let t = e.param.get(&truth);
            let z = (e.fitted - t) / e.std;
            println!(
                "  {:34} fitted {:>12.5e} truth {:>12.5e} 1σ {:>10.3e} {:+6.2}σ{}",
                e.field,
                e.fitted,
                t,
                e.std,
                z,
                if e.identifiable {
                    String::new()
                } else {
                    format!(
                        "  (not identifiable: {})",
                        e.reason.as_deref().unwrap_or("")
                    )
                }
            );
            bad |= e.identifiable && z.abs() > 2.0;
        }
    }
    std::process::exit(i32::from(bad));
}
