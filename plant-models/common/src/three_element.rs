//! The 3-element viscoelastic model (seed 002 Eq. 3) as the plant
//! integrates it: exactly, over steps whose input is linear in time.
//!
//! A spring `k2` in series with a Kelvin–Voigt element (`k1` ∥ dashpot `b`):
//! `f = k2 (u − x) = k1 x + b ẋ`. Between two samples the input (force or
//! displacement) is taken as the straight line through them — a step input
//! is a jump at a sample instant followed by a constant — and the ordinary
//! differential equation for the dashpot displacement `x` is solved in
//! closed form over the step. The update is therefore exact, for any step
//! length, for every load made of ramps and holds (creep, relaxation,
//! constant-velocity probing, piecewise-constant tractions), and second
//! order in the step for smooth loads.
//!
//! This is the plant's own code, chosen for accuracy: the firmware's core
//! integrates the same model with the seed's implicit first-order scheme,
//! and is tested *against* this one (`tests/tests/visco_core_vs_plant.rs`);
//! the two share nothing.
//!
//! Derivation (force in, displacement out): `b ẋ = f − k1 x`, so with
//! `a = k1/b`, `E = e^(−a h)` and `φ = (1 − E)/(a h)`, for `f` linear from
//! `f0` to `f1` over the step,
//! `x1 = E x0 + [f1 − E f0 − (f1 − f0) φ] / k1` and `u1 = f1/k2 + x1`.
//! Displacement in, force out: `b ẋ = k2 u − (k1 + k2) x`, the same form
//! with `a = (k1 + k2)/b` and input gain `k2/(k1 + k2)`; `f1 = k2 (u1 − x1)`.
//! A tensor element (`B ẋ = f − K1 x`) has the same solution with matrix
//! exponentials, computed by Van Loan's block-matrix exponential so that no
//! `A⁻¹` appears (stiff and weakly damped directions alike).
//!
//! Left out: nonlinear (large-strain) springs and dashpots.
use nalgebra::{Matrix3, SMatrix, Vector3};

use crate::scalar::Scalar;

use crate::check::{
    named_non_negative as check_non_negative, named_positive as check_positive, ParamError,
};

/// The result of building an element or a step: a refused parameter is named.
pub type Result<T> = std::result::Result<T, ParamError>;

/// `(E, φ)` of one step: `E = e^(−a h)`, `φ = (1 − E)/(a h)`, with the
/// limits `(0, 0)` for no damping (`a h = ∞`) and `(1, 1)` for `a h → 0`.
fn decay(a_h: f64) -> (f64, f64) {
    decay_of(a_h)
}

/// [`decay`] of any [`Scalar`]: the limits by value, carrying no
/// derivative.
#[inline(always)]
fn decay_of<S: Scalar>(a_h: S) -> (S, S) {
    if a_h.val().is_infinite() {
        (S::cst(0.0), S::cst(0.0))
    } else if a_h.val() < 1e-300 {
        (S::cst(1.0), S::cst(1.0))
    } else {
        // 1 − E by expm1: no cancellation for small a h.
        let one_minus_e = -(-a_h).exp_m1();
        (-one_minus_e + 1.0, one_minus_e / a_h)
    }
}

/// A step length: finite and > 0 seconds.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct StepLength(f64);

impl StepLength {
    /// Accepts `h_s` when finite and > 0, naming it `h` otherwise.
    pub fn new(h_s: f64) -> Result<Self> {
        Ok(StepLength(check_positive("h", h_s)?))
    }

    /// The step in seconds.
    pub fn seconds(self) -> f64 {
        self.0
    }
}

/// Scalar 3-element parameters: `k1` (delayed spring), `k2` (series
/// spring), `b` (dashpot). In the SPEC's closed forms `E1 = k2`, `E2 = k1`,
/// `η = b`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Element {
    k1: f64,
    k2: f64,
    b: f64,
}

