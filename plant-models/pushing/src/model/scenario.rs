//! The experiment of §VIII-A and §VIII-D of the seed: a rectangular block on
//! a table, pushed by a cylindrical finger (seen as a circle) and then the
//! finger retrieved, 50 frames each, at the three sites of §VIII-A.
//!
//! Geometry is in image pixels with the seed's camera scales; the finger's
//! size, depth and approach gap are not given in the seed and are estimates.
//! The camera looks at the block from the side: the table is the line
//! y = 0, the finger comes down from above (the seed's "push down").
use crate::collision::{Finger, Table};
use crate::error::{check_positive, check_range, Result};
use crate::V2;
use serde::{Deserialize, Serialize};

/// Block length, m (§VIII-A: 8.5 cm).
pub const BLOCK_LENGTH_M: f64 = 0.085;
/// Block width, m (§VIII-A: 5 cm); the side seen when it lies on its long side.
pub const BLOCK_WIDTH_M: f64 = 0.05;
/// Camera scale for the sponge, px/m (§VIII-A).
pub const SPONGE_SCALE_PX_PER_M: f64 = 4600.0;
/// Camera scale for the plasticine, px/m (§VIII-A).
pub const PLASTICINE_SCALE_PX_PER_M: f64 = 4350.0;
/// Time between frames, s (§VIII-D: 0.17 ± 0.007 s).
pub const FRAME_INTERVAL_S: f64 = 0.17;
/// Integration step h, s (§VII-A and §VIII-D: 0.1 s).
pub const STEP_S: f64 = 0.1;
/// Frames of the push phase and of the retrieval phase (§VIII-D: ~50 each).
pub const FRAMES_PER_PHASE: usize = 50;
/// Finger radius, m (estimate: a finger of about 2 cm diameter).
pub const FINGER_RADIUS_M: f64 = 0.01;
/// Deepest finger travel into the block, m (estimate).
pub const PUSH_DEPTH_M: f64 = 0.015;
/// Gap between finger and block at frame 0, m (estimate).
pub const APPROACH_GAP_M: f64 = 0.003;
/// Distance of the "near the corner" push from the block's end, m (estimate).
pub const CORNER_OFFSET_M: f64 = 0.015;

/// Where the block is pushed (§VIII-A).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PushSite {
    /// 1) Middle of the longest side (the training push in the seed).
    MiddleLongSide,
    /// 2) Close to the corner of the longest side.
    NearCorner,
    /// 3) Middle of the shortest side (the block stands on its short side).
    MiddleShortSide,
}

impl PushSite {
    /// All three, in the seed's order.
    pub const ALL: [PushSite; 3] = [
        PushSite::MiddleLongSide,
        PushSite::NearCorner,
        PushSite::MiddleShortSide,
    ];

    /// Short lowercase name for files and command lines.
    pub fn name(self) -> &'static str {
        match self {
            PushSite::MiddleLongSide => "middle-long",
            PushSite::NearCorner => "corner",
            PushSite::MiddleShortSide => "middle-short",
        }
    }
}

/// One push experiment: block, finger path and timing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PushScenario {
    pub site: PushSite,
    /// Block width seen by the camera (along the table), px.
    pub block_width_px: f64,
    /// Block height seen by the camera, px.
    pub block_height_px: f64,
    /// Horizontal position of the finger's centre, px (block spans [0, width]).
    pub finger_x_px: f64,
    pub finger_radius_px: f64,
    /// Deepest travel of the finger below the block's top, px.
    pub push_depth_px: f64,
    /// Gap between finger and block top at frame 0, px.
    pub approach_gap_px: f64,
    pub frames_push: usize,
    pub frames_retrieval: usize,
    pub frame_interval_s: f64,
}

