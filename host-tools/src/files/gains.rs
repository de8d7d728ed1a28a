//! Gains files (`softjoint tune -o`): controller gains and how they were
//! found, loaded by scenarios (`controller.gains_file`) and the console
//! (`gains load FILE`).
use std::path::Path;

use anyhow::{bail, Context};
use serde::{Deserialize, Serialize};

use crate::files::JointKind;

/// Controller gains (what a gains file holds).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Gains {
    /// K_P per coil, paper numbering (V/°).
    pub kp_v_per_deg: Vec<f64>,
    /// Integral gain (V/(°·s)); 0 = P only.
    pub ki_v_per_deg_s: f64,
    /// Limit of the integral contribution (V).
    pub integral_limit_v: f64,
    /// The law's v_offset (V); gains files written before it existed have
    /// the paper's 1.7 V.
    #[serde(default = "paper_v_offset")]
    pub v_offset_v: f64,
}

/// The paper's v_offset (V), what gains files written before it existed
/// hold: the firmware's f32 constant as the decimal it is written as (1.7,
/// not the f32's exact 1.7000000476837158, which files and
/// `--print-default` would otherwise show; both are the same f32).
pub fn paper_v_offset() -> f64 {
    let v = firmware::control::PAPER_V_OFFSET_V;
    v.to_string().parse().unwrap_or(f64::from(v))
}

impl Gains {
    /// The paper's gains for a joint with `coils` coils.
    pub fn paper(coils: usize) -> Self {
        Self {
            kp_v_per_deg: vec![2.0; coils],
            ki_v_per_deg_s: 0.0,
            integral_limit_v: 1.0,
            v_offset_v: paper_v_offset(),
        }
    }
}

/// The costs of one candidate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Score {
    /// Mean cost over the plants.
    pub mean: f64,
    /// Standard deviation over the plants.
    pub std: f64,
    /// mean + std: what the search minimises.
    pub robust: f64,
    /// The run on plant 0 (the identified plant).
    pub nominal: RunCost,
}

/// What a gains file records about its tuning.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tuning {
    /// The plant file tuned on.
    pub plant_file: String,
    /// Candidates scored.
    pub candidates: usize,
    /// Plants per candidate.
    pub plants: usize,
    /// Seed.
    pub seed: u64,
    /// The tuned gains' score.
    pub score: Score,
    /// The paper's gains' score on the same plants.
    pub paper: Score,
    /// Whether v_offset was searched (`--search-v-offset`).
    #[serde(default)]
    pub v_offset_searched: bool,
    /// The tuned and the paper's gains on the held-out steps and plants
    /// (issue 28); absent in files written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub heldout: Option<HeldOut>,
}

/// Tuned gains against the paper's on manoeuvres the search never saw
/// (`host_tools::joint::tune::Manoeuvre`) and on plants drawn anew from
/// the identification's uncertainty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HeldOut {
    /// The tuned gains' score on the held-out steps (the first
    /// manoeuvre, the only one before the others were added).
    pub score: Score,
    /// The paper's gains' score there.
    pub paper: Score,
    /// Whether the tuned gains' robust cost is at most the paper's
    /// (within `host_tools::joint::tune::HELDOUT_TIE`) on the steps and on
    /// every other manoeuvre.
    pub beats_or_ties_paper: bool,
    /// The other manoeuvres (the planes in opposite directions, a load);
    /// absent in files written before them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub manoeuvres: Vec<ManoeuvreScore>,
}

/// The tuned and the paper's gains on one held-out manoeuvre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManoeuvreScore {
    /// The manoeuvre ("opposite planes", "load").
    pub name: String,
    /// Whether the tuned gains beat or tie the paper's on it.
    pub beats_or_ties_paper: bool,
    /// The tuned gains' score.
    pub tuned: Score,
    /// The paper's gains' score.
    pub paper: Score,
}

/// The comment lines `softjoint tune` starts a gains file with.
pub const GAINS_HEADER: &str = "# Written by `softjoint tune`: gains for the console (`gains load FILE`)\n# and scenarios (`controller.gains_file`).\n";

/// A gains file (`softjoint tune -o`), loaded by scenarios
/// (`controller.gains_file`) and the console (`gains load FILE`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GainsFile {
    /// "2d" or "3d".
    pub joint: JointKind,
    /// The gains.
    pub controller: Gains,
    /// How they were found.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tuning: Option<Tuning>,
}

impl GainsFile {
    /// `[K_P agonist, K_P antagonist]` per pair (plane) as the board takes
    /// them (coil order: [`firmware::joint::coil_index`]).
    pub fn pair_gains(&self) -> Vec<[f32; 2]> {
        let kp = &self.controller.kp_v_per_deg;
        let planes = kp.len() / 2;
        (0..planes)
            .map(|p| {
                let k = |ant| kp[firmware::joint::coil_index(planes, p, ant)] as f32;
                [k(false), k(true)]
            })
            .collect()
    }

    /// Reads and checks a gains file (K_P > 0 and one per coil, K_I and
    /// the limit ≥ 0, all finite); errors name the file and field.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read gains file {}", path.display()))?;
        Self::from_text(&text, path)
    }

    /// Reads and checks a gains file's text, as [`GainsFile::load`];
    /// errors name `path`.
    pub fn from_text(text: &str, path: &Path) -> anyhow::Result<Self> {
        let g: GainsFile = crate::input::from_toml(text, &path.display().to_string())?;
        let coils = match g.joint {
            JointKind::TwoD => 2,
            JointKind::ThreeD => 4,
        };
        let c = &g.controller;
        if c.kp_v_per_deg.len() != coils {
            bail!(
                "gains file {}: `controller.kp_v_per_deg` needs {coils} values (one per coil), got {}",
                path.display(),
                c.kp_v_per_deg.len()
            );
        }
        for (i, k) in c.kp_v_per_deg.iter().enumerate() {
            if !(k.is_finite() && *k > 0.0 && *k <= 100.0) {
                bail!(
                    "gains file {}: `controller.kp_v_per_deg[{i}]` must be in (0, 100] V/°, got {}",
                    path.display(),
                    plant_common::short_number(*k)
                );
            }
        }
        let supply = f64::from(firmware::control::PAPER_SUPPLY_V);
        if !(c.v_offset_v.is_finite() && (0.0..supply).contains(&c.v_offset_v)) {
            bail!(
                "gains file {}: `controller.v_offset_v` must be in 0..{} V (below the driver's supply), got {}",
                path.display(),
                plant_common::short_number(supply),
                plant_common::short_number(c.v_offset_v)
            );
        }
        for (f, v) in [
            ("ki_v_per_deg_s", c.ki_v_per_deg_s),
            ("integral_limit_v", c.integral_limit_v),
        ] {
            if !(v.is_finite() && (0.0..=100.0).contains(&v)) {
                bail!(
                    "gains file {}: `controller.{f}` must be in 0..=100, got {}",
                    path.display(),
                    plant_common::short_number(v)
                );
            }
        }
        Ok(g)
    }
}

/// Metrics of one closed-loop run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunCost {
    /// Mean settling time over segments and planes (s).
    pub settling_s: f64,
    /// Largest overshoot (°).
    pub overshoot_deg: f64,
    /// Largest steady-state error (°).
    pub steady_state_error_deg: f64,
    /// Peak coil temperature (°C).
    pub peak_coil_c: f64,
    /// Smallest margin of the firmware's modelled coil rise below its trip
    /// rise (K).
    pub budget_margin_k: f64,
    /// Whether any supervisor fault was seen.
    pub fault: bool,
    /// The cost (see the module docs).
    pub cost: f64,
}