impl Element {
    /// Checks `k1 > 0`, `k2 > 0`, `b ≥ 0` (finite), naming the parameter.
    pub fn new(k1: f64, k2: f64, b: f64) -> Result<Self> {
        let (k1, k2) = (check_positive("k1", k1)?, check_positive("k2", k2)?);
        if !(k1 + k2).is_finite() {
            // The exact step divides by k1 + k2: an overflowed sum would
            // give a wrong (not a NaN) answer.
            return Err(ParamError {
                name: "k1 + k2",
                value: k1 + k2,
                reason: "the two springs' sum overflows f64",
            });
        }
        Ok(Self {
            k1,
            k2,
            b: check_non_negative("b", b)?,
        })
    }

    /// The stiffness-ratio form (seed 002 Eq. 9–11, scalar): relaxed
    /// stiffness `k` split so that `k1` and `k2` in series equal `k`, with
    /// `r = k2/k1`, and a Rayleigh dashpot `b = b_R·k`.
    pub fn from_ratio(k: f64, ratio: f64, rayleigh_b_s: f64) -> Result<Self> {
        let k = check_positive("k", k)?;
        let r = check_positive("ratio", ratio)?;
        let br = check_non_negative("rayleigh_b_s", rayleigh_b_s)?;
        Self::new((1.0 + r) / r * k, (1.0 + r) * k, br * k)
    }

    /// Delayed spring `k1`.
    pub fn k1(&self) -> f64 {
        self.k1
    }
    /// Series spring `k2`.
    pub fn k2(&self) -> f64 {
        self.k2
    }
    /// Dashpot `b`.
    pub fn b(&self) -> f64 {
        self.b
    }
    /// Relaxed stiffness: `k1` and `k2` in series.
    pub fn relaxed_stiffness(&self) -> f64 {
        self.k1 * self.k2 / (self.k1 + self.k2)
    }

    /// The exact update over steps of `h`, displacement from force.
    pub fn creep_step(&self, h: StepLength) -> ExactStep {
        let (e, phi) = decay(self.k1 / self.b * h.0);
        ExactStep {
            e,
            phi,
            gain: 1.0 / self.k1,
            k2: self.k2,
        }
    }

    /// The exact update over steps of `h`, force from displacement.
    pub fn relaxation_step(&self, h: StepLength) -> ExactStep {
        let (e, phi) = decay((self.k1 + self.k2) / self.b * h.0);
        ExactStep {
            e,
            phi,
            gain: self.k2 / (self.k1 + self.k2),
            k2: self.k2,
        }
    }
}

/// The exact update of one element over one step length (see the module
/// docs), for scalars or for vectors whose components share the element
/// (Rayleigh damping makes a tensor element act like this on every axis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactStep {
    e: f64,
    phi: f64,
    /// Input → dashpot gain: `1/k1` (force in) or `k2/(k1 + k2)`
    /// (displacement in).
    gain: f64,
    k2: f64,
}

impl ExactStep {
    /// The dashpot displacement at the end of the step from `x0`, for an
    /// input going linearly from `start` (just after any jump at the start
    /// instant) to `end`.
    #[inline]
    pub fn dashpot<V>(&self, x0: V, start: V, end: V) -> V
    where
        V: Copy
            + core::ops::Add<Output = V>
            + core::ops::Sub<Output = V>
            + core::ops::Mul<f64, Output = V>,
    {
        x0 * self.e + (end - start * self.e - (end - start) * self.phi) * self.gain
    }

    /// Creep form: the total displacement at the end of a step whose force
    /// goes from `f_start` to `f_end`; advances `x`.
    #[inline]
    pub fn displacement<V>(&self, x: &mut V, f_start: V, f_end: V) -> V
    where
        V: Copy
            + core::ops::Add<Output = V>
            + core::ops::Sub<Output = V>
            + core::ops::Mul<f64, Output = V>,
    {
        *x = self.dashpot(*x, f_start, f_end);
        f_end * (1.0 / self.k2) + *x
    }

    /// Relaxation form: the force at the end of a step whose displacement
    /// goes from `u_start` to `u_end`; advances `x`.
    #[inline]
    pub fn force<V>(&self, x: &mut V, u_start: V, u_end: V) -> V
    where
        V: Copy
            + core::ops::Add<Output = V>
            + core::ops::Sub<Output = V>
            + core::ops::Mul<f64, Output = V>,
    {
        *x = self.dashpot(*x, u_start, u_end);
        (u_end - *x) * self.k2
    }
}

