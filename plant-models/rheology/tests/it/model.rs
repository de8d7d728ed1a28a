//! The rheology lattice against closed forms (issue 14, first must-show
//! group): one basic element's creep, recovery, permanent set and
//! relaxation; a lattice column at rest and creeping under gravity; the
//! explicit Euler's stability bound.
use plant_rheology::contact::{ContactParams, Contacts, Schedule};
use plant_rheology::element::{
    creep_elongation_m, creep_recovery_elongation_m, permanent_elongation_m, ramp_hold_force_n,
    ElementConstants,
};
use plant_rheology::lattice::{ElementDef, Lattice, VolumeMode, V3};
use plant_rheology::params::{ElementClass, ElementParams, LatticeParams};
use plant_rheology::sim::{Integrator, LatticeSim, NodeDrive, SimSettings};
use plant_rheology::{Instability, RheologyError};

/// The paper's defaults on a 1 cm voxel: k = 980.665 N/m, c1 = c2 =
/// 3922.66 N·s/m, retardation 4 s.
fn paper_element() -> ElementConstants {
    ElementConstants::from_params(&ElementParams::PAPER_DEFAULT, 0.01, 1.0)
}

/// Two masses 1 cm apart along x, high above the table, one element.
fn single_element() -> Lattice {
    Lattice::custom(
        vec![V3::new(0.0, 1.0, 0.0), V3::new(0.01, 1.0, 0.0)],
        vec![ElementDef {
            i: 0,
            j: 1,
            rest_m: 0.01,
            class: ElementClass::SurfaceOn,
            weight: 1.0,
        }],
        0.01,
    )
}

fn no_contacts(n: usize) -> Contacts {
    Contacts::new(
        ContactParams::default(),
        None,
        vec![1e-4; n],
        [0.01, 0.01],
        vec![],
    )
    .unwrap()
}

fn settings(integrator: Integrator, dt_s: f64) -> SimSettings {
    SimSettings {
        integrator,
        dt_s,
        gravity_m_s2: 0.0,
        // Momentum balance, and so the flow's F·T/c2, holds per step to
        // the solve's tolerance: at the default 1e-7 a warm-started step
        // whose residual is already below it takes no iteration, and the
        // flow drifts by 2e-8 of itself over 1500 steps.
        tolerance: 1e-13,
        ..SimSettings::default()
    }
}

/// Force F on mass 1 for T, then released; returns (t, elongation) per
/// step and the flow q of the element at the end.
fn creep_and_release(
    integrator: Integrator,
    total_mass_kg: f64,
    dt_s: f64,
    force_n: f64,
    hold_steps: usize,
    end_s: f64,
) -> (Vec<(f64, f64)>, f64, f64) {
    let lat = single_element();
    let c = paper_element();
    let mut sim = LatticeSim::new(
        &lat,
        vec![c],
        total_mass_kg,
        settings(integrator, dt_s),
        no_contacts(2),
    )
    .unwrap();
    sim.drive(NodeDrive::pin(0, lat.rest_m[0], [true; 3]))
        .unwrap();
    sim.set_external_force(1, V3::new(force_n, 0.0, 0.0));
    let mut out = Vec::new();
    let steps = (end_s / dt_s).round() as usize;
    for s in 1..=steps {
        if s == hold_steps + 1 {
            sim.set_external_force(1, V3::zeros());
        }
        let r = sim.step().unwrap();
        out.push((r.t_s, sim.positions()[1].x - 0.01));
    }
    let v = sim.velocities()[1].x;
    (out, sim.flow_m()[0], v)
}

