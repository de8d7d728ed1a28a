//! Unit checks of the mass-spring model of seed 001 against closed forms,
//! finite differences of the energy and the seed's own formulas.
use plant_pushing::collision::{
    closest_point_on_segment, repair_triangles, Finger, Table, FINGER_CLEARANCE_PX, FLAT_AREA_PX2,
};
use plant_pushing::forces::{
    accumulate_internal_forces, accumulate_internal_forces_reference, angle_forces, area_forces,
    elastic_energy, length_force, MaterialParams,
};
use plant_pushing::mesh::{signed_area, Mesh};
use plant_pushing::plasticity::update_alpha;
use plant_pushing::sim::{DrivingMode, Instability, Integrator, SimConfig, Simulator};
use plant_pushing::{PushError, V2};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn params(k_length: f64, k_area: f64, k_angle: f64) -> MaterialParams {
    MaterialParams {
        k_length,
        k_damping: 0.0,
        k_area,
        k_angle,
        max_force: 1e12,
        yield_strain: 1.0,
        creep: 0.0,
        max_alpha: 0.0,
    }
}

fn table_far_below() -> Table {
    Table {
        point_px: V2::new(0.0, -1e6),
        normal: V2::new(0.0, 1.0),
    }
}

#[test]
fn grid_counts_follow_the_star_pattern() {
    for (nx, ny) in [(3usize, 2usize), (10, 5), (20, 10), (7, 1)] {
        let m = Mesh::grid(V2::zeros(), 85.0, 50.0, nx, ny).unwrap();
        assert_eq!(m.vertex_count(), (nx + 1) * (ny + 1));
        assert_eq!(m.triangles.len(), 2 * nx * ny);
        // horizontal + vertical + one diagonal per square
        assert_eq!(m.edges.len(), nx * (ny + 1) + (nx + 1) * ny + nx * ny);
        assert_eq!(m.boundary_loop.len(), 2 * (nx + ny));
        let total = m.total_area_px2(&m.rest_positions_px);
        assert!((total - 85.0 * 50.0).abs() < 1e-9, "area {total}");
        assert!(
            m.rest_areas_px2.iter().all(|a| *a > 0.0),
            "all triangles counter-clockwise"
        );
    }
    // Star pattern: interior vertices alternate between 8 and 4 springs.
    let m = Mesh::grid(V2::zeros(), 10.0, 10.0, 4, 4).unwrap();
    let mut degree = vec![0usize; m.vertex_count()];
    for e in &m.edges {
        degree[e[0]] += 1;
        degree[e[1]] += 1;
    }
    let idx = |i: usize, j: usize| j * 5 + i;
    assert_eq!(degree[idx(2, 2)], 8);
    assert_eq!(degree[idx(1, 1)], 8);
    assert_eq!(degree[idx(2, 1)], 4);
    // The seed's three grids: each has its 8-spring vertices.
    let m20 = Mesh::grid(V2::zeros(), 391.0, 230.0, 20, 10).unwrap();
    assert_eq!(
        (m20.vertex_count(), m20.edges.len(), m20.triangles.len()),
        (231, 630, 400)
    );
}

