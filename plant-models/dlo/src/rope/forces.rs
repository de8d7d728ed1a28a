//! Internal forces of the rope (Shi & Payandeh §II-B, L1230–1290): linear
//! spring (Eq. 5–6), linear damper (Eq. 7), torsional spring (Eq. 8–10),
//! torsional damper (Eq. 11–13) and swivel damper (Eq. 14–16).
//!
//! Every term acts on two or three neighbouring points with forces that
//! sum to zero (Eq. 10, 13, 16 and the action–reaction of Eq. 6–7), so the
//! internal forces never move the rope's centre of mass.
//!
//! **Signs of Eq. 11–12 and 14–15.** As printed, the torsional damper and
//! the swivel damper push the outer points *along* their velocity relative
//! to the centre point: their power is +k_td·R² and +k_sw·Σw²/l, i.e. they
//! feed energy in. The rope here applies them with the opposite sign, so
//! that they dissipate (power −k_td·R² and −k_sw·Σw²/l, tested in
//! `dampers_dissipate`), which is what the text says they are for ("works
//! against the torsional spring to prevent any harmonic motion",
//! "fix the problem of perpetual orbiting").
//!
//! Near a straight joint (|ê_{i−1} × ê_i| below 1e-12) the bending plane is
//! undefined; the three bending terms are then left out (the spring's
//! force α/π → 0 there anyway).
use nalgebra::Vector3;

use super::params::{RopeModel, RopeParams};

/// A 3-vector, m or N or m/s.
pub type V3 = Vector3<f64>;

/// The force terms, for breakdowns (Figs. 9–13 of the paper plot them one
/// by one at node 15).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Term {
    /// Eq. 6.
    LinearSpring,
    /// Eq. 7.
    LinearDamper,
    /// Eq. 8–10.
    TorsionalSpring,
    /// Eq. 11–13.
    TorsionalDamper,
    /// Eq. 14–16.
    SwivelDamper,
}

impl Term {
    /// All terms, in the paper's order.
    pub const ALL: [Term; 5] = [
        Term::LinearSpring,
        Term::LinearDamper,
        Term::TorsionalSpring,
        Term::TorsionalDamper,
        Term::SwivelDamper,
    ];
    /// Short name for files.
    pub fn name(self) -> &'static str {
        match self {
            Term::LinearSpring => "linear_spring",
            Term::LinearDamper => "linear_damper",
            Term::TorsionalSpring => "torsional_spring",
            Term::TorsionalDamper => "torsional_damper",
            Term::SwivelDamper => "swivel_damper",
        }
    }
}

/// Smallest |ê_{i−1} × ê_i| for which the bending plane is defined.
const MIN_SIN_BEND: f64 = 1e-12;

/// One segment's length l and direction ê = d/l (NaN when l = 0).
#[derive(Clone, Copy)]
struct Segment {
    e: V3,
    l: f64,
}

/// Calls `sink(term, node, force_n)` for every internal force contribution
/// of the rope at positions `x` (m) and velocities `v` (m/s).
///
/// Cost (issue 34), not the paper's: one pass over the segments computes
/// each segment's length and direction once (the bending terms of joint i
/// reuse those of segments i − 1 and i instead of recomputing them), and
/// joint j is handled right after segment j + 1. The calls reach every node
/// in the order of two separate passes (all segments, then all joints):
/// node k hears from segments k − 1 and k before any joint, because joint
/// j, the first to touch node j + 1, comes after segment j + 1. A sum in
/// the sink is therefore the same, bit for bit.
pub fn for_each_internal_force(
    p: &RopeParams,
    x: &[V3],
    v: &[V3],
    mut sink: impl FnMut(Term, usize, V3),
) {
    let n = x.len();
    let l_r = p.rest_length_m();
    let bending = p.model.torsional_spring();
    // Segments i − 2 and i − 1 when segment i is reached.
    let mut before = Segment {
        e: V3::zeros(),
        l: 0.0,
    };
    let mut last = before;
    for i in 0..n.saturating_sub(1) {
        let d = x[i + 1] - x[i];
        let l = d.norm();
        let e = d / l;
        // Linear spring and damper on segment i (Eq. 5–7); a NaN length
        // goes through, so that the checks of the step see it.
        let degenerate = l <= 0.0;
        if !degenerate {
            let strain = (l - l_r) / l_r;
            let magnitude = match p.model {
                // Model 5 (L1501): quadratic in the length difference, signed.
                RopeModel::Quadratic => p.linear_stiffness_n * strain * strain.abs(),
                _ => p.linear_stiffness_n * strain,
            };
            let fs = e * magnitude;
            sink(Term::LinearSpring, i, fs);
            sink(Term::LinearSpring, i + 1, -fs);
            let fd = e * (p.linear_damping_n_s_per_m * (v[i + 1] - v[i]).dot(&e));
            sink(Term::LinearDamper, i, fd);
            sink(Term::LinearDamper, i + 1, -fd);
        }
        if bending && i >= 2 {
            joint_forces(p, v, i - 1, before, last, &mut sink);
        }
        before = last;
        last = Segment { e, l };
    }
    if bending && n >= 3 {
        joint_forces(p, v, n - 2, before, last, &mut sink);
    }
}

