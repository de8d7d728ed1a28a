//! A fitted contour checks its own answer before it is reported as
//! verified (issue 29): what the fit returned is compared with what the
//! data show without any spline — the polygon through the data points —
//! and with the neighbouring frames.
//!
//! Per frame:
//! * **λ against the degrees-of-freedom bound** (GCV wanted to interpolate:
//!   the data showed no noise to smooth, [`LambdaReport::at_dof_bound`]).
//! * **Self-intersection**: a signature whose radius reaches 0 or below
//!   (the contour passes through its centre), or a closed curve whose
//!   dense sample (≥ 16 points per knot interval, ≥ 256) crosses itself.
//! * **Area and perimeter against the data polygon**: the polygon through
//!   the data points is an estimate that needs no λ. A smooth fit lies
//!   close to it: sparse points cut corners (a regular polygon of 6
//!   points on a circle has 83 % of its area and 95 % of its length) and
//!   noise lengthens the polygon, so the fit is allowed an area ratio
//!   within [1/[`AREA_RATIO_LIMIT`], AREA_RATIO_LIMIT] and a length at
//!   most [`PERIMETER_RATIO_LIMIT`] times the polygon's. A collapsed fit
//!   (issue 29: area 7×, perimeter 117×) is far outside both.
//! * **Resolution**: the frame's points split into two halves (every other
//!   point along the contour), each fitted with the same knots and λ; when
//!   the halves' areas or perimeters differ by more than [`HALF_LIMIT`] of
//!   the full fit's, the points do not determine the contour (too sparse,
//!   or gaps the spline bridges by guesswork). A two-resolution estimate:
//!   the full data's error is smaller than the halves' spread. Frames of
//!   fewer than 6 points cannot be split and fail it.
//! * **Gaps**: the halves share the data's largest gap, so they agree on
//!   how to bridge it even when both cut a corner there. Every gap is
//!   bounded by the area the truth may enclose between itself and the
//!   fit's bridge there, with the ends held by the data on either side
//!   and the truth's curvature at most the fit's largest, κ_max
//!   ([`gap_caps`]: ≈ (κ_max + F) ℓ³/32 plus the ends' direction
//!   uncertainty). A bound over [`GAP_AREA_LIMIT`] of the area is
//!   flagged. (Before: the chord cap κ_max g³/12 of the largest gap.)
//! * **Jumps across frames** (per-frame fits of ≥ 3 frames): the ratio of
//!   the fit's area (perimeter) to its data polygon's, against the median
//!   of the same ratio over the two frames either side. A fit that departs
//!   from its data differently from its neighbours by more than
//!   [`JUMP_LIMIT`] is flagged; a contour that really changes shows the
//!   change in its data polygon too and is not.
//!
//! Left out: a check of the fit against the true contour (unknown), and
//! self-intersection loops smaller than the sampling step.
use crate::identify::gcv::LambdaReport;
use crate::identify::tracked::Point;
use serde::{Deserialize, Serialize};

/// The fit's area may be at most this many times the data polygon's, or
/// at least its reciprocal.
pub const AREA_RATIO_LIMIT: f64 = 1.25;
/// The fit's perimeter may be at most this many times the data polygon's.
pub const PERIMETER_RATIO_LIMIT: f64 = 1.25;
/// Largest relative departure of a frame's fit-to-data ratio from its
/// neighbours' median.
pub const JUMP_LIMIT: f64 = 0.1;
/// Largest relative spread of the two half-data fits' area or perimeter.
pub const HALF_LIMIT: f64 = 0.1;
/// Largest share of the area that a data gap may hide ([`gap_caps`]):
/// the 5 % to which a verified area is claimed
/// (the campaign's tolerance, [`crate::identify::campaign::TOLERANCE`]).
pub const GAP_AREA_LIMIT: f64 = 0.05;
/// Frames either side that a frame is compared with.
pub const JUMP_WINDOW: usize = 2;

/// Why a frame is not verified.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Flag {
    /// GCV's minimum is against the degrees-of-freedom bound.
    LambdaAtDofBound,
    /// The fitted contour crosses itself (or its radius reaches 0).
    SelfIntersection,
    /// The halves of the data give contours too different to trust the
    /// whole.
    UnderResolved,
    /// The largest gap between data points may hide too much area.
    DataGap,
    /// The fitted area is outside the data polygon's allowance.
    AreaDisagreesWithData,
    /// The fitted perimeter exceeds the data polygon's allowance.
    PerimeterDisagreesWithData,
    /// The fit-to-data area ratio jumps against the neighbouring frames.
    AreaJump,
    /// The fit-to-data perimeter ratio jumps against the neighbouring
    /// frames.
    PerimeterJump,
}

