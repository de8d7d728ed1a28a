//! Calibration files (`softjoint calibrate wire -o`): one estimation law
//! per angle, loaded by scenarios, `hil` and the console.
use std::path::Path;

use anyhow::{bail, Context};
use firmware::estimate::{CalibrationError, LinearLaw, PlaneLaw, QuadraticLaw};
use serde::{Deserialize, Serialize};

/// A law as stored in calibration files (sensor numbers 1-based, as the
/// paper numbers them).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "method", rename_all = "snake_case", deny_unknown_fields)]
pub enum LawSpec {
    /// Eq. 2 on sensor `sensor`.
    Single {
        /// Sensor (1-based).
        sensor: u8,
        /// d² coefficient (deg/mm²).
        a: f64,
        /// d coefficient (deg/mm).
        b: f64,
        /// Constant (deg).
        c: f64,
    },
    /// Eq. 3 on d[plus] − d[minus].
    Differential {
        /// Sensor pushed in as the angle rises (1-based).
        plus: u8,
        /// The antagonistic sensor (1-based).
        minus: u8,
        /// Slope (deg/mm).
        gain: f64,
        /// Offset (deg).
        offset: f64,
    },
    /// Eq. 4.
    Switching {
        /// Differential branch, plus sensor (1-based).
        plus: u8,
        /// Differential branch, minus sensor (1-based).
        minus: u8,
        /// Slope (deg/mm).
        gain: f64,
        /// Offset (deg).
        offset: f64,
        /// Single-sensor branch sensor (1-based).
        sensor: u8,
        /// d² coefficient.
        a: f64,
        /// d coefficient.
        b: f64,
        /// Constant.
        c: f64,
        /// Switching angle (deg).
        threshold_deg: f64,
        /// Hysteresis band (deg).
        hysteresis_deg: f64,
    },
}

impl LawSpec {
    /// A core law as the file writes it (sensor indices to 1-based numbers).
    pub fn from_law(law: &PlaneLaw) -> LawSpec {
        let n = |i: u8| i.saturating_add(1);
        match *law {
            PlaneLaw::Single { sensor, law } => LawSpec::Single {
                sensor: n(sensor),
                a: f64::from(law.a),
                b: f64::from(law.b),
                c: f64::from(law.c),
            },
            PlaneLaw::Differential { plus, minus, law } => LawSpec::Differential {
                plus: n(plus),
                minus: n(minus),
                gain: f64::from(law.gain),
                offset: f64::from(law.offset),
            },
            PlaneLaw::Switching {
                plus,
                minus,
                high,
                sensor,
                low,
                threshold_deg,
                hysteresis_deg,
            } => LawSpec::Switching {
                plus: n(plus),
                minus: n(minus),
                gain: f64::from(high.gain),
                offset: f64::from(high.offset),
                sensor: n(sensor),
                a: f64::from(low.a),
                b: f64::from(low.b),
                c: f64::from(low.c),
                threshold_deg: f64::from(threshold_deg),
                hysteresis_deg: f64::from(hysteresis_deg),
            },
        }
    }

    /// The core's law (sensor numbers to 0-based indices).
    pub fn to_law(&self) -> anyhow::Result<PlaneLaw> {
        let idx = |s: u8| -> anyhow::Result<u8> {
            if s == 0 {
                bail!("sensor numbers are 1-based, got 0");
            }
            Ok(s - 1)
        };
        Ok(match *self {
            LawSpec::Single { sensor, a, b, c } => PlaneLaw::Single {
                sensor: idx(sensor)?,
                law: QuadraticLaw {
                    a: a as f32,
                    b: b as f32,
                    c: c as f32,
                },
            },
            LawSpec::Differential {
                plus,
                minus,
                gain,
                offset,
            } => PlaneLaw::Differential {
                plus: idx(plus)?,
                minus: idx(minus)?,
                law: LinearLaw {
                    gain: gain as f32,
                    offset: offset as f32,
                },
            },
            LawSpec::Switching {
                plus,
                minus,
                gain,
                offset,
                sensor,
                a,
                b,
                c,
                threshold_deg,
                hysteresis_deg,
            } => PlaneLaw::Switching {
                plus: idx(plus)?,
                minus: idx(minus)?,
                high: LinearLaw {
                    gain: gain as f32,
                    offset: offset as f32,
                },
                sensor: idx(sensor)?,
                low: QuadraticLaw {
                    a: a as f32,
                    b: b as f32,
                    c: c as f32,
                },
                threshold_deg: threshold_deg as f32,
                hysteresis_deg: hysteresis_deg as f32,
            },
        })
    }

    /// Sensor fields (name, 1-based number) of the law.
    fn sensor_fields(&self) -> Vec<(&'static str, u8)> {
        match *self {
            LawSpec::Single { sensor, .. } => vec![("sensor", sensor)],
            LawSpec::Differential { plus, minus, .. } => vec![("plus", plus), ("minus", minus)],
            LawSpec::Switching {
                plus,
                minus,
                sensor,
                ..
            } => vec![("plus", plus), ("minus", minus), ("sensor", sensor)],
        }
    }

