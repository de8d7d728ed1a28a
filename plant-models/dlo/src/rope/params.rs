//! Rope parameters: Table I of Shi & Payandeh (seed 000, L1417–1432) as the
//! default, and the few constants the paper leaves open (marked "estimate").
use serde::{Deserialize, Serialize};

use crate::error::{check_non_negative, check_positive, check_range, DloError, Result};

/// Standard gravity used by the paper, N/kg (L1193: G = 9.8 N/kg).
pub const GRAVITY_N_PER_KG: f64 = 9.8;
/// Largest force a PHANTOM Omni can exert, N (L1399: 0.75 lbf ≈ 3.3 N).
pub const OMNI_MAX_FORCE_N: f64 = 3.3;

/// Which force terms are on: the paper's five models (L1446–1509).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RopeModel {
    /// Model 1: linear spring and damper only.
    LinearOnly,
    /// Model 2: + torsional spring.
    TorsionalSpring,
    /// Model 3: + torsional damper (orbits perpetually).
    TorsionalDamper,
    /// Model 4: + swivel damper (the paper's choice, L1509).
    Swivel,
    /// Model 5: model 4 with the linear spring quadratic in the strain.
    Quadratic,
}

impl RopeModel {
    /// Number as in the paper.
    pub fn number(self) -> u8 {
        match self {
            RopeModel::LinearOnly => 1,
            RopeModel::TorsionalSpring => 2,
            RopeModel::TorsionalDamper => 3,
            RopeModel::Swivel => 4,
            RopeModel::Quadratic => 5,
        }
    }
    pub(crate) fn torsional_spring(self) -> bool {
        self.number() >= 2
    }
    pub(crate) fn torsional_damper(self) -> bool {
        self.number() >= 3
    }
    pub(crate) fn swivel_damper(self) -> bool {
        self.number() >= 4
    }
}

/// Every constant of the rope. Field names carry units; where the paper
/// gives a bare number (Table I), the unit is the one that makes its
/// equation dimensionally consistent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RopeParams {
    /// Number of mass points N (Table I: 20–50).
    pub nodes: usize,
    /// Rope length l, m (Table I: 5.0 m); the rest length of a segment is
    /// l/(N − 1).
    pub length_m: f64,
    /// Rope radius r, m (Table I: 0.05 m).
    pub radius_m: f64,
    /// Mass of one point m, kg (Table I: 0.05 kg).
    pub node_mass_kg: f64,
    /// Gravity G, N/kg (Table I: 9.8).
    pub gravity_n_per_kg: f64,
    /// Virtual coupling spring k_h, N/m (Table I: 1200).
    pub coupling_stiffness_n_per_m: f64,
    /// Virtual coupling damper B, N·s/m (estimate: L1384 names it, Table I
    /// gives no value; 5 gives a damping ratio ≈ 0.3 on one node).
    pub coupling_damping_n_s_per_m: f64,
    /// Output scale s for the haptic device (Table I: 0.003).
    pub output_scale: f64,
    /// Rope–rope friction constant μ (Table I: 10).
    pub friction: f64,
    /// Repulsion spring k_rs, N/m (Table I: 100).
    pub repulse_stiffness_n_per_m: f64,
    /// Repulsion damper k_rd, N·s/m (Table I: 5).
    pub repulse_damping_n_s_per_m: f64,
    /// Linear spring k_l, N per unit strain (Table I: 800; Eq. 6 multiplies
    /// it by the strain Δl).
    pub linear_stiffness_n: f64,
    /// Linear damper k_d, N·s/m (Table I: 1).
    pub linear_damping_n_s_per_m: f64,
    /// Torsional spring k_ts, N·m per π rad (Table I: 10; Eq. 8).
    pub torsional_stiffness_n_m: f64,
    /// Torsional damper k_td, N·m·s (Table I: 0.05; Eq. 11).
    pub torsional_damping_n_m_s: f64,
    /// Swivel damper k_sw, N·s (Table I: 0.2; Eq. 14).
    pub swivel_damping_n_s: f64,
    /// Shortest segment as a fraction of its rest length, l_min/l_r
    /// (estimate: §III names l_min without a value).
    pub min_length_ratio: f64,
    /// Longest segment as a fraction of its rest length, l_max/l_r
    /// (estimate: §III names l_max without a value).
    pub max_length_ratio: f64,
    /// Safety margin ε of the collision shift, m (Fig. 6; estimate: the
    /// paper gives no value).
    pub collision_margin_m: f64,
    /// Shift passes per step over the colliding pairs (estimate; one pass
    /// is the paper's, more settle contacts that share a segment).
    pub collision_passes: usize,
    /// Friction between rope and desk μ_d (estimate: the desk of L1530 has
    /// no stated friction).
    pub desk_friction: f64,
    /// Time step dt, s (L1434: 500–1000 Hz updates → 1 ms).
    pub dt_s: f64,
    /// Which force terms are on (L1446–1509; the paper prefers model 4).
    pub model: RopeModel,
}

