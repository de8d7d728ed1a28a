//! The linear object (wire, cord) of Wakamatsu et al. §II–IV (L686–905).
//!
//! Shape: Euler angles φ, θ, ψ and strain ε along the length (Eq. 1–6);
//! position x(s) = x₀ + ∫(1 + ε)ζ ds. Energy: flexure R_f κ²/2, torsion
//! R_t ω²/2, extension R_e ε²/2, gravity D·x (Eq. 7–11, gravity along +x
//! as in L757). Constraints: relative position of two points (Eq. 12),
//! orientation at a point (Eq. 13), obstacles f(x(s)) ≤ 0 at the grid
//! points (Eq. 14), no self-interference (Eq. 15, as an exterior penalty on
//! a coarse grid), and crossings with their own unknowns s_u, s_l
//! (Eq. 21–24). Each profile is a Ritz series (Eq. 16–20) and the energy
//! is minimised by the multiplier method with BFGS ([`super::optimize`]).
//!
//! Internally everything is in units of the length L (s̃ = s/L, x̃ = x/L)
//! and of R_f/L for energy, so one set of solver tolerances serves any
//! wire; results come back in SI units. Integrals use the trapezoid rule
//! on `intervals` equal intervals.
//!
//! Left out: the knitted fabric of Eq. 25–30, R_f, R_t, R_e and D varying
//! along s (constants here), and self-contact as exact inequalities (a
//! penalty that grows with ρ instead).
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

use super::basis::{self, Basis};
use super::frame::rotation_and_partials;
use super::optimize::{self, Kind, Problem, Settings, Solution};
use super::verify::{Checks, Penalised};
use crate::error::{check_non_negative, check_positive, check_range, DloError, Result};

type V3 = Vector3<f64>;

/// Material and geometry of a wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WireParams {
    /// Length L, m (the measured wire: 871 mm, L817).
    pub length_m: f64,
    /// Flexural rigidity R_f, N·m² (L818: 6.6e-4).
    pub flexural_rigidity_n_m2: f64,
    /// Torsional rigidity R_t, N·m² (L818: 2.3e-4).
    pub torsional_rigidity_n_m2: f64,
    /// Extensional rigidity R_e, N; none = inextensible (ε ≡ 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extensional_rigidity_n: Option<f64>,
    /// Weight per length D, N/m (L818: 1.0e-2; 0 leaves gravity out, as the
    /// paper's Fig. 3 computation does, L824).
    #[serde(default)]
    pub weight_n_per_m: f64,
    /// Radius of the cross-section r, m (for crossings and self-contact;
    /// estimate: the paper gives none).
    pub radius_m: f64,
}

impl WireParams {
    /// The measured wire of §III-C (L817–819), gravity neglected as in the
    /// paper's comparison, radius 1 mm (estimate).
    pub fn paper_wire() -> Self {
        Self {
            length_m: 0.871,
            flexural_rigidity_n_m2: 6.6e-4,
            torsional_rigidity_n_m2: 2.3e-4,
            extensional_rigidity_n: None,
            weight_n_per_m: 0.0,
            radius_m: 1e-3,
        }
    }

    /// Checks every field; the error names the bad one.
    pub fn validate(&self) -> Result<()> {
        check_positive("length_m", self.length_m)?;
        check_positive("flexural_rigidity_n_m2", self.flexural_rigidity_n_m2)?;
        check_non_negative("torsional_rigidity_n_m2", self.torsional_rigidity_n_m2)?;
        if let Some(r) = self.extensional_rigidity_n {
            check_positive("extensional_rigidity_n", r)?;
        }
        check_non_negative("weight_n_per_m", self.weight_n_per_m)?;
        check_range("radius_m", self.radius_m, 0.0, 0.1 * self.length_m)?;
        Ok(())
    }
}

/// A geometric constraint (positions and arc lengths in m, angles in rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Constraint {
    /// Eq. 12: x(s_b) − x(s_a) = l.
    Position {
        s_a_m: f64,
        s_b_m: f64,
        l_m: [f64; 3],
    },
    /// Eq. 13: A(φ, θ, ψ) at s equals A of the given Euler angles.
    Orientation { s_m: f64, euler_rad: [f64; 3] },
    /// Eq. 14 with a ball: f(x) = R² − |x − c|² ≤ 0 at every grid point.
    Ball { centre_m: [f64; 3], radius_m: f64 },
    /// Eq. 21–24: the wire touches itself, strand at s_u on top (+y) of
    /// the one at s_l; the arc lengths are unknowns, starting from the
    /// guesses, whose order along the wire is kept (Eq. 24). The loop
    /// between the two strands is at least `min_loop_m` long (default 4r):
    /// without it the two points may slide together until they are 2r
    /// apart along a wire that runs along y, which meets Eq. 21–23 without
    /// any crossing.
    Crossing {
        upper_guess_m: f64,
        lower_guess_m: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        min_loop_m: Option<f64>,
    },
}

/// A wire problem: parameters, constraints, discretisation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WireProblem {
    pub wire: WireParams,
    pub constraints: Vec<Constraint>,
    /// Sine/cosine pairs of the Ritz basis (Eq. 20: 4).
    #[serde(default = "default_harmonics")]
    pub harmonics: usize,
    /// Integration intervals along the wire.
    #[serde(default = "default_intervals")]
    pub intervals: usize,
    /// Keep the wire out of itself (Eq. 15).
    #[serde(default = "default_true")]
    pub self_contact: bool,
    /// Tilt of the start away from the straight natural state, rad (see
    /// [`Compiled::natural_start`]; 0 keeps a straight solution straight).
    #[serde(default = "default_tilt")]
    pub initial_tilt_rad: f64,
}

fn default_tilt() -> f64 {
    1e-3
}

fn default_harmonics() -> usize {
    4
}
fn default_intervals() -> usize {
    160
}
fn default_true() -> bool {
    true
}

