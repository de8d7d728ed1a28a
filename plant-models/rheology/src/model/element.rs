//! The paper's basic element (L1645, L1739–1742): a Voigt unit (spring K
//! parallel to damper C1) in series with a damper C2; the Voigt part takes
//! the fraction a of the element's rest length.
//!
//! With tension F, elongation u = L − L0, Voigt extension e and series
//! flow q (u = e + q):
//!
//! ```text
//!   F = k·e + c1·ė        (Voigt)
//!   F = c2·q̇              (series damper)
//! ```
//!
//! Eliminating ė: `F = κ·k·(u − q) + c_s·u̇` with `κ = c2/(c1 + c2)` and the
//! series damping `c_s = c1·c2/(c1 + c2)`, and `q̇ = F/c2`. So the element
//! creeps (Voigt retardation), relaxes (a Maxwell-like flow through c2) and
//! keeps a permanent elongation: after a force F held for T and released,
//! q stays at F·T/c2 while e decays to zero.
//!
//! Closed forms (used by the tests and the README):
//! * creep under a step force F: `u(t) = F/k·(1 − e^(−k t/c1)) + F t/c2`;
//! * recovery after release at T: the Voigt part decays with `e^(−k(t−T)/c1)`,
//!   leaving exactly `F·T/c2`;
//! * relaxation under an elongation ramp at rate r for t_r, then held:
//!   `e` obeys `ė = κ u̇ − e/τ`, `τ = (c1 + c2)/k`, and `F = κ(k e + c1 u̇)`.
use crate::model::params::{ElementParams, PA_PER_GF_PER_CM2};

/// The constants of one element in SI units (per element, after the
/// voxel contributions that share it are summed).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementConstants {
    /// Voigt spring k (N/m).
    pub k_n_per_m: f64,
    /// Voigt damper c1 (N·s/m).
    pub c1_ns_per_m: f64,
    /// Series damper c2 (N·s/m).
    pub c2_ns_per_m: f64,
}

impl ElementConstants {
    /// One voxel's contribution to an element of a voxel of edge
    /// `voxel_edge_m`, times `weight` (1 for a full element, 2 for a half
    /// element, which is half as long and so twice as stiff): spring
    /// `K·h/a`, dampers `C1·h/a` and `C2·h/(1−a)` (see `params` for the units).
    pub fn from_params(p: &ElementParams, voxel_edge_m: f64, weight: f64) -> Self {
        let h = voxel_edge_m * weight * PA_PER_GF_PER_CM2;
        Self {
            k_n_per_m: p.k_gf_per_cm2 * h / p.a,
            c1_ns_per_m: p.c1_gfs_per_cm2 * h / p.a,
            c2_ns_per_m: p.c2_gfs_per_cm2 * h / (1.0 - p.a),
        }
    }

    /// Two elements between the same nodes, in parallel. Exact when both
    /// have the same a (their internal states are then equal); the lattice
    /// only merges elements of one class.
    pub fn plus(self, o: Self) -> Self {
        Self {
            k_n_per_m: self.k_n_per_m + o.k_n_per_m,
            c1_ns_per_m: self.c1_ns_per_m + o.c1_ns_per_m,
            c2_ns_per_m: self.c2_ns_per_m + o.c2_ns_per_m,
        }
    }

    /// κ = c2/(c1 + c2).
    pub fn kappa(&self) -> f64 {
        self.c2_ns_per_m / (self.c1_ns_per_m + self.c2_ns_per_m)
    }

    /// Series damping c_s = c1·c2/(c1 + c2) (N·s/m): the element's response
    /// to a sudden elongation rate.
    pub fn series_damping_ns_per_m(&self) -> f64 {
        self.c1_ns_per_m * self.c2_ns_per_m / (self.c1_ns_per_m + self.c2_ns_per_m)
    }

    /// Tension (N) at flow `q_m`, elongation `u_m` and elongation rate
    /// `u_rate_m_s` (the explicit form).
    pub fn force_n(&self, u_m: f64, q_m: f64, u_rate_m_s: f64) -> f64 {
        self.kappa() * self.k_n_per_m * (u_m - q_m) + self.series_damping_ns_per_m() * u_rate_m_s
    }

    /// Backward Euler over a step `dt_s`: the tension at the end of the
    /// step is `f0 + beta·u̇` where u̇ is the elongation rate over the step
    /// and `u_m − q_m` the state at its start (q updated with the end-of-
    /// step tension: `q += dt·F/c2`). Returns `(f0_n, beta_ns_per_m)`.
    pub fn implicit_step(&self, u_m: f64, q_m: f64, dt_s: f64) -> (f64, f64) {
        let k = self.k_n_per_m;
        let alpha = 1.0 / (1.0 + k * dt_s / (self.c1_ns_per_m + self.c2_ns_per_m));
        let kk = self.kappa() * k;
        (
            alpha * kk * (u_m - q_m),
            alpha * (kk * dt_s + self.series_damping_ns_per_m()),
        )
    }

