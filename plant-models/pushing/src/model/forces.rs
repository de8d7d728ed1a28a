//! Constraint forces of the 2D mass-spring model (§VI-A and Appendix of the
//! seed): every constraint C has energy E = ½kC² (Eq. 7) and pushes with
//! F = −kC ∂C/∂p (Eq. 8).
//!
//! * Length with damping (Eq. 9, 10, 20), on every spring, with the plastic
//!   rest length l0 = (1 − α)·D0 of Algorithm 2 and Teschner's 1/D0²
//!   normalisation.
//! * Area (Eq. 11, 21–23) per triangle, no damping (as in the seed).
//! * Angle (Eq. 12, 26–30) at every corner of every triangle.
//!
//! Area and angle use the *signed* area and angle (counter-clockwise
//! positive). For a triangle that is not reversed they are exactly the
//! absolute-value forms of Eq. 11 and 12 and the forces are those of Eq. 23
//! and 29; for a reversed triangle they keep pushing it back to its rest
//! orientation instead of towards the mirror image. The angle force is
//! applied to all three vertices (the full gradient), so that constraint
//! forces sum to zero; Eq. 26 writes only the apex term, which is the
//! negative sum of the other two.
//!
//! Left out: gravity and friction (the seed has none in the model), the
//! Eq. 24–25 variant that normalises the gradient direction.
use crate::error::{check_range, PushError, Result};
use crate::mesh::{corner, corner_angle, cross, Mesh};
use crate::V2;
use serde::{Deserialize, Serialize};

/// The learnable constants of the mass-spring model (§VII-A, Table III).
/// Stiffnesses are in model units (unit masses, lengths in px): the
/// calibration absorbs the conversion to SI, as in the seed.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialParams {
    /// k_L: length preservation stiffness (Eq. 20). Table III: [1e-5, 1e4].
    pub k_length: f64,
    /// k_d: damping of the length constraint (Eq. 20). Table III: [1e-5, 2].
    pub k_damping: f64,
    /// k_A: area preservation stiffness (Eq. 23). Table III: [1e-5, 1e4].
    pub k_area: f64,
    /// k_φ: angle preservation stiffness (Eq. 26). Table III: [1e-5, 100].
    pub k_angle: f64,
    /// max(F): cap on the magnitude of the total force per vertex, model
    /// units (§VII-A). Table III: [5, 1e5].
    pub max_force: f64,
    /// yield: elastic compression strain beyond which a spring creeps
    /// (Algorithm 2). Table III: [1e-5, 1].
    pub yield_strain: f64,
    /// creep: fraction of the excess strain turned permanent per step
    /// (Algorithm 2). Table III: [1e-5, 1].
    pub creep: f64,
    /// max α: largest permanent compression of a spring (Algorithm 2).
    /// Table III: [1e-5, 0.9].
    pub max_alpha: f64,
}

impl std::fmt::Display for MaterialParams {
    /// The parameters as Table III names them.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "k_L = {:.6}, k_d = {:.6}, k_A = {:.6}, k_φ = {:.6}, max(F) = {:.6}, yield = {:.6}, creep = {:.6}, max α = {:.6}",
            self.k_length,
            self.k_damping,
            self.k_area,
            self.k_angle,
            self.max_force,
            self.yield_strain,
            self.creep,
            self.max_alpha
        )
    }
}

impl MaterialParams {
    /// The sponge parameters the seed prints under Fig. 14 (20×10 mesh).
    pub const SEED_FIG14_SPONGE: Self = Self {
        k_length: 3034.48,
        k_damping: 0.000237,
        k_area: 103.568,
        k_angle: 66.774,
        max_force: 1218.81,
        yield_strain: 0.000434973,
        creep: 0.00890343,
        max_alpha: 0.45204,
    };
    /// The plasticine parameters the seed prints under Fig. 15.
    pub const SEED_FIG15_PLASTICINE: Self = Self {
        k_length: 642.328,
        k_damping: 0.562201,
        k_area: 29.2776,
        k_angle: 72.6202,
        max_force: 765.912,
        yield_strain: 0.0790105,
        creep: 0.664469,
        max_alpha: 0.48842,
    };