/// The solved shape in SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct WireShape {
    /// Arc length s_k, m.
    pub s_m: Vec<f64>,
    /// Positions x(s_k), m.
    pub x_m: Vec<V3>,
    /// Euler angles (φ, θ, ψ) at s_k, rad.
    pub euler_rad: Vec<[f64; 3]>,
    /// Strain ε at s_k.
    pub strain: Vec<f64>,
    /// Total energy and its parts, J.
    pub energy_j: f64,
    pub flexural_j: f64,
    pub torsional_j: f64,
    pub extensional_j: f64,
    pub gravitational_j: f64,
    /// Crossing arc lengths (s_u, s_l), m.
    pub crossings_m: Vec<(f64, f64)>,
    /// Largest constraint violation, m (or 1 for orientation entries).
    pub max_violation: f64,
    /// Closest approach of points more than 2r apart along the wire
    /// (Eq. 15 holds when this is ≥ 2r), m.
    pub min_self_distance_m: f64,
    pub solution: Solution,
    /// The answer's own evidence (issue 29): constraints, stationarity,
    /// stability, self-contact, discretisation; see [`Checks`].
    pub checks: Checks,
}

impl WireShape {
    /// Whether every check holds: only then is the answer converged.
    pub fn verified(&self) -> bool {
        self.checks.verified()
    }
}

/// Per-grid state of one evaluation.
struct Grid {
    phi: Vec<f64>,
    dphi: Vec<f64>,
    theta: Vec<f64>,
    dtheta: Vec<f64>,
    psi: Vec<f64>,
    dpsi: Vec<f64>,
    eps: Vec<f64>,
    /// ζ, ∂ζ/∂φ, ∂ζ/∂θ at each grid point.
    zeta: Vec<[V3; 3]>,
    /// Cumulative positions X_k (x̃, x₀ = 0).
    x: Vec<V3>,
}

/// The problem compiled for the solver (dimensionless).
pub struct Compiled {
    p: WireProblem,
    basis: Basis,
    n: usize,
    extensible: bool,
    crossings: usize,
    kinds: Vec<Kind>,
    r_t: f64,
    r_e: f64,
    d: f64,
    radius: f64,
    /// Gravity weights G_j (see `new`).
    g_w: Vec<f64>,
}

impl WireProblem {
    /// Checks every field; the error names the bad one.
    pub fn validate(&self) -> Result<()> {
        self.wire.validate()?;
        check_range("harmonics", self.harmonics as f64, 0.0, 12.0)?;
        check_range("intervals", self.intervals as f64, 16.0, 2000.0)?;
        check_range("initial_tilt_rad", self.initial_tilt_rad, -1.0, 1.0)?;
        let l = self.wire.length_m;
        let in_wire = |name: &str, s: f64| check_range(name, s, 0.0, l);
        for (k, c) in self.constraints.iter().enumerate() {
            let name = |f: &str| format!("constraints[{k}].{f}");
            match c {
                Constraint::Position { s_a_m, s_b_m, l_m } => {
                    in_wire(&name("s_a_m"), *s_a_m)?;
                    in_wire(&name("s_b_m"), *s_b_m)?;
                    for v in l_m {
                        check_range(&name("l_m"), *v, -l, l)?;
                    }
                }
                Constraint::Orientation { s_m, euler_rad } => {
                    in_wire(&name("s_m"), *s_m)?;
                    for v in euler_rad {
                        check_range(&name("euler_rad"), *v, -100.0, 100.0)?;
                    }
                }
                Constraint::Ball { centre_m, radius_m } => {
                    check_positive(&name("radius_m"), *radius_m)?;
                    for v in centre_m {
                        check_range(&name("centre_m"), *v, -1e3, 1e3)?;
                    }
                }
                Constraint::Crossing {
                    upper_guess_m,
                    lower_guess_m,
                    min_loop_m,
                } => {
                    if let Some(m) = min_loop_m {
                        check_range(&name("min_loop_m"), *m, 0.0, l)?;
                    }
                    in_wire(&name("upper_guess_m"), *upper_guess_m)?;
                    in_wire(&name("lower_guess_m"), *lower_guess_m)?;
                    if (upper_guess_m - lower_guess_m).abs() < 4.0 * self.wire.radius_m {
                        return Err(DloError::InvalidScenario(format!(
                            "constraints[{k}]: the two strands of a crossing must be more than 4r apart along the wire"
                        )));
                    }
                }
            }
        }
        Ok(())
    }

    /// Compiles the problem for the solver.
    pub fn compile(&self) -> Result<Compiled> {
        self.validate()?;
        let basis = Basis::new(self.harmonics, self.intervals);
        let n = basis.n;
        let w = &self.wire;
        let l = w.length_m;
        let extensible = w.extensional_rigidity_n.is_some();
        let mut kinds = Vec::new();
        let mut crossings = 0;
        for c in &self.constraints {
            match c {
                Constraint::Position { .. } => kinds.extend([Kind::Equality; 3]),
                Constraint::Orientation { .. } => kinds.extend([Kind::Equality; 6]),
                Constraint::Ball { .. } => kinds.extend(vec![Kind::Inequality; self.intervals + 1]),
                Constraint::Crossing { .. } => {
                    crossings += 1;
                    // Eq. 21–23, Eq. 24 (order), and both in [0, 1].
                    kinds.extend([Kind::Equality; 3]);
                    kinds.extend([Kind::Inequality; 5]);
                }
            }
        }
        // G_j = Σ_k w_k c_kj for the gravity term (trapezoid cumulative).
        let m = self.intervals;
        let h = basis.h();
        let mut g_w = vec![0.0; m + 1];
        for k in 1..=m {
            for (j, g) in g_w.iter_mut().enumerate().take(k + 1) {
                let c = if j == 0 || j == k { 0.5 * h } else { h };
                *g += basis.w[k] * c;
            }
        }
        Ok(Compiled {
            basis,
            n,
            extensible,
            crossings,
            kinds,
            r_t: w.torsional_rigidity_n_m2 / w.flexural_rigidity_n_m2,
            r_e: w.extensional_rigidity_n.unwrap_or(0.0) * l * l / w.flexural_rigidity_n_m2,
            d: w.weight_n_per_m * l.powi(3) / w.flexural_rigidity_n_m2,
            radius: w.radius_m / l,
            g_w,
            p: self.clone(),
        })
    }

    /// Solves from the natural (straight) state, nudged by `start` (added
    /// coefficients; see [`Compiled::natural_start`]): one start, no
    /// continuation, no discretisation estimate; the shape carries the
    /// checks that can be made at this discretisation.
    pub fn solve(&self, settings: &Settings, start: Option<Vec<f64>>) -> Result<WireShape> {
        let c = self.compile()?;
        let x0 = start.unwrap_or_else(|| c.natural_start(self.initial_tilt_rad));
        let sol = c.polished(optimize::solve(&c, x0, settings)?, settings);
        Ok(c.shape(sol))
    }

