//! Breast compression between two plates (seed 000, Kita, Tokumoto &
//! Hirai, L2363–2522; SEED000-SYSTEMS §7).
//!
//! - [`model`]: the semi-ellipsoidal phantom (130 × 110 × 70 mm, 286
//!   markers), the geometric compression model of the CAD system under
//!   A1/A2, and a finite-element model on the project's shared FEM with
//!   displacement-controlled sticking plates and the chest wall fixed in z.
//! - [`measure`]: the phantom experiment at 100 and 80 mm: where the
//!   markers go in each model, the paper's observations (mid-plane, pressed
//!   vs outer markers, density), and the geometric model's marker error
//!   against the FEM.
//!
//! No phantom scans ship with the seed: the FEM is the reference the
//! geometric model is scored against, and it is itself a model (linear
//! gel, sticking plates) — its limits are in [`model::plates`].
pub mod measure;
pub mod model;

pub use measure::compare;
pub use model::{geometric, phantom, plates};
