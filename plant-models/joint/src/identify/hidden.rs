//! The hidden plants of the twin tests: the defaults with every parameter
//! identification fits moved by 20–50 %, more sensor noise, and jamming on.
//! What identification must find without being told.

use rand::Rng;

use crate::{Joint2dParams, Joint3dParams, PlaneParams, SupportParams, WireSensorParams};

/// The factors (hidden / default) of the twin tests, with the slope set
/// absolutely (its default is 0). Temperatures move as `ambient + f·(T −
/// ambient)`.
pub const FACTORS: &[(&str, f64)] = &[
    ("driver.transconductance_a_v", 0.75),
    ("coil.convection_w_m2_k", 1.3),
    ("coil temperatures above ambient", 0.8),
    ("support.youngs_modulus_pa", 1.4),
    ("support.rayleigh_damping_s", 0.7),
    ("link.inertia_kg_m2", 1.5),
    ("wires.jam.buckling_gain", 1.4),
    ("wires.jam.max_lag_mm", 0.7),
    ("wires.jam.max_lag_per_mm", 1.33),
];

/// Hidden Clausius–Clapeyron slope (K/MPa): inside the 0.07–0.14 NiTi range.
pub const HIDDEN_STRESS_SHIFT_K_PER_MPA: f64 = 0.08;

/// Camera angle noise of the hidden plant (deg; the default is 0.03).
pub const HIDDEN_CAMERA_NOISE_DEG: f64 = 0.1;

fn factor(name: &str) -> f64 {
    FACTORS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|f| f.1)
        .unwrap_or(1.0)
}

/// One plane of the hidden plant; `scale` multiplies every perturbation
/// (1 for α, another value for β so the planes differ).
pub fn plane(mut p: PlaneParams, scale: f64) -> PlaneParams {
    let f = |name: &str| 1.0 + scale * (factor(name) - 1.0);
    p.driver.transconductance_a_v *= f("driver.transconductance_a_v");
    p.coil.convection_w_m2_k *= f("coil.convection_w_m2_k");
    let amb = p.coil.ambient_c;
    let ft = f("coil temperatures above ambient");
    for t in [
        &mut p.coil.austenite_start_c,
        &mut p.coil.austenite_finish_c,
        &mut p.coil.martensite_start_c,
        &mut p.coil.martensite_finish_c,
    ] {
        *t = amb + ft * (*t - amb);
    }
    p.coil.stress_shift_k_per_mpa = HIDDEN_STRESS_SHIFT_K_PER_MPA;
    if let SupportParams::Cartilage(c) = &mut p.support {
        c.youngs_modulus_pa *= f("support.youngs_modulus_pa");
        c.rayleigh_damping_s *= f("support.rayleigh_damping_s");
    }
    p.link.inertia_kg_m2 *= f("link.inertia_kg_m2");
    p
}

fn wire(mut w: WireSensorParams) -> WireSensorParams {
    w.jam.buckling_gain *= factor("wires.jam.buckling_gain");
    w.jam.max_lag_mm *= factor("wires.jam.max_lag_mm");
    w.jam.max_lag_per_mm *= factor("wires.jam.max_lag_per_mm");
    w
}

/// The hidden 2D joint, seeded.
pub fn joint_2d(seed: u64) -> Joint2dParams {
    let mut p = Joint2dParams::default();
    p.plane = plane(p.plane, 1.0);
    p.wire = wire(p.wire);
    p.camera.angle_noise_deg = HIDDEN_CAMERA_NOISE_DEG;
    p.sim.seed = seed;
    p
}

/// The hidden 3D joint, seeded: α as the 2D one, β with the perturbations
/// scaled by 0.6 (so it differs from α).
pub fn joint_3d(seed: u64) -> Joint3dParams {
    let mut p = Joint3dParams::default();
    p.alpha = plane(p.alpha, 1.0);
    p.beta = plane(p.beta, 0.6);
    p.wires = p.wires.map(wire);
    p.camera.angle_noise_deg = HIDDEN_CAMERA_NOISE_DEG;
    p.sim.seed = seed;
    p
}

