//! Force predictor (FP) of §V: segmented least-squares regression of the
//! sensed force against the material's deformation (finger travel beyond
//! the point of first contact).
//!
//! Push phase: a straight-line family (Eq. 1–4) and a logarithmic family
//! (the same fit on ln x) are each grown from a few points until the
//! normalised error passes a threshold — the discontinuity — and then a new
//! segment starts there. The family whose longest single segment covers more
//! points is chosen. Retrieval phase: straight lines only (§VIII-C).
//!
//! The normalised error is the RMS residual of the window divided by the
//! range of all forces of the phase; threshold and minimum window are
//! estimates (the seed says "a threshold value" and "e.g. five" points).
use crate::error::{check_range, PushError, Result};
use crate::scenario::PushScenario;
use serde::{Deserialize, Serialize};

/// Points a segment starts with (§V: "e.g. five").
pub const MIN_SEGMENT_POINTS: usize = 5;
/// Normalised RMS error that marks a discontinuity (estimate).
pub const DEFAULT_ERROR_THRESHOLD: f64 = 0.04;
/// Fraction of the peak force that marks first contact (estimate).
pub const CONTACT_FRACTION: f64 = 0.05;

/// A regression family of §V.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Family {
    /// y = m x + y0.
    Linear,
    /// y = m ln x + y0.
    Logarithmic,
}

/// One fitted piece, valid on [x_start_px, x_end_px] of deformation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    pub family: Family,
    pub x_start_px: f64,
    pub x_end_px: f64,
    /// m, N per px (linear) or N (logarithmic).
    pub slope: f64,
    /// y0, N.
    pub intercept_n: f64,
    pub points: usize,
}

impl Segment {
    pub fn eval(&self, x_px: f64) -> f64 {
        match self.family {
            Family::Linear => self.slope * x_px + self.intercept_n,
            Family::Logarithmic => self.slope * x_px.max(1e-6).ln() + self.intercept_n,
        }
    }
}

/// Least squares line through (x, y), Eq. 2–4: (m, y0, squared error).
pub fn fit_line(x: &[f64], y: &[f64]) -> Option<(f64, f64, f64)> {
    let n = x.len() as f64;
    if x.len() < 2 || x.len() != y.len() {
        return None;
    }
    let (sx, sy) = (x.iter().sum::<f64>(), y.iter().sum::<f64>());
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| a * b).sum();
    let sxx: f64 = x.iter().map(|a| a * a).sum();
    let den = n * sxx - sx * sx;
    if den.abs() <= 1e-12 * n * sxx.max(1e-300) {
        return None;
    }
    let m = (n * sxy - sx * sy) / den;
    let y0 = sy / n - m * sx / n;
    let err = x
        .iter()
        .zip(y)
        .map(|(a, b)| (b - (m * a + y0)).powi(2))
        .sum();
    Some((m, y0, err))
}

/// Grows segments of one family over sorted (x, y) points.
pub fn segment_family(family: Family, x: &[f64], y: &[f64], threshold: f64) -> Vec<Segment> {
    let (xs, ys): (Vec<f64>, Vec<f64>) = match family {
        Family::Linear => (x.to_vec(), y.to_vec()),
        Family::Logarithmic => x
            .iter()
            .zip(y)
            .filter(|(a, _)| **a > 0.0)
            .map(|(a, b)| (a.ln(), *b))
            .unzip(),
    };
    let xs_raw: Vec<f64> = match family {
        Family::Linear => x.to_vec(),
        Family::Logarithmic => x.iter().copied().filter(|a| *a > 0.0).collect(),
    };
    let n = xs.len();
    let y_lo = ys.iter().copied().fold(f64::INFINITY, f64::min);
    let y_hi = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let scale = (y_hi - y_lo).max(1e-9);
    let mut segs = Vec::new();
    let mut start = 0;
    while start < n {
        let mut end = (start + MIN_SEGMENT_POINTS).min(n);
        if end - start < 2 {
            // One last point: extend the previous segment to cover it.
            if let Some(last) = segs.last_mut() {
                let s: &mut Segment = last;
                s.x_end_px = xs_raw[n - 1];
                s.points += n - start;
            }
            break;
        }
        let mut best = fit_line(&xs[start..end], &ys[start..end]);
        while end < n {
            match fit_line(&xs[start..=end], &ys[start..=end]) {
                Some(fit) => {
                    let rms = (fit.2 / (end + 1 - start) as f64).sqrt();
                    if rms / scale > threshold {
                        break;
                    }
                    best = Some(fit);
                    end += 1;
                }
                None => break,
            }
        }
        let (m, y0) = match best {
            Some((m, y0, _)) => (m, y0),
            None => (
                0.0,
                ys[start..end].iter().sum::<f64>() / (end - start) as f64,
            ),
        };
        segs.push(Segment {
            family,
            x_start_px: xs_raw[start],
            x_end_px: xs_raw[end - 1],
            slope: m,
            intercept_n: y0,
            points: end - start,
        });
        start = end;
    }
    segs
}

