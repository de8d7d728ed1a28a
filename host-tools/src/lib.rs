//! The library behind the `softjoint` program: the file formats
//! ([`files`]), one run of the joint ([`run`]), a board as the controller
//! ([`board`]), the joint's calibration, excitation and tuning ([`joint`]),
//! and what every command shares: checked output ([`output`]), pictures
//! ([`plot`]), input parsing ([`input`]), progress bars ([`progress`]),
//! signals ([`stop`]), a stopped search's scores ([`resume`]) and sizes checked against memory ([`memory`]).
//! What the seed systems' commands do around their crates' calls, shared
//! with the Python package: the push prepared and its frame table
//! ([`push`]), a static solve's summary and checks ([`dlo_solve`]), a
//! viscoelastic trial's fit ([`visco_fit`]) and object run
//! ([`visco_object`]), and the contour test cases
//! ([`contour_synth`]).

pub mod board;
pub mod contour_synth;
pub mod dlo_solve;
pub mod files;
pub mod input;
pub mod joint;
pub mod memory;
pub mod output;
pub mod plot;
pub mod progress;
pub mod push;
pub mod ray;
pub mod resume;
pub mod run;
pub mod stop;
pub mod visco_core;
pub mod visco_fit;
pub mod visco_object;
