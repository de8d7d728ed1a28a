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
use crate::time::{Duration, Instant};

/// Why a pulse coder could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WireSensorError {
    /// No new reading is available this instant.
    NotReady,
    /// The device reported a fault (open line, counter error).
    Fault,
}

impl core::fmt::Display for WireSensorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            WireSensorError::NotReady => "no new reading is available",
            WireSensorError::Fault => "the pulse coder reported a fault",
        })
    }
}

impl core::error::Error for WireSensorError {}

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
    /// The shortest span the rate is judged over: a reading is compared
    /// with an accepted one at least this old (or the first of the
    /// channel), allowing `max_rate_per_s × max(elapsed, rate_window)`.
    /// A reading moves by a count or a wire's stick-slip at once, at any
    /// loop period; judged reading by reading, a loop faster than the
    /// limits were set for would see those steps as implausible rates. At
    /// loop periods of `rate_window` or longer every reading is judged
    /// against the previous accepted one, as if there were no window.
    pub rate_window: Duration,
    /// A channel whose last accepted reading is older than this is stale.
    pub stale_after: Duration,
}

impl SensorLimits {
    /// Wire insertions: ±10 mm (estimate: about 2.5× the ±3.9 mm that
    /// Eq. 2 needs for ±20°), 200 mm/s (estimate: the joint covers its range
    /// in ~0.2 s at the fastest, i.e. ~40 mm/s, with a 5× margin) judged
    /// over at least 1 ms (the paper's 1 kHz loop, which the limits were
    /// set for: 0.2 mm, room for a count of 0.01 mm and a stick-slip jump
    /// of the wire in its tube, up to 0.08 mm in the simulated joint's
    /// estimate, that a 100 µs loop would otherwise take for 800 mm/s),
    /// stale after 50 ms (50 periods of a 1 kHz loop).
    pub const WIRE_DEFAULT: SensorLimits = SensorLimits {
        min: -10.0,
        max: 10.0,
        max_rate_per_s: 200.0,
        rate_window: Duration::from_millis(1),
        stale_after: Duration::from_millis(50),
    };

    /// Camera angles: ±45° (the joint moves ±20°, paper §VI-A), 1000°/s
    /// judged over at least 1 ms (frames are 33 ms apart: the window never
    /// matters), stale after 0.2 s (six frames of a 30 frames/s NTSC
    /// camera).
    pub const CAMERA_DEFAULT: SensorLimits = SensorLimits {
        min: -45.0,
        max: 45.0,
        max_rate_per_s: 1000.0,
        rate_window: Duration::from_millis(1),
        stale_after: Duration::from_millis(200),
    };

    /// True when every limit is finite and ordered and the stale limit is
    /// not zero.
    pub fn is_valid(&self) -> bool {
        self.min.is_finite()
            && self.max.is_finite()
            && self.min < self.max
            && self.max_rate_per_s.is_finite()
            && self.max_rate_per_s > 0.0
            && !self.stale_after.is_zero()
    }
}

/// What [`SensorGuard::check`] found at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Checked<const S: usize> {
    /// The held value of every channel: the last accepted reading, or 0 for
    /// a channel that has not delivered one yet (see `delivered`).
    pub values: [f32; S],
    /// Any of [`Faults::SENSOR_RANGE`], [`Faults::SENSOR_RATE`],
    /// [`Faults::SENSOR_STALE`].
    pub faults: Faults,
    /// Bit `k` is set when channel `k` has delivered at least one accepted
    /// reading since the guard was created or reset. A value whose bit is
    /// clear is a placeholder, not a measurement: nothing may be driven
    /// from it.
    pub delivered: u32,
}

impl<const S: usize> Checked<S> {
    /// True when every channel in `mask` has delivered a reading.
    pub fn has_delivered(&self, mask: u32) -> bool {
        self.delivered & mask == mask
    }
}

