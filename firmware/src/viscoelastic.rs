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
//!   discrete Green's function matrix Ξ with a list of active columns (seed
//!   §5), so the cost is O(n × active); its columns are Rayleigh
//!   ([`RayleighColumns`]) or general damping tensors ([`TensorColumns`]), and
//!   its storage is the caller's (static arrays on a board, [`DgfmBuffers`],
//!   or buffers sized at run time on the host).
//!
//! What is not here: estimating the parameters from measurements and
//! computing a DGFM from a mesh (host side, `plant-models`). The plant's
//! viscoelastic solids do not use this module: they integrate the same
//! model with their own (exact) f64 code, and this module is tested against
//! them (`tests/tests/visco_core_vs_plant.rs`).
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
use core::marker::PhantomData;

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
    /// More columns would be active than the storage allows.
    ActiveListFull,
    /// A tensor pair precomputed for one step was asked for another.
    StepMismatch,
    /// Storage or an output does not match the vertex count.
    StorageMismatch,
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
            ViscoError::ActiveListFull => "more columns would be active than the storage allows",
            ViscoError::StepMismatch => {
                "tensor damping is precomputed for one fixed step; rebuild it for another"
            }
            ViscoError::StorageMismatch => {
                "storage or output length does not match the number of vertices"
            }
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

/// How the (i, j) terms of one DGFM column are advanced: the Rayleigh form
/// ([`RayleighColumns`], Eq. 12, any step) or precomputed general damping
/// tensors ([`TensorColumns`], Eq. 5–6, one fixed step).
pub trait ColumnUpdate<T> {
    /// Number of traction vertices n.
    fn vertices(&self) -> usize;
    /// Whether steps of `h` can be taken (a precomputed update has one).
    fn check_step(&self, h: TimeStep<T>) -> Result<(), ViscoError> {
        let _ = h;
        Ok(())
    }
    /// Advances column `j` by `h` under traction `p`: updates the states
    /// `x[i] = x_ij` and adds `u_ij` to `out[i]`, for every row i (both
    /// slices have n entries).
    fn step_column(
        &self,
        j: usize,
        traction: Vec3<T>,
        h: TimeStep<T>,
        x: &mut [Vec3<T>],
        out: &mut [Vec3<T>],
    ) -> Result<(), ViscoError>;
}

/// The Rayleigh form of every column (seed 002 Eq. 12 with the traction
/// `p_j`): Ξ column-major (`xi[j·n + i] = Ξ_ij`), per-column parameters
/// (§4.2 spreading). `X` and `P` are slices a board borrows (Ξ in flash) or
/// vectors a host owns.
#[derive(Clone, Copy, Debug)]
pub struct RayleighColumns<T, X, P> {
    n: usize,
    xi: X,
    params: P,
    real: PhantomData<fn() -> T>,
}

impl<T: Real, X: AsRef<[Mat3<T>]>, P: AsRef<[RayleighParams<T>]>> RayleighColumns<T, X, P> {
    /// Checks that `xi` holds n² finite blocks and `params` n columns.
    pub fn new(xi: X, params: P) -> Result<Self, ViscoError> {
        let n = params.as_ref().len();
        if n.checked_mul(n) != Some(xi.as_ref().len()) || n > usize::from(u16::MAX) {
            return Err(ViscoError::VertexOutOfRange);
        }
        if !xi.as_ref().iter().all(|m| m.is_finite()) {
            return Err(ViscoError::NonFiniteInput);
        }
        Ok(Self {
            n,
            xi,
            params,
            real: PhantomData,
        })
    }

    /// Column j of Ξ.
    fn column(&self, j: usize) -> &[Mat3<T>] {
        let start = j.saturating_mul(self.n);
        self.xi.as_ref().get(start..start + self.n).unwrap_or(&[])
    }

    /// The quasi-static elastic answer `u_i = Σ_j Ξ_ij p_j` (seed 002
    /// Eq. 1) for tractions on the listed columns.
    pub fn static_displacement(&self, tractions: &[(usize, Vec3<T>)], out: &mut [Vec3<T>]) {
        for u in out.iter_mut() {
            *u = Vec3::zero();
        }
        for (j, p) in tractions {
            for (u, block) in out.iter_mut().zip(self.column(*j)) {
                *u = *u + block.mul_vec(*p);
            }
        }
    }
}

