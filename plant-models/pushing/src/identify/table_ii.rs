//! The protocol behind Table II of the seed (§VIII-B): "sets of 24 training
//! sessions were run, using different combinations of elasticity and
//! plasticity terms (damped preservation of length only, preservation of
//! area and angle only, or all of them together), cases including plastic
//! deformation, and removing the collision resolution routines and the aid
//! of geometric constraints", for each of the three integration schemes;
//! the table reports mean ± standard deviation over the 24 sessions of the
//! best, worst and average model.
//!
//! Read here as the full factorial 3 term sets × plasticity on/off ×
//! collision resolution on/off × geometric repair on/off = 24 sessions
//! (the count matches the seed's 24). Each session is one Algorithm 5
//! calibration under the scheme being tested, so every scheme is calibrated
//! for itself with the same data, search settings and seeds. A term that is
//! off is held at 0 whatever the search proposes; without collisions the
//! finger acts only through the sensed force (§VI-F mode 2).
use crate::forces::MaterialParams;
use crate::sim::{DrivingMode, Integrator, SimConfig};

/// Which preservation terms a session's model has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Terms {
    /// Damped preservation of length only (k_A = k_φ = 0).
    LengthOnly,
    /// Preservation of area and angle only (k_L = k_d = 0).
    AreaAngleOnly,
    /// All of them.
    All,
}

/// One training session's model configuration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Session {
    pub terms: Terms,
    pub plasticity: bool,
    pub collisions: bool,
    pub geometric_repair: bool,
}

impl Session {
    /// The 24 sessions, all terms with plasticity, collisions and repair
    /// first.
    pub fn all() -> Vec<Session> {
        let mut v = Vec::with_capacity(24);
        for terms in [Terms::All, Terms::LengthOnly, Terms::AreaAngleOnly] {
            for plasticity in [true, false] {
                for collisions in [true, false] {
                    for geometric_repair in [true, false] {
                        v.push(Session {
                            terms,
                            plasticity,
                            collisions,
                            geometric_repair,
                        });
                    }
                }
            }
        }
        v
    }

    /// `p` with the session's switched-off terms set to 0.
    pub fn mask(&self, p: &MaterialParams) -> MaterialParams {
        let mut q = *p;
        match self.terms {
            Terms::LengthOnly => {
                q.k_area = 0.0;
                q.k_angle = 0.0;
            }
            Terms::AreaAngleOnly => {
                q.k_length = 0.0;
                q.k_damping = 0.0;
            }
            Terms::All => {}
        }
        if !self.plasticity {
            q.creep = 0.0;
            q.max_alpha = 0.0;
        }
        q
    }

    /// Simulation settings of the session under `integrator`.
    pub fn sim_config(&self, integrator: Integrator) -> SimConfig {
        let mode = if self.collisions {
            DrivingMode::CollisionAndForces
        } else {
            DrivingMode::ForcesOnVertices
        };
        SimConfig {
            integrator,
            mode,
            geometric_repair: self.geometric_repair,
            ..SimConfig::default()
        }
    }

    /// Short label, e.g. `all+plastic+coll+repair`.
    pub fn label(&self) -> String {
        let t = match self.terms {
            Terms::LengthOnly => "length",
            Terms::AreaAngleOnly => "area+angle",
            Terms::All => "all",
        };
        format!(
            "{t}{}{}{}",
            if self.plasticity { "+plastic" } else { "" },
            if self.collisions { "+coll" } else { "" },
            if self.geometric_repair { "+repair" } else { "" }
        )
    }
}

/// μ(F) relative to the score of a block that never deforms:
/// (μ − μ_still)/(1 − μ_still), 0 for "no better than not deforming", 1 for
/// perfect. Same ranking as μ(F) on one video (an increasing affine map),
/// but it shows the gaps on the scale of the deformation.
pub fn skill(mean_f: f64, still_mean_f: f64) -> f64 {
    (mean_f - still_mean_f) / (1.0 - still_mean_f)
}
