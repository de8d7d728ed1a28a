//! The 3-element update against the SPEC §3 closed forms, the Rayleigh
//! shortcut against the general tensor form, and the DGFM static limit
//! (seed 002, requirement 2).
use firmware::linalg::{Mat3, Vec3};
use firmware::viscoelastic::*;

// Seed 002 Fig. 5's 3-element example: k1 = 1.5, k2 = 3.0, b = 0.5.
const K1: f64 = 1.5;
const K2: f64 = 3.0;
const B: f64 = 0.5;

fn model() -> ThreeElement<f64> {
    ThreeElement::new(K1, K2, B).unwrap()
}

/// Max |numeric − exact| over t ∈ (0, 1 s] for step `h`: `step` advances
/// the model by one step and returns its output, `exact` is the closed form.
fn max_error(
    h: f64,
    mut step: impl FnMut(&ThreeElement<f64>, &mut ThreeElementState<f64>, f64, TimeStep<f64>) -> f64,
    exact: impl Fn(f64) -> f64,
) -> f64 {
    let m = model();
    let mut s = ThreeElementState::default();
    let hs = TimeStep::new(h).unwrap();
    let n = (1.0 / h).round() as usize;
    (1..=n)
        .map(|k| {
            let t = k as f64 * h;
            (step(&m, &mut s, t, hs) - exact(t)).abs()
        })
        .fold(0.0, f64::max)
}

/// Creep under a step force F0 = 2: u(t) = F0/E1 + F0/E2 (1 − e^(−t/τc)).
fn creep_error(h: f64) -> f64 {
    let (f0, tau) = (2.0, B / K1);
    max_error(
        h,
        |m, s, _, hs| m.step_displacement(s, f0, hs),
        |t| f0 / K2 + f0 / K1 * (1.0 - (-t / tau).exp()),
    )
}

/// Relaxation under a step displacement u0 = 0.4.
fn relaxation_error(h: f64) -> f64 {
    let (u0, e_inf, tau) = (0.4, K1 * K2 / (K1 + K2), B / (K1 + K2));
    max_error(
        h,
        |m, s, _, hs| m.step_force(s, u0, hs),
        |t| u0 * (e_inf + (K2 - e_inf) * (-t / tau).exp()),
    )
}

/// Constant-velocity loading u = r·t, r = 0.7.
fn constant_velocity_error(h: f64) -> f64 {
    let (rate, e_inf, tau) = (0.7, K1 * K2 / (K1 + K2), B / (K1 + K2));
    max_error(
        h,
        |m, s, t, hs| m.step_force(s, rate * t, hs),
        |t| rate * (e_inf * t + (K2 - e_inf) * tau * (1.0 - (-t / tau).exp())),
    )
}

/// Halving h must roughly halve the error (first order), and the error at
/// the finest step must be small in absolute terms.
fn assert_first_order(name: &str, err: impl Fn(f64) -> f64, scale: f64) {
    let steps = [4e-3, 2e-3, 1e-3, 5e-4];
    let errors: Vec<f64> = steps.iter().map(|&h| err(h)).collect();
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!(
            (1.8..2.2).contains(&ratio),
            "{name}: error ratio {ratio} for halved h ({errors:?})"
        );
    }
    let finest = errors[errors.len() - 1];
    assert!(
        finest < 2e-3 * scale,
        "{name}: error {finest} at h = 5e-4 (scale {scale})"
    );
}

#[test]
fn creep_converges_to_the_closed_form_at_first_order() {
    assert_first_order("creep", creep_error, 2.0 / K1 + 2.0 / K2);
}

#[test]
fn relaxation_converges_to_the_closed_form_at_first_order() {
    assert_first_order("relaxation", relaxation_error, 0.4 * K2);
}

#[test]
fn constant_velocity_loading_converges_at_first_order() {
    assert_first_order("constant velocity", constant_velocity_error, 0.7 * K2);
}

#[test]
fn ratio_form_is_two_springs_in_series_equal_to_k() {
    let m = ThreeElement::from_ratio(4.0_f64, 2.5, 0.1).unwrap();
    assert!((m.relaxed_stiffness() - 4.0).abs() < 1e-12);
    assert!((m.k2() / m.k1() - 2.5).abs() < 1e-12, "r = k2/k1");
    assert!((m.b() - 0.4).abs() < 1e-12, "Rayleigh b·k");
}

#[test]
fn errors_read_as_sentences_not_variant_names() {
    assert_eq!(
        ViscoError::K1NotPositive.to_string(),
        "k1 (delayed spring) must be finite and > 0"
    );
    assert_eq!(
        ViscoError::StepNotPositive.to_string(),
        "the time step must be finite and > 0"
    );
}

