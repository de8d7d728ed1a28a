//! The randomised campaign of hanging ropes against the closed form of
//! the discrete chain (issue 29), full form: `cargo run --profile ci-opt
//! -p plant-dlo --example rope_campaign -- [CASES] [SEED] [--table-step]`
//! (default 300 cases, seed 29; `--table-step`: Table I's 1 ms for every
//! case instead of a step from the axial stability limit).
//!
//! Each case is a random rope (tests/it/rope_campaign.rs says which
//! ranges) relaxed to rest as a `softjoint dlo rope` scenario with every
//! check, the time-step one included. Prints every case that is not
//! solved, then the counts: solved (right and verified), wrong answers
//! called verified (with all checks, and without the time-step check) and
//! reported unverified. Exit 0 when no wrong answer is called verified; 1
//! otherwise; 2 for a bad argument. CI runs the short form
//! (`rope_campaign::` in the test binary).
#[path = "../tests/it/rope_campaign.rs"]
mod rope_campaign;
#[path = "../tests/it/splitmix.rs"]
mod splitmix;

use std::process::ExitCode;

fn main() -> ExitCode {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let table_step = args.iter().any(|a| a == "--table-step");
    args.retain(|a| a != "--table-step");
    let parse = |k: usize, default: u64| -> Option<u64> {
        args.get(k).map_or(Some(default), |a| a.parse().ok())
    };
    let (Some(cases), Some(seed)) = (parse(0, 300), parse(1, 29)) else {
        eprintln!("usage: rope_campaign [CASES] [SEED] [--table-step] (whole numbers)");
        return ExitCode::from(2);
    };
    let started = std::time::Instant::now();
    let (mut solved, mut wrong_verified, mut wrong_verified_without_step) = (0u64, 0u64, 0u64);
    let (mut unverified, mut unverified_right) = (0u64, 0u64);
    let mut failed: std::collections::BTreeMap<&'static str, u64> = Default::default();
    for i in 0..cases {
        if i % 20 == 0 {
            eprintln!(
                "{i} of {cases} cases: {solved} solved, {wrong_verified} wrong and called verified"
            );
        }
        let c = rope_campaign::case(seed, i);
        let o = rope_campaign::run(&c, table_step);
        wrong_verified_without_step += u64::from(!o.right && o.verified_without_step);
        if o.right && o.verified {
            solved += 1;
            continue;
        }
        if o.verified {
            wrong_verified += 1;
        } else {
            unverified += 1;
            unverified_right += u64::from(o.right);
            for f in &o.failures {
                *failed.entry(f).or_default() += 1;
            }
        }
        println!(
            "case {i}: {c:?} -> stretch {:.6e} m, closed form {:.6e} m ({:.1e} off), verified {}, fails {:?}, rest force {:.1e} of its tolerance",
            o.stretch_m, o.closed_form_m, o.relative_error, o.verified, o.failures, o.rest_ratio
        );
    }
    let share = |k: u64| 100.0 * k as f64 / cases.max(1) as f64;
    println!(
        "{cases} cases (seed {seed}, {} step, {:.0} s): solved {solved} ({:.1} %), wrong answers called verified {wrong_verified} ({:.1} %; {wrong_verified_without_step} without the time-step check), reported unverified {unverified} ({:.1} %; {unverified_right} of them right), failed checks {failed:?}",
        if table_step { "Table I's 1 ms" } else { "stability-limited" },
        started.elapsed().as_secs_f64(),
        share(solved),
        share(wrong_verified),
        share(unverified)
    );
    if wrong_verified == 0 {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    }
}