impl<T: Real, X: AsRef<[Mat3<T>]>, P: AsRef<[RayleighParams<T>]>> ColumnUpdate<T>
    for RayleighColumns<T, X, P>
{
    fn vertices(&self) -> usize {
        self.n
    }

    fn step_column(
        &self,
        j: usize,
        traction: Vec3<T>,
        h: TimeStep<T>,
        x: &mut [Vec3<T>],
        out: &mut [Vec3<T>],
    ) -> Result<(), ViscoError> {
        let params = self
            .params
            .as_ref()
            .get(j)
            .ok_or(ViscoError::VertexOutOfRange)?;
        let coeff = params.coefficients(h.0);
        for ((u, x), block) in out.iter_mut().zip(x.iter_mut()).zip(self.column(j)) {
            *u = *u + rayleigh_term(block.mul_vec(traction), x, coeff);
        }
        Ok(())
    }
}

/// One DGFM column with a general damping tensor `B_j` (seed 002 §4.1,
/// Eq. 5–6, 9–10), precomputed for one fixed step, spread down the column
/// as its relaxation-rate tensor `R_j = B_j⁻¹ K_jj`: every pair (i, j)
/// follows `ẋ_ij = R_j (Ξ_ij p_j − c x_ij)`, `u_ij = Ξ_ij p_j/(1+r) + x_ij`,
/// `c = (1+r)/r`, advanced with the seed's implicit first-order scheme:
/// `x' = (I + h c R)⁻¹ (x + h R y)`.
///
/// On the diagonal this is exactly the seed's tensor update (Eq. 6 with
/// `f_j = α_j p_j`, `K = α_j Ξ_jj⁻¹`), and with `B_j = b K_jj` it is the
/// Rayleigh form (Eq. 12). The seed's literal spreading (`B_·,j = B_j`
/// against every `K_ij`) is not used: `K_ij` of distant vertices is
/// indefinite, which makes those pairs grow without bound in continuous
/// time (the plant counts 10,738 of 24,025 on its shipped object), and the
/// implicit scheme turns that into NaN where `λ h ≈ −1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TensorColumn<T> {
    /// `(I + h c R)⁻¹`.
    decay: Mat3<T>,
    /// `(I + h c R)⁻¹ h R`.
    gain: Mat3<T>,
    /// `1/(1+r)`.
    instant: T,
    h: TimeStep<T>,
}

impl<T: Real> TensorColumn<T> {
    /// The column of vertex j: self stiffness `K_jj` (N/m), damping tensor
    /// `B_j` (N·s/m; zero for none), stiffness ratio `r`, step `h`.
    pub fn new(k_jj: Mat3<T>, b_j: Mat3<T>, ratio: T, h: TimeStep<T>) -> Result<Self, ViscoError> {
        let r = positive(ratio, ViscoError::RatioNotPositive)?;
        if !(k_jj.is_finite() && b_j.is_finite()) {
            return Err(ViscoError::NonFiniteInput);
        }
        let one = T::one();
        let c = (one + r) / r;
        let instant = one / (one + r);
        if b_j.0.iter().flatten().all(|v| *v == T::zero()) {
            // No damping: x = y/c at once.
            return Ok(Self {
                decay: Mat3::zero(),
                gain: Mat3::identity().scale(one / c),
                instant,
                h,
            });
        }
        let rate = b_j.inverse().ok_or(ViscoError::SingularTensor)? * k_jj;
        let hr = rate.scale(h.0);
        let decay = (Mat3::identity() + hr.scale(c))
            .inverse()
            .ok_or(ViscoError::SingularTensor)?;
        Ok(Self {
            decay,
            gain: decay * hr,
            instant,
            h,
        })
    }
}

/// Every column in the tensor form ([`TensorColumn`]): Ξ column-major
/// (`xi[j·n + i] = Ξ_ij`), one precomputed column each; borrowed or owned
/// as for [`RayleighColumns`].
#[derive(Clone, Copy, Debug)]
pub struct TensorColumns<T, X, C> {
    n: usize,
    xi: X,
    columns: C,
    real: PhantomData<fn() -> T>,
}

impl<T: Real, X: AsRef<[Mat3<T>]>, C: AsRef<[TensorColumn<T>]>> TensorColumns<T, X, C> {
    /// Checks that `xi` holds n² finite blocks for the n `columns`, all
    /// precomputed for the same step.
    pub fn new(xi: X, columns: C) -> Result<Self, ViscoError> {
        let cols = columns.as_ref();
        let n = cols.len();
        if n.checked_mul(n) != Some(xi.as_ref().len()) || n > usize::from(u16::MAX) {
            return Err(ViscoError::VertexOutOfRange);
        }
        if !xi.as_ref().iter().all(|m| m.is_finite()) {
            return Err(ViscoError::NonFiniteInput);
        }
        if let Some(first) = cols.first() {
            if cols.iter().any(|c| c.h != first.h) {
                return Err(ViscoError::StepMismatch);
            }
        }
        Ok(Self {
            n,
            xi,
            columns,
            real: PhantomData,
        })
    }
}

