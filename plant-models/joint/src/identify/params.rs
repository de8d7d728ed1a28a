//! The parameters identification fits: where each lives in the plant's
//! parameters, the coordinate the minimiser moves (log for positive
//! scales, kelvin for temperatures), and when its uncertainty is too large
//! for the log to have determined it.

use serde::Serialize;

use super::replay::PlaneModel;
use crate::SupportParams;

/// A parameter a lab cannot read off a datasheet.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Param {
    /// ULN2003 transconductance (A/V), `driver.transconductance_a_v`.
    Transconductance,
    /// Driver turn-on voltage (V), `driver.turn_on_v`.
    TurnOn,
    /// Convection coefficient (W/(m²·K)), `coil.convection_w_m2_k`; it sets
    /// the coil's thermal time constant m·c/(h·A).
    Convection,
    /// `coil.austenite_start_c`.
    AusteniteStart,
    /// `coil.austenite_finish_c`.
    AusteniteFinish,
    /// `coil.martensite_start_c`.
    MartensiteStart,
    /// `coil.martensite_finish_c`.
    MartensiteFinish,
    /// Clausius–Clapeyron shift (K/MPa), `coil.stress_shift_k_per_mpa`.
    StressShift,
    /// Sponge Young's modulus (Pa), `support.youngs_modulus_pa`.
    SpongeModulus,
    /// Sponge Rayleigh damping (s), `support.rayleigh_damping_s`.
    SpongeDamping,
    /// Link inertia about its centre of mass (kg·m²), `link.inertia_kg_m2`.
    LinkInertia,
    /// Wire buckling gain κ, `jam.buckling_gain`.
    JamGain,
    /// Wire lag ceiling at rest e₀ (mm), `jam.max_lag_mm`.
    JamMaxLag,
    /// Extra lag ceiling per mm pushed e₁, `jam.max_lag_per_mm`.
    JamLagPerMm,
}

/// How the minimiser moves a parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Scale {
    /// ln of the value; determined when its 1σ is below `max_rel` (relative).
    Log {
        /// Largest relative 1σ that counts as determined.
        max_rel: f64,
    },
    /// The value itself; determined when 1σ is below `max_abs` (its unit).
    Linear {
        /// Largest 1σ that counts as determined.
        max_abs: f64,
    },
}

impl Param {
    /// Every parameter, in stage order.
    pub const ALL: [Param; 14] = [
        Param::Transconductance,
        Param::TurnOn,
        Param::Convection,
        Param::AusteniteStart,
        Param::AusteniteFinish,
        Param::MartensiteStart,
        Param::MartensiteFinish,
        Param::StressShift,
        Param::SpongeModulus,
        Param::SpongeDamping,
        Param::LinkInertia,
        Param::JamGain,
        Param::JamMaxLag,
        Param::JamLagPerMm,
    ];

    /// The parameter whose [`Self::field`] is `field`.
    pub fn from_field(field: &str) -> Option<Param> {
        Self::ALL.into_iter().find(|p| p.field() == field)
    }

