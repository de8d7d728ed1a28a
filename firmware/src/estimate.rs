//! Joint-angle estimation from wire length sensors (seed 000, last paper,
//! §V–VI).
//!
//! A LEVEX pulse coder counts the insertion `d` of a 0.2 mm SUS304 wire into
//! a tube along the socket. Counts become millimetres through a
//! [`PulseCoder`], millimetres become degrees through a calibrated law:
//!
//! - [`QuadraticLaw`] on one sensor, Eq. 2: `θ = A d² + B d + C`
//!   (paper: A = 0.349, B = −5.525, C = 0.753);
//! - [`LinearLaw`] on the difference of two antagonistic sensors, Eq. 3:
//!   `α = A (d3 − d1) + B`, `β = C (d4 − d2) + D`
//!   (paper: 2.727, 0.323, 2.670, 0.131);
//! - threshold switching between the two, Eq. 4: the differential law when
//!   the angle is at or above `α_th`, the single-sensor quadratic below it
//!   (paper: `α_th = −7.46°`; its `A0..C1` were not published, so they come
//!   from calibration — see [`crate::fit`] and `softjoint calibrate wire`).
//!
//! Which method is active is decided on one selector signal, the
//! differential estimate (the paper's "α(t)" in Eq. 4), with a hysteresis
//! band around the threshold: the method changes only when the selector
//! leaves the band on the far side. The differential law is the selector
//! because it is valid over the whole range (it is the paper's baseline
//! Eq. 3, degraded only by jamming), whereas the single-sensor quadratic is
//! calibrated below the threshold only and may extrapolate wildly above it.
//! Deciding on the active method's own estimate instead would chatter
//! whenever the methods disagree by more than the band (after a switch the
//! new method may already lie beyond the opposite edge); with one selector
//! the band only has to exceed the noise. At a switch the output steps from
//! one method's value to the other's, so a jump is never larger than their
//! disagreement at that instant.
//!
//! Units: insertions in millimetres, angles in degrees.

/// Why a calibration was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum CalibrationError {
    /// A coefficient is NaN or infinite.
    CoefficientNotFinite,
    /// A sensor index is outside the sensor array.
    SensorIndexOutOfRange,
    /// The differential law needs two different sensors.
    SameSensorTwice,
    /// The switching threshold must be finite.
    ThresholdNotFinite,
    /// The hysteresis band must be finite and ≥ 0.
    HysteresisNegative,
    /// The pulse coder's mm per count must be finite and non-zero.
    ScaleNotUsable,
    /// The differential law's gain is zero: the estimate would be its
    /// offset whatever the sensors read.
    GainZero,
    /// The single-sensor law's `a` and `b` are both zero: the estimate
    /// would be its constant `c` whatever the sensor reads.
    QuadraticFlat,
}

impl core::fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            CalibrationError::CoefficientNotFinite => "a coefficient is not finite",
            CalibrationError::SensorIndexOutOfRange => "a sensor index is outside the sensor array",
            CalibrationError::SameSensorTwice => "the differential law needs two different sensors",
            CalibrationError::ThresholdNotFinite => "the switching threshold is not finite",
            CalibrationError::HysteresisNegative => "the hysteresis band must be finite and >= 0",
            CalibrationError::ScaleNotUsable => {
                "the pulse coder's mm per count must be finite and non-zero"
            }
            CalibrationError::GainZero => {
                "the differential gain must be non-zero (with 0 the estimate ignores the sensors)"
            }
            CalibrationError::QuadraticFlat => {
                "the single-sensor law needs a or b non-zero (with both 0 the estimate is c whatever the sensor reads)"
            }
        })
    }
}

impl core::error::Error for CalibrationError {}

fn finite(values: &[f32]) -> Result<(), CalibrationError> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(CalibrationError::CoefficientNotFinite)
    }
}

/// Pulse counts to wire insertion.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PulseCoder {
    mm_per_count: f32,
    zero_counts: i32,
}

impl PulseCoder {
    /// `insertion_mm = (counts − zero_counts) · mm_per_count`.
    pub fn new(mm_per_count: f32, zero_counts: i32) -> Result<Self, CalibrationError> {
        if !mm_per_count.is_finite() || mm_per_count == 0.0 {
            return Err(CalibrationError::ScaleNotUsable);
        }
        Ok(Self {
            mm_per_count,
            zero_counts,
        })
    }

    /// Millimetres per count.
    pub fn mm_per_count(&self) -> f32 {
        self.mm_per_count
    }

    /// Count reading at zero insertion.
    pub fn zero_counts(&self) -> i32 {
        self.zero_counts
    }

    /// Insertion in millimetres for a count reading.
    pub fn insertion_mm(&self, counts: i32) -> f32 {
        // i64 avoids overflow for counts near the i32 limits.
        (i64::from(counts) - i64::from(self.zero_counts)) as f32 * self.mm_per_count
    }
}

