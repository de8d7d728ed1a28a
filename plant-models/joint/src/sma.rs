//! SMA coil actuator (BioMetal Helix BMX200-like): lumped thermal model,
//! hysteretic martensite fraction, and a coil spring whose stiffness, rest
//! length and resistance move with the phase.
//!
//! Thermal model (SPEC §2):
//!
//! ```text
//!   m c dT/dt = I² R(ξ) − h A (T − T_amb) + m ΔH dξ/dt
//! ```
//!
//! `ξ` is the martensite fraction (1 = cold, fully martensite). The Joule and
//! convection terms are integrated **exactly** over a step for the power at
//! the start of the step (`T ← T_eq + (T − T_eq) e^{−h/τ}`), which is
//! unconditionally stable and makes the frozen-phase step response the
//! analytic exponential. The latent heat (heating M→A absorbs it, cooling
//! A→M releases it) is then settled together with the phase: the step ends
//! at the temperature `T` with `c (T − T_sensible) = ΔH (ξ(T) − ξ₀)`, so the
//! phase is always on its branch at the coil's actual temperature (see
//! [`SmaParams::settle_latent_heat`]).
//!
//! Phase (Liang–Rogers cosine law with separate branches):
//! - heating, `A_s ≤ T ≤ A_f`: `ξ = ξ₀ · g_A(T)/g_A(T₀)`,
//!   `g_A(T) = (1 + cos(π (T − A_s)/(A_f − A_s)))/2`;
//! - cooling, `M_f ≤ T ≤ M_s`: `1 − ξ = (1 − ξ₀) · g_M(T)/g_M(T₀)`,
//!   `g_M(T) = (1 − cos(π (T − M_f)/(M_s − M_f)))/2`.
//!
//! The update is applied incrementally from the previous step (`T₀`, `ξ₀` =
//! last step). Because the law is a ratio, increments telescope: a partial
//! heating that turns into cooling resumes from the partial fraction on the
//! cooling branch (and vice versa), reaching ξ = 0 exactly at `A_f` and
//! ξ = 1 exactly at `M_f` from any starting point — the minor-loop rule of
//! Liang–Rogers as usually implemented for control simulations.
//!
//! Stress dependence (Clausius–Clapeyron, off by default): with
//! `stress_shift_k_per_mpa = s > 0` every transformation temperature rises
//! by `s·σ`, σ = F/A the coil's tension over the wire's cross-section (the
//! nominal wire stress the BMX datasheets rate). Evaluated as the phase law
//! on the *effective* temperature `T − s·σ`, with σ from the coil's tension
//! at the end of the previous substep, so a tension that rises at constant
//! temperature moves the effective temperature down and forms martensite
//! (stress-induced transformation) as the MATLAB models of the field
//! (Liang–Rogers, Brinson) do with `T_x + σ/C_x`. One slope serves all four
//! temperatures (C_M = C_A). With `s = 0` the coil is bit-identical to the
//! model without it, so the paper figures and their tests are unchanged.
//!
//! Left out: R-phase, pseudo-plastic detwinning of the cold coil (the cold
//! coil is a linear spring here), fatigue and the coil's thermal coupling to
//! its neighbours and to the socket.

use plant_common::scalar::Scalar;
use serde::{Deserialize, Serialize};

use super::{check_finite, check_positive, PlantError};

/// Parameters of one SMA coil. Defaults: typical NiTi values from SPEC §2 and
/// estimates for the BMX200 coil (its datasheet is not available here).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmaParams {
    /// Wire diameter (m). Estimate (SPEC §2: 0.2 mm wire).
    pub wire_diameter_m: f64,
    /// Length of wire wound into the coil (m). Estimate: chosen so that the
    /// martensite resistance is ≈ 5 Ω (SPEC §2: ~5 Ω per 20 mm coil):
    /// L = R·A/ρ_M = 5 Ω · 3.14e-8 m² / 80e-8 Ω·m ≈ 0.196 m.
    pub wire_length_m: f64,
    /// NiTi density (kg/m³). SPEC §2 typical value.
    pub density_kg_m3: f64,
    /// NiTi specific heat (J/(kg·K)). SPEC §2 typical value.
    pub specific_heat_j_kg_k: f64,
    /// Latent heat of the transformation (J/kg); 0 disables it. SPEC §2.
    pub latent_heat_j_kg: f64,
    /// Resistivity of martensite (Ω·m). SPEC §2: 80 µΩ·cm.
    pub resistivity_martensite_ohm_m: f64,
    /// Resistivity of austenite (Ω·m). SPEC §2: 100 µΩ·cm.
    pub resistivity_austenite_ohm_m: f64,
    /// Austenite start (°C). SPEC §2, low-temperature wire.
    pub austenite_start_c: f64,
    /// Austenite finish (°C). SPEC §2.
    pub austenite_finish_c: f64,
    /// Martensite start (°C). SPEC §2.
    pub martensite_start_c: f64,
    /// Martensite finish (°C). SPEC §2.
    pub martensite_finish_c: f64,
    /// Convective coefficient (W/(m²·K)). SPEC §2 gives 20–150; 54 puts the
    /// coil's thermal time constant m·c/(h·A) at ≈ 5 s, the middle of the
    /// SPEC's 3–7 s estimate for the BMX200.
    pub convection_w_m2_k: f64,
    /// Ambient temperature (°C). Estimate (room temperature).
    pub ambient_c: f64,
    /// Coil spring rate when fully martensite (N/m). SPEC §2 estimate.
    pub stiffness_martensite_n_m: f64,
    /// Coil spring rate when fully austenite (N/m). SPEC §2 estimate.
    pub stiffness_austenite_n_m: f64,
    /// Rest (zero-force) length when fully martensite (m). Estimate, tuned
    /// with the coil geometry (see `link::CoilGeometry`): 16 mm for a coil
    /// installed at 20 mm gives a cold bias-spring pretension ≈ 0.36 N, so
    /// the antagonist stays taut beyond ±15° (a slack coil would make the
    /// unpowered joint much softer than the paper's 12° under 50 g).
    pub rest_length_martensite_m: f64,
    /// Rest length when fully austenite (m). Tuned estimate: 7 mm makes the
    /// hot coil pull ≈ 2 N near 20°, enough for the paper's ±20° range at
    /// 5 V against the cold antagonist and the sponge (open loop reaches
    /// ≈ 22°); the paper puts one coil at 5 V at "about 150 g" (≈ 1.5 N).
    /// That is above the 172 MPa long-life wire stress (SPEC §2) — a known
    /// compromise of a linear austenite spring.
    pub rest_length_austenite_m: f64,
    /// Internal damping of the coil along its axis (N·s/m). Estimate (small:
    /// a metal coil dissipates little).
    pub damping_n_s_m: f64,
    /// Clausius–Clapeyron shift of the transformation temperatures per unit
    /// wire stress, 1/C (K/MPa); 0 (the default) leaves it out. NiTi's
    /// stress–temperature slopes C are of order 7–14 MPa/K (the values
    /// used in Liang–Rogers and Brinson type models; not checked against a
    /// BMX200 datasheet, which is not available here), i.e. 0.07–0.14 K/MPa;
    /// a 2 N hot-coil tension on a 0.2 mm wire (64 MPa) then shifts A_s by
    /// 4–9 K. Off by default so the paper's figures stay as they were
    /// tuned; `softjoint identify joint` fits it.
    pub stress_shift_k_per_mpa: f64,
}

impl Default for SmaParams {
    fn default() -> Self {
        Self {
            wire_diameter_m: 0.2e-3,
            wire_length_m: 0.196,
            density_kg_m3: 6450.0,
            specific_heat_j_kg_k: 837.0,
            latent_heat_j_kg: 24.2e3,
            resistivity_martensite_ohm_m: 80e-8,
            resistivity_austenite_ohm_m: 100e-8,
            austenite_start_c: 68.0,
            austenite_finish_c: 78.0,
            martensite_start_c: 52.0,
            martensite_finish_c: 42.0,
            convection_w_m2_k: 54.0,
            ambient_c: 25.0,
            stiffness_martensite_n_m: 90.0,
            stiffness_austenite_n_m: 230.0,
            rest_length_martensite_m: 16.0e-3,
            rest_length_austenite_m: 7.0e-3,
            damping_n_s_m: 0.02,
            stress_shift_k_per_mpa: 0.0,
        }
    }
}

