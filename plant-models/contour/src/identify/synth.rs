//! The paper's test cases as data (`softjoint contour synth`): the
//! red-blood-cell surface of Eq. 38 sampled on an N × N grid with noise,
//! with its true contours; and the pulsating, translating contour movie
//! observed as a tracker would (centroid and radii along rays), every k-th
//! frame, with its true contour at every frame.
//!
//! The noise comes from the seeded stream `CONTOUR_SYNTH_NOISE`, so a seed
//! gives the same data on every machine.
use plant_common::rng;

use crate::error::Result;
use crate::identify::movie::{PulsatingContour, TRUTH_POINTS};
use crate::identify::paper::{self, rbc_surface, DOMAIN};
use crate::identify::tracked::{Point, Signature};

/// Points of each true contour of the red-blood-cell case.
pub const RBC_TRUTH_POINTS: usize = 200;

/// One frame of the red-blood-cell case: frame i at s = 10 i/(N − 1).
#[derive(Debug, Clone, PartialEq)]
pub struct RbcFrame {
    /// The surface's time-like variable s.
    pub s: f64,
    /// The noisy data: (θ, radius) at θ(t_j), t_j = 10 j/N.
    pub data: Vec<(f64, f64)>,
    /// The true contour f(s, ·) in polar form (Eq. 39): (θ, radius) at
    /// [`RBC_TRUTH_POINTS`] values of t.
    pub truth: Vec<(f64, f64)>,
}

/// Eq. 38 on an `n` × `n` grid of (s, t) with Gaussian noise of `sigma`.
pub fn rbc_case(n: usize, sigma: f64, seed: u64) -> Vec<RbcFrame> {
    let mut noise = rng::stream(seed, rng::CONTOUR_SYNTH_NOISE);
    paper::rbc_frames(n, sigma, &mut noise)
        .into_iter()
        .map(|(s, data)| RbcFrame {
            s,
            data,
            truth: (0..RBC_TRUTH_POINTS)
                .map(|j| {
                    let t = DOMAIN * j as f64 / RBC_TRUTH_POINTS as f64;
                    (paper::theta(t), rbc_surface(s, t))
                })
                .collect(),
        })
        .collect()
}

/// One frame of the movie case.
#[derive(Debug, Clone, PartialEq)]
pub struct MovieFrame {
    pub frame: usize,
    /// The true contour, [`TRUTH_POINTS`]/4 points.
    pub truth: Vec<Point>,
    /// What the tracker saw (kept frames only).
    pub observed: Option<Signature>,
}

/// The movie case: the default pulsating contour at every frame, observed
/// along `angles` rays with noise of `sigma_px` at every `every`-th frame.
#[derive(Debug, Clone, PartialEq)]
pub struct MovieCase {
    pub movie: PulsatingContour,
    pub frames: Vec<MovieFrame>,
}

impl MovieCase {
    /// Frames the tracker observed.
    pub fn kept(&self) -> usize {
        self.frames.iter().filter(|f| f.observed.is_some()).count()
    }
}

/// The movie observed every `every`-th frame (`every` ≥ 1).
pub fn movie_case(every: usize, angles: usize, sigma_px: f64, seed: u64) -> Result<MovieCase> {
    let mut noise = rng::stream(seed, rng::CONTOUR_SYNTH_NOISE);
    let movie = PulsatingContour::default();
    let mut frames = Vec::with_capacity(movie.frames);
    for f in 0..movie.frames {
        let observed = if f % every.max(1) == 0 {
            Some(movie.observe(f, angles, sigma_px, &mut noise)?)
        } else {
            None
        };
        frames.push(MovieFrame {
            frame: f,
            truth: movie.contour(f as f64, TRUTH_POINTS / 4),
            observed,
        });
    }
    Ok(MovieCase { movie, frames })
}
