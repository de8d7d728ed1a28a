//! Is a rope knotted? Crossings of a curve seen along a direction, and the
//! knot determinant |Δ(−1)| of the curve closed far outside itself.
//!
//! - [`crossings`]: the crossings of the open polyline's projection, each
//!   with which strand is on top. The *projected crossing number* of a
//!   straight or gently curved rope is 0.
//! - [`knot_determinant`]: the open curve is closed by lifting both ends
//!   above everything, running out past the curve's outline and joining
//!   them along a circle there — a closure whose added arc only ever passes
//!   over the rope, so it adds no knotting of its own. The determinant of
//!   the closed diagram comes from its Fox colouring matrix (each crossing:
//!   2·over − under_in − under_out), with one row and column struck out,
//!   computed exactly (Bareiss elimination on integers). The determinant
//!   is a knot invariant: 1 for the unknot, 3 for the trefoil (an overhand
//!   knot), 5 for the figure-eight knot. A determinant of 1 does not prove
//!   a curve unknotted (some knots have it), but anything else proves it
//!   knotted.
//!
//! The view direction should be generic (no two crossings at one point,
//! no vertex exactly over another strand); [`View::default`] is a top view
//! tilted by a few hundredths of a radian so that a rope lying flat on a
//! desk is seen in general position.
use nalgebra::{Rotation3, Vector3};

type V3 = Vector3<f64>;

/// A projection: points are rotated by `rotation`, then (x, y) is the
/// picture and z the height towards the viewer.
#[derive(Debug, Clone, Copy)]
pub struct View {
    rotation: Rotation3<f64>,
}

impl Default for View {
    fn default() -> Self {
        Self::from_above(0.0123, 0.0347)
    }
}

impl View {
    /// Looking down the z axis, tilted by `tilt_x` and `tilt_y` radians.
    pub fn from_above(tilt_x: f64, tilt_y: f64) -> Self {
        Self {
            rotation: Rotation3::from_euler_angles(tilt_x, tilt_y, 0.0),
        }
    }
    /// Looking along `axis` (towards −axis from its tip).
    pub fn along(axis: V3) -> Self {
        let rotation = Rotation3::rotation_between(&axis, &V3::z())
            .unwrap_or_else(|| Rotation3::from_euler_angles(std::f64::consts::PI, 0.0, 0.0));
        Self { rotation }
    }
    fn apply(&self, p: &V3) -> V3 {
        self.rotation * p
    }
}

/// One crossing of a projected curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// Position along the curve of the strand on top (segment index +
    /// fraction).
    pub over: f64,
    /// Position along the curve of the strand below.
    pub under: f64,
}

/// 2D intersection of segments p0p1 and q0q1: fractions (s, t) if they
/// cross in their interiors.
fn intersect_2d(p0: &V3, p1: &V3, q0: &V3, q1: &V3) -> Option<(f64, f64)> {
    let (dx, dy) = (p1.x - p0.x, p1.y - p0.y);
    let (ex, ey) = (q1.x - q0.x, q1.y - q0.y);
    let den = dx * ey - dy * ex;
    if den.abs() < 1e-300 {
        return None;
    }
    let (rx, ry) = (q0.x - p0.x, q0.y - p0.y);
    let s = (rx * ey - ry * ex) / den;
    let t = (rx * dy - ry * dx) / den;
    ((0.0..1.0).contains(&s) && (0.0..1.0).contains(&t)).then_some((s, t))
}

/// Crossings of the polyline through the projected points `q`; `closed`
/// adds the segment from the last point back to the first.
fn crossings_of(q: &[V3], closed: bool) -> Vec<Crossing> {
    let n = q.len();
    let segs = if closed { n } else { n.saturating_sub(1) };
    let mut out = Vec::new();
    for i in 0..segs {
        let (p0, p1) = (&q[i], &q[(i + 1) % n]);
        for j in i + 2..segs {
            if closed && i == 0 && j == segs - 1 {
                continue; // neighbours through the closing segment
            }
            let (q0, q1) = (&q[j], &q[(j + 1) % n]);
            if let Some((s, t)) = intersect_2d(p0, p1, q0, q1) {
                let zi = p0.z + s * (p1.z - p0.z);
                let zj = q0.z + t * (q1.z - q0.z);
                let (pi, pj) = (i as f64 + s, j as f64 + t);
                out.push(if zi >= zj {
                    Crossing {
                        over: pi,
                        under: pj,
                    }
                } else {
                    Crossing {
                        over: pj,
                        under: pi,
                    }
                });
            }
        }
    }
    out
}

/// Crossings of the open curve through `points` seen in `view`.
pub fn crossings(points: &[V3], view: View) -> Vec<Crossing> {
    let q: Vec<V3> = points.iter().map(|p| view.apply(p)).collect();
    crossings_of(&q, false)
}

/// The curve closed outside itself (module doc), in view coordinates.
fn closure(points: &[V3], view: View) -> Vec<V3> {
    let q: Vec<V3> = points.iter().map(|p| view.apply(p)).collect();
    let n = q.len() as f64;
    let (cx, cy) = (
        q.iter().map(|p| p.x).sum::<f64>() / n,
        q.iter().map(|p| p.y).sum::<f64>() / n,
    );
    let reach = q
        .iter()
        .map(|p| (p.x - cx).hypot(p.y - cy))
        .fold(0.0, f64::max);
    let top = q.iter().map(|p| p.z).fold(f64::NEG_INFINITY, f64::max) + 1.0 + reach;
    let radius = 1.5 * reach + 1.0;
    let angle = |p: &V3| (p.y - cy).atan2(p.x - cx);
    let (first, last) = (q[0], q[q.len() - 1]);
    let (a_end, a_start) = (angle(&last), angle(&first));
    let mut out = q.clone();
    // Up above everything, out, round, in, down.
    out.push(V3::new(last.x, last.y, top));
    let mut sweep = a_start - a_end;
    while sweep > std::f64::consts::PI {
        sweep -= 2.0 * std::f64::consts::PI;
    }
    while sweep < -std::f64::consts::PI {
        sweep += 2.0 * std::f64::consts::PI;
    }
    let arc = 48;
    for k in 0..=arc {
        let a = a_end + sweep * k as f64 / arc as f64;
        out.push(V3::new(cx + radius * a.cos(), cy + radius * a.sin(), top));
    }
    out.push(V3::new(first.x, first.y, top));
    out
}

