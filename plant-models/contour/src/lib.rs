//! Periodic and closed smoothing spline contours and surfaces: Fujioka &
//! Kano, *Contour and Shape Modeling of Wet Material Objects using Periodic
//! and Closed Spline Surfaces* (seed 000, pp. 2–7; README in this folder).
//!
//! [`model`] is the mathematics: normalised uniform B-splines (Eq. 1–4) on
//! uniform knot axes, the Gramians of Eq. 18–19, the optimal smoothing
//! spline of Eq. 8 under the periodicity ties (Eq. 21–24) by the KKT system
//! of Eq. 27 (minimum-norm when singular) or by eliminating the ties and a
//! banded Cholesky, curves (periodic signatures, closed parametric curves)
//! and surfaces (periodic in one or both variables) with the area and
//! smoothness functionals of Eq. 40–41. [`identify`] fits them to data:
//! λ by generalised cross-validation, contours from tracked points, the
//! deforming contour over time with its centroid path, CSV input, and the
//! paper's studies (Eq. 38 and Theorem 1, the closed red-blood-cell
//! surface, held-out frames of a deforming-contour movie).
//!
//! What is modelled: cubic splines (k = 3, as the paper's fits) with
//! uniform knots, the Laplacian-squared roughness of Eq. 8, weights per
//! data point. Left out: other degrees in the fits, non-uniform knots, 3D
//! dynamic shapes (the paper's outlook), image processing (the signature is
//! computed from contour points, not from pixels).
//!
//! Units: whatever the data carry (px for tracked contours); spline
//! parameters run over `[0, m]` with knot spacing 1, as in the paper's §IV.
pub mod error;
pub mod identify;
pub mod model;

pub use error::{ContourError, Result};
pub use model::{basis, curve, fit, gramian, surface};
