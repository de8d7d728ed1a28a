//! The fishbone belt on straight segments: the default belt solver.
//!
//! The spine is cut into N segments of length h = L_u/N. On segment i the
//! frame [ξ η ζ] turns at constant body rates ω_i = (0, τ_i, κ_i): the
//! in-plane rate ω_ξ is zero on every segment, so Eq. 48 holds along the
//! whole spine and not only at collocation points. β = tan α lives on the
//! nodes (β₀ = β_N = 0, Eq. 59 and 61); on a segment β is the mean of its
//! nodes and the twist rate is τ = −βκ, which is Eq. 55. The energy is
//! Eq. 57 in the form R_f/2 Σ h κ²(1 + β²)², Eq. 56 is imposed between
//! every pair of nodes, and Eq. 58 and 60 fix the far end.
//!
//! The frame of node i+1 is A_i·exp(h·\[ω_i\]×) (exact); the spine advances by
//! h·A_i·exp(h/2·\[ω_i\]×)·e_y, the tangent at the middle of the segment, which
//! is second order in h. The unknowns are the N rates κ_i and the N−1
//! interior β; derivatives are analytic (right Jacobians of SO(3)) and
//! checked against differences in the tests.
//!
//! Why not only the paper's Ritz form ([`super::belt`] with
//! `method = "ritz"`): with Euler angles in the Eq. 20 basis, Eq. 48 and 55
//! can hold only at the collocation points, and with the paper's 16 points
//! the spine bends in its own plane between them (rms ω_ξ ≈ 1.4 × rms ω_ζ
//! on the 6-harmonic solution, `belt_ritz_with_the_papers_16_points_…`):
//! the solved surface is not developable. Here developability holds by construction, and the
//! answer converges as N grows (README, "The belt's highest point").
use nalgebra::{Matrix3, Vector3};

use super::belt::BeltProblem;
use super::optimize::{Kind, Problem};

type V3 = Vector3<f64>;
type M3 = Matrix3<f64>;

