//! The softjoint board application on an STM32F4: a Nucleo-F446RE
//! (STM32F446RE, Cortex-M4F), through the `stm32f4xx-hal` crate.
//!
//! The same [`App`](firmware::app::App) as the mps2-an386 image (protocol,
//! lockstep HIL, console commands, the 3D joint's control core), with the
//! board's own I/O around it:
//! - **coils**: four PWM channels of TIM3 at [`PWM_HZ`], one per ULN2003
//!   input, driven through the core's [`PairDriver`] (idle coil off first);
//! - **wire sensors**: four pulse coders on the quadrature-encoder inputs
//!   of TIM1, TIM2, TIM4 and TIM8, each 16-bit count extended to `i32` by
//!   [`QuadratureCount`];
//! - **protocol**: USART2 at [`BAUD`] (the ST-LINK virtual COM port on a
//!   Nucleo), bytes received by interrupt into a queue;
//! - **clock**: SysTick at 1 kHz, a wrapping `u32` of milliseconds
//!   extended by [`MillisCounter`];
//! - **watchdog**: the independent watchdog (IWDG, [`IWDG_TIMEOUT_MS`]),
//!   fed from the SysTick interrupt only while the control loop's
//!   heartbeat moves ([`StallWatchdog`], [`STALL_LIMIT_MS`]); a stalled
//!   loop has its outputs zeroed by the interrupt and the chip reset;
//! - **outputs off first**: at reset (before the peripherals are taken),
//!   on a stall, in the panic handler and in the HardFault handler, the
//!   four coil pins are forced to plain GPIO outputs driven low.
//!
//! The pin map (every pin, its header position and what it connects to)
//! is the one table in docs/board.md ("Wiring"); in code it
//! is [`BoardPins`], built in one place ([`run`]).
//!
//! Two images come from this crate, differing only in their [`Flavour`]:
//! `softjoint-stm32f4` ([`Nucleo`]) for the real board, and
//! `softjoint-stm32f4-qemu` ([`Qemu`]) for QEMU's `netduinoplus2`
//! (STM32F405), which does not model the RCC clock tree (its registers
//! read 0, so waiting for a PLL-ready flag hangs) nor timer I/O. The QEMU
//! flavour skips the clock setup (the chip runs on its reset clocks) and
//! the timer I/O (coil outputs are recorded in RAM, the wire sensors read
//! nothing); the USART, the interrupt-driven receive path, SysTick, the
//! watchdog glue, the app and the core are the same code.
#![no_std]
// As in the core: no unwrap/expect/panic! and no indexing that can panic
// in the image's code (the HAL's setup has asserts of its own, reached only
// with the constant arguments given here).
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

mod nucleo;
mod qemu;

pub use nucleo::Nucleo;
pub use qemu::Qemu;

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use critical_section::Mutex;
use defmt_rtt as _;
use firmware::app::{App, BoardSensors};
use firmware::control::{DriveVolts, DriverConfig};
use firmware::time::{Instant, MillisCounter};
use firmware::watchdog::{StallWatchdog, WatchdogAction};
use heapless::spsc::{Consumer, Producer, Queue};
use stm32f4xx_hal::gpio::{PA0, PA1, PA6, PA7, PA8, PA9, PB0, PB1, PB6, PB7, PC6, PC7};
use stm32f4xx_hal::pac;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Rcc;
use stm32f4xx_hal::serial::{self, Rx};
use stm32f4xx_hal::watchdog::IndependentWatchdog;

#[doc(hidden)]
pub use {cortex_m_rt as __rt, stm32f4xx_hal::pac as __pac};

pub use firmware::control::PairDriver;
pub use firmware::sensor::QuadratureCount;

/// USART2 baud rate: the host tools' default (`--baud 115200`), which
/// every ST-LINK virtual COM port supports. A lockstep step moves 31 bytes
/// (two frames of 15 and 16), 2.7 ms of line time at this rate.
pub const BAUD: u32 = 115_200;

