//! Measuring and identifying the block: the reference (ground truth) that
//! stands in for the paper's recordings, the objective S, and the paper's
//! randomized and genetic searches.
pub mod measurement;
pub mod reference;
pub mod objective;
pub mod search;
pub mod ga;
pub mod ra;
pub mod calibrate;
