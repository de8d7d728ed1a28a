//! The geometric compression model of Kita's CAD system under its two
//! approximations (Kita §II, L2403–2405):
//! - **A1**: each cross-section for compression (a plane parallel to the
//!   compression direction y and perpendicular to the chest wall, i.e. a
//!   plane x = const) deforms only within its plane: `x' = x`;
//! - **A2**: the mid-plane between the plates (y = 0) does not deform.
//!
//! The seed names the approximations but not the rule inside a
//! cross-section (that is in its ref. [16]); ours is the simplest one that
//! keeps both: every chord parallel to the compression direction (fixed x
//! and z) that is wider than the plate gap is squeezed uniformly about the
//! mid-plane to fit between the plates, `y' = y · h / Y(x, z)` with `h` half
//! the gap and `Y` the chord's half-width; narrower chords stay. z is kept,
//! so the model loses volume where the plates press — the FEM twin shows
//! where the tissue goes instead.
use super::phantom::SemiEllipsoid;

/// Where the geometric model puts the point `p` (mm) with the plates at
/// y = ±`half_gap_mm`.
pub fn compress_point(body: &SemiEllipsoid, p: [f64; 3], half_gap_mm: f64) -> [f64; 3] {
    let y_half = body.chord_half_width_mm(p[0], p[2]);
    if y_half <= half_gap_mm {
        return p;
    }
    [p[0], p[1] * half_gap_mm / y_half, p[2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a1_and_a2_hold_and_points_stay_between_the_plates() {
        let body = SemiEllipsoid::phantom();
        for p in body.markers() {
            let q = compress_point(&body, p, 40.0);
            assert_eq!(q[0], p[0], "A1: no motion across the cross-section");
            assert_eq!(q[2], p[2]);
            if p[1] == 0.0 {
                assert_eq!(q, p, "A2: the mid-plane does not move");
            }
            assert!(q[1].abs() <= 40.0 + 1e-12);
            assert!(q[1].abs() <= p[1].abs() + 1e-12);
        }
        // A chord narrower than the gap is untouched.
        let p = [60.0, 5.0, 10.0];
        assert!(body.chord_half_width_mm(60.0, 10.0) < 40.0);
        assert_eq!(compress_point(&body, p, 40.0), p);
    }
}