impl Flag {
    /// What the flag means, for the text report.
    pub fn describe(self) -> &'static str {
        match self {
            Flag::LambdaAtDofBound => "GCV heads for interpolation (λ against its degrees-of-freedom bound: no noise seen, or too few points for the knots)",
            Flag::SelfIntersection => "the fitted contour crosses itself",
            Flag::DataGap => "a gap between the points may hide more than 5 % of the area (a departure from the fit across it with the ends held by the data and curvature up to the fit's largest)",
            Flag::UnderResolved => "the two halves of the points (every other one) give areas or perimeters more than 10 % apart: too few points, or gaps, to determine the contour",
            Flag::AreaDisagreesWithData => "the fitted area is not within 25 % of the data polygon's",
            Flag::PerimeterDisagreesWithData => "the fitted perimeter is more than 1.25× the data polygon's",
            Flag::AreaJump => "the fit's area departs from its data unlike the neighbouring frames' (> 10 %)",
            Flag::PerimeterJump => "the fit's perimeter departs from its data unlike the neighbouring frames' (> 10 %)",
        }
    }
}

/// Whether a frame passed its checks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Status {
    /// Every check held.
    Verified,
    /// At least one check failed: the figures are not to be trusted.
    Unverified,
}

/// The checks of one frame and the data-polygon figures they used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameChecks {
    /// Verified when `flags` is empty.
    pub status: Status,
    /// The failed checks.
    pub flags: Vec<Flag>,
    /// Area of the polygon through the data points (None without data).
    pub data_area: Option<f64>,
    /// Perimeter of that polygon.
    pub data_perimeter: Option<f64>,
    /// Relative spread `|a₁ − a₂| / a` of the two half-data fits' areas
    /// (None: not split, e.g. a surface's frame).
    pub half_area_spread: Option<f64>,
    /// The same for the perimeters.
    pub half_perimeter_spread: Option<f64>,
    /// The largest share of the area a gap between data points may hide,
    /// `K g³ / 12 A` with K the curvature bound across that gap
    /// ([`gap_caps`]; None without data). The figure the gap check tests.
    pub gap_area_bound: Option<f64>,
    /// The same with K the fit's largest curvature anywhere and the
    /// largest gap, `κ_max g³ / 12 A` (the check before the local bound;
    /// reported for comparison, not tested).
    #[serde(default)]
    pub gap_area_bound_global: Option<f64>,
}

impl FrameChecks {
    /// Checks of a frame with data: its λ report, whether the fit crosses
    /// itself, the fitted area and perimeter, and the data points in order
    /// along the contour.
    pub fn of_frame(
        lambda: Option<&LambdaReport>,
        self_intersects: bool,
        area: f64,
        perimeter: f64,
        data: &[Point],
    ) -> Self {
        let mut flags = Vec::new();
        if lambda.is_some_and(|l| l.at_dof_bound) {
            flags.push(Flag::LambdaAtDofBound);
        }
        if self_intersects {
            flags.push(Flag::SelfIntersection);
        }
        let (mut data_area, mut data_perimeter) = (None, None);
        if data.len() >= 3 {
            let (a, p) = (polygon_area(data).abs(), polygon_perimeter(data));
            let ratio = area / a;
            if !(ratio.is_finite() && (1.0 / AREA_RATIO_LIMIT..=AREA_RATIO_LIMIT).contains(&ratio))
            {
                flags.push(Flag::AreaDisagreesWithData);
            }
            if !(perimeter.is_finite() && perimeter <= PERIMETER_RATIO_LIMIT * p) {
                flags.push(Flag::PerimeterDisagreesWithData);
            }
            data_area = Some(a);
            data_perimeter = Some(p);
        }
        Self::with(flags, data_area, data_perimeter)
    }

    fn with(flags: Vec<Flag>, data_area: Option<f64>, data_perimeter: Option<f64>) -> Self {
        Self {
            status: if flags.is_empty() {
                Status::Verified
            } else {
                Status::Unverified
            },
            flags,
            data_area,
            data_perimeter,
            half_area_spread: None,
            half_perimeter_spread: None,
            gap_area_bound: None,
            gap_area_bound_global: None,
        }
    }