impl SmaParams {
    /// Rejects non-finite, non-positive or inconsistent values, naming the
    /// field (`prefix` is prepended, e.g. `"coil."`).
    pub fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        let p = |f: &str| format!("{prefix}{f}");
        check_positive(&p("wire_diameter_m"), self.wire_diameter_m)?;
        check_positive(&p("wire_length_m"), self.wire_length_m)?;
        check_positive(&p("density_kg_m3"), self.density_kg_m3)?;
        check_positive(&p("specific_heat_j_kg_k"), self.specific_heat_j_kg_k)?;
        check_finite(&p("latent_heat_j_kg"), self.latent_heat_j_kg)?;
        if self.latent_heat_j_kg < 0.0 {
            return Err(PlantError::param(&p("latent_heat_j_kg"), "must be ≥ 0"));
        }
        check_positive(
            &p("resistivity_martensite_ohm_m"),
            self.resistivity_martensite_ohm_m,
        )?;
        check_positive(
            &p("resistivity_austenite_ohm_m"),
            self.resistivity_austenite_ohm_m,
        )?;
        check_finite(&p("austenite_start_c"), self.austenite_start_c)?;
        check_finite(&p("austenite_finish_c"), self.austenite_finish_c)?;
        check_finite(&p("martensite_start_c"), self.martensite_start_c)?;
        check_finite(&p("martensite_finish_c"), self.martensite_finish_c)?;
        if self.austenite_finish_c <= self.austenite_start_c {
            return Err(PlantError::param(
                &p("austenite_finish_c"),
                "must exceed austenite_start_c",
            ));
        }
        if self.martensite_start_c <= self.martensite_finish_c {
            return Err(PlantError::param(
                &p("martensite_start_c"),
                "must exceed martensite_finish_c",
            ));
        }
        check_positive(&p("convection_w_m2_k"), self.convection_w_m2_k)?;
        check_finite(&p("ambient_c"), self.ambient_c)?;
        check_positive(
            &p("stiffness_martensite_n_m"),
            self.stiffness_martensite_n_m,
        )?;
        check_positive(&p("stiffness_austenite_n_m"), self.stiffness_austenite_n_m)?;
        check_positive(
            &p("rest_length_martensite_m"),
            self.rest_length_martensite_m,
        )?;
        check_positive(&p("rest_length_austenite_m"), self.rest_length_austenite_m)?;
        check_finite(&p("damping_n_s_m"), self.damping_n_s_m)?;
        if self.damping_n_s_m < 0.0 {
            return Err(PlantError::param(&p("damping_n_s_m"), "must be ≥ 0"));
        }
        check_finite(&p("stress_shift_k_per_mpa"), self.stress_shift_k_per_mpa)?;
        if !(0.0..=1.0).contains(&self.stress_shift_k_per_mpa) {
            return Err(PlantError::param(
                &p("stress_shift_k_per_mpa"),
                "must be in 0..=1 K/MPa",
            ));
        }
        Ok(())
    }

    /// Cross-section of the wire (m²).
    pub fn wire_area_m2(&self) -> f64 {
        core::f64::consts::PI * 0.25 * self.wire_diameter_m * self.wire_diameter_m
    }

    /// Wire mass (kg).
    pub fn mass_kg(&self) -> f64 {
        self.density_kg_m3 * self.wire_area_m2() * self.wire_length_m
    }

    /// Heat capacity m·c (J/K).
    pub fn heat_capacity_j_k(&self) -> f64 {
        self.mass_kg() * self.specific_heat_j_kg_k
    }

    /// Convective conductance h·A (W/K), A the wire's lateral surface.
    pub fn conductance_w_k(&self) -> f64 {
        self.convection_w_m2_k * core::f64::consts::PI * self.wire_diameter_m * self.wire_length_m
    }

    /// Thermal time constant m·c/(h·A) (s).
    pub fn time_constant_s(&self) -> f64 {
        self.heat_capacity_j_k() / self.conductance_w_k()
    }

    /// Resistance at martensite fraction `xi` (Ω), resistivities mixed
    /// linearly by phase.
    pub fn resistance_ohm(&self, xi: f64) -> f64 {
        let rho =
            xi * self.resistivity_martensite_ohm_m + (1.0 - xi) * self.resistivity_austenite_ohm_m;
        rho * self.wire_length_m / self.wire_area_m2()
    }

    /// The constants of [`Self::phase_update`]'s two cosine branches.
    fn phase_shape(&self) -> PhaseShape {
        Law::new(
            self.austenite_start_c,
            self.austenite_finish_c,
            self.martensite_start_c,
            self.martensite_finish_c,
        )
    }

    /// Heating-branch shape g_A(T): 1 below A_s, 0 above A_f.
    #[cfg(test)]
    fn g_heat(&self, shape: &PhaseShape, t: f64) -> f64 {
        shape.g_heat(t)
    }

    /// Cooling-branch shape g_M(T): 1 above M_s, 0 below M_f.
    #[cfg(test)]
    fn g_cool(&self, shape: &PhaseShape, t: f64) -> f64 {
        shape.g_cool(t)
    }

    /// Temperature rise equivalent to a full transformation, ΔH/c (K).
    fn latent_rise_k(&self) -> f64 {
        self.latent_heat_j_kg / self.specific_heat_j_kg_k
    }

    /// End of a step whose Joule and convective heat alone would take the
    /// coil from `t_old` to `t_sensible`: the temperature `T` and phase
    /// `ξ(T)` that satisfy the energy balance with the latent heat,
    ///
    /// ```text
    ///   T = t_sensible + (ΔH/c) · (ξ(T) − ξ_old),   ξ(T) = phase_update(t_old, ξ_old, T),
    /// ```
    ///
    /// so the phase stays on its Liang–Rogers branch at the temperature the
    /// coil actually ends at. (Applying the latent heat *after* a phase step
    /// taken to `t_sensible` — the obvious split — transforms the coil
    /// against a temperature it never reaches; the error does not shrink
    /// with the step and squeezed 80 % of the heating transformation into
    /// the first 2.5 K of the 10 K A_s–A_f band.)
    ///
    /// The residual `r(T) = T − t_sensible − (ΔH/c)(ξ(T) − ξ_old)` is
    /// strictly increasing in `T` and changes sign between `t_old` and
    /// `t_sensible` (the latent heat slows a temperature change but cannot
    /// reverse it), so the root is bracketed; it is found by the Illinois
    /// variant of regula falsi to [`LATENT_HEAT_TOLERANCE_K`]. Since ξ(T)
    /// never rises with `T` (on either branch, and across `t_old` where
    /// they meet at ξ_old), `r` rises at least as fast as `T`: |T − T*| ≤
    /// |r(T)| for the root T*, so the search stops at the first iterate
    /// whose residual is within the tolerance (or once the bracket is).
    pub fn settle_latent_heat(&self, t_old: f64, xi_old: f64, t_sensible: f64) -> (f64, f64) {
        self.settle_latent_heat_with(
            &self.phase_shape(),
            t_old,
            xi_old,
            t_sensible,
            [0.0; 2],
            &mut ShapeCache::default(),
        )
    }

    /// [`Self::settle_latent_heat`] with the branch constants precomputed.
    /// Most steps end outside the transformation bands with ξ unchanged:
    /// that is settled here, inline, and only the rest goes to
    /// [`Self::settle_latent_heat_solve`] (which finds the same ξ first).
    /// `cache` carries the branch shapes at the temperature a search ended
    /// at to the next step, which starts there.
    #[inline(always)]
    fn settle_latent_heat_with(
        &self,
        shape: &PhaseShape,
        t_old: f64,
        xi_old: f64,
        t_sensible: f64,
        shift_k: [f64; 2],
        cache: &mut ShapeCache,
    ) -> (f64, f64) {
        let outside = shape.outside(t_old - shift_k[0], xi_old, t_sensible - shift_k[1]);
        match outside {
            Some(xi) if xi == xi_old || self.latent_rise_k() == 0.0 => (t_sensible, xi),
            _ => self.settle_latent_heat_solve(shape, t_old, xi_old, t_sensible, shift_k, cache),
        }
    }

    /// [`Self::settle_latent_heat_with`] in full: the search, starting
    /// from the branch shapes at the step's start if `cache` holds them
    /// (a search ended there), and leaving those at its end in `cache`.
    /// The shapes are functions of the effective temperature alone, so a
    /// cached one is, to the bit, what evaluating it again would give.
    #[inline(never)]
    fn settle_latent_heat_solve(
        &self,
        shape: &PhaseShape,
        t_old: f64,
        xi_old: f64,
        t_sensible: f64,
        shift_k: [f64; 2],
        cache: &mut ShapeCache,
    ) -> (f64, f64) {
        let t_from = t_old - shift_k[0];
        let from = cache.at(t_from);
        let (t, xi, at) =
            self.settle_latent_heat_search(shape, from, t_old, xi_old, t_sensible, shift_k);
        cache.store(t - shift_k[1], at);
        (t, xi)
    }

    /// [`Self::settle_latent_heat_solve`]'s search, from the branch shapes
    /// `from` at the step's start (those known); returns the temperature,
    /// ξ there and the branch shapes evaluated there.
    #[inline(always)]
    fn settle_latent_heat_search(
        &self,
        shape: &PhaseShape,
        mut from: PhaseFrom,
        t_old: f64,
        xi_old: f64,
        t_sensible: f64,
        shift_k: [f64; 2],
    ) -> (f64, f64, PhaseFrom) {
        // The phase law on the effective temperature T − s·σ: `shift_k` is
        // s·σ at the start and at the end of the step ([0, 0] without the
        // stress dependence, where the subtractions are exact). Every
        // evaluation starts from the same (T_old, ξ_old), so the branch
        // shapes there are computed once (`from`), and each temperature's
        // ξ is kept with its residual rather than evaluated again: the
        // same operations on the same values as evaluating afresh.
        let mut xi_at = |t: f64| {
            let mut at = PhaseFrom::default();
            let t_to = t - shift_k[1];
            let xi = shape.update_from(&mut from, t_old - shift_k[0], xi_old, t_to, &mut at);
            (xi, at)
        };
        let (xi_sensible, at_sensible) = xi_at(t_sensible);
        let l = self.latent_rise_k();
        if xi_sensible == xi_old || l == 0.0 {
            return (t_sensible, xi_sensible, at_sensible);
        }
        let residual = |t: f64, xi: f64| t - t_sensible - l * (xi - xi_old);
        // Bracket [lo, hi] with residual(lo) < 0 < residual(hi).
        let ((mut lo, xi_lo, at_lo), (mut hi, xi_hi, at_hi)) = if t_sensible > t_old {
            let (xi, at) = xi_at(t_old);
            ((t_old, xi, at), (t_sensible, xi_sensible, at_sensible))
        } else {
            let (xi, at) = xi_at(t_old);
            ((t_sensible, xi_sensible, at_sensible), (t_old, xi, at))
        };
        let (mut r_lo, mut r_hi) = (residual(lo, xi_lo), residual(hi, xi_hi));
        if r_lo >= 0.0 {
            return (lo, xi_lo, at_lo);
        }
        if r_hi <= 0.0 {
            return (hi, xi_hi, at_hi);
        }
        let mut side = 0i8;
        let mut t = 0.5 * (lo + hi);
        let (mut xi, mut at) = (xi_old, PhaseFrom::default());
        for _ in 0..60 {
            t = (lo * r_hi - hi * r_lo) / (r_hi - r_lo);
            if !(t > lo && t < hi) {
                t = 0.5 * (lo + hi);
            }
            (xi, at) = xi_at(t);
            let r = residual(t, xi);
            if r.abs() <= LATENT_HEAT_TOLERANCE_K || hi - lo < LATENT_HEAT_TOLERANCE_K {
                break;
            }
            if r < 0.0 {
                lo = t;
                r_lo = r;
                if side == -1 {
                    r_hi *= 0.5;
                }
                side = -1;
            } else {
                hi = t;
                r_hi = r;
                if side == 1 {
                    r_lo *= 0.5;
                }
                side = 1;
            }
        }
        (t, xi, at)
    }

    /// One Liang–Rogers phase update from (`t_old`, `xi_old`) to `t_new`.
    pub fn phase_update(&self, t_old: f64, xi_old: f64, t_new: f64) -> f64 {
        self.phase_update_with(&self.phase_shape(), t_old, xi_old, t_new)
    }

    /// [`Self::phase_update`] with the branch constants already computed.
    /// Outside the transformation bands both shapes are 1, and the update
    /// is evaluated without the divisions and cosines that would give 1/1:
    /// same operations on the same values otherwise, so the result is
    /// bit-identical.
    #[inline]
    fn phase_update_with(&self, shape: &PhaseShape, t_old: f64, xi_old: f64, t_new: f64) -> f64 {
        let mut at = PhaseFrom::default();
        shape.update_from(&mut PhaseFrom::default(), t_old, xi_old, t_new, &mut at)
    }
}

