//! The one error type of the rheology module: every variant names the bad
//! parameter, the bad piece of input or the instability, so that a caller
//! can fix it or report it.
use thiserror::Error;

/// Why a rheology-model operation refused its input or stopped.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum RheologyError {
    /// A named scalar parameter is NaN/infinite or outside its valid range.
    #[error("invalid parameter `{name}` = {}: {reason}", plant_common::short_number(*.value))]
    InvalidParameter {
        name: String,
        value: f64,
        reason: &'static str,
    },
    /// A structural setting (grid, schedule, parameter count) is unusable.
    #[error("invalid setting `{name}`: {reason}")]
    InvalidSetting { name: String, reason: String },
    /// Input data (a CSV file, a series of frames) is malformed.
    #[error("{location}: {reason}")]
    MalformedInput { location: String, reason: String },
    /// The objective of a search could not score a batch (a remote worker
    /// lost for good, a cancelled sweep); the search stops there.
    #[error("the search's objective failed: {reason}")]
    Evaluation { reason: String },
    /// A simulation became unstable; the run stops at the named step.
    #[error("unstable at t = {} s (step {step}): {kind}", plant_common::short_number(*.time_s))]
    Unstable {
        step: usize,
        time_s: f64,
        kind: Instability,
    },
}

/// How a simulation went wrong (reported by name, never as silent NaN).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Instability {
    /// A position or velocity became NaN or infinite.
    NonFinite { node: usize },
    /// A node flew further from the block than the escape distance.
    Escaped { node: usize, distance_m: f64 },
    /// An element shrank below 1 % of its rest length (the lattice folded
    /// through itself) or a tetrahedron inverted.
    Collapsed { element: usize, length_ratio: f64 },
    /// The implicit step's linear solve did not converge.
    SolverStalled { iterations: usize, residual: f64 },
}

impl std::fmt::Display for Instability {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        use plant_common::short_number as n;
        match *self {
            Instability::NonFinite { node } => {
                write!(f, "node {node} has a non-finite position or velocity")
            }
            Instability::Escaped { node, distance_m } => write!(
                f,
                "node {node} flew {} m from the block",
                n(distance_m)
            ),
            Instability::Collapsed {
                element,
                length_ratio,
            } => write!(
                f,
                "element {element} collapsed to {}× its rest size",
                n(length_ratio)
            ),
            Instability::SolverStalled {
                iterations,
                residual,
            } => write!(
                f,
                "the implicit step's solver stalled after {iterations} iterations (relative residual {})",
                n(residual)
            ),
        }
    }
}

/// Result alias of the rheology module.
pub type Result<T> = core::result::Result<T, RheologyError>;

/// Checks that `value` is finite and inside `[min, max]`; names it otherwise.
pub(crate) fn check_range(name: &str, value: f64, min: f64, max: f64) -> Result<f64> {
    plant_common::check::in_range(value, min, max).map_err(|reason| {
        RheologyError::InvalidParameter {
            name: name.to_string(),
            value,
            reason,
        }
    })
}

/// Checks that `value` is finite and strictly positive.
pub(crate) fn check_positive(name: &str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| RheologyError::InvalidParameter {
        name: name.to_string(),
        value,
        reason,
    })
}

/// Checks that `value` is finite and ≥ 0.
pub(crate) fn check_non_negative(name: &str, value: f64) -> Result<f64> {
    plant_common::check::non_negative(value).map_err(|reason| RheologyError::InvalidParameter {
        name: name.to_string(),
        value,
        reason,
    })
}

/// An [`RheologyError::InvalidSetting`].
pub(crate) fn bad_setting(name: &str, reason: impl Into<String>) -> RheologyError {
    RheologyError::InvalidSetting {
        name: name.to_string(),
        reason: reason.into(),
    }
}