    /// Numeric fields (name, value) of the law.
    pub(crate) fn number_fields(&self) -> Vec<(&'static str, f64)> {
        match *self {
            LawSpec::Single { a, b, c, .. } => vec![("a", a), ("b", b), ("c", c)],
            LawSpec::Differential { gain, offset, .. } => vec![("gain", gain), ("offset", offset)],
            LawSpec::Switching {
                gain,
                offset,
                a,
                b,
                c,
                threshold_deg,
                hysteresis_deg,
                ..
            } => vec![
                ("gain", gain),
                ("offset", offset),
                ("a", a),
                ("b", b),
                ("c", c),
                ("threshold_deg", threshold_deg),
                ("hysteresis_deg", hysteresis_deg),
            ],
        }
    }

    /// The largest sensor number the law reads (1-based).
    pub fn max_sensor(&self) -> u8 {
        self.sensor_fields()
            .into_iter()
            .map(|(_, s)| s)
            .max()
            .unwrap_or(0)
    }

    /// Checks the law for an array of `sensors` sensors the way the
    /// firmware will. The firmware's own check decides; this one only
    /// names the field when a number cannot be held in the f32 the
    /// firmware computes in, and says when a gain is 0 only after rounding.
    pub fn check(&self, sensors: usize) -> anyhow::Result<()> {
        for (name, v) in self.number_fields() {
            if !v.is_finite() {
                bail!("field `{name}` = {v} is not finite");
            }
            if !(v as f32).is_finite() {
                bail!(
                    "field `{name}` = {v:e} is outside the f32 range the firmware computes in (|value| <= {:e})",
                    f32::MAX
                );
            }
        }
        self.to_law()?.validate(sensors).map_err(|e| {
            let field = |name: &str| {
                self.number_fields()
                    .into_iter()
                    .find_map(|(n, v)| (n == name).then_some(v))
            };
            match (field("gain"), field("a"), field("b")) {
                (Some(g), ..) if e == CalibrationError::GainZero && g != 0.0 => {
                    anyhow::anyhow!("field `gain` = {g:e}, 0 in f32: {e}")
                }
                (_, Some(a), Some(b))
                    if e == CalibrationError::QuadraticFlat && (a != 0.0 || b != 0.0) =>
                {
                    anyhow::anyhow!("fields `a` = {a:e} and `b` = {b:e}, both 0 in f32: {e}")
                }
                _ => anyhow::anyhow!("{e}"),
            }
        })
    }

    /// The threshold (switching only).
    pub fn threshold_deg(&self) -> Option<f64> {
        match self {
            LawSpec::Switching { threshold_deg, .. } => Some(*threshold_deg),
            _ => None,
        }
    }
}

/// A calibration file: one law per angle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// α (3D) or θ (2D).
    pub alpha: LawSpec,
    /// β (3D only).
    #[serde(default)]
    pub beta: Option<LawSpec>,
}

impl CalibrationFile {
    /// Reads and validates a calibration file.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read calibration {}", path.display()))?;
        let c: CalibrationFile = crate::input::from_toml(&text, &path.display().to_string())?;
        c.check()
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(c)
    }

    /// Checks both laws, naming the table and field at fault. A file with
    /// `[beta]` is a 3D calibration (sensors d1..d4), one without a 2D one
    /// (sensor d1).
    pub fn check(&self) -> anyhow::Result<()> {
        if self.beta.is_none() && self.alpha.max_sensor() > 1 {
            bail!(
                "the `[beta]` table is missing: `[alpha]` reads sensor d{}, so this is a 3D calibration (sensors d1..d4), which needs a `[beta]` law too; a 2D calibration has `[alpha]` only, on sensor 1",
                self.alpha.max_sensor()
            );
        }
        let sensors = if self.beta.is_some() { 4 } else { 1 };
        for (name, law) in [("alpha", Some(&self.alpha)), ("beta", self.beta.as_ref())] {
            if let Some(l) = law {
                l.check(sensors)
                    .map_err(|e| anyhow::anyhow!("`[{name}]`: {e}"))?;
            }
        }
        Ok(())
    }

    /// Writes it as TOML, atomically: a write that fails leaves the file
    /// that was there.
    pub fn save(&self, path: &Path) -> anyhow::Result<()> {
        self.save_to(crate::output::AtomicFile::create(path)?)
    }

    /// Writes it into `file` (created before a computation, to check the
    /// path first) and commits it.
    pub fn save_to(&self, file: crate::output::AtomicFile) -> anyhow::Result<()> {
        let header = "# Wire-sensor calibration written by `softjoint calibrate wire`.\n\
                      # Sensor numbers are 1-based (the paper's d1..d4); angles in degrees, insertions in mm.\n";
        file.commit_toml(header, self)
    }

    /// The laws for the core.
    pub fn laws(&self) -> anyhow::Result<Vec<PlaneLaw>> {
        let mut v = vec![self.alpha.to_law()?];
        if let Some(b) = &self.beta {
            v.push(b.to_law()?);
        }
        Ok(v)
    }
}

/// A law as a formula (sensors 1-based, as the paper numbers them).
pub fn describe(law: &LawSpec) -> String {
    match law {
        LawSpec::Single { sensor, a, b, c } => format!("{a:.4}·d{sensor}² + {b:.4}·d{sensor} + {c:.4}"),
        LawSpec::Differential { plus, minus, gain, offset } => format!("{gain:.4}·(d{plus} − d{minus}) + {offset:.4}"),
        LawSpec::Switching { plus, minus, gain, offset, sensor, a, b, c, threshold_deg, .. } => format!(
            "≥ {threshold_deg:.2}°: {gain:.4}·(d{plus} − d{minus}) + {offset:.4}; below: {a:.4}·d{sensor}² + {b:.4}·d{sensor} + {c:.4}"
        ),
    }
}
