//! The cartilage: an off-the-shelf sponge (paper: 10 mm thick, Young's
//! modulus about 20 kPa) glued between the socket and the link base,
//! modelled as `N` columns spread evenly across the base width. Each column
//! carries two 3-element viscoelastic models (seed 002 Eq. 3, the plant's
//! exact [`Element`]): one normal (compression / tension, glued) and one
//! tangential (shear). A column's displacement is the motion of its glued
//! point on the link base from where it was at rest, in the socket frame;
//! over a substep it is taken as moving linearly, and the dashpot's state is
//! advanced exactly for that motion.
//!
//! Because every column pushes back on its own point, a coil pulling one
//! side down compresses that side more: the link tilts about a point inside
//! the sponge that moves with the load — the shifting centre of rotation of
//! the paper's Fig. 3 — without any pivot in the model.
//!
//! Column stiffness from the continuum (relaxed, i.e. long-term):
//! `k_n = E·(w/N)·D/t` normal and `k_t = G·(w/N)·D/t` shear, `w` the base
//! width, `D` the depth, `t` the thickness. The instantaneous stiffness is
//! `(1 + r)` times that (seed 002 Eq. 9–10, stiffness ratio `r`) and the
//! dashpot is Rayleigh, `b = b_R·k` (Eq. 11).
//!
//! Left out: coupling between neighbouring columns (no Poisson bulging,
//! no bending of the sponge as a plate), large-strain stiffening of the foam
//! and contact/lift-off (the sponge is glued, as in the paper).

use serde::{Deserialize, Serialize};

use plant_common::scalar::Scalar;
use plant_common::three_element::{Element, ExactPair, StepLength};

use super::{check_positive, PlantError};

/// Sponge parameters.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CartilageParams {
    /// Young's modulus (Pa). Paper: "about 20 kPa".
    pub youngs_modulus_pa: f64,
    /// Shear modulus as a fraction of E. Estimate: 0.38 = 1/(2(1+ν)) for an
    /// open-cell foam with ν ≈ 0.3.
    pub shear_fraction: f64,
    /// Thickness (m). Paper: 10 mm.
    pub thickness_m: f64,
    /// Width of the glued base in the plane of motion (m). Estimate, tuned
    /// with the coil lever so the 50 g compliance test gives ≈ 12° unpowered
    /// and ≈ 7.5° at 3 V / 2 V (README.md): 22 mm, a fingertip-sized socket.
    pub width_m: f64,
    /// Depth out of the plane (m). Estimate: square pad, 22 mm.
    pub depth_m: f64,
    /// Number of columns across the width. 8 resolves the pressure
    /// distribution well enough for a shifting centre (the step's cost
    /// does not grow with it: the columns are summed by moments).
    pub columns: usize,
    /// Stiffness ratio r = k2/k1 (instantaneous over delayed spring).
    /// Estimate: 3 — foams are several times stiffer at impact than relaxed.
    pub stiffness_ratio: f64,
    /// Rayleigh damping coefficient b_R (s): dashpot = b_R × relaxed
    /// stiffness. Estimate, tuned so the return after cutting the weight is
    /// damped (paper Fig. 5) — see the compliance tests.
    pub rayleigh_damping_s: f64,
}

impl Default for CartilageParams {
    fn default() -> Self {
        Self {
            youngs_modulus_pa: 20e3,
            shear_fraction: 0.38,
            thickness_m: 10e-3,
            width_m: 22e-3,
            depth_m: 22e-3,
            columns: 8,
            stiffness_ratio: 3.0,
            rayleigh_damping_s: 0.05,
        }
    }
}

impl CartilageParams {
    /// Rejects bad values, naming the field.
    pub fn validate(&self, prefix: &str) -> Result<(), PlantError> {
        let p = |f: &str| format!("{prefix}{f}");
        check_positive(&p("youngs_modulus_pa"), self.youngs_modulus_pa)?;
        check_positive(&p("shear_fraction"), self.shear_fraction)?;
        check_positive(&p("thickness_m"), self.thickness_m)?;
        check_positive(&p("width_m"), self.width_m)?;
        check_positive(&p("depth_m"), self.depth_m)?;
        if !(2..=64).contains(&self.columns) {
            return Err(PlantError::param(&p("columns"), "must be in 2..=64"));
        }
        check_positive(&p("stiffness_ratio"), self.stiffness_ratio)?;
        super::check_finite(&p("rayleigh_damping_s"), self.rayleigh_damping_s)?;
        if self.rayleigh_damping_s < 0.0 {
            return Err(PlantError::param(&p("rayleigh_damping_s"), "must be ≥ 0"));
        }
        Ok(())
    }

