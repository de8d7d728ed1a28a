//! The twin experiment of plant-models/joint/README.md ("Identified
//! from a log"): a hidden joint (defaults moved 20–50 %, noise, jamming)
//! records the standard excitation; identification starts from the
//! defaults. `cargo run --release -p plant-joint --example identify_twin -- [SECONDS] [2d|3d] [noelec]`
use std::time::Instant;

use plant_joint::identify::{self, hidden, twin, ElectricalNoise, ExcitationPlan};
use plant_joint::{Joint2dParams, Joint3dParams};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let secs: f64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(240.0);
    let three = args.get(2).is_some_and(|s| s == "3d");
    let elec = !args.iter().any(|a| a == "noelec");
    let noise = ElectricalNoise {
        current_a: 0.002,
        resistance_ohm: 0.02,
    };
    let opts = identify::IdentifyOptions::default();
    let t0 = Instant::now();
    let (reports, n) = if three {
        let plan = ExcitationPlan::standard(2, secs, false);
        let log = twin::record_3d(&hidden::joint_3d(7), &plan, elec, noise)?;
        eprintln!(
            "recorded {} rows in {:.1} s",
            log.len(),
            t0.elapsed().as_secs_f64()
        );
        let t1 = Instant::now();
        let (_, r) = identify::identify_3d(&log, &Joint3dParams::default(), &opts)?;
        eprintln!("identified in {:.1} s", t1.elapsed().as_secs_f64());
        (r, log.len())
    } else {
        let plan = ExcitationPlan::standard(1, secs, false);
        let log = twin::record_2d(&hidden::joint_2d(7), &plan, elec, noise)?;
        eprintln!(
            "recorded {} rows in {:.1} s",
            log.len(),
            t0.elapsed().as_secs_f64()
        );
        let t1 = Instant::now();
        let (_, r) = identify::identify_2d(&log, &Joint2dParams::default(), &opts)?;
        eprintln!("identified in {:.1} s", t1.elapsed().as_secs_f64());
        (r, log.len())
    };
    let truth3 = hidden::joint_3d(7);
    for (p, r) in reports.iter().enumerate() {
        let mut truth = identify::PlaneModel {
            plane: if p == 0 {
                truth3.alpha.clone()
            } else {
                truth3.beta.clone()
            },
            wires: vec![truth3.wires[p].clone()],
            settle_s: 1.0,
            substep_s: 1e-3,
        };
        if !three {
            let t2 = hidden::joint_2d(7);
            truth.plane = t2.plane;
            truth.wires = vec![t2.wire];
        }
        println!("plane {} ({n} rows)", r.plane);
        for e in &r.estimates {
            let tv = e.param.get(&truth);
            println!(
                "  {:32} {:>12.5} ± {:<10.3e} true {:>12.5} prior {:>12.5} err {:>7.1} % {} [{}]",
                e.field,
                e.value,
                e.std,
                tv,
                e.prior,
                100.0 * (e.value - tv) / tv,
                if e.identifiable {
                    ""
                } else {
                    "NOT IDENTIFIABLE"
                },
                e.stage
            );
        }
        for s in &r.stages {
            println!(
                "  stage {}: {} it, {} evals, {} residuals, rms {:.3}",
                s.name, s.iterations, s.evaluations, s.residuals, s.rms_scaled
            );
        }
        let v = &r.validation;
        println!(
            "  fit rms {:.3}°, held-out rms {:.3}° max {:.3}° (prior {:?})",
            v.fit_rms_deg, v.heldout_rms_deg, v.heldout_max_deg, v.prior_heldout_rms_deg
        );
    }
    Ok(())
}
