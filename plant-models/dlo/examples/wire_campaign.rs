//! The randomised campaign of clamped wires against the elastica (issue
//! 29), full form: `cargo run --release -p plant-dlo --example
//! wire_campaign -- [CASES] [SEED] [--only I,J,...]` (default 500 cases,
//! seed 29; `--only` runs just the listed case indices of that seed).
//!
//! Each case is a random wire (tests/it/campaign.rs says which ranges)
//! solved as `softjoint dlo solve` solves a file and compared with the
//! closed-form elastica (tests/it/elastica_ref.rs). Prints every case that
//! is not solved, then the share of wrong answers reported as converged and
//! the share of cases solved. Exit 0 when no wrong answer is called
//! converged and at least 99 % are solved; 1 otherwise; 2 for a bad
//! argument. CI runs the short form (`campaign::` in the test binary).
#[path = "../tests/it/campaign.rs"]
mod campaign;
#[path = "../tests/it/elastica_ref.rs"]
mod elastica_ref;
#[path = "../tests/it/splitmix.rs"]
mod splitmix;

use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    // `--only 17,203`: just these case indices (of the same seed).
    let mut only: Option<Vec<u64>> = None;
    if let Some(k) = args.iter().position(|a| a == "--only") {
        let list = args.get(k + 1).map(|v| {
            v.split(',')
                .map(|i| i.trim().parse::<u64>())
                .collect::<Result<Vec<_>, _>>()
        });
        let Some(Ok(list)) = list else {
            eprintln!("--only takes case indices separated by commas, e.g. --only 17,203");
            return ExitCode::from(2);
        };
        only = Some(list);
        args.drain(k..k + 2);
    }
    let parse = |k: usize, default: u64| -> Option<u64> {
        args.get(k).map_or(Some(default), |a| a.parse().ok())
    };
    let (Some(cases), Some(seed)) = (parse(0, 500), parse(1, 29)) else {
        eprintln!("usage: wire_campaign [CASES] [SEED] [--only I,J,...] (whole numbers)");
        return ExitCode::from(2);
    };
    let indices: Vec<u64> = only.unwrap_or_else(|| (0..cases).collect());
    let cases = indices.len() as u64;
    let started = std::time::Instant::now();
    let (mut solved, mut wrong_converged, mut unverified) = (0u64, 0u64, 0u64);
    for (n, &i) in indices.iter().enumerate() {
        if n % 10 == 0 {
            eprintln!("{n} of {cases} cases: {solved} solved, {wrong_converged} wrong and called converged");
        }
        let c = campaign::case(seed, i);
        let o = campaign::run(&c);
        if o.right && o.verified {
            solved += 1;
        } else {
            if o.verified {
                wrong_converged += 1;
            } else {
                unverified += 1;
            }
            println!(
                "case {i}: {c:?} -> right {}, verified {}, energy {:.1e} off, mid deflection {:.1e} L off, fails {:?}, elastica k = {:.3}",
                o.right, o.verified, o.energy_error, o.deflection_error, o.failures, o.modulus_k
            );
        }
    }
    let share = |k: u64| 100.0 * k as f64 / cases.max(1) as f64;
    println!(
        "{cases} cases (seed {seed}, {:.0} s): solved {solved} ({:.1} %), wrong answers called converged {wrong_converged} ({:.1} %), reported unverified {unverified} ({:.1} %)",
        started.elapsed().as_secs_f64(),
        share(solved),
        share(wrong_converged),
        share(unverified)
    );
    if wrong_converged == 0 && share(solved) >= 99.0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
