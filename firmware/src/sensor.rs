//! Wire length sensors: the hardware trait and the validity checks.
//!
//! embedded-hal 1.0 has no encoder or ADC trait, so the core defines
//! [`WireSensor`] for a pulse coder (a quadrature counter on a board, a
//! simulated coder in `hal-sim`, a sensor frame in hardware-in-the-loop).
//!
//! [`SensorGuard`] turns a set of readings taken at one instant into held
//! values plus fault flags: out of range (or not finite), implausible rate
//! of change, and stale (no successful reading for too long). A missing
//! reading is not a fault by itself — a camera delivers 30 frames/s to a
//! faster loop — until it has been missing for longer than the stale limit.

use crate::supervisor::Faults;

/// Why a pulse coder could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireSensorError {
    /// No new reading is available this instant.
    NotReady,
    /// The device reported a fault (open line, counter error).
    Fault,
}

/// A wire-insertion pulse coder.
pub trait WireSensor {
    /// Reads the current count.
    fn read_counts(&mut self) -> Result<i32, WireSensorError>;
}

impl<T: WireSensor + ?Sized> WireSensor for &mut T {
    fn read_counts(&mut self) -> Result<i32, WireSensorError> {
        (**self).read_counts()
    }
}

/// Plausibility limits for one kind of reading (insertions in mm, or
/// camera angles in degrees).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorLimits {
    /// Lowest plausible value.
    pub min: f32,
    /// Highest plausible value.
    pub max: f32,
    /// Largest plausible rate of change per second (absolute).
    pub max_rate_per_s: f32,
    /// A reading older than this (seconds) is stale.
    pub stale_after_s: f32,
}

impl SensorLimits {
    /// Wire insertions: ±10 mm (estimate: about 2.5× the ±3.9 mm that
    /// Eq. 2 needs for ±20°), 200 mm/s (estimate: the joint covers its range
    /// in ~0.2 s at the fastest, i.e. ~40 mm/s, with a 5× margin), stale
    /// after 50 ms (50 periods of a 1 kHz loop).
    pub const WIRE_DEFAULT: SensorLimits = SensorLimits {
        min: -10.0,
        max: 10.0,
        max_rate_per_s: 200.0,
        stale_after_s: 0.05,
    };

    /// Camera angles: ±45° (the joint moves ±20°, paper §VI-A), 1000°/s,
    /// stale after 0.2 s (six frames of a 30 frames/s NTSC camera).
    pub const CAMERA_DEFAULT: SensorLimits = SensorLimits {
        min: -45.0,
        max: 45.0,
        max_rate_per_s: 1000.0,
        stale_after_s: 0.2,
    };

    /// True when every limit is finite and ordered.
    pub fn is_valid(&self) -> bool {
        self.min.is_finite()
            && self.max.is_finite()
            && self.min < self.max
            && self.max_rate_per_s.is_finite()
            && self.max_rate_per_s > 0.0
            && self.stale_after_s.is_finite()
            && self.stale_after_s > 0.0
    }
}

/// Holds the last good value of `S` channels and checks new readings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorGuard<const S: usize> {
    limits: SensorLimits,
    value: [f32; S],
    last_ok_s: [Option<f32>; S],
    /// Time of the first check: a channel that has never delivered is
    /// stale only once the stale limit has passed since then (a camera's
    /// first frame arrives one frame period after start).
    started_s: Option<f32>,
}

impl<const S: usize> SensorGuard<S> {
    /// A guard with nothing read yet.
    pub fn new(limits: SensorLimits) -> Self {
        Self {
            limits,
            value: [0.0; S],
            last_ok_s: [None; S],
            started_s: None,
        }
    }

    /// The limits in use.
    pub fn limits(&self) -> SensorLimits {
        self.limits
    }

    /// Forgets all readings.
    pub fn reset(&mut self) {
        self.last_ok_s = [None; S];
        self.started_s = None;
    }