    /// The robust solve (issue 29): every start is polished and checked,
    /// and the lowest-energy answer that passes its checks is kept.
    ///
    /// Starts: continuation from the natural state (straight, untwisted,
    /// tilted by `initial_tilt_rad`), whose position and orientation targets
    /// are moved to the asked ones in steps of at most 0.05 L and 0.2 rad,
    /// each solve starting from the last with its multipliers (the paper
    /// moves the end likewise, L811); and the direct solve from the natural
    /// state, tilted by `initial_tilt_rad` and by 0.3 rad. The kept answer is then solved again on a
    /// discretisation twice as fine (harmonics and intervals doubled, up to
    /// 12 and 2000), started from it, for the discretisation check.
    pub fn solve_verified(&self, settings: &Settings) -> Result<WireShape> {
        let c = self.compile()?;
        let mut candidates = vec![self.continuation(settings)?];
        for tilt in [self.initial_tilt_rad, 0.3] {
            let sol = optimize::solve(&c, c.natural_start(tilt), settings)?;
            candidates.push(c.settled(c.shape(c.polished(sol, settings)), settings)?);
        }
        let rank = |s: &WireShape| (!s.verified(), s.energy_j);
        let mut best = candidates
            .into_iter()
            .min_by(|a, b| {
                let (ra, rb) = (rank(a), rank(b));
                ra.0.cmp(&rb.0).then(ra.1.total_cmp(&rb.1))
            })
            .expect("three starts were solved");
        self.estimate_discretisation(&mut best, settings)?;
        Ok(best)
    }

    /// The continuation start of [`Self::solve_verified`].
    fn continuation(&self, settings: &Settings) -> Result<WireShape> {
        let l = self.wire.length_m;
        let mut steps = 1.0f64;
        for k in &self.constraints {
            match k {
                Constraint::Position { s_a_m, s_b_m, l_m } => {
                    let natural = [0.0, 0.0, s_b_m - s_a_m];
                    for d in 0..3 {
                        steps = steps.max((l_m[d] - natural[d]).abs() / (0.05 * l));
                    }
                }
                Constraint::Orientation { euler_rad, .. } => {
                    for v in euler_rad {
                        steps = steps.max(v.abs() / 0.2);
                    }
                }
                _ => {}
            }
        }
        let steps = (steps.ceil() as usize).min(200);
        let mut prev: Option<Solution> = None;
        let mut last = None;
        for k in 1..=steps {
            let t = k as f64 / steps as f64;
            let mut p = self.clone();
            for k in &mut p.constraints {
                match k {
                    Constraint::Position { s_a_m, s_b_m, l_m } => {
                        let natural = [0.0, 0.0, *s_b_m - *s_a_m];
                        for d in 0..3 {
                            l_m[d] = natural[d] + t * (l_m[d] - natural[d]);
                        }
                    }
                    Constraint::Orientation { euler_rad, .. } => {
                        euler_rad.iter_mut().for_each(|v| *v *= t);
                    }
                    _ => {}
                }
            }
            let c = p.compile()?;
            let sol = match prev.take() {
                // The multipliers carry the reactions from step to step;
                // ρ starts afresh (a ρ grown to 1e9 on an earlier step
                // leaves BFGS too ill-conditioned to reach stationarity).
                Some(s) => optimize::solve_warm(
                    &c,
                    s.x.clone(),
                    Some((&s.multipliers, settings.rho0)),
                    settings,
                )?,
                None => optimize::solve(&c, c.natural_start(self.initial_tilt_rad), settings)?,
            };
            let sol = if k == steps {
                c.polished(sol, settings)
            } else {
                sol
            };
            prev = Some(sol.clone());
            last = Some((c, sol));
        }
        let (c, sol) = last.expect("at least one step");
        c.settled(c.shape(sol), settings)
    }

    /// Solves again with harmonics and intervals doubled, from `shape`'s
    /// coefficients, and records the change in `shape.checks`.
    fn estimate_discretisation(&self, shape: &mut WireShape, settings: &Settings) -> Result<()> {
        let mut fine = self.clone();
        fine.harmonics = (2 * self.harmonics).clamp(1, 12);
        fine.intervals = (2 * self.intervals).min(2000);
        let (cc, cf) = (self.compile()?, fine.compile()?);
        let x0 = cf.embed(&cc, &shape.solution.x);
        let warm = Some((shape.solution.multipliers.as_slice(), shape.solution.rho));
        let sol = optimize::solve_warm(&cf, x0, warm, settings)?;
        let f = cf.settled(cf.shape(cf.polished(sol, settings)), settings)?;
        let l = self.wire.length_m;
        if f.verified() {
            let scale = f
                .energy_j
                .abs()
                .max(1e-9 * self.wire.flexural_rigidity_n_m2 / l);
            shape.checks.discretisation_energy = Some((f.energy_j - shape.energy_j).abs() / scale);
            // Points at the same arc length (the fine grid holds the coarse
            // one), by their distances to the two ends: a rigid turn that
            // leaves the problem unchanged (a planar shape turned about its
            // clamps' axis, an exact zero mode) does not count as a change.
            let ends = |x: &[V3], k: usize| {
                let last = x.len() - 1;
                ((x[k] - x[0]).norm(), (x[k] - x[last]).norm())
            };
            let moved = (0..shape.s_m.len())
                .map(|k| {
                    let (a, b) = (ends(&f.x_m, 2 * k), ends(&shape.x_m, k));
                    (a.0 - b.0).abs().max((a.1 - b.1).abs()) / l
                })
                .fold(0.0, f64::max);
            shape.checks.discretisation_position = Some(moved);
        } else {
            shape.checks.fine_solve_failed = true;
        }
        Ok(())
    }
}

impl Compiled {
    fn angle_offset(&self, which: usize) -> usize {
        which * self.n
    }
    fn eps_offset(&self) -> usize {
        3 * self.n
    }
    fn cross_offset(&self) -> usize {
        if self.extensible {
            4 * self.n
        } else {
            3 * self.n
        }
    }

