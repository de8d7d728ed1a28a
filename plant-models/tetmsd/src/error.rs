//! The one error type of the tetrahedral Voigt module: every variant names
//! the bad parameter, the bad piece of input or the tick where a run went
//! wrong, so that a caller can fix it. Nothing on these paths panics on bad
//! input and no run ends in a silent NaN.
use thiserror::Error;

/// Why a tetrahedral-MSD operation refused its input or stopped.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum TetError {
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
    /// A refinement level outside the meshes this module builds.
    #[error("refinement level {level} is outside {min}..={max}")]
    LevelOutOfRange {
        /// Requested level.
        level: u32,
        /// Smallest level.
        min: u32,
        /// Largest level.
        max: u32,
    },
    /// A node or tetrahedron index outside the mesh.
    #[error("{what} {index} is outside this mesh of {len} {what}s")]
    IndexOutOfRange {
        /// `node` or `tetrahedron`.
        what: &'static str,
        /// The index.
        index: usize,
        /// How many there are.
        len: usize,
    },
    /// The explicit integration blew up (a velocity or position became
    /// non-finite or left the plausible range, an edge collapsed).
    #[error("unstable at tick {tick}: {what}")]
    Unstable {
        /// The 1 kHz tick being computed.
        tick: u64,
        /// What was detected.
        what: String,
    },
    /// The static reference solver did not converge.
    #[error("static solve: {0}")]
    StaticSolve(String),
    /// Malformed input (scenario file, probe script): where and why.
    #[error("{location}: {reason}")]
    Malformed {
        /// File and field (or line).
        location: String,
        /// What is wrong.
        reason: String,
    },
    /// The replicated session cannot go on; the reason is named.
    #[error("session: {0}")]
    Session(String),
    /// A real-time site (its threads, its UDP socket, its peer) failed or
    /// stopped; the message names the thread, the socket call or the peer.
    #[error("{0}")]
    Site(String),
}

/// Result alias of the tetrahedral module.
pub type Result<T> = core::result::Result<T, TetError>;

/// Checks that `value` is finite and strictly positive.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| TetError::InvalidParameter {
        name,
        value,
        reason,
    })
}

/// Checks that `value` is finite and inside `[min, max]`; `reason` states
/// the range for the user.
pub(crate) fn check_range(
    name: &'static str,
    value: f64,
    min: f64,
    max: f64,
    reason: &'static str,
) -> Result<f64> {
    if !value.is_finite() || value < min || value > max {
        return Err(TetError::InvalidParameter {
            name,
            value,
            reason,
        });
    }
    Ok(value)
}
