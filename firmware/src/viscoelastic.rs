//! The 3-element viscoelastic model of seed 002 (§3, Eq. 3–12).
//!
//! A spring `k2` in series with a Kelvin–Voigt element (spring `k1` parallel
//! to a dashpot `b`):
//!
//! ```text
//!   f = k2 (u − x) = k1 x + b ẋ            (seed 002, Eq. 3)
//! ```
//!
//! where `u` is the total displacement and `x` the displacement of the damped
//! spring. Time is discretised with the seed's implicit first-order scheme,
//! `k1 x(t+h) + b (x(t+h) − x(t)) / h`, which is unconditionally stable and
//! converges to the continuous solution with error O(h).
//!
//! What is here:
//! - [`ThreeElement`]: the scalar model, both directions (displacement from
//!   force, Eq. 4–6 in 1D; force from displacement, Eq. 7–8 in 1D);
//! - [`ThreeElementTensor`]: the 3×3 tensor form for one (i, j) vertex pair,
//!   with its inverses precomputed for a fixed step (seed §5);
//! - [`RayleighParams`] and [`rayleigh_displacement_step`]: the
//!   stiffness-ratio parametrisation (Eq. 9–10) with Rayleigh damping
//!   (Eq. 11), i.e. the cheap update of Eq. 12, valid for any step;
//! - [`ViscoDgfm`]: the multi-vertex traction → displacement update over a
//!   discrete Green's function matrix Ξ with compile-time sizes and a list of
//!   active columns (seed §5), so the cost is O(N × active).
//!
//! What is not here: estimating the parameters from measurements and
//! computing a DGFM from a mesh (host side, `plant-models`).
//!
//! Naming follows the seed: `k2` is the instantaneous (series) spring, `k1`
//! the delayed spring, `b` the dashpot. In the SPEC's closed forms
//! `E1 = k2`, `E2 = k1`, `η = b`.
//!
//! A note on Eq. 12: the seed prints `α_j Ξ_ij f_j`. With `K = α_j Ξ_ij⁻¹`
//! (Eq. 2) and the general form (Eq. 5–6) fed a *force* `f_j`, the term that
//! appears is `K⁻¹ f_j = Ξ_ij f_j / α_j = Ξ_ij p_j`, with `p_j` the traction.
//! This module therefore takes tractions `p_j` in the Rayleigh and DGFM
//! forms; tests check it equals the general tensor form fed `f_j = α_j p_j`,
//! and that its static limit is exactly the DGFM product `Σ_j Ξ_ij p_j`
//! (the seed's requirement 2).

use crate::linalg::{Mat3, Vec3};
use crate::real::Real;

/// Why a set of viscoelastic parameters or a step was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ViscoError {
    /// `k1` must be finite and > 0.
    K1NotPositive,
    /// `k2` must be finite and > 0.
    K2NotPositive,
    /// `b` (dashpot, or Rayleigh coefficient) must be finite and ≥ 0.
    DampingNegative,
    /// The stiffness ratio `r = k2/k1` must be finite and > 0.
    RatioNotPositive,
    /// The node area `α_j` must be finite and > 0.
    AreaNotPositive,
    /// The time step must be finite and > 0.
    StepNotPositive,
    /// A tensor that must be inverted is singular or not finite.
    SingularTensor,
    /// A force, traction or displacement input was not finite.
    NonFiniteInput,
    /// A vertex index was outside the DGFM.
    VertexOutOfRange,
    /// More columns would be active than the compile-time capacity allows.
    ActiveListFull,
}

impl core::fmt::Display for ViscoError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ViscoError::K1NotPositive => "k1 (delayed spring) must be finite and > 0",
            ViscoError::K2NotPositive => "k2 (series spring) must be finite and > 0",
            ViscoError::DampingNegative => "b (damping) must be finite and >= 0",
            ViscoError::RatioNotPositive => "the stiffness ratio r = k2/k1 must be finite and > 0",
            ViscoError::AreaNotPositive => "the node area must be finite and > 0",
            ViscoError::StepNotPositive => "the time step must be finite and > 0",
            ViscoError::SingularTensor => "a tensor to invert is singular or not finite",
            ViscoError::NonFiniteInput => "a force, traction or displacement is not finite",
            ViscoError::VertexOutOfRange => "a vertex index is outside the DGFM",
            ViscoError::ActiveListFull => "more columns would be active than the capacity allows",
        })
    }
}