#[test]
fn bad_meshes_and_parameters_are_refused_with_named_errors() {
    assert!(matches!(
        Mesh::grid(V2::zeros(), 10.0, 10.0, 0, 3),
        Err(PushError::InvalidParameter { name: "nx", .. })
    ));
    assert!(matches!(
        Mesh::grid(V2::zeros(), f64::NAN, 10.0, 3, 3),
        Err(PushError::InvalidParameter {
            name: "width_px",
            ..
        })
    ));
    assert!(matches!(
        Mesh::grid(V2::zeros(), 10.0, -1.0, 3, 3),
        Err(PushError::InvalidParameter {
            name: "height_px",
            ..
        })
    ));
    let p = vec![
        V2::new(0.0, 0.0),
        V2::new(1.0, 0.0),
        V2::new(2.0, 0.0),
        V2::new(0.0, 1.0),
    ];
    let e = Mesh::new(p.clone(), vec![[0, 1, 2]]).unwrap_err();
    assert!(
        matches!(e, PushError::InvalidMesh(ref s) if s.contains("degenerate")),
        "{e}"
    );
    let e = Mesh::new(p.clone(), vec![[0, 1, 9]]).unwrap_err();
    assert!(
        matches!(e, PushError::InvalidMesh(ref s) if s.contains("vertex 9")),
        "{e}"
    );
    let e = Mesh::new(p.clone(), vec![[0, 1, 3]]).unwrap_err();
    assert!(
        matches!(e, PushError::InvalidMesh(ref s) if s.contains("vertex 2 belongs to no triangle")),
        "{e}"
    );
    let mut q = p.clone();
    q[3] = V2::new(f64::INFINITY, 0.0);
    assert!(matches!(
        Mesh::new(q, vec![[0, 1, 3]]),
        Err(PushError::InvalidMesh(_))
    ));
    // Clockwise input is re-ordered, not refused.
    let m = Mesh::new(
        vec![V2::new(0.0, 0.0), V2::new(0.0, 1.0), V2::new(1.0, 0.0)],
        vec![[0, 1, 2]],
    )
    .unwrap();
    assert!(m.rest_areas_px2[0] > 0.0);

    let mesh = Mesh::grid(V2::zeros(), 10.0, 10.0, 2, 2).unwrap();
    let mut bad = params(1.0, 1.0, 1.0);
    bad.k_length = f64::NAN;
    let err = Simulator::new(&mesh, bad, SimConfig::default(), table_far_below()).unwrap_err();
    assert!(
        matches!(
            err,
            PushError::InvalidParameter {
                name: "k_length",
                ..
            }
        ),
        "{err}"
    );
    let mut bad = params(1.0, 1.0, 1.0);
    bad.max_alpha = 1.0;
    let err = bad.validate().unwrap_err();
    assert!(
        matches!(
            err,
            PushError::OutOfRange {
                name: "max_alpha",
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("0..=0.99"), "{err}");
    let mut bad = params(1.0, 1.0, 1.0);
    bad.k_area = -3.0;
    assert!(matches!(
        bad.validate(),
        Err(PushError::OutOfRange { name: "k_area", .. })
    ));
    let cfg = SimConfig {
        step_s: 0.0,
        ..SimConfig::default()
    };
    assert!(matches!(
        Simulator::new(&mesh, params(1.0, 1.0, 1.0), cfg, table_far_below()),
        Err(PushError::InvalidParameter { name: "step_s", .. })
    ));
}

#[test]
fn length_force_matches_eq_20_closed_form() {
    // Spring of rest D0 = 20 px stretched to 25 px along x; k_L = 400.
    let f = length_force(
        V2::new(0.0, 0.0),
        V2::new(25.0, 0.0),
        V2::zeros(),
        V2::zeros(),
        20.0,
        20.0,
        400.0,
        0.0,
    );
    // k_L/D0² (l − D0) = 400/400 · 5 = 5, pulling i towards j.
    assert!((f.x - 5.0).abs() < 1e-12 && f.y.abs() < 1e-12, "{f:?}");
    // Plastic rest length l0 = (1 − α) D0 = 18: force k_L/D0² (l − l0) = 7.
    let f = length_force(
        V2::new(0.0, 0.0),
        V2::new(25.0, 0.0),
        V2::zeros(),
        V2::zeros(),
        20.0,
        18.0,
        400.0,
        0.0,
    );
    assert!((f.x - 7.0).abs() < 1e-12);
    // Damping: only the relative velocity along the spring counts.
    let f = length_force(
        V2::new(0.0, 0.0),
        V2::new(0.0, 20.0),
        V2::new(3.0, 0.0),
        V2::new(-7.0, 2.0),
        20.0,
        20.0,
        0.0,
        0.8,
    );
    // k_d/D0² ((v_j − v_i)·u) u = 0.8/400 · 2 · (0, 1)
    assert!(f.x.abs() < 1e-15 && (f.y - 0.004).abs() < 1e-15, "{f:?}");
}

#[test]
fn area_force_matches_eq_23_as_printed() {
    let (a, b, c) = (V2::new(1.0, 2.0), V2::new(30.0, 5.0), V2::new(8.0, 27.0));
    let (a0, ka) = (250.0, 33.0);
    let f = area_forces(a, b, c, a0, ka);
    // Eq. 23 for vertex i with (j, k): −k_A/(2A0²)(A − A0) · sign(cross) · [ẑ × (p_j − p_k)]
    // where ẑ × (x, y) = (−y, x) and sign(cross) = +1 for this CCW triangle.
    let cr = (b - a).x * (c - a).y - (b - a).y * (c - a).x;
    let area = 0.5 * cr.abs();
    let eq23 = |pj: V2, pk: V2| {
        let d = pj - pk;
        let z_cross = V2::new(-d.y, d.x);
        // The printed [1 × (p_j − p_k)] points out of the triangle for i;
        // the gradient of A w.r.t. p_i is −½ z×(p_j − p_k).
        z_cross * (ka / (2.0 * a0 * a0) * (area - a0) * cr.signum())
    };
    for (got, want) in [(f[0], eq23(b, c)), (f[1], eq23(c, a)), (f[2], eq23(a, b))] {
        assert!(
            (got - want).norm() < 1e-12 * want.norm().max(1.0),
            "{got:?} vs {want:?}"
        );
    }
}

/// Eq. 29 exactly as printed, for the apex of a non-reversed corner.
fn eq29_apex_gradient(pi: V2, pj: V2, pk: V2) -> V2 {
    let pp = (pj - pi).dot(&(pk - pi));
    let dji = (pj - pi).norm();
    let dki = (pk - pi).norm();
    let root = (1.0 - (pp / (dji * dki)).powi(2)).sqrt();
    ((pk - pi) * (1.0 - pp / (dki * dki)) + (pj - pi) * (1.0 - pp / (dji * dji)))
        / (dji * dki * root)
}

#[test]
fn angle_force_matches_eq_26_to_30_as_printed() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..50 {
        let pi = V2::new(rng.gen_range(-10.0..10.0), rng.gen_range(-10.0..10.0));
        let pj = pi + V2::new(rng.gen_range(5.0..20.0), rng.gen_range(-3.0..3.0));
        let pk = pi + V2::new(rng.gen_range(-5.0..5.0), rng.gen_range(5.0..20.0));
        let phi0 = rng.gen_range(0.3..2.5);
        let k = 7.5;
        let f = angle_forces(pi, pj, pk, phi0, k);
        let phi = ((pj - pi).dot(&(pk - pi)) / ((pj - pi).norm() * (pk - pi).norm())).acos();
        let want = eq29_apex_gradient(pi, pj, pk) * (-k * (phi - phi0));
        assert!(
            (f[0] - want).norm() < 1e-9 * want.norm().max(1e-3),
            "{:?} vs {want:?}",
            f[0]
        );
        // Internal: the three forces cancel.
        assert!((f[0] + f[1] + f[2]).norm() < 1e-12);
    }
}

#[test]
fn forces_are_the_negative_gradient_of_the_energy() {
    let mesh = Mesh::grid(V2::new(3.0, 1.0), 60.0, 40.0, 3, 2).unwrap();
    let p = params(500.0, 80.0, 30.0);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let pos: Vec<V2> = mesh
        .rest_positions_px
        .iter()
        .map(|q| *q + V2::new(rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0)))
        .collect();
    let mut rest_len = mesh.rest_lengths_px.clone();
    rest_len[4] *= 0.9; // a plastically shortened spring
    let mut forces = vec![V2::zeros(); pos.len()];
    let vel = vec![V2::zeros(); pos.len()];
    accumulate_internal_forces(&mesh, &pos, &vel, &rest_len, &p, &mut forces);
    let h = 1e-6;
    for v in 0..pos.len() {
        for axis in 0..2 {
            let mut plus = pos.clone();
            let mut minus = pos.clone();
            if axis == 0 {
                plus[v].x += h;
                minus[v].x -= h;
            } else {
                plus[v].y += h;
                minus[v].y -= h;
            }
            let grad = (elastic_energy(&mesh, &plus, &rest_len, &p)
                - elastic_energy(&mesh, &minus, &rest_len, &p))
                / (2.0 * h);
            let f = if axis == 0 { forces[v].x } else { forces[v].y };
            assert!(
                (f + grad).abs() < 1e-5 * (1.0 + grad.abs()),
                "vertex {v} axis {axis}: force {f} vs −∂E {}",
                -grad
            );
        }
    }
    // Newton's third law and no net torque for internal forces.
    let sum = forces.iter().fold(V2::zeros(), |a, f| a + *f);
    let torque: f64 = pos
        .iter()
        .zip(&forces)
        .map(|(r, f)| r.x * f.y - r.y * f.x)
        .sum();
    assert!(sum.norm() < 1e-9, "{sum:?}");
    assert!(torque.abs() < 1e-7, "{torque}");
}

