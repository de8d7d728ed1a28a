//! A minimal Cortex-M4F image that links the portable core and runs the 3D
//! control step: the basis of the flash/RAM figures in the README. Under
//! QEMU (`cargo run -p firmware --release --target thumbv7em-none-eabihf
//! --bin step-probe`) it runs 1000 steps against a synthetic sweep of wire
//! counts, prints a one-line summary over semihosting and exits 0 when every
//! output was bounded.
//!
//! On the host it only explains itself, so `cargo build --workspace` works.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

#[cfg(target_os = "none")]
mod image {
    use core::hint::black_box;
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hprintln};
    #[cfg(feature = "defmt")]
    use defmt_semihosting as _;
    use firmware::joint::{Feedback, Joint3d, JointConfig, StepInput};

    const STEPS: i32 = 1000;
    const DT_S: f32 = 0.001;

    #[entry]
    fn main() -> ! {
        let ok = match Joint3d::new(JointConfig::paper_3d()) {
            Ok(mut joint) => run(&mut joint),
            Err(_) => false,
        };
        debug::exit(if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE });
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
        for k in 0..STEPS {
            // A slow triangle sweep of ±1 mm on the α and β pairs.
            let phase = (k % 400) - 200;
            let d = black_box(phase.abs() - 100);
            let counts = [Some(-d), Some(d / 2), Some(d), Some(-d / 2)];
            let input = StepInput { now_s: k as f32 * DT_S, dt_s: DT_S, feedback: Feedback::WireCounts(counts) };
            let out = black_box(joint.step(&input));
            for v in out.paper_coil_volts() {
                bounded &= (0.0..=joint.driver().supply_v()).contains(&v);
                driven += u32::from(v > 0.0);
            }
            faults |= out.faults.bits();
        }
        #[cfg(feature = "defmt")]
        defmt::info!("step-probe: {=i32} steps, {=u32} coil-steps driven", STEPS, driven);
        hprintln!("step-probe: {} steps, {} coil-steps driven, faults {:#06x}", STEPS, driven, faults);
        bounded && driven > 0 && faults == 0
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