impl Default for PulseCoder {
    /// 0.01 mm per count, zero at count 0 (an estimate: the LEVEX coder's
    /// resolution is not given in the paper).
    fn default() -> Self {
        Self {
            mm_per_count: 0.01,
            zero_counts: 0,
        }
    }
}

/// Single-sensor law, seed Eq. 2: `θ = a d² + b d + c` (deg, d in mm).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QuadraticLaw {
    /// Coefficient of d² (deg/mm²).
    pub a: f32,
    /// Coefficient of d (deg/mm).
    pub b: f32,
    /// Constant (deg).
    pub c: f32,
}

impl QuadraticLaw {
    /// The paper's 2D calibration (Eq. 2): A = 0.349, B = −5.525, C = 0.753.
    pub const PAPER_2D: QuadraticLaw = QuadraticLaw {
        a: 0.349,
        b: -5.525,
        c: 0.753,
    };

    /// Angle in degrees for insertion `d_mm`.
    pub fn angle_deg(&self, d_mm: f32) -> f32 {
        (self.a * d_mm + self.b) * d_mm + self.c
    }
}

/// Differential law, seed Eq. 3: `angle = gain · (d_plus − d_minus) + offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinearLaw {
    /// Slope (deg/mm).
    pub gain: f32,
    /// Offset (deg).
    pub offset: f32,
}

impl LinearLaw {
    /// The paper's α law (Eq. 3): A = 2.727, B = 0.323.
    pub const PAPER_ALPHA: LinearLaw = LinearLaw {
        gain: 2.727,
        offset: 0.323,
    };
    /// The paper's β law (Eq. 3): C = 2.670, D = 0.131.
    pub const PAPER_BETA: LinearLaw = LinearLaw {
        gain: 2.670,
        offset: 0.131,
    };

    /// Angle in degrees for a difference of insertions `diff_mm`.
    pub fn angle_deg(&self, diff_mm: f32) -> f32 {
        self.gain * diff_mm + self.offset
    }
}

/// Which estimation method produced an angle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Method {
    /// One sensor, quadratic (Eq. 2, or the low branch of Eq. 4).
    Single,
    /// Two sensors, linear in their difference (Eq. 3, high branch of Eq. 4).
    Differential,
}

/// How one projection angle is computed from `S` sensor insertions.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PlaneLaw {
    /// Eq. 2 on sensor `sensor`.
    Single {
        /// Sensor index (0-based: the paper's d1 is 0).
        sensor: u8,
        /// The quadratic.
        law: QuadraticLaw,
    },
    /// Eq. 3 on `d[plus] − d[minus]`.
    Differential {
        /// Sensor whose insertion grows with the angle (d3 for α).
        plus: u8,
        /// Sensor whose insertion shrinks with the angle (d1 for α).
        minus: u8,
        /// The linear law.
        law: LinearLaw,
    },
    /// Eq. 4: differential at or above the threshold, single below, with a
    /// hysteresis band of total width `hysteresis_deg` centred on it.
    Switching {
        /// Differential branch (used when angle ≥ threshold).
        plus: u8,
        /// See `plus`.
        minus: u8,
        /// Linear law of the differential branch.
        high: LinearLaw,
        /// Sensor of the single-sensor branch.
        sensor: u8,
        /// Quadratic law of the single-sensor branch (angle < threshold).
        low: QuadraticLaw,
        /// Switching angle (deg); the paper's α_th = −7.46°.
        threshold_deg: f32,
        /// Total width of the hysteresis band (deg).
        hysteresis_deg: f32,
    },
}

/// The paper's α threshold for Eq. 4 (seed 000, last paper, §VI-D).
pub const PAPER_ALPHA_THRESHOLD_DEG: f32 = -7.46;

/// Default hysteresis band of the switching law: 0.5° total (estimate: a few
/// times the ~0.1° noise of one count step of the quadratic at 0.01 mm/count).
pub const DEFAULT_HYSTERESIS_DEG: f32 = 0.5;

impl PlaneLaw {
    /// The sensors this law reads, as a bit mask (bit k = sensor k; indices
    /// of 32 or more, which no validated law has, are left out).
    pub fn sensor_mask(&self) -> u32 {
        let bit = |i: u8| 1u32.checked_shl(u32::from(i)).unwrap_or(0);
        match *self {
            PlaneLaw::Single { sensor, .. } => bit(sensor),
            PlaneLaw::Differential { plus, minus, .. } => bit(plus) | bit(minus),
            PlaneLaw::Switching {
                plus,
                minus,
                sensor,
                ..
            } => bit(plus) | bit(minus) | bit(sensor),
        }
    }

