//! The loop-stall policy behind a board's hardware watchdog.
//!
//! A board's control loop (bytes in, [`App::poll`](crate::app::App::poll),
//! outputs out) must not stop while a coil is powered: the supervisor that
//! would switch a coil off runs in that loop. [`StallWatchdog`] is the
//! decision, kept apart from any hardware so that it is tested on the host.
//! The loop counts a heartbeat once per pass; a periodic tick (a board's
//! 1 ms clock interrupt) looks at it, and
//! - while the heartbeat moves, the tick feeds the hardware watchdog;
//! - once it has not moved for `limit` ticks, the loop has stalled: from
//!   then on the tick zeroes the outputs itself (the interrupt still runs)
//!   and never feeds again, so the hardware watchdog resets the chip, which
//!   comes up with its outputs off and disarmed.
//!
//! If the tick itself stops (interrupts masked, a fault), nothing feeds and
//! the hardware watchdog resets the chip on its own timeout. The stall is
//! latched on purpose: a loop that hung once and resumes may hold stale
//! state (a half-read frame, an integrator over a long step), and the clean
//! state is a reset.
//!
//! Left out: what the hardware watchdog's own timeout is (a board constant)
//! and how outputs are zeroed (board code); a loop that runs but never
//! steps the joint is the app's business (its free-running step and link
//! checks), not this policy's.

/// What the tick must do with the hardware watchdog.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum WatchdogAction {
    /// The loop is alive: reload the hardware watchdog.
    Feed,
    /// The loop has stalled: zero the outputs and do not feed (the hardware
    /// watchdog will reset the chip).
    Starve,
}

/// Decides, once per tick, whether the control loop is still alive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StallWatchdog {
    limit_ticks: u32,
    last_beat: Option<u32>,
    silent_ticks: u32,
    stalled: bool,
}

impl StallWatchdog {
    /// A policy that declares a stall after `limit_ticks` ticks without a
    /// heartbeat (at least 1).
    pub const fn new(limit_ticks: u32) -> Self {
        Self {
            limit_ticks: if limit_ticks == 0 { 1 } else { limit_ticks },
            last_beat: None,
            silent_ticks: 0,
            stalled: false,
        }
    }

    /// Ticks without a heartbeat that make a stall.
    pub const fn limit_ticks(&self) -> u32 {
        self.limit_ticks
    }

    /// True once a stall has been seen (for ever after).
    pub const fn is_stalled(&self) -> bool {
        self.stalled
    }

    /// One tick, given the loop's heartbeat counter (any wrapping `u32`
    /// that the loop changes once per pass). The first tick only records
    /// the heartbeat.
    pub fn tick(&mut self, heartbeat: u32) -> WatchdogAction {
        if self.stalled {
            return WatchdogAction::Starve;
        }
        if self.last_beat == Some(heartbeat) {
            self.silent_ticks = self.silent_ticks.saturating_add(1);
            if self.silent_ticks >= self.limit_ticks {
                self.stalled = true;
                return WatchdogAction::Starve;
            }
        } else {
            self.last_beat = Some(heartbeat);
            self.silent_ticks = 0;
        }
        WatchdogAction::Feed
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_live_loop_is_fed_for_ever() {
        let mut w = StallWatchdog::new(25);
        let mut beat = u32::MAX - 100; // the heartbeat wraps on the way
        for _ in 0..10_000 {
            beat = beat.wrapping_add(3); // several passes per tick
            assert_eq!(w.tick(beat), WatchdogAction::Feed);
        }
        assert!(!w.is_stalled());
    }

    #[test]
    fn a_slow_but_live_loop_is_fed() {
        // One pass every 24 ticks (a long reply on a slow UART) stays
        // under a 25-tick limit.
        let mut w = StallWatchdog::new(25);
        let mut beat = 0u32;
        for t in 0..2400u32 {
            if t % 24 == 0 {
                beat = beat.wrapping_add(1);
            }
            assert_eq!(w.tick(beat), WatchdogAction::Feed, "tick {t}");
        }
    }

    #[test]
    fn a_stall_starves_after_exactly_the_limit_and_latches() {
        let mut w = StallWatchdog::new(25);
        assert_eq!(w.tick(7), WatchdogAction::Feed);
        // 24 silent ticks are still fed; the 25th is the stall.
        for k in 1..25 {
            assert_eq!(w.tick(7), WatchdogAction::Feed, "silent tick {k}");
        }
        assert_eq!(w.tick(7), WatchdogAction::Starve);
        assert!(w.is_stalled());
        // The loop coming back does not undo it: only a reset does.
        for beat in 8..100 {
            assert_eq!(w.tick(beat), WatchdogAction::Starve);
        }
    }

    #[test]
    fn a_loop_that_never_beats_after_the_first_tick_stalls() {
        let mut w = StallWatchdog::new(3);
        assert_eq!(w.tick(0), WatchdogAction::Feed);
        assert_eq!(w.tick(0), WatchdogAction::Feed);
        assert_eq!(w.tick(0), WatchdogAction::Feed);
        assert_eq!(w.tick(0), WatchdogAction::Starve);
    }

    #[test]
    fn a_zero_limit_means_one_tick() {
        let mut w = StallWatchdog::new(0);
        assert_eq!(w.limit_ticks(), 1);
        assert_eq!(w.tick(1), WatchdogAction::Feed);
        assert_eq!(w.tick(1), WatchdogAction::Starve);
    }
}
