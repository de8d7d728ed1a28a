//! Floating-point abstraction shared by the numeric parts of the core.
//!
//! The board runs the control step in `f32` (the Cortex-M4F has a
//! single-precision FPU); the host reuses the same viscoelastic update in
//! `f64`, where the seed's static-limit requirement is checked to 1e-9.
//! Math functions come from `libm` through `num-traits`, so nothing here
//! needs std.

use num_traits::Float;

/// A float type the core can compute with: `f32` or `f64`.
pub trait Real: Float + core::fmt::Debug + Default + Send + Sync + 'static {
    /// Converts an `f64` literal (constants, tolerances) to `Self`.
    fn lit(x: f64) -> Self;
}

impl Real for f32 {
    #[inline]
    fn lit(x: f64) -> Self {
        x as f32
    }
}

impl Real for f64 {
    #[inline]
    fn lit(x: f64) -> Self {
        x
    }
}