    /// The natural state: straight along z, untwisted, with the crossing
    /// unknowns at their guesses and θ nudged by `nudge` rad in a
    /// sin(2πs) pattern in the x–z plane (at exactly θ ≡ 0 the end-to-end
    /// constraint has no gradient with respect to θ, so the paper's
    /// "natural state" start needs a tilt to leave it).
    pub fn natural_start(&self, nudge: f64) -> Vec<f64> {
        let mut x = vec![0.0; self.vars()];
        if self.n > 2 {
            x[self.angle_offset(1) + 2] = nudge;
        }
        let l = self.p.wire.length_m;
        let mut k = self.cross_offset();
        for c in &self.p.constraints {
            if let Constraint::Crossing {
                upper_guess_m,
                lower_guess_m,
                ..
            } = c
            {
                x[k] = upper_guess_m / l;
                x[k + 1] = lower_guess_m / l;
                k += 2;
            }
        }
        x
    }

    fn grid(&self, a: &[f64]) -> Grid {
        let b = &self.basis;
        let n = self.n;
        let m = b.s.len();
        let (af, at, ap) = (&a[0..n], &a[n..2 * n], &a[2 * n..3 * n]);
        let mut g = Grid {
            phi: Vec::with_capacity(m),
            dphi: Vec::with_capacity(m),
            theta: Vec::with_capacity(m),
            dtheta: Vec::with_capacity(m),
            psi: Vec::with_capacity(m),
            dpsi: Vec::with_capacity(m),
            eps: Vec::with_capacity(m),
            zeta: Vec::with_capacity(m),
            x: Vec::with_capacity(m),
        };
        for k in 0..m {
            let (e, de) = (&b.e[k], &b.de[k]);
            let (f, t) = (basis::dot(af, e), basis::dot(at, e));
            g.phi.push(f);
            g.dphi.push(basis::dot(af, de));
            g.theta.push(t);
            g.dtheta.push(basis::dot(at, de));
            g.psi.push(basis::dot(ap, e));
            g.dpsi.push(basis::dot(ap, de));
            g.eps.push(if self.extensible {
                basis::dot(&a[3 * n..4 * n], e)
            } else {
                0.0
            });
            let (sf, cf) = f.sin_cos();
            let (st, ct) = t.sin_cos();
            g.zeta.push([
                V3::new(st * cf, st * sf, ct),
                V3::new(-st * sf, st * cf, 0.0),
                V3::new(ct * cf, ct * sf, -st),
            ]);
        }
        let h = b.h();
        let mut x = V3::zeros();
        g.x.push(x);
        for k in 1..m {
            let f0 = g.zeta[k - 1][0] * (1.0 + g.eps[k - 1]);
            let f1 = g.zeta[k][0] * (1.0 + g.eps[k]);
            x += (f0 + f1) * (0.5 * h);
            g.x.push(x);
        }
        g
    }

    /// Adds `coef` · ∂f_j/∂a (the derivative of the integrand (1+ε)ζ at
    /// grid point j, dotted with `dir`) into `grad`.
    fn add_integrand_grad(&self, g: &Grid, j: usize, dir: &V3, coef: f64, grad: &mut [f64]) {
        let n = self.n;
        let e = &self.basis.e[j];
        let scale = 1.0 + g.eps[j];
        let dphi = coef * scale * g.zeta[j][1].dot(dir);
        let dtheta = coef * scale * g.zeta[j][2].dot(dir);
        let deps = coef * g.zeta[j][0].dot(dir);
        for i in 0..n {
            grad[i] += dphi * e[i];
            grad[n + i] += dtheta * e[i];
        }
        if self.extensible {
            let o = self.eps_offset();
            for i in 0..n {
                grad[o + i] += deps * e[i];
            }
        }
    }

    /// x̃(s̃) (linear in the last interval) and, if `grad` is given,
    /// `coef`·dir·∂x̃/∂a added into it; returns (x̃, dx̃/ds̃).
    fn position_at(
        &self,
        a: &[f64],
        g: &Grid,
        s: f64,
        grad: Option<(&V3, f64, &mut [f64])>,
    ) -> (V3, V3) {
        let m = self.basis.s.len() - 1;
        let h = self.basis.h();
        let s = s.clamp(0.0, 1.0);
        let k = ((s / h).floor() as usize).min(m - 1);
        let t = s - k as f64 * h;
        let n = self.n;
        let hm = self.p.harmonics;
        let (e, de) = (basis::values(hm, s), basis::derivatives(hm, s));
        let f = basis::dot(&a[0..n], &e);
        let th = basis::dot(&a[n..2 * n], &e);
        let eps = if self.extensible {
            basis::dot(&a[3 * n..4 * n], &e)
        } else {
            0.0
        };
        let (sf, cf) = f.sin_cos();
        let (st, ct) = th.sin_cos();
        let zeta = V3::new(st * cf, st * sf, ct);
        let z_f = V3::new(-st * sf, st * cf, 0.0);
        let z_t = V3::new(ct * cf, ct * sf, -st);
        let fk = g.zeta[k][0] * (1.0 + g.eps[k]);
        let fs = zeta * (1.0 + eps);
        let x = g.x[k] + (fk + fs) * (0.5 * t);
        // d/ds of the interval term: (f_k + f(s))/2 + t/2·f'(s).
        let dphi_s = basis::dot(&a[0..n], &de);
        let dth_s = basis::dot(&a[n..2 * n], &de);
        let deps_s = if self.extensible {
            basis::dot(&a[3 * n..4 * n], &de)
        } else {
            0.0
        };
        let df = (z_f * dphi_s + z_t * dth_s) * (1.0 + eps) + zeta * deps_s;
        let dxds = (fk + fs) * 0.5 + df * (0.5 * t);
        if let Some((dir, coef, grad)) = grad {
            // ∂X_k/∂a = Σ_j c_kj ∂f_j/∂a.
            for j in 0..=k {
                let c = cumulative_weight(k, j, h);
                if c != 0.0 {
                    self.add_integrand_grad(g, j, dir, coef * c, grad);
                }
            }
            self.add_integrand_grad(g, k, dir, coef * 0.5 * t, grad);
            // The point s itself.
            let scale = coef * 0.5 * t;
            let dphi = scale * (1.0 + eps) * z_f.dot(dir);
            let dtheta = scale * (1.0 + eps) * z_t.dot(dir);
            for i in 0..n {
                grad[i] += dphi * e[i];
                grad[n + i] += dtheta * e[i];
            }
            if self.extensible {
                let o = self.eps_offset();
                let deps = scale * zeta.dot(dir);
                for i in 0..n {
                    grad[o + i] += deps * e[i];
                }
            }
        }
        (x, dxds)
    }

