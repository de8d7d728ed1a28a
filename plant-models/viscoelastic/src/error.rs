//! The one error type of the viscoelastic module. Every variant names what
//! was wrong (the parameter, or the file and line of the input) so that a
//! user can fix it; nothing on these paths panics on bad input.
use thiserror::Error;

impl From<plant_common::check::ParamError> for VeError {
    fn from(e: plant_common::check::ParamError) -> Self {
        VeError::InvalidParameter {
            name: e.name,
            value: e.value,
            reason: e.reason,
        }
    }
}

/// Why a viscoelastic-object operation refused its input.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum VeError {
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
    /// A surface or volume mesh is unusable (open, degenerate, not star-shaped…).
    #[error("invalid mesh: {0}")]
    InvalidMesh(String),
    /// Malformed text input (CSV, OBJ): `source` is the file name or a label.
    #[error("{file}:{line}: {reason}")]
    Parse {
        /// File name (or label) of the input.
        file: String,
        /// 1-based line number.
        line: usize,
        /// What is wrong on that line.
        reason: String,
    },
    /// The stiffness matrix is not positive definite (mechanism / free body).
    #[error("FEM stiffness is not positive definite at equation {equation}: is the object held (Λu needs at least three non-collinear vertices to stop rigid motion)?")]
    NotPositiveDefinite {
        /// Index of the pivot that failed.
        equation: usize,
    },
    /// A vertex index outside the mesh or outside the traction set Λv.
    #[error("vertex {vertex} is not a traction vertex of this {n}-vertex object")]
    VertexNotInTractionSet {
        /// Requested mesh vertex.
        vertex: usize,
        /// Number of mesh vertices.
        n: usize,
    },
    /// A fit was given fewer samples than it has parameters, so the data
    /// cannot determine them.
    #[error("the {needed} parameters ({parameters}) need at least {needed} samples to be determined, got {got}")]
    TooFewSamples {
        /// The parameters of the fit, as the user knows them.
        parameters: &'static str,
        /// Samples needed (the number of parameters).
        needed: usize,
        /// Samples given.
        got: usize,
    },
    /// A fit's parameters are not determined by its data (see
    /// `TrialFit::check_determined`).
    #[error("{reason}; a trial must show the force relaxing under a held displacement (a constant or purely elastic force fixes one stiffness only)")]
    NotDetermined {
        /// Which parameters are free and how far, or why the fit did not
        /// settle.
        reason: String,
    },
    /// A probe-script event could not be applied (`index` counts the
    /// script's events from 0, so a reader can name the file's line).
    /// `error` is shown in this message and not also returned as the
    /// source, so that chain-printing reporters show it once.
    #[error("probe event {index} (time_s = {}): {error}", plant_common::short_number(*.time_s))]
    ProbeEvent {
        /// Index of the event in the script.
        index: usize,
        /// Its time (s).
        time_s: f64,
        /// Why it could not be applied.
        error: Box<VeError>,
    },
    /// The parameters of one DGFM column cannot be used. `error` is shown in
    /// this message and not also returned as the source.
    #[error("column {column} (mesh vertex {vertex}): {error}")]
    Column {
        /// DGFM column.
        column: usize,
        /// Its mesh vertex.
        vertex: usize,
        /// Why.
        error: Box<VeError>,
    },
    /// The 3-element model overflowed on a table's sample: the parameters
    /// and the input are too large together for f64.
    #[error("{file}: the model overflowed at the sample at time_s = {time_s} (displacement {displacement}, force {force}): k1 = {k1:e}, k2 = {k2:e}, b = {b:e} and the input are too large together")]
    Overflow {
        /// The input's name.
        file: String,
        /// The sample's time (s).
        time_s: f64,
        /// Its displacement (m), input or result.
        displacement: f64,
        /// Its force (N), input or result.
        force: f64,
        /// k1 (N/m).
        k1: f64,
        /// k2 (N/m).
        k2: f64,
        /// b (N·s/m).
        b: f64,
    },
    /// A fit's model force overflowed: the trial's numbers are too large.
    #[error("the model's force overflowed (rms residual {} N): displacements and forces this large cannot be fitted", plant_common::short_number(*.rms_residual_n))]
    FitOverflow {
        /// The fit's rms residual (N), not finite.
        rms_residual_n: f64,
    },
    /// Two series that must line up do not.
    #[error("length mismatch: {what} has {got} entries, expected {expected}")]
    LengthMismatch {
        /// Which series.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The length it should have.
        expected: usize,
    },
}

impl From<plant_common::fem::FemError> for VeError {
    /// The shared FEM's refusals, in this module's words.
    fn from(e: plant_common::fem::FemError) -> Self {
        use plant_common::fem::FemError as F;
        match e {
            F::InvalidParameter {
                name,
                value,
                reason,
            } => VeError::InvalidParameter {
                name,
                value,
                reason,
            },
            F::NotPositiveDefinite { equation } => VeError::NotPositiveDefinite { equation },
            F::LengthMismatch {
                what,
                got,
                expected,
            } => VeError::LengthMismatch {
                what,
                got,
                expected,
            },
            other => VeError::InvalidMesh(other.to_string()),
        }
    }
}

/// Result alias of the viscoelastic module.
pub type Result<T> = core::result::Result<T, VeError>;

/// Checks that `value` is finite and > 0; names it otherwise.
pub(crate) fn check_positive(name: &'static str, value: f64) -> Result<f64> {
    plant_common::check::positive(value).map_err(|reason| VeError::InvalidParameter {
        name,
        value,
        reason,
    })
}

/// Checks that `value` is finite and ≥ 0; names it otherwise.
pub(crate) fn check_non_negative(name: &'static str, value: f64) -> Result<f64> {
    plant_common::check::non_negative(value).map_err(|reason| VeError::InvalidParameter {
        name,
        value,
        reason,
    })
}
