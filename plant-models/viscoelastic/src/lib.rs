//! Measurement-based viscoelastic solids (seed 002, SPEC §3): a DGFM
//! object computed from a tetrahedral FEM, its 3-element viscoelastic
//! evaluation, a haptic/display driver, a probe-measurement simulator and
//! the parameter estimation of §4 (per-trial Nelder–Mead fits, damping
//! tensor, Rayleigh coefficient, stiffness ratio, column spreading).
//!
//! - [`model`]: the object — surface mesh, FEM, DGFM, the 3-element model
//!   integrated exactly ([`three_element`]) and the object's evaluation and
//!   haptic loop ([`object`]). This is the plant: it shares no code with the
//!   firmware's real-time update, which is tested against it.
//! - [`identify`]: measuring it (the probe simulator that generates ground
//!   truth, [`measure`]) and identifying its parameters from measurements
//!   ([`fit`], [`estimate`]).
//! - [`experiment`]: the experiments `softjoint viscoelastic` runs, built
//!   from the two: the model on a user's table, a checked trial fit, and
//!   the measured-object pipeline (DGFM, campaign, estimate, scripted
//!   probe beside the exact reference).
//!
//! What is modelled: linear small-strain elasticity of a closed, star-
//! shaped object resting on a support (Λu); the seed's 3-element model per
//! DGFM entry with stiffness ratio and Rayleigh or tensor damping; probe
//! trials at constant velocity with a 1 kHz force sensor, Gaussian noise
//! and the growing contact area at the start of loading.
//!
//! What is left out: see each submodule; in short, large deformation,
//! inertia, collision detection, the seed's stereo-vision DGFM estimation
//! (our DGFM comes from the FEM), display subdivision.
//!
//! Units: metres, newtons, pascals, seconds; names carry them.

pub mod error;
pub mod experiment;
pub mod identify;
pub mod io;
pub mod model;

pub use identify::{estimate, fit, measure};
pub use model::{dgfm, fem, mesh, object, three_element};

pub use dgfm::Dgfm;
pub use error::{Result, VeError};
pub use mesh::SurfaceMesh;
pub use object::{ColumnParams, Contact, HapticLoop, TractionModel, ViscoObject};
pub use three_element::{Element, RayleighColumn, TensorPair};

/// A 3-vector (force, traction, displacement at one vertex).
pub type Vec3 = nalgebra::Vector3<f64>;
/// A 3×3 tensor (a DGFM block, a stiffness or damping tensor).
pub type Mat3 = nalgebra::Matrix3<f64>;
