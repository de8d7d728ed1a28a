//! Plant speed at a 1 kHz control rate: one `step(1 ms)` of the 2D and 3D
//! joints, driven by the paper's antagonistic P law on the true angle (a
//! stand-in for the controller, so the link keeps moving and the wires get
//! pushed and pulled). Real-time factor = 1 ms / (time per step).
//!
//! `cargo bench -p plant-models --bench joint`

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use plant_joint::{Joint2d, Joint2dParams, Joint3d, Joint3dParams};

fn p_law(angle: f64, target: f64) -> [f64; 2] {
    let e = angle - target;
    if e < 0.0 {
        [1.7 - 2.0 * e, 0.0]
    } else {
        [0.0, 1.7 + 2.0 * e]
    }
}

/// Target that steps between −10°, 0° and 10° every 3 s of plant time.
fn target(k: u64) -> f64 {
    [0.0, 10.0, 0.0, -10.0][((k / 3000) % 4) as usize]
}

fn bench(c: &mut Criterion) {
    let mut j2 = Joint2d::new(Joint2dParams::default()).unwrap();
    let mut k2 = 0u64;
    c.bench_function("joint2d_step_1ms", |b| {
        b.iter(|| {
            let v = p_law(j2.angle_deg(), target(k2));
            j2.step(black_box(1e-3), &v).unwrap();
            k2 += 1;
        })
    });
    let mut j3 = Joint3d::new(Joint3dParams::default()).unwrap();
    let mut k3 = 0u64;
    c.bench_function("joint3d_step_1ms", |b| {
        b.iter(|| {
            let [a, be] = j3.angles_deg();
            let t = target(k3);
            let va = p_law(a, t);
            let vb = p_law(be, -t);
            j3.step(black_box(1e-3), &[va[0], vb[0], va[1], vb[1]])
                .unwrap();
            k3 += 1;
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