/// Coil PWM frequency (Hz). The coils are resistive (an SMA spring heats
/// by its mean power, time constants of seconds), so any frequency well
/// above 1 kHz acts as a mean; 10 kHz keeps the ULN2003's switching delays
/// (≤ 1 µs per edge, TI ULN2003A datasheet, t_PLH/t_PHL max) to ≤ 2 % of a
/// period, and at the 84 MHz timer clock gives a full scale of 8,400 steps.
pub const PWM_HZ: u32 = 10_000;

/// Core clock of the real board (Hz): HSI 16 MHz through the PLL. 84 MHz
/// needs no voltage-regulator overdrive and gives TIM3 (APB1 at 42 MHz,
/// timers at twice that) an 84 MHz clock.
pub const SYSCLK_HZ: u32 = 84_000_000;

/// The loop may go this long (ms) without a heartbeat before it counts as
/// stalled. It beats at the end of every pass (at least once per SysTick)
/// and after every frame it sends; the longest legitimate gap is one
/// frame on the blocking transmit path: the longest frame (`Status`, 47
/// bytes with its delimiter, docs/protocol.md) takes 4.1 ms at [`BAUD`].
pub const STALL_LIMIT_MS: u32 = 25;

/// Independent-watchdog timeout (ms at the nominal 32 kHz LSI). The LSI
/// may run at 17–47 kHz (DS10693, LSI characteristics), so the real
/// timeout is 68–188 ms: the reset after a stall, or after the tick
/// interrupt itself stops, comes within that.
pub const IWDG_TIMEOUT_MS: u32 = 100;

/// Receive queue (bytes): more than ten frames of the longest message.
const RX_QUEUE: usize = 512;

/// The pins and timers of the coil and sensor I/O, in the board's pin
/// map. Built once in [`run`]; the flavour decides what to make of them.
pub struct BoardPins {
    /// TIM3, the coil PWM timer.
    pub pwm_timer: pac::TIM3,
    /// Coil pins, TIM3 channels 1–4: α agonist (PA6), α antagonist (PA7),
    /// β agonist (PB0), β antagonist (PB1).
    pub coils: (PA6, PA7, PB0, PB1),
    /// Wire sensors 1–4: TIM1 (PA8, PA9), TIM2 (PA0, PA1), TIM4 (PB6,
    /// PB7), TIM8 (PC6, PC7); channel 1 is the coder's A output.
    pub sensor1: (pac::TIM1, PA8, PA9),
    /// Wire sensor 2.
    pub sensor2: (pac::TIM2, PA0, PA1),
    /// Wire sensor 3.
    pub sensor3: (pac::TIM4, PB6, PB7),
    /// Wire sensor 4.
    pub sensor4: (pac::TIM8, PC6, PC7),
}

/// Applies the app's per-coil outputs to the coils.
pub trait CoilOutputs {
    /// Drives both pairs, `[agonist, antagonist]` each (both coils of a
    /// pair only when the app has the plane in open-loop drive mode).
    fn apply(&mut self, coils: [[DriveVolts; 2]; 2], driver: &DriverConfig);
}

/// What differs between the real board and its QEMU flavour: clock setup
/// and timer I/O, and how to stop after a fault.
pub trait Flavour {
    /// The board's name in the boot log.
    const NAME: &'static str;
    /// The coil outputs and wire sensors.
    type Io: CoilOutputs + BoardSensors;
    /// Sets the clocks up (or not) and returns the RCC with the clocks in
    /// use.
    fn clocks(rcc: pac::RCC) -> Rcc;
    /// The frequency SysTick counts (the core clock), in Hz.
    fn systick_hz(rcc: &Rcc) -> u32;
    /// Builds the coil and sensor I/O from the pin map.
    fn timer_io(pins: BoardPins, rcc: &mut Rcc) -> Self::Io;
    /// Every coil output off, now, from any context (reset, the tick
    /// interrupt, the panic and fault handlers): register writes only.
    fn outputs_off_now() {
        coil_pins_low();
    }
    /// Stops for good once the outputs are off (panic, fault, failed
    /// boot).
    fn halt() -> !;
}