impl core::error::Error for ViscoError {}

/// A validated, strictly positive, finite time step in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TimeStep<T>(T);

impl<T: Real> TimeStep<T> {
    /// Accepts `h_s` when finite and > 0.
    pub fn new(h_s: T) -> Result<Self, ViscoError> {
        if h_s.is_finite() && h_s > T::zero() {
            Ok(TimeStep(h_s))
        } else {
            Err(ViscoError::StepNotPositive)
        }
    }

    /// The step in seconds.
    pub fn seconds(self) -> T {
        self.0
    }
}

/// Scalar 3-element parameters (seed 002 Eq. 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThreeElement<T> {
    k1: T,
    k2: T,
    b: T,
}

/// Internal state of one 3-element model: the damped spring's displacement.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ThreeElementState<T> {
    /// Displacement `x` of the Kelvin–Voigt part.
    pub x: T,
}

fn positive<T: Real>(v: T, err: ViscoError) -> Result<T, ViscoError> {
    if v.is_finite() && v > T::zero() {
        Ok(v)
    } else {
        Err(err)
    }
}

fn non_negative<T: Real>(v: T, err: ViscoError) -> Result<T, ViscoError> {
    if v.is_finite() && v >= T::zero() {
        Ok(v)
    } else {
        Err(err)
    }
}

impl<T: Real> ThreeElement<T> {
    /// Parameters `k1` (delayed spring), `k2` (series spring), `b` (dashpot).
    pub fn new(k1: T, k2: T, b: T) -> Result<Self, ViscoError> {
        Ok(Self {
            k1: positive(k1, ViscoError::K1NotPositive)?,
            k2: positive(k2, ViscoError::K2NotPositive)?,
            b: non_negative(b, ViscoError::DampingNegative)?,
        })
    }

    /// The stiffness-ratio form (seed 002 Eq. 9–11, scalar): a relaxed
    /// stiffness `k` split so that `k1` and `k2` in series equal `k`, with
    /// `r = k2/k1`, and a Rayleigh dashpot `b = b_rayleigh · k`.
    pub fn from_ratio(k: T, r: T, b_rayleigh_s: T) -> Result<Self, ViscoError> {
        let k = positive(k, ViscoError::K1NotPositive)?;
        let r = positive(r, ViscoError::RatioNotPositive)?;
        let br = non_negative(b_rayleigh_s, ViscoError::DampingNegative)?;
        Self::new((T::one() + r) / r * k, (T::one() + r) * k, br * k)
    }

    /// Delayed spring `k1`.
    pub fn k1(&self) -> T {
        self.k1
    }
    /// Series spring `k2`.
    pub fn k2(&self) -> T {
        self.k2
    }
    /// Dashpot `b`.
    pub fn b(&self) -> T {
        self.b
    }

    /// Static (relaxed) stiffness: `k1` and `k2` in series.
    pub fn relaxed_stiffness(&self) -> T {
        self.k1 * self.k2 / (self.k1 + self.k2)
    }

    /// Displacement at `t+h` for the force `f` applied at `t+h`
    /// (seed Eq. 5–6 in 1D): `x' = (f + (b/h)x)/(k1 + b/h)`, `u = f/k2 + x'`.
    pub fn step_displacement(
        &self,
        state: &mut ThreeElementState<T>,
        force: T,
        h: TimeStep<T>,
    ) -> T {
        let bh = self.b / h.0;
        state.x = (force + bh * state.x) / (self.k1 + bh);
        force / self.k2 + state.x
    }

    /// Force at `t+h` for the displacement `u` imposed at `t+h`
    /// (seed Eq. 7–8 in 1D): `x' = (k2 u + (b/h)x)/(k1 + k2 + b/h)`,
    /// `f = k2 (u − x')`.
    pub fn step_force(
        &self,
        state: &mut ThreeElementState<T>,
        displacement: T,
        h: TimeStep<T>,
    ) -> T {
        let bh = self.b / h.0;
        state.x = (self.k2 * displacement + bh * state.x) / (self.k1 + self.k2 + bh);
        self.k2 * (displacement - state.x)
    }
}

