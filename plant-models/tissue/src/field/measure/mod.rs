//! Measuring the field (Zhang §II, §III-B, §IV): Harris points, matching
//! with the strength of matches and the direction constraint, Horn's rigid
//! part, the pipeline on a pair, the comparison on a synthetic twin, and
//! the whole experiment of `softjoint tissue field` (variants, timing,
//! truth).
pub mod experiment;
pub mod harris;
pub mod horn;
pub mod matching;
pub mod pipeline;
pub mod twin;
