//! Issue 28's seeded twin campaign: hidden 3D joints drawn from a stated
//! distribution, each recording the standard plan, each identified from
//! the defaults, each judged against its truth. It prints, per plane and
//! in all:
//! - the **coverage** of the reported 1σ: the share of the parameters
//!   called identifiable whose fit lies within 1σ and within 2σ of the
//!   truth (a calibrated 1σ gives ≈ 68 % and ≈ 95 %), over all planes and
//!   over the verified planes alone (the only ones whose 1σ reaches a
//!   plant file's `[[uncertainty]]`);
//! - the **share of twins where a wrong parameter is called identifiable**
//!   on a plane that says it is verified: a parameter identifiable,
//!   verified, more than 3σ from the truth (the goal is 0);
//! - the **verdicts**: planes verified and unverified, with the first
//!   reason of each unverified one.
//!
//! The distribution is `identify::hidden::campaign_joint_3d`'s (its doc
//! comment): per plane the driver's turn-on uniform in 1.5–2.1 V, g, h,
//! the sponge's modulus and damping × U(0.8, 1.2), the temperatures
//! shifted by U(±5) K, the slope U(0.03, 0.14) K/MPa; camera noise 0.05°,
//! the twins' current and resistance noise (2 mA, 0.02 Ω), jamming at the
//! defaults. Twins FIRST..FIRST + TWINS (default 0..20); the tests use
//! twins from 100 on, never the campaign's.
//!
//! `cargo run --release -p plant-joint --example identify_campaign -- [TWINS] [SECONDS] [FIRST] [Z.csv]`
//! (default 20 twins of the 240 s plan; ≈ 15–40 s of CPU per twin). With
//! `Z.csv` (a new file: an existing one is refused), every estimate
//! called identifiable is written there with its
//! signed distance from the truth in its own 1σ (what the 1σ's
//! calibration is measured from).
//! With `CAMPAIGN_JACOBIANS=differences` the mechanics stage differences
//! its Jacobians instead of taking them from replays carrying derivatives
//! (`IdentifyOptions::derivative_jacobians`, the default since session
//! 53).
//! With `CAMPAIGN_PLAN=adapted`, each twin records the probe first
//! (`ExcitationPlan::probe`) and then the plan adapted to what the probe
//! found (`ExcitationPlan::adapted`, the firmware's default budget), as
//! `identify probe` / `identify plan --probe` do (≈ 2× the CPU).
//! Exits 1 when a wrong parameter is called identifiable on a verified
//! plane, 2 on a bad argument or a failed identification.
use plant_joint::identify::{
    self, hidden, twin, ElectricalNoise, IdentifyOptions, PlaneModel, PlaneReport,
};
use plant_joint::Joint3dParams;

const NOISE: ElectricalNoise = ElectricalNoise {
    current_a: 0.002,
    resistance_ohm: 0.02,
};

/// Tallies over planes.
#[derive(Default)]
struct Tally {
    planes: usize,
    verified: usize,
    identifiable: usize,
    within_1: usize,
    within_2: usize,
    /// The same three counts over the verified planes only: the 1σ a
    /// user is given to trust (an unverified plane's are not).
    identifiable_verified: usize,
    within_1_verified: usize,
    within_2_verified: usize,
    wrong_called_identifiable: usize,
}

impl Tally {
    fn add(&mut self, r: &PlaneReport, truth: &PlaneModel) -> Vec<String> {
        self.planes += 1;
        self.verified += usize::from(r.verdict.verified);
        let mut wrong = Vec::new();
        for e in r.estimates.iter().filter(|e| e.identifiable && e.std > 0.0) {
            let z = (e.fitted - e.param.get(truth)).abs() / e.std;
            self.identifiable += 1;
            self.within_1 += usize::from(z <= 1.0);
            self.within_2 += usize::from(z <= 2.0);
            if r.verdict.verified {
                self.identifiable_verified += 1;
                self.within_1_verified += usize::from(z <= 1.0);
                self.within_2_verified += usize::from(z <= 2.0);
            }
            if z > 3.0 && e.verified && r.verdict.verified {
                wrong.push(format!(
                    "{} {:.1}σ ({} stage: fitted {:.5e}, truth {:.5e}, 1σ {:.3e}, white 1σ {:.3e})",
                    e.field,
                    z,
                    e.stage,
                    e.fitted,
                    e.param.get(truth),
                    e.std,
                    e.white_std
                ));
            }
        }
        self.wrong_called_identifiable += usize::from(!wrong.is_empty());
        wrong
    }