/// Holds the last good value of `S` channels (at most 32) and checks new
/// readings.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorGuard<const S: usize> {
    limits: SensorLimits,
    value: [f32; S],
    last_ok: [Option<Instant>; S],
    /// The accepted reading new ones are judged against (and when it was
    /// taken): the last accepted one at least `rate_window` older than its
    /// successor (see [`SensorLimits::rate_window`]).
    anchor_value: [f32; S],
    anchor_at: [Option<Instant>; S],
    /// Time of the first check: a channel that has never delivered is
    /// stale only once the stale limit has passed since then (a camera's
    /// first frame arrives one frame period after start).
    started: Option<Instant>,
}

impl<const S: usize> SensorGuard<S> {
    /// A guard with nothing read yet.
    pub fn new(limits: SensorLimits) -> Self {
        Self {
            limits,
            value: [0.0; S],
            last_ok: [None; S],
            anchor_value: [0.0; S],
            anchor_at: [None; S],
            started: None,
        }
    }

    /// The limits in use.
    pub fn limits(&self) -> SensorLimits {
        self.limits
    }

    /// Forgets all readings.
    pub fn reset(&mut self) {
        self.value = [0.0; S];
        self.last_ok = [None; S];
        self.anchor_value = [0.0; S];
        self.anchor_at = [None; S];
        self.started = None;
    }

    /// Checks the readings taken at `now` (`None`: no new reading on that
    /// channel). A reading that fails a check is not accepted as the held
    /// value. The rate is judged against the channel's anchor (see
    /// [`SensorLimits::rate_window`]). `now` must not be earlier than the
    /// previous call's (the joint checks that); an earlier one counts ages
    /// as 0.
    pub fn check(&mut self, now: Instant, readings: &[Option<f32>; S]) -> Checked<S> {
        let mut faults = Faults::NONE;
        let lim = self.limits;
        let started = *self.started.get_or_insert(now);
        let mut delivered = 0u32;
        for (k, ((((value, last), anchor_value), anchor_at), reading)) in self
            .value
            .iter_mut()
            .zip(self.last_ok.iter_mut())
            .zip(self.anchor_value.iter_mut())
            .zip(self.anchor_at.iter_mut())
            .zip(readings.iter())
            .enumerate()
        {
            if let Some(r) = *reading {
                if !r.is_finite() || r < lim.min || r > lim.max {
                    faults |= Faults::SENSOR_RANGE;
                } else {
                    // Time since the anchor (0 for a time base that ran
                    // back), judged over at least the window.
                    let since_anchor = anchor_at.map(|t| now.saturating_duration_since(t));
                    let plausible = match since_anchor {
                        // A first reading: no rate to judge.
                        None => true,
                        Some(elapsed) => {
                            let span_us = elapsed.as_micros().max(lim.rate_window.as_micros());
                            within_rate(r, *anchor_value, lim.max_rate_per_s * span_s(span_us))
                        }
                    };
                    if plausible {
                        *value = r;
                        *last = Some(now);
                        if since_anchor.is_none_or(|e| e >= lim.rate_window) {
                            *anchor_value = r;
                            *anchor_at = Some(now);
                        }
                    } else {
                        faults |= Faults::SENSOR_RATE;
                    }
                }
            }
            let since = match *last {
                Some(t) => {
                    delivered |= 1u32.checked_shl(k as u32).unwrap_or(0);
                    t
                }
                None => started,
            };
            if now - since > lim.stale_after {
                faults |= Faults::SENSOR_STALE;
            }
        }
        Checked {
            values: self.value,
            faults,
            delivered,
        }
    }
}

/// True when `reading` is within `max_change` of `held`, the limit
/// included. The comparison allows for the rounding of both values to
/// `f32` (four units in the last place of the larger magnitude, and of the
/// limit): a change of exactly the limit — 20 counts of 0.01 mm in 1 ms at
/// 200 mm/s — is accepted whatever the counts, where a bare `<=` accepted
/// it at some counts and refused it at others. The allowance is below
/// 10⁻⁵ mm at the ±10 mm range, far below one count, so a change one count
/// above the limit is still refused.
pub fn within_rate(reading: f32, held: f32, max_change: f32) -> bool {
    let change = (reading - held).abs();
    let rounding = 4.0 * f32::EPSILON * (reading.abs().max(held.abs()) + max_change.abs());
    change <= max_change + rounding
}

