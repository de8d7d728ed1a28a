//! The integration tests of `plant-rheology`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod calibration;
mod model;
mod plate;
mod stiffness;
mod volume;
