//! Calibrating the wire-sensor laws against reference angles, as the paper
//! did against camera images (seed 000, last paper, Fig. 14, 20, 22).
//!
//! Input: a sweep of insertions and reference angles (CSV). For each angle
//! the tool fits, with the core's least-squares accumulators
//! ([`firmware::fit::PolyFit`]):
//! - the single-sensor quadratic (Eq. 2) on the sensor that is *pulled out*
//!   on the low side (d3 for α, d4 for β, the only sensor in 2D);
//! - the differential linear law (Eq. 3) on d3 − d1 (α) or d4 − d2 (β);
//! - threshold switching (Eq. 4): for each candidate threshold on a 0.1°
//!   grid the quadratic is fitted to the rows below it and the linear law to
//!   the rows at or above it, the switching estimator (as the firmware runs
//!   it, hysteresis included, over the sweep in order) is evaluated on every
//!   row, and the threshold with the smallest worst-case error wins.
//!
//! The chosen estimator is the one with the smallest worst-case error.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{bail, Context};
use firmware::estimate::{
    CalibrationError, LinearLaw, PlaneEstimator, PlaneLaw, QuadraticLaw, DEFAULT_HYSTERESIS_DEG,
};
use firmware::fit::PolyFit;
use plant_common::short_number as short;
use serde::{Deserialize, Serialize};

/// One calibration sample: insertions (mm) and reference angles (deg).
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRow {
    /// Insertions d1..dS (mm).
    pub d_mm: Vec<f64>,
    /// Reference angles: [θ] (2D) or [α, β] (3D).
    pub angle_deg: Vec<f64>,
}

/// Header of a 3D sweep file.
pub const HEADER_3D: &str = "d1_mm,d2_mm,d3_mm,d4_mm,alpha_deg,beta_deg";
/// Header of a 2D sweep file.
pub const HEADER_2D: &str = "d_mm,theta_deg";

/// Writes a sweep as CSV (3D if rows have 4 insertions, else 2D).
pub fn write_sweep(path: &Path, rows: &[SweepRow]) -> anyhow::Result<()> {
    let three_d = rows.first().map(|r| r.d_mm.len() == 4).unwrap_or(true);
    let mut s = String::new();
    s.push_str(if three_d { HEADER_3D } else { HEADER_2D });
    s.push('\n');
    for r in rows {
        let cells: Vec<String> = r
            .d_mm
            .iter()
            .chain(r.angle_deg.iter())
            .map(|v| format!("{v:.5}"))
            .collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    crate::output::write_csv(path, &s)
}

/// Reads a sweep CSV; a bad row is an error naming the file and line.
pub fn read_sweep(path: &Path) -> anyhow::Result<Vec<SweepRow>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_sweep_named(&text, &path.display().to_string())
}

/// Parses sweep CSV text (header required: 3D or 2D columns, any order);
/// errors are labelled `sweep`.
pub fn parse_sweep(text: &str) -> anyhow::Result<Vec<SweepRow>> {
    parse_sweep_named(text, "sweep")
}

fn parse_sweep_named(text: &str, file: &str) -> anyhow::Result<Vec<SweepRow>> {
    let table = plant_common::csv_input::read_numeric(text, file)?;
    let find = |names: &[&str]| -> Option<Vec<usize>> {
        names
            .iter()
            .map(|n| table.columns.iter().position(|c| c == n))
            .collect()
    };
    let (d_cols, a_cols) = match (
        find(&["d1_mm", "d2_mm", "d3_mm", "d4_mm"]),
        find(&["alpha_deg", "beta_deg"]),
        find(&["d_mm"]),
        find(&["theta_deg"]),
    ) {
        (Some(d), Some(a), _, _) => (d, a),
        (_, _, Some(d), Some(a)) => (d, a),
        _ => bail!(
            "{file}:{}: the header must have the columns `{HEADER_3D}` (3D) or `{HEADER_2D}` (2D) in any order; it has: {}",
            table.header_line,
            plant_common::csv_input::excerpt(&table.columns.join(", "))
        ),
    };
    let mut rows = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        // The firmware estimates in f32: a value it cannot hold would only
        // surface later as an unusable fit.
        for (v, name) in row.values.iter().zip(&table.columns) {
            if !(*v as f32).is_finite() {
                bail!(
                    "{}",
                    table.error(
                        row.line,
                        Some(name),
                        format!(
                            "{v:e} is outside the f32 range the firmware computes in (|value| <= {:e})",
                            f32::MAX
                        )
                    )
                );
            }
        }
        rows.push(SweepRow {
            d_mm: d_cols.iter().map(|&c| row.values[c]).collect(),
            angle_deg: a_cols.iter().map(|&c| row.values[c]).collect(),
        });
    }
    table.require_rows(10, "to calibrate")?;
    Ok(rows)
}