    /// Energy parts (flexural, torsional, extensional, gravitational) in
    /// units of R_f/L.
    fn energy_parts(&self, g: &Grid) -> [f64; 4] {
        let mut parts = [0.0; 4];
        for k in 0..self.basis.s.len() {
            let w = self.basis.w[k];
            let st = g.theta[k].sin();
            let kappa2 = g.dtheta[k].powi(2) + (g.dphi[k] * st).powi(2);
            let omega = g.dphi[k] * g.theta[k].cos() + g.dpsi[k];
            parts[0] += w * 0.5 * kappa2;
            parts[1] += w * 0.5 * self.r_t * omega * omega;
            parts[2] += w * 0.5 * self.r_e * g.eps[k] * g.eps[k];
            parts[3] += self.d * self.g_w[k] * (1.0 + g.eps[k]) * g.zeta[k][0].x;
        }
        parts
    }

    /// Turns a solution into the shape in SI units.
    pub fn shape(&self, sol: Solution) -> WireShape {
        let g = self.grid(&sol.x);
        let l = self.p.wire.length_m;
        let e0 = self.p.wire.flexural_rigidity_n_m2 / l;
        let parts = self.energy_parts(&g);
        let mut crossings_m = Vec::new();
        let o = self.cross_offset();
        for c in 0..self.crossings {
            crossings_m.push((sol.x[o + 2 * c] * l, sol.x[o + 2 * c + 1] * l));
        }
        let x_m: Vec<V3> = g.x.iter().map(|x| x * l).collect();
        let s_m: Vec<f64> = self.basis.s.iter().map(|s| s * l).collect();
        let r = self.p.wire.radius_m;
        let mut min_d = f64::INFINITY;
        for i in 0..x_m.len() {
            for j in i + 1..x_m.len() {
                if s_m[j] - s_m[i] >= 2.0 * r + 1e-12 {
                    min_d = min_d.min((x_m[i] - x_m[j]).norm());
                }
            }
        }
        WireShape {
            euler_rad: (0..g.phi.len())
                .map(|k| [g.phi[k], g.theta[k], g.psi[k]])
                .collect(),
            strain: g.eps.clone(),
            energy_j: e0 * parts.iter().sum::<f64>(),
            flexural_j: e0 * parts[0],
            torsional_j: e0 * parts[1],
            extensional_j: e0 * parts[2],
            gravitational_j: e0 * parts[3],
            crossings_m,
            max_violation: sol.max_violation * l,
            min_self_distance_m: min_d,
            checks: self.checks(&sol, min_d, Settings::default().tolerance),
            s_m,
            x_m,
            solution: sol,
        }
    }

    /// `sol` after a Newton polish of its KKT conditions (with the
    /// self-contact penalty at the solve's last weight), when the polish
    /// reaches a KKT point no higher in energy; else `sol` itself.
    pub fn polished(&self, sol: Solution, settings: &Settings) -> Solution {
        let p = Penalised {
            problem: self,
            weight: sol.rho,
        };
        // The polish compares energies with the penalty included.
        let mut base = sol.clone();
        base.energy += sol.rho * sol.penalty;
        match optimize::polish(&p, &base, settings.tolerance) {
            Some(mut s) => {
                let mut g = vec![0.0; s.x.len()];
                s.energy = self.energy(&s.x, &mut g);
                s.penalty = self.penalty(&s.x, 1.0, &mut g);
                s
            }
            None => sol,
        }
    }

    /// `shape` again, when it is not stationary: up to three more rounds
    /// of the multiplier method from it with ρ started afresh, each
    /// polished (the multiplier method stops on the violation alone, which
    /// its first round may meet before BFGS is stationary).
    fn settled(&self, mut shape: WireShape, settings: &Settings) -> Result<WireShape> {
        for _ in 0..3 {
            if shape.checks.kkt_residual <= shape.checks.kkt_tolerance {
                break;
            }
            let s = &shape.solution;
            let again = optimize::solve_warm(
                self,
                s.x.clone(),
                Some((&s.multipliers, settings.rho0)),
                settings,
            )?;
            shape = self.shape(self.polished(again, settings));
        }
        Ok(shape)
    }

    /// The checks of `sol` at this discretisation (the discretisation
    /// check is left to [`WireProblem::solve_verified`]).
    fn checks(&self, sol: &Solution, min_self_distance_m: f64, tolerance: f64) -> Checks {
        let p = Penalised {
            problem: self,
            weight: sol.rho,
        };
        let reach = 2.0 * self.p.wire.radius_m;
        let overlap = if self.p.self_contact && reach > 0.0 {
            ((reach - min_self_distance_m) / reach).max(0.0)
        } else {
            0.0
        };
        Checks {
            self_overlap: Some(overlap),
            ..Checks::at(&p, sol, sol.max_violation, tolerance)
        }
    }

    /// Coefficients of `coarse` (a compiled problem with fewer harmonics)
    /// as a start of this one: the shared basis functions keep their
    /// coefficients, the added harmonics start at 0.
    fn embed(&self, coarse: &Compiled, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.vars()];
        let blocks = if self.extensible { 4 } else { 3 };
        for b in 0..blocks.min(if coarse.extensible { 4 } else { 3 }) {
            out[b * self.n..b * self.n + coarse.n]
                .copy_from_slice(&x[b * coarse.n..(b + 1) * coarse.n]);
        }
        let (o, oc) = (self.cross_offset(), coarse.cross_offset());
        out[o..].copy_from_slice(&x[oc..oc + 2 * self.crossings]);
        out
    }

    /// Grid points used for the self-contact penalty.
    fn contact_stride(&self) -> usize {
        (self.p.intervals / 48).max(1)
    }
}

impl Problem for Compiled {
    fn vars(&self) -> usize {
        self.cross_offset() + 2 * self.crossings
    }

