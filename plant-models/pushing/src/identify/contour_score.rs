//! The tracked contour as a periodic smoothing spline, and a score that
//! looks where the block deforms.
//!
//! **Tracking.** Each frame's tracked contour points (the seed's snake
//! output; here the ground truth's noisy boundary) are fitted by a closed
//! parametric smoothing spline `(x(t), y(t))` of Fujioka & Kano (seed 000,
//! [`plant_contour`]): one knot per two points, λ by generalised
//! cross-validation, t the chord length. The spline filters the contour
//! noise and can be resampled at any density (here every
//! [`TrackingOptions::spacing_px`] along the contour). A closed curve, not
//! the paper's signature r(θ): a deeply dented block is not star-shaped
//! about its centroid.
//!
//! **Contour distance.** The pixel F-score barely discriminates (an
//! undeformed block already scores 0.96–0.97, README of `pushing`): the
//! block's area dwarfs the dent. The contour distance looks only where the
//! finger can reach: the zone of points within
//! `finger radius + margin` of the finger centre's path (from its start
//! to its deepest point). Per frame, the distances from the tracked
//! spline's points in the zone to the model's boundary polygon, and from
//! the model boundary's points in the zone to the tracked spline, pooled:
//! their mean and their largest value, px. Over a video: the mean over
//! frames of each. A frame from which the model is unstable scores the
//! zone's diameter (as far off as anything in the zone can be).
//!
//! **Baseline.** The undeformed block (the model mesh at rest in every
//! frame) gets the same score; `skill = 1 − D_model / D_still` says which
//! fraction of the deformation's contour mismatch the model removes (1 =
//! all, 0 = no better than not deforming at all, < 0 = worse).
//!
//! Left out: occlusion of the contour by the finger (a camera would lose
//! the contour under it; the ground truth here does not), tracking across
//! frames (each frame is fitted on its own).
use crate::classify::{tally, MaterialModel, Tally};
use crate::error::{check_positive, check_range, PushError, Result};
use crate::evaluate::{simulate_frames, PreparedVideo};
use crate::forces::MaterialParams;
use crate::reference::Video;
use crate::scenario::PushScenario;
use crate::sim::{DrivingMode, SimConfig};
use crate::V2;
use plant_contour::curve::ClosedCurve;
use plant_contour::fit::Solver;
use plant_contour::identify::distance::point_segment_distance;
use plant_contour::identify::gcv::Lambda;
use plant_contour::identify::movie::resample_polygon;
use plant_contour::identify::tracked::{fit_closed_curve, ContourOptions};
use serde::{Deserialize, Serialize};

/// How the tracked contour is smoothed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackingOptions {
    /// Tracked points per knot interval (2: a knot every other point; with
    /// one knot per point GCV sometimes interpolates the noise).
    pub points_per_knot: f64,
    /// λ, or GCV per frame.
    pub lambda: Lambda,
    /// Spacing of the resampled contour, px.
    pub spacing_px: f64,
}

impl Default for TrackingOptions {
    fn default() -> Self {
        Self {
            points_per_knot: 2.0,
            lambda: Lambda::Gcv,
            spacing_px: 1.0,
        }
    }
}

/// A video's contours as splines.
#[derive(Debug, Clone, PartialEq)]
pub struct TrackedVideo {
    /// The spline of each frame.
    pub curves: Vec<ClosedCurve>,
    /// λ of each frame's fit.
    pub lambda_per_frame: Vec<f64>,
    /// RMS distance of the tracked points from their fitted points, px.
    pub rms_residual_px: Vec<f64>,
    /// Each spline resampled every `spacing_px` (closed polygon).
    pub contours_px: Vec<Vec<V2>>,
}

