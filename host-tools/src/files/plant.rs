//! Plant files: the joint's parameters in TOML, as `softjoint identify
//! joint` writes them, loaded by `sim`, `hil` and the calibration sweep in
//! place of the defaults (scenario field `plant.file`), and read by
//! `softjoint tune` with the identification's uncertainties.
//!
//! Exactly one of `[joint2d]` and `[joint3d]` holds the full parameter set
//! of `plant_joint` (every field optional, defaults filled in,
//! unknown keys refused); `[[uncertainty]]` lists the identified
//! parameters with their 1σ.

use std::path::Path;

use anyhow::{bail, Context};
use plant_joint::{Joint2dParams, Joint3dParams};
use serde::{Deserialize, Serialize};

/// The parameters of one joint.
// A few per scenario and per sampled plant; boxing the 3D variant would
// only add an indirection to every match.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum PlantParams {
    /// The 2D joint.
    TwoD(Joint2dParams),
    /// The 3D joint.
    ThreeD(Joint3dParams),
}

/// One identified parameter and its 1σ.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Uncertainty {
    /// "theta", "alpha" or "beta".
    pub plane: String,
    /// Field within the plane (e.g. `coil.convection_w_m2_k`).
    pub field: String,
    /// The identified value.
    pub value: f64,
    /// Its 1σ (same unit).
    pub std: f64,
}

/// A plant file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantFile {
    /// The 2D joint's parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint2d: Option<Joint2dParams>,
    /// The 3D joint's parameters.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint3d: Option<Joint3dParams>,
    /// The identified parameters with their 1σ.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub uncertainty: Vec<Uncertainty>,
}

impl PlantFile {
    /// A file for `params`.
    pub fn new(params: PlantParams, uncertainty: Vec<Uncertainty>) -> Self {
        match params {
            PlantParams::TwoD(p) => Self {
                joint2d: Some(p),
                uncertainty,
                ..Self::default()
            },
            PlantParams::ThreeD(p) => Self {
                joint3d: Some(p),
                uncertainty,
                ..Self::default()
            },
        }
    }

    /// The joint's parameters.
    pub fn params(&self) -> anyhow::Result<PlantParams> {
        match (&self.joint2d, &self.joint3d) {
            (Some(p), None) => Ok(PlantParams::TwoD(p.clone())),
            (None, Some(p)) => Ok(PlantParams::ThreeD(p.clone())),
            (Some(_), Some(_)) => bail!("give one of [joint2d] and [joint3d], not both"),
            (None, None) => bail!("no [joint2d] or [joint3d] table"),
        }
    }

    /// Reads and checks a plant file; errors name the file and the field.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read plant file {}", path.display()))?;
        Self::from_text(&text, &path.display().to_string())
    }

    /// Reads and checks a plant file's text; errors name `name` (the
    /// file's path, as [`PlantFile::load`] gives it) and the field.
    pub fn from_text(text: &str, name: &str) -> anyhow::Result<Self> {
        let path = Path::new(name);
        let f: PlantFile = crate::input::from_toml(text, name)?;
        let checked = match f.params() {
            Ok(PlantParams::TwoD(p)) => p.validate().map_err(|e| e.to_string()),
            Ok(PlantParams::ThreeD(p)) => p.validate().map_err(|e| e.to_string()),
            Err(e) => Err(e.to_string()),
        };
        if let Err(e) = checked {
            bail!("plant file {}: {e}", path.display());
        }
        for (i, u) in f.uncertainty.iter().enumerate() {
            if u.std.is_nan() || u.std < 0.0 {
                bail!(
                    "plant file {}: `uncertainty[{i}].std` must be ≥ 0",
                    path.display()
                );
            }
        }
        Ok(f)
    }

    /// Writes the file (through the checked writer).
    pub fn save(&self, path: &Path, header: &str) -> anyhow::Result<()> {
        crate::output::write_toml(path, header, self)
    }
}

/// The 1σ of every parameter identified and verified in `reports`, as a
/// plant file lists them (what `softjoint identify joint` writes and
/// `softjoint tune` samples).
pub fn uncertainties(reports: &[plant_joint::identify::PlaneReport]) -> Vec<Uncertainty> {
    reports
        .iter()
        .flat_map(|r| {
            r.estimates
                .iter()
                .filter(|e| e.identifiable && e.verified && e.std.is_finite())
                .map(|e| Uncertainty {
                    plane: r.plane.clone(),
                    field: e.field.clone(),
                    value: e.value,
                    std: e.std,
                })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_refuses_both_or_neither() {
        let f = PlantFile::new(
            PlantParams::ThreeD(Joint3dParams::default()),
            vec![Uncertainty {
                plane: "alpha".into(),
                field: "coil.convection_w_m2_k".into(),
                value: 60.0,
                std: 2.0,
            }],
        );
        let text = toml::to_string_pretty(&f).unwrap();
        let back: PlantFile = crate::input::from_toml(&text, "x").unwrap();
        assert_eq!(back, f);
        let two = PlantFile::new(PlantParams::TwoD(Joint2dParams::default()), vec![]);
        let text2 = toml::to_string_pretty(&two).unwrap();
        let both: PlantFile = crate::input::from_toml(
            &format!(
                "{text2}\n{}",
                toml::to_string_pretty(&PlantFile::new(
                    PlantParams::ThreeD(Joint3dParams::default()),
                    vec![]
                ))
                .unwrap()
            ),
            "x",
        )
        .unwrap();
        assert!(both.params().is_err());
        assert!(PlantFile::default().params().is_err());
        let e = crate::input::from_toml::<PlantFile>("[joint2d]\nsim.speed = 1\n", "p.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("p.toml:") && e.contains("speed"), "{e}");
    }
}
