//! The one error type of the contour module: every variant names the bad
//! parameter or the bad piece of input (frame, point, line) so that a
//! caller can fix it.
use thiserror::Error;

/// Why a spline operation refused its input.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ContourError {
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
    /// Too few data points to fit (a frame of a contour, a time axis).
    #[error("{location}: too few points: {got}, need at least {needed} ({why})")]
    TooFewPoints {
        /// Which frame or series.
        location: String,
        /// Points given.
        got: usize,
        /// Points needed.
        needed: usize,
        /// Why that many.
        why: &'static str,
    },
    /// Two points of one frame sit at the same angle (or parameter) of a
    /// periodic axis: a signature must be a function of the angle.
    #[error("{location}: duplicate {axis} {} (points {first} and {second}); a contour signature needs one radius per angle", plant_common::short_number(*.value))]
    DuplicateParameter {
        /// Which frame.
        location: String,
        /// The axis name ("angle", "parameter").
        axis: &'static str,
        /// The repeated value.
        value: f64,
        /// 0-based indices of the two points.
        first: usize,
        second: usize,
    },
    /// A value that must be finite is not.
    #[error("{location}: `{what}` is not finite ({})", plant_common::short_number(*.value))]
    NonFinite {
        /// Where (frame and point, sample index).
        location: String,
        /// Which quantity.
        what: &'static str,
        /// The value.
        value: f64,
    },
    /// A data site lies outside the spline's domain on a non-periodic axis.
    #[error("{location}: {axis} = {} lies outside the spline's domain [{}, {}]", plant_common::short_number(*.value), plant_common::short_number(*.start), plant_common::short_number(*.end))]
    OutsideDomain {
        /// Which sample.
        location: String,
        /// The axis name.
        axis: &'static str,
        /// The value.
        value: f64,
        /// Domain start.
        start: f64,
        /// Domain end.
        end: f64,
    },
    /// Two series that must line up do not.
    #[error("length mismatch: {what} has {got} entries, expected {expected}")]
    LengthMismatch {
        /// Which series.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The length it must have.
        expected: usize,
    },
    /// The fit could not be solved (every solver failed, or a non-finite
    /// result): says why.
    #[error("the smoothing problem could not be solved: {0}")]
    Unsolvable(String),
    /// The problem is too large for the dense KKT solver of Eq. 27.
    #[error("the dense KKT system of Eq. 27 would have {size} equations (more than {limit}); use the reduced solver")]
    TooLargeForKkt {
        /// Equations of the KKT system.
        size: usize,
        /// The limit.
        limit: usize,
    },
    /// Malformed input data (CSV) with its location.
    #[error("{location}: {reason}")]
    MalformedInput {
        /// File and line, or a label.
        location: String,
        /// What is wrong.
        reason: String,
    },
}

/// Result alias of the contour module.
pub type Result<T> = core::result::Result<T, ContourError>;

/// Checks that `value` is finite and strictly positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| ContourError::InvalidParameter {
        name,
        value,
        reason,
    })
}

/// Checks that `value` is finite.
pub(crate) fn check_finite(name: &'static str, value: f64) -> Result<f64> {
    if !value.is_finite() {
        return Err(ContourError::InvalidParameter {
            name,
            value,
            reason: "must be a finite number",
        });
    }
    Ok(value)
}
