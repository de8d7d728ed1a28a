//! Monotonic time for the control core: integer microseconds.
//!
//! The core never reads a clock; callers pass an [`Instant`] into every step.
//! Instants and durations are `u64` microseconds (as in smoltcp's
//! `time.rs`), so resolution never degrades with uptime and the counter
//! outlives any hardware: 2⁶⁴ µs is 584,000 years. An `f32` seconds clock, by
//! contrast, steps by 1 ms after about 2.3 hours (2²³ ms) and by 4 ms after
//! 9.3 hours, so consecutive 1 ms control steps would read the same time and
//! rate and staleness checks would silently stop working.
//!
//! A board's hardware counter is usually narrower and wraps (a `u32`
//! millisecond SysTick count wraps every 49.7 days). [`MillisCounter`]
//! extends such a counter to an [`Instant`] with wrapping arithmetic, as
//! long as it is read at least once per wrap period.
//!
//! Arithmetic saturates instead of panicking or wrapping: the core has no
//! panicking paths, and a saturated instant 584,000 years from now is as
//! harmless as it is unreachable. Step sizes for the physics (integrators,
//! the thermal budget) are derived per step with [`Duration::as_secs_f32`],
//! which is exact to f32 rounding for any duration the core sees.

use core::ops::{Add, AddAssign, Sub};

/// A point in time: microseconds since an arbitrary epoch (the board's
/// boot, or the start of a simulation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Instant {
    micros: u64,
}

/// A non-negative span of time in microseconds.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Duration {
    micros: u64,
}

impl Instant {
    /// The epoch.
    pub const ZERO: Instant = Instant { micros: 0 };

    /// The instant `micros` microseconds after the epoch.
    pub const fn from_micros(micros: u64) -> Self {
        Instant { micros }
    }

    /// The instant `millis` milliseconds after the epoch (saturating).
    pub const fn from_millis(millis: u64) -> Self {
        Instant {
            micros: millis.saturating_mul(1000),
        }
    }

    /// The instant `secs` seconds after the epoch (saturating).
    pub const fn from_secs(secs: u64) -> Self {
        Instant {
            micros: secs.saturating_mul(1_000_000),
        }
    }

    /// Microseconds since the epoch.
    pub const fn as_micros(self) -> u64 {
        self.micros
    }

    /// Whole milliseconds since the epoch.
    pub const fn as_millis(self) -> u64 {
        self.micros / 1000
    }

    /// Milliseconds since the epoch as a wrapping `u32` (the wire format of
    /// the protocol's board-clock fields, which wrap every 49.7 days).
    pub const fn wrapping_millis_u32(self) -> u32 {
        // Truncation is the documented wrap.
        (self.as_millis() & 0xFFFF_FFFF) as u32
    }

    /// Time from `earlier` to `self`, or `None` if `earlier` is later.
    pub const fn checked_duration_since(self, earlier: Instant) -> Option<Duration> {
        match self.micros.checked_sub(earlier.micros) {
            Some(micros) => Some(Duration { micros }),
            None => None,
        }
    }

    /// Time from `earlier` to `self`, zero if `earlier` is later.
    pub const fn saturating_duration_since(self, earlier: Instant) -> Duration {
        Duration {
            micros: self.micros.saturating_sub(earlier.micros),
        }
    }

    /// `self + d`, saturating at the end of time.
    pub const fn saturating_add(self, d: Duration) -> Instant {
        Instant {
            micros: self.micros.saturating_add(d.micros),
        }
    }

    /// `self + d`, or `None` on overflow.
    pub const fn checked_add(self, d: Duration) -> Option<Instant> {
        match self.micros.checked_add(d.micros) {
            Some(micros) => Some(Instant { micros }),
            None => None,
        }
    }
}

impl Duration {
    /// No time.
    pub const ZERO: Duration = Duration { micros: 0 };

    /// `micros` microseconds.
    pub const fn from_micros(micros: u64) -> Self {
        Duration { micros }
    }

    /// `millis` milliseconds (saturating).
    pub const fn from_millis(millis: u64) -> Self {
        Duration {
            micros: millis.saturating_mul(1000),
        }
    }

    /// `secs` seconds (saturating).
    pub const fn from_secs(secs: u64) -> Self {
        Duration {
            micros: secs.saturating_mul(1_000_000),
        }
    }

    /// Microseconds.
    pub const fn as_micros(self) -> u64 {
        self.micros
    }

    /// Whole milliseconds.
    pub const fn as_millis(self) -> u64 {
        self.micros / 1000
    }

    /// Seconds as `f32`, for the physics of one step. Whole seconds and the
    /// microsecond remainder are converted separately, so durations below a
    /// second (every control period) are correctly rounded (`1000 µs` is
    /// exactly the f32 nearest to 0.001).
    pub fn as_secs_f32(self) -> f32 {
        let whole = self.micros / 1_000_000;
        let frac = self.micros % 1_000_000;
        // u64 → f32 is an `as` conversion: exact below 2²⁴ and correctly
        // rounded above, never a panic.
        whole as f32 + frac as f32 / 1_000_000.0
    }

    /// `self × n`, saturating.
    pub const fn saturating_mul(self, n: u64) -> Duration {
        Duration {
            micros: self.micros.saturating_mul(n),
        }
    }

