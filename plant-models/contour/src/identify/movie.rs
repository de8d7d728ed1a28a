//! A synthetic deforming-contour movie in the spirit of the paper's
//! jellyfish (§IV-B; no movie ships with the seed), and the held-out-frame
//! experiment of its Fig. 6: fit the contour × time surface to every 10th
//! frame and compare the model's contour with the truth at frames it never
//! saw, against linear interpolation in time between the neighbouring
//! used frames.
//!
//! The ground truth is *not* a spline: a closed curve given by
//! trigonometric series (a pulsating, slowly turning, three-lobed bell)
//! whose centre translates along a wavy path. It is observed the way the
//! paper observes its frames: the centroid of the drawn region (polygon of
//! 720 true boundary points) and the distance from it to the boundary
//! along rays at N equally spaced angles, plus Gaussian noise.
use crate::error::Result;
use crate::identify::distance::{point_polygon_distance, ray_exit_distance};
use crate::identify::tracked::{
    fit_movie, polygon_centroid, MovieFit, MovieOptions, Point, Signature,
};
use crate::ContourError;
use rand::Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// The pulsating, translating contour (all lengths in px, time in frames).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PulsatingContour {
    /// Frames 0 … frames − 1 (the paper's movie: 101).
    pub frames: usize,
    /// Mean radius, px.
    pub radius_px: f64,
    /// Relative amplitude of the pulsation of the radius.
    pub pulse: f64,
    /// Period of the pulsation, frames.
    pub period_frames: f64,
    /// Relative amplitude of the elongation (cos 2θ) mode.
    pub elongation: f64,
    /// Relative amplitude of the three-lobed mode (cos 3θ), travelling with
    /// the pulsation.
    pub lobes: f64,
    /// Rotation of the elongation per frame, rad.
    pub turn_rad_per_frame: f64,
    /// Centre at frame 0, px.
    pub start_px: Point,
    /// Drift of the centre per frame, px.
    pub drift_px_per_frame: Point,
    /// Amplitude of the centre's sideways sway, px.
    pub sway_px: f64,
}

impl Default for PulsatingContour {
    /// 101 frames as the paper's movie; two pulsations over the movie, so
    /// every 10th frame samples a pulsation five times (all estimates of a
    /// swimming bell, chosen before any fit was run).
    fn default() -> Self {
        Self {
            frames: 101,
            radius_px: 40.0,
            pulse: 0.15,
            period_frames: 50.0,
            elongation: 0.18,
            lobes: 0.06,
            turn_rad_per_frame: 0.004,
            start_px: (80.0, 90.0),
            drift_px_per_frame: (1.2, 0.3),
            sway_px: 10.0,
        }
    }
}

impl PulsatingContour {
    /// Centre of the shape (not its centroid) at a frame.
    pub fn centre(&self, frame: f64) -> Point {
        (
            self.start_px.0 + self.drift_px_per_frame.0 * frame,
            self.start_px.1
                + self.drift_px_per_frame.1 * frame
                + self.sway_px * (TAU * frame / (1.6 * self.period_frames)).sin(),
        )
    }

    /// Radius about [`centre`](Self::centre) at angle θ.
    pub fn radius(&self, frame: f64, angle_rad: f64) -> f64 {
        let ph = TAU * frame / self.period_frames;
        self.radius_px
            * (1.0 + self.pulse * ph.sin())
            * (1.0
                + self.elongation * (2.0 * (angle_rad - self.turn_rad_per_frame * frame)).cos()
                + self.lobes * (3.0 * angle_rad + ph).cos())
    }

    /// The true contour at a frame: `n` points, counter-clockwise.
    pub fn contour(&self, frame: f64, n: usize) -> Vec<Point> {
        let c = self.centre(frame);
        (0..n)
            .map(|k| {
                let a = TAU * k as f64 / n as f64;
                let r = self.radius(frame, a);
                (c.0 + r * a.cos(), c.1 + r * a.sin())
            })
            .collect()
    }

    /// What a tracker reports at a frame: the drawn region's centroid and
    /// the boundary distance along `n_angles` rays (θ_j = 2πj/N), each with
    /// Gaussian noise of `sigma_px`.
    pub fn observe(
        &self,
        frame: usize,
        n_angles: usize,
        sigma_px: f64,
        rng: &mut impl Rng,
    ) -> Result<Signature> {
        let drawn = self.contour(frame as f64, TRUTH_POINTS);
        let (centre, _) = polygon_centroid(&drawn).ok_or_else(|| {
            ContourError::Unsolvable(format!("frame {frame}: the true contour has no area"))
        })?;
        let angles: Vec<f64> = (0..n_angles)
            .map(|j| TAU * j as f64 / n_angles as f64)
            .collect();
        let mut radii = Vec::with_capacity(n_angles);
        for &a in &angles {
            let r = ray_exit_distance(centre, a, &drawn).ok_or_else(|| {
                ContourError::Unsolvable(format!("frame {frame}: a ray misses the contour"))
            })?;
            let e: f64 = StandardNormal.sample(rng);
            radii.push(r + sigma_px * e);
        }
        Signature::new(&format!("frame {frame}"), centre, &angles, &radii)
    }
}

/// Points of the drawn (true) contour.
pub const TRUTH_POINTS: usize = 720;

/// The paper's held-out frames 26, 46, 66, 86 (1-based), as 0-based frames.
pub const PAPER_HELD_OUT: [usize; 4] = [25, 45, 65, 85];