impl Default for RopeParams {
    fn default() -> Self {
        Self {
            nodes: 50,
            length_m: 5.0,
            radius_m: 0.05,
            node_mass_kg: 0.05,
            gravity_n_per_kg: GRAVITY_N_PER_KG,
            coupling_stiffness_n_per_m: 1200.0,
            coupling_damping_n_s_per_m: 5.0,
            output_scale: 0.003,
            friction: 10.0,
            repulse_stiffness_n_per_m: 100.0,
            repulse_damping_n_s_per_m: 5.0,
            linear_stiffness_n: 800.0,
            linear_damping_n_s_per_m: 1.0,
            torsional_stiffness_n_m: 10.0,
            torsional_damping_n_m_s: 0.05,
            swivel_damping_n_s: 0.2,
            min_length_ratio: 0.8,
            max_length_ratio: 1.25,
            collision_margin_m: 0.002,
            collision_passes: 4,
            desk_friction: 0.5,
            dt_s: 1e-3,
            model: RopeModel::Swivel,
        }
    }
}

impl RopeParams {
    /// Rest length of one segment l_r, m.
    pub fn rest_length_m(&self) -> f64 {
        self.length_m / (self.nodes as f64 - 1.0)
    }

    /// Checks every field; the error names the bad one.
    pub fn validate(&self) -> Result<()> {
        if !(3..=2000).contains(&self.nodes) {
            return Err(DloError::InvalidParameter {
                name: "nodes".into(),
                value: self.nodes as f64,
                reason: "must be 3..=2000",
            });
        }
        check_positive("length_m", self.length_m)?;
        check_positive("radius_m", self.radius_m)?;
        check_positive("node_mass_kg", self.node_mass_kg)?;
        check_non_negative("gravity_n_per_kg", self.gravity_n_per_kg)?;
        check_non_negative(
            "coupling_stiffness_n_per_m",
            self.coupling_stiffness_n_per_m,
        )?;
        check_non_negative(
            "coupling_damping_n_s_per_m",
            self.coupling_damping_n_s_per_m,
        )?;
        check_non_negative("output_scale", self.output_scale)?;
        check_non_negative("friction", self.friction)?;
        check_non_negative("repulse_stiffness_n_per_m", self.repulse_stiffness_n_per_m)?;
        check_non_negative("repulse_damping_n_s_per_m", self.repulse_damping_n_s_per_m)?;
        check_positive("linear_stiffness_n", self.linear_stiffness_n)?;
        check_non_negative("linear_damping_n_s_per_m", self.linear_damping_n_s_per_m)?;
        check_non_negative("torsional_stiffness_n_m", self.torsional_stiffness_n_m)?;
        check_non_negative("torsional_damping_n_m_s", self.torsional_damping_n_m_s)?;
        check_non_negative("swivel_damping_n_s", self.swivel_damping_n_s)?;
        check_range("min_length_ratio", self.min_length_ratio, 0.0, 1.0)?;
        check_range("max_length_ratio", self.max_length_ratio, 1.0, 10.0)?;
        check_non_negative("collision_margin_m", self.collision_margin_m)?;
        if self.collision_margin_m > self.radius_m {
            return Err(DloError::InvalidParameter {
                name: "collision_margin_m".into(),
                value: self.collision_margin_m,
                reason: "must not exceed radius_m",
            });
        }
        if self.collision_passes > 100 {
            return Err(DloError::InvalidParameter {
                name: "collision_passes".into(),
                value: self.collision_passes as f64,
                reason: "must be 0..=100",
            });
        }
        check_non_negative("desk_friction", self.desk_friction)?;
        check_range("dt_s", self.dt_s, 1e-6, 0.01)?;
        Ok(())
    }
}
