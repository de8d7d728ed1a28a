//! Fault campaign for the lockstep link: the closed loop of `softjoint hil`
//! (plant ⇄ `BoardController` over the protocol) against a board — the pty
//! board (the firmware's board application in a thread) or the firmware
//! image under QEMU — with faults injected on the wire in both directions
//! at a seeded rate (dropped, duplicated, delayed, bit-flipped, truncated,
//! garbage frames, noise bursts; `integration_tests::fault_injector`) and a
//! board reset in the middle.
//!
//! What must hold:
//! - **every plant step ran exactly once with the board's answer for that
//!   step**: the run's true angles, coil voltages and fault bits equal, at
//!   every step, those of the same closed loop with the firmware core in
//!   process and no faults (its core restarted at the reset step, as the
//!   board was). The scenario has integral action (ki > 0) and targets
//!   that keep moving, so a step run twice or skipped shows in the
//!   integrator and the trajectory;
//! - **no fault passed undetected**: every corrupting fault is counted by
//!   the receiving decoder (board or host) — exactly one error each — and
//!   the reset is detected (one restart);
//! - **the counters add up**: the board's and host's frame and error
//!   counters equal those of a reference decoder fed with exactly the bytes
//!   the injector delivered, and no step is lost.
//!
//! These are the short forms (pty board 100,000 steps; QEMU 5,000 steps in
//! the QEMU stage of scripts/test-all.sh); the campaign itself lives in
//! `integration_tests::fault_campaign`. The long forms (1,000,000 steps
//! each) are the example `fault_campaign`:
//! `cargo run --release -p integration-tests --example fault_campaign -- pty`
//! (or `qemu`; figures in docs/experiments.md).
use integration_tests::fault_campaign::{pty_campaign, qemu_campaign};

#[test]
fn fault_campaign_pty_board_100k_steps() {
    // 0.2 % of the frames: ≈ 200 faults each way, ≈ 45 s on a loaded
    // 2-core machine (a lost frame costs its 20 ms timeout).
    pty_campaign(100_000, 1, 0.002);
}

#[test]
#[ignore = "needs qemu-system-arm and the thumbv7em image; run by scripts/test-all.sh"]
fn fault_campaign_qemu_5k_steps() {
    // QEMU steps are ≈ 10× slower: fewer steps, 2 % of the frames (≈ 100
    // faults each way, every kind ≥ 14 times).
    qemu_campaign(5_000, 2, 0.02);
}