impl<T: Real, X: AsRef<[Mat3<T>]>, C: AsRef<[TensorColumn<T>]>> ColumnUpdate<T>
    for TensorColumns<T, X, C>
{
    fn vertices(&self) -> usize {
        self.n
    }

    fn check_step(&self, h: TimeStep<T>) -> Result<(), ViscoError> {
        match self.columns.as_ref().first() {
            Some(c) if c.h != h => Err(ViscoError::StepMismatch),
            _ => Ok(()),
        }
    }

    fn step_column(
        &self,
        j: usize,
        traction: Vec3<T>,
        h: TimeStep<T>,
        x: &mut [Vec3<T>],
        out: &mut [Vec3<T>],
    ) -> Result<(), ViscoError> {
        let column = self
            .columns
            .as_ref()
            .get(j)
            .ok_or(ViscoError::VertexOutOfRange)?;
        if column.h != h {
            return Err(ViscoError::StepMismatch);
        }
        let start = j.saturating_mul(self.n);
        let blocks = self
            .xi
            .as_ref()
            .get(start..start + self.n)
            .ok_or(ViscoError::VertexOutOfRange)?;
        for ((u, x), block) in out.iter_mut().zip(x.iter_mut()).zip(blocks) {
            let y = block.mul_vec(traction);
            *x = column.decay.mul_vec(*x) + column.gain.mul_vec(y);
            *u = *u + y.scale(column.instant) + *x;
        }
        Ok(())
    }
}

/// One slot of the active-column list: the column's vertex and traction.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct ColumnSlot<T> {
    vertex: u16,
    traction: Vec3<T>,
}

/// Multi-vertex viscoelastic evaluation over a DGFM, traction in,
/// displacement out (seed 002 Eq. 4 with per-column parameters, §4.2),
/// keeping a list of active columns (§5): a column is active while traction
/// is applied to it or while its displacement effect `max_i |x_ij|` is
/// above the rest threshold (default 1e-3, the seed's figure). Cost per
/// step: O(n · active).
///
/// The caller provides the storage — `slots` (one per column that may be
/// active at once) and `states` (`slots.len() · n` vectors) — as static
/// arrays on a board ([`DgfmBuffers`]) or heap buffers on the host, so the
/// same code serves a compile-time 193-vertex object in flash and a mesh
/// loaded at run time.
pub struct ViscoDgfm<T, U, S, X> {
    update: U,
    slots: S,
    states: X,
    active: usize,
    rest_threshold: T,
}

/// Default displacement effect below which an unloaded column is dropped
/// from the active list (seed 002 §5: "above 1e-3").
pub const DEFAULT_REST_THRESHOLD: f64 = 1.0e-3;

