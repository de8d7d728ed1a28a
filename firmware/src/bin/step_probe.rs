//! A minimal Cortex-M4F image that links the portable core and runs the 3D
//! control step: the basis of the flash/RAM figures in docs/benchmarks.md. Under
//! QEMU (`cargo run -p firmware --release --target thumbv7em-none-eabihf
//! --bin step-probe`) it runs 1000 steps against a synthetic sweep of wire
//! counts, prints a one-line summary over semihosting and exits 0 when every
//! output was bounded.
//!
//! It also measures instructions per control step. Under `qemu-system-arm
//! -icount shift=0` QEMU advances virtual time by exactly 1 ns per executed
//! instruction, and SysTick counts the AN386's 25 MHz system clock (40 ns
//! per tick), so `ticks × 40` is the number of instructions executed. Built
//! for another Cortex-M core, the probe is for the QEMU machine that runs
//! it (firmware/probes/build.rs: thumbv7m on mps2-an385, thumbv8m.main on
//! mps2-an505, thumbv6m on microbit) and counts at that machine's clock.
//! Built for riscv32imac (firmware/probes, QEMU's `virt` machine) it reads
//! the `minstret` CSR instead, which QEMU under `-icount` keeps as the count
//! of executed instructions: one instruction per "tick". A loop of known
//! length (`nop; subs; bne` on Cortex-M, `nop; addi; bnez` on RISC-V, 3
//! instructions per iteration) is timed the same way as a check of the
//! method. Without `-icount` the figures are host-speed dependent and
//! meaningless. Only the counter, the entry point and the semihosting crate
//! differ between the architectures: the step loop (`run`) is one source.
//!
//! On the host it only explains itself, so `cargo build --workspace` works.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]
#![deny(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]

#[cfg(target_os = "none")]
mod image {
    use core::hint::black_box;
    #[cfg(target_arch = "arm")]
    use cortex_m_rt::entry;
    #[cfg(target_arch = "arm")]
    use cortex_m_semihosting::{debug, hprintln};
    #[cfg(feature = "defmt")]
    use defmt_semihosting as _;
    use firmware::joint::{Feedback, Joint3d, JointConfig, StepInput};
    use firmware::time::{Duration, Instant};
    #[cfg(target_arch = "riscv32")]
    use riscv_rt::entry;
    #[cfg(target_arch = "riscv32")]
    use riscv_semihosting::{debug, hprintln};

    const STEPS: i32 = 1000;
    const PERIOD: Duration = Duration::from_millis(1);
    #[cfg(target_arch = "riscv32")]
    use clock_minstret::{start_clock, ticks, HALF_INSNS_PER_TICK};
    #[cfg(target_arch = "arm")]
    use clock_systick::{start_clock, ticks, HALF_INSNS_PER_TICK};

    #[entry]
    fn main() -> ! {
        start_clock();
        // Check of the method: 100 000 iterations of nop/subs/bne
        // (nop/addi/bnez on RISC-V).
        let t0 = ticks();
        for _ in 0..black_box(100_000u32) {
            #[cfg(target_arch = "arm")]
            cortex_m::asm::nop();
            #[cfg(target_arch = "riscv32")]
            riscv::asm::nop();
        }
        let nop_insns = (ticks() - t0) * HALF_INSNS_PER_TICK / 2;
        hprintln!(
            "nop loop: {} instructions measured for 100000 iterations",
            nop_insns
        );
        let ok = match Joint3d::new(JointConfig::paper_3d()) {
            Ok(mut joint) => run(&mut joint),
            Err(_) => false,
        };
        debug::exit(if ok {
            debug::EXIT_SUCCESS
        } else {
            debug::EXIT_FAILURE
        });
        #[allow(clippy::empty_loop)]
        loop {}
    }

