//! The project's file formats, apart from the algorithms that read and
//! write them: scenarios, plant files, gains files, calibration files and
//! sweeps.
use serde::{Deserialize, Serialize};

pub mod calibration;
pub mod gains;
pub mod plant;
pub mod rheology;
pub mod scenario;
pub mod sweep;

/// Which joint to simulate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum JointKind {
    /// One plane, one wire sensor (the paper's §III–V prototypes).
    #[serde(rename = "2d")]
    TwoD,
    /// Two projection planes, four wire sensors (the paper's §VI).
    #[serde(rename = "3d")]
    ThreeD,
}
