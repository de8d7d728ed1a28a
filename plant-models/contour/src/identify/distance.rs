//! Distances between contours: point to closed polygon, and where a ray
//! from a centre leaves a polygon (the signature of a drawn contour).
use crate::identify::tracked::Point;

/// Distance from `p` to segment `a`–`b`.
pub fn point_segment_distance(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let u = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.0 - (a.0 + u * dx)).hypot(p.1 - (a.1 + u * dy))
}

/// Distance from `p` to the closed polygon through `poly` (its edges,
/// including the closing one); ∞ for an empty polygon.
pub fn point_polygon_distance(p: Point, poly: &[Point]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| point_segment_distance(p, poly[i], poly[(i + 1) % n]))
        .fold(f64::INFINITY, f64::min)
}

/// Distance from `centre` along direction `angle_rad` to the farthest
/// crossing of the closed polygon (the boundary pixel a signature reads on
/// a binary image's ray); `None` if the ray misses it.
pub fn ray_exit_distance(centre: Point, angle_rad: f64, poly: &[Point]) -> Option<f64> {
    let (ux, uy) = (angle_rad.cos(), angle_rad.sin());
    let n = poly.len();
    let mut best: Option<f64> = None;
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (ex, ey) = (b.0 - a.0, b.1 - a.1);
        let den = ux * ey - uy * ex;
        if den.abs() < 1e-300 {
            continue;
        }
        let (wx, wy) = (a.0 - centre.0, a.1 - centre.1);
        let t = (wx * ey - wy * ex) / den;
        let v = (wx * uy - wy * ux) / den;
        if t >= 0.0 && (0.0..=1.0).contains(&v) {
            best = Some(best.map_or(t, |b: f64| b.max(t)));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_to_a_unit_square() {
        let sq = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        assert!((point_polygon_distance((0.5, 0.5), &sq) - 0.5).abs() < 1e-15);
        assert!((point_polygon_distance((2.0, 0.5), &sq) - 1.0).abs() < 1e-15);
        assert!((point_polygon_distance((2.0, 2.0), &sq) - 2f64.sqrt()).abs() < 1e-15);
        let r = ray_exit_distance((0.5, 0.5), 0.0, &sq).unwrap();
        assert!((r - 0.5).abs() < 1e-15);
        let r = ray_exit_distance((0.5, 0.5), std::f64::consts::FRAC_PI_4, &sq).unwrap();
        assert!((r - 0.5 * 2f64.sqrt()).abs() < 1e-12);
        assert!(ray_exit_distance((5.0, 5.0), 0.0, &sq).is_none());
    }
}
