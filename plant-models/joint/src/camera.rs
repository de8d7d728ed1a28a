//! The camera that watches the marker on the link (paper: an NTSC CCD at
//! 30 frames/s for control; angles from the second-order moments of a black
//! 9.5 × 19.5 mm rectangle).
//!
//! A frame is *captured* every `1/frame_rate_hz` s of plant time (at the
//! first plant step that reaches the capture instant, so with 1 ms steps the
//! capture jitter is ≤ 1 ms), and becomes *available* `latency_frames`
//! frame periods later. Each captured value gets Gaussian noise from a seeded
//! RNG: marker-angle noise and end-point position noise (pixel noise × scale).
//! A frame captured inside an occlusion window carries no measurement.
//!
//! Left out: motion blur, lens distortion, rolling shutter, and the
//! angle-dependent foreshortening of the marker in 3D (each plane's angle is
//! measured as if viewed square-on).

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::{check_finite, check_positive, PlantError};

/// Camera parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraParams {
    /// Frames per second. Paper: NTSC, 30 frames/s.
    pub frame_rate_hz: f64,
    /// Frames of latency between capture and availability (0..=3).
    /// Estimate: one frame (grab + moment computation).
    pub latency_frames: u32,
    /// Standard deviation of the measured marker angle (deg). Estimate:
    /// sub-pixel moment estimate of a ~100 px marker.
    pub angle_noise_deg: f64,
    /// Standard deviation of one pixel coordinate (px). Estimate.
    pub pixel_noise_px: f64,
    /// Image scale (mm per pixel). Estimate: 640 px over a 64 mm field.
    pub mm_per_px: f64,
    /// Occlusion windows `[start_s, end_s)` of plant time.
    pub occlusions_s: Vec<[f64; 2]>,
}

impl Default for CameraParams {
    fn default() -> Self {
        Self {
            frame_rate_hz: 30.0,
            latency_frames: 1,
            angle_noise_deg: 0.03,
            pixel_noise_px: 0.3,
            mm_per_px: 0.1,
            occlusions_s: Vec::new(),
        }
    }
}

impl CameraParams {
    /// Rejects bad values, naming the field.
    pub fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        let p = |f: &str| format!("{prefix}{f}");
        check_positive(&p("frame_rate_hz"), self.frame_rate_hz)?;
        if self.latency_frames > 3 {
            return Err(PlantError::param(&p("latency_frames"), "must be ≤ 3"));
        }
        for (name, v) in [
            ("angle_noise_deg", self.angle_noise_deg),
            ("pixel_noise_px", self.pixel_noise_px),
        ] {
            check_finite(&p(name), v)?;
            if v < 0.0 {
                return Err(PlantError::param(&p(name), "must be ≥ 0"));
            }
        }
        check_positive(&p("mm_per_px"), self.mm_per_px)?;
        for (i, w) in self.occlusions_s.iter().enumerate() {
            let f = p(&format!("occlusions_s[{i}]"));
            check_finite(&f, w[0])?;
            check_finite(&f, w[1])?;
            if w[1] < w[0] {
                return Err(PlantError::param(&f, "end before start"));
            }
        }
        Ok(())
    }
}

/// One camera frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraFrame {
    /// Frame number (0 = first capture at t = 0).
    pub index: u64,
    /// Plant time of the capture (s).
    pub capture_time_s: f64,
    /// Plant time from which the frame can be read (s).
    pub available_time_s: f64,
    /// Measured angles (deg): 2D `[θ, 0]`, 3D `[α, β]`; `None` if occluded.
    pub angles_deg: Option<[f64; 2]>,
    /// Measured link end (mm, socket frame of the first plane: x, y); `None`
    /// if occluded.
    pub end_mm: Option<[f64; 2]>,
}

const QUEUE: usize = 4;

/// Camera state.
#[derive(Clone, Debug)]
pub struct Camera {
    params: CameraParams,
    period_s: f64,
    next_index: u64,
    queue: [Option<CameraFrame>; QUEUE],
    latest: Option<CameraFrame>,
    fresh: bool,
    two_angles: bool,
    /// Earliest `available_time_s` of a queued frame not yet published
    /// (∞ if none): with no capture due before it, `update` has nothing to
    /// do (see [`Camera::is_due`]).
    pending_available_s: f64,
}

impl Camera {
    /// A camera whose first capture is at t = 0, measuring one angle (2D)
    /// or two (3D, `two_angles`).
    pub fn new(params: CameraParams, two_angles: bool) -> Result<Self, PlantError> {
        params.validate("camera.")?;
        Ok(Self {
            period_s: 1.0 / params.frame_rate_hz,
            params,
            next_index: 0,
            queue: [None; QUEUE],
            latest: None,
            fresh: false,
            two_angles,
            pending_available_s: f64::INFINITY,
        })
    }

    /// Parameters.
    pub fn params(&self) -> &CameraParams {
        &self.params
    }

