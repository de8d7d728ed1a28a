//! The test cases of `softjoint contour synth` (Fujioka & Kano, seed
//! 000) with the command's checks of its arguments: the red-blood-cell
//! surface of Eq. 38 on an N × N grid with noise, and the pulsating,
//! translating contour movie. The program and the Python package both
//! take them from here; files and pictures are the program's.
use plant_contour::identify::paper;
use plant_contour::identify::synth::{movie_case, rbc_case, MovieCase, RbcFrame};
use serde::Serialize;

/// What a case is: the figures of `synth`'s summary (the program adds
/// where it wrote what, and a command that fits the data).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SynthFigures {
    pub case: &'static str,
    /// Frames of data (the movie: those observed).
    pub frames: usize,
    pub points_per_frame: usize,
    /// The noise's standard deviation (rbc: radius units; movie: px).
    pub sigma: f64,
    pub seed: u64,
}

/// An argument refused, in words that begin with its name as the Python
/// package calls it (the program adds `--`); other errors are the case's.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthArgError(pub String);

impl std::fmt::Display for SynthArgError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for SynthArgError {}

/// The movie's default noise, px (one pixel of tracking error).
pub const MOVIE_SIGMA_PX: f64 = 1.0;

fn check_sigma(sigma: f64, unit: &str) -> anyhow::Result<()> {
    if sigma.is_finite() && sigma >= 0.0 {
        return Ok(());
    }
    Err(anyhow::Error::new(SynthArgError(format!(
        "sigma must be finite and ≥ 0{unit}, got {sigma}"
    ))))
}

/// Eq. 38 on an `n` × `n` grid (2..=1000; the paper: 5 and 40) with
/// Gaussian noise of `sigma` (default: the paper's 0.3) seeded by `seed`:
/// the case's figures and its frames (frame i ↔ s = 10 i/(N − 1); angle
/// θ(t_j) = 2π j/N).
pub fn rbc(
    n: usize,
    sigma: Option<f64>,
    seed: u64,
) -> anyhow::Result<(SynthFigures, Vec<RbcFrame>)> {
    let sigma = sigma.unwrap_or(paper::SIGMA);
    check_sigma(sigma, "")?;
    if !(2..=1000).contains(&n) {
        return Err(anyhow::Error::new(SynthArgError(format!(
            "n must be 2..=1000 (the paper: 5 and 40), got {n}"
        ))));
    }
    let figures = SynthFigures {
        case: "rbc",
        frames: n,
        points_per_frame: n,
        sigma,
        seed,
    };
    Ok((figures, rbc_case(n, sigma, seed)))
}

/// The movie observed along `angles` rays (3..=100000) at every
/// `every`-th frame (1..=100) with noise of `sigma` px (default
/// [`MOVIE_SIGMA_PX`]) seeded by `seed`: the case's figures and the case.
pub fn movie(
    every: usize,
    angles: usize,
    sigma: Option<f64>,
    seed: u64,
) -> anyhow::Result<(SynthFigures, MovieCase)> {
    let sigma = sigma.unwrap_or(MOVIE_SIGMA_PX);
    check_sigma(sigma, " (px)")?;
    if !(3..=100_000).contains(&angles) {
        return Err(anyhow::Error::new(SynthArgError(format!(
            "angles must be 3..=100000, got {angles}"
        ))));
    }
    if !(1..=100).contains(&every) {
        return Err(anyhow::Error::new(SynthArgError(format!(
            "every must be 1..=100, got {every}"
        ))));
    }
    let case = movie_case(every, angles, sigma, seed)?;
    let figures = SynthFigures {
        case: "movie",
        frames: case.kept(),
        points_per_frame: angles,
        sigma,
        seed,
    };
    Ok((figures, case))
}
