//! The rig's plate against closed forms (issue 29): a force-driven plate
//! covering the block strains it as the derived uniaxial creep from the
//! first sample on, and a held plate's force relaxes as the basic
//! element's relaxation, with no jump.
use plant_rheology::params::{ElementParams, PA_PER_GF_PER_CM2};
use plant_rheology::scenario::{run_scenario, Scenario};

/// The defaults' relaxation time τ = (c1 + c2)/k = (C1/a + C2/(1−a))/(K/a).
fn relaxation_time_s(p: &ElementParams) -> f64 {
    (p.c1_gfs_per_cm2 / p.a + p.c2_gfs_per_cm2 / (1.0 - p.a)) / (p.k_gf_per_cm2 / p.a)
}

#[test]
fn a_force_driven_plate_over_the_whole_top_creeps_the_block_as_the_closed_form_from_the_first_sample(
) {
    // A constant 1 N on the whole 10 × 10 cm top from t = 0 (100 Pa), no
    // gravity, no friction: uniaxial stress. The depth is the block's
    // creep, H·ε(t) with E = (144/19)·K/a, η1 = (144/19)·C1/a, η2 =
    // (144/19)·C2/(1 − a) (README, "Effective stiffness of the lattice"),
    // plus the table's penalty compliance σ/k_pen (10,000 kPa/mm).
    let mut sc = Scenario::default();
    sc.model.gravity = false;
    sc.contact.mu_static = 0.0;
    sc.contact.mu_kinetic = 0.0;
    sc.plate.depth_mm = None;
    sc.plate.footprint_cm = [12.0, 12.0];
    sc.plate.force_n = Some(vec![[0.0, 1.0], [2.0, 1.0]]);
    sc.plate.end_s = 2.0;
    sc.measure.frame_times_s = vec![1.0];
    sc.model.solver_tolerance = 1e-9;
    let run = run_scenario(&sc, None).unwrap();
    assert!(run.instability.is_none());
    let p = ElementParams::PAPER_DEFAULT;
    let s = 144.0 / 19.0 * PA_PER_GF_PER_CM2;
    let (e, eta1, eta2) = (
        s * p.k_gf_per_cm2 / p.a,
        s * p.c1_gfs_per_cm2 / p.a,
        s * p.c2_gfs_per_cm2 / (1.0 - p.a),
    );
    let stress = 1.0 / 0.01;
    let penalty = 1e4 * 1e6;
    let height = 0.06;
    for (k, (&t, &depth)) in run.t_s.iter().zip(&run.plate_depth_m).enumerate() {
        let strain = stress / e * (1.0 - (-t * e / eta1).exp()) + stress * t / eta2;
        let want = height * strain + stress / penalty;
        // Backward Euler at 5 ms against τ = C1/K = 4 s: ≈ dt/(2τ) of the
        // Voigt part; 1 % covers it.
        assert!(
            (depth - want).abs() < 1e-2 * want,
            "sample {k} at {t} s: depth {depth:.4e} m, closed form {want:.4e} m"
        );
    }
}

#[test]
fn the_default_push_held_with_full_stick_relaxes_as_the_element_closed_form_without_a_jump() {
    // The default push (15 mm in 1 s, held to 3 s), no gravity, friction
    // that never slips. Every element shares the relaxation time τ, so the
    // held plate's force decays as e^(−t/τ) once the Voigt dampers'
    // transient is over (a few steps after 1 s).
    let mut sc = Scenario::default();
    sc.model.gravity = false;
    sc.contact.mu_static = 1e6;
    sc.contact.mu_kinetic = 1e5;
    sc.plate.end_s = 3.0;
    sc.measure.frame_times_s = vec![1.0];
    let run = run_scenario(&sc, None).unwrap();
    assert!(run.instability.is_none());
    let tau = relaxation_time_s(&ElementParams::PAPER_DEFAULT);
    assert!((tau - 8.0).abs() < 1e-12);
    let at = |t: f64| {
        let k = run.t_s.iter().position(|&s| (s - t).abs() < 1e-6).unwrap();
        run.plate_force_n[k]
    };
    let f0 = at(1.1);
    assert!(f0 > 0.0);
    for (&t, &f) in run.t_s.iter().zip(&run.plate_force_n) {
        if (1.1..=2.999).contains(&t) {
            let want = f0 * (-(t - 1.1) / tau).exp();
            // Geometric nonlinearity at 25 % strain: within 2 %.
            assert!(
                (f - want).abs() < 2e-2 * want,
                "at {t:.3} s: {f:.2} N, closed form {want:.2} N"
            );
        }
    }
}
