//! The integration tests of `plant-viscoelastic`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod dgfm;
mod estimate;