#[test]
fn one_element_keeps_exactly_f_t_over_c2_and_creeps_and_recovers_as_its_closed_form() {
    let c = paper_element();
    let (f, dt) = (2.0, 0.002);
    let hold_steps = 1500; // T = 3 s
    let t_hold = hold_steps as f64 * dt;
    // Implicit Euler, physical mass (1 g per mass: overdamped by 1e6).
    let (curve, q, v) = creep_and_release(Integrator::ImplicitEuler, 2e-3, dt, f, hold_steps, 60.0);
    let permanent = permanent_elongation_m(&c, f, t_hold);
    assert!((permanent - 1.5295e-3).abs() < 1e-7, "{permanent}");
    // The flow is F·T/c2 exactly, up to the momentum m·v still in the mass.
    let momentum_term = 1e-3 * v / c.c2_ns_per_m;
    assert!(
        (q - permanent).abs() <= 1e-12 * permanent + momentum_term.abs() + 1e-18,
        "flow {q} vs F·T/c2 {permanent}"
    );
    // The elongation after the Voigt part has relaxed (57 s ≈ 14 retardation times).
    let last = curve.last().unwrap().1;
    assert!(
        (last - permanent).abs() < 1e-6 * permanent,
        "final elongation {last} vs {permanent}"
    );
    // Creep and recovery against the closed form: backward Euler's O(dt/τ)
    // error with τ = 4 s is ≈ 5e-4 of the curve.
    let peak = creep_elongation_m(&c, f, t_hold);
    let worst = curve
        .iter()
        .map(|&(t, u)| (u - creep_recovery_elongation_m(&c, f, t_hold, t)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3 * peak, "worst {worst} of {peak}");

    // The paper's explicit Euler at 2 ms reproduces the same curve when
    // the masses are heavy enough for it to be stable (10 kg: M/c_s = 5 ms).
    let (curve_e, q_e, v_e) =
        creep_and_release(Integrator::ExplicitEuler, 20.0, dt, f, hold_steps, 60.0);
    assert!((q_e - permanent).abs() <= 1e-12 * permanent + (10.0 * v_e / c.c2_ns_per_m).abs());
    let worst_e = curve_e
        .iter()
        .filter(|(t, _)| *t > 0.05 && (*t < t_hold || *t > t_hold + 0.05))
        .map(|&(t, u)| (u - creep_recovery_elongation_m(&c, f, t_hold, t)).abs())
        .fold(0.0, f64::max);
    assert!(worst_e < 5e-3 * peak, "explicit: worst {worst_e} of {peak}");
}

#[test]
fn explicit_euler_at_the_papers_step_diverges_with_physical_masses_and_says_so() {
    // 1 g per mass with c_s ≈ 1961 N·s/m: stable only below 2M/c_s ≈ 1 µs.
    let lat = single_element();
    let mut sim = LatticeSim::new(
        &lat,
        vec![paper_element()],
        2e-3,
        settings(Integrator::ExplicitEuler, 0.002),
        no_contacts(2),
    )
    .unwrap();
    sim.drive(NodeDrive::pin(0, lat.rest_m[0], [true; 3]))
        .unwrap();
    sim.set_external_force(1, V3::new(1.0, 0.0, 0.0));
    let err = (0..100)
        .find_map(|_| sim.step().err())
        .expect("explicit Euler at 2 ms must fail");
    match &err {
        RheologyError::Unstable { step, kind, .. } => {
            assert!(*step < 100);
            assert!(matches!(
                kind,
                Instability::Collapsed { .. }
                    | Instability::Escaped { .. }
                    | Instability::NonFinite { .. }
            ));
        }
        other => panic!("unexpected {other}"),
    }
    assert!(err.to_string().starts_with("unstable at t = "), "{err}");
    // Below the bound it is stable.
    let mut ok = LatticeSim::new(
        &lat,
        vec![paper_element()],
        2e-3,
        settings(Integrator::ExplicitEuler, 4e-7),
        no_contacts(2),
    )
    .unwrap();
    ok.drive(NodeDrive::pin(0, lat.rest_m[0], [true; 3]))
        .unwrap();
    ok.set_external_force(1, V3::new(1.0, 0.0, 0.0));
    for _ in 0..20_000 {
        ok.step().unwrap();
    }
}

#[test]
fn one_element_relaxes_as_its_closed_form_under_a_ramp_and_hold() {
    let c = paper_element();
    let lat = single_element();
    let (rate, ramp) = (2e-3, 0.5);
    let dt = 0.002;
    let mut sim = LatticeSim::new(
        &lat,
        vec![c],
        2e-3,
        settings(Integrator::ImplicitEuler, dt),
        no_contacts(2),
    )
    .unwrap();
    sim.drive(NodeDrive::pin(0, lat.rest_m[0], [true; 3]))
        .unwrap();
    sim.drive(NodeDrive {
        node: 1,
        axes: [true; 3],
        origin_m: lat.rest_m[1],
        direction: V3::new(1.0, 0.0, 0.0),
        offset_m: Schedule::new("ramp", vec![(0.0, 0.0), (ramp, rate * ramp)]).unwrap(),
    })
    .unwrap();
    let peak = ramp_hold_force_n(&c, rate, ramp, ramp);
    let mut worst: f64 = 0.0;
    for _ in 0..(10.0 / dt) as usize {
        let r = sim.step().unwrap();
        let t = r.t_s;
        if (t - ramp).abs() < 0.01 {
            continue; // the jump of the damper at the end of the ramp
        }
        // The tension over a step is the end-of-step value: compare there.
        let f = sim.tensions_n()[0];
        worst = worst.max((f - ramp_hold_force_n(&c, rate, ramp, t)).abs());
    }
    assert!(worst < 2e-3 * peak, "worst {worst} of {peak}");
}

/// A laterally confined 2 × n × 2 column (x and z of every mass held,
/// the bottom masses pinned): every layer of elements carries the weight
/// above it, and a voxel's vertical stiffness is (4 + 8·½ + 4·⅓)·k = 28k/3
/// (edges, face and body diagonals projected on the vertical). The closed
/// forms are small-strain: with 5 g the strain is ≈ 0.1 % and the
/// geometric error ≈ 2e-4 (ten times the mass gives ten times the error).
fn confined_column(
    layers: usize,
    total_mass_kg: f64,
    params: ElementParams,
    dt_s: f64,
    end_s: f64,
    times: &[f64],
) -> Vec<Vec<f64>> {
    let lat = Lattice::grid(
        [2, layers + 1, 2],
        [0.01, 0.01 * layers as f64, 0.01],
        VolumeMode::None,
    )
    .unwrap();
    let consts = lat.element_constants(&LatticeParams::uniform(params));
    let mut sim = LatticeSim::new(
        &lat,
        consts,
        total_mass_kg,
        SimSettings {
            dt_s,
            tolerance: 1e-10,
            ..SimSettings::default()
        },
        no_contacts(lat.masses()),
    )
    .unwrap();
    for (n, p) in lat.rest_m.iter().enumerate() {
        let bottom = p.y == 0.0;
        sim.drive(NodeDrive::pin(n, *p, [true, bottom, true]))
            .unwrap();
    }
    let mut out = Vec::new();
    let steps = (end_s / dt_s).round() as usize;
    for s in 1..=steps {
        sim.step().unwrap();
        let t = s as f64 * dt_s;
        if times.iter().any(|&w| (w - t).abs() < dt_s / 2.0) {
            // Height of each level (mean of its 4 masses).
            out.push(
                (0..=layers)
                    .map(|j| {
                        (0..4)
                            .map(|c| {
                                sim.positions()[(c & 1) + 2 * j + 2 * (layers + 1) * (c >> 1)].y
                            })
                            .sum::<f64>()
                            / 4.0
                    })
                    .collect(),
            );
        }
    }
    out
}

#[test]
fn a_confined_column_at_rest_under_gravity_matches_the_static_closed_form() {
    // C2 very large: the series damper does not flow, the Voigt part
    // settles (retardation C1/K = 4 s; 60 s is 15 of them).
    let layers = 4;
    let mass = 0.005;
    let p = ElementParams {
        c2_gfs_per_cm2: 1e12,
        ..ElementParams::PAPER_DEFAULT
    };
    let k = ElementConstants::from_params(&p, 0.01, 1.0).k_n_per_m;
    let heights = confined_column(layers, mass, p, 0.1, 60.0, &[60.0]);
    let m = mass / (4.0 * (layers + 1) as f64);
    let g = 9.806_65;
    let mut expected = 0.0;
    for (j, &height) in heights[0].iter().enumerate().skip(1) {
        // The layer below level j carries the 4 masses of every level ≥ j.
        let weight = 4.0 * m * g * (layers + 1 - j) as f64;
        expected += weight / (28.0 / 3.0 * k);
        let sag = 0.01 * j as f64 - height;
        assert!(
            (sag - expected).abs() < 1e-3 * expected,
            "level {j}: sag {sag} m, closed form {expected} m"
        );
    }
}

#[test]
fn a_confined_column_creeps_under_gravity_as_the_element_closed_form() {
    // Each layer's elements see a constant force W/(28/3) per unit
    // projection, so every layer creeps as one element under that force.
    let layers = 3;
    let mass = 0.005;
    let p = ElementParams::PAPER_DEFAULT;
    let c = ElementConstants::from_params(&p, 0.01, 1.0);
    let times = [0.5, 2.0, 5.0];
    let heights = confined_column(layers, mass, p, 0.002, 5.0, &times);
    let m = mass / (4.0 * (layers + 1) as f64);
    for (ti, &t) in times.iter().enumerate() {
        let mut expected = 0.0;
        for (j, &height) in heights[ti].iter().enumerate().skip(1) {
            let weight = 4.0 * m * 9.806_65 * (layers + 1 - j) as f64;
            expected += creep_elongation_m(&c, weight / (28.0 / 3.0), t);
            let sag = 0.01 * j as f64 - height;
            assert!(
                (sag - expected).abs() < 1e-3 * expected,
                "t = {t} s, level {j}: sag {sag} m, closed form {expected} m"
            );
        }
    }
}