/// The knot determinant of `points` closed outside itself, seen in `view`
/// (module doc). `None` if the exact elimination overflowed (a diagram of
/// some hundred crossings).
pub fn knot_determinant(points: &[V3], view: View) -> Option<u128> {
    if points.len() < 2 {
        return Some(1);
    }
    let q = closure(points, view);
    let cs = crossings_of(&q, true);
    let n = cs.len();
    if n == 0 {
        return Some(1);
    }
    // Arcs run from one under-passage to the next along the closed curve.
    let mut unders: Vec<f64> = cs.iter().map(|c| c.under).collect();
    unders.sort_by(f64::total_cmp);
    // Arc k starts at unders[k] and ends at unders[k+1] (cyclically); a
    // position p lies on the arc whose start is the last under-passage ≤ p.
    let arc_of = |p: f64| -> usize {
        match unders.iter().rposition(|&u| u <= p) {
            Some(k) => k,
            None => n - 1, // before the first under-passage: the last arc
        }
    };
    let mut m = vec![vec![0i128; n]; n];
    for (row, c) in cs.iter().enumerate() {
        let k_in = unders.iter().position(|&u| u == c.under).unwrap_or(0);
        let arc_after = k_in;
        let arc_before = (k_in + n - 1) % n;
        m[row][arc_of(c.over)] += 2;
        m[row][arc_before] -= 1;
        m[row][arc_after] -= 1;
    }
    // Strike out the last row and column; the determinant of the rest.
    let size = n - 1;
    if size == 0 {
        return Some(1);
    }
    let mut a: Vec<Vec<i128>> = m[..size].iter().map(|r| r[..size].to_vec()).collect();
    bareiss_det(&mut a).map(|d| d.unsigned_abs())
}

/// Exact determinant by fraction-free elimination; `None` on overflow.
fn bareiss_det(a: &mut [Vec<i128>]) -> Option<i128> {
    let n = a.len();
    let mut sign = 1i128;
    let mut prev = 1i128;
    for k in 0..n {
        if a[k][k] == 0 {
            let Some(swap) = (k + 1..n).find(|&i| a[i][k] != 0) else {
                return Some(0);
            };
            a.swap(k, swap);
            sign = -sign;
        }
        for i in k + 1..n {
            for j in k + 1..n {
                let v = a[i][j]
                    .checked_mul(a[k][k])?
                    .checked_sub(a[i][k].checked_mul(a[k][j])?)?;
                a[i][j] = v / prev;
            }
            a[i][k] = 0;
        }
        prev = a[k][k];
    }
    Some(sign * a[n - 1][n - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An open trefoil: the standard (2,3) torus-knot parametrisation with
    /// a small gap cut out, its ends pulled apart.
    fn open_trefoil(samples: usize) -> Vec<V3> {
        (0..samples)
            .map(|k| {
                let t = 0.05 + (2.0 * std::f64::consts::PI - 0.1) * k as f64 / (samples - 1) as f64;
                V3::new(
                    t.sin() + 2.0 * (2.0 * t).sin(),
                    t.cos() - 2.0 * (2.0 * t).cos(),
                    -(3.0 * t).sin(),
                )
            })
            .collect()
    }

    fn figure_eight(samples: usize) -> Vec<V3> {
        (0..samples)
            .map(|k| {
                let t = 0.05 + (2.0 * std::f64::consts::PI - 0.1) * k as f64 / (samples - 1) as f64;
                V3::new(
                    (2.0 + (2.0 * t).cos()) * (3.0 * t).cos(),
                    (2.0 + (2.0 * t).cos()) * (3.0 * t).sin(),
                    (4.0 * t).sin(),
                )
            })
            .collect()
    }

    #[test]
    fn trefoil_has_determinant_3_seen_from_anywhere() {
        let c = open_trefoil(400);
        for view in [
            View::default(),
            View::along(V3::new(1.0, 0.3, 0.2)),
            View::along(V3::new(-0.2, 1.0, 0.5)),
        ] {
            assert_eq!(knot_determinant(&c, view), Some(3));
        }
        assert_eq!(crossings(&c, View::default()).len(), 3);
    }

    #[test]
    fn figure_eight_has_determinant_5() {
        assert_eq!(
            knot_determinant(&figure_eight(600), View::default()),
            Some(5)
        );
    }

    #[test]
    fn unknotted_curves_have_determinant_1() {
        // A straight line, and a coiled spring (many crossings, no knot).
        let line: Vec<V3> = (0..20).map(|i| V3::new(i as f64, 0.0, 0.0)).collect();
        assert_eq!(crossings(&line, View::default()).len(), 0);
        assert_eq!(knot_determinant(&line, View::default()), Some(1));
        let coil: Vec<V3> = (0..400)
            .map(|k| {
                let t = k as f64 * 0.05;
                V3::new(t.cos(), 0.1 * t, t.sin())
            })
            .collect();
        let view = View::along(V3::new(0.3, 1.0, 0.2));
        assert!(crossings(&coil, view).len() > 3);
        assert_eq!(knot_determinant(&coil, view), Some(1));
    }
}