#[test]
fn invalid_parameters_are_rejected_by_name() {
    assert_eq!(
        ThreeElement::new(0.0, 1.0, 1.0).err(),
        Some(ViscoError::K1NotPositive)
    );
    assert_eq!(
        ThreeElement::new(1.0, f64::NAN, 1.0).err(),
        Some(ViscoError::K2NotPositive)
    );
    assert_eq!(
        ThreeElement::new(1.0, 1.0, -1.0).err(),
        Some(ViscoError::DampingNegative)
    );
    assert_eq!(
        TimeStep::new(0.0_f64).err(),
        Some(ViscoError::StepNotPositive)
    );
    assert_eq!(
        TimeStep::new(f32::INFINITY).err(),
        Some(ViscoError::StepNotPositive)
    );
    assert_eq!(
        RayleighParams::new(-1.0_f64, 0.1).err(),
        Some(ViscoError::RatioNotPositive)
    );
    let singular = Mat3([[1.0_f64, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]]);
    let h = TimeStep::new(1e-3).unwrap();
    assert_eq!(
        ThreeElementTensor::from_dgfm_entry(singular, 1.0, 1.0, Mat3::zero(), h).err(),
        Some(ViscoError::SingularTensor)
    );
}

/// A symmetric positive definite 3×3 block with off-diagonal coupling.
fn spd_block(seed: f64) -> Mat3<f64> {
    let a = Mat3([
        [1.0 + 0.3 * seed.sin(), 0.2 * seed.cos(), 0.1],
        [0.05 * seed, 0.8, 0.15 * (2.0 * seed).sin()],
        [0.1, -0.1, 1.2 + 0.1 * seed.cos()],
    ]);
    (a * a.transpose()).scale(1e-3) // compliance: mm per unit traction
}

#[test]
fn rayleigh_shortcut_equals_the_general_tensor_form() {
    let xi = spd_block(0.7);
    let area = 0.35;
    let params = RayleighParams::new(2.5, 0.04).unwrap();
    let h = TimeStep::new(1e-3).unwrap();
    let k = xi.inverse().unwrap().scale(area);
    let damping = k.scale(params.b_s()); // B = b K (Eq. 11)
    let general =
        ThreeElementTensor::from_dgfm_entry(xi, area, params.ratio(), damping, h).unwrap();
    let (mut x_general, mut x_rayleigh) = (Vec3::zero(), Vec3::zero());
    let (mut xf_general, mut xf_rayleigh) = (Vec3::zero(), Vec3::zero());
    let mut worst = 0.0f64;
    for n in 0..3000 {
        let t = n as f64 * 1e-3;
        // A loading history with a ramp, a hold and a release.
        let mag = if t < 1.0 {
            t
        } else if t < 2.0 {
            1.0
        } else {
            0.0
        };
        let p = Vec3::new(mag, -0.5 * mag, 0.25 * mag * (3.0 * t).sin());
        let u_general = general.step_displacement(&mut x_general, p.scale(area)); // force f = α p
        let u_rayleigh = rayleigh_displacement_step(&xi, p, params, h, &mut x_rayleigh);
        let du = (u_general - u_rayleigh).max_abs() / u_general.max_abs().max(1e-12);
        // Force from displacement, both ways.
        let u_in = Vec3::new(0.01 * mag, 0.004 * mag, -0.002 * mag);
        let f_general = general.step_force(&mut xf_general, u_in);
        let f_rayleigh = rayleigh_force_step(&k, u_in, params, h, &mut xf_rayleigh);
        let df = (f_general - f_rayleigh).max_abs() / f_general.max_abs().max(1e-12);
        worst = worst.max(du).max(if mag > 0.0 { df } else { 0.0 });
    }
    assert!(worst < 1e-9, "relative difference {worst}");
}

const N: usize = 12;

/// A test DGFM, column-major (`xi[j·N + i] = Ξ_ij`), with its blocks also
/// addressable as `block(i, j)`.
fn test_dgfm() -> Vec<Mat3<f64>> {
    let mut xi = vec![Mat3::zero(); N * N];
    for j in 0..N {
        for i in 0..N {
            // Self-compliance dominates; coupling decays with index distance.
            let d = (i as f64 - j as f64).abs();
            xi[j * N + i] = spd_block((i * N + j) as f64 * 0.37).scale(1.0 / (1.0 + d * d));
        }
    }
    xi
}

fn column_params() -> [RayleighParams<f64>; N] {
    core::array::from_fn(|j| {
        RayleighParams::new(0.5 + 0.25 * j as f64, 0.01 + 0.01 * (j % 4) as f64).unwrap()
    })
}

