//! Scenario files: what to simulate (joint, controller, estimator, targets
//! over time, disturbances, duration, seed), in TOML.
//!
//! Every field has a default, so `softjoint sim` with no file runs
//! [`Scenario::default`]: the 3D joint under wire-sensor feedback with
//! threshold-switching estimation, targets (0°, 0°) → (5°, 5°) → (10°, 10°).
//! A malformed file is an error naming the file, the field and the reason.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use plant_common::short_number as short;
use serde::{Deserialize, Serialize};

pub use crate::files::JointKind;

/// Gains the control core can hold: it computes in f32, where a smaller
/// positive gain rounds to zero (or a subnormal) and a larger one to infinity.
const F32_GAIN_RANGE: std::ops::RangeInclusive<f64> =
    (f32::MIN_POSITIVE as f64)..=(f32::MAX as f64);

/// Longest scenario (s): 31 years, a bound no run reaches, far inside
/// what the step count (u64), the core's clock (u64 µs: 584,000 years) and
/// f64 time (exact step times) can hold. The old 3600 s cap existed only
/// because the whole trace was kept in memory.
pub const MAX_DURATION_S: f64 = 1e9;

/// What the controller sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FeedbackKind {
    /// Wire length sensors.
    Wire,
    /// The 30 frames/s camera (the paper's visual feedback, §III).
    Camera,
}

/// How each pair uses its coils.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlMode {
    /// The antagonistic law (§V–VI).
    Antagonistic,
    /// One actuator, the other a bias spring (Eq. 1).
    Single,
}

/// Controller settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ControllerSpec {
    /// Single actuator or antagonistic.
    pub mode: ControlMode,
    /// Proportional gain per coil in the paper's numbering (V/deg): 2 values
    /// for 2D (coil 1, coil 2), 4 for 3D (K_P1..K_P4). One value applies to
    /// every coil.
    pub kp_v_per_deg: Vec<f64>,
    /// Integral gain (V/(deg·s)); 0 = the paper's pure P law.
    pub ki_v_per_deg_s: f64,
    /// Limit of the integral contribution (V).
    pub integral_limit_v: f64,
    /// The law's v_offset (V): its input at zero effort, 0 ≤ · < 5 (the
    /// paper's 1.7 V, its drivers' conduction threshold).
    pub v_offset_v: f64,
    /// A gains file written by `softjoint tune` (relative to the scenario
    /// file): its gains replace `kp_v_per_deg`, `ki_v_per_deg_s`,
    /// `integral_limit_v` and `v_offset_v`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gains_file: Option<PathBuf>,
}

impl Default for ControllerSpec {
    fn default() -> Self {
        Self {
            mode: ControlMode::Antagonistic,
            kp_v_per_deg: vec![2.0],
            ki_v_per_deg_s: 0.0,
            integral_limit_v: 1.0,
            v_offset_v: crate::files::gains::paper_v_offset(),
            gains_file: None,
        }
    }
}

/// How angles are estimated from the wires.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EstimatorMethod {
    /// The paper's published laws: Eq. 3 (3D) or Eq. 2 (2D).
    Paper,
    /// Threshold switching (Eq. 4/5) as `calibrate wire` fits it (3D): the
    /// threshold search keeps a single-wire branch only where it lowers the
    /// worst-case error; otherwise the law is the differential branch alone.
    Switching,
    /// One sensor, quadratic, calibrated (the jamming-prone method).
    Single,
    /// Differential linear law, calibrated (3D).
    Differential,
}

/// Estimator settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EstimatorSpec {
    /// Which law.
    pub method: EstimatorMethod,
    /// Calibration file written by `softjoint calibrate wire` (relative to
    /// the scenario file). Without one, calibrated methods first run a
    /// simulated calibration sweep of this same joint and fit it.
    pub calibration: Option<PathBuf>,
}

impl Default for EstimatorSpec {
    fn default() -> Self {
        Self {
            method: EstimatorMethod::Switching,
            calibration: None,
        }
    }
}

/// A change of desired angles at a time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetStep {
    /// From this time on (s).
    pub t_s: f64,
    /// Desired angles (deg): [θ] for 2D, [α, β] for 3D.
    pub deg: Vec<f64>,
}

