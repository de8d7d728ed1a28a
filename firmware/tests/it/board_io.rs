//! What a board image does around the app that QEMU cannot show: the
//! mapping of pair commands to PWM duty cycles, the extension of 16-bit
//! quadrature counters to `i32` across wraps, and the loop-stall watchdog
//! policy. Each is checked against an independent model over random inputs.
//!
//! The STM32F4 board (firmware/stm32f4) drives four PWM channels of one
//! timer at a full scale of 8,400 (10 kHz from its 84 MHz timer clock);
//! the tests use that full scale and any other.
use firmware::control::{volts_to_duty, DriverConfig, PairCommand, PairDriver};
use firmware::protocol::pair_to_mv;
use firmware::sensor::QuadratureCount;
use firmware::watchdog::{StallWatchdog, WatchdogAction};
use proptest::prelude::*;

/// The STM32F4 board's PWM full scale: TIM3 at 10 kHz from 84 MHz.
const STM32_MAX_DUTY: u16 = 8_400;

/// A PWM channel that keeps its last duty.
struct Channel {
    max: u16,
    duty: u16,
}

impl embedded_hal::pwm::ErrorType for Channel {
    type Error = core::convert::Infallible;
}

impl embedded_hal::pwm::SetDutyCycle for Channel {
    fn max_duty_cycle(&self) -> u16 {
        self.max
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
        assert!(
            duty <= self.max,
            "duty {duty} above the channel's {}",
            self.max
        );
        self.duty = duty;
        Ok(())
    }
}

/// The four duties the board sets for two pair commands: α agonist,
/// α antagonist, β agonist, β antagonist (channels 1–4 of the timer).
fn board_duties(cmds: [PairCommand; 2], driver: &DriverConfig, max: u16) -> [u16; 4] {
    let ch = || Channel { max, duty: 0 };
    let mut pairs = [PairDriver::new(ch(), ch()), PairDriver::new(ch(), ch())];
    for (pair, cmd) in pairs.iter_mut().zip(cmds) {
        pair.apply(cmd, driver).unwrap();
    }
    let [a, b] = pairs.map(|p| p.release());
    [a.0.duty, a.1.duty, b.0.duty, b.1.duty]
}

fn command(side: u8, volts: f32, driver: &DriverConfig) -> PairCommand {
    match side {
        0 => PairCommand::Off,
        1 => PairCommand::Agonist(driver.clamp(volts)),
        _ => PairCommand::Antagonist(driver.clamp(volts)),
    }
}