/// Milliseconds since boot, counted by SysTick (wraps after 49.7 days;
/// [`MillisCounter`] extends it).
static MILLIS: AtomicU32 = AtomicU32::new(0);
/// Passes of the control loop (wrapping), read by the tick.
static HEARTBEAT: AtomicU32 = AtomicU32::new(0);
/// Received bytes the queue had no room for, and receive errors
/// (overrun, framing, noise): both lose a byte, which the protocol's CRC
/// catches and the host retries.
static RX_DROPPED: AtomicU32 = AtomicU32::new(0);
static RX_ERRORS: AtomicU32 = AtomicU32::new(0);

/// The stall policy and the started watchdog, owned by the tick.
static STALL: Mutex<Cell<StallWatchdog>> =
    Mutex::new(Cell::new(StallWatchdog::new(STALL_LIMIT_MS)));
static IWDG: Mutex<RefCell<Option<IndependentWatchdog>>> = Mutex::new(RefCell::new(None));
/// USART2's receiver and the queue's producer, owned by its interrupt.
type RxEnd = (Rx<pac::USART2>, Producer<'static, u8, RX_QUEUE>);
static RX: Mutex<RefCell<Option<RxEnd>>> = Mutex::new(RefCell::new(None));

defmt::timestamp!("{=u32:ms}", MILLIS.load(Ordering::Relaxed));

/// The board's monotonic clock (read from the loop only).
struct Clock(MillisCounter);

impl Clock {
    fn now(&mut self) -> Instant {
        self.0.extend(MILLIS.load(Ordering::Relaxed))
    }
}

/// The image: outputs off, peripherals, then the control loop for ever.
pub fn run<F: Flavour>() -> ! {
    // Before anything else: coil pins low (they are floating inputs from
    // reset until here, which a ULN2003 input reads as off).
    F::outputs_off_now();
    let (Some(dp), Some(cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        fail::<F>("peripherals already taken")
    };
    // The watchdog first, so a hang anywhere in the setup resets the chip.
    // Halting the core in a debugger stops it (no reset at a breakpoint).
    let mut iwdg = IndependentWatchdog::new(dp.IWDG);
    iwdg.stop_on_debug(&dp.DBGMCU, true);
    iwdg.start(IWDG_TIMEOUT_MS.millis());
    // The loop sleeps in WFI between interrupts; keep the debug port's
    // clock running meanwhile so a probe (probe-rs reading the defmt RTT
    // buffer) keeps its access (RM0390, DBGMCU_CR.DBG_SLEEP).
    dp.DBGMCU.cr().modify(|_, w| w.dbg_sleep().set_bit());

    let mut rcc = F::clocks(dp.RCC);
    let gpioa = dp.GPIOA.split(&mut rcc);
    let gpiob = dp.GPIOB.split(&mut rcc);
    let gpioc = dp.GPIOC.split(&mut rcc);

    // USART2: PA2 TX, PA3 RX (AF7), the ST-LINK virtual COM port.
    let serial_config = serial::Config::default().baudrate(BAUD.bps());
    let Ok(serial) = dp
        .USART2
        .serial::<u8>((gpioa.pa2, gpioa.pa3), serial_config, &mut rcc)
    else {
        fail::<F>("USART2 configuration refused")
    };
    let (mut tx, mut rx) = serial.split();
    let Some(queue) = cortex_m::singleton!(: Queue<u8, RX_QUEUE> = Queue::new()) else {
        fail::<F>("receive queue already taken")
    };
    let (producer, mut consumer): (_, Consumer<'static, u8, RX_QUEUE>) = queue.split();
    rx.listen();
    critical_section::with(|cs| RX.borrow_ref_mut(cs).replace((rx, producer)));

    let mut io = F::timer_io(
        BoardPins {
            pwm_timer: dp.TIM3,
            coils: (gpioa.pa6, gpioa.pa7, gpiob.pb0, gpiob.pb1),
            sensor1: (dp.TIM1, gpioa.pa8, gpioa.pa9),
            sensor2: (dp.TIM2, gpioa.pa0, gpioa.pa1),
            sensor3: (dp.TIM4, gpiob.pb6, gpiob.pb7),
            sensor4: (dp.TIM8, gpioc.pc6, gpioc.pc7),
        },
        &mut rcc,
    );
    let Ok(mut app) = App::new() else {
        fail::<F>("joint configuration refused")
    };

    // The tick takes the watchdog over, then SysTick and the receive
    // interrupt start.
    critical_section::with(|cs| IWDG.borrow_ref_mut(cs).replace(iwdg));
    let systick_hz = start_interrupts::<F>(cp.SYST, &rcc);
    defmt::info!(
        "{=str} up: SysTick at {=u32} Hz, PWM {=u32} Hz, USART2 at {=u32} Bd",
        F::NAME,
        systick_hz,
        PWM_HZ,
        BAUD
    );

    let mut send = |frame: &[u8]| {
        for &b in frame {
            // Blocks for at most one byte time while the transmitter is
            // busy; the HAL's write has no error of its own.
            let _ = nb::block!(tx.write(b));
        }
        // A frame sent is progress: a pass that answers many queued
        // requests (each reply up to 4.1 ms of line time) stays alive.
        beat();
    };
    let mut clock = Clock(MillisCounter::new());
    let mut reported = (0u32, 0u32);
    loop {
        // A byte the interrupt did not take: QEMU 7.2's USART model can
        // leave RXNE set with its interrupt line low (its DR read lowers the
        // line unconditionally; seen in the lockstep tests: RXNE and RXNEIE
        // set, nothing pending in the NVIC, the guest waiting for ever). On
        // silicon the interrupt is level-triggered and this finds nothing.
        receive_pending();
        // At most one queue's worth per pass, so a flood of bytes cannot
        // keep the loop from its control step.
        for _ in 0..RX_QUEUE {
            let Some(b) = consumer.dequeue() else { break };
            app.on_byte(b, clock.now(), &mut send);
        }
        app.poll(clock.now(), &mut io, &mut send);
        io.apply(app.outputs(), app.joint().driver());
        beat();
        warn_of_lost_bytes(&mut reported);
        // Sleep until the next interrupt: SysTick every millisecond (the
        // control period), or a received byte.
        cortex_m::asm::wfi();
    }
}

/// Starts SysTick at 1 kHz (the control period and the clock) and unmasks
/// USART2's receive interrupt; returns SysTick's clock (Hz).
fn start_interrupts<F: Flavour>(mut syst: cortex_m::peripheral::SYST, rcc: &Rcc) -> u32 {
    let systick_hz = F::systick_hz(rcc);
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(systick_hz / 1000 - 1);
    syst.clear_current();
    syst.enable_counter();
    syst.enable_interrupt();
    // SAFETY: unmasking USART2's interrupt is sound: its handler only
    // touches `RX` (inside a critical section) and two atomic counters.
    #[allow(unsafe_code)]
    unsafe {
        cortex_m::peripheral::NVIC::unmask(pac::Interrupt::USART2);
    }
    systick_hz
}

/// Logs received bytes lost since the last report (`reported`: dropped,
/// receive errors), once per change.
fn warn_of_lost_bytes(reported: &mut (u32, u32)) {
    let lost = (
        RX_DROPPED.load(Ordering::Relaxed),
        RX_ERRORS.load(Ordering::Relaxed),
    );
    if lost != *reported {
        defmt::warn!(
            "USART2: {=u32} bytes dropped (queue full), {=u32} receive errors",
            lost.0,
            lost.1
        );
        *reported = lost;
    }
}

/// The loop made progress (a pass completed, or a frame went out).
fn beat() {
    HEARTBEAT.fetch_add(1, Ordering::Relaxed);
}

/// SysTick, every millisecond: the clock, and the stall policy deciding
/// whether to feed the watchdog or to zero the outputs and let it bite.
pub fn on_tick<F: Flavour>() {
    MILLIS.fetch_add(1, Ordering::Relaxed);
    let beat = HEARTBEAT.load(Ordering::Relaxed);
    let action = critical_section::with(|cs| {
        let cell = STALL.borrow(cs);
        let mut policy = cell.get();
        let action = policy.tick(beat);
        cell.set(policy);
        if action == WatchdogAction::Feed {
            if let Some(iwdg) = IWDG.borrow_ref_mut(cs).as_mut() {
                iwdg.feed();
            }
        }
        action
    });
    if action == WatchdogAction::Starve {
        F::outputs_off_now();
    }
}

/// USART2 interrupt: every received byte into the queue.
pub fn on_usart2() {
    receive_pending();
}

/// Moves what USART2 holds into the queue (interrupt, or the loop's
/// check for a byte the interrupt missed).
fn receive_pending() {
    critical_section::with(|cs| {
        let mut end = RX.borrow_ref_mut(cs);
        let Some((rx, producer)) = end.as_mut() else {
            return;
        };
        // Until the receiver is empty (an error read also clears the error
        // flag); bounded, since an emulator may refill it at once.
        for _ in 0..32 {
            match rx.read() {
                Ok(b) => {
                    if producer.enqueue(b).is_err() {
                        RX_DROPPED.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(_)) => {
                    RX_ERRORS.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    });
}

/// The panic handler's body: outputs off first, then the log, then stop.
pub fn on_panic<F: Flavour>() -> ! {
    F::outputs_off_now();
    defmt::error!("panic: outputs off");
    F::halt()
}

/// The HardFault handler's body: as a panic.
pub fn on_fault<F: Flavour>() -> ! {
    F::outputs_off_now();
    defmt::error!("hard fault: outputs off");
    F::halt()
}

fn fail<F: Flavour>(why: &str) -> ! {
    F::outputs_off_now();
    defmt::error!("boot failed: {=str}; outputs off", why);
    F::halt()
}

/// Forces the four coil pins (PA6, PA7, PB0, PB1) to plain GPIO outputs
/// driven low, whatever they were (floating inputs after reset, TIM3's
/// alternate function while running): every ULN2003 input off. Register
/// writes only, no state, so it is callable before the peripherals are
/// taken and from interrupt and fault handlers.
pub fn coil_pins_low() {
    // SAFETY: the RCC, GPIOA and GPIOB register blocks are always mapped.
    // The loop never touches RCC's AHB1ENR or these ports' ODR/MODER after
    // setup, and every caller here runs either before setup (reset) or
    // when the loop is stalled, panicking or faulted; BSRR writes are
    // atomic set/reset operations.
    #[allow(unsafe_code)]
    let (rcc, gpioa, gpiob) =
        unsafe { (&*pac::RCC::ptr(), &*pac::GPIOA::ptr(), &*pac::GPIOB::ptr()) };
    // The ports must be clocked for the writes to take (they are not at
    // reset).
    rcc.ahb1enr()
        .modify(|_, w| w.gpioaen().set_bit().gpioben().set_bit());
    // Output data low first, then output mode: no high glitch.
    gpioa.bsrr().write(|w| w.br6().set_bit().br7().set_bit());
    gpiob.bsrr().write(|w| w.br0().set_bit().br1().set_bit());
    gpioa
        .moder()
        .modify(|_, w| w.moder6().output().moder7().output());
    gpiob
        .moder()
        .modify(|_, w| w.moder0().output().moder1().output());
}

/// The handlers of an image with flavour `$flavour`: reset entry, SysTick,
/// USART2, HardFault and panic.
#[macro_export]
macro_rules! image {
    ($flavour:ty) => {
        #[$crate::__rt::entry]
        fn main() -> ! {
            $crate::run::<$flavour>()
        }

        #[$crate::__rt::exception]
        fn SysTick() {
            $crate::on_tick::<$flavour>()
        }

        #[allow(unsafe_code)] // cortex-m-rt requires HardFault to be an unsafe fn
        #[$crate::__rt::exception]
        unsafe fn HardFault(_frame: &$crate::__rt::ExceptionFrame) -> ! {
            $crate::on_fault::<$flavour>()
        }

        use $crate::__pac::interrupt;
        #[interrupt]
        fn USART2() {
            $crate::on_usart2()
        }

        #[panic_handler]
        fn panic(_info: &core::panic::PanicInfo) -> ! {
            $crate::on_panic::<$flavour>()
        }
    };
}