/// Max and RMS error of one method over the sweep (deg).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorStats {
    /// Worst-case |estimate − reference|.
    pub max_error_deg: f64,
    /// Root mean square error.
    pub rms_error_deg: f64,
}

/// The fits of one angle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlaneFit {
    /// "alpha", "beta" or "theta".
    pub angle: String,
    /// Single-sensor quadratic over the whole sweep, and its errors.
    pub single: (LawSpec, ErrorStats),
    /// Differential law over the whole sweep (3D only).
    pub differential: Option<(LawSpec, ErrorStats)>,
    /// Threshold switching (3D only).
    pub switching: Option<(LawSpec, ErrorStats)>,
    /// The method with the smallest worst-case error.
    pub chosen: LawSpec,
    /// Its errors.
    pub chosen_errors: ErrorStats,
}

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
    fn number_fields(&self) -> Vec<(&'static str, f64)> {
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

/// Runs an estimator over the rows in order and returns its errors.
fn evaluate<const S: usize>(law: PlaneLaw, rows: &[SweepRow], plane: usize) -> Option<ErrorStats> {
    let mut est = PlaneEstimator::<S>::new(law).ok()?;
    let (mut max, mut sq) = (0.0f64, 0.0f64);
    for r in rows {
        let d: [f32; S] =
            core::array::from_fn(|k| r.d_mm.get(k).copied().unwrap_or(f64::NAN) as f32);
        let e = f64::from(est.estimate(&d).angle_deg) - r.angle_deg[plane];
        max = max.max(e.abs());
        sq += e * e;
    }
    Some(ErrorStats {
        max_error_deg: max,
        rms_error_deg: (sq / rows.len().max(1) as f64).sqrt(),
    })
}

fn fit_quadratic(rows: impl Iterator<Item = (f64, f64)>) -> Option<[f64; 3]> {
    let mut f = PolyFit::quadratic(0.0);
    rows.for_each(|(x, y)| f.add(x, y));
    f.solve().ok()
}

fn fit_linear(rows: impl Iterator<Item = (f64, f64)>) -> Option<[f64; 3]> {
    let mut f = PolyFit::linear(0.0);
    rows.for_each(|(x, y)| f.add(x, y));
    f.solve().ok()
}

/// Fits every method for every angle of the sweep.
pub fn fit(rows: &[SweepRow]) -> anyhow::Result<Vec<PlaneFit>> {
    let Some(first) = rows.first() else {
        bail!("no rows")
    };
    if first.d_mm.len() == 1 {
        return Ok(vec![fit_plane::<1>(rows, 0, "theta", 0, None)?]);
    }
    // α: d3 − d1, single on d3; β: d4 − d2, single on d4 (0-based indices).
    Ok(vec![
        fit_plane::<4>(rows, 0, "alpha", 2, Some(0))?,
        fit_plane::<4>(rows, 1, "beta", 3, Some(1))?,
    ])
}

/// Smallest span of reference angles a sweep must cover (deg). Below it a
/// law would fit the reference's noise (the camera's ≈ 0.03°) and the
/// wires' stick-slip, not the joint: a constant angle gave a = b = 0 with
/// 0.000° error as the "chosen" law. The paper sweeps ±20° (estimate).
pub const MIN_SWEEP_SPAN_DEG: f64 = 1.0;

/// Step of the threshold search (deg).
const THRESHOLD_GRID_DEG: f64 = 0.1;
/// Most thresholds the search tries (a 10 000° span at 0.1°).
const MAX_THRESHOLD_CANDIDATES: f64 = 100_000.0;

fn fit_plane<const S: usize>(
    rows: &[SweepRow],
    plane: usize,
    name: &str,
    plus: usize,
    minus: Option<usize>,
) -> anyhow::Result<PlaneFit> {
    let ang = |r: &SweepRow| r.angle_deg[plane];
    let (lo_deg, hi_deg) = rows
        .iter()
        .map(ang)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    // (NaN spans cannot occur: the reader refuses non-finite values.)
    if hi_deg - lo_deg < MIN_SWEEP_SPAN_DEG {
        bail!(
            "{name}: the sweep's `{name}_deg` only spans {}° to {}° over its {} rows; a calibration needs the joint moved through at least {MIN_SWEEP_SPAN_DEG}° (the paper sweeps ±20°), or the law fits noise",
            short(lo_deg),
            short(hi_deg),
            rows.len()
        );
    }
    let [a, b, c] =
        fit_quadratic(rows.iter().map(|r| (r.d_mm[plus], ang(r)))).ok_or_else(|| {
            anyhow::anyhow!(
                "{name}: the insertions do not determine a quadratic (sweep too narrow?)"
            )
        })?;
    let single = LawSpec::Single {
        sensor: plus as u8 + 1,
        a,
        b,
        c,
    };
    let range = |f: &dyn Fn(&SweepRow) -> f64| {
        rows.iter()
            .map(f)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            })
    };
    let (a_lo, a_hi) = range(&ang);
    let sensors = if S == 1 { 1 } else { 4 };
    // Why a fitted law cannot be used, and the data range behind it.
    let unusable = |what: &str, law: &LawSpec, x: &str, (x_lo, x_hi): (f64, f64)| {
        let beyond_f32 = law
            .number_fields()
            .iter()
            .any(|&(_, v)| !(v as f32).is_finite());
        let (why, hint) = match law.check(sensors) {
            Err(e) => (e.to_string(), beyond_f32),
            Ok(()) => (
                "its estimates are not finite in f32 on the sweep".into(),
                true,
            ),
        };
        let hint = if hint {
            ": angles this large over insertions this small need coefficients beyond f32"
        } else {
            ""
        };
        anyhow::anyhow!(
            "{name}: the {what} fit cannot be used: {why}; the sweep's {name} runs from {}° to {}° over {x} from {} to {} mm{hint}",
            short(a_lo),
            short(a_hi),
            short(x_lo),
            short(x_hi)
        )
    };
    let usable = |law: &LawSpec| -> Option<ErrorStats> {
        law.check(sensors).ok()?;
        let e = evaluate::<S>(law.to_law().ok()?, rows, plane)?;
        (e.max_error_deg.is_finite() && e.rms_error_deg.is_finite()).then_some(e)
    };
    let d_plus = format!("d{}", plus + 1);
    let single_err = usable(&single).ok_or_else(|| {
        unusable(
            "single-sensor quadratic (Eq. 2)",
            &single,
            &d_plus,
            range(&|r: &SweepRow| r.d_mm[plus]),
        )
    })?;
    let mut candidates = vec![(single.clone(), single_err)];
    let (mut differential, mut switching) = (None, None);
    if let Some(minus) = minus {
        let diff = |r: &SweepRow| r.d_mm[plus] - r.d_mm[minus];
        let [_, gain, offset] = fit_linear(rows.iter().map(|r| (diff(r), ang(r))))
            .ok_or_else(|| anyhow::anyhow!("{name}: the insertions do not determine a line"))?;
        let d = LawSpec::Differential {
            plus: plus as u8 + 1,
            minus: minus as u8 + 1,
            gain,
            offset,
        };
        let de = usable(&d).ok_or_else(|| {
            unusable(
                "differential (Eq. 3)",
                &d,
                &format!("{d_plus} − d{}", minus + 1),
                range(&diff),
            )
        })?;
        differential = Some((d.clone(), de));
        candidates.push((d, de));
        // Threshold search on a 0.1° grid within the sweep's range, keeping
        // at least 15 % of the rows on each side: a branch fitted to a
        // sliver of the range extrapolates wildly (the selector is the
        // differential law, so such a branch would only be used there, but
        // its coefficients would mean nothing).
        let mut sorted: Vec<f64> = rows.iter().map(ang).collect();
        sorted.sort_by(f64::total_cmp);
        let margin = sorted.len() * 15 / 100;
        let lo = sorted[margin];
        let hi = sorted[sorted.len() - 1 - margin];
        // Beyond this many candidates the search would take hours, and
        // beyond 2^53 · 0.1° `th += 0.1` no longer moves: it never ends.
        if (hi - lo) / THRESHOLD_GRID_DEG > MAX_THRESHOLD_CANDIDATES {
            bail!(
                "{name}: the threshold search would try every {THRESHOLD_GRID_DEG}° from {}° to {}°, more than {MAX_THRESHOLD_CANDIDATES} candidates: a joint sweep spans tens of degrees (is `{name}_deg` in degrees?)",
                short(lo),
                short(hi)
            );
        }
        let mut best: Option<(LawSpec, ErrorStats)> = None;
        let mut th = (lo * 10.0).ceil() / 10.0;
        while th <= hi {
            let below = rows.iter().filter(|r| ang(r) < th);
            let above = rows.iter().filter(|r| ang(r) >= th);
            if let (Some([qa, qb, qc]), Some([_, g, o])) = (
                fit_quadratic(below.map(|r| (r.d_mm[plus], ang(r)))),
                fit_linear(above.map(|r| (diff(r), ang(r)))),
            ) {
                let s = LawSpec::Switching {
                    plus: plus as u8 + 1,
                    minus: minus as u8 + 1,
                    gain: g,
                    offset: o,
                    sensor: plus as u8 + 1,
                    a: qa,
                    b: qb,
                    c: qc,
                    threshold_deg: th,
                    hysteresis_deg: f64::from(DEFAULT_HYSTERESIS_DEG),
                };
                if let Some(e) = s.to_law().ok().and_then(|l| evaluate::<S>(l, rows, plane)) {
                    if best
                        .as_ref()
                        .is_none_or(|(_, b)| e.max_error_deg < b.max_error_deg)
                    {
                        best = Some((s, e));
                    }
                }
            }
            th += THRESHOLD_GRID_DEG;
        }
        if let Some(b) = best {
            switching = Some(b);
        }
    }
    // The simplest law wins unless switching lowers the worst-case error by
    // at least 5 %: two branches and a threshold are worth it only for a
    // real improvement, not a fitting artefact.
    let (mut chosen, mut chosen_errors) = candidates
        .into_iter()
        .min_by(|x, y| x.1.max_error_deg.total_cmp(&y.1.max_error_deg))
        .ok_or_else(|| anyhow::anyhow!("{name}: no method could be fitted"))?;
    if let Some((law, e)) = &switching {
        if e.max_error_deg < 0.95 * chosen_errors.max_error_deg {
            (chosen, chosen_errors) = (law.clone(), *e);
        }
    }
    Ok(PlaneFit {
        angle: name.into(),
        single: (single, single_err),
        differential,
        switching,
        chosen,
        chosen_errors,
    })
}

