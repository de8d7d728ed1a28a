//! The firmware's no_std 3-element updates (seed 002's implicit first-order
//! scheme) against the plant's independent, exact integration of the same
//! model, on the same loads: the scalar model in both directions, a general
//! tensor pair, the Rayleigh pair, and the whole DGFM of the shipped
//! 198-vertex object under a random load history, with Rayleigh and tensor
//! columns. The firmware's error must shrink as O(h): halving the step
//! halves it.
use std::sync::OnceLock;

use firmware::linalg::{Mat3 as CoreMat3, Vec3 as CoreVec3};
use firmware::viscoelastic::{
    rayleigh_displacement_step, RayleighParams, ThreeElement, ThreeElementState,
    ThreeElementTensor, TimeStep,
};
use host_tools::visco_core::CoreObject;
use plant_common::three_element::{Element, RayleighColumn, StepLength, TensorPair};
use plant_viscoelastic::{ColumnParams, Dgfm, Mat3, TractionModel, Vec3, ViscoObject};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Steps (s) of the convergence study: 2 ms down to 0.25 ms.
const STEPS_S: [f64; 4] = [2e-3, 1e-3, 5e-4, 2.5e-4];

/// Halving h must roughly halve the error (first order).
fn assert_first_order(name: &str, errors: &[f64]) {
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (1.7..2.3).contains(&ratio),
            "{name}: error ratio {ratio:.3} for a halved step ({errors:?})"
        );
    }
}

fn core_mat(m: &Mat3) -> CoreMat3<f64> {
    CoreMat3(core::array::from_fn(|r| {
        core::array::from_fn(|c| m[(r, c)])
    }))
}

fn core_vec(v: &Vec3) -> CoreVec3<f64> {
    CoreVec3([v[0], v[1], v[2]])
}

// Seed 002 Fig. 5's example: k1 = 1.5, k2 = 3.0, b = 0.5.
const K1: f64 = 1.5;
const K2: f64 = 3.0;
const B: f64 = 0.5;

/// A load of ramps and holds: 0 → 1 over 0.3 s, held to 0.6 s, then a
/// step down to 0.25 held to 1 s (exact for the plant at every step).
fn ramp_hold(t: f64) -> f64 {
    if t < 0.3 {
        t / 0.3
    } else if t < 0.6 {
        1.0
    } else {
        0.25
    }
}

/// Max |firmware − plant| over (0, 1 s] for the scalar model at step `h`:
/// creep (force in) or relaxation (displacement in) under `load`.
fn scalar_error(h: f64, creep: bool, load: impl Fn(f64) -> f64) -> f64 {
    let core = ThreeElement::new(K1, K2, B).unwrap();
    let plant = Element::new(K1, K2, B).unwrap();
    let len = StepLength::new(h).unwrap();
    let exact = if creep {
        plant.creep_step(len)
    } else {
        plant.relaxation_step(len)
    };
    let hs = TimeStep::new(h).unwrap();
    let (mut sc, mut xp) = (ThreeElementState::default(), 0.0);
    let n = (1.0 / h).round() as usize;
    let mut worst = 0.0f64;
    // Loads are right-continuous: `load(t)` is the value just after t. The
    // step from t₀ to t₁ runs from load(t₀) to the value just before t₁
    // (linearly for the plant; the firmware's implicit step uses the end
    // value), so a jump at t₁ belongs to the next step for both.
    for k in 1..=n {
        let (t0, t) = ((k - 1) as f64 * h, k as f64 * h);
        let (start, end) = (load(t0), load(t - 1e-12));
        let v = end;
        let (a, b) = if creep {
            (
                core.step_displacement(&mut sc, v, hs),
                exact.displacement(&mut xp, start, end),
            )
        } else {
            (
                core.step_force(&mut sc, v, hs),
                exact.force(&mut xp, start, end),
            )
        };
        worst = worst.max((a - b).abs());
    }
    worst
}

#[test]
fn scalar_creep_relaxation_and_ramp_hold_converge_to_the_plant_at_first_order() {
    for (name, creep, load) in [
        ("creep", true, (|_| 2.0) as fn(f64) -> f64),
        ("relaxation", false, |_| 0.4),
        ("ramp-hold force", true, ramp_hold),
        ("ramp-hold displacement", false, ramp_hold),
    ] {
        let errors: Vec<f64> = STEPS_S
            .iter()
            .map(|&h| scalar_error(h, creep, load))
            .collect();
        assert_first_order(name, &errors);
        assert!(errors[3] < 2e-3, "{name}: {errors:?}");
    }
}

/// A symmetric positive definite 3×3 tensor.
fn spd(seed: f64, scale: f64) -> Mat3 {
    let a = Mat3::new(
        1.0,
        0.3 * seed.sin(),
        0.1,
        0.2,
        1.0 + 0.2 * seed.cos(),
        -0.15,
        0.05,
        0.1,
        1.0,
    );
    (a * a.transpose() + Mat3::identity() * 0.5) * scale
}

/// A random piecewise-constant force history (changes every 50 ms).
fn history(seed: u64, duration_s: f64) -> Vec<Vec3> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..(duration_s / 0.05).round() as usize)
        .map(|_| {
            Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-2.0..0.5),
            )
        })
        .collect()
}