impl PushScenario {
    /// The seed's set-up for a block seen at `scale_px_per_m`.
    pub fn seed(site: PushSite, scale_px_per_m: f64) -> Result<Self> {
        check_positive("scale_px_per_m", scale_px_per_m)?;
        let (w, h) = match site {
            PushSite::MiddleLongSide | PushSite::NearCorner => (BLOCK_LENGTH_M, BLOCK_WIDTH_M),
            PushSite::MiddleShortSide => (BLOCK_WIDTH_M, BLOCK_LENGTH_M),
        };
        let finger_x = match site {
            PushSite::NearCorner => w - CORNER_OFFSET_M,
            _ => 0.5 * w,
        };
        let s = Self {
            site,
            block_width_px: w * scale_px_per_m,
            block_height_px: h * scale_px_per_m,
            finger_x_px: finger_x * scale_px_per_m,
            finger_radius_px: FINGER_RADIUS_M * scale_px_per_m,
            push_depth_px: PUSH_DEPTH_M * scale_px_per_m,
            approach_gap_px: APPROACH_GAP_M * scale_px_per_m,
            frames_push: FRAMES_PER_PHASE,
            frames_retrieval: FRAMES_PER_PHASE,
            frame_interval_s: FRAME_INTERVAL_S,
        };
        s.validate()?;
        Ok(s)
    }

    /// Checks every field; errors name the bad one.
    pub fn validate(&self) -> Result<()> {
        check_positive("block_width_px", self.block_width_px)?;
        check_positive("block_height_px", self.block_height_px)?;
        check_range("finger_x_px", self.finger_x_px, 0.0, self.block_width_px)?;
        check_positive("finger_radius_px", self.finger_radius_px)?;
        check_range(
            "push_depth_px",
            self.push_depth_px,
            0.0,
            0.9 * self.block_height_px,
        )?;
        check_range("approach_gap_px", self.approach_gap_px, 0.0, f64::MAX)?;
        check_positive("frame_interval_s", self.frame_interval_s)?;
        if self.frames_push == 0 {
            return Err(crate::PushError::InvalidParameter {
                name: "frames_push",
                value: 0.0,
                reason: "needs at least one frame",
            });
        }
        Ok(())
    }

    /// Total number of frames.
    pub fn frame_count(&self) -> usize {
        self.frames_push + self.frames_retrieval
    }

    /// Time of frame `f`, s.
    pub fn frame_time_s(&self, f: usize) -> f64 {
        f as f64 * self.frame_interval_s
    }

    /// How deep the finger's lowest point is below the block's top at time
    /// `t_s`, px (negative before contact). Linear in, linear out.
    pub fn finger_depth_px(&self, t_s: f64) -> f64 {
        let t_push = self.frames_push as f64 * self.frame_interval_s;
        let t_end = self.frame_count() as f64 * self.frame_interval_s;
        let travel = self.approach_gap_px + self.push_depth_px;
        let s = if t_s <= t_push {
            (t_s / t_push).max(0.0)
        } else if t_end > t_push {
            (1.0 - (t_s - t_push) / (t_end - t_push)).max(0.0)
        } else {
            0.0
        };
        -self.approach_gap_px + travel * s
    }

    /// The finger at time `t_s`.
    pub fn finger_at(&self, t_s: f64) -> Finger {
        let depth = self.finger_depth_px(t_s);
        Finger {
            centre_px: V2::new(
                self.finger_x_px,
                self.block_height_px + self.finger_radius_px - depth,
            ),
            radius_px: self.finger_radius_px,
        }
    }

    /// Direction the finger pushes in (unit).
    pub fn push_direction(&self) -> V2 {
        V2::new(0.0, -1.0)
    }

    /// Whether frame `f` belongs to the push phase (else retrieval).
    pub fn is_push_frame(&self, f: usize) -> bool {
        f < self.frames_push
    }

    /// The table the block rests on: y ≥ 0.
    pub fn table(&self) -> Table {
        Table {
            point_px: V2::new(0.0, 0.0),
            normal: V2::new(0.0, 1.0),
        }
    }
}