    fn run(joint: &mut Joint3d) -> bool {
        joint.arm();
        if joint.set_target(0, 5.0).is_err() || joint.set_target(1, -5.0).is_err() {
            return false;
        }
        let mut bounded = true;
        let mut driven = 0u32;
        let mut faults = 0u16;
        let t0 = ticks();
        for k in 0..STEPS {
            // A slow triangle sweep of ±1 mm on the α and β pairs.
            let phase = (k % 400) - 200;
            let d = black_box(phase.abs() - 100);
            let counts = [Some(-d), Some(d / 2), Some(d), Some(-d / 2)];
            let input = StepInput {
                now: Instant::ZERO + PERIOD.saturating_mul(k as u64),
                dt: PERIOD,
                feedback: Feedback::WireCounts(counts),
            };
            let out = black_box(joint.step(&input));
            for v in out.paper_coil_volts() {
                bounded &= (0.0..=joint.driver().supply_v()).contains(&v);
                driven += u32::from(v > 0.0);
            }
            faults |= out.faults.bits();
        }
        let insns = (ticks() - t0) * HALF_INSNS_PER_TICK / 2;
        hprintln!("3D control step: {} instructions per step (mean of {} steps, loop and input setup included)", insns / STEPS as u64, STEPS);
        #[cfg(feature = "defmt")]
        defmt::info!(
            "step-probe: {=i32} steps, {=u32} coil-steps driven",
            STEPS,
            driven
        );
        hprintln!(
            "step-probe: {} steps, {} coil-steps driven, faults {:#06x}",
            STEPS,
            driven,
            faults
        );
        bounded && driven > 0 && faults == 0
    }

    /// The Cortex-M clock: SysTick on the core clock, its wraps counted.
    #[cfg(target_arch = "arm")]
    mod clock_systick {
        use core::sync::atomic::{AtomicU32, Ordering};
        use cortex_m::peripheral::{syst::SystClkSource, SYST};
        use cortex_m_rt::exception;

        /// SysTick reload: the full 24-bit range.
        const RELOAD: u32 = 0x00FF_FFFF;
        /// Nanoseconds per SysTick tick, times 2, at the system clock of the
        /// QEMU machine this target's probe runs in; with -icount shift=0
        /// instructions per tick (×2). AN385/AN386: 25 MHz (hw/arm/mps2.c);
        /// AN505: 20 MHz (hw/arm/mps2-tz.c); micro:bit: 16 MHz
        /// (hw/arm/nrf51_soc.c, 62.5 ns).
        pub const HALF_INSNS_PER_TICK: u64 = if cfg!(probe_machine = "an505") {
            100
        } else if cfg!(probe_machine = "microbit") {
            125
        } else {
            80
        };

        static WRAPS: AtomicU32 = AtomicU32::new(0);

        #[exception]
        fn SysTick() {
            // Load and store, not fetch_add (Cortex-M0 has no atomic
            // read-modify-write): the handler is the only writer, and the main
            // loop cannot run inside it.
            WRAPS.store(
                WRAPS.load(Ordering::Relaxed).wrapping_add(1),
                Ordering::Relaxed,
            );
        }

        /// Ticks since SysTick was started (wrap count × reload + elapsed).
        pub fn ticks() -> u64 {
            loop {
                let w1 = WRAPS.load(Ordering::Relaxed);
                let v = SYST::get_current();
                let w2 = WRAPS.load(Ordering::Relaxed);
                if w1 == w2 {
                    return u64::from(w1) * (u64::from(RELOAD) + 1) + u64::from(RELOAD - v);
                }
            }
        }

        /// SysTick on the core clock, full range, wraps counted.
        pub fn start_clock() {
            if let Some(mut core) = cortex_m::Peripherals::take() {
                core.SYST.set_clock_source(SystClkSource::Core);
                core.SYST.set_reload(RELOAD);
                core.SYST.clear_current();
                core.SYST.enable_interrupt();
                core.SYST.enable_counter();
                // VAL reads 0 until the first reload (which raises no
                // exception); wait for it so elapsed ticks start at 0.
                while SYST::get_current() == 0 {}
            }
        }
    }

    /// The RISC-V clock: the `minstret` CSR (retired instructions, 64 bits
    /// as `minstreth:minstret`), which the probe reads in machine mode,
    /// where riscv-rt starts it. QEMU keeps it as the instruction count
    /// under `-icount` (target/riscv/csr.c), and without `-icount` as the
    /// host's tick counter.
    #[cfg(target_arch = "riscv32")]
    mod clock_minstret {
        /// One count per instruction (×2).
        pub const HALF_INSNS_PER_TICK: u64 = 2;

        /// Counts from reset: nothing to start.
        pub fn start_clock() {}

        /// Instructions retired since reset.
        pub fn ticks() -> u64 {
            riscv::register::minstret::read64()
        }
    }

    #[panic_handler]
    fn panic(_info: &core::panic::PanicInfo) -> ! {
        // Nothing drives hardware in this probe; report failure and stop.
        debug::exit(debug::EXIT_FAILURE);
        #[allow(clippy::empty_loop)]
        loop {}
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("step-probe is a thumbv7em-none-eabihf image: cargo run -p firmware --release --target thumbv7em-none-eabihf --bin step-probe");
}
