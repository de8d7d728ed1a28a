//! The integration tests of `plant-pushing`, one binary (each file under tests/
//! would otherwise be a binary of its own to link).
mod acceptance;
mod contour_score;
mod model;
mod scoring;