/// The phase law's constants — the transformation temperatures and the
/// cosine branches' π/(A_f − A_s) and π/(M_s − M_f) — in any [`Scalar`]:
/// with duals the law carries the derivatives of ξ with respect to the
/// temperatures (identification's sensitivities); with `f64` it is the
/// law as it always was, operation for operation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Law<S> {
    a_s: S,
    a_f: S,
    m_s: S,
    m_f: S,
    heat_scale: S,
    cool_scale: S,
}

/// The `f64` law, as [`SmaParams::phase_shape`] gives it.
type PhaseShape = Law<f64>;

impl<S: Scalar> Law<S> {
    /// The law of the temperatures A_s, A_f, M_s, M_f (°C).
    pub(crate) fn new(a_s: S, a_f: S, m_s: S, m_f: S) -> Self {
        Self {
            a_s,
            a_f,
            m_s,
            m_f,
            heat_scale: S::cst(core::f64::consts::PI) / (a_f - a_s),
            cool_scale: S::cst(core::f64::consts::PI) / (m_s - m_f),
        }
    }

    /// The law's values (no derivatives).
    #[inline(always)]
    fn values(&self) -> Law<f64> {
        Law {
            a_s: self.a_s.val(),
            a_f: self.a_f.val(),
            m_s: self.m_s.val(),
            m_f: self.m_f.val(),
            heat_scale: self.heat_scale.val(),
            cool_scale: self.cool_scale.val(),
        }
    }

    /// Heating-branch shape g_A(T): 1 below A_s, 0 above A_f.
    #[inline(always)]
    fn g_heat(&self, t: S) -> S {
        if t.val() <= self.a_s.val() {
            S::cst(1.0)
        } else if t.val() >= self.a_f.val() {
            S::cst(0.0)
        } else {
            ((self.heat_scale * (t - self.a_s)).cos() + 1.0) * 0.5
        }
    }

    /// Cooling-branch shape g_M(T): 1 above M_s, 0 below M_f.
    #[inline(always)]
    fn g_cool(&self, t: S) -> S {
        if t.val() >= self.m_s.val() {
            S::cst(1.0)
        } else if t.val() <= self.m_f.val() {
            S::cst(0.0)
        } else {
            (-(self.cool_scale * (t - self.m_f)).cos() + 1.0) * 0.5
        }
    }

    /// One update from (`t_old`, `xi_old`) to `t_new` keeping g_A(`t_old`)
    /// and g_M(`t_old`) in `from` once computed, for several updates from
    /// the same (`t_old`, `xi_old`); the shape it evaluates at `t_new` (if
    /// any) goes to `at`.
    #[inline(always)]
    fn update_from(
        &self,
        from: &mut PhaseFrom<S>,
        t_old: S,
        xi_old: S,
        t_new: S,
        at: &mut PhaseFrom<S>,
    ) -> S {
        if let Some(xi) = self.outside(t_old, xi_old, t_new) {
            return xi;
        }
        let (zero, one) = (S::cst(0.0), S::cst(1.0));
        if t_new.val() > t_old.val() {
            let g_old = *from.heat.get_or_insert_with(|| self.g_heat(t_old));
            if g_old.val() <= 0.0 {
                return xi_old;
            }
            let g_new = self.g_heat(t_new);
            at.heat = Some(g_new);
            (xi_old * g_new / g_old).min_of(xi_old).clamp_to(zero, one)
        } else {
            let g_old = *from.cool.get_or_insert_with(|| self.g_cool(t_old));
            if g_old.val() <= 0.0 {
                return xi_old;
            }
            let g_new = self.g_cool(t_new);
            at.cool = Some(g_new);
            let aus = ((-xi_old + 1.0) * g_new / g_old).min_of(-xi_old + 1.0);
            (-aus + 1.0).clamp_to(zero, one)
        }
    }