/// Two elements' exact relaxation steps side by side (a sponge column's
/// shear and normal models): the same operations in the same order as two
/// [`ExactStep::force`] calls, so the results are bit-identical, laid out
/// so that both lanes share one SIMD instruction each. Over a [`Scalar`]:
/// with duals ([`ExactPair::relaxation`]) the step carries the
/// derivatives of its coefficients with respect to the springs and the
/// dashpot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExactPair<S = f64> {
    e: [S; 2],
    phi: [S; 2],
    gain: [S; 2],
    k2: [S; 2],
}

impl From<[ExactStep; 2]> for ExactPair {
    fn from(steps: [ExactStep; 2]) -> Self {
        Self {
            e: steps.map(|s| s.e),
            phi: steps.map(|s| s.phi),
            gain: steps.map(|s| s.gain),
            k2: steps.map(|s| s.k2),
        }
    }
}

impl<S: Scalar> ExactPair<S> {
    /// The relaxation steps of two elements given as (`k1`, `k2`, `b`) in
    /// any scalar: with `f64` the same numbers as
    /// [`Element::relaxation_step`] (checked by a test), with duals their
    /// derivatives too. The elements are taken as valid (`k1`, `k2` > 0,
    /// `b` ≥ 0: built by [`Element::new`] for their values).
    pub fn relaxation(elements: [(S, S, S); 2], h: StepLength) -> Self {
        let lane = |(k1, k2, b): (S, S, S)| {
            let (e, phi) = decay_of((k1 + k2) / b * h.0);
            (e, phi, k2 / (k1 + k2), k2)
        };
        let [a, c] = elements.map(lane);
        Self {
            e: [a.0, c.0],
            phi: [a.1, c.1],
            gain: [a.2, c.2],
            k2: [a.3, c.3],
        }
    }

    /// [`ExactStep::force`] of both lanes.
    #[inline(always)]
    pub fn force(&self, x: &mut [S; 2], u_start: [S; 2], u_end: [S; 2]) -> [S; 2] {
        let mut f = [S::cst(0.0); 2];
        for i in 0..2 {
            let (start, end) = (u_start[i], u_end[i]);
            x[i] = x[i] * self.e[i]
                + (end - start * self.e[i] - (end - start) * self.phi[i]) * self.gain[i];
            f[i] = (end - x[i]) * self.k2[i];
        }
        f
    }
}

/// Per-column parameters of the stiffness-ratio + Rayleigh form (seed 002
/// Eq. 9–12): ratio `r = k2/k1` and Rayleigh coefficient `b` (s) with
/// `B_ij = b K_ij`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayleighColumn {
    ratio: f64,
    b_s: f64,
}

impl RayleighColumn {
    /// `ratio > 0`, `b_s ≥ 0`, both finite.
    pub fn new(ratio: f64, b_s: f64) -> Result<Self> {
        Ok(Self {
            ratio: check_positive("ratio", ratio)?,
            b_s: check_non_negative("rayleigh_b_s", b_s)?,
        })
    }
    /// Stiffness ratio `r`.
    pub fn ratio(&self) -> f64 {
        self.ratio
    }
    /// Rayleigh coefficient `b` (s).
    pub fn b_s(&self) -> f64 {
        self.b_s
    }

    /// The exact step of one (i, j) pair of this column, traction in.
    ///
    /// With `K = α_j Ξ_ij⁻¹`, `K1 = (1+r)/r K`, `K2 = (1+r) K`, `B = b K`
    /// and the nodal force `f = α_j p`, `B ẋ = f − K1 x` becomes
    /// `b ẋ = Ξ_ij p − ((1+r)/r) x` — the scalar creep element with
    /// `k1 = (1+r)/r`, `k2 = 1 + r`, dashpot `b`, driven by the static
    /// response `y = Ξ_ij p` — and `u_ij = y/(1+r) + x`.
    pub fn step(&self, h: StepLength) -> ExactStep {
        let r = self.ratio;
        // r > 0 and b ≥ 0 are finite (checked by `new`), so these are a
        // valid element's parameters.
        Element {
            k1: (1.0 + r) / r,
            k2: 1.0 + r,
            b: self.b_s,
        }
        .creep_step(h)
    }
}

