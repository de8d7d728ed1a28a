//! The library behind the `softjoint` program: scenarios, the closed-loop
//! simulation, wire-sensor calibration, reports, and the serial tools.

pub mod board;
pub mod calibrate;
pub mod excite;
pub mod hil;
pub mod input;
pub mod link;
pub mod output;
pub mod plant_file;
pub mod plot;
pub mod progress;
pub mod pty_board;
pub mod qemu;
pub mod report;
pub mod scenario;
pub mod sim;
pub mod stop;
pub mod tetmsd_rt;
pub mod trace;
pub mod tune;
pub mod visco_core;