    /// Checks every gap between consecutive `data` points (in order along
    /// the contour, `data_t` their parameters on the fit `dense`, `rms`
    /// the fit's residual) against the area it may hide, relative to the
    /// fitted `area`; see [`gap_caps`].
    pub fn gap(
        &mut self,
        data: &[Point],
        data_t: &[f64],
        dense: &DenseContour,
        rms: f64,
        area: f64,
    ) {
        let Some(caps) = gap_caps(data, data_t, dense, rms) else {
            return;
        };
        let share = |cap: f64| cap / area.abs();
        let local = share(caps.local);
        self.gap_area_bound = Some(local).filter(|v| v.is_finite());
        self.gap_area_bound_global = Some(share(caps.global)).filter(|v| v.is_finite());
        if local.is_nan() || local > GAP_AREA_LIMIT {
            self.flag(Flag::DataGap);
        }
    }

    /// Records the half-data fits' (area, perimeter) pairs against the
    /// full fit's, or `None` when the frame could not be split or a half
    /// could not be fitted; flags [`Flag::UnderResolved`] accordingly.
    pub fn halves(&mut self, full: (f64, f64), halves: Option<[(f64, f64); 2]>) {
        match halves {
            Some([a, b]) => {
                let da = (a.0 - b.0).abs() / full.0.abs();
                let dp = (a.1 - b.1).abs() / full.1.abs();
                self.half_area_spread = Some(da).filter(|v| v.is_finite());
                self.half_perimeter_spread = Some(dp).filter(|v| v.is_finite());
                if da.is_nan() || dp.is_nan() || da > HALF_LIMIT || dp > HALF_LIMIT {
                    self.flag(Flag::UnderResolved);
                }
            }
            None => self.flag(Flag::UnderResolved),
        }
    }

    /// Adds a failed check.
    pub fn flag(&mut self, flag: Flag) {
        if !self.flags.contains(&flag) {
            self.flags.push(flag);
        }
        self.status = Status::Unverified;
    }

    /// True when every check held.
    pub fn verified(&self) -> bool {
        self.status == Status::Verified
    }
}

/// A fitted closed contour sampled at equally spaced parameters over one
/// period: the parameter, the point and the signed curvature of each
/// sample.
#[derive(Debug, Clone, PartialEq)]
pub struct DenseContour {
    /// The parameter's period; sample `j` is at `t[0] + j·period/n`.
    pub period: f64,
    /// The samples' parameters.
    pub t: Vec<f64>,
    /// The samples' points.
    pub points: Vec<Point>,
    /// The signed curvature at each sample, 1/length.
    pub kappa: Vec<f64>,
}

/// The areas (length²) the gaps between data points may hide.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapCaps {
    /// The largest over the gaps of the area by which the contour may
    /// depart from the fit across the gap ([`gap_caps`]).
    pub local: f64,
    /// `κ_max g³/12` for the largest gap g, κ_max the fit's largest
    /// curvature anywhere: the cap of a circle of curvature κ_max over
    /// the chord (the bound before, kept for comparison).
    pub global: f64,
    /// The largest gap (chord), length.
    pub largest_gap: f64,
}