/// Fits every frame's tracked contour with a closed smoothing spline.
pub fn track_video(video: &Video, opts: &TrackingOptions) -> Result<TrackedVideo> {
    check_range("points_per_knot", opts.points_per_knot, 0.5, 100.0)?;
    check_range("spacing_px", opts.spacing_px, 0.05, 1e3)?;
    let n = video.contours_px.len();
    let mut out = TrackedVideo {
        curves: Vec::with_capacity(n),
        lambda_per_frame: Vec::with_capacity(n),
        rms_residual_px: Vec::with_capacity(n),
        contours_px: Vec::with_capacity(n),
    };
    for (f, c) in video.contours_px.iter().enumerate() {
        let pts: Vec<(f64, f64)> = c.iter().map(|p| (p.x, p.y)).collect();
        let knots = ((pts.len() as f64 / opts.points_per_knot).round() as usize).max(4);
        let fit = fit_closed_curve(
            &format!("frame {f}"),
            &pts,
            &ContourOptions {
                knots,
                lambda: opts.lambda,
                solver: Solver::Reduced,
            },
        )?;
        let samples = ((fit.curve.length(2) / opts.spacing_px).ceil() as usize).max(8);
        out.contours_px.push(
            fit.curve
                .sample(samples)
                .into_iter()
                .map(|(x, y)| V2::new(x, y))
                .collect(),
        );
        out.lambda_per_frame.push(fit.lambda.lambda);
        out.rms_residual_px.push(fit.rms_residual);
        out.curves.push(fit.curve);
    }
    Ok(out)
}

/// The part of the image within the finger's reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReachZone {
    /// Finger centre at the start of the push, px.
    pub path_start_px: V2,
    /// Finger centre at its deepest, px.
    pub path_end_px: V2,
    /// Points within this distance of the path are in the zone, px.
    pub radius_px: f64,
}

/// Margin of the reach zone beyond the finger's radius, in finger radii
/// (estimate: the dent's shoulders and bulges lie within one finger
/// radius of the contact).
pub const DEFAULT_REACH_MARGIN_RADII: f64 = 1.0;

impl ReachZone {
    /// The zone of `scenario`'s finger with `margin_px` beyond its radius.
    pub fn of(scenario: &PushScenario, margin_px: f64) -> Result<Self> {
        check_range("reach margin", margin_px, 0.0, 1e4)?;
        let t_deepest = scenario.frames_push as f64 * scenario.frame_interval_s;
        Ok(Self {
            path_start_px: scenario.finger_at(0.0).centre_px,
            path_end_px: scenario.finger_at(t_deepest).centre_px,
            radius_px: scenario.finger_radius_px + margin_px,
        })
    }

    /// The default zone of `scenario` ([`DEFAULT_REACH_MARGIN_RADII`]).
    pub fn default_of(scenario: &PushScenario) -> Result<Self> {
        Self::of(
            scenario,
            DEFAULT_REACH_MARGIN_RADII * scenario.finger_radius_px,
        )
    }

    /// Distance of `p` from the finger's path.
    pub fn path_distance(&self, p: V2) -> f64 {
        point_segment_distance(
            (p.x, p.y),
            (self.path_start_px.x, self.path_start_px.y),
            (self.path_end_px.x, self.path_end_px.y),
        )
    }

    /// Whether `p` is in the zone.
    pub fn contains(&self, p: V2) -> bool {
        self.path_distance(p) <= self.radius_px
    }

    /// The zone's diameter: the score of a frame with an unstable model.
    pub fn diameter_px(&self) -> f64 {
        2.0 * self.radius_px
            + (self.path_end_px - self.path_start_px)
                .norm()
                .min(2.0 * self.radius_px)
    }
}

/// Segments of the other curve are searched within this distance beyond
/// the zone (px): distances up to it are exact; none in the pushes comes
/// near it (dents are ≤ 70 px deep, the zone's radius is 2 finger radii).
pub const SEARCH_MARGIN_PX: f64 = 120.0;

/// One frame of the tracked contour, prepared for scoring.
#[derive(Debug, Clone, PartialEq)]
struct TargetFrame {
    /// Resampled tracked points inside the zone.
    zone_points: Vec<V2>,
    /// Tracked polyline segments near the zone.
    near_segments: Vec<(V2, V2)>,
}

/// A tracked video prepared for the contour distance.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourTarget {
    /// The finger's reach.
    pub zone: ReachZone,
    /// Spacing of the resampled curves, px.
    pub spacing_px: f64,
    frames: Vec<TargetFrame>,
}

