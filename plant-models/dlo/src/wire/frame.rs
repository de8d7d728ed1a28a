//! Euler angles of the local frame (Eq. 1–2, L700–722): the rotation
//! A(φ, θ, ψ) = Rz(φ)·Ry(θ)·Rz(ψ) whose columns are ξ, η, ζ, its partial
//! derivatives, and the angle rates ω_ξ, ω_η, ω_ζ along the object.
use nalgebra::{Matrix3, Vector3};

/// A(φ, θ, ψ) of Eq. 1 and ∂A/∂φ, ∂A/∂θ, ∂A/∂ψ.
pub fn rotation_and_partials(phi: f64, theta: f64, psi: f64) -> [Matrix3<f64>; 4] {
    let (sf, cf) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = psi.sin_cos();
    #[rustfmt::skip]
    let a = Matrix3::new(
        ct * cf * cp - sf * sp, -ct * cf * sp - sf * cp, st * cf,
        ct * sf * cp + cf * sp, -ct * sf * sp + cf * cp, st * sf,
        -st * cp,               st * sp,                 ct,
    );
    #[rustfmt::skip]
    let d_phi = Matrix3::new(
        -ct * sf * cp - cf * sp, ct * sf * sp - cf * cp, -st * sf,
        ct * cf * cp - sf * sp,  -ct * cf * sp - sf * cp, st * cf,
        0.0,                     0.0,                     0.0,
    );
    #[rustfmt::skip]
    let d_theta = Matrix3::new(
        -st * cf * cp, st * cf * sp, ct * cf,
        -st * sf * cp, st * sf * sp, ct * sf,
        -ct * cp,      ct * sp,      -st,
    );
    #[rustfmt::skip]
    let d_psi = Matrix3::new(
        -ct * cf * sp - sf * cp, -ct * cf * cp + sf * sp, 0.0,
        -ct * sf * sp + cf * cp, -ct * sf * cp - cf * sp, 0.0,
        st * sp,                 st * cp,                 0.0,
    );
    [a, d_phi, d_theta, d_psi]
}

/// The Euler angles (φ, θ, ψ) of Eq. 1 of a rotation, θ ∈ [0, π]. Where
/// sin θ = 0 only φ ± ψ is defined; φ = 0 is taken there.
pub fn euler_angles(a: &Matrix3<f64>) -> [f64; 3] {
    let theta = a[(2, 2)].clamp(-1.0, 1.0).acos();
    if theta.sin() < 1e-12 {
        // A = Rz(ψ) at θ = 0 and Ry(π)Rz(ψ) at θ = π: the middle row is
        // (sin ψ, cos ψ, 0) in both.
        return [0.0, theta, a[(1, 0)].atan2(a[(1, 1)])];
    }
    [
        a[(1, 2)].atan2(a[(0, 2)]),
        theta,
        a[(2, 1)].atan2(-a[(2, 0)]),
    ]
}

/// (ω_ξ, ω_η, ω_ζ) of Eq. 2 from the angles and their rates.
pub fn omegas(theta: f64, psi: f64, dphi: f64, dtheta: f64, dpsi: f64) -> Vector3<f64> {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = psi.sin_cos();
    Vector3::new(
        -st * cp * dphi + sp * dtheta,
        st * sp * dphi + cp * dtheta,
        ct * dphi + dpsi,
    )
}

/// Partial derivatives of (ω_ξ, ω_η, ω_ζ) with respect to
/// (θ, ψ, φ', θ', ψ'), as columns.
pub fn omega_partials(theta: f64, psi: f64, dphi: f64, dtheta: f64) -> [Vector3<f64>; 5] {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = psi.sin_cos();
    [
        // ∂/∂θ
        Vector3::new(-ct * cp * dphi, ct * sp * dphi, -st * dphi),
        // ∂/∂ψ
        Vector3::new(
            st * sp * dphi + cp * dtheta,
            st * cp * dphi - sp * dtheta,
            0.0,
        ),
        // ∂/∂φ'
        Vector3::new(-st * cp, st * sp, ct),
        // ∂/∂θ'
        Vector3::new(sp, cp, 0.0),
        // ∂/∂ψ'
        Vector3::new(0.0, 0.0, 1.0),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Rotation3;

    #[test]
    fn eq_1_is_rz_ry_rz_and_partials_match_differences() {
        let (f, t, p) = (0.3, 1.1, -0.7);
        let [a, df, dt, dp] = rotation_and_partials(f, t, p);
        let want = Rotation3::from_axis_angle(&Vector3::z_axis(), f)
            * Rotation3::from_axis_angle(&Vector3::y_axis(), t)
            * Rotation3::from_axis_angle(&Vector3::z_axis(), p);
        assert!((a - want.matrix()).norm() < 1e-12);
        let h = 1e-6;
        let num = |g: &dyn Fn(f64) -> Matrix3<f64>| (g(h) - g(-h)) / (2.0 * h);
        assert!((num(&|e| rotation_and_partials(f + e, t, p)[0]) - df).norm() < 1e-8);
        assert!((num(&|e| rotation_and_partials(f, t + e, p)[0]) - dt).norm() < 1e-8);
        assert!((num(&|e| rotation_and_partials(f, t, p + e)[0]) - dp).norm() < 1e-8);
    }

    #[test]
    fn euler_angles_invert_eq_1_including_both_poles() {
        use std::f64::consts::PI;
        for (f, t, p) in [
            (0.3, 1.1, -0.7),
            (-2.0, 0.4, 2.5),
            (0.0, 0.0, 0.9),
            (0.0, PI, -1.2),
        ] {
            let a = rotation_and_partials(f, t, p)[0];
            let [f2, t2, p2] = euler_angles(&a);
            assert!(
                (rotation_and_partials(f2, t2, p2)[0] - a).norm() < 1e-12,
                "{f} {t} {p}"
            );
            assert!((t2 - t).abs() < 1e-9);
        }
    }

    #[test]
    fn omegas_are_the_body_rates_of_eq_2() {
        // Aᵀ dA/ds is the skew matrix of (ω_ξ, ω_η, ω_ζ).
        let ang = |s: f64| (0.4 + 1.3 * s, 0.8 - 0.5 * s * s, 0.2 * s);
        let s = 0.37;
        let h = 1e-6;
        let a = |s: f64| {
            let (f, t, p) = ang(s);
            rotation_and_partials(f, t, p)[0]
        };
        let da = (a(s + h) - a(s - h)) / (2.0 * h);
        let w = a(s).transpose() * da;
        let (f1, t1, p1) = ang(s + h);
        let (f0, t0, p0) = ang(s - h);
        let (_, t, p) = ang(s);
        let om = omegas(
            t,
            p,
            (f1 - f0) / (2.0 * h),
            (t1 - t0) / (2.0 * h),
            (p1 - p0) / (2.0 * h),
        );
        assert!((w[(2, 1)] - om.x).abs() < 1e-7, "{} {}", w[(2, 1)], om.x);
        assert!((w[(0, 2)] - om.y).abs() < 1e-7);
        assert!((w[(1, 0)] - om.z).abs() < 1e-7);
    }
}
