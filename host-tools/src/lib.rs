//! The library behind the `softjoint` program: the file formats
//! ([`files`]), one run of the joint ([`run`]), a board as the controller
//! ([`board`]), the joint's calibration, excitation and tuning ([`joint`]),
//! and what every command shares: checked output ([`output`]), pictures
//! ([`plot`]), input parsing ([`input`]), progress bars ([`progress`]),
//! signals ([`stop`]), a stopped search's scores ([`resume`]) and sizes checked against memory ([`memory`]).

pub mod board;
pub mod files;
pub mod input;
pub mod joint;
pub mod memory;
pub mod output;
pub mod plot;
pub mod progress;
pub mod resume;
pub mod run;
pub mod stop;
pub mod visco_core;