/// Segments of the closed polygon near the zone.
fn near_segments(poly: &[V2], zone: &ReachZone) -> Vec<(V2, V2)> {
    let n = poly.len();
    (0..n)
        .filter_map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            let mid = (a + b) * 0.5;
            let reach = zone.radius_px + SEARCH_MARGIN_PX + 0.5 * (b - a).norm();
            (zone.path_distance(mid) <= reach).then_some((a, b))
        })
        .collect()
}

impl ContourTarget {
    /// Prepares `tracked` for scoring in `zone`.
    pub fn new(tracked: &TrackedVideo, zone: ReachZone, spacing_px: f64) -> Result<Self> {
        check_positive("spacing_px", spacing_px)?;
        let frames = tracked
            .contours_px
            .iter()
            .map(|c| TargetFrame {
                zone_points: c.iter().copied().filter(|p| zone.contains(*p)).collect(),
                near_segments: near_segments(c, &zone),
            })
            .collect();
        Ok(Self {
            zone,
            spacing_px,
            frames,
        })
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames.len()
    }

    /// Mean and largest distance between the tracked contour of `frame` and
    /// the closed polygon `model_px`, both ways, inside the zone.
    pub fn frame_distance(&self, frame: usize, model_px: &[V2]) -> (f64, f64) {
        let t = &self.frames[frame];
        let model_segments = near_segments(model_px, &self.zone);
        let poly: Vec<(f64, f64)> = model_px.iter().map(|p| (p.x, p.y)).collect();
        let model_points: Vec<V2> =
            resample_polygon(&poly, polygon_samples(model_px, self.spacing_px))
                .into_iter()
                .map(|(x, y)| V2::new(x, y))
                .filter(|p| self.zone.contains(*p))
                .collect();
        let dist = |p: V2, segs: &[(V2, V2)]| {
            segs.iter()
                .map(|(a, b)| point_segment_distance((p.x, p.y), (a.x, a.y), (b.x, b.y)))
                .fold(SEARCH_MARGIN_PX, f64::min)
        };
        let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
        for &p in &t.zone_points {
            let d = dist(p, &model_segments);
            sum += d;
            max = max.max(d);
            n += 1;
        }
        for &p in &model_points {
            let d = dist(p, &t.near_segments);
            sum += d;
            max = max.max(d);
            n += 1;
        }
        if n == 0 {
            (0.0, 0.0)
        } else {
            (sum / n as f64, max)
        }
    }
}

/// Points to resample a polygon at about `spacing_px`.
fn polygon_samples(poly: &[V2], spacing_px: f64) -> usize {
    let n = poly.len();
    let perimeter: f64 = (0..n).map(|i| (poly[(i + 1) % n] - poly[i]).norm()).sum();
    ((perimeter / spacing_px).ceil() as usize).max(n)
}

/// Contour distances of one model run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContourScore {
    /// Mean distance in the zone per frame, px.
    pub mean_px_per_frame: Vec<f64>,
    /// Largest distance in the zone per frame, px.
    pub max_px_per_frame: Vec<f64>,
    /// Mean over frames of the per-frame mean, px (the headline figure).
    pub mean_px: f64,
    /// Mean over frames of the per-frame largest distance, px.
    pub max_px: f64,
    /// The largest distance of any frame, px.
    pub worst_px: f64,
    /// First frame scored as the zone's diameter because the run became
    /// unstable.
    pub unstable_from_frame: Option<usize>,
}

impl ContourScore {
    fn from_frames(mean: Vec<f64>, max: Vec<f64>, unstable: Option<usize>) -> Self {
        let n = mean.len().max(1) as f64;
        Self {
            mean_px: mean.iter().sum::<f64>() / n,
            max_px: max.iter().sum::<f64>() / n,
            worst_px: max.iter().copied().fold(0.0, f64::max),
            mean_px_per_frame: mean,
            max_px_per_frame: max,
            unstable_from_frame: unstable,
        }
    }
}

