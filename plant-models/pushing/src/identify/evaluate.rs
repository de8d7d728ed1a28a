//! Running the mass-spring model against a recorded push and scoring it
//! with the pixel F-score per frame and μ(F) (§VII-B, Eq. 16–19).
//!
//! The model's mesh is initialised from the first frame's contour (its
//! bounding rectangle, §IV: "the system only requires visual analysis of
//! the first frame to initialise the predictors"), then fed back step after
//! step (§VI-F). Frames are 0.17 s apart, steps 0.1 s (§VIII-D): frame f is
//! compared with the state after round(t_f / h) steps; the finger path is
//! evaluated at each step and sensed forces are linearly interpolated
//! between frames (§VI-C). From the frame where the run turns unstable,
//! F = 0 (§VII-B).
use crate::error::{check_range, PushError, Result};
use crate::forces::MaterialParams;
use crate::mesh::Mesh;
use crate::raster::{f_score, rasterise_mesh, rasterise_polygon, running_mean, Bitmap, RasterGrid};
use crate::reference::Video;
use crate::scenario::PushScenario;
use crate::sim::{Instability, SimConfig, Simulator};
use crate::V2;
use serde::{Deserialize, Serialize};

/// Mesh resolution and image resolution of an evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvalSetup {
    /// Squares along the block's width and height (§VIII-A: 3×2, 10×5, 20×10).
    pub nx: usize,
    pub ny: usize,
    /// Raster cell side, px (1 = camera pixels as in the seed).
    pub cell_px: f64,
}

impl Default for EvalSetup {
    fn default() -> Self {
        Self {
            nx: 20,
            ny: 10,
            cell_px: 1.0,
        }
    }
}

/// A video with its ground-truth images and the model's initial mesh,
/// prepared once and scored many times.
#[derive(Debug, Clone)]
pub struct PreparedVideo {
    pub video: Video,
    pub grid: RasterGrid,
    pub truth: Vec<Bitmap>,
    pub mesh: Mesh,
}

/// The image region scored for a scenario: the block with room for the
/// bulges of a push around it.
pub fn raster_grid(scenario: &PushScenario, cell_px: f64) -> Result<RasterGrid> {
    let w = scenario.block_width_px;
    let h = scenario.block_height_px;
    RasterGrid::covering(V2::new(-0.3 * w, -4.0), V2::new(1.3 * w, 1.25 * h), cell_px)
}

impl PreparedVideo {
    /// Rasterises every ground-truth contour and builds the `nx × ny` mesh
    /// on the first contour's bounding box. `nx`/`ny` follow the video's
    /// orientation: the longer count goes along the longer side.
    pub fn new(video: Video, setup: &EvalSetup) -> Result<Self> {
        let truth = video.contours_px.clone();
        Self::with_truth_contours(video, setup, &truth)
    }

    /// As [`new`](Self::new), but the images scored against, and the
    /// first frame's bounding box the mesh starts from, come from
    /// `truth_contours` (one closed polygon per frame) instead of the
    /// video's raw tracked points — e.g. the tracked contour smoothed by a
    /// periodic spline and resampled densely
    /// ([`contour_score::track_video`](crate::contour_score::track_video)).
    pub fn with_truth_contours(
        video: Video,
        setup: &EvalSetup,
        truth_contours: &[Vec<V2>],
    ) -> Result<Self> {
        video.validate()?;
        if truth_contours.len() != video.contours_px.len() {
            return Err(PushError::LengthMismatch {
                what: "truth_contours",
                got: truth_contours.len(),
                expected: video.contours_px.len(),
            });
        }
        if let Some(f) = truth_contours.iter().position(|c| c.len() < 3) {
            return Err(PushError::MalformedInput {
                location: format!("truth contour of frame {f}"),
                reason: "fewer than 3 points".into(),
            });
        }
        check_range("cell_px", setup.cell_px, 1e-3, 1e3)?;
        for (name, n) in [("nx", setup.nx), ("ny", setup.ny)] {
            if n == 0 || n > 2000 {
                return Err(PushError::InvalidParameter {
                    name,
                    value: n as f64,
                    reason: "needs between 1 and 2000 squares",
                });
            }
        }
        let grid = raster_grid(&video.scenario, setup.cell_px)?;
        let mut truth = Vec::with_capacity(truth_contours.len());
        for c in truth_contours {
            let mut img = grid.empty();
            rasterise_polygon(&grid, &mut img, c);
            truth.push(img);
        }
        let first = &truth_contours[0];
        let mut lo = first[0];
        let mut hi = first[0];
        for p in first {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        let lo = V2::new(lo.x, lo.y.max(0.0));
        let (w, h) = (hi.x - lo.x, hi.y - lo.y);
        let (long, short) = (setup.nx.max(setup.ny), setup.nx.min(setup.ny));
        let (nx, ny) = if w >= h { (long, short) } else { (short, long) };
        let mesh = Mesh::grid(lo, w, h, nx, ny)?;
        Ok(Self {
            video,
            grid,
            truth,
            mesh,
        })
    }

    pub fn frame_count(&self) -> usize {
        self.truth.len()
    }
}

/// Score of one model run on one video.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunScore {
    /// F per frame (0 from the frame of an instability on).
    pub f_per_frame: Vec<f64>,
    /// μ(F) over all frames.
    pub mean_f: f64,
    /// First frame scored 0 because the run became unstable.
    pub unstable_from_frame: Option<usize>,
    pub instability: Option<Instability>,
}