    fn energy(&self, a: &[f64], grad: &mut [f64]) -> f64 {
        let g = self.grid(a);
        let n = self.n;
        let parts = self.energy_parts(&g);
        for k in 0..self.basis.s.len() {
            let w = self.basis.w[k];
            let (st, ct) = g.theta[k].sin_cos();
            let omega = g.dphi[k] * ct + g.dpsi[k];
            // Local derivatives of the energy density.
            let d_dphi = w * (g.dphi[k] * st * st + self.r_t * omega * ct);
            let d_dtheta = w * g.dtheta[k];
            let d_theta = w * (g.dphi[k] * g.dphi[k] * st * ct - self.r_t * omega * g.dphi[k] * st);
            let d_dpsi = w * self.r_t * omega;
            let (e, de) = (&self.basis.e[k], &self.basis.de[k]);
            for i in 0..n {
                grad[i] += d_dphi * de[i];
                grad[n + i] += d_dtheta * de[i] + d_theta * e[i];
                grad[2 * n + i] += d_dpsi * de[i];
            }
            if self.extensible {
                let o = self.eps_offset();
                let d_eps = w * self.r_e * g.eps[k];
                for i in 0..n {
                    grad[o + i] += d_eps * e[i];
                }
            }
            if self.d != 0.0 {
                self.add_integrand_grad(&g, k, &V3::x(), self.d * self.g_w[k], grad);
            }
        }
        parts.iter().sum()
    }

    fn kinds(&self) -> &[Kind] {
        &self.kinds
    }

    fn constraints(&self, a: &[f64], values: &mut [f64], jac: &mut [Vec<f64>]) {
        let g = self.grid(a);
        let l = self.p.wire.length_m;
        let n = self.n;
        for row in jac.iter_mut() {
            row.iter_mut().for_each(|v| *v = 0.0);
        }
        let mut r = 0;
        let mut cross = self.cross_offset();
        let axes = [V3::x(), V3::y(), V3::z()];
        for c in &self.p.constraints {
            match c {
                Constraint::Position { s_a_m, s_b_m, l_m } => {
                    for (d, axis) in axes.iter().enumerate() {
                        let (xb, _) =
                            self.position_at(a, &g, s_b_m / l, Some((axis, 1.0, &mut jac[r])));
                        let (xa, _) =
                            self.position_at(a, &g, s_a_m / l, Some((axis, -1.0, &mut jac[r])));
                        values[r] = xb[d] - xa[d] - l_m[d] / l;
                        r += 1;
                    }
                }
                Constraint::Orientation { s_m, euler_rad } => {
                    let s = s_m / l;
                    let hm = self.p.harmonics;
                    let e = basis::values(hm, s);
                    let ang: Vec<f64> = (0..3)
                        .map(|q| basis::dot(&a[q * n..(q + 1) * n], &e))
                        .collect();
                    let [am, df, dt, dp] = rotation_and_partials(ang[0], ang[1], ang[2]);
                    let target: Matrix3<f64> =
                        rotation_and_partials(euler_rad[0], euler_rad[1], euler_rad[2])[0];
                    // Columns ξ (0) and ζ (2).
                    for col in [0usize, 2] {
                        for d in 0..3 {
                            values[r] = am[(d, col)] - target[(d, col)];
                            for (q, dm) in [df, dt, dp].iter().enumerate() {
                                let v = dm[(d, col)];
                                for i in 0..n {
                                    jac[r][q * n + i] += v * e[i];
                                }
                            }
                            r += 1;
                        }
                    }
                }
                Constraint::Ball { centre_m, radius_m } => {
                    let centre = V3::new(centre_m[0], centre_m[1], centre_m[2]) / l;
                    let rad = radius_m / l;
                    for k in 0..self.basis.s.len() {
                        let d = g.x[k] - centre;
                        values[r] = rad * rad - d.norm_squared();
                        // ∂/∂a of −|d|² = −2 d·∂x_k/∂a.
                        let h = self.basis.h();
                        for j in 0..=k {
                            let c = cumulative_weight(k, j, h);
                            if c != 0.0 {
                                self.add_integrand_grad(&g, j, &d, -2.0 * c, &mut jac[r]);
                            }
                        }
                        r += 1;
                    }
                }
                Constraint::Crossing { .. } => {
                    let (su, sl) = (a[cross], a[cross + 1]);
                    // Eq. 21–23: x(s_u) − x(s_l) = (0, 2r, 0).
                    let want = [0.0, 2.0 * self.radius, 0.0];
                    for (d, axis) in axes.iter().enumerate() {
                        let (xu, du) = self.position_at(a, &g, su, Some((axis, 1.0, &mut jac[r])));
                        let (xl, dl) = self.position_at(a, &g, sl, Some((axis, -1.0, &mut jac[r])));
                        values[r] = xu[d] - xl[d] - want[d];
                        jac[r][cross] += du[d];
                        jac[r][cross + 1] -= dl[d];
                        r += 1;
                    }
                    // Eq. 24: the order along the wire is kept (the guesses
                    // set it), at least the loop length apart; both inside
                    // the wire.
                    let sign = if self_first(c) { 1.0 } else { -1.0 };
                    let gap = match c {
                        Constraint::Crossing {
                            min_loop_m: Some(m),
                            ..
                        } => m / l,
                        _ => 4.0 * self.radius,
                    };
                    values[r] = sign * (su - sl) + gap;
                    jac[r][cross] = sign;
                    jac[r][cross + 1] = -sign;
                    r += 1;
                    for (q, v) in [(cross, su), (cross + 1, sl)] {
                        values[r] = -v;
                        jac[r][q] = -1.0;
                        r += 1;
                        if q == cross {
                            values[r] = v - 1.0;
                            jac[r][q] = 1.0;
                            r += 1;
                        }
                    }
                    // The fifth: s_l ≤ 1.
                    values[r] = sl - 1.0;
                    jac[r][cross + 1] = 1.0;
                    r += 1;
                    cross += 2;
                }
            }
        }
        debug_assert_eq!(r, values.len());
    }

    fn penalty(&self, a: &[f64], weight: f64, grad: &mut [f64]) -> f64 {
        if !self.p.self_contact || self.radius <= 0.0 {
            return 0.0;
        }
        // Eq. 15 on every `stride`-th grid point: Σ max(0, (2r)² − |x_i − x_j|²)²
        // over pairs at least 2r + one stride apart along the wire.
        let g = self.grid(a);
        let stride = self.contact_stride();
        let h = self.basis.h();
        let reach = 2.0 * self.radius;
        let idx: Vec<usize> = (0..self.basis.s.len()).step_by(stride).collect();
        let mut total = 0.0;
        for (p, &i) in idx.iter().enumerate() {
            for &j in &idx[p + 1..] {
                if (j - i) as f64 * h < reach + stride as f64 * h {
                    continue;
                }
                let d = g.x[j] - g.x[i];
                let gap = reach * reach - d.norm_squared();
                if gap <= 0.0 {
                    continue;
                }
                total += gap * gap;
                // ∂(gap²)/∂a = −4 gap · d·(∂x_j − ∂x_i)/∂a.
                let coef = -4.0 * weight * gap;
                for t in 0..=j {
                    let c = cumulative_weight(j, t, h) - cumulative_weight(i, t, h);
                    if c != 0.0 {
                        self.add_integrand_grad(&g, t, &d, coef * c, grad);
                    }
                }
            }
        }
        weight * total
    }
}