/// The area each gap between consecutive `data` points (in order along
/// the contour; `data_t` their parameters on `dense`) may hide, given
/// the fit's residual `rms` (length).
///
/// What is hidden is the area between the true contour and the fit
/// across the gap (not the chord: the fit already bends across it). Let
/// the truth be the fit's bridge (arc length ℓ) displaced along its
/// normal by e(s), 0 ≤ s ≤ ℓ. To first order in e:
///
/// * e″ = κ_true − κ_fit, so |e″| ≤ M = κ_max + F with κ_max the fit's
///   largest |κ| anywhere (the assumption the bound rests on, as before:
///   the contour bends nowhere more sharply than the fit shows where it
///   has data) and F the fit's largest |κ| across the gap;
/// * the data on either side hold the position and the direction of the
///   contour at the gap's ends: e = 0 there, and e′ = 0 up to the
///   direction's uncertainty δ ≈ 2·rms/h, h the spacing of the two
///   points that end the gap on that side.
///
/// With e = e′ = 0 at both ends, `∫e ds = ∫ e″ s(ℓ − s)/2 ds` with ∫e″ = 0
/// and ∫ s e″ = 0, which |e″| ≤ M bounds by M ℓ³/32 (e″ = ±M switching at
/// ℓ/4 and 3ℓ/4). The end directions add at most (δ_a + δ_b) ℓ²/12 (the
/// area of the cubic Hermite slope functions). The gap's bound is the
/// sum. Without the end directions the same argument gives M ℓ³/12, more
/// than the old chord cap κ_max g³/12, which ignored the fit's own bend.
///
/// The first-order model strains once Mℓ is not small (a gap as long as
/// the contour's radius of curvature); the figure is then an estimate
/// of the right size, as κ_max g³/12 was. A feature sharper than any the
/// fit resolves, inside a gap, is what this cannot see. `None` with fewer
/// than 4 points or 3 samples.
pub fn gap_caps(data: &[Point], data_t: &[f64], dense: &DenseContour, rms: f64) -> Option<GapCaps> {
    let (n, m) = (data.len(), dense.points.len());
    if n < 4 || m < 3 || data_t.len() != n || dense.kappa.len() != m {
        return None;
    }
    let dist = |a: Point, b: Point| (b.0 - a.0).hypot(b.1 - a.1);
    // Arc length at each sample; the closing segment makes the perimeter.
    let mut arc = Vec::with_capacity(m + 1);
    arc.push(0.0);
    for j in 0..m {
        let step = dist(dense.points[j], dense.points[(j + 1) % m]);
        arc.push(arc[j] + step);
    }
    let perimeter = arc[m];
    let kappa_max = dense.kappa.iter().fold(0.0, |a: f64, k| a.max(k.abs()));
    let h = dense.period / m as f64;
    let mi = m as i64;
    // Unwrapped arc length at sample index j (any integer).
    let arc_of_index =
        |j: i64| j.div_euclid(mi) as f64 * perimeter + arc[j.rem_euclid(mi) as usize];
    // Sample position (fractional index in [0, m)) of parameter t.
    let position = |t: f64| ((t - dense.t[0]) / h).rem_euclid(m as f64);
    let arc_of_position = |u: f64| {
        let j = u.floor();
        let f = u - j;
        let j = j as i64;
        (1.0 - f) * arc_of_index(j) + f * arc_of_index(j + 1)
    };
    let point = |i: usize| data[i % n];
    let (mut local, mut largest_gap) = (0.0_f64, 0.0_f64);
    for i in 0..n {
        let g = dist(point(i), point(i + 1));
        largest_gap = largest_gap.max(g);
        let ua = position(data_t[i]);
        let mut ub = position(data_t[(i + 1) % n]);
        if ub <= ua {
            ub += m as f64;
        }
        let l = arc_of_position(ub) - arc_of_position(ua);
        // The fit's largest |κ| across the gap (samples inside it and the
        // one either side).
        let across = (ua.floor() as i64..=ub.ceil() as i64)
            .map(|j| dense.kappa[j.rem_euclid(mi) as usize].abs())
            .fold(0.0, f64::max);
        // The end directions, each fitted to the points on that side
        // within ℓ of the gap's end (at least the next one).
        let delta =
            direction_error(data, i, n - 1, l, rms) + direction_error(data, i + 1, 1, l, rms);
        let hidden = (kappa_max + across) * l.powi(3) / 32.0 + delta * l * l / 12.0;
        local = local.max(hidden);
    }
    Some(GapCaps {
        local,
        global: kappa_max * largest_gap.powi(3) / 12.0,
        largest_gap,
    })
}

/// The uncertainty (rad) of the contour's direction at `data[end]` as the
/// points on one side fix it: the points `end`, `end + step`, … (indices
/// modulo n; step 1 goes forward, n − 1 back) within `reach` of the end,
/// at least two. A straight line fitted to c points spread over a
/// baseline b with noise σ (`rms`) has a slope error ≈ σ√12/(b√c) (the
/// least-squares slope's standard deviation for evenly spread points).
fn direction_error(data: &[Point], end: usize, step: usize, reach: f64, rms: f64) -> f64 {
    let n = data.len();
    let p0 = data[end % n];
    let (mut count, mut baseline) = (1usize, 0.0_f64);
    for k in 1..n {
        let p = data[(end + k * step) % n];
        let d = (p.0 - p0.0).hypot(p.1 - p0.1);
        count += 1;
        baseline = baseline.max(d);
        if baseline >= reach {
            break;
        }
    }
    rms * 12f64.sqrt() / (baseline * (count as f64).sqrt())
}