    /// The update where it needs neither branch's shape: no change of
    /// temperature, an end outside the band of the branch taken (heating:
    /// at or above A_f, at or below A_s; cooling: at or below M_f, at or
    /// above M_s), or a phase the branch cannot move (heating with no
    /// martensite left, cooling with no austenite); `None` inside the band
    /// otherwise.
    #[inline(always)]
    fn outside(&self, t_old: S, xi_old: S, t_new: S) -> Option<S> {
        let (zero, one) = (S::cst(0.0), S::cst(1.0));
        if t_new.val() > t_old.val() {
            if t_new.val() >= self.a_f.val() {
                return Some(zero);
            }
            if t_new.val() <= self.a_s.val() {
                // g_A(t_old) = g_A(t_new) = 1: ξ·1/1 = ξ.
                return Some(xi_old.min_of(xi_old).clamp_to(zero, one));
            }
            if xi_old.val() == 0.0 {
                // ξ·g_A(t_new)/g_A(t_old) with ξ = ±0 and shapes in
                // [0, 1] (or g_A(t_old) = 0, which returns ξ): ξ itself,
                // to the bit, without the two cosines (issue 34).
                return Some(xi_old);
            }
            None
        } else if t_new.val() < t_old.val() {
            if t_new.val() <= self.m_f.val() {
                return Some(one);
            }
            if t_new.val() >= self.m_s.val() {
                // g_M(t_old) = g_M(t_new) = 1: (1 − ξ)·1/1 = 1 − ξ.
                let aus = (-xi_old + 1.0).min_of(-xi_old + 1.0);
                return Some((-aus + 1.0).clamp_to(zero, one));
            }
            if xi_old.val() == 1.0 {
                // (1 − ξ)·g_M(t_new)/g_M(t_old) = 0: 1 − 0 = 1 = ξ (or
                // g_M(t_old) = 0, which returns ξ).
                return Some(xi_old);
            }
            None
        } else {
            Some(xi_old)
        }
    }
}

impl Law<f64> {
    /// ∂ξ/∂t_new of [`Law::update_from`] (values): the slope of the branch
    /// inside its band, 0 where the update is held (outside the bands, at
    /// the min or the clamp).
    fn slope(&self, t_old: f64, xi_old: f64, t_new: f64) -> f64 {
        if self.outside(t_old, xi_old, t_new).is_some() {
            return 0.0;
        }
        if t_new > t_old {
            let g_old = self.g_heat(t_old);
            if g_old <= 0.0 {
                return 0.0;
            }
            let x = xi_old * self.g_heat(t_new) / g_old;
            if x > xi_old || !(0.0..=1.0).contains(&x) {
                return 0.0;
            }
            let arg = self.heat_scale * (t_new - self.a_s);
            xi_old * (-0.5 * arg.sin() * self.heat_scale) / g_old
        } else {
            let g_old = self.g_cool(t_old);
            if g_old <= 0.0 {
                return 0.0;
            }
            let aus = (1.0 - xi_old) * self.g_cool(t_new) / g_old;
            if aus > 1.0 - xi_old || !(0.0..=1.0).contains(&(1.0 - aus)) {
                return 0.0;
            }
            let arg = self.cool_scale * (t_new - self.m_f);
            -((1.0 - xi_old) * (0.5 * arg.sin() * self.cool_scale) / g_old)
        }
    }
}

/// The end (T, ξ) of a coil's step in duals, from the temperature `t` the
/// `f64` search settled on (values): where it took the step's sensible
/// end or its start, that end with ξ there; at a root of the latent-heat
/// balance `T = T_s + L (ξ(T) − ξ₀)`, the derivatives by the implicit
/// function rule, `dT = (dT_s + L (dξ_p − dξ₀)) / (1 − L ∂ξ/∂T)` with
/// `dξ_p` ξ's derivatives at fixed T.
#[allow(clippy::too_many_arguments)] // the step's state, as the f64 solve takes it
fn settle_tangents<S: Scalar>(
    law: &Law<S>,
    latent_rise_k: f64,
    t_old: S,
    xi_old: S,
    t_sensible: S,
    shift_k: [S; 2],
    t: f64,
) -> (S, S) {
    let from_t = t_old - shift_k[0];
    let xi_at = |t: S| {
        law.update_from(
            &mut PhaseFrom::default(),
            from_t,
            xi_old,
            t - shift_k[1],
            &mut PhaseFrom::default(),
        )
    };
    if t == t_sensible.val() {
        return (t_sensible, xi_at(t_sensible));
    }
    if t == t_old.val() {
        return (t_old, xi_at(t_old));
    }
    let xi_p = xi_at(S::cst(t));
    let xi_t = law
        .values()
        .slope(from_t.val(), xi_old.val(), t - shift_k[1].val());
    let k = 1.0 / (1.0 - latent_rise_k * xi_t);
    let rhs = t_sensible + (xi_p - xi_old) * latent_rise_k;
    let t_end = (rhs - rhs.val()) * k + t;
    (t_end, xi_p.plus_tangents_of(xi_t, t_end))
}

/// Accuracy of the temperature that settles the latent heat
/// ([`SmaParams::settle_latent_heat`]): within this of the exact root (K).
pub const LATENT_HEAT_TOLERANCE_K: f64 = 1e-9;

/// The phase law's branch shapes at the start of a step, g_A(T_old) and
/// g_M(T_old), once computed.
#[derive(Clone, Copy, Debug)]
struct PhaseFrom<S = f64> {
    heat: Option<S>,
    cool: Option<S>,
}

impl<S> Default for PhaseFrom<S> {
    fn default() -> Self {
        Self {
            heat: None,
            cool: None,
        }
    }
}

/// The branch shapes at one effective temperature, kept by a coil from
/// the end of one latent-heat search for the next step, which starts at
/// that temperature. A cache, not state: coils that differ only in it are
/// equal.
#[derive(Clone, Copy, Debug, Default)]
struct ShapeCache {
    /// The effective temperature (its bits) and the shapes there.
    held: Option<(u64, PhaseFrom)>,
}

impl ShapeCache {
    /// The shapes held for `t_eff`, or none.
    #[inline(always)]
    fn at(&self, t_eff: f64) -> PhaseFrom {
        match self.held {
            Some((bits, from)) if bits == t_eff.to_bits() => from,
            _ => PhaseFrom::default(),
        }
    }

    /// Holds `shapes`, those at `t_eff`.
    #[inline(always)]
    fn store(&mut self, t_eff: f64, shapes: PhaseFrom) {
        self.held = Some((t_eff.to_bits(), shapes));
    }
}

impl PartialEq for ShapeCache {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// State of one coil, in any [`Scalar`]: `f64` for the plant, a dual for
/// identification's sensitivities to the coil's convection, transformation
/// temperatures and stress slope ([`SmaCoil::with_seeds`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SmaCoil<S = f64> {
    params: SmaParams,
    heat_capacity_j_k: f64,
    conductance_w_k: S,
    resistance_martensite_ohm: f64,
    resistance_austenite_ohm: f64,
    phase_shape: Law<S>,
    /// Its values, which the latent-heat search runs on.
    law_values: Law<f64>,
    /// `stress_shift_k_per_mpa`.
    stress_slope: S,
    cached_dt_s: f64,
    cached_decay: S,
    temperature_c: S,
    martensite_fraction: S,
    /// Resistance, spring rate and rest length at `martensite_fraction`,
    /// refreshed whenever it changes (read several times per step).
    mix: PhaseMix<S>,
    current_a: S,
    /// s·σ of the last step and of the next (K): the Clausius–Clapeyron
    /// shift of the transformation temperatures.
    shift_k: S,
    next_shift_k: S,
    /// The branch shapes where the last latent-heat search ended.
    shape_cache: ShapeCache,
}