/// The joint of issue 28: the defaults moved by 5–20 % in directions the
/// twins above do not take, α's driver turning on at 2.0 V, above the
/// standard plan's sustained levels (1.85 and 1.9 V) and its ramp, so
/// that α's coils conduct only in the saturated pulses and its driver's
/// turn-on cannot be regressed; β's driver turns on at 1.6 V, inside the
/// plan's levels. h +10 % (α) / +8 % (β), the transformation temperatures
/// moved by +1 K (α) / −2 K (β), a slope of 0.08 / 0.075 K/MPa, the
/// sponge's modulus −15 % / −10 % and damping +20 % / +10 %; camera noise
/// 0.05° (the lab camera), jamming as the defaults. On the 240 s
/// standard plan, identification before issue 28 called α's g, h, the
/// four temperatures and the slope identifiable 4.6–25.6 σ from the truth
/// (slope −74 %), with a held-out rms of 0.062° against 0.05° of noise.
pub fn off_plan_joint_3d(seed: u64) -> Joint3dParams {
    let mut p = Joint3dParams::default();
    let shift = |mut q: PlaneParams, v_on: f64, h: f64, dt: f64, slope: f64, e: f64, d: f64| {
        q.driver.turn_on_v = v_on;
        q.coil.convection_w_m2_k *= h;
        for t in [
            &mut q.coil.austenite_start_c,
            &mut q.coil.austenite_finish_c,
            &mut q.coil.martensite_start_c,
            &mut q.coil.martensite_finish_c,
        ] {
            *t += dt;
        }
        q.coil.stress_shift_k_per_mpa = slope;
        if let SupportParams::Cartilage(c) = &mut q.support {
            c.youngs_modulus_pa *= e;
            c.rayleigh_damping_s *= d;
        }
        q
    };
    p.alpha = shift(p.alpha, 2.0, 1.1, 1.0, 0.08, 0.85, 1.2);
    p.beta = shift(p.beta, 1.6, 1.08, -2.0, 0.075, 0.9, 1.1);
    p.camera.angle_noise_deg = 0.05;
    p.sim.seed = seed;
    p
}

/// One plane of issue 28's campaign distribution (see [`campaign_joint_3d`]).
fn campaign_plane(mut p: PlaneParams, rng: &mut impl Rng) -> PlaneParams {
    let mut f = |lo: f64, hi: f64| lo + (hi - lo) * rng.gen::<f64>();
    p.driver.turn_on_v = f(1.5, 2.1);
    p.driver.transconductance_a_v *= f(0.8, 1.2);
    p.coil.convection_w_m2_k *= f(0.8, 1.2);
    let dt = f(-5.0, 5.0);
    for t in [
        &mut p.coil.austenite_start_c,
        &mut p.coil.austenite_finish_c,
        &mut p.coil.martensite_start_c,
        &mut p.coil.martensite_finish_c,
    ] {
        *t += dt;
    }
    p.coil.stress_shift_k_per_mpa = f(0.03, 0.14);
    let (e, d) = (f(0.8, 1.2), f(0.8, 1.2));
    if let SupportParams::Cartilage(c) = &mut p.support {
        c.youngs_modulus_pa *= e;
        c.rayleigh_damping_s *= d;
    }
    p
}

/// Hidden 3D joint number `k` of issue 28's seeded twin campaign
/// (`examples/identify_campaign.rs`), drawn per plane, independently,
/// from `rng::stream(k, rng::IDENTIFY_SAMPLE)`: the driver's turn-on
/// uniform in 1.5–2.1 V (the plausible range of a ULN2003 stage's input
/// threshold, across the standard plan's 1.85 and 1.9 V levels), its
/// transconductance × U(0.8, 1.2), h × U(0.8, 1.2), the four
/// transformation temperatures shifted together by U(−5, +5) K, the
/// Clausius–Clapeyron slope U(0.03, 0.14) K/MPa, the sponge's modulus and
/// damping × U(0.8, 1.2) each; camera noise 0.05°, jamming at the
/// defaults; the plant's own seed 1000 + `k`. The campaign runs twins
/// 0..20 by default; tests take theirs from elsewhere (k ≥ 100), so the
/// campaign is never judged on a twin a check was written against.
pub fn campaign_joint_3d(k: u64) -> Joint3dParams {
    let mut rng = plant_common::rng::stream(k, plant_common::rng::IDENTIFY_SAMPLE);
    let mut p = Joint3dParams::default();
    p.alpha = campaign_plane(p.alpha, &mut rng);
    p.beta = campaign_plane(p.beta, &mut rng);
    p.camera.angle_noise_deg = 0.05;
    p.sim.seed = 1000 + k;
    p
}

/// What identifying plane `plane` (0: α, 1: β) of the hidden joint `j`
/// aims at: its plane and its wire sensor, with the settle time and substep
/// the twins and the campaign judge estimates against.
pub fn plane_truth(j: &Joint3dParams, plane: usize) -> super::PlaneModel {
    let (p, wire) = if plane == 0 {
        (&j.alpha, &j.wires[0])
    } else {
        (&j.beta, &j.wires[1])
    };
    super::PlaneModel {
        plane: p.clone(),
        wires: vec![wire.clone()],
        settle_s: 1.0,
        substep_s: 1e-3,
    }
}
