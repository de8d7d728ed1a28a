//! The integration tests of `plant-joint`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod compliance;
mod identify;
mod integration;
mod wire;
