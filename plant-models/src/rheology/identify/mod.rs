//! Measuring and identifying the block: the reference (ground truth) that
//! stands in for the paper's recordings, the objective S, and the paper's
//! randomized and genetic searches.