#[test]
fn static_limit_equals_the_dgfm_product() {
    let xi = test_dgfm();
    let params = column_params();
    let mut buffers = DgfmBuffers::<f64, N, 3>::default();
    let mut model = buffers
        .dgfm(RayleighColumns::new(&xi, &params).unwrap())
        .unwrap();
    let loads = [
        (2, Vec3::new(1.0, 0.0, -0.5)),
        (7, Vec3::new(0.0, 2.0, 0.0)),
        (11, Vec3::new(-0.3, 0.3, 1.0)),
    ];
    for (j, p) in loads {
        model.set_traction(j, p).unwrap();
    }
    let h = TimeStep::new(1e-3).unwrap();
    let mut u = [Vec3::zero(); N];
    for _ in 0..20_000 {
        model.step(h, &mut u).unwrap();
    }
    // Independent evaluation of Σ_j Ξ_ij p_j.
    for (i, ui) in u.iter().enumerate() {
        let mut expect = Vec3::zero();
        for (j, p) in loads {
            expect = expect + xi[j * N + i].mul_vec(p);
        }
        let rel = (*ui - expect).max_abs() / expect.max_abs();
        assert!(rel < 1e-9, "vertex {i}: relative error {rel}");
    }
    let mut stat = [Vec3::zero(); N];
    model.update().static_displacement(&loads, &mut stat);
    assert!((stat[4] - u[4]).max_abs() / stat[4].max_abs() < 1e-9);
}

#[test]
fn dgfm_transient_equals_the_sum_of_pairwise_updates() {
    let xi = test_dgfm();
    let params = column_params();
    let mut buffers = DgfmBuffers::<f64, N, 2>::default();
    let mut model = buffers
        .dgfm(RayleighColumns::new(&xi, &params).unwrap())
        .unwrap();
    // Threshold 0: columns stay active until exactly at rest, so the result
    // must equal the pairwise sum exactly (the 1e-3 rest threshold has its
    // own test below).
    model.set_rest_threshold(0.0).unwrap();
    let mut x = vec![[Vec3::zero(); N]; 2];
    let cols = [3usize, 9];
    let h = TimeStep::new(2e-3).unwrap();
    let mut u = [Vec3::zero(); N];
    for n in 0..400 {
        let p = [
            Vec3::new(0.01 * n as f64, 0.0, 0.0),
            Vec3::new(0.0, 0.0, if n < 200 { 1.0 } else { 0.0 }),
        ];
        for (c, pj) in cols.iter().zip(p) {
            model.set_traction(*c, pj).unwrap();
        }
        model.step(h, &mut u).unwrap();
        for (i, ui) in u.iter().enumerate() {
            let mut expect = Vec3::zero();
            for (k, (c, pj)) in cols.iter().zip(p).enumerate() {
                expect = expect
                    + rayleigh_displacement_step(&xi[*c * N + i], pj, params[*c], h, &mut x[k][i]);
            }
            assert!(
                (*ui - expect).max_abs() <= 1e-12 * expect.max_abs().max(1.0),
                "step {n} vertex {i}"
            );
        }
    }
}

#[test]
fn tensor_columns_are_the_seeds_form_on_the_diagonal_and_rayleigh_for_b_k() {
    let xi = test_dgfm();
    let params = column_params();
    let areas: Vec<f64> = (0..N).map(|j| 1e-4 * (1.0 + j as f64)).collect();
    let h = TimeStep::new(1e-3).unwrap();
    let stiffness = |j: usize| xi[j * N + j].inverse().unwrap().scale(areas[j]);
    // B_j = b_j K_jj: the Rayleigh form on every pair.
    let rayleigh_b: Vec<TensorColumn<f64>> = (0..N)
        .map(|j| {
            TensorColumn::new(
                stiffness(j),
                stiffness(j).scale(params[j].b_s()),
                params[j].ratio(),
                h,
            )
            .unwrap()
        })
        .collect();
    let mut rb = DgfmBuffers::<f64, N, 2>::default();
    let mut tb = DgfmBuffers::<f64, N, 2>::default();
    let mut ray = rb
        .dgfm(RayleighColumns::new(&xi, &params).unwrap())
        .unwrap();
    let mut ten = tb
        .dgfm(TensorColumns::new(&xi, &rayleigh_b).unwrap())
        .unwrap();
    let (mut ur, mut ut) = ([Vec3::zero(); N], [Vec3::zero(); N]);
    for n in 0..300 {
        if n == 0 {
            ray.set_traction(4, Vec3::new(0.5, -1.0, 2.0)).unwrap();
            ten.set_traction(4, Vec3::new(0.5, -1.0, 2.0)).unwrap();
        }
        if n == 150 {
            ray.release_all();
            ten.release_all();
        }
        ray.step(h, &mut ur).unwrap();
        ten.step(h, &mut ut).unwrap();
        for i in 0..N {
            assert!(
                (ur[i] - ut[i]).max_abs() <= 1e-9 * ur[i].max_abs().max(1e-12),
                "step {n} vertex {i}: {:?} vs {:?}",
                ur[i],
                ut[i]
            );
        }
    }
    // A general tensor: on the diagonal pair the column is the seed's own
    // tensor update (Eq. 6, f = α p, K = α Ξ⁻¹).
    let j = 4;
    let b = spd_block(3.1).scale(0.02);
    let general = [TensorColumn::new(stiffness(j), b, params[j].ratio(), h).unwrap(); N];
    let pair =
        ThreeElementTensor::from_dgfm_entry(xi[j * N + j], areas[j], params[j].ratio(), b, h)
            .unwrap();
    let mut gb = DgfmBuffers::<f64, N, 1>::default();
    let mut gen = gb.dgfm(TensorColumns::new(&xi, &general).unwrap()).unwrap();
    let (mut ug, mut x) = ([Vec3::zero(); N], Vec3::zero());
    let p = Vec3::new(0.2, 0.7, -1.1);
    gen.set_traction(j, p).unwrap();
    for n in 0..200 {
        gen.step(h, &mut ug).unwrap();
        let want = pair.step_displacement(&mut x, p.scale(areas[j]));
        assert!(
            (ug[j] - want).max_abs() <= 1e-9 * want.max_abs(),
            "step {n}: {:?} vs {want:?}",
            ug[j]
        );
    }
    // A column precomputed for one step refuses another.
    assert_eq!(
        ten.step(TimeStep::new(2e-3).unwrap(), &mut ut),
        Err(ViscoError::StepMismatch)
    );
}

