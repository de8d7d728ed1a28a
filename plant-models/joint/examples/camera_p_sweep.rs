//! Eq. 1 (one coil, camera feedback, Kp = 2 V/°, θd = 20°) on the plant
//! alone, over the driver transconductances and convection coefficients of
//! SPEC §2: the mean of θ − θd over 10–60 s, lowest and highest of seeds
//! 1–5. Reproduces the table in the joint README (plant-models/joint/README.md):
//!
//! ```text
//! cargo run --release -p plant-joint --example camera_p_sweep
//! ```
use plant_joint::{Joint2d, Joint2dParams, PlantError};

const KP_V_PER_DEG: f64 = 2.0;
const TARGET_DEG: f64 = 20.0;
/// ULN2003 turn-on (paper: v_offset).
const OFFSET_V: f64 = 1.7;

fn mean_error_deg(seed: u64, g_a_v: f64, h_w_m2_k: f64) -> Result<f64, PlantError> {
    let mut p = Joint2dParams::default();
    p.sim.seed = seed;
    p.plane.driver.transconductance_a_v = g_a_v;
    p.plane.coil.convection_w_m2_k = h_w_m2_k;
    let mut j = Joint2d::new(p)?;
    let mut measured = j.angle_deg();
    let (mut sum, mut n) = (0.0, 0u32);
    for k in 0..60_000 {
        if let Some(a) = j.camera().take_new().and_then(|f| f.angles_deg) {
            measured = a[0];
        }
        let v1 = (-KP_V_PER_DEG * (measured - TARGET_DEG) + OFFSET_V).clamp(0.0, 5.0);
        j.step(1e-3, &[v1, 0.0])?;
        if k >= 10_000 {
            sum += j.angle_deg() - TARGET_DEG;
            n += 1;
        }
    }
    Ok(sum / f64::from(n))
}

fn main() -> Result<(), PlantError> {
    println!("mean θ − θd over 10–60 s (deg), seeds 1–5: lowest … highest");
    print!("g (A/V) \\ h (W/(m²·K))");
    let hs = [30.0, 40.0, 54.0, 70.0, 90.0];
    for h in hs {
        print!(" | {h:>13}");
    }
    println!();
    for g in [0.9, 1.0, 1.2, 1.35, 1.5] {
        print!("{g:>22}");
        for h in hs {
            let e = (1..=5)
                .map(|s| mean_error_deg(s, g, h))
                .collect::<Result<Vec<_>, _>>()?;
            let lo = e.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            print!(" | {lo:+.3}…{hi:+.3}");
        }
        println!();
    }
    Ok(())
}
