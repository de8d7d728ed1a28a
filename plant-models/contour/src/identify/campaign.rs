//! The self-check campaign of issue 29: random noisy closed contours whose
//! truth is known, fitted as `softjoint contour fit` fits a file (λ by
//! GCV, default knots), and each answer compared with the truth. A wrong
//! answer is a frame reported `verified` whose area or perimeter is more
//! than [`TOLERANCE`] from the truth; the campaign counts them (must be 0)
//! and the share solved (verified and right).
//!
//! The population (drawn from [`rng::CONTOUR_CAMPAIGN`]): half ellipses
//! (axis ratio 0.4–1, any orientation), half lobed contours
//! `r = R(1 + Σ a_k cos(kθ + φ_k))` with 1–3 harmonics k ∈ 2…5, each
//! amplitude ≤ 0.12/k (so r stays positive and the contour convex-ish to
//! wavy); 24–160 points, half at jittered equal angles (±0.3 of the
//! spacing), half at independent uniform angles (gaps); noise σ from 0.5 %
//! to 3 % of R. Half are given as x, y points in order along the contour
//! (noise on both coordinates; the closed-curve model), half as
//! angle/radius about the true centre (noise on the radius; the
//! signature model, the paper's form).
//!
//! The truth comes from the shape's formula, not from the splines: the
//! area and perimeter of a 20,000-point polygon of the true contour
//! (relative error below 10⁻⁷ for these shapes; an ellipse's area is also
//! πab exactly, which the tests check).
use std::f64::consts::TAU;

use plant_common::rng;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::Serialize;

use crate::error::Result;
use crate::identify::checks::{polygon_area, polygon_perimeter, Flag};
use crate::identify::contours::{fit_contours, ContourFitSpec, ContourModel};
use crate::identify::data::{ContourData, FrameData};
use crate::identify::gcv::Lambda;
use crate::identify::tracked::{Point, Signature};
use crate::model::fit::Solver;

/// Largest relative error of area and perimeter a verified answer may
/// have.
pub const TOLERANCE: f64 = 0.05;
/// Points of the polygon the truth is computed on.
pub const TRUTH_POINTS: usize = 20_000;

/// A true contour, star-shaped about `centre`: r(θ).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub enum TrueShape {
    /// An ellipse with semi-axes a ≥ b turned by `turn_rad`.
    Ellipse { a: f64, b: f64, turn_rad: f64 },
    /// `r = R(1 + Σ a_k cos(kθ + φ_k))`, (k, a_k, φ_k).
    Lobed {
        radius: f64,
        harmonics: Vec<(u32, f64, f64)>,
    },
}

impl TrueShape {
    /// r(θ) about the centre.
    pub fn radius(&self, theta: f64) -> f64 {
        match self {
            TrueShape::Ellipse { a, b, turn_rad } => {
                let t = theta - turn_rad;
                a * b / ((b * t.cos()).powi(2) + (a * t.sin()).powi(2)).sqrt()
            }
            TrueShape::Lobed { radius, harmonics } => {
                radius
                    * (1.0
                        + harmonics
                            .iter()
                            .map(|&(k, a, p)| a * (k as f64 * theta + p).cos())
                            .sum::<f64>())
            }
        }
    }

    /// The mean size R (the ellipse's √(ab)).
    pub fn size(&self) -> f64 {
        match self {
            TrueShape::Ellipse { a, b, .. } => (a * b).sqrt(),
            TrueShape::Lobed { radius, .. } => *radius,
        }
    }

    /// Area and perimeter of the [`TRUTH_POINTS`]-gon of the contour.
    pub fn area_and_perimeter(&self) -> (f64, f64) {
        let pts: Vec<Point> = (0..TRUTH_POINTS)
            .map(|k| {
                let t = TAU * k as f64 / TRUTH_POINTS as f64;
                let r = self.radius(t);
                (r * t.cos(), r * t.sin())
            })
            .collect();
        (polygon_area(&pts), polygon_perimeter(&pts))
    }
}

/// One random contour and how it is observed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Case {
    pub index: usize,
    pub shape: TrueShape,
    pub centre: Point,
    pub points: usize,
    /// Angles independent uniform (true) or jittered equal (false).
    pub random_angles: bool,
    /// Noise standard deviation, in the data's length unit.
    pub sigma: f64,
    /// Closed curve (x, y) or signature (angle, radius).
    pub model: ContourModel,
}

