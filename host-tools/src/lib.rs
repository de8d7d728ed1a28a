//! The library behind the `softjoint` program: scenarios, the closed-loop
//! simulation, wire-sensor calibration, reports, and the serial tools.

pub mod board;
pub mod calibrate;
pub mod hil;
pub mod link;
pub mod plot;
pub mod pty_board;
pub mod qemu;
pub mod report;
pub mod scenario;
pub mod sim;
pub mod tetmsd_rt;
pub mod visco_core;