impl<T, U, S, X> ViscoDgfm<T, U, S, X>
where
    T: Real,
    U: ColumnUpdate<T>,
    S: AsRef<[ColumnSlot<T>]> + AsMut<[ColumnSlot<T>]>,
    X: AsRef<[Vec3<T>]> + AsMut<[Vec3<T>]>,
{
    /// An evaluation with `update`'s columns over the caller's storage
    /// (borrowed slices, or owned vectors). Rejects `states` that do not
    /// hold `slots.len() · n` vectors.
    pub fn new(update: U, slots: S, states: X) -> Result<Self, ViscoError> {
        if slots.as_ref().len().checked_mul(update.vertices()) != Some(states.as_ref().len()) {
            return Err(ViscoError::StorageMismatch);
        }
        Ok(Self {
            update,
            slots,
            states,
            active: 0,
            rest_threshold: T::lit(DEFAULT_REST_THRESHOLD),
        })
    }

    /// The column update.
    pub fn update(&self) -> &U {
        &self.update
    }

    /// Changes the rest threshold (must be finite and ≥ 0).
    pub fn set_rest_threshold(&mut self, threshold: T) -> Result<(), ViscoError> {
        self.rest_threshold = non_negative(threshold, ViscoError::NonFiniteInput)?;
        Ok(())
    }

    fn states_of(&mut self, k: usize) -> &mut [Vec3<T>] {
        let n = self.update.vertices();
        let start = k.saturating_mul(n);
        self.states
            .as_mut()
            .get_mut(start..start + n)
            .unwrap_or(&mut [])
    }

    /// Applies traction `p` to column `vertex` from the next step on (zero
    /// to release it; the column stays active until it has relaxed).
    pub fn set_traction(&mut self, vertex: usize, traction: Vec3<T>) -> Result<(), ViscoError> {
        if vertex >= self.update.vertices() {
            return Err(ViscoError::VertexOutOfRange);
        }
        if !traction.is_finite() {
            return Err(ViscoError::NonFiniteInput);
        }
        let active = self
            .slots
            .as_mut()
            .get_mut(..self.active)
            .unwrap_or(&mut []);
        if let Some(slot) = active.iter_mut().find(|s| usize::from(s.vertex) == vertex) {
            slot.traction = traction;
            return Ok(());
        }
        if traction.is_zero() {
            return Ok(()); // an inactive column at rest stays inactive
        }
        let k = self.active;
        let slot = self
            .slots
            .as_mut()
            .get_mut(k)
            .ok_or(ViscoError::ActiveListFull)?;
        *slot = ColumnSlot {
            // `vertex < n ≤ u16::MAX`, checked by the column update.
            vertex: u16::try_from(vertex).map_err(|_| ViscoError::VertexOutOfRange)?,
            traction,
        };
        for x in self.states_of(k) {
            *x = Vec3::zero();
        }
        self.active += 1;
        Ok(())
    }

    /// Releases every traction (columns relax and then leave the list).
    pub fn release_all(&mut self) {
        for slot in self.slots.as_mut().iter_mut().take(self.active) {
            slot.traction = Vec3::zero();
        }
    }

    /// Number of active columns.
    pub fn active_count(&self) -> usize {
        self.active
    }

    /// Advances one step of `h` and writes every vertex displacement
    /// `u_i = Σ_j u_ij` into `out` (n entries).
    pub fn step(&mut self, h: TimeStep<T>, out: &mut [Vec3<T>]) -> Result<(), ViscoError> {
        let n = self.update.vertices();
        if out.len() != n {
            return Err(ViscoError::StorageMismatch);
        }
        self.update.check_step(h)?;
        for u in out.iter_mut() {
            *u = Vec3::zero();
        }
        let threshold = self.rest_threshold;
        let slots = self.slots.as_ref().get(..self.active).unwrap_or(&[]);
        for (slot, x) in slots
            .iter()
            .zip(self.states.as_mut().chunks_exact_mut(n.max(1)))
        {
            self.update
                .step_column(usize::from(slot.vertex), slot.traction, h, x, out)?;
        }
        // Drop columns that carry no traction and whose effect has decayed,
        // keeping the others in order.
        let mut kept = 0;
        for k in 0..self.active {
            let at_rest = {
                let loaded = self
                    .slots
                    .as_ref()
                    .get(k)
                    .is_some_and(|s| !s.traction.is_zero());
                let start = k.saturating_mul(n);
                // Only an unloaded column's states are read.
                !loaded
                    && !self
                        .states
                        .as_ref()
                        .get(start..start + n)
                        .is_some_and(|xs| xs.iter().any(|x| x.max_abs() > threshold))
            };
            if at_rest {
                continue;
            }
            if kept != k {
                self.slots.as_mut().swap(kept, k);
                let (low, high) = self.states.as_mut().split_at_mut(k.saturating_mul(n));
                if let (Some(dst), Some(src)) = (
                    low.get_mut(kept.saturating_mul(n)..kept.saturating_mul(n) + n),
                    high.get_mut(..n),
                ) {
                    dst.swap_with_slice(src);
                }
            }
            kept += 1;
        }
        self.active = kept;
        Ok(())
    }
}

/// Fixed-size storage for a [`ViscoDgfm`] of `N` vertices with at most `A`
/// active columns (a board's static buffers).
pub struct DgfmBuffers<T, const N: usize, const A: usize> {
    slots: [ColumnSlot<T>; A],
    states: [[Vec3<T>; N]; A],
}

impl<T: Real, const N: usize, const A: usize> Default for DgfmBuffers<T, N, A> {
    fn default() -> Self {
        Self {
            slots: [ColumnSlot::default(); A],
            states: [[Vec3::zero(); N]; A],
        }
    }
}

impl<T: Real, const N: usize, const A: usize> DgfmBuffers<T, N, A> {
    /// An evaluation with `update`'s columns (which must have `N` vertices)
    /// in these buffers.
    #[allow(clippy::type_complexity)]
    pub fn dgfm<U: ColumnUpdate<T>>(
        &mut self,
        update: U,
    ) -> Result<ViscoDgfm<T, U, &mut [ColumnSlot<T>], &mut [Vec3<T>]>, ViscoError> {
        if update.vertices() != N {
            return Err(ViscoError::StorageMismatch);
        }
        ViscoDgfm::new(
            update,
            self.slots.as_mut_slice(),
            self.states.as_flattened_mut(),
        )
    }
}