/// A projection plane of the 3D joint, by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlaneName {
    /// α: coils 1 and 3, sensors 1 and 3.
    Alpha,
    /// β: coils 2 and 4, sensors 2 and 4.
    Beta,
}

impl PlaneName {
    /// Plane index (0 = α, 1 = β).
    pub fn index(self) -> usize {
        match self {
            PlaneName::Alpha => 0,
            PlaneName::Beta => 1,
        }
    }
}

/// Something done to the joint from `from_s` to `to_s`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Disturbance {
    /// A coil driven at a fixed voltage regardless of the controller (the
    /// paper's Fig. 9: coil 2 at 5 V from 4 s to 6 s).
    CoilVoltage {
        /// Coil, paper numbering (1-based).
        coil: usize,
        /// Driver input (V).
        volts: f64,
        /// Start (s).
        from_s: f64,
        /// End (s).
        to_s: f64,
    },
    /// A weight hanging from the link end by a thread led along
    /// `direction` (socket frame; default horizontal towards −θ).
    Weight {
        /// Mass (g).
        mass_g: f64,
        /// Plane for 3D ("alpha", the default, or "beta"); ignored for 2D.
        #[serde(default)]
        plane: Option<PlaneName>,
        /// Thread direction; default [-1, 0].
        #[serde(default)]
        direction: Option<[f64; 2]>,
        /// Hung at (s).
        from_s: f64,
        /// Thread cut at (s).
        to_s: f64,
    },
}

/// Plant options.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct PlantSpec {
    /// Replace the cartilage by a rigid bearing (the paper's Fig. 10–11).
    pub rigid_bearing: bool,
    /// A plant file (`softjoint identify joint` writes one; relative to the
    /// scenario file) whose parameters replace the defaults. The
    /// scenario's `seed` still seeds the run.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// The parameters in force instead of the defaults: the file's, once
    /// loaded, or set by a program (`softjoint tune`'s sampled plants).
    #[serde(skip)]
    pub params: Option<crate::files::plant::PlantParams>,
}

/// A complete scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Shown in reports.
    pub name: String,
    /// 2D or 3D.
    pub joint: JointKind,
    /// Simulated duration (s).
    pub duration_s: f64,
    /// Control period (µs); the paper's controller ran much faster than the
    /// camera; 1 ms (1 kHz) is the default.
    pub control_period_us: u32,
    /// Seed of every random stream (plant noise, jamming, camera).
    pub seed: u64,
    /// Feedback.
    pub feedback: FeedbackKind,
    /// Controller.
    pub controller: ControllerSpec,
    /// Estimator.
    pub estimator: EstimatorSpec,
    /// Desired angles over time (sorted by time; the first applies from 0).
    pub targets: Vec<TargetStep>,
    /// Disturbances.
    pub disturbances: Vec<Disturbance>,
    /// Plant options.
    pub plant: PlantSpec,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: "default: 3D joint, threshold switching, (0,0) → (5,5) → (10,10)".into(),
            joint: JointKind::ThreeD,
            duration_s: 30.0,
            control_period_us: 1000,
            seed: 1,
            feedback: FeedbackKind::Wire,
            controller: ControllerSpec::default(),
            estimator: EstimatorSpec::default(),
            targets: default_targets(2),
            disturbances: vec![],
            plant: PlantSpec::default(),
        }
    }
}

/// The default targets for a joint of `planes` angles: 0° → 5° (at 10 s)
/// → 10° (at 20 s) on every angle.
pub fn default_targets(planes: usize) -> Vec<TargetStep> {
    [(0.0, 0.0), (10.0, 5.0), (20.0, 10.0)]
        .map(|(t_s, deg)| TargetStep {
            t_s,
            deg: vec![deg; planes],
        })
        .to_vec()
}

impl Scenario {
    /// Angles controlled: 1 (2D) or 2 (3D).
    pub fn planes(&self) -> usize {
        match self.joint {
            JointKind::TwoD => 1,
            JointKind::ThreeD => 2,
        }
    }

