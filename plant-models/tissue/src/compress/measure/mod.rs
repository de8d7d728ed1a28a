//! The phantom experiment on the twin: markers through both models, the
//! paper's observations and the geometric model's error.
pub mod compare;
