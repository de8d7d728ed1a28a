//! The integration tests of `integration-tests`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod closed_loop_camera;
mod closed_loop_determinism;
mod closed_loop_faults;
mod closed_loop_wire;
mod common;
mod fault_campaign;
mod layout;
mod link_failures;
mod protocol_pty;
mod qemu_conform;
mod qemu_hil;
mod qemu_tuned_gains;
mod visco_core_vs_plant;
