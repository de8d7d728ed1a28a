//! Inner deformation fields from volume images (seed 000, Zhang, Hirai &
//! Endo, L388–673; SEED000-SYSTEMS §6).
//!
//! - [`model`]: the volume image and its NIfTI reader/writer, synthetic
//!   twins of the paper's calf volumes with a known warp, the Delaunay
//!   tetrahedra and the dense field by linear shape functions (Eq. 9–11).
//! - [`measure`]: 3-D Harris points (Eq. 1–3), matching by strength with
//!   and without the direction-consistency constraint (Eq. 4–7), Horn's
//!   rigid part (Eq. 8), the whole pipeline and Eq. 12, and the comparison
//!   of matching variants against a twin's true field, and the experiment
//!   `softjoint tissue field` runs (several variants, timed, with the truth
//!   when there is one).
//!
//! What is modelled and left out is in each submodule; the tissue README
//! has the paper facts and the figures.
pub mod measure;
pub mod model;

pub use measure::{experiment, harris, horn, matching, pipeline, twin};
pub use model::{delaunay, shape, synth, volume};