/// Flags the frames whose fit-to-data ratio of `fitted` (area or
/// perimeter, one per frame, in frame order) against `data` departs by
/// more than [`JUMP_LIMIT`] from the median ratio of the [`JUMP_WINDOW`]
/// frames either side. Returns the indices of the frames that jump (none
/// with fewer than 3 frames).
pub fn jumps(fitted: &[f64], data: &[Option<f64>]) -> Vec<usize> {
    let ratio: Vec<Option<f64>> = fitted
        .iter()
        .zip(data)
        .map(|(f, d)| d.map(|d| f / d).filter(|r| r.is_finite() && *r > 0.0))
        .collect();
    let n = ratio.len();
    if n < 3 {
        return Vec::new();
    }
    (0..n)
        .filter(|&i| {
            let Some(r) = ratio[i] else { return false };
            let mut nb: Vec<f64> = (i.saturating_sub(JUMP_WINDOW)..(i + JUMP_WINDOW + 1).min(n))
                .filter(|&j| j != i)
                .filter_map(|j| ratio[j])
                .collect();
            if nb.is_empty() {
                return false;
            }
            nb.sort_by(f64::total_cmp);
            let med = if nb.len() % 2 == 1 {
                nb[nb.len() / 2]
            } else {
                0.5 * (nb[nb.len() / 2 - 1] + nb[nb.len() / 2])
            };
            (r / med - 1.0).abs() > JUMP_LIMIT
        })
        .collect()
}

/// Signed area of a closed polygon (counter-clockwise positive).
pub fn polygon_area(points: &[Point]) -> f64 {
    let n = points.len();
    0.5 * (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            a.0 * b.1 - b.0 * a.1
        })
        .sum::<f64>()
}

/// Perimeter of a closed polygon.
pub fn polygon_perimeter(points: &[Point]) -> f64 {
    let n = points.len();
    (0..n)
        .map(|i| {
            let (a, b) = (points[i], points[(i + 1) % n]);
            (b.0 - a.0).hypot(b.1 - a.1)
        })
        .sum()
}

/// Whether a closed polygon crosses itself: some two edges that are not
/// neighbours intersect (touching counts). O(n²); for a few hundred
/// points.
pub fn polygon_self_intersects(points: &[Point]) -> bool {
    let n = points.len();
    if n < 4 {
        return false;
    }
    let edge = |i: usize| (points[i], points[(i + 1) % n]);
    for i in 0..n {
        let (a, b) = edge(i);
        let (lo_x, hi_x) = (a.0.min(b.0), a.0.max(b.0));
        let (lo_y, hi_y) = (a.1.min(b.1), a.1.max(b.1));
        // Edges i + 2 … skipping the edge that shares i's start point.
        for j in i + 2..n {
            if i == 0 && j == n - 1 {
                continue;
            }
            let (c, d) = edge(j);
            if c.0.max(d.0) < lo_x
                || c.0.min(d.0) > hi_x
                || c.1.max(d.1) < lo_y
                || c.1.min(d.1) > hi_y
            {
                continue;
            }
            if segments_cross(a, b, c, d) {
                return true;
            }
        }
    }
    false
}

/// Whether segments ab and cd have a common point.
fn segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool {
    let orient =
        |p: Point, q: Point, r: Point| (q.0 - p.0) * (r.1 - p.1) - (q.1 - p.1) * (r.0 - p.0);
    let (d1, d2) = (orient(c, d, a), orient(c, d, b));
    let (d3, d4) = (orient(a, b, c), orient(a, b, d));
    if ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0))
        && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
    {
        return true;
    }
    let on = |p: Point, q: Point, r: Point| {
        r.0 >= p.0.min(q.0) && r.0 <= p.0.max(q.0) && r.1 >= p.1.min(q.1) && r.1 <= p.1.max(q.1)
    };
    (d1 == 0.0 && on(c, d, a))
        || (d2 == 0.0 && on(c, d, b))
        || (d3 == 0.0 && on(a, b, c))
        || (d4 == 0.0 && on(a, b, d))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_figure_eight_crosses_itself_and_a_square_does_not() {
        let square = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        assert!(!polygon_self_intersects(&square));
        assert_eq!(polygon_area(&square), 1.0);
        assert_eq!(polygon_perimeter(&square), 4.0);
        let bow = [(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)];
        assert!(polygon_self_intersects(&bow));
        // A circle sampled finely does not cross itself.
        let circle: Vec<Point> = (0..300)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 300.0;
                (a.cos(), a.sin())
            })
            .collect();
        assert!(!polygon_self_intersects(&circle));
    }

    #[test]
    fn a_ratio_that_jumps_against_its_neighbours_is_flagged() {
        let data = vec![Some(100.0); 7];
        let mut fit = vec![101.0, 99.0, 100.5, 100.0, 99.5, 100.0, 101.0];
        assert!(jumps(&fit, &data).is_empty());
        fit[3] = 700.0;
        assert_eq!(jumps(&fit, &data), vec![3]);
        // The data change with the fit: no jump.
        let mut data2 = data.clone();
        data2[3] = Some(690.0);
        assert!(jumps(&fit, &data2).is_empty());
    }
}
