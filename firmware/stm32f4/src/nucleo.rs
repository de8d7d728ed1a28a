//! The real board: a Nucleo-F446RE. Clock tree from the HSI through the
//! PLL, TIM3 PWM on the coil pins, four quadrature-encoder timers on the
//! wire-sensor pins; a fault waits for the independent watchdog's reset.

use firmware::app::BoardSensors;
use firmware::control::{DriveVolts, DriverConfig, PairDriver};
use firmware::sensor::QuadratureCount;
use stm32f4xx_hal::pac::{self, TIM1, TIM2, TIM3, TIM4, TIM8};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::qei::Qei;
use stm32f4xx_hal::rcc::{Config, Rcc};
use stm32f4xx_hal::timer::{PwmChannel, PwmHzManager};

use crate::{BoardPins, CoilOutputs, Flavour, PWM_HZ, SYSCLK_HZ};

/// The Nucleo-F446RE flavour (image `softjoint-stm32f4`).
pub struct Nucleo;

/// TIM3's four PWM channels as two pair drivers, and the four coders.
pub struct NucleoIo {
    // Kept so the timer is owned for the image's life.
    _pwm: PwmHzManager<TIM3>,
    alpha: PairDriver<PwmChannel<TIM3, 0>, PwmChannel<TIM3, 1>>,
    beta: PairDriver<PwmChannel<TIM3, 2>, PwmChannel<TIM3, 3>>,
    coders: (Qei<TIM1>, Qei<TIM2>, Qei<TIM4>, Qei<TIM8>),
    counts: [QuadratureCount; 4],
}

impl Flavour for Nucleo {
    const NAME: &'static str = "softjoint-stm32f4 (Nucleo-F446RE)";
    type Io = NucleoIo;

    fn clocks(rcc: pac::RCC) -> Rcc {
        // HSI (16 MHz internal RC, ±1 % at 25 °C, DS10693) through the PLL:
        // no dependence on the ST-LINK's 8 MHz MCO reaching PH0 (a solder
        // bridge option on Nucleo-64 boards). ±1 % is well inside a UART's
        // tolerance and the control loop's needs.
        rcc.freeze(Config::hsi().sysclk(SYSCLK_HZ.Hz()))
    }

    fn systick_hz(rcc: &Rcc) -> u32 {
        rcc.clocks.hclk().raw()
    }

    fn timer_io(pins: BoardPins, rcc: &mut Rcc) -> NucleoIo {
        let (pwm, (c1, c2, c3, c4)) = pins.pwm_timer.pwm_hz(PWM_HZ.Hz(), rcc);
        let (pa6, pa7, pb0, pb1) = pins.coils;
        let (mut c1, mut c2, mut c3, mut c4) =
            (c1.with(pa6), c2.with(pa7), c3.with(pb0), c4.with(pb1));
        // Compare registers at 0 before any output is enabled.
        c1.set_duty(0);
        c2.set_duty(0);
        c3.set_duty(0);
        c4.set_duty(0);
        c1.enable();
        c2.enable();
        c3.enable();
        c4.enable();
        // Coder outputs are often open collector: the pins' pull-ups
        // (≈ 40 kΩ, DS10693 R_PU) hold an idle line high.
        let (t1, a1, b1) = pins.sensor1;
        let (t2, a2, b2) = pins.sensor2;
        let (t3, a3, b3) = pins.sensor3;
        let (t4, a4, b4) = pins.sensor4;
        let q1 = t1.qei((a1.internal_pull_up(true), b1.internal_pull_up(true)), rcc);
        let q2 = t2.qei((a2.internal_pull_up(true), b2.internal_pull_up(true)), rcc);
        let q3 = t3.qei((a3.internal_pull_up(true), b3.internal_pull_up(true)), rcc);
        let q4 = t4.qei((a4.internal_pull_up(true), b4.internal_pull_up(true)), rcc);
        // Counts start at 0 where the counters are now. TIM2 is a 32-bit
        // timer; its low 16 bits are a 16-bit counter like the others.
        let counts = [
            QuadratureCount::new(q1.count()),
            QuadratureCount::new(q2.count() as u16),
            QuadratureCount::new(q3.count()),
            QuadratureCount::new(q4.count()),
        ];
        NucleoIo {
            _pwm: pwm,
            alpha: PairDriver::new(c1, c2),
            beta: PairDriver::new(c3, c4),
            coders: (q1, q2, q3, q4),
            counts,
        }
    }

    fn halt() -> ! {
        // Nothing runs any more, the tick included, so nothing feeds the
        // independent watchdog: it resets the chip, which comes up
        // disarmed with its outputs off.
        cortex_m::interrupt::disable();
        loop {
            core::hint::spin_loop();
        }
    }
}

impl CoilOutputs for NucleoIo {
    fn apply(&mut self, coils: [[DriveVolts; 2]; 2], driver: &DriverConfig) {
        let [alpha, beta] = coils;
        // The HAL's PWM channels cannot fail (their error type is
        // Infallible), so neither can the pair drivers.
        let Ok(()) = self.alpha.apply_coils(alpha, driver);
        let Ok(()) = self.beta.apply_coils(beta, driver);
    }
}

impl BoardSensors for NucleoIo {
    fn read_counts(&mut self) -> [Option<i32>; 4] {
        let [c1, c2, c3, c4] = &mut self.counts;
        let (q1, q2, q3, q4) = &self.coders;
        [
            Some(c1.update(q1.count())),
            Some(c2.update(q2.count() as u16)),
            Some(c3.update(q3.count())),
            Some(c4.update(q4.count())),
        ]
    }
}