/// The 3×3 tensor form of the 3-element model for one (i, j) vertex pair
/// (seed Eq. 4–8), with the tensors it needs precomputed for a fixed step
/// `h` — the seed notes (§5) that the general form is only real-time when
/// `h` is held constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThreeElementTensor<T> {
    k2: Mat3<T>,
    k2_inv: Mat3<T>,
    /// (K1 + B/h)⁻¹, for displacement from force (Eq. 6).
    soft_inv: Mat3<T>,
    /// (K1 + K2 + B/h)⁻¹, for force from displacement (Eq. 8).
    stiff_inv: Mat3<T>,
    b_over_h: Mat3<T>,
    h: TimeStep<T>,
}

impl<T: Real> ThreeElementTensor<T> {
    /// Precomputes the update for tensors `K1`, `K2`, `B` and step `h`.
    pub fn new(k1: Mat3<T>, k2: Mat3<T>, b: Mat3<T>, h: TimeStep<T>) -> Result<Self, ViscoError> {
        if !(k1.is_finite() && k2.is_finite() && b.is_finite()) {
            return Err(ViscoError::NonFiniteInput);
        }
        let b_over_h = b.scale(T::one() / h.0);
        let k2_inv = k2.inverse().ok_or(ViscoError::SingularTensor)?;
        let soft_inv = (k1 + b_over_h)
            .inverse()
            .ok_or(ViscoError::SingularTensor)?;
        let stiff_inv = (k1 + k2 + b_over_h)
            .inverse()
            .ok_or(ViscoError::SingularTensor)?;
        Ok(Self {
            k2,
            k2_inv,
            soft_inv,
            stiff_inv,
            b_over_h,
            h,
        })
    }

    /// Builds the tensors of one DGFM entry from the stiffness-ratio form
    /// (Eq. 9–10): `K = α_j Ξ_ij⁻¹`, `K1 = (1+r)/r K`, `K2 = (1+r) K`, and a
    /// general damping tensor `B`.
    pub fn from_dgfm_entry(
        xi: Mat3<T>,
        area: T,
        ratio: T,
        damping: Mat3<T>,
        h: TimeStep<T>,
    ) -> Result<Self, ViscoError> {
        let area = positive(area, ViscoError::AreaNotPositive)?;
        let r = positive(ratio, ViscoError::RatioNotPositive)?;
        let k = xi.inverse().ok_or(ViscoError::SingularTensor)?.scale(area);
        Self::new(
            k.scale((T::one() + r) / r),
            k.scale(T::one() + r),
            damping,
            h,
        )
    }

    /// The step this update was precomputed for.
    pub fn step_size(&self) -> TimeStep<T> {
        self.h
    }

    /// Displacement from force (Eq. 5–6): `x' = (K1 + B/h)⁻¹ (f + (B/h) x)`,
    /// `u = K2⁻¹ f + x'`.
    pub fn step_displacement(&self, x: &mut Vec3<T>, force: Vec3<T>) -> Vec3<T> {
        *x = self.soft_inv.mul_vec(force + self.b_over_h.mul_vec(*x));
        self.k2_inv.mul_vec(force) + *x
    }

    /// Force from displacement (Eq. 7–8): `x' = (K1 + K2 + B/h)⁻¹ (K2 u +
    /// (B/h) x)`, `f = K2 (u − x')`.
    pub fn step_force(&self, x: &mut Vec3<T>, displacement: Vec3<T>) -> Vec3<T> {
        *x = self
            .stiff_inv
            .mul_vec(self.k2.mul_vec(displacement) + self.b_over_h.mul_vec(*x));
        self.k2.mul_vec(displacement - *x)
    }
}

/// Per-column parameters of the stiffness-ratio + Rayleigh form
/// (seed 002 Eq. 9–12): ratio `r = k2/k1` and Rayleigh coefficient `b`
/// (seconds) with `B_ij = b K_ij`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayleighParams<T> {
    ratio: T,
    b_s: T,
}

