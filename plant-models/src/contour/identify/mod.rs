//! Fitting splines to data: λ by generalised cross-validation, contours
//! from tracked points (signatures about the centroid, parametric closed
//! curves), deforming contours over time, and the paper's test cases.
pub mod gcv;
pub mod tracked;