    /// Checks every field is finite and physically meaningful (non-negative
    /// stiffnesses, max α below 1 so rest lengths stay positive).
    pub fn validate(&self) -> Result<()> {
        check_range("k_length", self.k_length, 0.0, f64::MAX)?;
        check_range("k_damping", self.k_damping, 0.0, f64::MAX)?;
        check_range("k_area", self.k_area, 0.0, f64::MAX)?;
        check_range("k_angle", self.k_angle, 0.0, f64::MAX)?;
        if !(self.max_force.is_finite() && self.max_force > 0.0) {
            return Err(PushError::InvalidParameter {
                name: "max_force",
                value: self.max_force,
                reason: "must be finite and > 0",
            });
        }
        check_range("yield_strain", self.yield_strain, 0.0, f64::MAX)?;
        check_range("creep", self.creep, 0.0, 1.0)?;
        check_range("max_alpha", self.max_alpha, 0.0, 0.99)?;
        Ok(())
    }

    /// The parameters as the vector searched by Algorithm 5, in the order of
    /// [`PARAM_NAMES`].
    pub fn to_array(&self) -> [f64; 8] {
        [
            self.k_damping,
            self.k_length,
            self.k_area,
            self.k_angle,
            self.max_force,
            self.max_alpha,
            self.yield_strain,
            self.creep,
        ]
    }

    /// Inverse of [`MaterialParams::to_array`].
    pub fn from_array(a: [f64; 8]) -> Self {
        Self {
            k_damping: a[0],
            k_length: a[1],
            k_area: a[2],
            k_angle: a[3],
            max_force: a[4],
            max_alpha: a[5],
            yield_strain: a[6],
            creep: a[7],
        }
    }
}

/// Names of the entries of [`MaterialParams::to_array`].
pub const PARAM_NAMES: [&str; 8] = [
    "k_damping",
    "k_length",
    "k_area",
    "k_angle",
    "max_force",
    "max_alpha",
    "yield",
    "creep",
];

/// Length force on vertex i from the spring (i, j), Eq. 20, with plastic
/// rest length `rest_len_px` and original length `d0_px` for normalisation.
/// The force on j is the negative.
#[inline]
#[allow(clippy::too_many_arguments)] // the eight quantities of Eq. 20, kept flat on the hot path
pub fn length_force(
    pi: V2,
    pj: V2,
    vi: V2,
    vj: V2,
    d0_px: f64,
    rest_len_px: f64,
    k_length: f64,
    k_damping: f64,
) -> V2 {
    let d = pj - pi;
    let l = d.norm();
    if l <= f64::EPSILON * d0_px {
        // Coincident ends: the direction is undefined; the geometric repair
        // (§VI-E) separates them. No force rather than NaN.
        return V2::zeros();
    }
    length_force_with(
        d,
        l,
        vj - vi,
        1.0 / (d0_px * d0_px),
        rest_len_px,
        k_length,
        k_damping,
    )
}

/// Eq. 20 from the spring vector `d` = p_j − p_i, its length `l` > 0, the
/// relative velocity and 1/D0² (precomputed per spring in [`Mesh`]).
#[inline(always)]
fn length_force_with(
    d: V2,
    l: f64,
    dv: V2,
    inv_d0_sq: f64,
    rest_len_px: f64,
    k_length: f64,
    k_damping: f64,
) -> V2 {
    let u = d * (1.0 / l);
    u * (k_length * inv_d0_sq * (l - rest_len_px) + k_damping * inv_d0_sq * u.dot(&dv))
}

/// Gradient of the signed area of triangle (a, b, c) w.r.t. each vertex,
/// px (the [1 × (p_j − p_k)]/2 factors of Eq. 23).
#[inline]
pub fn area_gradients(pa: V2, pb: V2, pc: V2) -> [V2; 3] {
    // ∂A/∂p_i = ½ R(p_j − p_k), R(x, y) = (y, −x), for (i, j, k) cyclic.
    let r = |v: V2| V2::new(v.y, -v.x);
    [0.5 * r(pb - pc), 0.5 * r(pc - pa), 0.5 * r(pa - pb)]
}

/// Area forces on the three vertices (Eq. 21–23): −k_A (A − A0)/A0² ∇A.
#[inline]
pub fn area_forces(pa: V2, pb: V2, pc: V2, a0_px2: f64, k_area: f64) -> [V2; 3] {
    let area = 0.5 * cross(pb - pa, pc - pa);
    let s = -k_area * (area - a0_px2) / (a0_px2 * a0_px2);
    let g = area_gradients(pa, pb, pc);
    [g[0] * s, g[1] * s, g[2] * s]
}

