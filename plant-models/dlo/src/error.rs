//! The one error type of the deformable-linear-object module: every variant
//! names the bad parameter, the bad piece of a scenario, or the physical
//! reason a run stopped, so that a caller can fix it.
use thiserror::Error;

use plant_common::short_number;

/// Why a rope simulation or a wire/belt solve refused its input or stopped.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum DloError {
    /// A named scalar parameter is NaN/infinite or outside its valid range.
    #[error("invalid parameter `{name}` = {}: {reason}", short_number(*value))]
    InvalidParameter {
        name: String,
        value: f64,
        reason: &'static str,
    },
    /// A named scalar parameter is finite but outside its range, which the
    /// message states.
    #[error("invalid parameter `{name}` = {}: must be within {}..={}", short_number(*value), short_number(*min), short_number(*max))]
    OutOfRange {
        name: String,
        value: f64,
        min: f64,
        max: f64,
    },
    /// A scenario item (a grasp, a waypoint, a constraint) is inconsistent.
    #[error("invalid scenario: {0}")]
    InvalidScenario(String),
    /// A field of a problem file is unusable as a whole (an empty list).
    #[error("field `{field}`: {reason}")]
    InvalidField {
        field: &'static str,
        reason: &'static str,
    },
    /// The rope simulation became unstable: a non-finite state, a segment
    /// stretched past any physical length, or a node that left the world.
    #[error("rope simulation unstable at t = {} s: {reason}", short_number(*time_s))]
    Unstable { time_s: f64, reason: String },
    /// The constrained minimisation of a wire or belt did not converge.
    #[error("solve did not converge: {0}")]
    NotConverged(String),
}

/// Result alias of the DLO module.
pub type Result<T> = core::result::Result<T, DloError>;

/// Checks that `value` is finite and strictly positive.
pub(crate) fn check_positive(name: &str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| DloError::InvalidParameter {
        name: name.to_string(),
        value,
        reason,
    })
}

/// Checks that `value` is finite and ≥ 0.
pub(crate) fn check_non_negative(name: &str, value: f64) -> Result<f64> {
    plant_common::check::non_negative(value).map_err(|reason| DloError::InvalidParameter {
        name: name.to_string(),
        value,
        reason,
    })
}

/// Checks that `value` is finite and inside `[min, max]`.
pub(crate) fn check_range(name: &str, value: f64, min: f64, max: f64) -> Result<f64> {
    plant_common::check::in_range(value, min, max).map_err(|reason| {
        if value.is_finite() {
            // The range itself, not only that there is one (`harmonics`
            // = 40 said "outside its allowed range").
            DloError::OutOfRange {
                name: name.to_string(),
                value,
                min,
                max,
            }
        } else {
            DloError::InvalidParameter {
                name: name.to_string(),
                value,
                reason,
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_value_out_of_range_is_told_the_range() {
        let e = check_range("harmonics", 40.0, 0.0, 12.0).unwrap_err();
        assert_eq!(
            e.to_string(),
            "invalid parameter `harmonics` = 40: must be within 0..=12"
        );
        let e = check_range("harmonics", f64::NAN, 0.0, 12.0).unwrap_err();
        assert!(e.to_string().contains("must be a finite number"), "{e}");
    }
}