fn tensor_error(h: f64) -> f64 {
    let (k1, k2, b) = (spd(1.0, 1.5), spd(2.0, 3.0), spd(3.0, 0.4));
    let core = ThreeElementTensor::new(
        core_mat(&k1),
        core_mat(&k2),
        core_mat(&b),
        TimeStep::new(h).unwrap(),
    )
    .unwrap();
    let plant = TensorPair::new(k1, k2, b, StepLength::new(h).unwrap()).unwrap();
    let forces = history(7, 1.0);
    let (mut xc, mut xp) = (CoreVec3::zero(), Vec3::zeros());
    let per = (0.05 / h).round() as usize;
    let mut worst = 0.0f64;
    for f in forces.iter().flat_map(|f| std::iter::repeat_n(f, per)) {
        let uc = core.step_displacement(&mut xc, core_vec(f));
        let up = plant.displacement(&mut xp, *f, *f);
        worst = worst.max((Vec3::from(uc.0) - up).amax());
    }
    worst
}

#[test]
fn a_general_tensor_pair_converges_to_the_plant_at_first_order() {
    let errors: Vec<f64> = STEPS_S.iter().map(|&h| tensor_error(h)).collect();
    assert_first_order("tensor pair", &errors);
}

fn rayleigh_error(h: f64) -> f64 {
    let xi = spd(4.0, 1e-4);
    let (r, b) = (0.8, 0.06);
    let core = RayleighParams::new(r, b).unwrap();
    let plant = RayleighColumn::new(r, b)
        .unwrap()
        .step(StepLength::new(h).unwrap());
    let hs = TimeStep::new(h).unwrap();
    let per = (0.05 / h).round() as usize;
    let (mut xc, mut xp) = (CoreVec3::zero(), Vec3::zeros());
    let mut worst = 0.0f64;
    for p in history(9, 1.0)
        .iter()
        .flat_map(|p| std::iter::repeat_n(p, per))
    {
        let uc = rayleigh_displacement_step(&core_mat(&xi), core_vec(p), core, hs, &mut xc);
        let y = xi * p;
        let up = plant.displacement(&mut xp, y, y);
        worst = worst.max((Vec3::from(uc.0) - up).amax());
    }
    worst
}

#[test]
fn the_rayleigh_pair_converges_to_the_plant_at_first_order() {
    let errors: Vec<f64> = STEPS_S.iter().map(|&h| rayleigh_error(h)).collect();
    assert_first_order("Rayleigh pair", &errors);
}

fn object() -> &'static Dgfm {
    static D: OnceLock<Dgfm> = OnceLock::new();
    D.get_or_init(|| Dgfm::default_object().expect("default object"))
}

/// Per-column Rayleigh parameters varying over the object (§4.2
/// spreading), slow enough that 2 ms is in the asymptotic regime.
fn rayleigh_columns(n: usize) -> ColumnParams {
    ColumnParams::Rayleigh(
        (0..n)
            .map(|j| {
                RayleighColumn::new(0.5 + 0.25 * (j % 7) as f64, 0.08 + 0.03 * (j % 5) as f64)
                    .unwrap()
            })
            .collect(),
    )
}

/// General damping tensors: a Rayleigh part plus an anisotropic one.
fn tensor_columns(d: &Dgfm) -> ColumnParams {
    let n = d.len();
    ColumnParams::Tensor {
        ratios: (0..n).map(|j| 0.6 + 0.2 * (j % 4) as f64).collect(),
        damping_n_s_per_m: (0..n)
            .map(|j| {
                d.stiffness(j, j).unwrap() * 0.1 + Mat3::from_diagonal(&Vec3::new(30.0, 10.0, 20.0))
            })
            .collect(),
    }
}

/// Max |firmware − plant| over every traction vertex and step of a random
/// traction history (six columns, tractions changing every 50 ms for 1 s,
/// some released) on the 198-vertex object, relative to max |plant|.
fn object_error(params: &ColumnParams, h: f64) -> f64 {
    let d = object();
    let mut plant = ViscoObject::new(d.clone(), params.clone(), h).unwrap();
    let mut core = CoreObject::new(d.clone(), params, h).unwrap();
    // Columns leave the active lists only when exactly at rest, so the
    // comparison sees the update and not the lists' cut-off.
    plant.set_rest_threshold_m(0.0).unwrap();
    core.set_rest_threshold_m(0.0).unwrap();
    let n = d.len();
    let mut rng = ChaCha8Rng::seed_from_u64(2004);
    let columns: Vec<usize> = (0..6).map(|_| rng.gen_range(0..n)).collect();
    let per = (0.05 / h).round() as usize;
    let (mut up, mut uc) = (vec![Vec3::zeros(); n], vec![Vec3::zeros(); n]);
    let (mut worst, mut scale) = (0.0f64, 0.0f64);
    for _change in 0..20 {
        for &j in &columns {
            let p = if rng.gen_bool(0.2) {
                Vec3::zeros()
            } else {
                Vec3::new(
                    rng.gen_range(-300.0..300.0),
                    rng.gen_range(-300.0..300.0),
                    rng.gen_range(-2e3..0.0),
                )
            };
            plant.set_traction(j, p).unwrap();
            core.set_traction(j, p).unwrap();
        }
        for _ in 0..per {
            plant.step(h, &mut up).unwrap();
            core.step(h, &mut uc).unwrap();
            for (a, b) in uc.iter().zip(&up) {
                worst = worst.max((a - b).amax());
                scale = scale.max(b.amax());
            }
        }
    }
    worst / scale
}

#[test]
fn the_object_dgfm_converges_to_the_plant_at_first_order_under_a_random_load_history() {
    let d = object();
    for (name, params) in [
        ("Rayleigh", rayleigh_columns(d.len())),
        ("tensor", tensor_columns(d)),
    ] {
        // Three steps (2, 1, 0.5 ms) keep this under half a minute unoptimised.
        let errors: Vec<f64> = STEPS_S[..3]
            .iter()
            .map(|&h| object_error(&params, h))
            .collect();
        println!("{name} columns: relative error {errors:?}");
        assert_first_order(name, &errors);
        assert!(errors[1] < 0.02, "{name}: {errors:?} at 1 ms");
    }
}