/// Gradient of the signed corner angle at apex i (from edge i→j to i→k)
/// w.r.t. (p_i, p_j, p_k), 1/px. Apex term equals Eq. 29.
#[inline]
pub fn angle_gradients(pi: V2, pj: V2, pk: V2) -> Option<[V2; 3]> {
    let e1 = pj - pi;
    let e2 = pk - pi;
    let l1 = e1.norm_squared();
    let l2 = e2.norm_squared();
    if l1 <= f64::MIN_POSITIVE || l2 <= f64::MIN_POSITIVE {
        return None;
    }
    // Rotating e by +90° and dividing by |e|² gives the angle's gradient.
    let gj = -V2::new(-e1.y, e1.x) / l1;
    let gk = V2::new(-e2.y, e2.x) / l2;
    Some([-(gj + gk), gj, gk])
}

/// Angle forces at one corner (Eq. 26): −k_φ (φ − φ0) ∂φ/∂p for the apex
/// and both neighbours. Returns zeros for a corner with a zero-length edge.
#[inline]
pub fn angle_forces(pi: V2, pj: V2, pk: V2, phi0_rad: f64, k_angle: f64) -> [V2; 3] {
    match angle_gradients(pi, pj, pk) {
        Some(g) => {
            let phi = corner_angle(pi, pj, pk);
            let s = -k_angle * (phi - phi0_rad);
            [g[0] * s, g[1] * s, g[2] * s]
        }
        None => [V2::zeros(); 3],
    }
}

/// Energy of the whole mesh (Eq. 7 summed over all constraints), model units.
/// Used by tests to check that the forces are its negative gradient.
pub fn elastic_energy(
    mesh: &Mesh,
    positions_px: &[V2],
    rest_len_px: &[f64],
    p: &MaterialParams,
) -> f64 {
    let mut e = 0.0;
    for (k, &[i, j]) in mesh.edges.iter().enumerate() {
        let d0 = mesh.rest_lengths_px[k];
        let c = ((positions_px[j] - positions_px[i]).norm() - rest_len_px[k]) / d0;
        e += 0.5 * p.k_length * c * c;
    }
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = *tri;
        let a0 = mesh.rest_areas_px2[t];
        let area = 0.5
            * cross(
                positions_px[b] - positions_px[a],
                positions_px[c] - positions_px[a],
            );
        let ca = (area - a0) / a0;
        e += 0.5 * p.k_area * ca * ca;
        for k in 0..3 {
            let (i, j, l) = corner(tri, k);
            let cphi = corner_angle(positions_px[i], positions_px[j], positions_px[l])
                - mesh.rest_angles_rad[t][k];
            e += 0.5 * p.k_angle * cphi * cphi;
        }
    }
    e
}