/// For `ẋ = −A x + g(s)` over a step of `h` with `g` linear: `e^(−A h)`,
/// `Φ0 = ∫₀ʰ e^(−A(h−s)) ds` and `Φ1 = ∫₀ʰ (s/h) e^(−A(h−s)) ds`, so that
/// `x(h) = e^(−Ah) x(0) + Φ0 g(0) + Φ1 (g(h) − g(0))`. Van Loan's method:
/// all three are blocks of `exp(h C)` with `C = [[−A, I, 0], [0, 0, I/h],
/// [0, 0, 0]]`, so no `A⁻¹` appears (stiff and weak directions alike).
fn van_loan(a: Matrix3<f64>, h: f64) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
    let mut c = SMatrix::<f64, 9, 9>::zeros();
    c.fixed_view_mut::<3, 3>(0, 0).copy_from(&(-a * h));
    c.fixed_view_mut::<3, 3>(0, 3)
        .copy_from(&(Matrix3::identity() * h));
    c.fixed_view_mut::<3, 3>(3, 6)
        .copy_from(&Matrix3::identity());
    let ex = c.exp();
    (
        ex.fixed_view::<3, 3>(0, 0).into(),
        ex.fixed_view::<3, 3>(0, 3).into(),
        ex.fixed_view::<3, 3>(0, 6).into(),
    )
}

/// One (i, j) pair in the general tensor form (seed 002 Eq. 5–6):
/// `B ẋ = f − K1 x`, `u = K2⁻¹ f + x`, updated exactly over a fixed step for
/// a force linear over the step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensorPair {
    /// `e^(−A h)`, `A = B⁻¹ K1`.
    e: Matrix3<f64>,
    /// `∫₀ʰ e^(−A(h−s)) ds · B⁻¹`: weight of the force at the step's start.
    m0: Matrix3<f64>,
    /// `∫₀ʰ (s/h) e^(−A(h−s)) ds · B⁻¹`: weight of the force's change.
    m1: Matrix3<f64>,
    k2_inv: Matrix3<f64>,
}

impl TensorPair {
    /// Precomputes the pair for tensors `K1`, `K2`, `B` and step `h_s`.
    /// `B = 0` is the elastic limit (`x = K1⁻¹ f`); otherwise `B` must be
    /// invertible (a dashpot that resists every direction).
    pub fn new(k1: Matrix3<f64>, k2: Matrix3<f64>, b: Matrix3<f64>, h: StepLength) -> Result<Self> {
        let h = h.0;
        let finite = |m: &Matrix3<f64>| m.iter().all(|v| v.is_finite());
        if !(finite(&k1) && finite(&k2) && finite(&b)) {
            return Err(ParamError {
                name: "tensor",
                value: f64::NAN,
                reason: "K1, K2 and B must be finite",
            });
        }
        let singular = |name| ParamError {
            name,
            value: 0.0,
            reason: "singular: the tensor form needs it invertible",
        };
        let k2_inv = k2.try_inverse().ok_or(singular("K2"))?;
        if b.iter().all(|v| *v == 0.0) {
            let k1_inv = k1.try_inverse().ok_or(singular("K1"))?;
            // x1 = K1⁻¹ f0 + K1⁻¹ (f1 − f0) = K1⁻¹ f1.
            return Ok(Self {
                e: Matrix3::zeros(),
                m0: k1_inv,
                m1: k1_inv,
                k2_inv,
            });
        }
        let b_inv = b.try_inverse().ok_or(singular("B"))?;
        let (e, phi0, phi1) = van_loan(b_inv * k1, h);
        let pair = Self {
            e,
            m0: phi0 * b_inv,
            m1: phi1 * b_inv,
            k2_inv,
        };
        let all_finite = [pair.e, pair.m0, pair.m1].iter().all(finite);
        if !all_finite {
            return Err(ParamError {
                name: "tensor",
                value: h,
                reason: "the exact step of these tensors is not finite",
            });
        }
        Ok(pair)
    }

