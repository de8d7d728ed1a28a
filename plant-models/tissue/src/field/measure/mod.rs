//! Measuring the field (Zhang §II, §III-B, §IV): Harris points, matching
//! with the strength of matches and the direction constraint, Horn's rigid
//! part, the pipeline on a pair, and the comparison on a synthetic twin.
pub mod harris;
pub mod horn;
pub mod matching;
pub mod pipeline;
pub mod twin;