/// The phase-mixed coil properties at one martensite fraction.
#[derive(Clone, Copy, Debug, PartialEq)]
struct PhaseMix<S> {
    resistance_ohm: S,
    stiffness_n_m: S,
    rest_length_m: S,
}

/// The coil parameters a dual coil carries derivatives of (each in its
/// own unit: W/(m²·K), °C, K/MPa).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoilSeeds<S> {
    /// `convection_w_m2_k`.
    pub convection_w_m2_k: S,
    /// `austenite_start_c`, `austenite_finish_c`, `martensite_start_c`,
    /// `martensite_finish_c`.
    pub transformation_c: [S; 4],
    /// `stress_shift_k_per_mpa`.
    pub stress_shift_k_per_mpa: S,
}

impl<S: Scalar> CoilSeeds<S> {
    /// The seeds' values: convection, stress slope, A_s, A_f, M_s, M_f.
    fn values(&self) -> [f64; 6] {
        let [a_s, a_f, m_s, m_f] = self.transformation_c.map(S::val);
        [
            self.convection_w_m2_k.val(),
            self.stress_shift_k_per_mpa.val(),
            a_s,
            a_f,
            m_s,
            m_f,
        ]
    }

    /// The parameters' values as constants (no derivatives).
    pub fn constants(p: &SmaParams) -> Self {
        Self {
            convection_w_m2_k: S::cst(p.convection_w_m2_k),
            transformation_c: [
                p.austenite_start_c,
                p.austenite_finish_c,
                p.martensite_start_c,
                p.martensite_finish_c,
            ]
            .map(S::cst),
            stress_shift_k_per_mpa: S::cst(p.stress_shift_k_per_mpa),
        }
    }
}

impl SmaCoil {
    /// A cold coil (ambient temperature, fully martensite).
    pub fn new(params: SmaParams) -> Result<Self, PlantError> {
        let seeds = CoilSeeds::constants(&params);
        Self::with_seeds(params, seeds)
    }

    /// Sets temperature and phase directly (tests, warm starts).
    pub fn set_state(
        &mut self,
        temperature_c: f64,
        martensite_fraction: f64,
    ) -> Result<(), PlantError> {
        check_finite("coil.temperature_c", temperature_c)?;
        if !(0.0..=1.0).contains(&martensite_fraction) {
            return Err(PlantError::param(
                "coil.martensite_fraction",
                "must be in [0, 1]",
            ));
        }
        self.temperature_c = temperature_c;
        self.martensite_fraction = martensite_fraction;
        self.refresh_mix();
        Ok(())
    }
}

impl<S: Scalar> SmaCoil<S> {
    /// A cold coil whose convection, transformation temperatures and
    /// stress slope are `seeds` (their values must be `params`'; a dual
    /// seed carries its derivatives through every step).
    pub fn with_seeds(params: SmaParams, seeds: CoilSeeds<S>) -> Result<Self, PlantError> {
        params.validate("coil.")?;
        let own = CoilSeeds::<f64>::constants(&params).values();
        let seeded = seeds.values().map(f64::to_bits) == own.map(f64::to_bits);
        if !seeded {
            return Err(PlantError::param(
                "coil",
                "seeded parameters differ from the coil's own values",
            ));
        }
        let t = params.ambient_c;
        // Cold start below A_s: fully martensite. (A coil above A_f would be
        // austenite; we only start at ambient, validated < A_s below.)
        if t >= params.austenite_start_c {
            return Err(PlantError::param(
                "coil.ambient_c",
                "must be below austenite_start_c",
            ));
        }
        let [a_s, a_f, m_s, m_f] = seeds.transformation_c;
        let law = Law::new(a_s, a_f, m_s, m_f);
        let mut coil = Self {
            heat_capacity_j_k: params.heat_capacity_j_k(),
            // As SmaParams::conductance_w_k, with h a scalar.
            conductance_w_k: seeds.convection_w_m2_k
                * core::f64::consts::PI
                * params.wire_diameter_m
                * params.wire_length_m,
            resistance_martensite_ohm: params.resistance_ohm(1.0),
            resistance_austenite_ohm: params.resistance_ohm(0.0),
            phase_shape: law,
            law_values: law.values(),
            stress_slope: seeds.stress_shift_k_per_mpa,
            cached_dt_s: 0.0,
            cached_decay: S::cst(1.0),
            temperature_c: S::cst(t),
            martensite_fraction: S::cst(1.0),
            mix: PhaseMix {
                resistance_ohm: S::cst(0.0),
                stiffness_n_m: S::cst(0.0),
                rest_length_m: S::cst(0.0),
            },
            current_a: S::cst(0.0),
            shift_k: S::cst(0.0),
            next_shift_k: S::cst(0.0),
            shape_cache: ShapeCache::default(),
            params,
        };
        coil.refresh_mix();
        Ok(coil)
    }

    /// Recomputes the phase-mixed properties for the present ξ (each mixed
    /// linearly by phase).
    fn refresh_mix(&mut self) {
        let xi = self.martensite_fraction;
        let p = &self.params;
        let aus = -xi + 1.0;
        self.mix = PhaseMix {
            resistance_ohm: xi * self.resistance_martensite_ohm
                + aus * self.resistance_austenite_ohm,
            stiffness_n_m: xi * p.stiffness_martensite_n_m + aus * p.stiffness_austenite_n_m,
            rest_length_m: xi * p.rest_length_martensite_m + aus * p.rest_length_austenite_m,
        };
    }

    /// Parameters.
    pub fn params(&self) -> &SmaParams {
        &self.params
    }

    /// Coil temperature (°C).
    pub fn temperature_c(&self) -> S {
        self.temperature_c
    }

    /// Martensite fraction ξ ∈ [0, 1].
    pub fn martensite_fraction(&self) -> S {
        self.martensite_fraction
    }

    /// Current through the coil during the last step (A).
    pub fn current_a(&self) -> S {
        self.current_a
    }

    /// Present resistance (Ω) (resistivity mixed linearly by phase).
    #[inline]
    pub fn resistance_ohm(&self) -> S {
        self.mix.resistance_ohm
    }

    /// Present spring rate (N/m), mixed linearly by phase.
    #[inline]
    pub fn stiffness_n_m(&self) -> S {
        self.mix.stiffness_n_m
    }

    /// Present rest length (m), mixed linearly by phase.
    #[inline]
    pub fn rest_length_m(&self) -> S {
        self.mix.rest_length_m
    }

    /// Axial tension (N) at `length_m` stretching at `rate_m_s`; a coil
    /// shorter than its rest length is slack (no push).
    #[inline]
    pub fn tension_n(&self, length_m: S, rate_m_s: S) -> S {
        let stretch = length_m - self.rest_length_m();
        if stretch.val() <= 0.0 {
            S::cst(0.0)
        } else {
            (self.stiffness_n_m() * stretch + rate_m_s * self.params.damping_n_s_m)
                .max_of(S::cst(0.0))
        }
    }

    /// The wire stress for the next step's phase law (the coil's present
    /// tension, N): with `stress_shift_k_per_mpa = s` the transformation
    /// temperatures of the next step are raised by `s·F/A`. Does nothing
    /// when `s = 0` — but for a number carrying derivatives, whose shift
    /// has the derivative `ds·F/A` there (its value stays +0).
    #[inline]
    pub fn set_tension_for_phase(&mut self, tension_n: S) {
        let s = self.stress_slope;
        if s.val() != 0.0 || S::TANGENTS {
            self.next_shift_k = s * tension_n / self.params.wire_area_m2() * 1e-6;
        }
    }

    /// The present Clausius–Clapeyron shift of the transformation
    /// temperatures (K).
    pub fn transformation_shift_k(&self) -> S {
        self.next_shift_k
    }