    /// Coils: 2 (2D) or 4 (3D).
    pub fn coils(&self) -> usize {
        2 * self.planes()
    }

    /// Reads and validates a scenario file; errors name the file, the field
    /// and the reason.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read scenario {}", path.display()))?;
        let mut s: Scenario = crate::input::from_toml(&text, &path.display().to_string())?;
        // No targets in the file: the default's steps, one angle per plane
        // of this joint (a 2D file would otherwise inherit the 3D
        // default's two angles and be refused for targets it never wrote).
        // Nor a name: the file's, not the built-in default's description.
        let written =
            toml::from_str::<toml::Table>(plant_common::strip_bom(&text)).unwrap_or_default();
        if !written.contains_key("targets") {
            s.targets = default_targets(s.planes());
        }
        if !written.contains_key("name") {
            s.name = path.display().to_string();
        }
        let base = path.parent().unwrap_or(Path::new("."));
        for c in [
            &mut s.estimator.calibration,
            &mut s.plant.file,
            &mut s.controller.gains_file,
        ]
        .into_iter()
        .flatten()
        {
            if c.is_relative() {
                *c = base.join(&*c);
            }
        }
        if let Some(f) = &s.plant.file {
            let file = crate::files::plant::PlantFile::load(f)?;
            s.plant.params = Some(file.params().map_err(|e| {
                anyhow::anyhow!("{}: plant file {}: {e}", path.display(), f.display())
            })?);
        }
        if let Some(g) = &s.controller.gains_file {
            let gains = crate::files::gains::GainsFile::load(g)?;
            s.controller.kp_v_per_deg = gains.controller.kp_v_per_deg.clone();
            s.controller.ki_v_per_deg_s = gains.controller.ki_v_per_deg_s;
            s.controller.integral_limit_v = gains.controller.integral_limit_v;
            s.controller.v_offset_v = gains.controller.v_offset_v;
        }
        s.validate()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(s)
    }

    /// Checks ranges and lengths; the error names the field.
    pub fn validate(&self) -> anyhow::Result<()> {
        self.validate_time()?;
        self.validate_controller()?;
        self.validate_estimator_and_plant()?;
        self.validate_targets()?;
        for (i, d) in self.disturbances.iter().enumerate() {
            self.validate_disturbance(i, d)?;
        }
        Ok(())
    }

    /// Duration and control period: at least one step, at most
    /// [`MAX_DURATION_S`].
    fn validate_time(&self) -> anyhow::Result<()> {
        finite_positive("duration_s", self.duration_s)?;
        // Memory does not grow with the run (the trace streams to disk, the
        // summary is accumulated), so the only bound is one no run reaches.
        if self.duration_s > MAX_DURATION_S {
            bail!(
                "field `duration_s`: at most {MAX_DURATION_S:e} s (31 years), got {}",
                short(self.duration_s)
            );
        }
        if !(100..=1_000_000).contains(&self.control_period_us) {
            bail!(
                "field `control_period_us`: must be 100..=1000000, got {}",
                self.control_period_us
            );
        }
        if self.steps() == 0 {
            bail!(
                "field `duration_s`: {} s is shorter than one control period ({} s): nothing would be simulated",
                self.duration_s,
                self.period_s()
            );
        }
        Ok(())
    }

    /// Gains the control core can hold (it computes in f32: a gain that
    /// rounds to 0 or to infinity there is refused here, by name, rather
    /// than by the core), and a v_offset below the driver's supply.
    fn validate_controller(&self) -> anyhow::Result<()> {
        let kp = &self.controller.kp_v_per_deg;
        if !(kp.len() == 1 || kp.len() == self.coils()) {
            bail!(
                "field `controller.kp_v_per_deg`: give 1 value or {} (one per coil) for a {} joint, got {}",
                self.coils(),
                if self.planes() == 1 { "2D" } else { "3D" },
                kp.len()
            );
        }
        for (i, k) in kp.iter().enumerate() {
            let field = format!("controller.kp_v_per_deg[{i}]");
            finite_positive(&field, *k)?;
            if !(F32_GAIN_RANGE.contains(k)) {
                bail!(
                    "field `{field}`: outside the controller's f32 range {:e}..={:e}, got {k:e}",
                    F32_GAIN_RANGE.start(),
                    F32_GAIN_RANGE.end()
                );
            }
        }
        for (f, v) in [
            ("controller.ki_v_per_deg_s", self.controller.ki_v_per_deg_s),
            (
                "controller.integral_limit_v",
                self.controller.integral_limit_v,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                bail!("field `{f}`: must be a finite number ≥ 0, got {}", short(v));
            }
            if v > *F32_GAIN_RANGE.end() {
                bail!(
                    "field `{f}`: above the controller's f32 range (at most {:e}), got {v:e}",
                    F32_GAIN_RANGE.end()
                );
            }
        }
        let v = self.controller.v_offset_v;
        let supply = f64::from(firmware::control::PAPER_SUPPLY_V);
        if !(v.is_finite() && (0.0..supply).contains(&v)) {
            bail!(
                "field `controller.v_offset_v`: must be in 0..{} V (below the driver's supply), got {}",
                short(supply),
                short(v)
            );
        }
        Ok(())
    }

    /// An estimation method the joint's sensors allow, and a plant file
    /// of the scenario's joint kind.
    fn validate_estimator_and_plant(&self) -> anyhow::Result<()> {
        if self.planes() == 1
            && matches!(
                self.estimator.method,
                EstimatorMethod::Switching | EstimatorMethod::Differential
            )
        {
            bail!("field `estimator.method`: the 2D joint has one wire sensor; use \"paper\" or \"single\"");
        }
        match (&self.plant.params, self.joint) {
            (Some(crate::files::plant::PlantParams::TwoD(_)), JointKind::ThreeD) => {
                bail!("field `plant.file`: a 2D plant ([joint2d]) for `joint = \"3d\"`")
            }
            (Some(crate::files::plant::PlantParams::ThreeD(_)), JointKind::TwoD) => {
                bail!("field `plant.file`: a 3D plant ([joint3d]) for `joint = \"2d\"`")
            }
            _ => Ok(()),
        }
    }

    /// At least one target; times finite, ≥ 0 and in order; one angle per
    /// plane within the core's target range.
    fn validate_targets(&self) -> anyhow::Result<()> {
        if self.targets.is_empty() {
            bail!("field `targets`: at least one target is needed");
        }
        let mut last_t = f64::NEG_INFINITY;
        for (i, t) in self.targets.iter().enumerate() {
            if !(t.t_s.is_finite() && t.t_s >= 0.0) {
                bail!(
                    "field `targets[{i}].t_s`: must be a finite time ≥ 0, got {}",
                    short(t.t_s)
                );
            }
            if t.t_s < last_t {
                bail!(
                    "field `targets[{i}].t_s`: targets must be in time order ({} after {})",
                    short(t.t_s),
                    short(last_t)
                );
            }
            last_t = t.t_s;
            if t.deg.len() != self.planes() {
                bail!(
                    "field `targets[{i}].deg`: need {} angle(s) for this joint, got {}",
                    self.planes(),
                    t.deg.len()
                );
            }
            for (k, d) in t.deg.iter().enumerate() {
                if !(d.is_finite() && d.abs() <= f64::from(firmware::joint::DEFAULT_MAX_TARGET_DEG))
                {
                    bail!(
                        "field `targets[{i}].deg[{k}]`: must be within ±{}°, got {}",
                        firmware::joint::DEFAULT_MAX_TARGET_DEG,
                        short(*d)
                    );
                }
            }
        }
        Ok(())
    }

    /// Disturbance `i`: a coil of this joint within the driver's 0–5 V, or
    /// a positive mass on a finite non-zero thread; 0 ≤ from < to.
    fn validate_disturbance(&self, i: usize, d: &Disturbance) -> anyhow::Result<()> {
        let (from, to) = match d {
            Disturbance::CoilVoltage {
                coil,
                volts,
                from_s,
                to_s,
            } => {
                if !(1..=self.coils()).contains(coil) {
                    bail!(
                        "field `disturbances[{i}].coil`: must be 1..={}, got {coil}",
                        self.coils()
                    );
                }
                if !(volts.is_finite() && (0.0..=5.0).contains(volts)) {
                    bail!(
                        "field `disturbances[{i}].volts`: must be within 0–5 V, got {}",
                        short(*volts)
                    );
                }
                (*from_s, *to_s)
            }
            Disturbance::Weight {
                mass_g,
                plane,
                direction,
                from_s,
                to_s,
            } => {
                finite_positive(&format!("disturbances[{i}].mass_g"), *mass_g)?;
                let _ = plane; // an enum: serde refused anything else
                if let Some(dir) = direction {
                    // The weight's force is mass·g/|direction|·direction:
                    // a subnormal length overflows it.
                    if !(dir.iter().all(|v| v.is_finite()) && dir[0].hypot(dir[1]).is_normal()) {
                        bail!("field `disturbances[{i}].direction`: must be a finite non-zero vector (length at least {:e}), got [{}, {}]", f64::MIN_POSITIVE, short(dir[0]), short(dir[1]));
                    }
                }
                (*from_s, *to_s)
            }
        };
        if !(from.is_finite() && to.is_finite() && from >= 0.0 && to > from) {
            bail!(
                "fields `disturbances[{i}].from_s/to_s`: need 0 ≤ from_s < to_s, got {}..{}",
                short(from),
                short(to)
            );
        }
        Ok(())
    }

    /// Control period (s).
    pub fn period_s(&self) -> f64 {
        f64::from(self.control_period_us) * 1e-6
    }

    /// Control steps in the run.
    pub fn steps(&self) -> u64 {
        (self.duration_s / self.period_s()).round() as u64
    }

    /// Desired angles at time `t_s`.
    pub fn target_at(&self, t_s: f64) -> &[f64] {
        target_at(&self.targets, t_s)
    }
}

