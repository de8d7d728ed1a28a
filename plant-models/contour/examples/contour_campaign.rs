//! The self-check campaign of issue 29 in full: random noisy closed
//! contours with known truth (`plant_contour::identify::campaign`), each
//! fitted with λ by GCV as `softjoint contour fit` fits it, and the answer
//! compared with the truth. Prints the counts, every unverified or wrong
//! case (with the gap check's bound, the old chord cap beside it, and the
//! true cap of its largest gap), the share of solvable cases solved
//! (`Outcome::solvable`), and exits 1 when any answer reported `verified` is more than 5 %
//! off in area or perimeter (the campaign's claim is that none is).
//!
//! `cargo run --release -p plant-contour --example contour_campaign -- [CASES] [SEED]`
//! (default 500 cases, seed 29). CI runs the short form (the first 40
//! cases of seed 29) as the test `campaign::`.
use plant_contour::identify::campaign::{run, TOLERANCE};

fn main() -> std::process::ExitCode {
    let mut args = std::env::args().skip(1);
    let parse = |a: Option<String>, default: u64| -> Option<u64> {
        match a {
            None => Some(default),
            Some(s) => s.parse().ok(),
        }
    };
    let (Some(cases), Some(seed)) = (parse(args.next(), 500), parse(args.next(), 29)) else {
        eprintln!("usage: contour_campaign [CASES] [SEED] (whole numbers)");
        return std::process::ExitCode::from(2);
    };
    let (summary, outcomes) = run(seed, cases as usize);
    for o in &outcomes {
        if o.verified && !o.wrong() {
            continue;
        }
        let err = |e: Option<f64>| e.map_or("—".to_string(), |v| format!("{:+.2} %", 100.0 * v));
        println!(
            "case {:3}: {:?}, {} points{}, σ/R = {:.3}: area {}, perimeter {} (halves {:?}, area/data polygon {:?}, gap bound local/global {:?}, true cap {:.2} %{}) — {}",
            o.case.index,
            o.case.model,
            o.case.points,
            if o.case.random_angles { " (random angles)" } else { "" },
            o.case.sigma / o.case.shape.size(),
            err(o.area_error),
            err(o.perimeter_error),
            o.half_spreads,
            o.area_over_data,
            o.gap_bounds,
            100.0 * o.truth_cap,
            if o.solvable() { "" } else { ", not solvable" },
            if o.wrong() {
                "WRONG (verified)".to_string()
            } else if let Some(r) = &o.refused {
                format!("refused: {r}")
            } else {
                format!("unverified: {:?}", o.flags)
            }
        );
    }
    let pct = |k: usize| 100.0 * k as f64 / summary.cases.max(1) as f64;
    println!(
        "{} cases (seed {seed}): solved (verified, within {:.0} %) {} = {:.1} %; wrong answers reported verified {} = {:.1} %; unverified {} ({} of them within tolerance); refused {}; worst verified error {:.2} %",
        summary.cases,
        100.0 * TOLERANCE,
        summary.solved,
        pct(summary.solved),
        summary.wrong,
        pct(summary.wrong),
        summary.unverified,
        summary.unverified_but_right,
        summary.refused,
        100.0 * summary.worst_verified_error
    );
    println!(
        "solvable (no gap holds more than {:.0} % of the true area outside the polygon through the noise-free points): {} of {}; solved {} = {:.1} % of them",
        100.0 * TOLERANCE,
        summary.solvable,
        summary.cases,
        summary.solvable_solved,
        100.0 * summary.solvable_solved as f64 / summary.solvable.max(1) as f64
    );
    // What the gap check does on its own: the answers it alone keeps
    // unverified, wrong and right.
    let only_gap = |o: &&plant_contour::identify::campaign::Outcome| {
        o.flags == [plant_contour::identify::checks::Flag::DataGap]
    };
    println!(
        "flagged by the gap check alone: {} wrong, {} right",
        outcomes
            .iter()
            .filter(only_gap)
            .filter(|o| !o.right())
            .count(),
        outcomes
            .iter()
            .filter(only_gap)
            .filter(|o| o.right())
            .count()
    );
    if summary.wrong == 0 {
        std::process::ExitCode::SUCCESS
    } else {
        std::process::ExitCode::FAILURE
    }
}
