//! The scenario file of `softjoint rheology`: the lattice's scenario
//! (block, model, contact, plate, measurements, objective), the reference
//! block that stands in for measurements, and the search settings. Read
//! here for the command and the Python package alike.
use std::fs;
use std::path::Path;

use anyhow::{Context, Result};
use plant_rheology::contact::ContactParams;
use plant_rheology::identify::ga::GaSettings;
use plant_rheology::identify::ra::RaSettings;
use plant_rheology::identify::reference::ReferenceConfig;
use plant_rheology::scenario::{BlockSpec, MeasureSpec, ModelSpec, Objective, PlateSpec, Scenario};
use serde::{Deserialize, Serialize};

/// The scenario file: the lattice's scenario, the reference block that
/// stands in for measurements, and the search settings.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScenarioFile {
    pub block: BlockSpec,
    pub model: ModelSpec,
    pub contact: ContactParams,
    pub plate: PlateSpec,
    pub measure: MeasureSpec,
    pub objective: Objective,
    pub reference: ReferenceConfig,
    pub ga: GaSettings,
    pub ra: RaSettings,
}

impl ScenarioFile {
    /// The lattice's scenario.
    pub fn scenario(&self) -> Scenario {
        Scenario {
            block: self.block.clone(),
            model: self.model.clone(),
            contact: self.contact,
            plate: self.plate.clone(),
            measure: self.measure.clone(),
            objective: self.objective,
        }
    }

    /// Reads and checks a scenario file (the built-in default without
    /// one); errors name the file and the field.
    pub fn load(path: Option<&Path>) -> Result<Self> {
        let Some(path) = path else {
            return Ok(Self::default());
        };
        let text = fs::read_to_string(path)
            .with_context(|| format!("cannot read scenario {}", path.display()))?;
        Self::from_text(&text, path)
    }

    /// Reads and checks a scenario file's text; errors name `path`.
    pub fn from_text(text: &str, path: &Path) -> Result<Self> {
        let file: ScenarioFile = toml::from_str(text)
            .map_err(|e| anyhow::anyhow!("{}: {}", path.display(), e.to_string().trim_end()))?;
        file.scenario()
            .validate()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        file.reference
            .validate()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        file.ga
            .validate()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        file.ra
            .validate()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(file)
    }
}