/// `v` when finite and > 0; else an error naming `field`.
fn finite_positive(field: &str, v: f64) -> anyhow::Result<()> {
    if !(v.is_finite() && v > 0.0) {
        bail!(
            "field `{field}`: must be a finite number > 0, got {}",
            short(v)
        );
    }
    Ok(())
}

/// Desired angles of `targets` at time `t_s`: the last target with
/// `t_s` ≤ the time, or the first target before it.
pub fn target_at(targets: &[TargetStep], t_s: f64) -> &[f64] {
    let mut cur: &[f64] = targets.first().map_or(&[], |t| &t.deg);
    for t in targets {
        if t.t_s <= t_s {
            cur = &t.deg;
        }
    }
    cur
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_round_trips_through_toml() {
        let s = Scenario::default();
        s.validate().unwrap();
        let text = toml::to_string(&s).unwrap();
        let back: Scenario = toml::from_str(&text).unwrap();
        assert_eq!(back, s);
        // The paper's v_offset reads as written, and is the core's f32.
        assert!(text.contains("v_offset_v = 1.7\n"), "{text}");
        assert_eq!(
            s.controller.v_offset_v as f32,
            firmware::control::PAPER_V_OFFSET_V
        );
    }

    #[test]
    fn errors_name_the_field() {
        let bad = |text: &str| -> String {
            match toml::from_str::<Scenario>(text) {
                Err(e) => e.to_string(),
                Ok(s) => s.validate().unwrap_err().to_string(),
            }
        };
        assert!(bad("duration_s = -1").contains("duration_s"));
        assert!(bad("joint = \"4d\"").contains("joint"));
        assert!(bad("[controller]\nkp_v_per_deg = [1.0, 2.0, 3.0]").contains("kp_v_per_deg"));
        assert!(bad("bogus = 1").contains("bogus"));
        assert!(bad("[[targets]]\nt_s = 0\ndeg = [1.0]").contains("targets[0].deg"));
        assert!(bad("[[targets]]\nt_s = 0\ndeg = [40.0, 0.0]").contains("targets[0].deg[0]"));
        assert!(bad(
            "[[disturbances]]\nkind = \"coil_voltage\"\ncoil = 9\nvolts = 5\nfrom_s = 1\nto_s = 2"
        )
        .contains("coil"));
        assert!(
            bad("joint = \"2d\"\n[[targets]]\nt_s = 0\ndeg = [1.0]").contains("estimator.method")
        );
    }
}
