//! Periodic and closed smoothing spline contours and surfaces (Fujioka &
//! Kano, seed 000 pp. 2–7).
pub mod error;
pub mod identify;
pub mod model;

pub use error::{ContourError, Result};
pub use model::{basis, curve, fit, gramian, surface};