    /// Dotted path in a plane's parameters (wire ones under `jam.` of each
    /// of the plane's wires).
    pub fn field(self) -> &'static str {
        match self {
            Param::Transconductance => "driver.transconductance_a_v",
            Param::TurnOn => "driver.turn_on_v",
            Param::Convection => "coil.convection_w_m2_k",
            Param::AusteniteStart => "coil.austenite_start_c",
            Param::AusteniteFinish => "coil.austenite_finish_c",
            Param::MartensiteStart => "coil.martensite_start_c",
            Param::MartensiteFinish => "coil.martensite_finish_c",
            Param::StressShift => "coil.stress_shift_k_per_mpa",
            Param::SpongeModulus => "support.youngs_modulus_pa",
            Param::SpongeDamping => "support.rayleigh_damping_s",
            Param::LinkInertia => "link.inertia_kg_m2",
            Param::JamGain => "wires.jam.buckling_gain",
            Param::JamMaxLag => "wires.jam.max_lag_mm",
            Param::JamLagPerMm => "wires.jam.max_lag_per_mm",
        }
    }

    /// Unit for reports.
    pub fn unit(self) -> &'static str {
        match self {
            Param::Transconductance => "A/V",
            Param::TurnOn => "V",
            Param::Convection => "W/(m²·K)",
            Param::AusteniteStart
            | Param::AusteniteFinish
            | Param::MartensiteStart
            | Param::MartensiteFinish => "°C",
            Param::StressShift => "K/MPa",
            Param::SpongeModulus => "Pa",
            Param::SpongeDamping => "s",
            Param::LinkInertia => "kg·m²",
            Param::JamGain => "1",
            Param::JamMaxLag => "mm",
            Param::JamLagPerMm => "mm/mm",
        }
    }

    /// The minimiser's coordinate and the identifiability threshold:
    /// ±15 % (1σ) for scales, ±1.5 K for temperatures, ±0.03 K/MPa for the
    /// stress slope, ±0.05 for κ and ±0.02 mm for the lag ceilings. These
    /// are choices: a parameter known worse than that is no better than
    /// the prior for simulation.
    pub fn scale(self) -> Scale {
        match self {
            Param::AusteniteStart
            | Param::AusteniteFinish
            | Param::MartensiteStart
            | Param::MartensiteFinish => Scale::Linear { max_abs: 1.5 },
            Param::StressShift => Scale::Linear { max_abs: 0.03 },
            Param::TurnOn => Scale::Linear { max_abs: 0.05 },
            Param::JamGain => Scale::Linear { max_abs: 0.05 },
            Param::JamMaxLag | Param::JamLagPerMm => Scale::Linear { max_abs: 0.02 },
            _ => Scale::Log { max_rel: 0.15 },
        }
    }

    /// The value in `m`.
    pub fn get(self, m: &PlaneModel) -> f64 {
        let p = &m.plane;
        let jam =
            |f: fn(&crate::JamParams) -> f64| m.wires.first().map(|w| f(&w.jam)).unwrap_or(0.0);
        match self {
            Param::Transconductance => p.driver.transconductance_a_v,
            Param::TurnOn => p.driver.turn_on_v,
            Param::Convection => p.coil.convection_w_m2_k,
            Param::AusteniteStart => p.coil.austenite_start_c,
            Param::AusteniteFinish => p.coil.austenite_finish_c,
            Param::MartensiteStart => p.coil.martensite_start_c,
            Param::MartensiteFinish => p.coil.martensite_finish_c,
            Param::StressShift => p.coil.stress_shift_k_per_mpa,
            Param::SpongeModulus => match &p.support {
                SupportParams::Cartilage(c) => c.youngs_modulus_pa,
                SupportParams::RigidBearing(_) => f64::NAN,
            },
            Param::SpongeDamping => match &p.support {
                SupportParams::Cartilage(c) => c.rayleigh_damping_s,
                SupportParams::RigidBearing(_) => f64::NAN,
            },
            Param::LinkInertia => p.link.inertia_kg_m2,
            Param::JamGain => jam(|j| j.buckling_gain),
            Param::JamMaxLag => jam(|j| j.max_lag_mm),
            Param::JamLagPerMm => jam(|j| j.max_lag_per_mm),
        }
    }

    /// Sets the value in `m` (every wire of the plane for the jam ones).
    pub fn set(self, m: &mut PlaneModel, v: f64) {
        let p = &mut m.plane;
        match self {
            Param::Transconductance => p.driver.transconductance_a_v = v,
            Param::TurnOn => p.driver.turn_on_v = v,
            Param::Convection => p.coil.convection_w_m2_k = v,
            Param::AusteniteStart => p.coil.austenite_start_c = v,
            Param::AusteniteFinish => p.coil.austenite_finish_c = v,
            Param::MartensiteStart => p.coil.martensite_start_c = v,
            Param::MartensiteFinish => p.coil.martensite_finish_c = v,
            Param::StressShift => p.coil.stress_shift_k_per_mpa = v,
            Param::SpongeModulus => {
                if let SupportParams::Cartilage(c) = &mut p.support {
                    c.youngs_modulus_pa = v;
                }
            }
            Param::SpongeDamping => {
                if let SupportParams::Cartilage(c) = &mut p.support {
                    c.rayleigh_damping_s = v;
                }
            }
            Param::LinkInertia => p.link.inertia_kg_m2 = v,
            Param::JamGain => m.wires.iter_mut().for_each(|w| w.jam.buckling_gain = v),
            Param::JamMaxLag => m.wires.iter_mut().for_each(|w| w.jam.max_lag_mm = v),
            Param::JamLagPerMm => m.wires.iter_mut().for_each(|w| w.jam.max_lag_per_mm = v),
        }
    }

    /// Value → the minimiser's coordinate.
    pub fn to_coord(self, v: f64) -> f64 {
        match self.scale() {
            Scale::Log { .. } => v.max(1e-300).ln(),
            Scale::Linear { .. } => v,
        }
    }

    /// The minimiser's coordinate → value.
    pub fn from_coord(self, x: f64) -> f64 {
        match self.scale() {
            Scale::Log { .. } => x.exp(),
            Scale::Linear { .. } => x,
        }
    }

    /// 1σ of the value from 1σ of the coordinate at value `v`.
    pub fn value_std(self, v: f64, coord_std: f64) -> f64 {
        match self.scale() {
            Scale::Log { .. } => v * coord_std,
            Scale::Linear { .. } => coord_std,
        }
    }

    /// Whether a coordinate 1σ of `coord_std` counts as determined.
    pub fn determined(self, coord_std: f64) -> bool {
        match self.scale() {
            Scale::Log { max_rel } => coord_std <= max_rel,
            Scale::Linear { max_abs } => coord_std <= max_abs,
        }
    }
}