/// The bending terms at joint i (points i − 1, i, i + 1) between segment
/// `sa` (i − 1) and `sb` (i): Eq. 8–16. Inlined: a call passing the two
/// segments costs more than the test that ends it on a straight joint.
#[inline(always)]
fn joint_forces(
    p: &RopeParams,
    v: &[V3],
    i: usize,
    sa: Segment,
    sb: Segment,
    sink: &mut impl FnMut(Term, usize, V3),
) {
    let (la, lb) = (sa.l, sb.l);
    if la <= 0.0 || lb <= 0.0 {
        return;
    }
    let (e1, e2) = (sa.e, sb.e);
    let c = e1.cross(&e2);
    let sin_a = c.norm();
    if sin_a < MIN_SIN_BEND {
        return;
    }
    let s_hat = c / sin_a;
    // t̂_{i+1} = ê_i × (ê_{i−1} × ê_i), t̂_{i−1} = ê_{i−1} × (ê_{i−1} × ê_i),
    // normalised: both point towards straightening the joint.
    let t_next = e2.cross(&s_hat);
    let t_prev = e1.cross(&s_hat);
    // α = arcsin|ê×ê| or π − arcsin|ê×ê| (L1252): atan2 covers both.
    let alpha = sin_a.atan2(e1.dot(&e2));
    // Eq. 8–10.
    let f_prev = t_prev * (p.torsional_stiffness_n_m * alpha / (std::f64::consts::PI * la));
    let f_next = t_next * (p.torsional_stiffness_n_m * alpha / (std::f64::consts::PI * lb));
    sink(Term::TorsionalSpring, i - 1, f_prev);
    sink(Term::TorsionalSpring, i + 1, f_next);
    sink(Term::TorsionalSpring, i, -(f_prev + f_next));
    if p.model.torsional_damper() {
        // Eq. 11–13 with the dissipative sign (module doc).
        let rate = (v[i - 1] - v[i]).dot(&t_prev) / la + (v[i + 1] - v[i]).dot(&t_next) / lb;
        let k = -p.torsional_damping_n_m_s * rate;
        let f_prev = t_prev * (k / la);
        let f_next = t_next * (k / lb);
        sink(Term::TorsionalDamper, i - 1, f_prev);
        sink(Term::TorsionalDamper, i + 1, f_next);
        sink(Term::TorsionalDamper, i, -(f_prev + f_next));
    }
    if p.model.swivel_damper() {
        // Eq. 14–16 with the dissipative sign (module doc).
        let f_prev = s_hat * (-p.swivel_damping_n_s * (v[i - 1] - v[i]).dot(&s_hat) / la);
        let f_next = s_hat * (-p.swivel_damping_n_s * (v[i + 1] - v[i]).dot(&s_hat) / lb);
        sink(Term::SwivelDamper, i - 1, f_prev);
        sink(Term::SwivelDamper, i + 1, f_next);
        sink(Term::SwivelDamper, i, -(f_prev + f_next));
    }
}

/// Adds every internal force to `out` (one entry per node).
pub fn add_internal_forces(p: &RopeParams, x: &[V3], v: &[V3], out: &mut [V3]) {
    for_each_internal_force(p, x, v, |_, i, f| out[i] += f);
}