/// Errors at one held-out frame, px.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HeldOutRow {
    /// 0-based frame.
    pub frame: usize,
    /// Mean distance to the true contour of the spline model's points at
    /// the data angles.
    pub spline_mean_px: f64,
    /// Largest such distance.
    pub spline_max_px: f64,
    /// Same for linear interpolation in time of the neighbouring frames'
    /// centroids and radii.
    pub linear_mean_px: f64,
    /// Largest such distance.
    pub linear_max_px: f64,
    /// Mean distance of the spline contour at 360 angles.
    pub spline_dense_mean_px: f64,
    /// Mean distance of the linear model's polygon (through its points at
    /// the data angles), sampled at 360 points along it.
    pub linear_dense_mean_px: f64,
    /// Distance of the spline's centroid path from the true centroid.
    pub spline_centre_px: f64,
    /// Distance of the linearly interpolated centroid from the true one.
    pub linear_centre_px: f64,
}

/// The held-out experiment: observe every `every`-th frame with
/// `n_angles` rays and noise `sigma_px`, fit, and score the held-out
/// frames.
pub fn held_out_study(
    movie: &PulsatingContour,
    every: usize,
    n_angles: usize,
    held_out: &[usize],
    sigma_px: f64,
    opts: &MovieOptions,
    rng: &mut impl Rng,
) -> Result<(MovieFit, Vec<HeldOutRow>)> {
    let every = every.max(1);
    let used: Vec<usize> = (0..movie.frames).step_by(every).collect();
    let mut data = Vec::with_capacity(used.len());
    for &f in &used {
        data.push((f as f64, movie.observe(f, n_angles, sigma_px, rng)?));
    }
    let fit = fit_movie(&data, opts)?;
    let mut rows = Vec::new();
    for &h in held_out {
        let Some(k) = used.iter().rposition(|&u| u <= h) else {
            continue;
        };
        if k + 1 >= used.len() || used[k] == h {
            continue;
        }
        let (fa, fb) = (used[k], used[k + 1]);
        let w = (h - fa) as f64 / (fb - fa) as f64;
        let (sa, sb) = (&data[k].1, &data[k + 1].1);
        let truth = movie.contour(h as f64, TRUTH_POINTS);
        let (true_centroid, _) = polygon_centroid(&truth)
            .ok_or_else(|| ContourError::Unsolvable(format!("frame {h}: no area")))?;
        let lerp = |a: f64, b: f64| a + w * (b - a);
        let lin_c = (
            lerp(sa.centre.0, sb.centre.0),
            lerp(sa.centre.1, sb.centre.1),
        );
        let lin_pts: Vec<Point> = sa
            .angles_rad
            .iter()
            .enumerate()
            .map(|(j, &a)| {
                let r = lerp(sa.radii[j], sb.radii[j]);
                (lin_c.0 + r * a.cos(), lin_c.1 + r * a.sin())
            })
            .collect();
        let sp_c = fit.centre_at(h as f64);
        let sp_pts: Vec<Point> = sa
            .angles_rad
            .iter()
            .map(|&a| {
                let r = fit.radius_at(h as f64, a);
                (sp_c.0 + r * a.cos(), sp_c.1 + r * a.sin())
            })
            .collect();
        let (sm, sx) = mean_max(&sp_pts, &truth);
        let (lm, lx) = mean_max(&lin_pts, &truth);
        let (sdm, _) = mean_max(&fit.contour_at(h as f64, 360), &truth);
        let (ldm, _) = mean_max(&resample_polygon(&lin_pts, 360), &truth);
        let dist = |p: Point| (p.0 - true_centroid.0).hypot(p.1 - true_centroid.1);
        rows.push(HeldOutRow {
            frame: h,
            spline_mean_px: sm,
            spline_max_px: sx,
            linear_mean_px: lm,
            linear_max_px: lx,
            spline_dense_mean_px: sdm,
            linear_dense_mean_px: ldm,
            spline_centre_px: dist(sp_c),
            linear_centre_px: dist(lin_c),
        });
    }
    Ok((fit, rows))
}

/// Mean and largest distance of `points` to the polygon `truth`.
pub fn mean_max(points: &[Point], truth: &[Point]) -> (f64, f64) {
    let d: Vec<f64> = points
        .iter()
        .map(|&p| point_polygon_distance(p, truth))
        .collect();
    let n = d.len().max(1) as f64;
    (
        d.iter().sum::<f64>() / n,
        d.iter().copied().fold(0.0, f64::max),
    )
}

/// `n` points equally spaced by arc length along the closed polygon.
pub fn resample_polygon(poly: &[Point], n: usize) -> Vec<Point> {
    let m = poly.len();
    if m == 0 || n == 0 {
        return Vec::new();
    }
    let seg: Vec<f64> = (0..m)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % m]);
            (b.0 - a.0).hypot(b.1 - a.1)
        })
        .collect();
    let total: f64 = seg.iter().sum();
    let mut out = Vec::with_capacity(n);
    let (mut i, mut start) = (0usize, 0.0);
    for k in 0..n {
        let target = total * k as f64 / n as f64;
        while i + 1 < m && start + seg[i] < target {
            start += seg[i];
            i += 1;
        }
        let u = if seg[i] > 0.0 {
            ((target - start) / seg[i]).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (poly[i], poly[(i + 1) % m]);
        out.push((a.0 + u * (b.0 - a.0), a.1 + u * (b.1 - a.1)));
    }
    out
}
