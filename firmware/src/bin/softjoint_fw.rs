//! The firmware image: the board application ([`firmware::app::App`]) on a
//! Cortex-M4F, talking over UART0.
//!
//! Default board: QEMU's `mps2-an386` (CMSDK APB UART0 at 0x4000_4000,
//! its receive interrupt on IRQ 0, 25 MHz system clock, SysTick as the
//! millisecond clock). The main loop sleeps in WFI between interrupts. Another board
//! goes in its own module behind a cargo feature, providing the same four
//! things: a byte UART, a millisecond clock, SMA driver outputs and wire
//! sensors.
//!
//! Run it under QEMU with its UART on a Unix socket QEMU listens on (what
//! `softjoint hil` does; docs/hil.md says why not a pty):
//! ```text
//! qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
//!     -semihosting-config enable=on,target=native \
//!     -serial unix:/tmp/board.sock,server=on,wait=off \
//!     -kernel target/thumbv7em-none-eabihf/release/softjoint-fw
//! ```
//! The image never speaks first: QEMU drops guest output until the host
//! connects, so the host sends `Hello` and the board answers.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

#[cfg(all(target_os = "none", not(feature = "board-mps2-an386")))]
compile_error!(
    "no board selected: enable a board feature such as `board-mps2-an386` (the default)"
);

#[cfg(all(target_os = "none", feature = "board-mps2-an386"))]
mod mps2 {
    //! QEMU mps2-an386 board support.
    #![allow(unsafe_code)] // memory-mapped registers; each access says why it is sound

    use core::sync::atomic::{AtomicU16, AtomicU32, Ordering};
    use cortex_m::peripheral::syst::SystClkSource;
    use cortex_m_rt::{entry, exception};
    #[cfg(feature = "defmt")]
    use defmt_semihosting as _;
    use firmware::app::{App, NoSensors};
    use firmware::control::{DriveVolts, DriverConfig};
    use firmware::protocol::coil_to_mv;
    use firmware::time::{Instant, MillisCounter};

    /// System clock of the AN386 image (ARM AN386 application note: 25 MHz).
    const SYSCLK_HZ: u32 = 25_000_000;

    /// CMSDK APB UART (ARM DDI 0479, "Cortex-M System Design Kit", §4.3).
    struct CmsdkUart {
        base: usize,
    }

    const DATA: usize = 0x000;
    const STATE: usize = 0x004;
    const CTRL: usize = 0x008;
    /// INTSTATUS when read, INTCLEAR when written.
    const INTCLEAR: usize = 0x00C;
    const BAUDDIV: usize = 0x010;
    const STATE_TX_FULL: u32 = 1 << 0;
    const STATE_RX_FULL: u32 = 1 << 1;
    const CTRL_TX_EN: u32 = 1 << 0;
    const CTRL_RX_EN: u32 = 1 << 1;
    const CTRL_RX_INT_EN: u32 = 1 << 3;
    const INT_RX: u32 = 1 << 1;
    const UART0_BASE: usize = 0x4000_4000;

    /// UART0's receive interrupt: IRQ 0 on the AN385/AN386 images (AN386's
    /// interrupt map: UART0 RX 0, TX 1; QEMU's mps2 machine wires it so).
    #[derive(Clone, Copy)]
    struct Uart0Rx;

    // SAFETY: 0 is a valid external interrupt number of this device (the
    // Cortex-M4 of AN386 has more than one), and the only one this type
    // returns.
    unsafe impl cortex_m::interrupt::InterruptNumber for Uart0Rx {
        fn number(self) -> u16 {
            0
        }
    }

    impl CmsdkUart {
        /// UART0 of mps2-an386, its receive interrupt enabled (the NVIC
        /// line is unmasked by `main`).
        fn uart0() -> Self {
            let u = Self { base: UART0_BASE };
            // 115200 Bd at 25 MHz: BAUDDIV = 217 (must be ≥ 16). QEMU's
            // model ignores the rate but requires the register and enables.
            u.write(BAUDDIV, SYSCLK_HZ / 115_200);
            u.write(CTRL, CTRL_TX_EN | CTRL_RX_EN | CTRL_RX_INT_EN);
            u
        }

        fn read(&self, off: usize) -> u32 {
            // SAFETY: `base + off` is a CMSDK UART register of this board,
            // 4-byte aligned, valid for volatile 32-bit access.
            unsafe { core::ptr::read_volatile((self.base + off) as *const u32) }
        }

        fn write(&self, off: usize, v: u32) {
            // SAFETY: as in `read`.
            unsafe { core::ptr::write_volatile((self.base + off) as *mut u32, v) }
        }

        fn rx_full(&self) -> bool {
            self.read(STATE) & STATE_RX_FULL != 0
        }

        fn try_read_byte(&self) -> Option<u8> {
            if self.rx_full() {
                Some((self.read(DATA) & 0xFF) as u8)
            } else {
                None
            }
        }