/// Whether the crossing's upper strand comes first along the wire (the
/// guesses fix the order, Eq. 24).
fn self_first(c: &Constraint) -> bool {
    match c {
        Constraint::Crossing {
            upper_guess_m,
            lower_guess_m,
            ..
        } => upper_guess_m < lower_guess_m,
        _ => true,
    }
}

/// c_kt: weight of the integrand at grid point t in the cumulative
/// trapezoid sum that gives x(s_k).
fn cumulative_weight(k: usize, t: usize, h: f64) -> f64 {
    if k == 0 || t > k {
        0.0
    } else if t == 0 || t == k {
        0.5 * h
    } else {
        h
    }
}

/// One step of the end-distance sequence of §III-B (L811–815).
#[derive(Debug, Clone)]
pub struct SequenceStep {
    /// End distance l / L.
    pub l_fraction: f64,
    /// The shape reached by moving one end along the axis from the straight
    /// wire (the paper's procedure), no crossing imposed.
    pub free: WireShape,
    /// The one-knot shape: a loop whose strands touch at one crossing
    /// (Eq. 21–24), followed from l = 0.1 L outwards.
    pub knot: WireShape,
}

impl SequenceStep {
    /// Whether the one-knot shape has the lower energy.
    pub fn knot_is_lower(&self) -> bool {
        self.knot.energy_j < self.free.energy_j
    }

    /// The shape of lower energy, as a name: `one_knot` or `knot_free`.
    pub fn lower(&self) -> &'static str {
        if self.knot_is_lower() {
            "one_knot"
        } else {
            "knot_free"
        }
    }

    /// Whether both shapes pass their checks (the discretisation check is
    /// not made for a sequence step).
    pub fn converged(&self) -> bool {
        self.free.verified() && self.knot.verified()
    }
}

/// Both ends clamped in the natural orientation, x(L) − x(0) = (0, 0, l),
/// optionally with one crossing (Eq. 21–24).
pub fn clamped_problem(
    wire: &WireParams,
    l_fraction: f64,
    crossing: bool,
    intervals: usize,
) -> WireProblem {
    let l = wire.length_m;
    let mut constraints = vec![
        Constraint::Orientation {
            s_m: 0.0,
            euler_rad: [0.0; 3],
        },
        Constraint::Position {
            s_a_m: 0.0,
            s_b_m: l,
            l_m: [0.0, 0.0, l_fraction * l],
        },
        Constraint::Orientation {
            s_m: l,
            euler_rad: [0.0; 3],
        },
    ];
    if crossing {
        constraints.push(Constraint::Crossing {
            upper_guess_m: 0.12 * l,
            lower_guess_m: 0.88 * l,
            min_loop_m: Some(0.3 * l),
        });
    }
    WireProblem {
        wire: wire.clone(),
        constraints,
        harmonics: 4,
        intervals,
        self_contact: true,
        initial_tilt_rad: 1e-3,
    }
}