fn skew(v: &V3) -> M3 {
    M3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// exp([φ]×) (Rodrigues) and the right Jacobian J_r(φ), with
/// d exp([φ]×) = exp([φ]×)·[J_r(φ) dφ]×.
fn exp_and_jr(phi: &V3) -> (M3, M3) {
    let t2 = phi.norm_squared();
    let k = skew(phi);
    let k2 = k * k;
    let (a, b, c) = if t2 < 1e-12 {
        (1.0 - t2 / 6.0, 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0)
    } else {
        let t = t2.sqrt();
        (t.sin() / t, (1.0 - t.cos()) / t2, (t - t.sin()) / (t2 * t))
    };
    let r = M3::identity() + k * a + k2 * b;
    let jr = M3::identity() - k * b + k2 * c;
    (r, jr)
}

/// Constraint rows of the far end (Eq. 58: 3, Eq. 60: 6), first in order.
pub const END_ROWS: usize = 9;

/// The belt compiled for the segment solver (lengths in units of L_u,
/// energy in units of R_f/L_u).
pub struct CompiledStrip {
    pub(crate) p: BeltProblem,
    /// Segments.
    pub(crate) segments: usize,
    kinds: Vec<Kind>,
    /// Width in units of L_u.
    width: f64,
    end: V3,
    target: M3,
}

/// Frames and positions along the strip for one set of unknowns.
pub(crate) struct Chain {
    /// Node frames A_0 … A_N.
    pub frames: Vec<M3>,
    /// Node positions x_0 … x_N.
    pub x: Vec<V3>,
    /// β at the nodes.
    pub beta: Vec<f64>,
    /// Per segment: body rates, exp(h/2 [ω]×), J_r(hω), J_r(hω/2).
    rates: Vec<V3>,
    half: Vec<M3>,
    jr: Vec<M3>,
    jr_half: Vec<M3>,
}

impl CompiledStrip {
    pub(crate) fn new(p: &BeltProblem) -> Self {
        let n = p.intervals;
        let mut kinds = vec![Kind::Equality; END_ROWS];
        kinds.extend(vec![Kind::Inequality; 2 * n]);
        let (s, c) = p.end_turn_rad.sin_cos();
        Self {
            segments: n,
            kinds,
            width: p.width_m / p.length_m,
            end: V3::new(p.end_m[0], p.end_m[1], p.end_m[2]) / p.length_m,
            // Eq. 60: ξ = x, η = (0, cos, sin), ζ = (0, −sin, cos).
            target: M3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
            p: p.clone(),
        }
    }

    fn h(&self) -> f64 {
        1.0 / self.segments as f64
    }

    /// β at node j (zero at both ends).
    fn node_beta(&self, z: &[f64], j: usize) -> f64 {
        let n = self.segments;
        if j == 0 || j == n {
            0.0
        } else {
            z[n + j - 1]
        }
    }

    /// The start: a bow of ψ amplitude `bow` towards +x, as the Ritz
    /// solver's ψ(u) = −bow·sin(2πu) (κ = ψ' on the flat belt), β = 0.
    pub(crate) fn start(&self, bow: f64) -> Vec<f64> {
        let n = self.segments;
        let h = self.h();
        let mut z = vec![0.0; 2 * n - 1];
        for (i, k) in z.iter_mut().take(n).enumerate() {
            let u = (i as f64 + 0.5) * h;
            *k = -bow * std::f64::consts::TAU * (std::f64::consts::TAU * u).cos();
        }
        z
    }

    /// A coarser solution `z` of `coarse` carried onto this strip: κ
    /// interpolated between segment middles, β between nodes.
    pub(crate) fn resample(&self, coarse: &CompiledStrip, z: &[f64]) -> Vec<f64> {
        let (m, n) = (coarse.segments, self.segments);
        let lerp = |f: &dyn Fn(usize) -> f64, count: usize, at: f64| {
            let pos = (at * (count - 1) as f64).clamp(0.0, (count - 1) as f64);
            let k = (pos.floor() as usize).min(count - 2);
            let t = pos - k as f64;
            f(k) * (1.0 - t) + f(k + 1) * t
        };
        let mut out = vec![0.0; self.vars()];
        for (i, k) in out.iter_mut().take(n).enumerate() {
            // Segment middles: u = (i + ½)/n; coarse middle j at (j + ½)/m.
            let u = (i as f64 + 0.5) / n as f64;
            let at = ((u * m as f64 - 0.5) / (m - 1) as f64).clamp(0.0, 1.0);
            *k = lerp(&|j| z[j], m, at);
        }
        for j in 1..n {
            out[n + j - 1] = lerp(&|q| coarse.node_beta(z, q), m + 1, j as f64 / n as f64);
        }
        out
    }

    pub(crate) fn chain(&self, z: &[f64]) -> Chain {
        let n = self.segments;
        let h = self.h();
        let mut c = Chain {
            frames: Vec::with_capacity(n + 1),
            x: Vec::with_capacity(n + 1),
            beta: (0..=n).map(|j| self.node_beta(z, j)).collect(),
            rates: Vec::with_capacity(n),
            half: Vec::with_capacity(n),
            jr: Vec::with_capacity(n),
            jr_half: Vec::with_capacity(n),
        };
        let mut a = M3::identity();
        let mut x = V3::zeros();
        for (i, &kappa) in z.iter().take(n).enumerate() {
            c.frames.push(a);
            c.x.push(x);
            let beta = 0.5 * (c.beta[i] + c.beta[i + 1]);
            let w = V3::new(0.0, -beta * kappa, kappa);
            let (r, jr) = exp_and_jr(&(w * h));
            let (m, jr_half) = exp_and_jr(&(w * (0.5 * h)));
            x += a * m * V3::y() * h;
            a *= r;
            c.rates.push(w);
            c.half.push(m);
            c.jr.push(jr);
            c.jr_half.push(jr_half);
        }
        c.frames.push(a);
        c.x.push(x);
        c
    }

    /// The far end's orientation error T⁻¹A_N as an angle, rad.
    pub(crate) fn end_angle(&self, c: &Chain) -> f64 {
        let s = self.target.transpose() * c.frames[self.segments];
        // atan2(|vee(skew S)|, (tr S − 1)/2): precise near zero, unlike acos.
        let v = V3::new(
            s[(2, 1)] - s[(1, 2)],
            s[(0, 2)] - s[(2, 0)],
            s[(1, 0)] - s[(0, 1)],
        );
        (0.5 * v.norm()).atan2(0.5 * (s.trace() - 1.0))
    }
}

impl Problem for CompiledStrip {
    fn vars(&self) -> usize {
        2 * self.segments - 1
    }

    fn energy(&self, z: &[f64], grad: &mut [f64]) -> f64 {
        let n = self.segments;
        let h = self.h();
        let mut total = 0.0;
        for i in 0..n {
            let (b0, b1) = (self.node_beta(z, i), self.node_beta(z, i + 1));
            let beta = 0.5 * (b0 + b1);
            let k = z[i];
            let q = 1.0 + beta * beta;
            total += 0.5 * h * k * k * q * q;
            grad[i] += h * k * q * q;
            let d_beta = h * k * k * q * 2.0 * beta;
            if i >= 1 {
                grad[n + i - 1] += 0.5 * d_beta;
            }
            if i + 1 < n {
                grad[n + i] += 0.5 * d_beta;
            }
        }
        total
    }

    fn kinds(&self) -> &[Kind] {
        &self.kinds
    }

    fn constraints(&self, z: &[f64], v: &mut [f64], jac: &mut [Vec<f64>]) {
        let n = self.segments;
        let h = self.h();
        for row in jac.iter_mut() {
            row.iter_mut().for_each(|x| *x = 0.0);
        }
        let c = self.chain(z);
        let xe = c.x[n];
        // Eq. 58: the far end of the spine.
        for d in 0..3 {
            v[d] = xe[d] - self.end[d];
        }
        // Eq. 60: η and ζ of the far end (six rows, three independent, as
        // the Ritz form); a turn [w]× of A_N moves a column c by w × c.
        let an = c.frames[n];
        for d in 0..3 {
            v[3 + d] = an[(d, 1)] - self.target[(d, 1)];
            v[6 + d] = an[(d, 2)] - self.target[(d, 2)];
        }
        let orient_eta = -skew(&an.column(1).into_owned());
        let orient_zeta = -skew(&an.column(2).into_owned());
        let ey = skew(&V3::y());
        for i in 0..n {
            // ∂(end position, end orientation)/∂ω_i.
            let world = c.frames[i + 1] * c.jr[i] * h;
            let gx = -(c.frames[i] * c.half[i] * ey * c.jr_half[i]) * (0.5 * h * h)
                - skew(&(xe - c.x[i + 1])) * world;
            let (ge, gz) = (orient_eta * world, orient_zeta * world);
            let w = c.rates[i];
            let beta = 0.5 * (c.beta[i] + c.beta[i + 1]);
            // ω_i = (0, −βκ, κ): ∂/∂κ_i = (0, −β, 1); ∂/∂β_node = (0, −κ/2, 0).
            let d_kappa = V3::new(0.0, -beta, 1.0);
            let d_node = V3::new(0.0, -0.5 * w.z, 0.0);
            let cols: [(Option<usize>, V3); 3] = [
                (Some(i), d_kappa),
                ((i >= 1).then(|| n + i - 1), d_node),
                ((i + 1 < n).then(|| n + i), d_node),
            ];
            for (col, dw) in cols {
                let Some(col) = col else { continue };
                let (px, pe, pz) = (gx * dw, ge * dw, gz * dw);
                for d in 0..3 {
                    jac[d][col] += px[d];
                    jac[3 + d][col] += pe[d];
                    jac[6 + d][col] += pz[d];
                }
            }
        }
        // Eq. 56 between every pair of nodes: ±(β_{j+1} − β_j)/h ≤ 2/V.
        let limit = 2.0 / self.width;
        for j in 0..n {
            let rate = (c.beta[j + 1] - c.beta[j]) / h;
            for (k, sign) in [(0, 1.0), (1, -1.0)] {
                let r = END_ROWS + 2 * j + k;
                v[r] = sign * rate - limit;
                if j + 1 < n {
                    jac[r][n + j] += sign / h;
                }
                if j >= 1 {
                    jac[r][n + j - 1] -= sign / h;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_and_right_jacobian_match_differences() {
        for phi in [V3::new(0.3, -0.7, 1.1), V3::new(1e-8, 0.0, -2e-8)] {
            let (r, jr) = exp_and_jr(&phi);
            let want = nalgebra::Rotation3::new(phi);
            assert!((r - want.matrix()).norm() < 1e-12);
            for k in 0..3 {
                let mut d = V3::zeros();
                d[k] = 1e-6;
                let num = (exp_and_jr(&(phi + d)).0 - exp_and_jr(&(phi - d)).0) / 2e-6;
                let ana = r * skew(&(jr * V3::ith(k, 1.0)));
                assert!((num - ana).norm() < 1e-8, "{k}: {num} vs {ana}");
            }
        }
    }

    #[test]
    fn strip_gradients_match_finite_differences() {
        let c = CompiledStrip::new(&BeltProblem {
            intervals: 12,
            ..BeltProblem::default()
        });
        let n = c.vars();
        let z: Vec<f64> = (0..n)
            .map(|i| 3.0 * ((i as f64) * 0.9).cos() + 0.2 * (i as f64 * 0.3).sin())
            .collect();
        super::super::optimize::assert_derivatives_match_differences(&c, &z, 1e-6, None);
    }

    #[test]
    fn a_flat_strip_is_straight_and_a_uniform_bend_is_a_circle() {
        let c = CompiledStrip::new(&BeltProblem {
            intervals: 40,
            ..BeltProblem::default()
        });
        let mut z = vec![0.0; c.vars()];
        let ch = c.chain(&z);
        assert!((ch.x[40] - V3::y()).norm() < 1e-12);
        // κ = π everywhere: a half circle of radius 1/π bowing to −x
        // (η' = −κξ), ending at (−2/π, 0, 0) with η reversed.
        z.iter_mut()
            .take(40)
            .for_each(|k| *k = std::f64::consts::PI);
        let ch = c.chain(&z);
        let end = ch.x[40];
        assert!(
            (end - V3::new(-2.0 / std::f64::consts::PI, 0.0, 0.0)).norm() < 1e-3,
            "{end}"
        );
        assert!((ch.frames[40].column(1) + V3::y()).norm() < 1e-12);
        let mut g = vec![0.0; c.vars()];
        let e = c.energy(&z, &mut g);
        assert!((e - 0.5 * std::f64::consts::PI.powi(2)).abs() < 1e-12);
    }
}
