//! Measurement-based viscoelastic solids (seed 002, SPEC §3): a DGFM
//! object computed from a tetrahedral FEM, its 3-element viscoelastic
//! evaluation (reusing the portable core's update), a haptic/display
//! driver, a probe-measurement simulator and the parameter estimation of
//! §4 (per-trial Nelder–Mead fits, damping tensor, Rayleigh coefficient,
//! stiffness ratio, column spreading).
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

pub mod dgfm;
pub mod error;
pub mod estimate;
pub mod fem;
pub mod fit;
pub mod io;
pub mod measure;
pub mod mesh;
pub mod object;
pub mod svg;

pub use dgfm::Dgfm;
pub use error::{Result, VeError};
pub use mesh::SurfaceMesh;
pub use object::{ColumnParams, Contact, HapticLoop, ViscoObject};