/// The end-distance sequence (L811: l = 0.6L … 0.1L) on two branches.
///
/// Knot-free: from the straight wire (θ nudged by 1e-3 rad), one end moves
/// along the axis in steps of `step` L, each solve starting from the last
/// (continuation, as the paper moves the end). One-knot: from a single
/// planar turn θ(s) = 2πs (a loop whose ends meet) with a crossing between
/// s = 0.12 L and 0.88 L (loop at least 0.3 L), solved at the smallest l and followed to the
/// larger ones. Returns the steps at `fractions` (descending).
pub fn end_distance_sequence(
    wire: &WireParams,
    fractions: &[f64],
    step: f64,
    intervals: usize,
    settings: &Settings,
) -> Result<Vec<SequenceStep>> {
    check_range("step", step, 1e-3, 0.5)?;
    for &f in fractions {
        check_range("l_fraction", f, 0.0, 0.99)?;
    }
    // Knot-free branch by continuation from l = L, multipliers carried on.
    let mut free = Vec::new();
    let mut start: Option<Solution> = None;
    let mut l = 1.0;
    let mut targets: Vec<f64> = fractions.to_vec();
    targets.sort_by(|a, b| b.total_cmp(a));
    for &target in &targets {
        loop {
            l = (l - step).max(target);
            let p = clamped_problem(wire, l, false, intervals);
            let c = p.compile()?;
            let sol = match start.take() {
                Some(prev) => optimize::solve_warm(
                    &c,
                    prev.x.clone(),
                    Some((&prev.multipliers, prev.rho)),
                    settings,
                )?,
                None => optimize::solve(&c, c.natural_start(1e-3), settings)?,
            };
            start = Some(sol.clone());
            if (l - target).abs() < 1e-12 {
                free.push(c.shape(c.polished(sol, settings)));
                break;
            }
        }
    }
    // One-knot branch from the loop, smallest l first. A loop reached from
    // the straight untwisted wire carries a full turn of twist opposite to
    // its writhe (link conserved), so the start is the turn θ = 2πs with
    // ψ = ∓2πs; both signs are solved and the lower energy kept.
    let mut knots = Vec::new();
    let mut start: Option<Solution> = None;
    for &target in targets.iter().rev() {
        let p = clamped_problem(wire, target, true, intervals);
        let c = p.compile()?;
        let sol = match start.take() {
            Some(prev) => optimize::solve_warm(
                &c,
                prev.x.clone(),
                Some((&prev.multipliers, prev.rho)),
                settings,
            )?,
            None => {
                let mut best: Option<Solution> = None;
                for sign in [1.0, -1.0] {
                    let mut x = c.natural_start(0.0);
                    x[c.angle_offset(1) + 1] = 2.0 * std::f64::consts::PI;
                    x[c.angle_offset(2) + 1] = -sign * 2.0 * std::f64::consts::PI;
                    let sol = optimize::solve(&c, x, settings)?;
                    let mut g = vec![0.0; sol.x.len()];
                    let better = match &best {
                        None => true,
                        Some(b) => {
                            sol.converged && c.energy(&sol.x, &mut g) < c.energy(&b.x, &mut g)
                        }
                    };
                    if better {
                        best = Some(sol);
                    }
                }
                best.expect("two starts were solved")
            }
        };
        start = Some(sol.clone());
        knots.push(c.shape(c.polished(sol, settings)));
    }
    knots.reverse();
    Ok(targets
        .iter()
        .zip(free.into_iter().zip(knots))
        .map(|(&l_fraction, (free, knot))| SequenceStep {
            l_fraction,
            free,
            knot,
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn twisted(l_frac: f64) -> WireProblem {
        let w = WireParams::paper_wire();
        let l = w.length_m;
        WireProblem {
            constraints: vec![
                Constraint::Orientation {
                    s_m: 0.0,
                    euler_rad: [0.0, 0.0, 0.0],
                },
                Constraint::Position {
                    s_a_m: 0.0,
                    s_b_m: l,
                    l_m: [0.0, 0.0, l_frac * l],
                },
                Constraint::Orientation {
                    s_m: l,
                    euler_rad: [0.0, 0.0, std::f64::consts::PI],
                },
            ],
            wire: w,
            harmonics: 4,
            intervals: 64,
            self_contact: false,
            initial_tilt_rad: 0.0,
        }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let mut p = twisted(0.5);
        p.wire.extensional_rigidity_n = Some(50.0);
        p.wire.weight_n_per_m = 0.01;
        p.self_contact = true;
        p.wire.radius_m = 0.05;
        p.constraints.push(Constraint::Crossing {
            upper_guess_m: 0.3,
            lower_guess_m: 0.6,
            min_loop_m: Some(0.2),
        });
        p.constraints.push(Constraint::Ball {
            centre_m: [0.1, 0.0, 0.4],
            radius_m: 0.2,
        });
        let c = p.compile().unwrap();
        let n = c.vars();
        // A bent, twisted, stretched state.
        let x: Vec<f64> = (0..n)
            .map(|i| 0.3 * ((i as f64) * 1.7).sin() / (1.0 + (i % c.n) as f64))
            .collect();
        let mut x = x;
        let o = c.cross_offset();
        x[o] = 0.3;
        x[o + 1] = 0.62;
        super::super::optimize::assert_derivatives_match_differences(&c, &x, 1e-6, Some(7.0));
    }

    #[test]
    fn straight_wire_twisted_by_pi_has_energy_rt_pi2_over_2l() {
        // SEED000-SYSTEMS §4: U = R_t π²/(2L) = 1.303e-3 J for the paper's
        // wire (R_t = 2.3e-4 N·m², L = 0.871 m).
        let p = twisted(1.0);
        let c = p.compile().unwrap();
        let sol = optimize::solve(&c, c.natural_start(0.0), &Settings::default()).unwrap();
        let shape = c.shape(sol);
        let exact = 2.3e-4 * std::f64::consts::PI.powi(2) / (2.0 * 0.871);
        assert!((exact - 1.303e-3).abs() < 5e-7);
        assert!(shape.solution.converged, "{:?}", shape.solution);
        assert!(
            (shape.energy_j - exact).abs() < 1e-6 * exact,
            "U = {} J, want {exact}",
            shape.energy_j
        );
        assert!(shape.flexural_j < 1e-12);
    }
}

#[cfg(test)]
mod sequence_tests {
    use super::*;
    use crate::topology::{crossings, View};

    fn check(steps: &[SequenceStep]) {
        let free = |f: f64| {
            &steps
                .iter()
                .find(|s| (s.l_fraction - f).abs() < 1e-9)
                .unwrap()
                .free
        };
        let knot = |f: f64| {
            &steps
                .iter()
                .find(|s| (s.l_fraction - f).abs() < 1e-9)
                .unwrap()
                .knot
        };
        for st in steps {
            assert!(
                st.free.solution.converged && st.knot.solution.converged,
                "l = {}",
                st.l_fraction
            );
        }
        // 0.6 L: the knot-free shape is the lower; it is planar (no
        // torsion) and seen along y it does not cross itself.
        assert!(free(0.6).energy_j < knot(0.6).energy_j);
        assert!(free(0.6).torsional_j < 1e-12);
        assert_eq!(crossings(&free(0.6).x_m, View::along(V3::y())).len(), 0);
        // 0.1 L: the one-knot shape (a loop crossing itself once, with a
        // full turn of twist: R_t(2π)²/(2L) = 5.21e-3 J) is the lower.
        assert!(knot(0.1).energy_j < free(0.1).energy_j);
        assert_eq!(crossings(&knot(0.1).x_m, View::along(V3::y())).len(), 1);
        let full_turn = 2.3e-4 * (2.0 * std::f64::consts::PI).powi(2) / (2.0 * 0.871);
        assert!(
            (knot(0.1).torsional_j - full_turn).abs() < 0.05 * full_turn,
            "{}",
            knot(0.1).torsional_j
        );
        // Eq. 21–23 hold at the crossing: the strands touch (2r apart).
        let (su, sl) = knot(0.1).crossings_m[0];
        assert!(sl - su > 0.3 * 0.871 - 1e-6);
    }

    /// The whole sequence of L811 on the finer grid; the README's table.
    /// `cargo test --release -p plant-models --lib whole_end_distance -- --ignored --nocapture`
    #[test]
    #[ignore = "long in debug builds: run with --release (README)"]
    fn whole_end_distance_sequence() {
        let fr = [0.6, 0.5, 0.4, 0.3, 0.2, 0.1];
        let t0 = std::time::Instant::now();
        let steps = end_distance_sequence(
            &WireParams::paper_wire(),
            &fr,
            0.05,
            96,
            &Settings::default(),
        )
        .unwrap();
        eprintln!("sequence solved in {:?}", t0.elapsed());
        for st in &steps {
            eprintln!(
                "l = {:.1} L: knot-free {:.4e} J (flex {:.3e}), one-knot {:.4e} J (flex {:.3e}, tor {:.3e})",
                st.l_fraction, st.free.energy_j, st.free.flexural_j, st.knot.energy_j, st.knot.flexural_j, st.knot.torsional_j
            );
        }
        check(&steps);
    }
}
