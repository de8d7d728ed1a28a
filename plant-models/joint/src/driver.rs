//! One ULN2003A Darlington channel sinking an SMA coil from a supply.
//!
//! ```text
//!   I = clamp(g·(V_in − V_on), 0, min(I_max, I_sat))
//!   I_sat: V_s = I·R_coil + V_CEsat(I),  V_CEsat(I) = V_0 + R_CE·I
//!        ⇒ I_sat = (V_s − V_0)/(R_coil + R_CE)
//! ```
//!
//! The saturation "fixed point" of SPEC §2 is linear in `I`, so it is solved
//! exactly (no iteration). Below `V_on` (1.7 V, the paper's `v_offset`) the
//! channel does not conduct. Left out: the Darlington's temperature drift,
//! the switching transients and the flyback diode (a resistive coil needs
//! none).

use plant_common::scalar::Scalar;
use serde::{Deserialize, Serialize};

use super::{check_positive, PlantError};

/// Driver channel parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriverParams {
    /// Input voltage below which no current flows (V). Paper: v_offset =
    /// 1.7 V, "the minimum voltage required for the drivers".
    pub turn_on_v: f64,
    /// Transconductance above turn-on (A/V). Estimate within SPEC §2's
    /// 0.3–1.5 A/V, taken high (1.2) so that the paper's P-control steady
    /// error < 0.15° at Kp = 2 V/° leaves enough current to hold the coil
    /// in its transformation band (≈ 0.15–0.25 A).
    pub transconductance_a_v: f64,
    /// Channel current limit (A). ULN2003A datasheet: 500 mA per channel.
    pub max_current_a: f64,
    /// Coil supply (V). Estimate (a 5 V rail, like the 0–5 V inputs).
    pub supply_v: f64,
    /// Saturation voltage at zero current (V). SPEC §2 (ULN2003A datasheet
    /// V_CE(sat) curve, linearised).
    pub vce_sat_v: f64,
    /// Slope of V_CE(sat) with current (Ω). SPEC §2 (datasheet, linearised).
    pub vce_sat_ohm: f64,
}

impl Default for DriverParams {
    fn default() -> Self {
        Self {
            turn_on_v: 1.7,
            transconductance_a_v: 1.2,
            max_current_a: 0.5,
            supply_v: 5.0,
            vce_sat_v: 0.75,
            vce_sat_ohm: 1.5,
        }
    }
}

impl DriverParams {
    /// Rejects non-finite or non-positive values, naming the field.
    pub fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        let p = |f: &str| format!("{prefix}{f}");
        check_positive(&p("turn_on_v"), self.turn_on_v)?;
        check_positive(&p("transconductance_a_v"), self.transconductance_a_v)?;
        check_positive(&p("max_current_a"), self.max_current_a)?;
        check_positive(&p("supply_v"), self.supply_v)?;
        check_positive(&p("vce_sat_v"), self.vce_sat_v)?;
        check_positive(&p("vce_sat_ohm"), self.vce_sat_ohm)?;
        Ok(())
    }

    /// Saturated current through a coil of `coil_ohm` (A).
    pub fn saturation_current_a(&self, coil_ohm: f64) -> f64 {
        self.saturation_current_of(coil_ohm)
    }

    /// [`Self::saturation_current_a`] of any [`Scalar`] resistance.
    #[inline]
    fn saturation_current_of<S: Scalar>(&self, coil_ohm: S) -> S {
        (S::cst(self.supply_v - self.vce_sat_v) / (coil_ohm + self.vce_sat_ohm)).max_of(S::cst(0.0))
    }

    /// Coil current (A) for input `input_v` and coil resistance `coil_ohm`.
    /// Non-finite inputs are the caller's business (the plant rejects them).
    #[inline]
    pub fn current_a(&self, input_v: f64, coil_ohm: f64) -> f64 {
        self.current_a_of(self.transconductance_a_v, input_v, coil_ohm)
    }

    /// [`Self::current_a`] with the transconductance and the resistance
    /// in any [`Scalar`] (their derivatives carried to the current).
    #[inline]
    pub fn current_a_of<S: Scalar>(&self, transconductance_a_v: S, input_v: f64, coil_ohm: S) -> S {
        let linear = transconductance_a_v * (input_v - self.turn_on_v);
        if linear.val() < 0.0 {
            // Below turn-on the clamp gives 0 whatever the limit: skip the
            // saturation current's division.
            return S::cst(0.0);
        }
        let limit = S::cst(self.max_current_a).min_of(self.saturation_current_of(coil_ohm));
        linear.clamp_to(S::cst(0.0), limit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn current_curve() {
        let d = DriverParams::default();
        let r = 5.0;
        assert_eq!(d.current_a(0.0, r), 0.0);
        assert_eq!(d.current_a(1.69, r), 0.0);
        assert!((d.current_a(2.0, r) - 1.2 * 0.3).abs() < 1e-12);
        // Saturation: (5 − 0.75)/(5 + 1.5) = 0.6538 A > 0.5 A limit.
        assert_eq!(d.current_a(5.0, r), 0.5);
        // A 10 Ω coil saturates below the channel limit: 4.25/11.5 = 0.37 A.
        assert!((d.current_a(5.0, 10.0) - 4.25 / 11.5).abs() < 1e-12);
        // The saturated point satisfies KVL with V_CEsat = 0.75 + 1.5 I.
        let i = d.saturation_current_a(10.0);
        assert!((i * 10.0 + 0.75 + 1.5 * i - 5.0).abs() < 1e-12);
        // Monotone in the input.
        let mut last = 0.0;
        for k in 0..=500 {
            let v = k as f64 * 0.01;
            let c = d.current_a(v, r);
            assert!(c >= last);
            last = c;
        }
    }

    #[test]
    fn bad_parameters_name_the_field() {
        let d = DriverParams {
            supply_v: -1.0,
            ..DriverParams::default()
        };
        assert!(d
            .validate("driver.")
            .unwrap_err()
            .to_string()
            .contains("driver.supply_v"));
    }
}