/// `1 − model / still`: the fraction of the undeformed block's contour
/// mismatch the model removes.
pub fn skill(model_px: f64, still_px: f64) -> f64 {
    if still_px > 0.0 {
        1.0 - model_px / still_px
    } else {
        0.0
    }
}

/// Scores `params` by contour distance on a prepared video.
pub fn score_contour_run(
    prepared: &PreparedVideo,
    target: &ContourTarget,
    forces_n: &[f64],
    params: &MaterialParams,
    sim: &SimConfig,
) -> Result<ContourScore> {
    if target.frame_count() != prepared.frame_count() {
        return Err(PushError::LengthMismatch {
            what: "contour target frames",
            got: target.frame_count(),
            expected: prepared.frame_count(),
        });
    }
    let penalty = target.zone.diameter_px();
    let mut mean = Vec::with_capacity(prepared.frame_count());
    let mut max = Vec::with_capacity(prepared.frame_count());
    let mut unstable = None;
    simulate_frames(
        &prepared.mesh,
        &prepared.video.scenario,
        forces_n,
        params,
        sim,
        |f, pos, inst| {
            if inst.is_some() {
                unstable.get_or_insert(f);
                mean.push(penalty);
                max.push(penalty);
                return;
            }
            let (m, x) = target.frame_distance(f, &prepared.mesh.contour_px(pos));
            mean.push(m);
            max.push(x);
        },
    )?;
    Ok(ContourScore::from_frames(mean, max, unstable))
}

/// The undeformed block's contour distance: the model mesh at rest in
/// every frame.
pub fn still_block_contour_score(prepared: &PreparedVideo, target: &ContourTarget) -> ContourScore {
    let rest = prepared.mesh.contour_px(&prepared.mesh.rest_positions_px);
    let (mean, max): (Vec<f64>, Vec<f64>) = (0..target.frame_count())
        .map(|f| target.frame_distance(f, &rest))
        .unzip();
    ContourScore::from_frames(mean, max, None)
}

/// The configuration that leaves the block undeformed with zero forces
/// (forces only, no collisions), for F-score baselines.
pub fn still_config(sim: &SimConfig) -> SimConfig {
    SimConfig {
        mode: DrivingMode::ForcesOnVertices,
        ..*sim
    }
}

/// Classification by contour distance: per frame the model with the
/// smaller mean distance wins; the global vote sums each model's margin
/// (px) below the frame's mean of all models.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ContourClassification {
    /// Model labels.
    pub labels: Vec<String>,
    /// Mean distance per frame of each model (outer: model), px.
    pub mean_px_per_frame: Vec<Vec<f64>>,
    /// Each model's video score.
    pub scores: Vec<ContourScore>,
    /// Winners and votes.
    pub tally: Tally,
}

impl ContourClassification {
    /// Label of the global winner, if the votes do not tie.
    pub fn winner_label(&self) -> Option<&str> {
        self.tally.winner.map(|k| self.labels[k].as_str())
    }

    /// The verdict in words: the winner's label, or `tie between a and b`.
    pub fn verdict(&self) -> String {
        self.tally.verdict(&self.labels)
    }
}

/// Classifies one video among `models` by contour distance.
pub fn classify_by_contour(
    prepared: &PreparedVideo,
    target: &ContourTarget,
    forces_n: &[f64],
    models: &[MaterialModel],
    sim: &SimConfig,
) -> Result<ContourClassification> {
    if models.len() < 2 {
        return Err(PushError::InvalidParameter {
            name: "models",
            value: models.len() as f64,
            reason: "classification needs at least two material models",
        });
    }
    let scores: Vec<ContourScore> = models
        .iter()
        .map(|m| score_contour_run(prepared, target, forces_n, &m.params, sim))
        .collect::<Result<_>>()?;
    let negated: Vec<Vec<f64>> = scores
        .iter()
        .map(|s| s.mean_px_per_frame.iter().map(|d| -d).collect())
        .collect();
    Ok(ContourClassification {
        labels: models.iter().map(|m| m.label.clone()).collect(),
        mean_px_per_frame: scores.iter().map(|s| s.mean_px_per_frame.clone()).collect(),
        tally: tally(&negated),
        scores,
    })
}
