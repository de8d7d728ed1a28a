//! The rope hanging at rest against closed forms (issue 29): with segments
//! shorter than 2r (N = 60 at Table I's l and r) and with model 5's
//! spring k_l·ε|ε|.
use plant_dlo::rope::{Rope, RopeModel, RopeParams, V3};

/// Hangs a rope of `nodes` points from its top and relaxes it; returns the
/// rope, its stretch (m) and the self-contacts of the last step.
fn hang(nodes: usize, model: RopeModel) -> (Rope, f64, usize) {
    let p = RopeParams {
        nodes,
        model,
        ..RopeParams::default()
    };
    let mut rope = Rope::straight(p, V3::new(0.0, 0.0, 10.0), -V3::z()).unwrap();
    rope.pin(0).unwrap();
    let steps = rope.relax(300_000, 1e-12).unwrap();
    assert!(steps < 300_000, "N = {nodes}: no rest after {steps} steps");
    let stretch = (rope.x[nodes - 1] - rope.x[0]).norm() - rope.params.length_m;
    let contacts = rope.stats.contacts;
    (rope, stretch, contacts)
}

/// The static stretch of a hanging chain written from its statics: the
/// segment k from the bottom (k = 1..N−1) carries k·m·g and stretches to the
/// strain where the spring force equals it.
fn stretch_closed_form(p: &RopeParams, quadratic: bool) -> f64 {
    let l_r = p.length_m / (p.nodes - 1) as f64;
    (1..p.nodes)
        .map(|k| {
            let t = k as f64 * p.node_mass_kg * p.gravity_n_per_kg / p.linear_stiffness_n;
            l_r * if quadratic { t.sqrt() } else { t }
        })
        .sum()
}

#[test]
fn a_rope_of_segments_shorter_than_2r_hangs_as_the_closed_form_says() {
    // Table I: l = 5 m, r = 0.05 m; N = 60 gives l_r = 0.0847 m < 2r.
    let (rope, stretch, contacts) = hang(60, RopeModel::Swivel);
    assert!(rope.params.rest_length_m() < 2.0 * rope.params.radius_m);
    let exact = stretch_closed_form(&rope.params, false);
    // l·m·g·N/(2k_l) (SEED000-SYSTEMS §3), the same sum.
    assert!((exact - 5.0 * 0.05 * 9.8 * 60.0 / 1600.0).abs() < 1e-12);
    assert_eq!(contacts, 0, "a straight hanging rope touches itself");
    assert!(
        (stretch - exact).abs() < 1e-3 * exact,
        "stretch {stretch} m, closed form {exact} m"
    );
}

#[test]
fn model_5_stretches_a_hanging_rope_more_than_model_4() {
    // The paper (L1501–1503) calls model 5 "a lot less stretchy". With the
    // spring k_l·ε|ε| and Table I's k_l, a force F stretches a segment by
    // √(F/k_l) instead of F/k_l: more, for every F < k_l (strain < 100 %).
    for nodes in [20, 50] {
        let (r4, s4, _) = hang(nodes, RopeModel::Swivel);
        let (r5, s5, _) = hang(nodes, RopeModel::Quadratic);
        let (e4, e5) = (
            stretch_closed_form(&r4.params, false),
            stretch_closed_form(&r5.params, true),
        );
        eprintln!(
            "N = {nodes}: model 4 {s4:.4} m ({e4:.4}), model 5 {s5:.4} m ({e5:.4}), ratio {:.2}",
            s5 / s4
        );
        assert!((s4 - e4).abs() < 1e-3 * e4, "model 4: {s4} vs {e4}");
        assert!((s5 - e5).abs() < 1e-3 * e5, "model 5: {s5} vs {e5}");
        assert!(s5 > 5.0 * s4, "model 5 is the stretchier by far");
    }
}