    /// Relaxed rotational stiffness of the pad about its centre (N·m/rad),
    /// E·D·w³/(12 t) — for documentation and tests.
    pub fn relaxed_rotational_stiffness(&self) -> f64 {
        self.youngs_modulus_pa * self.depth_m * self.width_m.powi(3) / (12.0 * self.thickness_m)
    }
}

/// The sponge's state: its columns, summed in closed form.
///
/// Every column has the same normal and shear models (equal widths), its
/// glued point moves by `(x + s(cos θ − 1), y − s sin θ)` for a column at
/// `s` on the base, and its dashpots start at rest: the columns' states
/// and forces are the same affine function `a + b·s` of their position at
/// every substep (the exact step is linear in the state and the motion).
/// So the sponge keeps the two coefficients per model instead of a state
/// per column, and sums the columns' forces and torques through the
/// moments `N`, `Σs` and `Σs²` of their positions. Exact in real
/// arithmetic against stepping each column (the rounding differs, ≈ 1e-16
/// relative; `tests::moments_match_the_columns_one_by_one`), and O(1)
/// instead of O(N) per substep.
#[derive(Clone, Debug)]
pub struct Cartilage<S = f64> {
    params: CartilageParams,
    /// The sponge's modulus and Rayleigh damping as scalars (a dual
    /// carries their derivatives; their values are `params`').
    modulus_pa: S,
    damping_s: S,
    /// Moments of the columns' lateral positions on the link base
    /// (link frame): [N, Σs (m), Σs² (m²)].
    moments: [f64; 3],
    /// Dashpot displacement of a column at `s`, [shear, normal] (m):
    /// `x[0] + x[1]·s`.
    x: [[S; 2]; 2],
    /// Column displacement at the end of the last substep, [shear, normal]
    /// (m), as `u[0] + u[1]·s`: the start of the next substep's linear
    /// motion.
    u: [[S; 2]; 2],
    /// The exact steps ([shear, normal]) for the last step length.
    steps: Option<(StepLength, ExactPair<S>)>,
}

/// Force (N) and clockwise torque about the link-base origin (N·m) on the
/// link.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Wrench<S = f64> {
    /// Force along x (N).
    pub fx_n: S,
    /// Force along y (N).
    pub fy_n: S,
    /// Clockwise torque about the link-base origin (N·m).
    pub torque_cw_nm: S,
}

impl Cartilage {
    /// Builds the columns (allocates once).
    pub fn new(params: CartilageParams) -> Result<Self, PlantError> {
        let (e, b) = (params.youngs_modulus_pa, params.rayleigh_damping_s);
        Self::with_seeds(params, e, b)
    }
}

impl<S: Scalar> Cartilage<S> {
    /// The columns with the modulus and the damping given as scalars
    /// (their values must be `params`'; a dual carries its derivatives).
    pub fn with_seeds(
        params: CartilageParams,
        modulus_pa: S,
        damping_s: S,
    ) -> Result<Self, PlantError> {
        params.validate("cartilage.")?;
        if modulus_pa.val().to_bits() != params.youngs_modulus_pa.to_bits()
            || damping_s.val().to_bits() != params.rayleigh_damping_s.to_bits()
        {
            return Err(PlantError::param(
                "cartilage",
                "seeded parameters differ from the sponge's own values",
            ));
        }
        let n = params.columns;
        let area = params.width_m / n as f64 * params.depth_m;
        let kn = params.youngs_modulus_pa * area / params.thickness_m;
        let kt = kn * params.shear_fraction;
        let mk = |k: f64| {
            Element::from_ratio(k, params.stiffness_ratio, params.rayleigh_damping_s)
                .map_err(|e| PlantError::param("cartilage", &e.to_string()))
        };
        // The elements are built for their checks (the step is computed
        // from the scalars, as `exact_steps` says).
        mk(kt)?;
        mk(kn)?;
        let mut moments = [0.0; 3];
        for s_m in column_positions_m(&params) {
            moments[0] += 1.0;
            moments[1] += s_m;
            moments[2] += s_m * s_m;
        }
        Ok(Self {
            modulus_pa,
            damping_s,
            moments,
            x: [[S::cst(0.0); 2]; 2],
            u: [[S::cst(0.0); 2]; 2],
            steps: None,
            params,
        })
    }