/// A span of the rate check in seconds: `µs / 10⁶` rounded once, as
/// [`Duration::as_secs_f32`] rounds spans below a second, without its
/// 64-bit division (a library call on a Cortex-M4, hundreds of
/// instructions per channel and step). Spans beyond 2²⁴ µs (16.8 s) count
/// as 16.8 s: by then any reading in range is plausible (a rate limit
/// times 16.8 s exceeds every sensor's range).
#[inline]
fn span_s(span_us: u64) -> f32 {
    const MAX_US: u32 = 1 << 24;
    let us = u32::try_from(span_us).map_or(MAX_US, |u| u.min(MAX_US));
    // Exact: a u32 below 2²⁴ is an f32 integer.
    us as f32 / 1_000_000.0
}

/// Extends a 16-bit hardware quadrature counter to an `i32` count.
///
/// A timer in encoder mode counts up and down modulo 2¹⁶ (a 32-bit timer
/// read through its low 16 bits is the same counter). Each reading adds the
/// wrapping difference from the previous reading, taken as a signed 16-bit
/// number, so the count follows the wire through any number of wraps in
/// either direction as long as it moves by less than 32,768 counts between
/// two readings (at a 1 kHz read rate: 32.8 million counts per second; a
/// faster coder, or a slower loop, would alias). The count is 0 at the raw
/// value given to [`QuadratureCount::new`] (the counter's value at reset),
/// and it saturates at the ends of `i32` instead of wrapping.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct QuadratureCount {
    last_raw: u16,
    count: i32,
}

impl QuadratureCount {
    /// A count of 0 at the counter value `raw_at_zero`.
    pub const fn new(raw_at_zero: u16) -> Self {
        Self {
            last_raw: raw_at_zero,
            count: 0,
        }
    }

    /// Takes the counter's reading `raw` and returns the extended count.
    pub fn update(&mut self, raw: u16) -> i32 {
        // The two's-complement reading of the wrapping difference: −32768
        // ..= 32767 counts since the last reading.
        let step = raw.wrapping_sub(self.last_raw) as i16;
        self.last_raw = raw;
        self.count = self.count.saturating_add(i32::from(step));
        self.count
    }

