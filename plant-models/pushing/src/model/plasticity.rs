//! Plastic deformation of the springs, Algorithm 2 of the seed (§VI-B).
//!
//! Each spring keeps a compression constant α; its rest length is
//! l0 = (1 − α)·D0. After each step, if the spring is compressed by more
//! than `yield` (elastic deformation (l0 − l)/D0), α grows by
//! creep × that deformation, capped at max α. Only compression is permanent
//! (the seed models permanent compression; stretching stays elastic).
//!
//! Line 2 of Algorithm 2 ("if α > max α then l0 ← l") can never fire once α
//! is capped at max α on line 11, so here the rest length is always
//! (1 − α)·D0.
use crate::forces::MaterialParams;

/// Updates α of one spring from its current length `l_px`; returns the new α.
#[inline]
pub fn update_alpha(alpha: f64, l_px: f64, d0_px: f64, p: &MaterialParams) -> f64 {
    let l0 = (1.0 - alpha) * d0_px;
    let elastic_deformation = (l0 - l_px) / d0_px;
    if elastic_deformation > p.yield_strain {
        (alpha + p.creep * elastic_deformation).min(p.max_alpha)
    } else {
        alpha
    }
}