/// Adds every internal constraint force of the mesh to `forces`.
/// `velocities` feed the damping of Eq. 20; `rest_len_px` holds the plastic
/// rest lengths (1 − α)·D0.
///
/// This is the hot loop of every simulation. Per triangle it computes the
/// three edge vectors, their squared lengths and twice the signed area once,
/// and compares each corner with its rest angle by rotating (dot, cross) of
/// the corner by −φ0 (stored cos φ0, sin φ0): the deviation φ − φ0 is then
/// atan(y/x) of a small ratio, which a short series evaluates to within
/// an ulp; only corners deviating by more than [`SERIES_MAX_RATIO`] (or
/// degenerate triangles) use libm's `atan2`. Same forces as
/// [`accumulate_internal_forces_reference`] (the per-corner transcription of
/// Eq. 20, 23, 26) up to floating-point rounding; a test compares the two.
pub fn accumulate_internal_forces(
    mesh: &Mesh,
    positions_px: &[V2],
    velocities_px_s: &[V2],
    rest_len_px: &[f64],
    p: &MaterialParams,
    forces: &mut [V2],
) {
    accumulate_length_forces(mesh, positions_px, velocities_px_s, rest_len_px, p, forces);
    let do_area = p.k_area != 0.0;
    let do_angle = p.k_angle != 0.0;
    if !(do_area || do_angle) {
        return;
    }
    let k_area = if do_area { p.k_area } else { 0.0 };
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = *tri;
        let (pa, pb, pc) = (positions_px[a], positions_px[b], positions_px[c]);
        let ab = pb - pa;
        let ac = pc - pa;
        let bc = pc - pb;
        // Twice the signed area: the cross product of any corner's edges.
        let twice_area = cross(ab, ac);
        let (mut fa, mut fb, mut fc) = (V2::zeros(), V2::zeros(), V2::zeros());
        if do_area {
            // Eq. 21–23, as `area_forces`: −k_A (A − A0)/A0² ∇A.
            let a0 = mesh.rest_areas_px2[t];
            let s = -k_area * (0.5 * twice_area - a0) / (a0 * a0);
            let r = |v: V2| V2::new(v.y, -v.x);
            fa = 0.5 * r(pb - pc) * s;
            fb = 0.5 * r(pc - pa) * s;
            fc = 0.5 * r(pa - pb) * s;
        }
        if do_angle {
            let l_ab = ab.norm_squared();
            let l_ac = ac.norm_squared();
            let l_bc = bc.norm_squared();
            if l_ab <= f64::MIN_POSITIVE || l_ac <= f64::MIN_POSITIVE || l_bc <= f64::MIN_POSITIVE {
                angle_forces_triangle_reference(mesh, t, positions_px, p.k_angle, forces);
            } else {
                // Dot products of the two edges leaving each corner.
                let dots = [ab.dot(&ac), -(ab.dot(&bc)), ac.dot(&bc)];
                let rest = &mesh.rest_angles_rad[t];
                let cs = &mesh.rest_angle_cos_sin[t];
                let mut s = [0.0; 3];
                for k in 0..3 {
                    s[k] = -p.k_angle * angle_deviation(twice_area, dots[k], rest[k], cs[k]);
                }
                // w_e = ∂φ/∂(far end of edge e) seen from its near end:
                // −R⁺(e)/|e|² with R⁺ the +90° rotation. Corner a gets
                // [−(w_ab + w_ca), w_ab, w_ca] on (a, b, c), and cyclically.
                let rot = |v: V2| V2::new(-v.y, v.x);
                let w_ab = -rot(ab) * (1.0 / l_ab);
                let w_bc = -rot(bc) * (1.0 / l_bc);
                let w_ca = rot(ac) * (1.0 / l_ac); // edge c→a is −ac
                fa += w_ab * (s[1] - s[0]) + w_ca * (s[2] - s[0]);
                fb += w_ab * (s[0] - s[1]) + w_bc * (s[2] - s[1]);
                fc += w_ca * (s[0] - s[2]) + w_bc * (s[1] - s[2]);
            }
        }
        forces[a] += fa;
        forces[b] += fb;
        forces[c] += fc;
    }
}

/// Largest |tan(φ − φ0)| evaluated by the series in [`angle_deviation`];
/// beyond it (about 7°) libm's `atan2` is used.
pub const SERIES_MAX_RATIO: f64 = 0.125;

/// φ − φ0 for a corner with cross product `cr` and dot product `dot` of its
/// edges and rest angle φ0 (cos, sin in `cs`), with φ = atan2(cr, dot) in
/// (−π, π] as in [`corner_angle`].
#[inline(always)]
fn angle_deviation(cr: f64, dot: f64, phi0: f64, cs: [f64; 2]) -> f64 {
    // Rotating the corner by −φ0: (x, y) = |e1||e2| (cos δ, sin δ).
    let x = dot * cs[0] + cr * cs[1];
    let y = cr * cs[0] - dot * cs[1];
    if x > 0.0 && y.abs() <= SERIES_MAX_RATIO * x {
        let t = y / x;
        let u = t * t;
        // atan t = Σ (−1)^n t^(2n+1)/(2n+1); for |t| ≤ 1/8 the first omitted
        // term (n = 9) is below 2.8e-18 |t|, a fortieth of an ulp.
        // Estrin's scheme (shorter dependency chain than Horner).
        let u2 = u * u;
        let u4 = u2 * u2;
        let p01 = 1.0 - u * (1.0 / 3.0);
        let p23 = 1.0 / 5.0 - u * (1.0 / 7.0);
        let p45 = 1.0 / 9.0 - u * (1.0 / 11.0);
        let p67 = 1.0 / 13.0 - u * (1.0 / 15.0);
        let poly = (p01 + u2 * p23) + u4 * ((p45 + u2 * p67) + u4 * (1.0 / 17.0));
        let d = t * poly;
        // φ in (−π, π]: a corner whose rest angle is near π and that opens
        // beyond π reads as φ − 2π, as the atan2 form does.
        if phi0 + d > core::f64::consts::PI {
            d - 2.0 * core::f64::consts::PI
        } else {
            d
        }
    } else {
        cr.atan2(dot) - phi0
    }
}