    /// Parameters.
    pub fn params(&self) -> &CartilageParams {
        &self.params
    }

    /// The exact steps of the shear and normal models over `h`, as
    /// [`Element::relaxation_step`] gives them (to the bit, with `f64`),
    /// from the modulus and damping scalars: each column's springs and
    /// dashpot as `Element::from_ratio` splits them.
    fn exact_steps(&self, h: StepLength) -> ExactPair<S> {
        let p = &self.params;
        let area = p.width_m / p.columns as f64 * p.depth_m;
        let kn = self.modulus_pa * area / p.thickness_m;
        let kt = kn * p.shear_fraction;
        let r = p.stiffness_ratio;
        let lanes = [kt, kn].map(|k| (k * ((1.0 + r) / r), k * (1.0 + r), self.damping_s * k));
        ExactPair::relaxation(lanes, h)
    }

    /// Advances every column by `h` with the link base moving to (`x`,
    /// `y`) m and angle `theta` (clockwise positive), and returns the
    /// sponge's wrench on the link. The columns' dashpots are integrated
    /// exactly for motion linear over the substep, so this part is
    /// unconditionally stable.
    #[inline]
    pub fn step(&mut self, h: StepLength, x: S, y: S, sin_t: S, cos_t: S) -> Wrench<S> {
        let steps = match self.steps {
            Some((cached, steps)) if cached == h => steps,
            _ => {
                let steps = self.exact_steps(h);
                self.steps = Some((h, steps));
                steps
            }
        };
        // Column at s: end = (x + s(cos θ − 1), y − s sin θ) = e0 + e1·s.
        let e0 = [x, y];
        let e1 = [cos_t - 1.0, -sin_t];
        let f0 = steps.force(&mut self.x[0], self.u[0], e0);
        let f1 = steps.force(&mut self.x[1], self.u[1], e1);
        self.u = [e0, e1];
        // On the link, column at s: f(s) = −(f0 + f1·s), [shear, normal].
        let [n, s1, s2] = self.moments;
        let sum = |k: usize| -(f0[k] * n + f1[k] * s1);
        let first = |k: usize| -(f0[k] * s1 + f1[k] * s2);
        // Σ (r_y f_t − r_x f_n), r = (s cos θ, −s sin θ).
        Wrench {
            fx_n: sum(0),
            fy_n: sum(1),
            torque_cw_nm: -sin_t * first(0) - cos_t * first(1),
        }
    }

    /// Resets the viscous states (unloaded sponge at its glued rest).
    pub fn reset(&mut self) {
        self.x = [[S::cst(0.0); 2]; 2];
        self.u = [[S::cst(0.0); 2]; 2];
    }
}

