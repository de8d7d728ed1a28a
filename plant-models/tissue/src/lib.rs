//! Inner deformation of soft tissue (seed 000): measuring deformation
//! fields from volume images (Zhang, [`field`]) and predicting the
//! compression of a breast-like body between two plates (Kita,
//! [`compress`]). No MR volumes, mammograms or phantom scans ship with the
//! seed; both run on synthetic twins whose true deformation is known.
//!
//! Units: millimetres for positions and displacements, pascals and newtons
//! for the FEM, intensities in the volumes' own units.
pub mod compress;
pub mod error;
pub mod field;

pub use error::{Result, TissueError};