fn accumulate_length_forces(
    mesh: &Mesh,
    positions_px: &[V2],
    velocities_px_s: &[V2],
    rest_len_px: &[f64],
    p: &MaterialParams,
    forces: &mut [V2],
) {
    if p.k_length != 0.0 || p.k_damping != 0.0 {
        for (k, &[i, j]) in mesh.edges.iter().enumerate() {
            // As `length_force`, with 1/D0² read from the mesh.
            let d = positions_px[j] - positions_px[i];
            let l = d.norm();
            if l <= f64::EPSILON * mesh.rest_lengths_px[k] {
                continue;
            }
            let f = length_force_with(
                d,
                l,
                velocities_px_s[j] - velocities_px_s[i],
                mesh.inv_rest_lengths_sq[k],
                rest_len_px[k],
                p.k_length,
                p.k_damping,
            );
            forces[i] += f;
            forces[j] -= f;
        }
    }
}

/// Angle forces of one triangle as a direct transcription of Eq. 26–29:
/// two corner angles by `atan2`, the third from the angle sum, gradients
/// per corner.
fn angle_forces_triangle_reference(
    mesh: &Mesh,
    t: usize,
    positions_px: &[V2],
    k_angle: f64,
    forces: &mut [V2],
) {
    let tri = &mesh.triangles[t];
    let [a, b, c] = *tri;
    let (pa, pb, pc) = (positions_px[a], positions_px[b], positions_px[c]);
    // Two corner angles by atan2; the third from the angle sum
    // (π for a counter-clockwise triangle, −π for a reversed one).
    let phi_a = corner_angle(pa, pb, pc);
    let phi_b = corner_angle(pb, pc, pa);
    let twice_area = cross(pb - pa, pc - pa);
    let phi_c = if twice_area.abs() > 1e-9 * (pb - pa).norm_squared().max((pc - pa).norm_squared())
    {
        core::f64::consts::PI.copysign(twice_area) - phi_a - phi_b
    } else {
        corner_angle(pc, pa, pb)
    };
    let r = &mesh.rest_angles_rad[t];
    for (k, phi) in [phi_a, phi_b, phi_c].into_iter().enumerate() {
        let (i, j, l) = corner(tri, k);
        if let Some(g) = angle_gradients(positions_px[i], positions_px[j], positions_px[l]) {
            let s = -k_angle * (phi - r[k]);
            forces[i] += g[0] * s;
            forces[j] += g[1] * s;
            forces[l] += g[2] * s;
        }
    }
}

/// The straightforward per-corner form of [`accumulate_internal_forces`]
/// (the implementation before the angle terms were restructured): every
/// angle from `atan2`, gradients and accumulation corner by corner. Kept as
/// the reference the fast version is tested against.
pub fn accumulate_internal_forces_reference(
    mesh: &Mesh,
    positions_px: &[V2],
    velocities_px_s: &[V2],
    rest_len_px: &[f64],
    p: &MaterialParams,
    forces: &mut [V2],
) {
    accumulate_length_forces(mesh, positions_px, velocities_px_s, rest_len_px, p, forces);
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = *tri;
        if p.k_area != 0.0 {
            let f = area_forces(
                positions_px[a],
                positions_px[b],
                positions_px[c],
                mesh.rest_areas_px2[t],
                p.k_area,
            );
            forces[a] += f[0];
            forces[b] += f[1];
            forces[c] += f[2];
        }
        if p.k_angle != 0.0 {
            angle_forces_triangle_reference(mesh, t, positions_px, p.k_angle, forces);
        }
    }
}

/// Caps the magnitude of each vertex force at `max_force` (§VII-A).
#[inline]
pub fn clamp_forces(forces: &mut [V2], max_force: f64) {
    for f in forces.iter_mut() {
        let n = f.norm();
        if n > max_force {
            *f *= max_force / n;
        }
    }
}