    /// Checks the readings taken at `now_s` (`None`: no new reading on that
    /// channel) and returns the held values with any of
    /// [`Faults::SENSOR_RANGE`], [`Faults::SENSOR_RATE`],
    /// [`Faults::SENSOR_STALE`]. A reading that fails a check is not
    /// accepted as the held value.
    pub fn check(&mut self, now_s: f32, readings: &[Option<f32>; S]) -> ([f32; S], Faults) {
        let mut faults = Faults::NONE;
        let lim = self.limits;
        let started = *self.started_s.get_or_insert(now_s);
        for ((value, last), reading) in self
            .value
            .iter_mut()
            .zip(self.last_ok_s.iter_mut())
            .zip(readings.iter())
        {
            if let Some(r) = *reading {
                if !r.is_finite() || r < lim.min || r > lim.max {
                    faults |= Faults::SENSOR_RANGE;
                } else {
                    let plausible = match *last {
                        Some(t) if now_s > t => {
                            (r - *value).abs() <= lim.max_rate_per_s * (now_s - t)
                        }
                        // Same instant or first reading: no rate to judge.
                        _ => true,
                    };
                    if plausible {
                        *value = r;
                        *last = Some(now_s);
                    } else {
                        faults |= Faults::SENSOR_RATE;
                    }
                }
            }
            match *last {
                None if !is_fresh(now_s - started, lim.stale_after_s) => {
                    faults |= Faults::SENSOR_STALE
                }
                None => {}
                Some(t) if !is_fresh(now_s - t, lim.stale_after_s) => {
                    faults |= Faults::SENSOR_STALE
                }
                Some(_) => {}
            }
        }
        (self.value, faults)
    }
}

/// True when a reading of age `age_s` is within `limit_s`. A NaN age (a NaN
/// clock) is not fresh: unknown age counts as stale.
pub(crate) fn is_fresh(age_s: f32, limit_s: f32) -> bool {
    age_s <= limit_s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn range_rate_and_staleness_are_flagged() {
        let mut g = SensorGuard::<2>::new(SensorLimits::WIRE_DEFAULT);
        let (_, f) = g.check(0.0, &[Some(1.0), None]);
        assert_eq!(
            f,
            Faults::NONE,
            "a channel gets the stale limit to deliver its first reading"
        );
        let (_, f) = g.check(0.051, &[Some(1.0), None]);
        assert_eq!(f, Faults::SENSOR_STALE, "channel 1 never read within 50 ms");
        let mut g = SensorGuard::<2>::new(SensorLimits::WIRE_DEFAULT);
        g.check(0.0, &[Some(1.0), Some(0.0)]);
        let (v, f) = g.check(0.001, &[Some(1.1), Some(0.0)]);
        assert_eq!(f, Faults::NONE);
        assert_eq!(v, [1.1, 0.0]);
        // 5 mm in 1 ms = 5000 mm/s: implausible, value held.
        let (v, f) = g.check(0.002, &[Some(6.1), Some(0.0)]);
        assert_eq!(f, Faults::SENSOR_RATE);
        assert_eq!(v[0], 1.1);
        // Out of range and NaN.
        assert_eq!(
            g.check(0.003, &[Some(11.0), Some(0.0)]).1,
            Faults::SENSOR_RANGE
        );
        assert_eq!(
            g.check(0.004, &[Some(f32::NAN), Some(0.0)]).1,
            Faults::SENSOR_RANGE
        );
        // Channel 0 has not been accepted since t = 0.001: stale after 50 ms.
        assert_eq!(g.check(0.050, &[None, Some(0.0)]).1, Faults::NONE);
        assert_eq!(g.check(0.052, &[None, Some(0.0)]).1, Faults::SENSOR_STALE);
        // A NaN clock is stale, not silently fresh.
        assert!(g
            .check(f32::NAN, &[Some(1.0), Some(0.0)])
            .1
            .contains(Faults::SENSOR_STALE));
    }
}
