//! The rigid part of a measured motion: Horn's closed-form absolute
//! orientation with unit quaternions (Zhang §III-B, Eq. 8, after Horn 1987,
//! the seed's ref. [15]).
//!
//! For point pairs `b_i ≈ R a_i + t`, the centred cross-covariance
//! `S = Σ (a_i − ā)(b_i − b̄)ᵀ` gives Horn's symmetric 4 × 4 matrix `N`;
//! the eigenvector of its largest eigenvalue is the unit quaternion of the
//! rotation that minimises `Σ |b_i − R a_i − t|²`, and `t = b̄ − R ā`.
//!
//! Eq. 8 leaves the translation out ("translation never affects the
//! deformation"); we keep Horn's `t` with `R`, because a translation is
//! not deformation either, and report both.
use crate::error::{Result, TissueError};
use nalgebra::{Matrix3, Matrix4, SymmetricEigen, Vector3};

/// A rigid motion `b = R a + t` and how well it fits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidFit {
    /// Rotation R.
    pub rotation: Matrix3<f64>,
    /// Translation t (mm).
    pub translation_mm: Vector3<f64>,
    /// Root-mean-square residual |b − R a − t| (mm).
    pub rms_residual_mm: f64,
}

impl RigidFit {
    /// Rotation angle (degrees).
    pub fn angle_deg(&self) -> f64 {
        ((self.rotation.trace() - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    /// Applies the motion to a point.
    pub fn apply(&self, a: [f64; 3]) -> [f64; 3] {
        let v = self.rotation * Vector3::from(a) + self.translation_mm;
        [v[0], v[1], v[2]]
    }
}

/// Angle (degrees) of the rotation `R₁ᵀ R₂` between two rotations.
pub fn rotation_difference_deg(r1: &Matrix3<f64>, r2: &Matrix3<f64>) -> f64 {
    let d = r1.transpose() * r2;
    ((d.trace() - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Horn's least-squares rigid motion taking `a[i]` to `b[i]`. Needs three
/// pairs that are not collinear.
pub fn horn(a: &[[f64; 3]], b: &[[f64; 3]]) -> Result<RigidFit> {
    if a.len() != b.len() {
        return Err(TissueError::TooFew {
            stage: "Horn's method",
            what: "pairs (the two point lists differ in length)",
            got: a.len().min(b.len()),
            needed: a.len().max(b.len()),
        });
    }
    if a.len() < 3 {
        return Err(TissueError::TooFew {
            stage: "Horn's method",
            what: "point pairs",
            got: a.len(),
            needed: 3,
        });
    }
    let n = a.len() as f64;
    let mean = |p: &[[f64; 3]]| {
        p.iter()
            .fold(Vector3::zeros(), |s, v| s + Vector3::from(*v))
            / n
    };
    let (ma, mb) = (mean(a), mean(b));
    let mut s = Matrix3::<f64>::zeros();
    for (pa, pb) in a.iter().zip(b) {
        s += (Vector3::from(*pa) - ma) * (Vector3::from(*pb) - mb).transpose();
    }
    let (sxx, sxy, sxz) = (s[(0, 0)], s[(0, 1)], s[(0, 2)]);
    let (syx, syy, syz) = (s[(1, 0)], s[(1, 1)], s[(1, 2)]);
    let (szx, szy, szz) = (s[(2, 0)], s[(2, 1)], s[(2, 2)]);
    #[rustfmt::skip]
    let nm = Matrix4::new(
        sxx + syy + szz, syz - szy,       szx - sxz,       sxy - syx,
        syz - szy,       sxx - syy - szz, sxy + syx,       szx + sxz,
        szx - sxz,       sxy + syx,       -sxx + syy - szz, syz + szy,
        sxy - syx,       szx + sxz,       syz + szy,       -sxx - syy + szz,
    );
    let eig = SymmetricEigen::new(nm);
    let mut order: Vec<usize> = (0..4).collect();
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let (l0, l1) = (eig.eigenvalues[order[0]], eig.eigenvalues[order[1]]);
    // Collinear (or coincident) points leave the largest eigenvalue double.
    let scale = eig.eigenvalues.iter().map(|v| v.abs()).fold(0.0, f64::max);
    if scale.is_nan() || scale <= 0.0 || (l0 - l1) <= 1e-12 * scale {
        return Err(TissueError::TooFew {
            stage: "Horn's method",
            what: "non-collinear point pairs (the rotation is not determined)",
            got: 0,
            needed: 3,
        });
    }
    let q = eig.eigenvectors.column(order[0]).normalize();
    let (q0, qx, qy, qz) = (q[0], q[1], q[2], q[3]);
    #[rustfmt::skip]
    let rotation = Matrix3::new(
        q0 * q0 + qx * qx - qy * qy - qz * qz, 2.0 * (qx * qy - q0 * qz),             2.0 * (qx * qz + q0 * qy),
        2.0 * (qy * qx + q0 * qz),             q0 * q0 - qx * qx + qy * qy - qz * qz, 2.0 * (qy * qz - q0 * qx),
        2.0 * (qz * qx - q0 * qy),             2.0 * (qz * qy + q0 * qx),             q0 * q0 - qx * qx - qy * qy + qz * qz,
    );
    let translation_mm = mb - rotation * ma;
    let sq: f64 = a
        .iter()
        .zip(b)
        .map(|(pa, pb)| {
            (Vector3::from(*pb) - rotation * Vector3::from(*pa) - translation_mm).norm_squared()
        })
        .sum();
    Ok(RigidFit {
        rotation,
        translation_mm,
        rms_residual_mm: (sq / n).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Rotation3, Unit};

    #[test]
    fn recovers_a_known_rotation_to_1e_9() {
        let axis = Unit::new_normalize(Vector3::new(0.3, -0.5, 0.81));
        let truth = Rotation3::from_axis_angle(&axis, 0.7).into_inner();
        let t = Vector3::new(12.0, -3.5, 40.0);
        let a: Vec<[f64; 3]> = (0..50)
            .map(|i| {
                let f = i as f64;
                [
                    30.0 * (0.37 * f).sin(),
                    25.0 * (0.91 * f).cos(),
                    10.0 * (0.13 * f).sin() + f * 0.2,
                ]
            })
            .collect();
        let b: Vec<[f64; 3]> = a
            .iter()
            .map(|p| {
                let v = truth * Vector3::from(*p) + t;
                [v[0], v[1], v[2]]
            })
            .collect();
        let fit = horn(&a, &b).unwrap();
        assert!(
            (fit.rotation - truth).amax() < 1e-9,
            "{}",
            fit.rotation - truth
        );
        assert!((fit.translation_mm - t).amax() < 1e-9);
        assert!(fit.rms_residual_mm < 1e-9);
        assert!(rotation_difference_deg(&fit.rotation, &truth) < 1e-6);
        assert!((fit.angle_deg() - 0.7f64.to_degrees()).abs() < 1e-9);
    }

    #[test]
    fn collinear_or_too_few_points_are_refused() {
        let a = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [3.0, 0.0, 0.0],
        ];
        assert!(horn(&a, &a).is_err());
        assert!(horn(&a[..2], &a[..2]).is_err());
    }
}
