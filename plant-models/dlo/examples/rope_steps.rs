//! Steps the Table I rope (N = 50) a given number of times, for counting
//! instructions per step with callgrind (issue 34): the count of a run of
//! 2K steps minus that of K steps is K steps without the set-up.
//!
//! `cargo run --release -p plant-dlo --example rope_steps -- hanging|knotted STEPS`
//!
//! * `hanging`: straight, pinned at its top point, released at rest length
//!   (no self-contact, no desk; the benchmark `rope_step_n50/hanging`).
//! * `knotted`: the overhand scenario (scenarios/dlo/overhand.toml) run to
//!   20 s, then stepped on the desk from that state with its top pinned
//!   (the benchmark `rope_step_n50/knotted_with_contacts`).
//!
//! Prints the steps taken, the self-contacts found over them and the last
//! point's position, so that two builds can be compared at a glance.
//! Exit 2 for a bad argument.
use plant_dlo::rope::script::RopeScenario;
use plant_dlo::rope::{Desk, Rope, RopeParams, V3};
use std::process::ExitCode;

const OVERHAND: &str = include_str!("../../../scenarios/dlo/overhand.toml");

fn rope(kind: &str) -> Option<Rope> {
    match kind {
        "hanging" => {
            let mut r =
                Rope::straight(RopeParams::default(), V3::new(0.0, 0.0, 10.0), -V3::z()).ok()?;
            r.pin(0).ok()?;
            Some(r)
        }
        "knotted" => {
            let scenario: RopeScenario = toml::from_str(OVERHAND).ok()?;
            let short = RopeScenario {
                duration_s: 20.0,
                ..scenario.clone()
            };
            let run = short.run(|_| {}).ok()?;
            let mut r = Rope::from_points(scenario.rope, run.frames.last()?.x.clone()).ok()?;
            r.pin(0).ok()?;
            r.desk = Some(Desk { height_m: 0.0 });
            Some(r)
        }
        _ => None,
    }
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let steps = args.get(1).and_then(|a| a.parse::<u64>().ok());
    let (Some(mut rope), Some(steps)) = (args.first().and_then(|k| rope(k)), steps) else {
        eprintln!("usage: rope_steps hanging|knotted STEPS (STEPS a whole number)");
        return ExitCode::from(2);
    };
    let mut contacts = 0;
    for _ in 0..steps {
        if let Err(e) = rope.step() {
            eprintln!("rope_steps: {e}");
            return ExitCode::FAILURE;
        }
        contacts += rope.stats.contacts;
    }
    let last = rope.x[rope.len() - 1];
    println!(
        "{steps} steps, {contacts} self-contacts, last point {:.17e} {:.17e} {:.17e}",
        last.x, last.y, last.z
    );
    ExitCode::SUCCESS
}
