//! The QEMU flavour of the board image, for `qemu-system-arm -machine
//! netduinoplus2` (an STM32F405). QEMU 7.2 models its USARTs, SysTick and
//! the NVIC, but not the RCC clock tree (every register reads 0, so the
//! HAL's wait for the PLL-ready flag would never end) nor timer I/O (no
//! PWM on pins, no encoder inputs). So this flavour
//! - skips the clock setup: `constrain()` takes the RCC without touching a
//!   register and the HAL assumes the reset clocks (HSI, 16 MHz), which is
//!   what sets USART2's baud divisor (QEMU ignores it);
//! - counts SysTick at the CPU clock QEMU gives the machine, 168 MHz, not
//!   at the HSI that real silicon would run on at reset;
//! - builds no timer I/O: the coil outputs are recorded in RAM as signed
//!   millivolts per pair (as on mps2-an386), the wire sensors read nothing
//!   (lockstep HIL sends the counts over the protocol);
//! - exits QEMU with a failure status on a panic or fault (semihosting)
//!   instead of waiting for the watchdog, which QEMU does not model.
//!
//! Everything else is the real board's code.

use core::sync::atomic::{AtomicU16, Ordering};

use firmware::app::{BoardSensors, NoSensors};
use firmware::control::{DriveVolts, DriverConfig};
use firmware::protocol::coil_to_mv;
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Rcc;

use crate::{coil_pins_low, BoardPins, CoilOutputs, Flavour};

/// The CPU clock of QEMU's netduinoplus2 model (Hz): `SYSCLK_FRQ` in QEMU's
/// hw/arm/netduinoplus2.c, fixed whatever the RCC registers say.
pub const QEMU_SYSCLK_HZ: u32 = 168_000_000;

/// The QEMU netduinoplus2 flavour (image `softjoint-stm32f4-qemu`).
pub struct Qemu;

/// The coil outputs as millivolts per coil, `[α agonist, α antagonist,
/// β agonist, β antagonist]` (what the PWM would apply); no sensors.
pub struct QemuIo;

static OUTPUT_MV: [AtomicU16; 4] = [
    AtomicU16::new(0),
    AtomicU16::new(0),
    AtomicU16::new(0),
    AtomicU16::new(0),
];

impl Flavour for Qemu {
    const NAME: &'static str = "softjoint-stm32f4-qemu (netduinoplus2)";
    type Io = QemuIo;

    fn clocks(rcc: pac::RCC) -> Rcc {
        rcc.constrain()
    }

    fn systick_hz(_rcc: &Rcc) -> u32 {
        QEMU_SYSCLK_HZ
    }

    fn timer_io(_pins: BoardPins, _rcc: &mut Rcc) -> QemuIo {
        // The pins and timers stay unused (QEMU models no timer I/O).
        QemuIo
    }

    fn outputs_off_now() {
        // The real board's pin writes too (QEMU ignores them), then the
        // recorded outputs.
        coil_pins_low();
        for cell in &OUTPUT_MV {
            cell.store(0, Ordering::SeqCst);
        }
    }

    fn halt() -> ! {
        cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
        loop {
            core::hint::spin_loop();
        }
    }
}

impl CoilOutputs for QemuIo {
    fn apply(&mut self, coils: [[DriveVolts; 2]; 2], driver: &DriverConfig) {
        for (cell, v) in OUTPUT_MV.iter().zip(coils.iter().flatten()) {
            cell.store(coil_to_mv(*v, driver), Ordering::SeqCst);
        }
    }
}

impl BoardSensors for QemuIo {
    fn read_counts(&mut self) -> [Option<i32>; 4] {
        NoSensors.read_counts()
    }
}