/// What the fit answered for a case, against the truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outcome {
    pub case: Case,
    /// Relative area error (fit/truth − 1); None when the fit refused.
    pub area_error: Option<f64>,
    pub perimeter_error: Option<f64>,
    pub verified: bool,
    pub flags: Vec<Flag>,
    /// The checks' two-halves spreads of area and perimeter.
    pub half_spreads: Option<(f64, f64)>,
    /// The fit's area over its data polygon's.
    pub area_over_data: Option<f64>,
    /// The fit's refusal, if it refused.
    pub refused: Option<String>,
    /// The checks' gap bound (share of the area; the tested one) and the
    /// global κ_max bound beside it.
    pub gap_bounds: Option<(f64, f64)>,
    /// The largest share of the true area outside the polygon through
    /// the noise-free points across one gap ([`truth_cap_share`]).
    pub truth_cap: f64,
}

impl Outcome {
    /// Within [`TOLERANCE`] in area and perimeter.
    pub fn right(&self) -> bool {
        matches!((self.area_error, self.perimeter_error),
            (Some(a), Some(p)) if a.abs() <= TOLERANCE && p.abs() <= TOLERANCE)
    }

    /// Reported verified but not right: the failure the campaign must
    /// never see.
    pub fn wrong(&self) -> bool {
        self.verified && !self.right()
    }

    /// Solvable from the truth alone: no gap between the data points
    /// holds more than [`TOLERANCE`] of the true area outside the
    /// polygon through the noise-free points. (A contour through the same
    /// points that runs straight across such a gap fits the data as well
    /// and differs from the truth by more than the tolerance.)
    pub fn solvable(&self) -> bool {
        self.truth_cap <= TOLERANCE
    }
}

/// The largest `|cap| / A` over the gaps between consecutive `angles`
/// (sorted, rad) of `shape`: the true area between the contour and the
/// chord joining its noise-free points at those angles, over the true
/// area A (sector ½∫r²dθ by Simpson on 64 panels, minus the triangle
/// with the centre; concave caps count by magnitude).
pub fn truth_cap_share(shape: &TrueShape, angles: &[f64]) -> f64 {
    let n = angles.len();
    if n < 2 {
        return f64::INFINITY;
    }
    let (area, _) = shape.area_and_perimeter();
    let panels = 64;
    (0..n)
        .map(|i| {
            let a = angles[i];
            let mut b = angles[(i + 1) % n];
            if b <= a {
                b += TAU;
            }
            let h = (b - a) / panels as f64;
            let f = |t: f64| 0.5 * shape.radius(t).powi(2);
            let sector = h / 3.0
                * (0..=panels)
                    .map(|k| {
                        let w = if k == 0 || k == panels {
                            1.0
                        } else if k % 2 == 1 {
                            4.0
                        } else {
                            2.0
                        };
                        w * f(a + k as f64 * h)
                    })
                    .sum::<f64>();
            let triangle = 0.5 * shape.radius(a) * shape.radius(b) * (b - a).sin();
            (sector - triangle).abs() / area
        })
        .fold(0.0, f64::max)
}

/// Draws case `index` of the campaign with `seed`.
pub fn draw_case(seed: u64, index: usize) -> Case {
    let mut r = rng::stream(
        seed.wrapping_mul(1_000_003).wrapping_add(index as u64),
        rng::CONTOUR_CAMPAIGN,
    );
    let size = r.gen_range(10.0..100.0);
    let shape = if index % 2 == 0 {
        let ratio: f64 = r.gen_range(0.4..1.0);
        TrueShape::Ellipse {
            a: size / ratio.sqrt(),
            b: size * ratio.sqrt(),
            turn_rad: r.gen_range(0.0..TAU),
        }
    } else {
        let n = r.gen_range(1..=3);
        let harmonics = (0..n)
            .map(|_| {
                let k: u32 = r.gen_range(2..=5);
                (k, r.gen_range(0.0..0.12) / k as f64, r.gen_range(0.0..TAU))
            })
            .collect();
        TrueShape::Lobed {
            radius: size,
            harmonics,
        }
    };
    Case {
        index,
        centre: (r.gen_range(-500.0..500.0), r.gen_range(-500.0..500.0)),
        points: r.gen_range(24..=160),
        random_angles: r.gen_bool(0.5),
        sigma: size * r.gen_range(0.005..0.03),
        model: if (index / 2) % 2 == 0 {
            ContourModel::Curve
        } else {
            ContourModel::Signature
        },
        shape,
    }
}

/// The noisy observation of a case (one frame), from the same stream.
pub fn observe(seed: u64, case: &Case) -> Result<ContourData> {
    observe_at(seed, case).map(|o| o.0)
}

