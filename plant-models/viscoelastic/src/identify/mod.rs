//! Measuring the object and identifying its parameters (seed 002 §4): the
//! probe simulator that generates ground truth from the plant, the per-trial
//! Nelder–Mead fits and the per-vertex estimation.
pub mod estimate;
pub mod fit;
pub mod measure;