    /// True when every float the law's kind uses is finite (the fields a
    /// kind does not use are not part of it).
    pub fn is_finite(&self) -> bool {
        match *self {
            PlaneLaw::Single { law, .. } => [law.a, law.b, law.c].iter().all(|v| v.is_finite()),
            PlaneLaw::Differential { law, .. } => law.gain.is_finite() && law.offset.is_finite(),
            PlaneLaw::Switching {
                high,
                low,
                threshold_deg,
                hysteresis_deg,
                ..
            } => [
                high.gain,
                high.offset,
                low.a,
                low.b,
                low.c,
                threshold_deg,
                hysteresis_deg,
            ]
            .iter()
            .all(|v| v.is_finite()),
        }
    }

    /// Checks coefficients and sensor indices against an array of `sensors`.
    pub fn validate(&self, sensors: usize) -> Result<(), CalibrationError> {
        let idx_ok = |i: u8| usize::from(i) < sensors;
        match *self {
            PlaneLaw::Single { sensor, law } => {
                finite(&[law.a, law.b, law.c])?;
                if law.a == 0.0 && law.b == 0.0 {
                    return Err(CalibrationError::QuadraticFlat);
                }
                if !idx_ok(sensor) {
                    return Err(CalibrationError::SensorIndexOutOfRange);
                }
            }
            PlaneLaw::Differential { plus, minus, law } => {
                finite(&[law.gain, law.offset])?;
                if law.gain == 0.0 {
                    return Err(CalibrationError::GainZero);
                }
                if !idx_ok(plus) || !idx_ok(minus) {
                    return Err(CalibrationError::SensorIndexOutOfRange);
                }
                if plus == minus {
                    return Err(CalibrationError::SameSensorTwice);
                }
            }
            PlaneLaw::Switching {
                plus,
                minus,
                high,
                sensor,
                low,
                threshold_deg,
                hysteresis_deg,
            } => {
                PlaneLaw::Differential {
                    plus,
                    minus,
                    law: high,
                }
                .validate(sensors)?;
                PlaneLaw::Single { sensor, law: low }.validate(sensors)?;
                if !threshold_deg.is_finite() {
                    return Err(CalibrationError::ThresholdNotFinite);
                }
                if !(hysteresis_deg.is_finite() && hysteresis_deg >= 0.0) {
                    return Err(CalibrationError::HysteresisNegative);
                }
            }
        }
        Ok(())
    }
}

/// An angle estimate and the method that produced it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// Estimated angle (deg); NaN if an input was not finite.
    pub angle_deg: f32,
    /// Method used.
    pub method: Method,
}

/// Estimator for one projection angle: a validated [`PlaneLaw`] plus the
/// switching state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlaneEstimator<const S: usize> {
    law: PlaneLaw,
    active: Option<Method>,
}

fn sensor_mm<const S: usize>(d_mm: &[f32; S], i: u8) -> f32 {
    // Indices were validated at construction; NaN (→ sensor fault) rather
    // than a panic if that invariant were ever broken.
    d_mm.get(usize::from(i)).copied().unwrap_or(f32::NAN)
}

impl<const S: usize> PlaneEstimator<S> {
    /// Validates `law` for `S` sensors.
    pub fn new(law: PlaneLaw) -> Result<Self, CalibrationError> {
        law.validate(S)?;
        Ok(Self { law, active: None })
    }

    /// Wraps a law the caller has already validated with
    /// [`PlaneLaw::validate`] for `S` sensors.
    pub(crate) fn from_validated(law: PlaneLaw) -> Self {
        Self { law, active: None }
    }

    /// The law in use.
    pub fn law(&self) -> PlaneLaw {
        self.law
    }

    /// Forgets the switching state (the next estimate picks afresh).
    pub fn reset(&mut self) {
        self.active = None;
    }

    /// The method currently selected by the switching state (None before
    /// the first estimate of a switching law).
    pub fn active_method(&self) -> Option<Method> {
        self.active
    }

