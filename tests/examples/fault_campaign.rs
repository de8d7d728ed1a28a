//! The long forms of the lockstep link's fault campaign
//! (`integration_tests::fault_campaign`): 1,000,000 lockstep steps against
//! a board with faults on 0.2 % of the frames in both directions and a
//! board reset half-way, every step checked against the fault-free loop
//! with the core in process, every corrupting fault against the decoders'
//! counters.
//!
//! ```sh
//! cargo run --release -p integration-tests --example fault_campaign -- pty|qemu [STEPS] [RATE]
//! ```
//!
//! `pty`: the pty board (the firmware's board application in a thread),
//! seed 3; `qemu`: the thumbv7em image under QEMU (mps2-an386; build it
//! first, see scripts/test-all.sh), seed 4. `STEPS` default 1,000,000,
//! `RATE` (the share of frames faulted) 0.002; the tests run the short
//! forms (pty 100,000 steps, QEMU 5,000). Prints the table of injected
//! faults and the counters; a property that does not hold panics with its
//! name (exit 101).
use integration_tests::fault_campaign::{pty_campaign, qemu_campaign};

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: fault_campaign pty|qemu [STEPS] [RATE]";
    let steps: u64 = match args.get(1) {
        Some(s) => s
            .parse()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| format!("STEPS must be a whole number ≥ 1, got `{s}`; {usage}"))?,
        None => 1_000_000,
    };
    let rate: f64 = match args.get(2) {
        Some(r) => r
            .parse()
            .ok()
            .filter(|r| (0.0..1.0).contains(r))
            .ok_or_else(|| format!("RATE must be a share in [0, 1), got `{r}`; {usage}"))?,
        None => 0.002,
    };
    match args.first().map(String::as_str) {
        Some("pty") => pty_campaign(steps, 3, rate),
        Some("qemu") => qemu_campaign(steps, 4, rate),
        Some(other) => return Err(format!("unknown board `{other}`; {usage}")),
        None => return Err(usage.into()),
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("fault_campaign: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