impl<T: Real> RayleighParams<T> {
    /// `ratio` must be > 0, `b_s` ≥ 0; both finite.
    pub fn new(ratio: T, b_s: T) -> Result<Self, ViscoError> {
        Ok(Self {
            ratio: positive(ratio, ViscoError::RatioNotPositive)?,
            b_s: non_negative(b_s, ViscoError::DampingNegative)?,
        })
    }
    /// Stiffness ratio `r`.
    pub fn ratio(&self) -> T {
        self.ratio
    }
    /// Rayleigh coefficient `b` in seconds.
    pub fn b_s(&self) -> T {
        self.b_s
    }

    /// The two scalars of Eq. 12 for step `h`: the weight of the
    /// instantaneous part `1/(1+r)` and the state gain `h r/(h + h r + b r)`.
    #[inline]
    fn coefficients(&self, h: T) -> (T, T, T) {
        let one = T::one();
        let r = self.ratio;
        let instant = one / (one + r);
        let gain = h * r / (h + h * r + self.b_s * r);
        (instant, gain, self.b_s / h)
    }
}

/// One (i, j) term of Eq. 12 given the static response `xi_p = Ξ_ij p_j`:
/// updates the state `x_ij` and returns `u_ij`.
#[inline]
fn rayleigh_term<T: Real>(xi_p: Vec3<T>, x: &mut Vec3<T>, coeff: (T, T, T)) -> Vec3<T> {
    let (instant, gain, b_over_h) = coeff;
    *x = (xi_p + x.scale(b_over_h)).scale(gain);
    xi_p.scale(instant) + *x
}

/// Displacement from traction for one (i, j) pair with Rayleigh damping
/// (seed 002 Eq. 12, written with the traction `p_j`; see the module docs):
/// `u_ij = Ξ_ij p_j/(1+r) + x_ij(t+h)`,
/// `x_ij(t+h) = h r/(h + h r + b r) · (Ξ_ij p_j + (b/h) x_ij(t))`.
/// Works for any step, with nothing precomputed.
pub fn rayleigh_displacement_step<T: Real>(
    xi: &Mat3<T>,
    traction: Vec3<T>,
    params: RayleighParams<T>,
    h: TimeStep<T>,
    x: &mut Vec3<T>,
) -> Vec3<T> {
    rayleigh_term(xi.mul_vec(traction), x, params.coefficients(h.0))
}

/// Force from displacement for one (i, j) pair with Rayleigh damping (the
/// substitution of Eq. 9–11 into Eq. 7–8 that the seed leaves out):
/// `x' = ((1+r) u + (b/h) x) / ((1+r)/r + 1 + r + b/h)`, `f = (1+r) K (u − x')`
/// with `K = α_j Ξ_ij⁻¹` passed in as `stiffness`.
pub fn rayleigh_force_step<T: Real>(
    stiffness: &Mat3<T>,
    displacement: Vec3<T>,
    params: RayleighParams<T>,
    h: TimeStep<T>,
    x: &mut Vec3<T>,
) -> Vec3<T> {
    let one = T::one();
    let r = params.ratio;
    let bh = params.b_s / h.0;
    let denom = (one + r) / r + one + r + bh;
    *x = (displacement.scale(one + r) + x.scale(bh)).scale(one / denom);
    stiffness.mul_vec(displacement - *x).scale(one + r)
}

/// One active column `j` of the DGFM: its applied traction and the states
/// `x_ij` for every row `i`.
#[derive(Clone, Debug)]
struct ActiveColumn<T, const N: usize> {
    vertex: u16,
    traction: Vec3<T>,
    x: [Vec3<T>; N],
}

/// Multi-vertex viscoelastic evaluation over a DGFM Ξ (N × N blocks of 3×3),
/// traction in, displacement out (seed 002 Eq. 4 with the Rayleigh update of
/// Eq. 12 and per-column parameters, §4.2), keeping at most `A` active
/// columns (§5): a column is active while traction is applied to it or while
/// its displacement effect `max_i |x_ij|` is above the rest threshold
/// (default 1e-3, the seed's figure). Cost per step: O(N · active).
///
/// Ξ is borrowed, so it can live in flash on a board or in a heap buffer on
/// the host; the state is `A · N · 3` values inside this struct.
pub struct ViscoDgfm<'a, T, const N: usize, const A: usize> {
    xi: &'a [[Mat3<T>; N]; N],
    columns: [RayleighParams<T>; N],
    active: heapless::Vec<ActiveColumn<T, N>, A>,
    rest_threshold: T,
}