/// The calibration file of a set of fits (the chosen law per angle).
pub fn calibration_of(fits: &[PlaneFit]) -> anyhow::Result<CalibrationFile> {
    let Some(first) = fits.first() else {
        bail!("no fits")
    };
    Ok(CalibrationFile {
        alpha: first.chosen.clone(),
        beta: fits.get(1).map(|f| f.chosen.clone()),
    })
}

/// An estimation method of the calibration (Eq. 2, Eq. 3, Eq. 4).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// One sensor, quadratic (Eq. 2).
    Single,
    /// Two sensors, linear in their difference (Eq. 3).
    Differential,
    /// Threshold switching between the two (Eq. 4).
    Switching,
}

impl Method {
    /// The name used in tables and files.
    pub fn name(self) -> &'static str {
        match self {
            Method::Single => "single",
            Method::Differential => "differential",
            Method::Switching => "switching",
        }
    }
}

/// A calibration file that forces one method for every angle (for
/// comparing methods in simulation).
pub fn calibration_with(fits: &[PlaneFit], method: Method) -> anyhow::Result<CalibrationFile> {
    let pick = |f: &PlaneFit| -> anyhow::Result<LawSpec> {
        let fitted = match method {
            Method::Single => Some(&f.single),
            Method::Differential => f.differential.as_ref(),
            Method::Switching => f.switching.as_ref(),
        };
        fitted
            .map(|(law, _)| law.clone())
            .ok_or_else(|| anyhow::anyhow!("{}: no {} fit", f.angle, method.name()))
    };
    let Some(first) = fits.first() else {
        bail!("no fits")
    };
    Ok(CalibrationFile {
        alpha: pick(first)?,
        beta: fits.get(1).map(pick).transpose()?,
    })
}