    /// The extended count at the last reading.
    pub fn count(&self) -> i32 {
        self.count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(t: u64) -> Instant {
        Instant::from_millis(t)
    }

    /// The guard's behaviour from `t0` on: the same checks give the same
    /// answers at any uptime.
    fn range_rate_and_staleness_from(t0: Instant) {
        let at = |t: u64| t0 + Duration::from_millis(t);
        let mut g = SensorGuard::<2>::new(SensorLimits::WIRE_DEFAULT);
        let c = g.check(at(0), &[Some(1.0), None]);
        assert_eq!(
            c.faults,
            Faults::NONE,
            "a channel gets the stale limit to deliver its first reading"
        );
        assert_eq!(c.delivered, 0b01, "channel 1 has not delivered");
        assert!(!c.has_delivered(0b11));
        let c = g.check(at(51), &[Some(1.0), None]);
        assert_eq!(
            c.faults,
            Faults::SENSOR_STALE,
            "channel 1 never read within 50 ms"
        );
        let mut g = SensorGuard::<2>::new(SensorLimits::WIRE_DEFAULT);
        g.check(at(0), &[Some(1.0), Some(0.0)]);
        let c = g.check(at(1), &[Some(1.1), Some(0.0)]);
        assert_eq!(c.faults, Faults::NONE);
        assert_eq!(c.values, [1.1, 0.0]);
        assert!(c.has_delivered(0b11));
        // 5 mm in 1 ms = 5000 mm/s: implausible, value held.
        let c = g.check(at(2), &[Some(6.1), Some(0.0)]);
        assert_eq!(c.faults, Faults::SENSOR_RATE);
        assert_eq!(c.values[0], 1.1);
        // Out of range and NaN.
        assert_eq!(
            g.check(at(3), &[Some(11.0), Some(0.0)]).faults,
            Faults::SENSOR_RANGE
        );
        assert_eq!(
            g.check(at(4), &[Some(f32::NAN), Some(0.0)]).faults,
            Faults::SENSOR_RANGE
        );
        // Channel 0 has not been accepted since t = 1 ms: stale after 50 ms.
        assert_eq!(g.check(at(51), &[None, Some(0.0)]).faults, Faults::NONE);
        assert_eq!(
            g.check(at(52), &[None, Some(0.0)]).faults,
            Faults::SENSOR_STALE
        );
        // Rate limits keep 1 ms resolution: 0.19 mm per ms is plausible,
        // 0.21 mm is not, after any uptime.
        let mut g = SensorGuard::<1>::new(SensorLimits::WIRE_DEFAULT);
        g.check(at(100), &[Some(0.0)]);
        assert_eq!(g.check(at(101), &[Some(0.19)]).faults, Faults::NONE);
        assert_eq!(g.check(at(102), &[Some(0.41)]).faults, Faults::SENSOR_RATE);
    }

    #[test]
    fn range_rate_and_staleness_are_flagged_at_any_uptime() {
        for t0 in [
            Instant::ZERO,
            // One second before a u32 millisecond counter wraps.
            Instant::from_millis(u64::from(u32::MAX) - 1000),
            Instant::from_secs(5 * 3600),
            Instant::from_secs(30 * 86_400),
            Instant::from_secs(365 * 86_400),
        ] {
            range_rate_and_staleness_from(t0);
        }
    }

    /// A healthy wire read by a loop ten times faster than the limits
    /// were set for (100 µs): a stick-slip jump of 0.08 mm and count steps
    /// within one period raise no fault (reading by reading they are
    /// 800 mm/s), while a wire that really moves at 300 mm/s is refused
    /// within the 1 ms window, as at 1 kHz.
    #[test]
    fn a_fast_loop_judges_the_rate_over_the_window_not_one_period() {
        let us = |t: u64| Instant::from_micros(t);
        let mut g = SensorGuard::<1>::new(SensorLimits::WIRE_DEFAULT);
        // Creeping in at 20 mm/s (0.002 mm per period, read in 0.01 mm
        // counts), a slip of 0.08 mm at 3 ms, creeping on: no fault.
        for k in 0..100u64 {
            let creep = 0.002 * k as f32;
            let slip = if k >= 30 { 0.08 } else { 0.0 };
            let counts = ((creep + slip) / 0.01).round();
            let c = g.check(us(100 * k), &[Some(counts * 0.01)]);
            assert_eq!(c.faults, Faults::NONE, "period {k}");
        }
        // 300 mm/s = 0.03 mm per 100 µs: refused once 1 ms of it exceeds
        // 0.2 mm (the 7th period), and the reading is held.
        let mut g = SensorGuard::<1>::new(SensorLimits::WIRE_DEFAULT);
        let mut first_fault = None;
        for k in 0..20u64 {
            let c = g.check(us(100 * k), &[Some(0.03 * k as f32)]);
            if c.faults == Faults::SENSOR_RATE && first_fault.is_none() {
                first_fault = Some(k);
                assert!(c.values[0] < 0.03 * k as f32, "held, not taken");
            }
        }
        assert_eq!(first_fault, Some(7));
    }

    /// At loop periods of the window or longer the window changes nothing:
    /// every reading is judged against the previous accepted one. The
    /// reference is that rule written out (held value, time, |Δ| ≤
    /// 200 mm/s × elapsed, the end point included), on a random walk with jumps and jittered
    /// periods of 1–3 ms.
    #[test]
    fn at_periods_of_the_window_or_longer_each_reading_is_judged_alone() {
        let mut g = SensorGuard::<1>::new(SensorLimits::WIRE_DEFAULT);
        let (mut held, mut held_at) = (None::<f32>, 0u64);
        // A deterministic walk (LCG): steps of up to ±0.6 mm.
        let mut x = 12_345u32;
        let mut next = || {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            x >> 8
        };
        let (mut t_us, mut d) = (0u64, 0.0f32);
        let mut faults = 0;
        for _ in 0..2000 {
            t_us += 1000 * u64::from(1 + next() % 3);
            d = (d + (next() % 1201) as f32 * 1e-3 - 0.6).clamp(-9.0, 9.0);
            // The limit includes its end point, with §8.1's allowance for
            // the f32 rounding of both readings and of the limit.
            let plausible = held.is_none_or(|v| {
                let limit = 200.0 * ((t_us - held_at) as f32 * 1e-6);
                (d - v).abs() <= limit + 4.0 * f32::EPSILON * (d.abs().max(v.abs()) + limit)
            });
            if plausible {
                (held, held_at) = (Some(d), t_us);
            }
            let c = g.check(Instant::from_micros(t_us), &[Some(d)]);
            let expected = if plausible {
                Faults::NONE
            } else {
                Faults::SENSOR_RATE
            };
            assert_eq!(c.faults, expected, "at {t_us} µs");
            assert_eq!(Some(c.values[0]), held, "at {t_us} µs");
            faults += usize::from(!plausible);
        }
        assert!(
            faults > 100,
            "the walk must exercise the rate check: {faults}"
        );
    }

    #[test]
    fn a_16_bit_counter_extends_across_wraps_in_both_directions() {
        // Start 3 counts below the wrap and move up 10: 65533 → 7.
        let mut q = QuadratureCount::new(65_533);
        let mut raw = 65_533u16;
        for k in 1..=10 {
            raw = raw.wrapping_add(1);
            assert_eq!(q.update(raw), k, "up through the wrap at raw {raw}");
        }
        // Back down 20: through 0 → 65535 again, to −10.
        for k in 1..=20 {
            raw = raw.wrapping_sub(1);
            assert_eq!(q.update(raw), 10 - k, "down through the wrap at raw {raw}");
        }
        assert_eq!(q.count(), -10);
        // Steps of 30,000 counts (below half the range) wrap many times and
        // lose nothing: 10 steps up is 300,000 counts, 4.6 wraps.
        let mut q = QuadratureCount::new(0);
        let mut raw = 0u16;
        for _ in 0..10 {
            raw = raw.wrapping_add(30_000);
            q.update(raw);
        }
        assert_eq!(q.count(), 300_000);
        for _ in 0..20 {
            raw = raw.wrapping_sub(30_000);
            q.update(raw);
        }
        assert_eq!(q.count(), -300_000);
    }

    #[test]
    fn the_largest_unambiguous_step_is_half_the_counter_range() {
        let mut q = QuadratureCount::new(0);
        assert_eq!(q.update(32_767), 32_767);
        let mut q = QuadratureCount::new(0);
        // 32,768 counts up cannot be told from 32,768 down: it reads as down.
        assert_eq!(q.update(32_768), -32_768);
    }

    #[test]
    fn the_extended_count_saturates_instead_of_wrapping() {
        let mut q = QuadratureCount::new(0);
        let mut raw = 0u16;
        // 2³¹ / 30,000 ≈ 71,583 steps reach i32::MAX; go well past it.
        for _ in 0..80_000 {
            raw = raw.wrapping_add(30_000);
            q.update(raw);
        }
        assert_eq!(q.count(), i32::MAX);
        // And it comes back down from the end, count for count.
        raw = raw.wrapping_sub(5);
        assert_eq!(q.update(raw), i32::MAX - 5);
    }

    #[test]
    fn reset_forgets_what_was_delivered() {
        let mut g = SensorGuard::<1>::new(SensorLimits::WIRE_DEFAULT);
        assert_eq!(g.check(ms(0), &[Some(2.0)]).delivered, 1);
        g.reset();
        let c = g.check(ms(1), &[None]);
        assert_eq!((c.delivered, c.values), (0, [0.0]));
    }
}