    /// The total displacement at the end of a step whose force goes
    /// linearly from `f_start` to `f_end`; advances `x`.
    pub fn displacement(
        &self,
        x: &mut Vector3<f64>,
        f_start: Vector3<f64>,
        f_end: Vector3<f64>,
    ) -> Vector3<f64> {
        *x = self.e * *x + self.m0 * f_start + self.m1 * (f_end - f_start);
        self.k2_inv * f_end + *x
    }
}

/// A DGFM column with a general damping tensor `B_j` (seed 002 §4.1,
/// Eq. 5–6, 9–10), spread down the column as its relaxation-rate tensor.
///
/// For the self pair the seed's form `B_j ẋ = α_j p − K1_jj x` is
/// `ẋ = R_j (y − c x)` with `R_j = B_j⁻¹ K_jj`, the static response
/// `y = Ξ_jj p` and `c = (1+r)/r`. Every pair (i, j) of the column uses the
/// same `R_j` on its own static response `y = Ξ_ij p`:
/// `ẋ_ij = R_j (Ξ_ij p − c x_ij)`, `u_ij = Ξ_ij p/(1+r) + x_ij`. This is the
/// seed's own equation on the diagonal and its Rayleigh form when
/// `B_j = b K_jj` (`R_j = I/b`), and it is well posed whenever the column's
/// measured material is passive (`R_j` with eigenvalues of positive real
/// part, true for symmetric positive definite `B_j` and `K_jj`).
///
/// The seed's literal spreading (`B_·,k = B_k` against every `K_ik`) is
/// not: `K_ik` of distant vertices is indefinite, and
/// `B_k⁻¹ k1 K_ik` then has eigenvalues of negative real part — growth as
/// `e^(|λ| t)`. On the shipped object that is 10,738 of 24,025 pairs
/// (`plant-models/viscoelastic/tests/it/dgfm.rs`); the implicit first-order scheme
/// hides it where `|λ| h ≫ 1` and blows up where `λ h ≈ −1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensorColumn {
    instant: f64,
    e: Matrix3<f64>,
    m0: Matrix3<f64>,
    m1: Matrix3<f64>,
}

impl TensorColumn {
    /// The column of vertex j with self stiffness `K_jj` (N/m), damping
    /// tensor `B_j` (N·s/m; zero for no damping), stiffness ratio `r`, for
    /// steps of `h`. Refuses a non-passive column naming its relaxation
    /// rate.
    pub fn new(k_jj: Matrix3<f64>, b_j: Matrix3<f64>, ratio: f64, h: StepLength) -> Result<Self> {
        let r = check_positive("ratio", ratio)?;
        let c = (1.0 + r) / r;
        let instant = 1.0 / (1.0 + r);
        if !(k_jj.iter().all(|v| v.is_finite()) && b_j.iter().all(|v| v.is_finite())) {
            return Err(ParamError {
                name: "tensor",
                value: f64::NAN,
                reason: "K_jj and B_j must be finite",
            });
        }
        if b_j.iter().all(|v| *v == 0.0) {
            // No damping: the dashpot follows at once, x = y/c.
            let i_c = Matrix3::identity() / c;
            return Ok(Self {
                instant,
                e: Matrix3::zeros(),
                m0: i_c,
                m1: i_c,
            });
        }
        let b_inv = b_j.try_inverse().ok_or(ParamError {
            name: "B_j",
            value: 0.0,
            reason: "singular: a damping tensor must resist every direction (or be zero)",
        })?;
        let rate = b_inv * k_jj;
        let slowest = rate
            .complex_eigenvalues()
            .iter()
            .map(|l| l.re)
            .fold(f64::INFINITY, f64::min);
        if slowest.is_nan() || slowest <= 0.0 {
            return Err(ParamError {
                name: "B_j",
                value: slowest,
                reason: "B_j⁻¹ K_jj has a relaxation rate (1/s) without a positive real part: not a passive material",
            });
        }
        let (e, phi0, phi1) = van_loan(rate * c, h.0);
        let col = Self {
            instant,
            e,
            m0: phi0 * rate,
            m1: phi1 * rate,
        };
        if ![col.e, col.m0, col.m1]
            .iter()
            .all(|m| m.iter().all(|v| v.is_finite()))
        {
            return Err(ParamError {
                name: "B_j",
                value: h.0,
                reason: "the exact step of this column is not finite",
            });
        }
        Ok(col)
    }

