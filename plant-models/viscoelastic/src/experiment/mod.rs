//! The experiments `softjoint viscoelastic` runs, as library calls that
//! return their results: the 3-element model on a user's table and the
//! checked fit of one trial ([`trial`]), and the measured-object pipeline
//! of seed §4–5 ([`pipeline`]). They compose [`crate::model`] and
//! [`crate::identify`]; files, flags and pictures stay with the caller.
pub mod pipeline;
pub mod trial;
