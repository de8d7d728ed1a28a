//! The integration tests of `plant-tissue`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod compress;
mod field;