#[test]
fn customised_scheme_relaxes_a_spring_geometrically_eq_15() {
    // Single spring between vertices 0 and 1 (others at rest far away).
    let mesh = Mesh::new(
        vec![V2::new(0.0, 0.0), V2::new(20.0, 0.0), V2::new(10.0, 30.0)],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let k = 50.0;
    let p = params(k, 0.0, 0.0);
    let cfg = SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::CollisionOnly,
        step_s: 0.1,
        geometric_repair: false,
    };
    // Stretch only along the spring's axis with vertex 2 moved to keep its
    // two springs at rest length: place it on the perpendicular bisector.
    let d = 4.0;
    let x0 = V2::new(-d / 2.0, 0.0);
    let x1 = V2::new(20.0 + d / 2.0, 0.0);
    let l2 = mesh.rest_lengths_px[1]; // (0,2)
    let half = (20.0 + d) / 2.0;
    let x2 = V2::new(10.0, (l2 * l2 - half * half).sqrt());
    let mut sim = Simulator::new(&mesh, p, cfg, table_far_below()).unwrap();
    sim.set_positions(&[x0, x1, x2]);
    // Relative coordinate: δ' = δ − 2 h k/D0² δ, exactly (the side springs
    // change length only to second order in δ, which we bound below).
    let factor: f64 = 1.0 - 2.0 * 0.1 * k / 400.0;
    let mut last = d;
    for n in 1..=20 {
        sim.step(None, None).unwrap();
        let l = (sim.positions_px()[1] - sim.positions_px()[0]).norm();
        let delta = l - 20.0;
        let want = d * factor.powi(n);
        assert!(
            (delta - want).abs() < 0.02 * d,
            "step {n}: δ {delta} vs {want}"
        );
        // No overshoot: the first-order scheme is critically damped (Eq. 14).
        assert!(delta > 0.0 && delta < last);
        last = delta;
    }
}