        fn write_bytes(&self, bytes: &[u8]) {
            for &b in bytes {
                while self.read(STATE) & STATE_TX_FULL != 0 {}
                self.write(DATA, u32::from(b));
            }
        }
    }

    /// Milliseconds since boot, advanced by SysTick. It wraps after 49.7
    /// days; [`MillisCounter`] extends it to a 64-bit monotonic instant.
    static MILLIS: AtomicU32 = AtomicU32::new(0);

    #[exception]
    fn SysTick() {
        MILLIS.fetch_add(1, Ordering::Relaxed);
    }

    /// Every interrupt without its own handler. UART0's receive interrupt
    /// only wakes the main loop from WFI: it is acknowledged here and the
    /// byte stays in the data register for the loop. Any other is not
    /// expected: outputs off, and under QEMU a failed exit (as a panic).
    #[exception]
    unsafe fn DefaultHandler(irqn: i16) {
        if irqn == 0 {
            CmsdkUart { base: UART0_BASE }.write(INTCLEAR, INT_RX);
        } else {
            all_outputs_off();
            cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
            halt()
        }
    }

    /// The board's monotonic clock (read from the main loop only).
    struct Clock(MillisCounter);

    impl Clock {
        fn now(&mut self) -> Instant {
            self.0.extend(MILLIS.load(Ordering::Relaxed))
        }
    }

    /// The SMA driver outputs as the board would set them (mV per coil:
    /// α agonist, α antagonist, β agonist, β antagonist). QEMU has no PWM
    /// peripheral, so the "hardware" is these cells; on a real board this
    /// is where the timer compare registers are written through
    /// `PairDriver::apply_coils`.
    static OUTPUT_MV: [AtomicU16; 4] = [
        AtomicU16::new(0),
        AtomicU16::new(0),
        AtomicU16::new(0),
        AtomicU16::new(0),
    ];

    fn apply_outputs(coils: [[DriveVolts; 2]; 2], driver: &DriverConfig) {
        for (cell, v) in OUTPUT_MV.iter().zip(coils.iter().flatten()) {
            cell.store(coil_to_mv(*v, driver), Ordering::SeqCst);
        }
    }

    fn all_outputs_off() {
        for cell in OUTPUT_MV.iter() {
            cell.store(0, Ordering::SeqCst);
        }
    }

    #[entry]
    fn main() -> ! {
        all_outputs_off();
        let Some(mut core) = cortex_m::Peripherals::take() else {
            halt()
        };
        core.SYST.set_clock_source(SystClkSource::Core);
        core.SYST.set_reload(SYSCLK_HZ / 1000 - 1);
        core.SYST.clear_current();
        core.SYST.enable_counter();
        core.SYST.enable_interrupt();

        let uart = CmsdkUart::uart0();
        // SAFETY: unmasking UART0's receive interrupt is sound: its handler
        // (`DefaultHandler`, IRQ 0) only writes the UART's INTCLEAR and
        // shares no data with the loop.
        unsafe { cortex_m::peripheral::NVIC::unmask(Uart0Rx) };
        let Ok(mut app) = App::new() else { halt() };
        #[cfg(feature = "defmt")]
        defmt::info!("softjoint-fw up");
        let mut send = |frame: &[u8]| uart.write_bytes(frame);
        let mut clock = Clock(MillisCounter::new());
        loop {
            while let Some(b) = uart.try_read_byte() {
                app.on_byte(b, clock.now(), &mut send);
            }
            app.poll(clock.now(), &mut NoSensors, &mut send);
            apply_outputs(app.outputs(), app.joint().driver());
            // Sleep until the next interrupt: SysTick every millisecond
            // (the control period) or a received byte. Interrupts are
            // masked from the check to the WFI, so a byte that arrives
            // after the check still ends the WFI (a pending interrupt
            // wakes it even while masked) and none waits for the next
            // tick. Under QEMU this is what keeps an idle board from
            // costing a host core: a spinning loop did, and its clock
            // (`-icount shift=0`) ran only as fast as QEMU executed it.
            cortex_m::interrupt::disable();
            if !uart.rx_full() {
                cortex_m::asm::wfi();
            }
            // SAFETY: re-enables what the line before disabled; no
            // critical section of the loop spans it.
            unsafe { cortex_m::interrupt::enable() };
        }
    }

    /// Unpowered forever (configuration failure at boot).
    fn halt() -> ! {
        all_outputs_off();
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[panic_handler]
    fn panic(_info: &core::panic::PanicInfo) -> ! {
        // Outputs first: unpowered is the safe state.
        all_outputs_off();
        #[cfg(feature = "defmt")]
        defmt::error!("panic");
        // Under QEMU (started with semihosting) report failure and stop; a
        // real board would wait here for its watchdog.
        cortex_m_semihosting::debug::exit(cortex_m_semihosting::debug::EXIT_FAILURE);
        halt()
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "softjoint-fw is a thumbv7em-none-eabihf image: cargo build -p firmware --release \
         --target thumbv7em-none-eabihf --bin softjoint-fw, then `softjoint hil`"
    );
}