/// The columns' lateral positions on the link base (m, link frame): `N`
/// equal widths across it, each at its middle.
fn column_positions_m(params: &CartilageParams) -> impl Iterator<Item = f64> + '_ {
    let n = params.columns;
    (0..n).map(move |i| -0.5 * params.width_m + (i as f64 + 0.5) * params.width_m / n as f64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn static_stiffness_matches_continuum() {
        let p = CartilageParams::default();
        let mut c = Cartilage::new(p.clone()).unwrap();
        let h = StepLength::new(1e-3).unwrap();
        // Hold a sink of 0.1 mm for long enough to relax: F = E A u / t.
        let mut w = Wrench::default();
        for _ in 0..20_000 {
            w = c.step(h, 0.0, -1e-4, 0.0, 1.0);
        }
        let expect = p.youngs_modulus_pa * p.width_m * p.depth_m / p.thickness_m * 1e-4;
        assert!(
            (w.fy_n - expect).abs() < 1e-6 * expect.max(1.0) + 1e-9,
            "{} vs {expect}",
            w.fy_n
        );
        assert!(w.torque_cw_nm.abs() < 1e-12);
        // Small rotation: torque → −E D w³/(12 t) θ · (1 − 1/N²) for N
        // discrete columns (sum of s_i² vs the integral).
        c.reset();
        let th: f64 = 1e-3;
        for _ in 0..20_000 {
            w = c.step(h, 0.0, 0.0, th.sin(), th.cos());
        }
        let n = p.columns as f64;
        let expect = -p.relaxed_rotational_stiffness() * (1.0 - 1.0 / (n * n)) * th;
        assert!(
            (w.torque_cw_nm - expect).abs() < 1e-3 * expect.abs(),
            "{} vs {expect}",
            w.torque_cw_nm
        );
    }

    /// The moments against an independent loop over the columns one by
    /// one with the exact step built afresh every time; the step length
    /// changes now and then (the cached step must follow it). Equal to
    /// rounding: the sums are the same in real arithmetic.
    #[test]
    fn moments_match_the_columns_one_by_one() {
        let p = CartilageParams::default();
        let mut c = Cartilage::new(p.clone()).unwrap();
        let n = p.columns;
        let area = p.width_m / n as f64 * p.depth_m;
        let kn = p.youngs_modulus_pa * area / p.thickness_m;
        let mk = |k: f64| Element::from_ratio(k, p.stiffness_ratio, p.rayleigh_damping_s);
        let (normal, shear) = (mk(kn).unwrap(), mk(kn * p.shear_fraction).unwrap());
        let (mut xn, mut xt) = (vec![0.0; n], vec![0.0; n]);
        let (mut un, mut ut) = (vec![0.0; n], vec![0.0; n]);
        let s_m: Vec<f64> = column_positions_m(&p).collect();
        let mut worst = 0.0f64;
        for k in 0..5000 {
            let h = StepLength::new(if k % 100 < 50 { 1e-3 } else { 0.25e-3 }).unwrap();
            let t = k as f64 * 1e-3;
            let (x, y, th) = (1e-4 * t.sin(), -2e-4 * t, 0.2 * (3.0 * t).sin());
            let (sn, cs) = th.sin_cos();
            let got = c.step(h, x, y, sn, cs);
            let mut want: Wrench = Wrench::default();
            // The scale of the rounding: each force is k₂ times the
            // difference of the column's displacement and its dashpot's,
            // the displacement (x + s·cos θ − s here) rounded relative to
            // its operands, so the force relative to k₂·(|x| + |s| + …).
            let mut scale: Wrench = Wrench::default();
            for (i, &s_m) in s_m.iter().enumerate() {
                let (rx, ry) = (s_m * cs, -s_m * sn);
                let (end_t, end_n) = (x + rx - s_m, y + ry);
                let ft = -shear.relaxation_step(h).force(&mut xt[i], ut[i], end_t);
                let fnn = -normal.relaxation_step(h).force(&mut xn[i], un[i], end_n);
                (ut[i], un[i]) = (end_t, end_n);
                want.fx_n += ft;
                want.fy_n += fnn;
                want.torque_cw_nm += ry * ft - rx * fnn;
                let operands = x.abs() + y.abs() + 2.0 * s_m.abs();
                let ft_scale = shear.k2() * (operands + xt[i].abs());
                let fn_scale = normal.k2() * (operands + xn[i].abs());
                scale.fx_n += ft_scale;
                scale.fy_n += fn_scale;
                scale.torque_cw_nm += (ry * ft_scale).abs() + (rx * fn_scale).abs();
            }
            for (g, w, sc) in [
                (got.fx_n, want.fx_n, scale.fx_n),
                (got.fy_n, want.fy_n, scale.fy_n),
                (got.torque_cw_nm, want.torque_cw_nm, scale.torque_cw_nm),
            ] {
                let rel = (g - w).abs() / sc.max(f64::MIN_POSITIVE);
                assert!(rel < 1e-14, "step {k}: {g} vs {w} (scale {sc})");
                worst = worst.max(rel);
            }
        }
        eprintln!("worst difference / its scale: {worst:.1e}");
    }

    #[test]
    fn instantaneous_response_is_stiffer_by_one_plus_r() {
        let p = CartilageParams::default();
        let mut c = Cartilage::new(p.clone()).unwrap();
        let h = StepLength::new(1e-6).unwrap();
        let w = c.step(h, 0.0, -1e-4, 0.0, 1.0);
        let relaxed = p.youngs_modulus_pa * p.width_m * p.depth_m / p.thickness_m * 1e-4;
        let ratio = w.fy_n / relaxed;
        assert!((ratio - (1.0 + p.stiffness_ratio)).abs() < 0.01, "{ratio}");
    }

    #[test]
    fn bad_parameters_name_the_field() {
        let p = CartilageParams {
            width_m: -1.0,
            ..CartilageParams::default()
        };
        assert!(Cartilage::new(p)
            .unwrap_err()
            .to_string()
            .contains("cartilage.width_m"));
        let p = CartilageParams {
            columns: 1,
            ..CartilageParams::default()
        };
        assert!(Cartilage::new(p)
            .unwrap_err()
            .to_string()
            .contains("cartilage.columns"));
    }
}