#[test]
fn euler_grows_oscillator_energy_by_exactly_one_plus_h2w2_per_step() {
    // One 20 px spring between vertices 0 and 1; vertex 2 is 1e4 px away so
    // its two springs pull below 1e-6 of the main one (k_area = k_angle = 0).
    let mesh = Mesh::new(
        vec![V2::new(0.0, 0.0), V2::new(20.0, 0.0), V2::new(10.0, 1e4)],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let k = 40.0;
    let h = 0.1;
    let cfg = SimConfig {
        integrator: Integrator::Euler,
        mode: DrivingMode::CollisionOnly,
        step_s: h,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(&mesh, params(k, 0.0, 0.0), cfg, table_far_below()).unwrap();
    let d = 1.0;
    sim.set_positions(&[
        V2::new(-d / 2.0, 0.0),
        V2::new(20.0 + d / 2.0, 0.0),
        V2::new(10.0, 1e4),
    ]);
    for _ in 0..30 {
        sim.step(None, None).unwrap();
    }
    let pos = sim.positions_px();
    let delta = (pos[1].x - pos[0].x) - 20.0;
    // Relative motion δ'' = −ω² δ with ω² = 2k/D0²; explicit Euler maps
    // [δ, v] ← [[1, h], [−hω², 1]] [δ, v] and multiplies ω²δ² + v² by
    // exactly (1 + h²ω²) per step.
    let w2 = 2.0 * k / 400.0;
    let (mut x, mut v) = (d, 0.0);
    for _ in 0..30 {
        let (nx, nv) = (x + h * v, v - h * w2 * x);
        x = nx;
        v = nv;
    }
    assert!(
        (delta - x).abs() < 1e-5 * x.abs().max(1.0),
        "δ {delta} vs discrete map {x}"
    );
    let energy = w2 * x * x + v * v;
    let energy0 = w2 * d * d;
    let want = energy0 * (1.0 + h * h * w2).powi(30);
    assert!((energy - want).abs() < 1e-9 * want, "{energy} vs {want}");
    assert!(energy > 1.05 * energy0, "explicit Euler must gain energy");
}

#[test]
fn verlet_oscillates_at_its_discrete_frequency() {
    let mesh = Mesh::new(
        vec![V2::new(0.0, 0.0), V2::new(20.0, 0.0), V2::new(10.0, 1e4)],
        vec![[0, 1, 2]],
    )
    .unwrap();
    let k = 40.0;
    let h = 0.1;
    let cfg = SimConfig {
        integrator: Integrator::Verlet,
        mode: DrivingMode::CollisionOnly,
        step_s: h,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(&mesh, params(k, 0.0, 0.0), cfg, table_far_below()).unwrap();
    let d = 1.0;
    sim.set_positions(&[
        V2::new(-d / 2.0, 0.0),
        V2::new(20.0 + d / 2.0, 0.0),
        V2::new(10.0, 1e4),
    ]);
    // δ_{n+1} = 2δ_n − δ_{n−1} − h²ω²δ_n with δ_{−1} = δ_0 = d (starting at
    // rest), whose solution is δ_n = d·cos((n + ½)θ)/cos(θ/2), cos θ = 1 − h²ω²/2.
    let w2 = 2.0 * k / 400.0;
    let (mut prev, mut cur) = (d, d);
    let theta = (1.0 - h * h * w2 / 2.0).acos();
    for n in 1..=60 {
        sim.step(None, None).unwrap();
        let next = 2.0 * cur - prev - h * h * w2 * cur;
        prev = cur;
        cur = next;
        let delta = sim.positions_px()[1].x - sim.positions_px()[0].x - 20.0;
        assert!((delta - cur).abs() < 1e-5, "step {n}: {delta} vs {cur}");
        // and the recurrence's closed form with δ_{−1} = δ_0
        let closed = d * ((n as f64 + 0.5) * theta).cos() / (0.5 * theta).cos();
        assert!((cur - closed).abs() < 1e-9, "{cur} vs {closed}");
    }
}

#[test]
fn algorithm_2_plasticity() {
    let p = MaterialParams {
        k_length: 1.0,
        k_damping: 0.0,
        k_area: 0.0,
        k_angle: 0.0,
        max_force: 10.0,
        yield_strain: 0.05,
        creep: 0.5,
        max_alpha: 0.3,
    };
    let d0 = 20.0;
    // Compressed by 10 % > yield: α += 0.5 · 0.1.
    assert!((update_alpha(0.0, 18.0, d0, &p) - 0.05).abs() < 1e-12);
    // Below yield: no change.
    assert_eq!(update_alpha(0.0, 19.5, d0, &p), 0.0);
    // Stretching never creeps.
    assert_eq!(update_alpha(0.1, 30.0, d0, &p), 0.1);
    // Elastic deformation measured from the current rest length (1 − α) D0.
    assert!((update_alpha(0.1, 16.0, d0, &p) - (0.1 + 0.5 * 0.1)).abs() < 1e-12);
    // Capped at max α.
    assert_eq!(update_alpha(0.25, 2.0, d0, &p), 0.3);
}

#[test]
fn algorithms_3_and_4_finger_collision() {
    let (a, b) = (V2::new(0.0, 0.0), V2::new(10.0, 0.0));
    assert_eq!(closest_point_on_segment(a, b, V2::new(-5.0, 3.0)), a);
    assert_eq!(closest_point_on_segment(a, b, V2::new(15.0, -2.0)), b);
    assert!((closest_point_on_segment(a, b, V2::new(4.0, 7.0)) - V2::new(4.0, 0.0)).norm() < 1e-12);
    // Edge crossing a finger of radius 3 centred 1 px above its middle.
    let finger = Finger {
        centre_px: V2::new(5.0, 1.0),
        radius_px: 3.0,
    };
    let mut pos = vec![a, b];
    let moved = finger.resolve_edges(&[[0, 1]], &mut pos, V2::new(0.0, -1.0));
    assert_eq!(moved, 1);
    // Pushed straight down until it clears the circle by ε.
    let want = -(3.0 - 1.0 + FINGER_CLEARANCE_PX);
    assert!(
        (pos[0].y - want).abs() < 1e-12 && (pos[1].y - want).abs() < 1e-12,
        "{pos:?}"
    );
    assert!((pos[0].x - 0.0).abs() < 1e-12);
    // Vertex stage: radially out to r + ε.
    let mut v = vec![V2::new(6.0, 1.0), V2::new(50.0, 0.0)];
    assert_eq!(finger.resolve_vertices(&mut v, V2::new(0.0, 1.0)), 1);
    assert!(((v[0] - finger.centre_px).norm() - (3.0 + FINGER_CLEARANCE_PX)).abs() < 1e-12);
    assert!((v[0].y - 1.0).abs() < 1e-12, "radial direction kept");
    assert_eq!(v[1], V2::new(50.0, 0.0));
    // Table: vertices below are put back on its border, others untouched.
    let t = Table {
        point_px: V2::zeros(),
        normal: V2::new(0.0, 1.0),
    };
    let mut q = vec![V2::new(1.0, -2.0), V2::new(3.0, 4.0)];
    assert_eq!(t.resolve(&mut q), 1);
    assert_eq!(q, vec![V2::new(1.0, 0.0), V2::new(3.0, 4.0)]);
}

#[test]
fn reversed_and_flat_triangles_are_repaired() {
    let mesh = Mesh::new(
        vec![V2::new(0.0, 0.0), V2::new(20.0, 0.0), V2::new(10.0, 10.0)],
        vec![[0, 1, 2]],
    )
    .unwrap();
    // Apex pushed through the base: reversed, height −4.
    let mut pos = vec![V2::new(0.0, 0.0), V2::new(20.0, 0.0), V2::new(10.0, -4.0)];
    let c = repair_triangles(&mesh, &mut pos);
    assert_eq!((c.reversed, c.flat), (1, 0));
    // Each side moves 3/4 · 4 = 3 px: apex at −1, base at −3 → height +2.
    assert!(
        (pos[2].y - (-1.0)).abs() < 1e-12 && (pos[0].y - (-3.0)).abs() < 1e-12,
        "{pos:?}"
    );
    assert!(signed_area(pos[0], pos[1], pos[2]) > 0.0);
    // Flat: apex on the base → area raised to the threshold (2.0 px²).
    let mut pos = vec![V2::new(0.0, 0.0), V2::new(20.0, 0.0), V2::new(10.0, 0.0)];
    let c = repair_triangles(&mesh, &mut pos);
    assert_eq!((c.reversed, c.flat), (0, 1));
    assert!((signed_area(pos[0], pos[1], pos[2]) - FLAT_AREA_PX2).abs() < 1e-9);
    // A healthy triangle is left alone.
    let mut pos = mesh.rest_positions_px.clone();
    assert_eq!(repair_triangles(&mesh, &mut pos), Default::default());
    assert_eq!(pos, mesh.rest_positions_px);
}

#[test]
fn customised_scheme_decreases_the_energy_of_a_deformed_block() {
    let mesh = Mesh::grid(V2::new(0.0, 0.0), 100.0, 50.0, 10, 5).unwrap();
    let p = params(200.0, 50.0, 5.0);
    let cfg = SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::CollisionOnly,
        step_s: 0.1,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(&mesh, p, cfg, table_far_below()).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let start: Vec<V2> = mesh
        .rest_positions_px
        .iter()
        .map(|q| *q + V2::new(rng.gen_range(-1.5..1.5), rng.gen_range(-1.5..1.5)))
        .collect();
    sim.set_positions(&start);
    let mut e = elastic_energy(&mesh, sim.positions_px(), &mesh.rest_lengths_px, &p);
    let e0 = e;
    for _ in 0..200 {
        sim.step(None, None).unwrap();
        let e1 = elastic_energy(&mesh, sim.positions_px(), &mesh.rest_lengths_px, &p);
        assert!(e1 <= e + 1e-9, "energy rose {e} → {e1}");
        e = e1;
    }
    assert!(e < 1e-3 * e0, "relaxed to {e} from {e0}");
}

/// The seed's Fig. 14 sponge parameters on the seed's block as the camera
/// sees it (8.5 × 5 cm at 4600 px/m, 20×10 mesh), at rest but for a
/// 0.05 px nudge, 10 s without finger: largest distance from rest, px.
fn fig14_nudged_block_after_10_s(integrator: Integrator, step_s: f64) -> f64 {
    let mesh = Mesh::grid(V2::zeros(), 0.085 * 4600.0, 0.05 * 4600.0, 20, 10).unwrap();
    let cfg = SimConfig {
        integrator,
        mode: DrivingMode::ForcesOnVertices,
        step_s,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(
        &mesh,
        MaterialParams::SEED_FIG14_SPONGE,
        cfg,
        table_far_below(),
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let start: Vec<V2> = mesh
        .rest_positions_px
        .iter()
        .map(|q| *q + V2::new(rng.gen_range(-0.05..0.05), rng.gen_range(-0.05..0.05)))
        .collect();
    sim.set_positions(&start);
    for _ in 0..(10.0 / step_s).round() as usize {
        if sim.step(None, None).is_err() {
            return f64::INFINITY;
        }
    }
    sim.positions_px()
        .iter()
        .zip(&mesh.rest_positions_px)
        .map(|(p, q)| (*p - *q).norm())
        .fold(0.0, f64::max)
}

/// The seed ran these parameters with the customised scheme at h = 0.1 s
/// (Fig. 14) and saw no gain at h = 0.01 s (§VII-A). Read as printed
/// (Eq. 15: every force at p(t), all vertices moved together), h·k_L/D0²
/// is 0.8 for a 19.5 px spring and the stiff modes grow: the nudge ends as
/// a mesh torn by up to h·max(F) = 122 px per step. At h = 0.01 s, or
/// with the springs relaxed one after another, it stays at rest.
#[test]
fn seed_fig14_parameters_need_the_spring_by_spring_update() {
    let printed = fig14_nudged_block_after_10_s(Integrator::Customised, 0.1);
    let printed_fine = fig14_nudged_block_after_10_s(Integrator::Customised, 0.01);
    let sequential = fig14_nudged_block_after_10_s(Integrator::CustomisedSequential, 0.1);
    assert!(printed > 10.0, "printed Eq. 15 at h = 0.1 s: {printed} px");
    assert!(
        printed_fine < 0.1,
        "printed Eq. 15 at h = 0.01 s: {printed_fine} px"
    );
    assert!(
        sequential < 0.1,
        "spring by spring at h = 0.1 s: {sequential} px"
    );
}

#[test]
fn spring_by_spring_update_relaxes_a_block_and_equals_eq_15_without_springs() {
    let mesh = Mesh::grid(V2::new(0.0, 0.0), 100.0, 50.0, 10, 5).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let start: Vec<V2> = mesh
        .rest_positions_px
        .iter()
        .map(|q| *q + V2::new(rng.gen_range(-1.5..1.5), rng.gen_range(-1.5..1.5)))
        .collect();
    let run = |integrator: Integrator, p: MaterialParams, steps: usize| {
        let cfg = SimConfig {
            integrator,
            mode: DrivingMode::CollisionOnly,
            step_s: 0.1,
            geometric_repair: false,
        };
        let mut sim = Simulator::new(&mesh, p, cfg, table_far_below()).unwrap();
        sim.set_positions(&start);
        let mut energies = vec![elastic_energy(&mesh, &start, &mesh.rest_lengths_px, &p)];
        for _ in 0..steps {
            if sim.step(None, None).is_err() {
                // Declared unstable: an unbounded energy.
                energies.push(f64::INFINITY);
                break;
            }
            energies.push(elastic_energy(
                &mesh,
                sim.positions_px(),
                &mesh.rest_lengths_px,
                &p,
            ));
        }
        (sim.positions_px().to_vec(), energies)
    };
    // Stiff springs (h·k_L/D0² = 0.7 for the 10 px springs): the sweep
    // relaxes the block where the simultaneous update would not be stable.
    let p = params(700.0, 50.0, 5.0);
    let (_, e) = run(Integrator::CustomisedSequential, p, 200);
    assert!(e.windows(2).all(|w| w[1] <= w[0] + 1e-9), "energy rose");
    assert!(e[200] < 1e-3 * e[0], "relaxed to {} from {}", e[200], e[0]);
    let (_, e_printed) = run(Integrator::Customised, p, 200);
    let e_end = *e_printed.last().unwrap();
    assert!(
        e_end > e[0],
        "the printed update at this stiffness should not relax: {e_end} from {}",
        e[0]
    );
    // Without length springs nothing is swept: the two updates coincide.
    let p = params(0.0, 50.0, 5.0);
    let (a, _) = run(Integrator::CustomisedSequential, p, 50);
    let (b, _) = run(Integrator::Customised, p, 50);
    assert!(a
        .iter()
        .zip(&b)
        .all(|(p, q)| p.x.to_bits() == q.x.to_bits() && p.y.to_bits() == q.y.to_bits()));
}

#[test]
fn force_cap_limits_each_vertex_step() {
    let mesh = Mesh::grid(V2::zeros(), 100.0, 50.0, 4, 2).unwrap();
    let mut p = params(1e4, 1e4, 100.0);
    p.max_force = 5.0;
    let cfg = SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::CollisionOnly,
        step_s: 0.1,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(&mesh, p, cfg, table_far_below()).unwrap();
    let mut start = mesh.rest_positions_px.clone();
    start[7].y += 20.0;
    sim.set_positions(&start);
    sim.step(None, None).unwrap();
    for (a, b) in start.iter().zip(sim.positions_px()) {
        assert!(
            (*b - *a).norm() <= 0.1 * 5.0 + 1e-12,
            "moved {}",
            (*b - *a).norm()
        );
    }
}

#[test]
fn unstable_runs_are_detected_and_frozen() {
    // Explicit Euler with a stiff spring at h = 0.1 s diverges.
    let mesh = Mesh::grid(V2::zeros(), 100.0, 50.0, 4, 2).unwrap();
    let mut p = params(1e4, 0.0, 0.0);
    p.max_force = 1e12;
    let cfg = SimConfig {
        integrator: Integrator::Euler,
        mode: DrivingMode::CollisionOnly,
        step_s: 0.1,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(&mesh, p, cfg, table_far_below()).unwrap();
    let mut start = mesh.rest_positions_px.clone();
    start[6].x += 1.0;
    sim.set_positions(&start);
    let mut failed_at = None;
    for n in 0..200 {
        if let Err(why) = sim.step(None, None) {
            failed_at = Some((n, why));
            break;
        }
    }
    let (n, why) = failed_at.expect("a stiff Euler run must be flagged unstable");
    assert!(
        matches!(
            why,
            Instability::Escaped { .. }
                | Instability::NonFinite { .. }
                | Instability::AreaCollapse { .. }
        ),
        "{why:?}"
    );
    assert!(n < 200);
    let frozen = sim.positions_px().to_vec();
    assert_eq!(sim.step(None, None), Err(why));
    assert_eq!(sim.positions_px(), &frozen[..]);
    // The same parameters with the customised scheme and a lower k stay stable.
    let mut p2 = p;
    p2.k_length = 100.0;
    let cfg2 = SimConfig {
        integrator: Integrator::Customised,
        ..cfg
    };
    let mut sim2 = Simulator::new(&mesh, p2, cfg2, table_far_below()).unwrap();
    sim2.set_positions(&start);
    for _ in 0..200 {
        sim2.step(None, None).unwrap();
    }
}

#[test]
fn finger_forces_push_the_touched_vertices_only() {
    let mesh = Mesh::grid(V2::zeros(), 100.0, 50.0, 4, 2).unwrap();
    let p = params(100.0, 10.0, 1.0);
    let cfg = SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::ForcesOnVertices,
        step_s: 0.1,
        geometric_repair: false,
    };
    let mut sim = Simulator::new(
        &mesh,
        p,
        cfg,
        Table {
            point_px: V2::zeros(),
            normal: V2::new(0.0, 1.0),
        },
    )
    .unwrap();
    // Finger just touching the top-middle vertex (50, 50) from above.
    let finger = Finger {
        centre_px: V2::new(50.0, 50.0 + 5.0),
        radius_px: 5.5,
    };
    sim.step(Some(&finger), Some(V2::new(0.0, -3.0))).unwrap();
    let top_mid = 2 * 5 + 2;
    // Only that vertex is within reach: it moves down by h·F = 0.3 px
    // (no internal force at rest, up to the rounding of the angle terms'
    // rest cos/sin), everything else stays.
    for (i, (a, b)) in mesh
        .rest_positions_px
        .iter()
        .zip(sim.positions_px())
        .enumerate()
    {
        if i == top_mid {
            assert!(
                (b.y - (a.y - 0.3)).abs() < 1e-12 && (b.x - a.x).abs() < 1e-12,
                "{b:?}"
            );
        } else {
            assert!((*a - *b).norm() < 1e-12, "vertex {i}: {a:?} → {b:?}");
        }
    }
}

/// §VIII-A: "the radial component of the registered force is applied at
/// any vertex that happens to be located within the radius of the robotic
/// finger" — every touched vertex gets the reading's component along its
/// own radius, the reading is not divided between them (it was, before:
/// each of three touched vertices moved a third as far).
#[test]
fn each_touched_vertex_gets_the_radial_component_of_the_whole_reading() {
    let mesh = Mesh::grid(V2::zeros(), 100.0, 50.0, 4, 2).unwrap();
    let cfg = SimConfig {
        integrator: Integrator::Customised,
        mode: DrivingMode::ForcesOnVertices,
        step_s: 0.1,
        geometric_repair: false,
    };
    // No internal forces at all, so only the finger's force moves vertices.
    let mut sim = Simulator::new(&mesh, params(0.0, 0.0, 0.0), cfg, table_far_below()).unwrap();
    // Reaches the three top vertices (25, 50), (50, 50), (75, 50) and
    // nothing else (the next row is 35 px from the centre).
    let finger = Finger {
        centre_px: V2::new(50.0, 60.0),
        radius_px: 27.0,
    };
    let reading = V2::new(0.0, -3.0);
    sim.step(Some(&finger), Some(reading)).unwrap();
    let mut touched = 0;
    for (a, b) in mesh.rest_positions_px.iter().zip(sim.positions_px()) {
        let d = *a - finger.centre_px;
        if d.norm() <= finger.radius_px + plant_pushing::sim::CONTACT_MARGIN_PX {
            touched += 1;
            let radial = d / d.norm();
            let expected = *a + radial * (0.1 * reading.dot(&radial));
            assert!(
                (*b - expected).norm() < 1e-12,
                "{a:?} → {b:?}, expected {expected:?}"
            );
        } else {
            assert!((*a - *b).norm() < 1e-12, "{a:?} → {b:?}");
        }
    }
    assert_eq!(touched, 3);
    // The vertex straight under the finger moves by the whole h·F = 0.3 px.
    let top_mid = 2 * 5 + 2;
    assert!((sim.positions_px()[top_mid].y - (50.0 - 0.3)).abs() < 1e-12);
}

#[test]
fn reruns_are_bit_identical() {
    let mesh = Mesh::grid(V2::zeros(), 100.0, 50.0, 10, 5).unwrap();
    let run = || {
        let cfg = SimConfig::default();
        let mut sim = Simulator::new(
            &mesh,
            MaterialParams::SEED_FIG15_PLASTICINE,
            cfg,
            Table {
                point_px: V2::zeros(),
                normal: V2::new(0.0, 1.0),
            },
        )
        .unwrap();
        for n in 0..80 {
            let f = Finger {
                centre_px: V2::new(40.0, 60.0 - 0.3 * n as f64),
                radius_px: 10.0,
            };
            let _ = sim.step(Some(&f), Some(V2::new(0.0, -2.0)));
        }
        (sim.positions_px().to_vec(), sim.alpha().to_vec())
    };
    let (a, b) = (run(), run());
    assert!(a
        .0
        .iter()
        .zip(&b.0)
        .all(|(p, q)| p.x.to_bits() == q.x.to_bits() && p.y.to_bits() == q.y.to_bits()));
    assert!(a
        .1
        .iter()
        .zip(&b.1)
        .all(|(p, q)| p.to_bits() == q.to_bits()));
    // and the finger did deform it (the test would be vacuous otherwise)
    assert!(a
        .0
        .iter()
        .zip(&mesh.rest_positions_px)
        .any(|(p, q)| (*p - *q).norm() > 1.0));
}

/// Largest difference between the restructured force loop and the
/// per-corner reference, against a tolerance of 1e-12 of the force scale
/// (largest reference force, or k_φ over the shortest edge: an angle
/// rounding error of an ulp of π moves a force by about k_φ·1e-16/|e|).
fn compare_with_reference(
    mesh: &Mesh,
    pos: &[V2],
    vel: &[V2],
    rest_len: &[f64],
    p: &MaterialParams,
) -> f64 {
    let mut fast = vec![V2::zeros(); pos.len()];
    let mut reference = vec![V2::zeros(); pos.len()];
    accumulate_internal_forces(mesh, pos, vel, rest_len, p, &mut fast);
    accumulate_internal_forces_reference(mesh, pos, vel, rest_len, p, &mut reference);
    let min_edge = mesh
        .edges
        .iter()
        .map(|&[i, j]| (pos[j] - pos[i]).norm())
        .fold(f64::INFINITY, f64::min);
    let scale = reference
        .iter()
        .map(|f| f.norm())
        .fold(p.k_angle / min_edge, f64::max);
    let worst = fast
        .iter()
        .zip(&reference)
        .map(|(a, b)| (*a - *b).norm())
        .fold(0.0, f64::max);
    assert!(
        worst <= 1e-12 * scale,
        "fast vs reference forces differ by {worst:e} (scale {scale:e})"
    );
    worst / scale
}

#[test]
fn fast_force_loop_matches_the_per_corner_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let p = MaterialParams {
        k_damping: 0.3,
        ..params(2600.0, 40.0, 60.0)
    };
    // Random distortions from barely (series path) to wild (reversed and
    // flat triangles, atan2 path), on the seed's 20×10 mesh.
    let mesh = Mesh::grid(V2::new(10.0, 0.0), 391.0, 230.0, 20, 10).unwrap();
    let mut worst: f64 = 0.0;
    for amp in [1e-6, 1e-3, 0.1, 1.0, 4.0, 12.0, 30.0] {
        for _ in 0..5 {
            let pos: Vec<V2> = mesh
                .rest_positions_px
                .iter()
                .map(|q| *q + V2::new(rng.gen_range(-amp..amp), rng.gen_range(-amp..amp)))
                .collect();
            let vel: Vec<V2> = pos
                .iter()
                .map(|_| V2::new(rng.gen_range(-5.0..5.0), rng.gen_range(-5.0..5.0)))
                .collect();
            let rest_len: Vec<f64> = mesh
                .rest_lengths_px
                .iter()
                .map(|l| l * rng.gen_range(0.9..1.0))
                .collect();
            worst = worst.max(compare_with_reference(&mesh, &pos, &vel, &rest_len, &p));
        }
    }
    // A general mesh with a rest angle close to π (the φ ∈ (−π, π] wrap):
    // flatten the obtuse corner through π and beyond.
    let mesh = Mesh::new(
        vec![
            V2::new(0.0, 0.0),
            V2::new(10.0, 0.0),
            V2::new(5.0, 0.3),
            V2::new(5.0, -4.0),
        ],
        vec![[0, 1, 2], [0, 3, 1]],
    )
    .unwrap();
    for dy in [0.3, 0.1, 0.01, -0.01, -0.1, -0.3] {
        let mut pos = mesh.rest_positions_px.clone();
        pos[2].y = dy;
        let vel = vec![V2::zeros(); 4];
        worst = worst.max(compare_with_reference(
            &mesh,
            &pos,
            &vel,
            &mesh.rest_lengths_px,
            &p,
        ));
    }
    println!("largest relative difference {worst:e}");
}

#[test]
fn fast_force_loop_matches_the_reference_along_a_push() {
    // Every frame of a simulated push of the 20×10 mesh (collisions,
    // sensed forces, repair, plasticity), for each integrator.
    use plant_pushing::evaluate::simulate_frames;
    use plant_pushing::scenario::{PushScenario, PushSite};
    let sc = PushScenario::seed(PushSite::MiddleLongSide, 4600.0).unwrap();
    let mesh = Mesh::grid(V2::zeros(), sc.block_width_px, sc.block_height_px, 20, 10).unwrap();
    let forces_n: Vec<f64> = (0..sc.frame_count())
        .map(|f| {
            if f < 50 {
                0.1 * f as f64
            } else {
                0.1 * (99 - f) as f64
            }
        })
        .collect();
    let p = MaterialParams {
        k_length: 2600.0,
        k_damping: 0.77,
        k_area: 0.5,
        k_angle: 40.0,
        max_force: 12.0,
        yield_strain: 3e-5,
        creep: 0.005,
        max_alpha: 1e-4,
    };
    for integrator in Integrator::ALL {
        let cfg = SimConfig {
            integrator,
            ..SimConfig::default()
        };
        simulate_frames(&mesh, &sc, &forces_n, &p, &cfg, |_, pos, _| {
            let vel = vec![V2::new(0.5, -0.25); pos.len()];
            compare_with_reference(&mesh, pos, &vel, &mesh.rest_lengths_px, &p);
        })
        .unwrap();
    }
}