/// The observation and the true angles (sorted) it was taken at.
pub fn observe_at(seed: u64, case: &Case) -> Result<(ContourData, Vec<f64>)> {
    let mut r = rng::stream(
        seed.wrapping_mul(1_000_003).wrapping_add(case.index as u64) ^ 0x5eed,
        rng::CONTOUR_CAMPAIGN,
    );
    let n = case.points;
    let mut angles: Vec<f64> = if case.random_angles {
        (0..n).map(|_| r.gen_range(0.0..TAU)).collect()
    } else {
        let phase = r.gen_range(0.0..TAU);
        (0..n)
            .map(|k| (phase + TAU * (k as f64 + r.gen_range(-0.3..0.3)) / n as f64).rem_euclid(TAU))
            .collect()
    };
    angles.sort_by(f64::total_cmp);
    let mut noise = || -> f64 { StandardNormal.sample(&mut r) };
    let file = format!("campaign case {}", case.index);
    let frame = match case.model {
        ContourModel::Signature => {
            let radii: Vec<f64> = angles
                .iter()
                .map(|&t| case.shape.radius(t) + case.sigma * noise())
                .collect();
            FrameData::Signature(Signature::new(&file, case.centre, &angles, &radii)?)
        }
        _ => FrameData::Points(
            angles
                .iter()
                .map(|&t| {
                    let rad = case.shape.radius(t);
                    (
                        case.centre.0 + rad * t.cos() + case.sigma * noise(),
                        case.centre.1 + rad * t.sin() + case.sigma * noise(),
                    )
                })
                .collect(),
        ),
    };
    Ok((
        ContourData {
            file,
            frames: vec![(0.0, frame)],
        },
        angles,
    ))
}

/// Fits case `index` as `softjoint contour fit` would and compares.
pub fn run_case(seed: u64, index: usize) -> Outcome {
    let case = draw_case(seed, index);
    let spec = ContourFitSpec {
        model: Some(case.model),
        knots: None,
        time_knots: None,
        lambda: Lambda::Gcv,
        solver: Solver::Reduced,
        samples: 64,
        signed_radii: false,
    };
    let (area, perimeter) = case.shape.area_and_perimeter();
    let (fitted, truth_cap) = match observe_at(seed, &case) {
        Ok((d, angles)) => (
            fit_contours(&d, &spec),
            truth_cap_share(&case.shape, &angles),
        ),
        Err(e) => (Err(e), f64::INFINITY),
    };
    match fitted {
        Ok(report) => {
            let r = &report.frames[0].result;
            Outcome {
                area_error: Some(r.area / area - 1.0),
                perimeter_error: Some(r.perimeter / perimeter - 1.0),
                verified: r.checks.verified(),
                flags: r.checks.flags.clone(),
                half_spreads: r
                    .checks
                    .half_area_spread
                    .zip(r.checks.half_perimeter_spread),
                area_over_data: r.checks.data_area.map(|a| r.area / a),
                refused: None,
                gap_bounds: r.checks.gap_area_bound.zip(r.checks.gap_area_bound_global),
                truth_cap,
                case,
            }
        }
        Err(e) => Outcome {
            area_error: None,
            perimeter_error: None,
            verified: false,
            flags: Vec::new(),
            half_spreads: None,
            area_over_data: None,
            refused: Some(e.to_string()),
            gap_bounds: None,
            truth_cap,
            case,
        },
    }
}

/// The campaign's counts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    pub cases: usize,
    /// Verified and within tolerance.
    pub solved: usize,
    /// Verified but not within tolerance (must be 0).
    pub wrong: usize,
    /// Flagged unverified (right or not).
    pub unverified: usize,
    /// Unverified although within tolerance (over-cautious flags).
    pub unverified_but_right: usize,
    /// Refused by the fit.
    pub refused: usize,
    /// Largest |error| (area or perimeter) among verified answers.
    pub worst_verified_error: f64,
    /// Solvable cases ([`Outcome::solvable`]).
    pub solvable: usize,
    /// Solvable cases solved.
    pub solvable_solved: usize,
}

/// Runs cases `0..cases` with `seed`.
pub fn run(seed: u64, cases: usize) -> (Summary, Vec<Outcome>) {
    let outcomes: Vec<Outcome> = (0..cases).map(|i| run_case(seed, i)).collect();
    let count = |f: &dyn Fn(&Outcome) -> bool| outcomes.iter().filter(|o| f(o)).count();
    let summary = Summary {
        cases,
        solved: count(&|o| o.verified && o.right()),
        wrong: count(&|o| o.wrong()),
        unverified: count(&|o| !o.verified && o.refused.is_none()),
        unverified_but_right: count(&|o| !o.verified && o.right()),
        refused: count(&|o| o.refused.is_some()),
        worst_verified_error: outcomes
            .iter()
            .filter(|o| o.verified)
            .filter_map(|o| Some(o.area_error?.abs().max(o.perimeter_error?.abs())))
            .fold(0.0, f64::max),
        solvable: count(&|o| o.solvable()),
        solvable_solved: count(&|o| o.solvable() && o.verified && o.right()),
    };
    (summary, outcomes)
}