    /// `u_ij` at the end of a step whose static response `y = Ξ_ij p` goes
    /// linearly from `y_start` to `y_end`; advances `x = x_ij`.
    #[inline]
    pub fn displacement(
        &self,
        x: &mut Vector3<f64>,
        y_start: Vector3<f64>,
        y_end: Vector3<f64>,
    ) -> Vector3<f64> {
        *x = self.e * *x + self.m0 * y_start + self.m1 * (y_end - y_start);
        y_end * self.instant + *x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Seed 002 Fig. 5's example: k1 = 1.5, k2 = 3.0, b = 0.5.
    const K1: f64 = 1.5;
    const K2: f64 = 3.0;
    const B: f64 = 0.5;

    #[test]
    fn the_pair_is_bit_identical_to_two_single_steps() {
        let models = [
            Element::new(K1, K2, B).unwrap(),
            Element::new(40.0, 7.0, 0.3).unwrap(),
        ];
        let h = StepLength::new(2.5e-4).unwrap();
        let steps = models.map(|m| m.relaxation_step(h));
        let pair = ExactPair::from(steps);
        let (mut xs, mut xp) = ([0.1, -0.2], [0.1, -0.2]);
        let mut start = [0.0, 0.0];
        for k in 0..1000 {
            let end = [
                (k as f64 * 0.37).sin() * 1e-3,
                (k as f64 * 0.11).cos() * 2e-3,
            ];
            let single = [0, 1].map(|i| steps[i].force(&mut xs[i], start[i], end[i]));
            let paired = pair.force(&mut xp, start, end);
            assert_eq!(single.map(f64::to_bits), paired.map(f64::to_bits));
            assert_eq!(xs.map(f64::to_bits), xp.map(f64::to_bits));
            start = end;
        }
    }

    /// The generic pair from (k1, k2, b) is the elements' own steps to
    /// the bit with f64, and with duals its derivatives are those of the
    /// force along a run (against central differences).
    #[test]
    fn the_generic_pair_is_the_elements_steps_and_differentiates() {
        use crate::scalar::Dual;
        let h = StepLength::new(1e-3).unwrap();
        for (k, ratio, b) in [(40.0, 3.0, 0.05), (2.5e3, 0.7, 1e-4), (1.0, 9.0, 30.0)] {
            let el = [
                Element::from_ratio(k, ratio, b).unwrap(),
                Element::from_ratio(2.0 * k, ratio, b).unwrap(),
            ];
            let from_steps = ExactPair::from(el.map(|e| e.relaxation_step(h)));
            let generic = ExactPair::<f64>::relaxation(el.map(|e| (e.k1(), e.k2(), e.b())), h);
            assert_eq!(format!("{from_steps:?}"), format!("{generic:?}"));
            // Force after 300 steps of a wiggling input, and its
            // derivatives with respect to k and b.
            let run = |k: f64, b: f64| -> f64 {
                let el = [
                    Element::from_ratio(k, ratio, b).unwrap(),
                    Element::from_ratio(2.0 * k, ratio, b).unwrap(),
                ];
                let pair = ExactPair::<f64>::relaxation(el.map(|e| (e.k1(), e.k2(), e.b())), h);
                let (mut x, mut u) = ([0.0; 2], [0.0; 2]);
                let mut f = [0.0; 2];
                for i in 0..300 {
                    let end = [
                        (i as f64 * 0.05).sin() * 1e-3,
                        (i as f64 * 0.02).cos() * 1e-3,
                    ];
                    f = pair.force(&mut x, u, end);
                    u = end;
                }
                f[0] + f[1]
            };
            let (kd, bd) = (Dual::<2>::var(k, 0), Dual::<2>::var(b, 1));
            let lanes =
                [kd, kd * 2.0].map(|k| (k * ((1.0 + ratio) / ratio), k * (1.0 + ratio), bd * k));
            let pair = ExactPair::relaxation(lanes, h);
            let (mut x, mut u) = ([Dual::cst(0.0); 2], [Dual::cst(0.0); 2]);
            let mut f = [Dual::cst(0.0); 2];
            for i in 0..300 {
                let end = [
                    (i as f64 * 0.05).sin() * 1e-3,
                    (i as f64 * 0.02).cos() * 1e-3,
                ]
                .map(Dual::cst);
                f = pair.force(&mut x, u, end);
                u = end;
            }
            let fd = f[0] + f[1];
            assert!((fd.v - run(k, b)).abs() <= 1e-12 * run(k, b).abs().max(1e-30));
            for (j, (dk, db)) in [(1e-6 * k, 0.0), (0.0, 1e-6 * b)].into_iter().enumerate() {
                let diff = (run(k + dk, b + db) - run(k - dk, b - db)) / (2.0 * (dk + db));
                assert!(
                    (fd.d[j] - diff).abs() <= 1e-6 * diff.abs().max(1e-12),
                    "k {k} b {b}: ∂{j} {} vs {diff}",
                    fd.d[j]
                );
            }
        }
    }

    #[test]
    fn creep_relaxation_and_ramps_are_exact_for_any_step() {
        let m = Element::new(K1, K2, B).unwrap();
        let (e_inf, tau_s, tau_c) = (K1 * K2 / (K1 + K2), B / (K1 + K2), B / K1);
        for h in [0.1, 0.013, 1e-3] {
            let creep = m.creep_step(StepLength::new(h).unwrap());
            let relax = m.relaxation_step(StepLength::new(h).unwrap());
            let (mut xc, mut xr, mut xv) = (0.0, 0.0, 0.0);
            let (f0, u0, rate) = (2.0, 0.4, 0.7);
            let n = (1.0 / h).round() as usize;
            for k in 1..=n {
                let t = k as f64 * h;
                let u = creep.displacement(&mut xc, f0, f0);
                let want = f0 / K2 + f0 / K1 * (1.0 - (-t / tau_c).exp());
                assert!((u - want).abs() < 1e-13, "creep h = {h}, t = {t}");
                let f = relax.force(&mut xr, u0, u0);
                let want = u0 * (e_inf + (K2 - e_inf) * (-t / tau_s).exp());
                assert!((f - want).abs() < 1e-13, "relaxation h = {h}, t = {t}");
                let f = relax.force(&mut xv, rate * (t - h), rate * t);
                let want = rate * (e_inf * t + (K2 - e_inf) * tau_s * (1.0 - (-t / tau_s).exp()));
                assert!((f - want).abs() < 1e-13, "ramp h = {h}, t = {t}");
            }
        }
    }

    #[test]
    fn no_damping_is_the_elastic_limit_and_huge_damping_the_instantaneous_one() {
        let ms = StepLength::new(1e-3).unwrap();
        let elastic = Element::new(K1, K2, 0.0).unwrap().creep_step(ms);
        let mut x = 0.0;
        let u = elastic.displacement(&mut x, 2.0, 2.0);
        assert!((u - 2.0 * (1.0 / K1 + 1.0 / K2)).abs() < 1e-15);
        let stiff = Element::new(K1, K2, 1e300).unwrap().creep_step(ms);
        let mut x = 0.0;
        let u = stiff.displacement(&mut x, 2.0, 2.0);
        assert!((u - 2.0 / K2).abs() < 1e-12);
    }

    #[test]
    fn a_rayleigh_tensor_pair_equals_the_scalar_form_on_every_axis() {
        // K SPD, B = b K: A = (1+r)/(r b) I, so the tensor pair must equal
        // the Rayleigh column step applied to y = K⁻¹ f.
        let k = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0);
        let (r, b) = (1.7, 0.08);
        let h = StepLength::new(2e-3).unwrap();
        let pair = TensorPair::new(k * ((1.0 + r) / r), k * (1.0 + r), k * b, h).unwrap();
        let col = RayleighColumn::new(r, b).unwrap().step(h);
        let k_inv = k.try_inverse().unwrap();
        let (mut xt, mut xs) = (Vector3::zeros(), Vector3::zeros());
        for n in 0..200 {
            let f0 = Vector3::new(0.3 * n as f64, -1.0, 2.0);
            let f1 = Vector3::new(0.3 * (n + 1) as f64, -1.0, if n < 100 { 2.0 } else { 0.5 });
            let ut = pair.displacement(&mut xt, f0, f1);
            let us = col.displacement(&mut xs, k_inv * f0, k_inv * f1);
            // Rayleigh's u = y/(1+r) + x with y = K⁻¹ f; the scalar form's
            // own u is y/k2 + x with k2 = 1 + r: the same.
            assert!(
                (ut - us).amax() < 1e-12 * us.amax().max(1e-12),
                "step {n}: {ut} vs {us}"
            );
        }
    }

