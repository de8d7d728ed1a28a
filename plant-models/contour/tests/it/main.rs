//! The integration tests of `plant-contour`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod checks;
mod model;
mod paper;