    /// Advances the thermal and phase state by `dt_s` with `current_a`
    /// flowing. With `freeze_phase`, ξ (and so R) stays fixed and no latent
    /// heat is exchanged — the case with a closed-form answer.
    #[inline]
    pub fn step(&mut self, dt_s: f64, current_a: S, freeze_phase: bool) {
        if dt_s != self.cached_dt_s {
            self.cached_dt_s = dt_s;
            self.cached_decay = (self.conductance_w_k * -dt_s / self.heat_capacity_j_k).exp();
        }
        self.current_a = current_a;
        let power_w = current_a * current_a * self.resistance_ohm();
        // An idle coil (the usual case for one coil of a pair) has
        // power_w = +0 and power_w / G = +0 exactly; skip the division.
        let heating_k = if power_w.val() == 0.0 {
            S::cst(0.0)
        } else {
            power_w / self.conductance_w_k
        };
        let t_eq = heating_k + self.params.ambient_c;
        let t_old = self.temperature_c;
        let t_sensible = t_eq + (t_old - t_eq) * self.cached_decay;
        if freeze_phase {
            self.temperature_c = t_sensible;
        } else {
            let xi_old = self.martensite_fraction;
            let shift = [self.shift_k, self.next_shift_k];
            self.shift_k = self.next_shift_k;
            let (t_new, xi_new) = self.params.settle_latent_heat_with(
                &self.law_values,
                t_old.val(),
                xi_old.val(),
                t_sensible.val(),
                shift.map(S::val),
                &mut self.shape_cache,
            );
            let (t_new, xi_new) = if S::TANGENTS {
                settle_tangents(
                    &self.phase_shape,
                    self.params.latent_rise_k(),
                    t_old,
                    xi_old,
                    t_sensible,
                    shift,
                    t_new,
                )
            } else {
                (S::cst(t_new), S::cst(xi_new))
            };
            self.temperature_c = t_new;
            // A dual's derivatives can move where its value does not.
            if xi_new.val() != xi_old.val() || S::TANGENTS {
                self.martensite_fraction = xi_new;
                self.refresh_mix();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_coil_matches_spec_estimates() {
        let p = SmaParams::default();
        let r = p.resistance_ohm(1.0);
        assert!((r - 5.0).abs() < 0.1, "R_M = {r}");
        assert!((p.resistance_ohm(0.0) / r - 1.25).abs() < 1e-12);
        let tau = p.time_constant_s();
        assert!((3.0..=7.0).contains(&tau), "tau = {tau}");
    }

    #[test]
    fn full_heating_then_cooling_cycle() {
        let p = SmaParams::default();
        let mut xi = 1.0;
        let mut t = 25.0;
        while t < 100.0 {
            let t2 = t + 0.5;
            xi = p.phase_update(t, xi, t2);
            t = t2;
            if t < p.austenite_start_c {
                assert_eq!(xi, 1.0);
            }
        }
        assert_eq!(xi, 0.0);
        while t > 20.0 {
            let t2 = t - 0.5;
            xi = p.phase_update(t, xi, t2);
            t = t2;
            if t > p.martensite_start_c {
                assert_eq!(xi, 0.0, "no reverse transformation above M_s (hysteresis)");
            }
        }
        assert_eq!(xi, 1.0);
    }

    #[test]
    fn partial_heating_resumes_on_the_cooling_branch() {
        let p = SmaParams::default();
        // Heat to the middle of the A band: ξ = g_A(73) = 0.5.
        let xi = p.phase_update(25.0, 1.0, 73.0);
        assert!((xi - 0.5).abs() < 1e-12, "{xi}");
        // Cooling to 60 °C (between A_s and M_s... above M_s): unchanged.
        let xi2 = p.phase_update(73.0, xi, 60.0);
        assert_eq!(xi2, xi);
        // Cooling to the middle of the M band: austenite halves (0.5 → 0.25).
        let xi3 = p.phase_update(60.0, xi2, 47.0);
        assert!((xi3 - 0.75).abs() < 1e-12, "{xi3}");
        // Reheating to 73 °C scales the martensite by g_A again: 0.75 · 0.5.
        let xi4 = p.phase_update(47.0, xi3, 73.0);
        assert!((xi4 - 0.375).abs() < 1e-12, "{xi4}");
        // Telescoping: many small steps give the same as one step.
        let mut xs = xi3;
        let mut t = 47.0;
        while t < 73.0 - 1e-9 {
            xs = p.phase_update(t, xs, t + 0.1);
            t += 0.1;
        }
        assert!((xs - p.phase_update(47.0, xi3, t)).abs() < 1e-9);
    }

    /// The phase law as first written (no fast paths, constants per call).
    fn phase_update_reference(p: &SmaParams, t_old: f64, xi_old: f64, t_new: f64) -> f64 {
        let pi = core::f64::consts::PI;
        let g_heat = |t: f64| {
            if t <= p.austenite_start_c {
                1.0
            } else if t >= p.austenite_finish_c {
                0.0
            } else {
                let a = pi / (p.austenite_finish_c - p.austenite_start_c);
                0.5 * (1.0 + (a * (t - p.austenite_start_c)).cos())
            }
        };
        let g_cool = |t: f64| {
            if t >= p.martensite_start_c {
                1.0
            } else if t <= p.martensite_finish_c {
                0.0
            } else {
                let a = pi / (p.martensite_start_c - p.martensite_finish_c);
                0.5 * (1.0 - (a * (t - p.martensite_finish_c)).cos())
            }
        };
        if t_new > t_old {
            if t_new >= p.austenite_finish_c {
                return 0.0;
            }
            let g_old = g_heat(t_old);
            if g_old <= 0.0 {
                return xi_old;
            }
            (xi_old * g_heat(t_new) / g_old).min(xi_old).clamp(0.0, 1.0)
        } else if t_new < t_old {
            if t_new <= p.martensite_finish_c {
                return 1.0;
            }
            let g_old = g_cool(t_old);
            if g_old <= 0.0 {
                return xi_old;
            }
            let aus = ((1.0 - xi_old) * g_cool(t_new) / g_old).min(1.0 - xi_old);
            (1.0 - aus).clamp(0.0, 1.0)
        } else {
            xi_old
        }
    }

    #[test]
    fn phase_update_fast_paths_are_bit_identical() {
        let p = SmaParams::default();
        let temps: Vec<f64> = (0..=600).map(|k| 20.0 + k as f64 * 0.1 + 1e-3).collect();
        let xis = [
            -0.0,
            0.0,
            1e-17,
            0.1,
            0.3,
            1.0 / 3.0,
            0.5,
            0.7,
            0.9,
            1.0 - 1e-16,
            1.0,
        ];
        for &xi in &xis {
            for (i, &a) in temps.iter().enumerate() {
                for &b in temps[i.saturating_sub(40)..(i + 40).min(temps.len())].iter() {
                    let fast = p.phase_update(a, xi, b);
                    let reference = phase_update_reference(&p, a, xi, b);
                    assert_eq!(fast.to_bits(), reference.to_bits(), "{a} → {b}, ξ = {xi}");
                }
            }
        }
    }

    #[test]
    fn frozen_phase_step_response_is_the_analytic_exponential() {
        let p = SmaParams::default();
        let mut c = SmaCoil::new(p.clone()).unwrap();
        let i = 0.2;
        let r = p.resistance_ohm(1.0);
        let ga = p.conductance_w_k();
        let tau = p.heat_capacity_j_k() / ga;
        let dt = 1e-3;
        for n in 1..=10_000 {
            c.step(dt, i, true);
            let t = n as f64 * dt;
            let expect = p.ambient_c + i * i * r / ga * (1.0 - (-t / tau).exp());
            assert!(
                (c.temperature_c() - expect).abs() < 1e-9,
                "t={t}: {} vs {expect}",
                c.temperature_c()
            );
        }
        // Independent forward-Euler check of the ODE at a small step, so a
        // wrong formula for T_eq or τ cannot pass by construction.
        let mut te = p.ambient_c;
        let h = 1e-4;
        for _ in 0..100_000 {
            te += h * (i * i * r - ga * (te - p.ambient_c)) / p.heat_capacity_j_k();
        }
        assert!(
            (c.temperature_c() - te).abs() < 0.01,
            "{} vs Euler {te}",
            c.temperature_c()
        );
    }

    #[test]
    fn latent_heat_slows_heating_through_the_band() {
        let p = SmaParams::default();
        let mut with = SmaCoil::new(p.clone()).unwrap();
        let mut without = SmaCoil::new(SmaParams {
            latent_heat_j_kg: 0.0,
            ..p
        })
        .unwrap();
        let mut steps = 0;
        while without.martensite_fraction() > 0.5 {
            with.step(1e-3, 0.3, false);
            without.step(1e-3, 0.3, false);
            steps += 1;
            assert!(steps < 30_000, "never transformed");
        }
        // Same power in; the latent heat absorbed keeps the other coil
        // cooler and less transformed.
        assert!(with.temperature_c() < without.temperature_c() - 1.0);
        assert!(with.martensite_fraction() > without.martensite_fraction() + 0.1);
    }

    #[test]
    fn latent_heat_keeps_the_phase_on_its_branch_through_both_bands() {
        // Heating from cold (ξ₀ = 1 below A_s) the phase must read
        // ξ = g_A(T) at the temperature the coil is actually at, and cooling
        // from fully austenite 1 − ξ = g_M(T): the latent heat changes how
        // fast T moves, never the ξ–T relation. At 1 ms steps with 0.5 A
        // the coil crosses the A band in ≈ 1 s, so each step carries a
        // latent correction of up to ≈ 0.2 K.
        let p = SmaParams::default();
        let mut c = SmaCoil::new(p.clone()).unwrap();
        let mut in_band = 0;
        for _ in 0..10_000 {
            c.step(1e-3, 0.5, false);
            let (t, xi) = (c.temperature_c(), c.martensite_fraction());
            if t > p.austenite_start_c && t < p.austenite_finish_c {
                in_band += 1;
            }
            assert!(
                (xi - p.g_heat(&p.phase_shape(), t)).abs() < 1e-6,
                "heating: ξ = {xi} at {t} °C, branch says {}",
                p.g_heat(&p.phase_shape(), t)
            );
        }
        assert!(in_band > 100, "only {in_band} steps inside the A band");
        assert_eq!(c.martensite_fraction(), 0.0);
        in_band = 0;
        for _ in 0..60_000 {
            c.step(1e-3, 0.0, false);
            let (t, xi) = (c.temperature_c(), c.martensite_fraction());
            if t > p.martensite_finish_c && t < p.martensite_start_c {
                in_band += 1;
            }
            assert!(
                ((1.0 - xi) - p.g_cool(&p.phase_shape(), t)).abs() < 1e-6,
                "cooling: ξ = {xi} at {t} °C, branch says {}",
                1.0 - p.g_cool(&p.phase_shape(), t)
            );
        }
        assert!(in_band > 100, "only {in_band} steps inside the M band");
        assert_eq!(c.martensite_fraction(), 1.0);
    }

    #[test]
    fn latent_heat_balances_the_energy_of_each_step() {
        // c·(T − T_sensible) = ΔH·(ξ − ξ₀): the settled state closes the
        // step's energy balance, and the step never reverses the direction
        // the sensible heat was taking the coil.
        let p = SmaParams::default();
        for (t_old, xi_old, t_sensible) in [
            (69.0, p.g_heat(&p.phase_shape(), 69.0), 69.5),
            (73.0, p.g_heat(&p.phase_shape(), 73.0), 74.0),
            (77.5, p.g_heat(&p.phase_shape(), 77.5), 79.0),
            (50.0, 1.0 - p.g_cool(&p.phase_shape(), 50.0), 49.0),
            (45.0, 1.0 - p.g_cool(&p.phase_shape(), 45.0), 44.9),
        ] {
            let (t, xi) = p.settle_latent_heat(t_old, xi_old, t_sensible);
            let lhs = p.specific_heat_j_kg_k * (t - t_sensible);
            let rhs = p.latent_heat_j_kg * (xi - xi_old);
            assert!(
                (lhs - rhs).abs() < 1e-6,
                "{t_old}→{t_sensible}: {lhs} vs {rhs}"
            );
            assert!(xi != xi_old, "{t_old}→{t_sensible}: no transformation");
            assert_eq!((t - t_old).signum(), (t_sensible - t_old).signum());
            assert!((t - t_old).abs() <= (t_sensible - t_old).abs());
        }
    }

    /// A coil carrying the branch shapes from one search to the next
    /// step is, to the bit, a coil that evaluates them afresh every step:
    /// heating through A_s–A_f and cooling through M_s–M_f at 1 ms with
    /// the stress shift on, against the same steps through
    /// `settle_latent_heat_with` with an empty cache each time.
    #[test]
    fn carried_branch_shapes_change_no_bit() {
        let p = SmaParams {
            stress_shift_k_per_mpa: 0.05,
            ..SmaParams::default()
        };
        let mut c = SmaCoil::new(p.clone()).unwrap();
        let (mut t, mut xi) = (p.ambient_c, 1.0);
        let (g, mc) = (p.conductance_w_k(), p.heat_capacity_j_k());
        let decay = (-1e-3 * g / mc).exp();
        let mut shift = [0.0; 2];
        let mut searched = 0;
        for k in 0..60_000 {
            let i = if k < 30_000 { 0.3 } else { 0.0 };
            let tension = 1.0 + 0.5 * (k as f64 * 1e-3).sin();
            c.set_tension_for_phase(tension);
            c.step(1e-3, i, false);
            let r = xi * p.resistance_ohm(1.0) + (1.0 - xi) * p.resistance_ohm(0.0);
            let t_eq = p.ambient_c + if i == 0.0 { 0.0 } else { i * i * r / g };
            let t_sensible = t_eq + (t - t_eq) * decay;
            shift = [shift[1], 0.05 * tension / p.wire_area_m2() * 1e-6];
            let shape = p.phase_shape();
            let (t2, xi2) = p.settle_latent_heat_with(
                &shape,
                t,
                xi,
                t_sensible,
                shift,
                &mut ShapeCache::default(),
            );
            searched += usize::from(xi2 != xi);
            (t, xi) = (t2, xi2);
            assert_eq!(c.temperature_c().to_bits(), t.to_bits(), "step {k}");
            assert_eq!(c.martensite_fraction().to_bits(), xi.to_bits(), "step {k}");
        }
        assert!(searched > 5000, "only {searched} steps transform");
    }

    /// The energy balance's residual T − t_sensible − (ΔH/c)(ξ(T) − ξ_old)
    /// on the phase law as first written: the two reference solvers' function.
    fn balance_residual(
        p: &SmaParams,
        t_old: f64,
        xi_old: f64,
        t_sensible: f64,
        shift_k: [f64; 2],
    ) -> impl Fn(f64) -> f64 + '_ {
        let l = p.latent_heat_j_kg / p.specific_heat_j_kg_k;
        move |t: f64| {
            let xi = phase_update_reference(p, t_old - shift_k[0], xi_old, t - shift_k[1]);
            t - t_sensible - l * (xi - xi_old)
        }
    }

    /// The settled temperature by bisection of the energy balance on the
    /// phase law as first written, to a bracket of 1e-13 K: a reference
    /// that shares no code with the solver.
    fn settle_by_bisection(
        p: &SmaParams,
        t_old: f64,
        xi_old: f64,
        t_sensible: f64,
        shift_k: [f64; 2],
    ) -> f64 {
        let r = balance_residual(p, t_old, xi_old, t_sensible, shift_k);
        let (mut lo, mut hi) = (t_old.min(t_sensible), t_old.max(t_sensible));
        if r(lo) >= 0.0 {
            return lo;
        }
        if r(hi) <= 0.0 {
            return hi;
        }
        while hi - lo > 1e-13 {
            let mid = 0.5 * (lo + hi);
            if mid <= lo || mid >= hi {
                break;
            }
            if r(mid) < 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    /// The solver before it stopped on the residual: Illinois until the
    /// bracket is < 1e-9 K (the code of 2b453f0, on the reference law).
    fn settle_to_bracket(
        p: &SmaParams,
        t_old: f64,
        xi_old: f64,
        t_sensible: f64,
        shift_k: [f64; 2],
    ) -> f64 {
        let r = balance_residual(p, t_old, xi_old, t_sensible, shift_k);
        let (mut lo, mut hi) = (t_old.min(t_sensible), t_old.max(t_sensible));
        let (mut r_lo, mut r_hi) = (r(lo), r(hi));
        if r_lo >= 0.0 {
            return lo;
        }
        if r_hi <= 0.0 {
            return hi;
        }
        let (mut side, mut t) = (0i8, lo);
        for _ in 0..60 {
            t = (lo * r_hi - hi * r_lo) / (r_hi - r_lo);
            if !(t > lo && t < hi) {
                t = 0.5 * (lo + hi);
            }
            let rt = r(t);
            if rt == 0.0 || hi - lo < 1e-9 {
                break;
            }
            if rt < 0.0 {
                (lo, r_lo) = (t, rt);
                if side == -1 {
                    r_hi *= 0.5;
                }
                side = -1;
            } else {
                (hi, r_hi) = (t, rt);
                if side == 1 {
                    r_lo *= 0.5;
                }
                side = 1;
            }
        }
        t
    }

    /// The latent-heat search stopping on its residual lands within
    /// [`LATENT_HEAT_TOLERANCE_K`] of a bisection to 1e-13 K over a sweep
    /// of the states a coil can be in, in and around both bands, on and off
    /// their branches (minor loops), steps from 1e-4 K to 3 K both ways,
    /// with and without a stress shift; its ξ is the phase law's at the
    /// temperature returned; and it moves the answer by at most twice the
    /// tolerance from the search it replaced.
    #[test]
    fn latent_heat_search_is_within_its_tolerance_of_a_bisection() {
        let p = SmaParams::default();
        let shape = p.phase_shape();
        let (mut worst_ref, mut worst_old, mut solved) = (0.0f64, 0.0f64, 0);
        for i in 0..=80 {
            let t_old = 38.0 + 0.5 * i as f64;
            let on_branch = [p.g_heat(&shape, t_old), 1.0 - p.g_cool(&shape, t_old)];
            for xi_old in [0.05, 0.3, 0.6, 0.95, 1.0, on_branch[0], on_branch[1]] {
                for dt in [
                    1e-4, 1e-3, 1e-2, 0.1, 1.0, 3.0, -1e-4, -1e-3, -1e-2, -0.1, -1.0, -3.0,
                ] {
                    for shift_k in [[0.0, 0.0], [2.0, 2.003], [1.5, 1.4]] {
                        // No coil reaches these (fully martensite below
                        // M_f, fully austenite above A_f); from them ξ(T)
                        // jumps at t_old and the balance has no root.
                        let t_eff = t_old - shift_k[0];
                        if (t_eff <= p.martensite_finish_c && xi_old < 1.0)
                            || (t_eff >= p.austenite_finish_c && xi_old > 0.0)
                        {
                            continue;
                        }
                        let t_sensible = t_old + dt;
                        let (t, xi) = p.settle_latent_heat_with(
                            &shape,
                            t_old,
                            xi_old,
                            t_sensible,
                            shift_k,
                            &mut ShapeCache::default(),
                        );
                        let t_ref = settle_by_bisection(&p, t_old, xi_old, t_sensible, shift_k);
                        let t_prev = settle_to_bracket(&p, t_old, xi_old, t_sensible, shift_k);
                        let xi_law =
                            phase_update_reference(&p, t_old - shift_k[0], xi_old, t - shift_k[1]);
                        assert!(
                            (xi - xi_law).abs() <= 1e-12,
                            "{t_old}, {xi_old}, {t_sensible}, {shift_k:?}: ξ {xi} vs {xi_law}"
                        );
                        worst_ref = worst_ref.max((t - t_ref).abs());
                        worst_old = worst_old.max((t - t_prev).abs());
                        solved += usize::from(xi != xi_old);
                    }
                }
            }
        }
        eprintln!(
            "{solved} transforming steps; max |T − bisection| {worst_ref:.2e} K, \
             max |T − previous search| {worst_old:.2e} K"
        );
        assert!(solved > 2000, "only {solved} steps transform");
        assert!(
            worst_ref <= LATENT_HEAT_TOLERANCE_K + 1e-12,
            "{worst_ref:e}"
        );
        assert!(worst_old <= 2.0 * LATENT_HEAT_TOLERANCE_K, "{worst_old:e}");
    }

    #[test]
    fn spring_moves_between_phases_and_goes_slack() {
        let p = SmaParams::default();
        let mut c = SmaCoil::new(p.clone()).unwrap();
        assert!((c.stiffness_n_m() - 90.0).abs() < 1e-12);
        assert!((c.tension_n(0.020, 0.0) - 90.0 * 0.004).abs() < 1e-12);
        c.set_state(90.0, 0.0).unwrap();
        assert!((c.tension_n(0.020, 0.0) - 230.0 * 0.013).abs() < 1e-12);
        assert_eq!(c.tension_n(0.006, 0.0), 0.0);
    }

    /// Heats (at 0.35 A) or cools a coil under a constant tension and
    /// returns the temperature at which ξ first crosses `xi`.
    fn crossing_c(p: &SmaParams, tension_n: f64, heat: bool, xi: f64) -> f64 {
        let mut c = SmaCoil::new(p.clone()).unwrap();
        if !heat {
            c.set_state(120.0, 0.0).unwrap();
        }
        for _ in 0..200_000 {
            c.set_tension_for_phase(tension_n);
            c.step(1e-3, if heat { 0.35 } else { 0.0 }, false);
            let crossed = if heat {
                c.martensite_fraction() < xi
            } else {
                c.martensite_fraction() > xi
            };
            if crossed {
                return c.temperature_c();
            }
        }
        panic!("no crossing");
    }

    #[test]
    fn clausius_clapeyron_shifts_every_transformation_by_slope_times_stress() {
        let p = SmaParams {
            stress_shift_k_per_mpa: 0.1,
            ..SmaParams::default()
        };
        let f = 2.0; // N: 2 / 3.1416e-8 m² = 63.66 MPa → 6.37 K.
        let shift = 0.1 * f / p.wire_area_m2() * 1e-6;
        assert!((shift - 6.366).abs() < 1e-3, "{shift}");
        for (heat, xi) in [(true, 0.5), (true, 0.9), (false, 0.5), (false, 0.1)] {
            let free = crossing_c(&p, 0.0, heat, xi);
            let loaded = crossing_c(&p, f, heat, xi);
            // Sampling at 1 ms steps: the crossing is seen within one
            // step's temperature change (< 0.1 K here).
            assert!(
                (loaded - free - shift).abs() < 0.15,
                "heat {heat}, ξ = {xi}: {free} → {loaded}, expected +{shift}"
            );
        }
        // Off (the default): bit-identical to a coil that never sees a
        // tension.
        let d = SmaParams::default();
        let (mut a, mut b) = (SmaCoil::new(d.clone()).unwrap(), SmaCoil::new(d).unwrap());
        for k in 0..20_000 {
            let i = if k < 12_000 { 0.3 } else { 0.0 };
            a.set_tension_for_phase(2.5);
            a.step(1e-3, i, false);
            b.step(1e-3, i, false);
            assert_eq!(a, b);
        }
    }

    #[test]
    fn rising_stress_at_constant_temperature_forms_martensite() {
        // A coil held inside its M band, austenite, then loaded: its
        // effective temperature falls and martensite forms without cooling.
        let p = SmaParams {
            stress_shift_k_per_mpa: 0.1,
            latent_heat_j_kg: 0.0,
            ..SmaParams::default()
        };
        let mut c = SmaCoil::new(p.clone()).unwrap();
        c.set_state(p.martensite_start_c - 0.5, 0.0).unwrap();
        c.step(0.0 + 1e-9, 0.0, false);
        let before = c.martensite_fraction();
        c.set_tension_for_phase(2.0);
        c.step(1e-9, 0.0, false);
        assert!(before < 0.05, "{before}");
        assert!(c.martensite_fraction() > 0.3, "{}", c.martensite_fraction());
    }

    #[test]
    fn bad_parameters_name_the_field() {
        let p = SmaParams {
            stress_shift_k_per_mpa: -0.1,
            ..SmaParams::default()
        };
        assert!(SmaCoil::new(p)
            .unwrap_err()
            .to_string()
            .contains("coil.stress_shift_k_per_mpa"));
        let p = SmaParams {
            convection_w_m2_k: f64::NAN,
            ..SmaParams::default()
        };
        let e = SmaCoil::new(p).unwrap_err();
        assert!(e.to_string().contains("coil.convection_w_m2_k"), "{e}");
        let p = SmaParams {
            austenite_finish_c: 60.0,
            ..SmaParams::default()
        };
        assert!(SmaCoil::new(p)
            .unwrap_err()
            .to_string()
            .contains("austenite_finish_c"));
    }
}
