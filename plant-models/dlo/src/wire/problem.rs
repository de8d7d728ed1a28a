//! A static problem as a file states it (`softjoint dlo solve`, TOML with a
//! `model` tag): one wire (Eq. 1–24), one belt (Eq. 31–61), or the
//! end-distance sequence of L811 on both branches; and what solving it
//! gives. Each solve carries its own evidence (constraint violation,
//! convergence) in the shapes it returns.
use serde::Deserialize;

use super::belt::{belt_settings, BeltMethod, BeltProblem, BeltShape};
use super::linear::{end_distance_sequence, SequenceStep, WireParams, WireProblem, WireShape};
use super::optimize::Settings;
use crate::error::{DloError, Result};

/// A static problem file.
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "model", rename_all = "snake_case", deny_unknown_fields)]
pub enum StaticProblem {
    /// One wire (Eq. 1–24).
    Wire { problem: WireProblem },
    /// One belt (Eq. 31–61).
    Belt { problem: BeltProblem },
    /// The end-distance sequence of L811 on both branches.
    Sequence {
        wire: WireParams,
        /// End distances l / L to report (descending order is not needed).
        fractions: Vec<f64>,
        /// Continuation step of the end distance, in units of L.
        #[serde(default = "default_step")]
        step: f64,
        /// Ritz intervals of each wire.
        #[serde(default = "default_intervals")]
        intervals: usize,
    },
}

/// The continuation step of the sequence (L811 moves the end in steps).
fn default_step() -> f64 {
    0.05
}

/// Intervals of the sequence's wires (enough for a loop at 0.1 L).
fn default_intervals() -> usize {
    96
}

/// What solving a [`StaticProblem`] gives.
#[derive(Debug, Clone)]
pub enum StaticSolution {
    /// The wire's shape, and the wire's radius (m, for drawing it).
    Wire { shape: WireShape, radius_m: f64 },
    /// The belt's shape, and how it was discretised.
    Belt {
        shape: BeltShape,
        method: BeltMethod,
    },
    /// Both branches at each end distance, and the wire's radius (m).
    Sequence {
        steps: Vec<SequenceStep>,
        radius_m: f64,
    },
}

impl StaticProblem {
    /// Solves the problem with the model's default settings.
    pub fn solve(&self) -> Result<StaticSolution> {
        Ok(match self {
            StaticProblem::Wire { problem } => StaticSolution::Wire {
                shape: problem.solve_verified(&Settings::default())?,
                radius_m: problem.wire.radius_m,
            },
            StaticProblem::Belt { problem } => StaticSolution::Belt {
                shape: problem.solve_verified(&belt_settings())?,
                method: problem.method,
            },
            StaticProblem::Sequence {
                wire,
                fractions,
                step,
                intervals,
            } => {
                if fractions.is_empty() {
                    return Err(DloError::InvalidField {
                        field: "fractions",
                        reason: "give at least one end distance",
                    });
                }
                StaticSolution::Sequence {
                    steps: end_distance_sequence(
                        wire,
                        fractions,
                        *step,
                        *intervals,
                        &Settings::default(),
                    )?,
                    radius_m: wire.radius_m,
                }
            }
        })
    }
}
