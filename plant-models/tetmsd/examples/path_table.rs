//! The link on every paper profile and on fixed paths of 10–200 ms with
//! 0–10 % loss and reordering, in virtual time: the table of
//! `plant_tetmsd::paths::full_table`, each row's measured round trip,
//! resends and committed lag against the path the emulators made, and
//! whether the replicas ended bit-identical. Exits non-zero, naming each
//! missed criterion, if any row misses one.
//!
//! `cargo run --release -p plant-tetmsd --example path_table -- [DURATION_S] [LEVEL] [SEED] [ONLY] [K]`
//! (default 10 s of session per row at level 3, seed 1; ONLY keeps the
//! rows whose label contains it, e.g. `rtt-200`, "" for all; K the copies
//! per input packet, default `link::DEFAULT_REDUNDANCY`).
use plant_tetmsd::link::DEFAULT_REDUNDANCY;
use plant_tetmsd::paths::{full_table, run_case_with, PathFigures};
use std::process::ExitCode;

fn arg<T: std::str::FromStr>(k: usize, name: &str, default: T) -> Result<T, String> {
    match std::env::args().nth(k) {
        None => Ok(default),
        Some(v) => v
            .parse()
            .map_err(|_| format!("{name}: cannot read {v:?} as a number")),
    }
}

fn main() -> ExitCode {
    let parsed = (|| {
        Ok::<_, String>((
            arg(1, "DURATION_S", 10.0f64)?,
            arg(2, "LEVEL", 3u32)?,
            arg(3, "SEED", 1u64)?,
            arg(5, "K", DEFAULT_REDUNDANCY)?,
        ))
    })();
    let (duration_s, level, seed, k) = match parsed {
        Ok(v) => v,
        Err(e) => {
            eprintln!("path_table: {e}");
            return ExitCode::from(2);
        }
    };
    let only = std::env::args().nth(4).unwrap_or_default();
    println!("{duration_s} s per row, level {level}, seed {seed}, K = {k} copies\n");
    println!("{}", PathFigures::header());
    let mut missed = Vec::new();
    for case in full_table()
        .into_iter()
        .filter(|c| c.label().contains(&only))
    {
        match run_case_with(case, level, duration_s, seed, k) {
            Ok(f) => {
                println!("{}", f.row());
                missed.extend(
                    f.failures()
                        .into_iter()
                        .map(|w| format!("{}: {w}", case.label())),
                );
            }
            Err(e) => missed.push(format!("{}: the run failed: {e}", case.label())),
        }
    }
    if missed.is_empty() {
        println!("\nevery row meets every criterion");
        ExitCode::SUCCESS
    } else {
        println!("\n{} criteria missed:", missed.len());
        for m in &missed {
            println!("- {m}");
        }
        ExitCode::FAILURE
    }
}