    /// `self + other`, saturating.
    pub const fn saturating_add(self, other: Duration) -> Duration {
        Duration {
            micros: self.micros.saturating_add(other.micros),
        }
    }

    /// True for a zero duration.
    pub const fn is_zero(self) -> bool {
        self.micros == 0
    }
}

/// Saturating (see the module docs).
impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        self.saturating_add(d)
    }
}

/// Saturating (see the module docs).
impl AddAssign<Duration> for Instant {
    fn add_assign(&mut self, d: Duration) {
        *self = self.saturating_add(d);
    }
}

/// Saturating: an earlier `self` gives zero (use
/// [`Instant::checked_duration_since`] to tell the two apart).
impl Sub<Instant> for Instant {
    type Output = Duration;
    fn sub(self, earlier: Instant) -> Duration {
        self.saturating_duration_since(earlier)
    }
}

/// Saturating.
impl Add for Duration {
    type Output = Duration;
    fn add(self, other: Duration) -> Duration {
        self.saturating_add(other)
    }
}

impl core::fmt::Display for Duration {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "{}.{:06} s",
            self.micros / 1_000_000,
            self.micros % 1_000_000
        )
    }
}

impl core::fmt::Display for Instant {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "t = {}.{:06} s",
            self.micros / 1_000_000,
            self.micros % 1_000_000
        )
    }
}

/// Extends a free-running, wrapping `u32` millisecond counter (a SysTick
/// count, say) to a monotonic [`Instant`].
///
/// Each reading adds the wrapping difference from the previous one, so the
/// counter may wrap any number of times as long as consecutive readings are
/// less than 2³² ms (49.7 days) apart — any control loop reads far more
/// often. The first reading sets the instant to the counter's own value, so
/// a counter that starts at 0 at boot gives time since boot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MillisCounter {
    last_raw: Option<u32>,
    millis: u64,
}

impl MillisCounter {
    /// Nothing read yet.
    pub const fn new() -> Self {
        MillisCounter {
            last_raw: None,
            millis: 0,
        }
    }

    /// The instant of the counter reading `raw_ms`.
    pub fn extend(&mut self, raw_ms: u32) -> Instant {
        self.millis = match self.last_raw {
            None => u64::from(raw_ms),
            Some(last) => self
                .millis
                .saturating_add(u64::from(raw_ms.wrapping_sub(last))),
        };
        self.last_raw = Some(raw_ms);
        Instant::from_millis(self.millis)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn control_periods_keep_their_resolution_at_any_uptime() {
        let one_year = Instant::from_secs(365 * 24 * 3600);
        let next = one_year + Duration::from_micros(1000);
        assert_eq!(next - one_year, Duration::from_millis(1));
        assert_eq!((next - one_year).as_secs_f32(), 0.001);
        // The f32 clock this replaces could not tell the two apart.
        let as_f32 = |t: Instant| t.as_micros() as f32 * 1e-6;
        assert_eq!(as_f32(one_year), as_f32(next));
    }

    #[test]
    fn arithmetic_saturates_instead_of_panicking() {
        let end = Instant::from_micros(u64::MAX);
        assert_eq!(end + Duration::from_secs(1), end);
        assert_eq!(Instant::ZERO - end, Duration::ZERO);
        assert_eq!(Instant::ZERO.checked_duration_since(end), None);
        assert_eq!(Duration::from_secs(u64::MAX).as_micros(), u64::MAX);
        assert_eq!(
            Duration::from_millis(5)
                .saturating_mul(u64::MAX)
                .as_micros(),
            u64::MAX
        );
    }

    #[test]
    fn durations_convert_to_seconds_accurately() {
        assert_eq!(Duration::from_micros(1000).as_secs_f32(), 0.001);
        assert_eq!(Duration::from_micros(100).as_secs_f32(), 0.0001);
        assert_eq!(Duration::from_millis(2500).as_secs_f32(), 2.5);
        let long = Duration::from_secs(100_000) + Duration::from_micros(250_000);
        assert!((long.as_secs_f32() - 100_000.25).abs() <= 0.01);
    }

    #[test]
    fn a_wrapping_millisecond_counter_extends_monotonically() {
        let mut c = MillisCounter::new();
        let start = u32::MAX - 999; // 1 s before the wrap
        let mut last = c.extend(start);
        assert_eq!(last.as_millis(), u64::from(start));
        let mut raw = start;
        for _ in 0..3000 {
            raw = raw.wrapping_add(1);
            let now = c.extend(raw);
            assert_eq!(now - last, Duration::from_millis(1), "at raw {raw}");
            last = now;
        }
        assert_eq!(last.as_millis(), u64::from(start) + 3000);
        assert_eq!(last.wrapping_millis_u32(), raw);
        // Several wraps between readings far apart is not supported, but one
        // reading per day for a year is.
        let mut c = MillisCounter::new();
        let mut raw = 0u32;
        c.extend(raw);
        for _ in 0..365 {
            raw = raw.wrapping_add(86_400_000);
            c.extend(raw);
        }
        assert_eq!(c.extend(raw).as_millis(), 365 * 86_400_000);
    }
}