    /// The relaxation time τ = (c1 + c2)/k (s).
    pub fn relaxation_time_s(&self) -> f64 {
        (self.c1_ns_per_m + self.c2_ns_per_m) / self.k_n_per_m
    }

    /// The Voigt retardation time c1/k (s).
    pub fn retardation_time_s(&self) -> f64 {
        self.c1_ns_per_m / self.k_n_per_m
    }
}

/// Creep: elongation (m) at `t_s` under a force `force_n` applied at t = 0.
pub fn creep_elongation_m(c: &ElementConstants, force_n: f64, t_s: f64) -> f64 {
    force_n / c.k_n_per_m * (1.0 - (-t_s / c.retardation_time_s()).exp())
        + force_n * t_s / c.c2_ns_per_m
}

/// Creep and recovery: the elongation at `t_s` when `force_n` acts over
/// [0, `hold_s`] and is then released.
pub fn creep_recovery_elongation_m(
    c: &ElementConstants,
    force_n: f64,
    hold_s: f64,
    t_s: f64,
) -> f64 {
    if t_s <= hold_s {
        return creep_elongation_m(c, force_n, t_s);
    }
    let tr = c.retardation_time_s();
    force_n / c.k_n_per_m * (1.0 - (-hold_s / tr).exp()) * (-(t_s - hold_s) / tr).exp()
        + permanent_elongation_m(c, force_n, hold_s)
}

/// The permanent elongation after a force held for `hold_s` and released:
/// exactly F·T/c2.
pub fn permanent_elongation_m(c: &ElementConstants, force_n: f64, hold_s: f64) -> f64 {
    force_n * hold_s / c.c2_ns_per_m
}

/// Relaxation: the tension at `t_s` when the elongation ramps at
/// `rate_m_s` over [0, `ramp_s`] and is then held.
pub fn ramp_hold_force_n(c: &ElementConstants, rate_m_s: f64, ramp_s: f64, t_s: f64) -> f64 {
    let tau = c.relaxation_time_s();
    let kappa = c.kappa();
    let e_ramp = |t: f64| kappa * rate_m_s * tau * (1.0 - (-t / tau).exp());
    if t_s <= ramp_s {
        kappa * (c.k_n_per_m * e_ramp(t_s) + c.c1_ns_per_m * rate_m_s)
    } else {
        kappa * c.k_n_per_m * e_ramp(ramp_s) * (-(t_s - ramp_s) / tau).exp()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn demo() -> ElementConstants {
        ElementConstants::from_params(&ElementParams::PAPER_DEFAULT, 0.01, 1.0)
    }

    #[test]
    fn paper_defaults_on_a_one_centimetre_voxel_are_k_over_a_gram_force_per_cm() {
        let c = demo();
        // K/a = 1000 gf/cm = 1000 × 9.80665e-3 N / 0.01 m.
        assert!((c.k_n_per_m - 980.665).abs() < 1e-9, "{c:?}");
        assert!((c.c1_ns_per_m - 3922.66).abs() < 1e-9);
        assert!((c.c2_ns_per_m - 3922.66).abs() < 1e-9);
        assert!((c.relaxation_time_s() - 8.0).abs() < 1e-12);
        assert!((c.retardation_time_s() - 4.0).abs() < 1e-12);
    }

    #[test]
    fn the_implicit_step_tends_to_the_explicit_force_law_as_dt_vanishes() {
        let c = demo();
        let (u, q, rate) = (1e-3, 2e-4, 5e-3);
        let (f0, beta) = c.implicit_step(u, q, 1e-9);
        let explicit = c.force_n(u, q, rate);
        assert!(((f0 + beta * rate) - explicit).abs() < 1e-6 * explicit.abs());
    }

    #[test]
    fn the_closed_forms_agree_with_each_other() {
        let c = demo();
        let (f, t) = (2.0, 3.0);
        // Creep-recovery equals creep up to the release.
        assert_eq!(
            creep_recovery_elongation_m(&c, f, t, 2.0),
            creep_elongation_m(&c, f, 2.0)
        );
        // Continuous at the release, and tends to F·T/c2.
        let before = creep_elongation_m(&c, f, t);
        let after = creep_recovery_elongation_m(&c, f, t, t + 1e-12);
        assert!((before - after).abs() < 1e-12);
        let late = creep_recovery_elongation_m(&c, f, t, 400.0);
        assert!((late - f * t / c.c2_ns_per_m).abs() < 1e-12);
        // The ramp force is continuous at the end of the ramp up to the
        // c1·κ·rate jump of the damper.
        let r = 1e-3;
        let jump = ramp_hold_force_n(&c, r, 1.0, 1.0) - ramp_hold_force_n(&c, r, 1.0, 1.0 + 1e-12);
        assert!((jump - c.kappa() * c.c1_ns_per_m * r).abs() < 1e-9);
    }
}
