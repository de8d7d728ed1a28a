//! The one error type of the tissue module (seed 000, Zhang and Kita).
//! Every variant names what was wrong — the file, the field or parameter,
//! the voxel — so that a user can fix it; nothing on these paths panics on
//! bad input.
use thiserror::Error;

/// Why a tissue operation refused its input or could not finish.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum TissueError {
    /// A named scalar parameter is NaN/infinite or outside its valid range.
    #[error("invalid parameter `{name}` = {}: {reason}", plant_common::short_number(*.value))]
    InvalidParameter {
        /// Parameter name as the user knows it.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
    /// A volume file could not be read or written.
    #[error("{path}: {reason}")]
    VolumeFile {
        /// The file.
        path: String,
        /// What went wrong (the NIfTI reader's or the file system's words).
        reason: String,
    },
    /// A volume has a shape this operation cannot use.
    #[error("{what}: {reason}")]
    VolumeShape {
        /// Which volume (a file name or a label).
        what: String,
        /// What is wrong with its shape.
        reason: String,
    },
    /// A voxel holds NaN or an infinity.
    #[error("{what}: voxel ({x}, {y}, {z}) is not a finite number")]
    NonFiniteVoxel {
        /// Which volume.
        what: String,
        /// Voxel index along x.
        x: usize,
        /// Voxel index along y.
        y: usize,
        /// Voxel index along z.
        z: usize,
    },
    /// Too few feature points or matches for the next step.
    #[error("{stage}: {got} {what}, at least {needed} needed")]
    TooFew {
        /// The step that needed them.
        stage: &'static str,
        /// What there were too few of.
        what: &'static str,
        /// How many there were.
        got: usize,
        /// How many are needed.
        needed: usize,
    },
    /// The Delaunay tetrahedralisation could not insert a point.
    #[error("Delaunay tetrahedralisation: {0}")]
    Delaunay(String),
    /// The compression model could not continue (an element turned inside
    /// out, the body lost its hold): named, never a NaN.
    #[error("compression at plate gap {gap_mm} mm: {reason}")]
    Compression {
        /// The plate gap (mm) the step was heading for.
        gap_mm: f64,
        /// What happened.
        reason: String,
    },
    /// The shared FEM refused (see [`plant_common::fem::FemError`]).
    #[error("FEM: {0}")]
    Fem(#[from] plant_common::fem::FemError),
}

/// Result alias of the tissue module.
pub type Result<T> = core::result::Result<T, TissueError>;

/// Checks that `value` is finite and > 0; names it otherwise.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| TissueError::InvalidParameter {
        name,
        value,
        reason,
    })
}

/// Checks that `value` is finite and in `[lo, hi]`; names it otherwise
/// with `reason` (which states the range).
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    lo: f64,
    hi: f64,
    reason: &'static str,
) -> Result<f64> {
    if value.is_finite() && value >= lo && value <= hi {
        Ok(value)
    } else {
        Err(TissueError::InvalidParameter {
            name,
            value,
            reason,
        })
    }
}