    /// Called after each plant step at time `t_s` with the true angles (deg)
    /// and link end (mm): captures a frame if one is due and publishes frames
    /// whose latency has elapsed.
    pub fn update(
        &mut self,
        t_s: f64,
        angles_deg: [f64; 2],
        end_mm: [f64; 2],
        rng: &mut ChaCha8Rng,
    ) {
        let eps = 1e-9;
        while self.next_index as f64 * self.period_s <= t_s + eps {
            let capture = self.next_index as f64 * self.period_s;
            let occluded = self
                .params
                .occlusions_s
                .iter()
                .any(|w| capture >= w[0] && capture < w[1]);
            // Always draw the noise, so occlusions do not shift later frames.
            let n: [f64; 4] = core::array::from_fn(|_| StandardNormal.sample(rng));
            let sa = self.params.angle_noise_deg;
            let sp = self.params.pixel_noise_px * self.params.mm_per_px;
            let frame = CameraFrame {
                index: self.next_index,
                capture_time_s: capture,
                available_time_s: capture + self.params.latency_frames as f64 * self.period_s,
                angles_deg: (!occluded).then(|| {
                    [
                        angles_deg[0] + sa * n[0],
                        if self.two_angles {
                            angles_deg[1] + sa * n[1]
                        } else {
                            0.0
                        },
                    ]
                }),
                end_mm: (!occluded).then(|| [end_mm[0] + sp * n[2], end_mm[1] + sp * n[3]]),
            };
            self.queue[(self.next_index as usize) % QUEUE] = Some(frame);
            self.next_index += 1;
        }
        // Publish the newest frame that is available.
        let mut best: Option<CameraFrame> = None;
        for f in self.queue.iter().flatten() {
            if f.available_time_s <= t_s + eps && best.is_none_or(|b| f.index > b.index) {
                best = Some(*f);
            }
        }
        if let Some(b) = best {
            if self.latest.is_none_or(|l| b.index > l.index) {
                self.latest = Some(b);
                self.fresh = true;
            }
        }
        let published = self.latest.map(|l| l.index);
        self.pending_available_s = self
            .queue
            .iter()
            .flatten()
            .filter(|f| published.is_none_or(|i| f.index > i))
            .map(|f| f.available_time_s)
            .fold(f64::INFINITY, f64::min);
    }

    /// Whether [`Self::update`] at `t_s` would capture or publish a frame.
    /// When it would not, the update leaves the camera (and its noise
    /// stream) untouched, so a caller may skip it — and skip computing the
    /// measurement it would be given.
    #[inline]
    pub fn is_due(&self, t_s: f64) -> bool {
        let eps = 1e-9;
        self.next_index as f64 * self.period_s <= t_s + eps || self.pending_available_s <= t_s + eps
    }

    /// The newest available frame (occluded or not), if any.
    pub fn latest(&self) -> Option<&CameraFrame> {
        self.latest.as_ref()
    }

    /// The newest available frame if it was not returned before.
    pub fn take_new(&mut self) -> Option<CameraFrame> {
        if self.fresh {
            self.fresh = false;
            self.latest
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn frame_rate_latency_and_occlusion() {
        let p = CameraParams {
            occlusions_s: vec![[0.5, 0.6]],
            ..CameraParams::default()
        };
        let mut cam = Camera::new(p, false).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut frames = Vec::new();
        for k in 0..=1000 {
            let t = k as f64 * 1e-3;
            cam.update(t, [t, 0.0], [0.0, 27.0], &mut rng);
            if let Some(f) = cam.take_new() {
                assert!(f.available_time_s <= t + 1e-9);
                assert!(t - f.available_time_s < 1.001e-3, "published late");
                frames.push((t, f));
            }
        }
        // Frames captured at 0..=29/30 s, available one frame later: 0..=29.
        assert_eq!(frames.len(), 30);
        for (t, f) in &frames {
            // The angle seen is the one at capture, one frame (33 ms) old.
            if let Some(a) = f.angles_deg {
                assert!((a[0] - f.capture_time_s).abs() < 0.2);
                assert!((t - f.capture_time_s - 1.0 / 30.0).abs() < 1.001e-3);
            }
        }
        let occluded: Vec<u64> = frames
            .iter()
            .filter(|(_, f)| f.angles_deg.is_none())
            .map(|(_, f)| f.index)
            .collect();
        assert_eq!(occluded, vec![15, 16, 17]);
    }

    #[test]
    fn skipping_updates_that_are_not_due_changes_nothing() {
        let p = CameraParams {
            occlusions_s: vec![[0.5, 0.6]],
            latency_frames: 2,
            ..CameraParams::default()
        };
        let mut every = Camera::new(p.clone(), true).unwrap();
        let mut skipping = Camera::new(p, true).unwrap();
        let (mut rng_a, mut rng_b) = (ChaCha8Rng::seed_from_u64(5), ChaCha8Rng::seed_from_u64(5));
        let mut skipped = 0;
        for k in 0..=3000 {
            let t = k as f64 * 1e-3;
            let m = ([t, -t], [0.1 * t, 27.0]);
            every.update(t, m.0, m.1, &mut rng_a);
            if skipping.is_due(t) {
                skipping.update(t, m.0, m.1, &mut rng_b);
            } else {
                skipped += 1;
            }
            assert_eq!(every.take_new(), skipping.take_new(), "t = {t}");
        }
        assert!(skipped > 2800, "{skipped}");
    }

    #[test]
    fn noise_has_the_stated_spread() {
        let mut cam = Camera::new(
            CameraParams {
                angle_noise_deg: 0.5,
                ..CameraParams::default()
            },
            false,
        )
        .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let mut sum = 0.0;
        let mut sq = 0.0;
        let mut n = 0.0;
        for k in 0..3000 {
            let t = k as f64 / 30.0;
            cam.update(t, [10.0, 0.0], [0.0, 0.0], &mut rng);
            if let Some(a) = cam.take_new().and_then(|f| f.angles_deg) {
                sum += a[0] - 10.0;
                sq += (a[0] - 10.0).powi(2);
                n += 1.0;
            }
        }
        let mean = sum / n;
        let sd = (sq / n - mean * mean).sqrt();
        assert!(
            mean.abs() < 0.05 && (sd - 0.5).abs() < 0.05,
            "mean {mean}, sd {sd}"
        );
    }
}