/// Evaluates a piecewise model: the segment containing x, else the nearest.
pub fn eval_segments(segs: &[Segment], x_px: f64) -> f64 {
    if segs.is_empty() {
        return 0.0;
    }
    for s in segs {
        if x_px >= s.x_start_px.min(s.x_end_px) && x_px <= s.x_start_px.max(s.x_end_px) {
            return s.eval(x_px);
        }
    }
    // Outside every segment: extrapolate the closest one.
    let closest = segs
        .iter()
        .min_by(|a, b| {
            let da = (a.x_start_px - x_px).abs().min((a.x_end_px - x_px).abs());
            let db = (b.x_start_px - x_px).abs().min((b.x_end_px - x_px).abs());
            da.total_cmp(&db)
        })
        .expect("non-empty");
    closest.eval(x_px)
}

/// The learned force predictor of one material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ForcePredictor {
    /// Finger depth (below the block top) where contact was detected, px.
    pub contact_depth_px: f64,
    pub push_family: Family,
    pub push_segments: Vec<Segment>,
    pub retrieval_segments: Vec<Segment>,
    /// Longest single segment of each family, points (linear, logarithmic).
    pub coverage: (usize, usize),
}

impl ForcePredictor {
    /// Fits the predictor to one video's finger path and force readings.
    pub fn fit(scenario: &PushScenario, forces_n: &[f64], threshold: f64) -> Result<Self> {
        check_range("threshold", threshold, 1e-6, 1.0)?;
        let n = scenario.frame_count();
        if forces_n.len() != n {
            return Err(PushError::LengthMismatch {
                what: "forces_n",
                got: forces_n.len(),
                expected: n,
            });
        }
        if let Some(i) = forces_n.iter().position(|f| !f.is_finite()) {
            return Err(PushError::MalformedInput {
                location: format!("frame {i}"),
                reason: "force is not finite".into(),
            });
        }
        let depth: Vec<f64> = (0..n)
            .map(|f| scenario.finger_depth_px(scenario.frame_time_s(f)))
            .collect();
        let push: Vec<usize> = (0..n).filter(|&f| scenario.is_push_frame(f)).collect();
        let peak = push.iter().map(|&f| forces_n[f]).fold(0.0, f64::max);
        if peak <= 0.0 {
            return Err(PushError::MalformedInput {
                location: "push phase".into(),
                reason: "the force never rises: no contact to learn from".into(),
            });
        }
        let contact = push
            .iter()
            .copied()
            .find(|&f| forces_n[f] > CONTACT_FRACTION * peak)
            .ok_or_else(|| PushError::MalformedInput {
                location: "push phase".into(),
                reason: "no contact found".into(),
            })?;
        // The deformation at the contact frame is taken as zero (§V).
        let contact_depth = depth[contact];
        let (px, py): (Vec<f64>, Vec<f64>) = push
            .iter()
            .filter(|&&f| f >= contact)
            .map(|&f| (depth[f] - contact_depth, forces_n[f]))
            .unzip();
        if px.len() < MIN_SEGMENT_POINTS {
            return Err(PushError::MalformedInput {
                location: "push phase".into(),
                reason: format!(
                    "only {} frames in contact, need {MIN_SEGMENT_POINTS}",
                    px.len()
                ),
            });
        }
        let lin = segment_family(Family::Linear, &px, &py, threshold);
        let log = segment_family(Family::Logarithmic, &px, &py, threshold);
        let cover = |s: &[Segment]| s.iter().map(|x| x.points).max().unwrap_or(0);
        let coverage = (cover(&lin), cover(&log));
        let (push_family, push_segments) = if coverage.1 > coverage.0 {
            (Family::Logarithmic, log)
        } else {
            (Family::Linear, lin)
        };
        // Retrieval: x decreases with time; fit on sorted x.
        let mut rx: Vec<(f64, f64)> = (0..n)
            .filter(|&f| !scenario.is_push_frame(f) && depth[f] >= contact_depth)
            .map(|f| (depth[f] - contact_depth, forces_n[f]))
            .collect();
        rx.sort_by(|a, b| a.0.total_cmp(&b.0));
        let (rxx, rxy): (Vec<f64>, Vec<f64>) = rx.into_iter().unzip();
        let retrieval_segments = if rxx.len() >= 2 {
            segment_family(Family::Linear, &rxx, &rxy, threshold)
        } else {
            Vec::new()
        };
        Ok(Self {
            contact_depth_px: contact_depth,
            push_family,
            push_segments,
            retrieval_segments,
            coverage,
        })
    }

    /// Predicted force for a finger `depth_px` below the block top, N.
    pub fn predict(&self, depth_px: f64, pushing: bool) -> f64 {
        let x = depth_px - self.contact_depth_px;
        if x < 0.0 {
            return 0.0;
        }
        let segs = if pushing || self.retrieval_segments.is_empty() {
            &self.push_segments
        } else {
            &self.retrieval_segments
        };
        eval_segments(segs, x).max(0.0)
    }

    /// Predicted force per frame of any scenario (same finger-path shape).
    pub fn predict_series(&self, scenario: &PushScenario) -> Vec<f64> {
        (0..scenario.frame_count())
            .map(|f| {
                self.predict(
                    scenario.finger_depth_px(scenario.frame_time_s(f)),
                    scenario.is_push_frame(f),
                )
            })
            .collect()
    }
}