/// The internal force of one term on every node.
pub fn term_forces(p: &RopeParams, x: &[V3], v: &[V3], term: Term) -> Vec<V3> {
    let mut out = vec![V3::zeros(); x.len()];
    for_each_internal_force(p, x, v, |t, i, f| {
        if t == term {
            out[i] += f;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn wiggly(n: usize) -> (Vec<V3>, Vec<V3>) {
        // A bent, moving 3D configuration: a helix with uneven velocities.
        let x = (0..n)
            .map(|i| {
                let t = i as f64 * 0.4;
                V3::new(
                    0.3 * t.cos(),
                    0.3 * t.sin(),
                    0.1 * t + 0.01 * (i % 3) as f64,
                )
            })
            .collect();
        let v = (0..n)
            .map(|i| {
                let t = i as f64;
                V3::new((1.3 * t).sin(), (0.7 * t).cos(), 0.2 * (2.1 * t).sin())
            })
            .collect();
        (x, v)
    }

    #[test]
    fn internal_forces_sum_to_zero_term_by_term() {
        let p = RopeParams {
            nodes: 20,
            ..RopeParams::default()
        };
        let (x, v) = wiggly(20);
        for term in Term::ALL {
            let f = term_forces(&p, &x, &v, term);
            let total: V3 = f.iter().sum();
            let scale: f64 = f.iter().map(|f| f.norm()).sum();
            assert!(scale > 1e-3, "{term:?} is inactive in the test");
            assert!(total.norm() < 1e-12 * scale, "{term:?}: sum {total}");
        }
    }

    /// The internal forces as two passes, all segments then all joints,
    /// each joint recomputing its segments (the code before issue 34's
    /// single pass), added into `out` in that order.
    fn two_passes(p: &RopeParams, x: &[V3], v: &[V3], out: &mut [V3]) {
        let n = x.len();
        let l_r = p.rest_length_m();
        for i in 0..n - 1 {
            let d = x[i + 1] - x[i];
            let l = d.norm();
            if l <= 0.0 {
                continue;
            }
            let e = d / l;
            let strain = (l - l_r) / l_r;
            let magnitude = match p.model {
                RopeModel::Quadratic => p.linear_stiffness_n * strain * strain.abs(),
                _ => p.linear_stiffness_n * strain,
            };
            let fs = e * magnitude;
            out[i] += fs;
            out[i + 1] += -fs;
            let fd = e * (p.linear_damping_n_s_per_m * (v[i + 1] - v[i]).dot(&e));
            out[i] += fd;
            out[i + 1] += -fd;
        }
        if !p.model.torsional_spring() {
            return;
        }
        for i in 1..n - 1 {
            let (a, b) = (x[i] - x[i - 1], x[i + 1] - x[i]);
            let (la, lb) = (a.norm(), b.norm());
            if la <= 0.0 || lb <= 0.0 {
                continue;
            }
            let (e1, e2) = (a / la, b / lb);
            let c = e1.cross(&e2);
            let sin_a = c.norm();
            if sin_a < MIN_SIN_BEND {
                continue;
            }
            let s_hat = c / sin_a;
            let (t_next, t_prev) = (e2.cross(&s_hat), e1.cross(&s_hat));
            let alpha = sin_a.atan2(e1.dot(&e2));
            let pi = std::f64::consts::PI;
            let f_prev = t_prev * (p.torsional_stiffness_n_m * alpha / (pi * la));
            let f_next = t_next * (p.torsional_stiffness_n_m * alpha / (pi * lb));
            out[i - 1] += f_prev;
            out[i + 1] += f_next;
            out[i] += -(f_prev + f_next);
            if p.model.torsional_damper() {
                let rate =
                    (v[i - 1] - v[i]).dot(&t_prev) / la + (v[i + 1] - v[i]).dot(&t_next) / lb;
                let k = -p.torsional_damping_n_m_s * rate;
                let (f_prev, f_next) = (t_prev * (k / la), t_next * (k / lb));
                out[i - 1] += f_prev;
                out[i + 1] += f_next;
                out[i] += -(f_prev + f_next);
            }
            if p.model.swivel_damper() {
                let k = -p.swivel_damping_n_s;
                let f_prev = s_hat * (k * (v[i - 1] - v[i]).dot(&s_hat) / la);
                let f_next = s_hat * (k * (v[i + 1] - v[i]).dot(&s_hat) / lb);
                out[i - 1] += f_prev;
                out[i + 1] += f_next;
                out[i] += -(f_prev + f_next);
            }
        }
    }

    #[test]
    fn one_pass_adds_up_bit_for_bit_like_two_passes() {
        // Issue 34: the single pass must give the same sums, to the bit,
        // for every model, with a zero-length segment (points 5 and 6
        // coincide) and with a non-finite point.
        let (x, v) = wiggly(20);
        let mut coincident = x.clone();
        coincident[6] = coincident[5];
        let mut broken = x.clone();
        broken[12].y = f64::NAN;
        let models = [
            RopeModel::LinearOnly,
            RopeModel::TorsionalSpring,
            RopeModel::TorsionalDamper,
            RopeModel::Swivel,
            RopeModel::Quadratic,
        ];
        for model in models {
            let p = RopeParams {
                nodes: 20,
                model,
                ..RopeParams::default()
            };
            for (name, x) in [
                ("wiggly", &x),
                ("coincident", &coincident),
                ("nan", &broken),
            ] {
                let g = V3::new(0.0, 0.0, -0.49);
                let (mut one, mut two) = (vec![g; 20], vec![g; 20]);
                add_internal_forces(&p, x, &v, &mut one);
                two_passes(&p, x, &v, &mut two);
                // NaN's sign and payload depend on how the compiler
                // orders an addition, so any NaN counts as one value.
                let bits = |f: &[V3]| -> Vec<u64> {
                    let canonical = |c: &f64| if c.is_nan() { u64::MAX } else { c.to_bits() };
                    f.iter().flat_map(|f| f.iter().map(canonical)).collect()
                };
                assert_eq!(bits(&one), bits(&two), "{model:?}, {name}");
            }
        }
    }

    #[test]
    fn dampers_dissipate() {
        // Power of each damper term: Σ f·v ≤ 0, and equal to −k R² etc.
        let p = RopeParams {
            nodes: 20,
            ..RopeParams::default()
        };
        let (x, v) = wiggly(20);
        for term in [
            Term::LinearDamper,
            Term::TorsionalDamper,
            Term::SwivelDamper,
        ] {
            let f = term_forces(&p, &x, &v, term);
            let power: f64 = f.iter().zip(&v).map(|(f, v)| f.dot(v)).sum();
            assert!(power < 0.0, "{term:?} power {power}");
        }
    }

    #[test]
    fn torsional_spring_magnitude_follows_eq_8() {
        // A right angle: α = π/2, so |f_{i−1}| = k_ts (1/2)/l and the force
        // straightens the joint.
        let p = RopeParams {
            nodes: 3,
            length_m: 2.0,
            ..RopeParams::default()
        };
        let x = vec![V3::new(-1.0, 0.0, 0.0), V3::zeros(), V3::new(0.0, 1.0, 0.0)];
        let v = vec![V3::zeros(); 3];
        let f = term_forces(&p, &x, &v, Term::TorsionalSpring);
        let expect = p.torsional_stiffness_n_m * 0.5 / 1.0;
        assert!(
            (f[0] - V3::new(0.0, -expect, 0.0)).norm() < 1e-12,
            "{}",
            f[0]
        );
        assert!(
            (f[2] - V3::new(expect, 0.0, 0.0)).norm() < 1e-12,
            "{}",
            f[2]
        );
    }

    #[test]
    fn spring_force_is_k_l_times_strain() {
        let p = RopeParams {
            nodes: 2 + 1,
            length_m: 2.0,
            model: RopeModel::LinearOnly,
            ..RopeParams::default()
        };
        let x = vec![
            V3::zeros(),
            V3::new(1.01, 0.0, 0.0),
            V3::new(2.01, 0.0, 0.0),
        ];
        let f = term_forces(&p, &x, &[V3::zeros(); 3], Term::LinearSpring);
        assert!((f[0].x - 800.0 * 0.01).abs() < 1e-9, "{}", f[0]);
    }
}