/// A human-readable table of the fits.
pub fn table(fits: &[PlaneFit]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{:<7} {:<13} {:>12} {:>12}  coefficients",
        "angle", "method", "max err (°)", "rms err (°)"
    );
    for f in fits {
        let mut rows = vec![(Method::Single.name(), &f.single)];
        if let Some(d) = &f.differential {
            rows.push((Method::Differential.name(), d));
        }
        if let Some(w) = &f.switching {
            rows.push((Method::Switching.name(), w));
        }
        for (name, (law, e)) in rows {
            let chosen = if *law == f.chosen { " ← chosen" } else { "" };
            let _ = writeln!(
                s,
                "{:<7} {:<13} {:>12.3} {:>12.3}  {}{}",
                f.angle,
                name,
                e.max_error_deg,
                e.rms_error_deg,
                describe(law),
                chosen
            );
        }
    }
    s
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_errors_name_the_line() {
        let e = parse_sweep("d_mm,theta_deg\n1,2\n3,x\n")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "sweep:3: column `theta_deg`: `x` is not a number");
        let e = parse_sweep("d_mm,theta_deg\n1,2\n3\n")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "sweep:3: 1 fields, but the header has 2");
        let e = parse_sweep("foo,bar\n").unwrap_err().to_string();
        assert!(e.starts_with("sweep:1: the header must have"), "{e}");
        let e = parse_sweep("d_mm,theta_deg\n1,NaN\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("sweep:2: column `theta_deg`"), "{e}");
        assert!(parse_sweep("").is_err());
        // An Excel export (byte-order mark, CRLF) reads like a plain file.
        let mut excel = String::from("\u{feff}d_mm,theta_deg\r\n");
        for i in 0..12 {
            excel.push_str(&format!("{},{}\r\n", f64::from(i) * 0.1, f64::from(i)));
        }
        assert_eq!(parse_sweep(&excel).unwrap().len(), 12);
    }

    #[test]
    fn exact_2d_data_recovers_eq2() {
        let rows: Vec<SweepRow> = (0..200)
            .map(|i| {
                let d = -3.5 + 7.0 * f64::from(i) / 199.0;
                SweepRow {
                    d_mm: vec![d],
                    angle_deg: vec![0.349 * d * d - 5.525 * d + 0.753],
                }
            })
            .collect();
        let fits = fit(&rows).unwrap();
        let LawSpec::Single { a, b, c, .. } = fits[0].chosen else {
            panic!("2D must choose single")
        };
        assert!((a - 0.349).abs() < 1e-6 && (b + 5.525).abs() < 1e-6 && (c - 0.753).abs() < 1e-6);
        assert!(fits[0].chosen_errors.max_error_deg < 1e-5);
    }

    #[test]
    fn switching_beats_both_methods_on_two_sided_jamming() {
        // A synthetic α plane: the differential law is exact except where
        // wire 1 jams (α < −7: it under-reads being pushed in), the
        // quadratic on d3 is exact except where wire 3 jams (α > 0).
        let rows: Vec<SweepRow> = (0..400)
            .map(|i| {
                let alpha = -20.0 + 40.0 * f64::from(i) / 399.0;
                let mut d3 = alpha / 5.454;
                let mut d1 = -alpha / 5.454;
                if alpha > 0.0 {
                    d3 -= 0.02 * alpha; // wire 3 jams while pushed in
                }
                if alpha < -7.0 {
                    d1 -= 0.05 * (-7.0 - alpha); // wire 1 jams
                    d3 += 0.0;
                }
                // β sweeps too (clean), so its fit is determined.
                let beta = 0.5 * alpha;
                SweepRow {
                    d_mm: vec![d1, -beta / 5.34, d3, beta / 5.34],
                    angle_deg: vec![alpha, beta],
                }
            })
            .collect();
        let f = &fit(&rows).unwrap()[0];
        let sw = f.switching.as_ref().unwrap().1.max_error_deg;
        assert!(
            sw < f.single.1.max_error_deg && sw < f.differential.as_ref().unwrap().1.max_error_deg,
            "{}",
            table(std::slice::from_ref(f))
        );
        assert!(matches!(f.chosen, LawSpec::Switching { .. }));
        // Between −7° and 0° both branches are exact, so the threshold must
        // land in or near that interval (grid 0.1°).
        let th = f.chosen.threshold_deg().unwrap();
        assert!((-7.5..=0.1).contains(&th), "threshold {th}");
    }
}