    #[test]
    fn a_tensor_column_is_the_seeds_form_on_the_diagonal_and_rayleigh_for_b_k() {
        let k = Matrix3::new(4.0, 1.0, 0.5, 1.0, 3.0, -0.2, 0.5, -0.2, 2.0);
        let b = Matrix3::new(0.3, 0.05, 0.0, 0.05, 0.2, 0.01, 0.0, 0.01, 0.25);
        let r = 0.8;
        let h = StepLength::new(1e-3).unwrap();
        let col = TensorColumn::new(k, b, r, h).unwrap();
        // The self pair as the seed writes it: B ẋ = f − K1 x, u = K2⁻¹ f + x,
        // with f = K y (α Ξ⁻¹ times Ξ p).
        let pair = TensorPair::new(k * ((1.0 + r) / r), k * (1.0 + r), b, h).unwrap();
        let (mut xc, mut xp) = (Vector3::zeros(), Vector3::zeros());
        for n in 0..300 {
            let y = Vector3::new(1e-3, if n < 150 { -2e-3 } else { 0.0 }, 5e-4);
            let uc = col.displacement(&mut xc, y, y);
            let up = pair.displacement(&mut xp, k * y, k * y);
            assert!((uc - up).amax() < 1e-12, "step {n}: {uc} vs {up}");
        }
        // B = b K: the Rayleigh column on every axis.
        let ray = TensorColumn::new(k, k * 0.05, r, h).unwrap();
        let scalar = RayleighColumn::new(r, 0.05).unwrap().step(h);
        let (mut xt, mut xs) = (Vector3::zeros(), Vector3::zeros());
        let y = Vector3::new(1.0, -2.0, 0.5);
        for _ in 0..100 {
            let ut = ray.displacement(&mut xt, y, y);
            let us = scalar.displacement(&mut xs, y, y);
            assert!((ut - us).amax() < 1e-12);
        }
        // A damping that feeds energy in is refused, by name.
        let e = TensorColumn::new(k, -b, r, h).unwrap_err().to_string();
        assert!(e.contains("B_j") && e.contains("passive"), "{e}");
    }

    #[test]
    fn bad_parameters_are_named() {
        assert!(Element::new(0.0, 1.0, 1.0)
            .unwrap_err()
            .to_string()
            .contains("k1"));
        assert!(Element::new(1.0, f64::NAN, 1.0)
            .unwrap_err()
            .to_string()
            .contains("k2"));
        assert!(Element::new(1.0, 1.0, -1.0)
            .unwrap_err()
            .to_string()
            .contains("`b`"));
        assert!(RayleighColumn::new(-1.0, 0.1).is_err());
        let e = Element::new(1e308, 1e308, 1.0).unwrap_err().to_string();
        assert!(e.contains("k1 + k2") && e.contains("overflows"), "{e}");
        let singular = Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
        let ms = StepLength::new(1e-3).unwrap();
        let e =
            TensorPair::new(Matrix3::identity(), Matrix3::identity(), singular, ms).unwrap_err();
        assert!(StepLength::new(0.0)
            .unwrap_err()
            .to_string()
            .contains("`h`"));
        assert!(e.to_string().contains("`B`"), "{e}");
    }
}