#[test]
fn duty_cycle_mapping_at_the_stm32_full_scale() {
    let d = DriverConfig::default(); // 5 V supply, 1.7 V offset (paper)
    let duties = |cmds| board_duties(cmds, &d, STM32_MAX_DUTY);
    assert_eq!(duties([PairCommand::Off; 2]), [0; 4]);
    // Full supply on α's agonist, 2.5 V on β's antagonist.
    assert_eq!(
        duties([
            PairCommand::Agonist(d.clamp(5.0)),
            PairCommand::Antagonist(d.clamp(2.5))
        ]),
        [8_400, 0, 0, 4_200]
    );
    // The paper's 1.7 V offset: 1.7 / 5 × 8400 = 2856 exactly.
    assert_eq!(
        duties([PairCommand::Antagonist(d.clamp(1.7)), PairCommand::Off]),
        [0, 2_856, 0, 0]
    );
    // Above the supply saturates at full duty, never beyond.
    assert_eq!(
        duties([PairCommand::Off, PairCommand::Agonist(d.clamp(12.0))]),
        [0, 0, 8_400, 0]
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    /// Any command at any full scale: bounded, the idle coil at 0, and the
    /// duty within half a step of the commanded voltage.
    #[test]
    fn duty_is_bounded_and_within_half_a_step(
        max in 1u16..=u16::MAX,
        volts in -2.0f32..8.0,
        side in 0u8..3,
        supply in 3.0f32..24.0,
    ) {
        let d = DriverConfig::new(0.0, supply).unwrap();
        let cmd = command(side, volts, &d);
        let duties = board_duties([cmd, PairCommand::Off], &d, max);
        prop_assert!(duties.iter().all(|&u| u <= max));
        prop_assert_eq!(&duties[2..], &[0, 0]);
        prop_assert!(duties[0] == 0 || duties[1] == 0, "both coils on: {:?}", duties);
        let [v_ag, v_ant] = cmd.coil_volts();
        for (duty, v) in [(duties[0], v_ag), (duties[1], v_ant)] {
            let applied = f64::from(duty) / f64::from(max) * f64::from(supply);
            let step = f64::from(supply) / f64::from(max);
            prop_assert!(
                (applied - f64::from(v)).abs() <= 0.5 * step + 1e-5 * f64::from(supply),
                "{v} V → duty {duty}/{max} = {applied} V"
            );
        }
    }

    /// Duty is monotone in the commanded voltage.
    #[test]
    fn duty_is_monotone(max in 1u16..=u16::MAX, a in -1.0f32..6.0, b in -1.0f32..6.0) {
        let d = DriverConfig::default();
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        prop_assert!(volts_to_duty(d.clamp(lo), &d, max) <= volts_to_duty(d.clamp(hi), &d, max));
    }

    /// The millivolts a board reports over the protocol (what the QEMU
    /// lockstep test checks against the simulation) and the duty the STM32
    /// board sets for the same command describe the same voltage, within
    /// one rounding step of each, and on the same coil.
    #[test]
    fn reported_millivolts_and_stm32_duty_agree(volts in 0.0f32..6.0, side in 0u8..3) {
        let d = DriverConfig::default();
        let cmd = command(side, volts, &d);
        let mv = pair_to_mv(cmd, &d);
        let duties = board_duties([cmd, PairCommand::Off], &d, STM32_MAX_DUTY);
        let duty_mv = f64::from(duties[0].max(duties[1])) / f64::from(STM32_MAX_DUTY)
            * f64::from(d.supply_v()) * 1000.0;
        let step_mv = f64::from(d.supply_v()) * 1000.0 / f64::from(STM32_MAX_DUTY);
        prop_assert!(
            (duty_mv - f64::from(mv.unsigned_abs())).abs() <= 0.5 * step_mv + 0.5 + 1e-3,
            "{cmd:?}: {mv} mV reported, duty {duties:?} = {duty_mv} mV"
        );
        if mv > 0 {
            prop_assert_eq!(duties[1], 0);
        }
        if mv < 0 {
            prop_assert_eq!(duties[0], 0);
        }
    }

    /// A wire moving by less than half the counter range per reading, for
    /// any number of readings: the extended count equals the true position
    /// (a 64-bit model), whether the timer is 16-bit or 32-bit read through
    /// its low half.
    #[test]
    fn quadrature_extension_follows_the_true_count(
        start in any::<u32>(),
        steps in prop::collection::vec(-32_767i64..=32_767, 1..400),
    ) {
        let mut q16 = QuadratureCount::new(start as u16);
        let mut q32 = QuadratureCount::new(start as u16);
        let mut true_count = 0i64;
        let mut raw32 = start;
        for (k, s) in steps.iter().enumerate() {
            true_count += s;
            raw32 = raw32.wrapping_add(*s as u32); // two's complement step
            let raw16 = (i64::from(start as u16) + true_count).rem_euclid(1 << 16) as u16;
            prop_assert_eq!(i64::from(q16.update(raw16)), true_count, "16-bit, reading {}", k);
            prop_assert_eq!(i64::from(q32.update(raw32 as u16)), true_count, "32-bit, reading {}", k);
        }
    }

    /// The policy starves exactly from the first tick that ends a run of
    /// `limit` silent ticks, and for ever after (a model of the rule).
    #[test]
    fn stall_watchdog_matches_its_rule(
        limit in 1u32..40,
        beats in prop::collection::vec(prop::bool::weighted(0.7), 1..600),
    ) {
        let mut w = StallWatchdog::new(limit);
        let mut heartbeat = 0u32;
        let mut silent = 0u32;
        let mut stalled = false;
        for (t, beat) in beats.iter().enumerate() {
            if *beat {
                heartbeat = heartbeat.wrapping_add(1);
            }
            // The model: the first tick only records; later ticks count
            // silence since the last change.
            if t > 0 {
                silent = if *beat { 0 } else { silent + 1 };
            }
            stalled |= silent >= limit;
            let want = if stalled { WatchdogAction::Starve } else { WatchdogAction::Feed };
            prop_assert_eq!(w.tick(heartbeat), want, "tick {}", t);
        }
    }
}