/// Sensed force along the push direction at time `t_s`, N: linear
/// interpolation of the per-frame readings (§VI-C).
pub fn interpolate_force(scenario: &PushScenario, forces_n: &[f64], t_s: f64) -> f64 {
    if forces_n.is_empty() {
        return 0.0;
    }
    let x = t_s / scenario.frame_interval_s;
    if x <= 0.0 {
        return forces_n[0];
    }
    let i = x.floor() as usize;
    if i + 1 >= forces_n.len() {
        return forces_n[forces_n.len() - 1];
    }
    let w = x - i as f64;
    forces_n[i] * (1.0 - w) + forces_n[i + 1] * w
}

/// Runs the model through the video's frames, calling `on_frame` with the
/// frame index, the mesh positions and the instability (if any) after each.
/// `forces_n` (per frame, N) drives the force modes; pass the measured
/// readings or a force predictor's output.
pub fn simulate_frames(
    mesh: &Mesh,
    scenario: &PushScenario,
    forces_n: &[f64],
    params: &MaterialParams,
    sim: &SimConfig,
    mut on_frame: impl FnMut(usize, &[V2], Option<Instability>),
) -> Result<()> {
    let n_frames = scenario.frame_count();
    if forces_n.len() != n_frames {
        return Err(PushError::LengthMismatch {
            what: "forces_n",
            got: forces_n.len(),
            expected: n_frames,
        });
    }
    let mut s = Simulator::new(mesh, *params, *sim, scenario.table())?;
    let h = sim.step_s;
    let dir = scenario.push_direction();
    let mut n = 0usize;
    for f in 0..n_frames {
        let target = (scenario.frame_time_s(f) / h).round() as usize;
        while n < target && s.instability().is_none() {
            let t = (n + 1) as f64 * h;
            let finger = scenario.finger_at(t);
            let force = dir * interpolate_force(scenario, forces_n, t);
            let _ = s.step(Some(&finger), Some(force));
            n += 1;
        }
        on_frame(f, s.positions_px(), s.instability());
    }
    Ok(())
}

/// Scores `params` on a prepared video with the given per-frame forces.
pub fn score_run(
    prepared: &PreparedVideo,
    forces_n: &[f64],
    params: &MaterialParams,
    sim: &SimConfig,
) -> Result<RunScore> {
    score_run_observed(prepared, forces_n, params, sim, |_, _| {})
}

/// [`score_run`], also passing each frame's index and mesh positions to
/// `observe` (snapshots and progress from the same pass).
pub fn score_run_observed(
    prepared: &PreparedVideo,
    forces_n: &[f64],
    params: &MaterialParams,
    sim: &SimConfig,
    mut observe: impl FnMut(usize, &[V2]),
) -> Result<RunScore> {
    let mut img = prepared.grid.empty();
    let mut f_per_frame = Vec::with_capacity(prepared.frame_count());
    let mut unstable_from = None;
    let mut why = None;
    simulate_frames(
        &prepared.mesh,
        &prepared.video.scenario,
        forces_n,
        params,
        sim,
        |f, pos, inst| {
            observe(f, pos);
            if let Some(i) = inst {
                unstable_from.get_or_insert(f);
                why.get_or_insert(i);
                f_per_frame.push(0.0);
                return;
            }
            rasterise_mesh(&prepared.grid, &mut img, &prepared.mesh, pos);
            f_per_frame.push(f_score(&prepared.truth[f], &img).f_score);
        },
    )?;
    let mean_f = f_per_frame.iter().sum::<f64>() / f_per_frame.len().max(1) as f64;
    Ok(RunScore {
        f_per_frame,
        mean_f,
        unstable_from_frame: unstable_from,
        instability: why,
    })
}

/// Scores with the video's own sensed forces (the calibration setting of
/// §VIII-C: "the reaction forces measured with the force sensor were used").
pub fn score_with_measured_forces(
    prepared: &PreparedVideo,
    params: &MaterialParams,
    sim: &SimConfig,
) -> Result<RunScore> {
    score_run(prepared, &prepared.video.forces_n, params, sim)
}

/// μ(F) after every frame, for plots.
pub fn mean_f_curve(score: &RunScore) -> Vec<f64> {
    running_mean(&score.f_per_frame)
}