#[test]
fn released_columns_relax_and_leave_the_active_list() {
    let xi = test_dgfm();
    let params = column_params();
    let mut buffers = DgfmBuffers::<f64, N, 2>::default();
    let mut model = buffers
        .dgfm(RayleighColumns::new(&xi, &params).unwrap())
        .unwrap();
    // Traction large enough that displacements are well above 1e-3.
    model.set_traction(5, Vec3::new(0.0, 0.0, 50.0)).unwrap();
    model.set_traction(6, Vec3::new(50.0, 0.0, 0.0)).unwrap();
    assert_eq!(
        model.set_traction(7, Vec3::new(1.0, 0.0, 0.0)),
        Err(ViscoError::ActiveListFull)
    );
    assert_eq!(
        model.set_traction(N, Vec3::new(1.0, 0.0, 0.0)),
        Err(ViscoError::VertexOutOfRange)
    );
    assert_eq!(
        model.set_traction(1, Vec3::new(f64::NAN, 0.0, 0.0)),
        Err(ViscoError::NonFiniteInput)
    );
    let h = TimeStep::new(1e-3).unwrap();
    let mut u = [Vec3::zero(); N];
    for _ in 0..500 {
        model.step(h, &mut u).unwrap();
    }
    assert!(u[5].max_abs() > 1e-3, "loaded displacement {:?}", u[5]);
    model.release_all();
    model.step(h, &mut u).unwrap();
    assert_eq!(
        model.active_count(),
        2,
        "still relaxing right after release"
    );
    let mut steps = 0;
    while model.active_count() > 0 && steps < 100_000 {
        model.step(h, &mut u).unwrap();
        steps += 1;
    }
    assert_eq!(model.active_count(), 0, "never came to rest");
    // At rest means every remaining displacement effect was below 1e-3.
    model.step(h, &mut u).unwrap();
    assert!(u.iter().all(|v| v.is_zero()));
    // A slot is free again.
    model.set_traction(7, Vec3::new(1.0, 0.0, 0.0)).unwrap();
    // Wrong sizes are errors, not panics.
    assert_eq!(model.step(h, &mut u[1..]), Err(ViscoError::StorageMismatch));
    let mut slots = [ColumnSlot::default(); 2];
    let mut states = vec![Vec3::zero(); 2 * N - 1];
    assert!(ViscoDgfm::new(
        RayleighColumns::new(&xi, &params).unwrap(),
        &mut slots,
        &mut states
    )
    .is_err());
    assert!(RayleighColumns::new(&xi[1..], &params).is_err());
}

#[test]
fn single_precision_tracks_double_precision() {
    // The board runs f32: over a 2 s creep at 1 kHz it must stay within
    // 1e-5 relative of the f64 answer.
    let m32 = ThreeElement::new(K1 as f32, K2 as f32, B as f32).unwrap();
    let m64 = model();
    let (mut s32, mut s64) = (ThreeElementState::default(), ThreeElementState::default());
    let (h32, h64) = (
        TimeStep::new(1e-3_f32).unwrap(),
        TimeStep::new(1e-3_f64).unwrap(),
    );
    for _ in 0..2000 {
        let a = m32.step_displacement(&mut s32, 2.0, h32) as f64;
        let b = m64.step_displacement(&mut s64, 2.0, h64);
        assert!((a - b).abs() <= 1e-5 * b.abs(), "{a} vs {b}");
    }
}
