//! Measuring and identifying the block: the reference (ground truth) that
//! stands in for the paper's recordings, the objective S, and the paper's
//! randomized and genetic searches; the command line's experiments as calls
//! that return reports ([`experiment`]).
pub mod calibrate;
pub mod experiment;
pub mod ga;
pub mod measurement;
pub mod objective;
pub mod ra;
pub mod reference;
pub mod search;
