//! Fitting splines to data: λ by generalised cross-validation, contours
//! from tracked points (signatures about the centroid, parametric closed
//! curves), deforming contours over time, distances between contours, and
//! the paper's test cases (Eq. 38, Theorem 1, the closed surface, a
//! deforming-contour movie with held-out frames). [`contours`] fits a data
//! file's frames and [`synth`] writes the test cases as data, as
//! `softjoint contour` does.
pub mod campaign;
pub mod checks;
mod circle;
pub mod contours;
pub mod data;
pub mod distance;
pub mod gcv;
pub mod movie;
pub mod paper;
pub mod synth;
pub mod tracked;