    fn row(&self, name: &str) -> String {
        let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
        format!(
            "| {name} | {} | {} | {:.0} % | {:.0} % | {:.0} % | {:.0} % | {} ({:.0} %) |",
            self.planes,
            self.verified,
            pct(self.within_1, self.identifiable),
            pct(self.within_2, self.identifiable),
            pct(self.within_1_verified, self.identifiable_verified),
            pct(self.within_2_verified, self.identifiable_verified),
            self.wrong_called_identifiable,
            pct(self.wrong_called_identifiable, self.planes)
        )
    }
}

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
    let twins = parse(1, 20.0) as u64;
    let seconds = parse(2, 240.0);
    let first = parse(3, 0.0) as u64;
    let adapted = std::env::var("CAMPAIGN_PLAN").is_ok_and(|v| v == "adapted");
    let opts = IdentifyOptions {
        derivative_jacobians: !std::env::var("CAMPAIGN_JACOBIANS")
            .is_ok_and(|v| v == "differences"),
        ..IdentifyOptions::default()
    };
    if adapted {
        println!("plan: each twin's probe recorded and analysed, the plan adapted to it");
    }
    // Opened before the campaign, as a new file only: nothing that already
    // exists (a user's file, a device, a FIFO, a link) is replaced, and a
    // refused path is said before the minutes of work, not after.
    let z_file = args.get(4).map(|path| {
        std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .unwrap_or_else(|e| {
                eprintln!("{path}: {e} (the σ-distances go to a new file only)");
                std::process::exit(2)
            })
    });
    let mut tallies = [Tally::default(), Tally::default()];
    let mut z_rows = String::from("twin,plane,field,stage,verified_plane,verified,z\n");
    for k in first..first + twins {
        let h = hidden::campaign_joint_3d(k);
        let (plan, refused) = twin::campaign_plan_3d(&h, seconds, NOISE, adapted);
        if let Some(e) = refused {
            println!("twin {k}: probe refused ({e}); the standard plan instead");
        }
        let run = twin::record_3d(&h, &plan, true, NOISE)
            .and_then(|log| identify::identify_3d(&log, &Joint3dParams::default(), &opts));
        let (_, reports) = run.unwrap_or_else(|e| {
            eprintln!("twin {k}: {e}");
            std::process::exit(2)
        });
        for (p, r) in reports.iter().enumerate() {
            let truth = hidden::plane_truth(&h, p);
            let wrong = tallies[p].add(r, &truth);
            for e in r.estimates.iter().filter(|e| e.identifiable && e.std > 0.0) {
                z_rows.push_str(&format!(
                    "{k},{},{},{},{},{},{:.4}\n",
                    r.plane,
                    e.field,
                    e.stage,
                    r.verdict.verified,
                    e.verified,
                    (e.fitted - e.param.get(&truth)) / e.std
                ));
            }
            println!(
                "twin {k} {}: turn-on {:.2} V, {}{}",
                r.plane,
                truth.plane.driver.turn_on_v,
                if r.verdict.verified {
                    "verified".to_string()
                } else {
                    format!("UNVERIFIED ({})", r.verdict.failures.join("; "))
                },
                if wrong.is_empty() {
                    String::new()
                } else {
                    format!("; WRONG but called identifiable: {}", wrong.join(", "))
                }
            );
        }
    }
    if let (Some(path), Some(mut f)) = (args.get(4), z_file) {
        use std::io::Write;
        if let Err(e) = f.write_all(z_rows.as_bytes()) {
            eprintln!("{path}: {e}");
            std::process::exit(2);
        }
    }
    println!("| plane | planes | verified | identifiable within 1σ | within 2σ | on verified planes within 1σ | within 2σ | planes with a wrong parameter called identifiable |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    println!("{}", tallies[0].row("alpha"));
    println!("{}", tallies[1].row("beta"));
    if tallies.iter().any(|t| t.wrong_called_identifiable > 0) {
        std::process::exit(1);
    }
}