    /// Estimates the angle from the sensor insertions `d_mm`.
    pub fn estimate(&mut self, d_mm: &[f32; S]) -> Estimate {
        match self.law {
            PlaneLaw::Single { sensor, law } => Estimate {
                angle_deg: law.angle_deg(sensor_mm(d_mm, sensor)),
                method: Method::Single,
            },
            PlaneLaw::Differential { plus, minus, law } => Estimate {
                angle_deg: law.angle_deg(sensor_mm(d_mm, plus) - sensor_mm(d_mm, minus)),
                method: Method::Differential,
            },
            PlaneLaw::Switching {
                plus,
                minus,
                high,
                sensor,
                low,
                threshold_deg,
                hysteresis_deg,
            } => {
                let diff = high.angle_deg(sensor_mm(d_mm, plus) - sensor_mm(d_mm, minus));
                let single = low.angle_deg(sensor_mm(d_mm, sensor));
                let half = 0.5 * hysteresis_deg;
                let selector = diff;
                let method = match self.active {
                    None if selector >= threshold_deg => Method::Differential,
                    None => Method::Single,
                    Some(Method::Differential) if selector < threshold_deg - half => Method::Single,
                    Some(Method::Single) if selector >= threshold_deg + half => {
                        Method::Differential
                    }
                    Some(m) => m,
                };
                // Do not let a non-finite reading move the switching state.
                if diff.is_finite() && single.is_finite() {
                    self.active = Some(method);
                }
                let angle_deg = match method {
                    Method::Differential => diff,
                    Method::Single => single,
                };
                Estimate { angle_deg, method }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_laws_evaluate_as_printed() {
        // Eq. 2 at d = 2 mm: 0.349·4 − 5.525·2 + 0.753 = −8.901°
        assert!((QuadraticLaw::PAPER_2D.angle_deg(2.0) - (-8.901)).abs() < 1e-5);
        // Eq. 3: α at d3 − d1 = 1 mm: 3.05°; β at d4 − d2 = −2 mm: −5.209°
        let mut alpha = PlaneEstimator::<4>::new(PlaneLaw::Differential {
            plus: 2,
            minus: 0,
            law: LinearLaw::PAPER_ALPHA,
        })
        .unwrap();
        let mut beta = PlaneEstimator::<4>::new(PlaneLaw::Differential {
            plus: 3,
            minus: 1,
            law: LinearLaw::PAPER_BETA,
        })
        .unwrap();
        let d = [0.5, 2.5, 1.5, 0.5];
        assert!((alpha.estimate(&d).angle_deg - 3.05).abs() < 1e-5);
        assert!((beta.estimate(&d).angle_deg - (-5.209)).abs() < 1e-5);
    }

    #[test]
    fn pulse_coder_converts_and_survives_extreme_counts() {
        let c = PulseCoder::new(0.01, 100).unwrap();
        assert!((c.insertion_mm(350) - 2.5).abs() < 1e-6);
        assert!(PulseCoder::new(0.01, i32::MAX)
            .unwrap()
            .insertion_mm(i32::MIN)
            .is_finite());
        assert_eq!(
            PulseCoder::new(0.0, 0),
            Err(CalibrationError::ScaleNotUsable)
        );
        assert_eq!(
            PulseCoder::new(f32::NAN, 0),
            Err(CalibrationError::ScaleNotUsable)
        );
    }

    #[test]
    fn bad_calibrations_are_rejected_with_the_reason() {
        let bad_idx = PlaneLaw::Single {
            sensor: 4,
            law: QuadraticLaw::PAPER_2D,
        };
        assert_eq!(
            PlaneEstimator::<4>::new(bad_idx).err(),
            Some(CalibrationError::SensorIndexOutOfRange)
        );
        let same = PlaneLaw::Differential {
            plus: 1,
            minus: 1,
            law: LinearLaw::PAPER_ALPHA,
        };
        assert_eq!(
            PlaneEstimator::<4>::new(same).err(),
            Some(CalibrationError::SameSensorTwice)
        );
        let nan = PlaneLaw::Single {
            sensor: 0,
            law: QuadraticLaw {
                a: f32::NAN,
                b: 0.0,
                c: 0.0,
            },
        };
        assert_eq!(
            PlaneEstimator::<1>::new(nan).err(),
            Some(CalibrationError::CoefficientNotFinite)
        );
        let sw = PlaneLaw::Switching {
            plus: 2,
            minus: 0,
            high: LinearLaw::PAPER_ALPHA,
            sensor: 2,
            low: QuadraticLaw::PAPER_2D,
            threshold_deg: -7.46,
            hysteresis_deg: -1.0,
        };
        assert_eq!(
            PlaneEstimator::<4>::new(sw).err(),
            Some(CalibrationError::HysteresisNegative)
        );
        let flat = PlaneLaw::Differential {
            plus: 2,
            minus: 0,
            law: LinearLaw {
                gain: 0.0,
                offset: 1.0,
            },
        };
        assert_eq!(
            PlaneEstimator::<4>::new(flat).err(),
            Some(CalibrationError::GainZero)
        );
        let constant = PlaneLaw::Single {
            sensor: 0,
            law: QuadraticLaw {
                a: 0.0,
                b: 0.0,
                c: 5.0,
            },
        };
        assert_eq!(
            PlaneEstimator::<1>::new(constant).err(),
            Some(CalibrationError::QuadraticFlat)
        );
        // One of the two is enough (a linear single-sensor law is fine).
        let linear = PlaneLaw::Single {
            sensor: 0,
            law: QuadraticLaw {
                a: 0.0,
                b: -5.5,
                c: 0.7,
            },
        };
        assert!(PlaneEstimator::<1>::new(linear).is_ok());
    }
}
