//! The one error type of the pushing module: every variant names the bad
//! parameter or the bad piece of input so that a caller can fix it.
use thiserror::Error;

/// Why a pushing-model operation refused its input.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum PushError {
    /// A named scalar parameter is NaN/infinite or outside its valid range.
    #[error("invalid parameter `{name}` = {}: {reason}", plant_common::short_number(*.value))]
    InvalidParameter {
        name: &'static str,
        value: f64,
        reason: &'static str,
    },
    /// A named scalar parameter is outside its range `[min, max]`.
    #[error(
        "invalid parameter `{name}` = {}: must be within {}..={}",
        plant_common::short_number(*.value),
        plant_common::short_number(*.min),
        plant_common::short_number(*.max)
    )]
    OutOfRange {
        name: &'static str,
        value: f64,
        min: f64,
        max: f64,
    },
    /// A mesh could not be built or validated.
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// Input data (a CSV file, a series of frames) is malformed.
    #[error("{location}: {reason}")]
    MalformedInput { location: String, reason: String },
    /// Two series that must line up (frames, forces, ground truth) do not.
    #[error("length mismatch: {what} has {got} entries, expected {expected}")]
    LengthMismatch {
        what: &'static str,
        got: usize,
        expected: usize,
    },
    /// The tracked contour could not be fitted by a periodic spline.
    #[error("contour tracking: {0}")]
    Tracking(#[from] plant_contour::ContourError),
}

/// Result alias of the pushing module.
pub type Result<T> = core::result::Result<T, PushError>;

/// Checks that `value` is finite and inside `[min, max]`; names it otherwise.
pub(crate) fn check_range(name: &'static str, value: f64, min: f64, max: f64) -> Result<f64> {
    if !value.is_finite() {
        return Err(PushError::InvalidParameter {
            name,
            value,
            reason: "must be a finite number",
        });
    }
    if value < min || value > max {
        return Err(PushError::OutOfRange {
            name,
            value,
            min,
            max,
        });
    }
    Ok(value)
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| PushError::InvalidParameter {
        name,
        value,
        reason,
    })
}
