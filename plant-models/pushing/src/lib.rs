//! Deformable blocks under robotic pushing: the multi-modal model of
//! Arriola-Rios & Wyatt (seed 001, SPEC §4).
//!
//! [`model`] holds the block being calibrated (mesh, forces, plasticity,
//! integrators, collisions, the push scenario); [`identify`] everything
//! that measures and identifies it (the ground-truth generator, scoring,
//! force regression, calibration, classification, the Table II protocol,
//! video files).
//!
//! What is modelled:
//! * a 2D triangular mass-spring mesh of the block's visible face with
//!   length (damped), area and angle preservation and per-spring plasticity
//!   ([`mesh`], [`forces`], [`plasticity`]);
//! * the seed's first-order integrator and Newtonian Euler and Verlet, the
//!   finger and table collisions and the triangle repair, the three driving
//!   modes and instability detection ([`sim`], [`collision`]);
//! * a ground-truth generator that is *not* the calibrated model: a finer
//!   co-rotational finite-element block with its own plasticity, table
//!   friction, contour noise and a noisy force sensor ([`reference`]);
//! * the pixel F-score and μ(F) ([`raster`], [`evaluate`]), the segmented
//!   force regression of §V ([`force_regression`]), the evolutionary
//!   calibration of Algorithm 5 ([`evolution`]) and material classification
//!   (§VIII-E, [`classify`]).
//!
//! What is left out: the camera and contour tracking of §IV (the ground
//! truth hands over contours directly), 3D, gravity, friction in the
//! mass-spring model (the seed has none), breaking.
//!
//! Units: lengths in image pixels (px) at the seed's camera scale, time in
//! seconds, forces in N for the sensor and in model units inside the mass-
//! spring model (unit masses; the calibration absorbs the conversion).

pub mod error;
pub mod identify;
pub mod model;

pub use identify::{
    classify, contour_score, evaluate, evolution, experiment, force_regression, raster, reference,
    table_ii, video_csv,
};
pub use model::{collision, forces, mesh, plasticity, scenario, sim, vec2};

pub use error::{PushError, Result};

pub use vec2::V2;