/// Default displacement effect below which an unloaded column is dropped
/// from the active list (seed 002 §5: "above 1e-3").
pub const DEFAULT_REST_THRESHOLD: f64 = 1.0e-3;

impl<'a, T: Real, const N: usize, const A: usize> ViscoDgfm<'a, T, N, A> {
    /// A model over `xi` (`xi[i][j]` = Ξ_ij) with per-column parameters
    /// (the seed's column spreading, §4.2). Rejects non-finite Ξ entries.
    pub fn new(
        xi: &'a [[Mat3<T>; N]; N],
        columns: [RayleighParams<T>; N],
    ) -> Result<Self, ViscoError> {
        if N > u16::MAX as usize {
            return Err(ViscoError::VertexOutOfRange);
        }
        if !xi.iter().flat_map(|row| row.iter()).all(|m| m.is_finite()) {
            return Err(ViscoError::NonFiniteInput);
        }
        Ok(Self {
            xi,
            columns,
            active: heapless::Vec::new(),
            rest_threshold: T::lit(DEFAULT_REST_THRESHOLD),
        })
    }

    /// Changes the rest threshold (must be finite and ≥ 0).
    pub fn set_rest_threshold(&mut self, threshold: T) -> Result<(), ViscoError> {
        self.rest_threshold = non_negative(threshold, ViscoError::NonFiniteInput)?;
        Ok(())
    }

    /// Applies traction `p` to vertex `j` from the next step on (zero to
    /// release it; the column stays active until it has relaxed).
    pub fn set_traction(&mut self, vertex: usize, traction: Vec3<T>) -> Result<(), ViscoError> {
        if vertex >= N {
            return Err(ViscoError::VertexOutOfRange);
        }
        if !traction.is_finite() {
            return Err(ViscoError::NonFiniteInput);
        }
        if let Some(col) = self.active.iter_mut().find(|c| c.vertex as usize == vertex) {
            col.traction = traction;
            return Ok(());
        }
        if traction.is_zero() {
            return Ok(()); // an inactive column at rest stays inactive
        }
        self.active
            .push(ActiveColumn {
                vertex: vertex as u16,
                traction,
                x: [Vec3::zero(); N],
            })
            .map_err(|_| ViscoError::ActiveListFull)
    }

    /// Releases every traction (columns relax and then leave the list).
    pub fn release_all(&mut self) {
        for col in self.active.iter_mut() {
            col.traction = Vec3::zero();
        }
    }

    /// Number of active columns.
    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    /// Advances one step of `h` and writes every vertex displacement
    /// `u_i = Σ_j u_ij` into `out`.
    pub fn step(&mut self, h: TimeStep<T>, out: &mut [Vec3<T>; N]) {
        for u in out.iter_mut() {
            *u = Vec3::zero();
        }
        let threshold = self.rest_threshold;
        let xi = self.xi;
        let columns = &self.columns;
        for col in self.active.iter_mut() {
            let j = col.vertex as usize;
            let Some(params) = columns.get(j) else {
                continue;
            };
            let coeff = params.coefficients(h.0);
            let p = col.traction;
            for ((u, x), row) in out.iter_mut().zip(col.x.iter_mut()).zip(xi.iter()) {
                let Some(block) = row.get(j) else { continue };
                *u = *u + rayleigh_term(block.mul_vec(p), x, coeff);
            }
        }
        // Drop columns that carry no traction and whose effect has decayed.
        self.active
            .retain(|col| !col.traction.is_zero() || col.x.iter().any(|x| x.max_abs() > threshold));
    }

    /// The quasi-static elastic answer for the current tractions,
    /// `u_i = Σ_j Ξ_ij p_j` (seed 002 Eq. 1), over the active columns.
    pub fn static_displacement(&self, out: &mut [Vec3<T>; N]) {
        for u in out.iter_mut() {
            *u = Vec3::zero();
        }
        for col in self.active.iter() {
            let j = col.vertex as usize;
            for (u, row) in out.iter_mut().zip(self.xi.iter()) {
                if let Some(block) = row.get(j) {
                    *u = *u + block.mul_vec(col.traction);
                }
            }
        }
    }
}
