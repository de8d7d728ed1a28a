//! Deformable linear objects (seed 000): the dynamic knotting rope of Shi &
//! Payandeh (L1162–1594) in [`rope`], and the static differential-geometry
//! model of wires and belts of Wakamatsu et al. (L674–1161) in [`wire`].
//! [`topology`] (crossings of a projected curve, the knot determinant of
//! its closure) serves both: it tells a knotted rope or wire from an
//! unknotted one.
//!
//! Units: metres, newtons, kilograms, seconds, radians; names carry them.
pub mod error;
pub mod rope;
pub mod topology;
pub mod wire;

pub use error::{DloError, Result};
