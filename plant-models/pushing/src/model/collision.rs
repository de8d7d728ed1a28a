//! Hard geometric constraints applied after each integration step (§VI-D,
//! §VI-E of the seed): the table, the circular finger (by vertex, then by
//! edge with Algorithms 3 and 4) and the repair of reversed and flat
//! triangles. Positions are moved directly; velocities are not touched (that
//! is how the seed's Euler and Verlet runs were disturbed by these routines).
//!
//! Left out: friction with the table, and the finger's own shape beyond a
//! circle (the seed treats it as a circular obstacle, §VIII-A).
use crate::mesh::{cross, signed_area, Mesh};
use crate::V2;

/// Distance ε to which a vertex or edge is pushed clear of the finger, px
/// (estimate; the seed names ε without a value, §VI-D).
pub const FINGER_CLEARANCE_PX: f64 = 0.5;

/// Area below which a triangle counts as flat, px² (§VII-A: "set to 2.0
/// units"; footnote 4).
pub const FLAT_AREA_PX2: f64 = 2.0;

/// Fraction of the vertex–edge distance a reversed vertex is pushed back
/// (§VI-E footnote 3: 3/4).
pub const REVERSED_PUSH_FRACTION: f64 = 0.75;

/// A half-plane obstacle: material must satisfy (p − point)·normal ≥ 0.
/// The seed's table (§VI-D) is the line the block rests on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Table {
    /// A point of the table's surface, px.
    pub point_px: V2,
    /// Unit normal pointing into the allowed side.
    pub normal: V2,
}

impl Table {
    /// Pushes every vertex that went through the table back onto its border.
    /// Returns how many were moved.
    pub fn resolve(&self, positions_px: &mut [V2]) -> usize {
        let mut moved = 0;
        for p in positions_px.iter_mut() {
            let depth = (*p - self.point_px).dot(&self.normal);
            if depth < 0.0 {
                *p -= self.normal * depth;
                moved += 1;
            }
        }
        moved
    }
}

/// The robot finger seen as a circle (§VIII-A).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Finger {
    /// Centre, px.
    pub centre_px: V2,
    /// Radius, px.
    pub radius_px: f64,
}

/// Algorithm 3: the point of segment AB closest to C.
#[inline]
pub fn closest_point_on_segment(a: V2, b: V2, c: V2) -> V2 {
    let ab = b - a;
    let len = ab.norm();
    if len <= f64::MIN_POSITIVE {
        return a;
    }
    let x = (c - a).dot(&ab) / len; // signed length of the projection
    if x < 0.0 {
        a
    } else if x > len {
        b
    } else {
        a + ab * (x / len)
    }
}

impl Finger {
    /// Vertex stage: a vertex inside the circle goes radially out to
    /// radius + ε. `fallback_dir` (unit) is used for a vertex exactly at the
    /// centre. Returns how many vertices moved.
    pub fn resolve_vertices(&self, positions_px: &mut [V2], fallback_dir: V2) -> usize {
        let mut moved = 0;
        for p in positions_px.iter_mut() {
            let d = *p - self.centre_px;
            // Squared test first (most vertices are far from the finger),
            // with a margin of a few ulps so that it never skips a vertex
            // the exact test below would move.
            if d.norm_squared() > self.radius_px * self.radius_px * (1.0 + 8.0 * f64::EPSILON) {
                continue;
            }
            let n = d.norm();
            if n < self.radius_px {
                let dir = if n > 1e-12 { d / n } else { fallback_dir };
                *p = self.centre_px + dir * (self.radius_px + FINGER_CLEARANCE_PX);
                moved += 1;
            }
        }
        moved
    }

    /// Edge stage, Algorithm 4 on every spring: an edge crossing the circle
    /// is translated along (closest − centre) until it clears it by ε.
    pub fn resolve_edges(
        &self,
        edges: &[[usize; 2]],
        positions_px: &mut [V2],
        fallback_dir: V2,
    ) -> usize {
        let mut moved = 0;
        let r = self.radius_px;
        let c = self.centre_px;
        for &[i, j] in edges {
            let (a, b) = (positions_px[i], positions_px[j]);
            // Cheap reject by bounding box.
            if a.x.max(b.x) < c.x - r
                || a.x.min(b.x) > c.x + r
                || a.y.max(b.y) < c.y - r
                || a.y.min(b.y) > c.y + r
            {
                continue;
            }
            let closest = closest_point_on_segment(a, b, c);
            let d = closest - c;
            let n = d.norm();
            if n < r {
                let dir = if n > 1e-12 { d / n } else { fallback_dir };
                let disp = dir * (r - n + FINGER_CLEARANCE_PX);
                positions_px[i] += disp;
                positions_px[j] += disp;
                moved += 1;
            }
        }
        moved
    }
}

/// What the geometric repair did in one pass.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RepairCount {
    pub reversed: usize,
    pub flat: usize,
}

/// §VI-E: repairs reversed triangles (the vertex opposite the longest edge
/// has crossed it: it is pushed 3/4 of its distance to the edge back, and
/// both ends of the edge the same amount the other way) and flat ones (area
/// below [`FLAT_AREA_PX2`]: the longest edge and its opposite vertex move
/// apart along the edge's normal until the area is the threshold).
pub fn repair_triangles(mesh: &Mesh, positions_px: &mut [V2]) -> RepairCount {
    let mut count = RepairCount::default();
    for tri in &mesh.triangles {
        let [a, b, c] = *tri;
        let area = signed_area(positions_px[a], positions_px[b], positions_px[c]);
        if area >= FLAT_AREA_PX2 {
            continue;
        }
        // Longest edge (u, v) and the opposite vertex w, kept in CCW order
        // (u, v, w) so that a positive height means "not reversed".
        let cands = [(a, b, c), (b, c, a), (c, a, b)];
        let mut best = cands[0];
        let mut best_len = -1.0;
        for &(u, v, w) in &cands {
            let l = (positions_px[v] - positions_px[u]).norm_squared();
            if l > best_len {
                best_len = l;
                best = (u, v, w);
            }
        }
        let (u, v, w) = best;
        let base = positions_px[v] - positions_px[u];
        let base_len = best_len.sqrt();
        if base_len <= 1e-12 {
            // All three vertices coincide: nothing defines a direction.
            continue;
        }
        // Inward normal of edge u→v for a CCW triangle (left side).
        let normal = V2::new(-base.y, base.x) / base_len;
        let height = cross(base, positions_px[w] - positions_px[u]) / base_len; // signed
        let shift = if height < 0.0 {
            count.reversed += 1;
            // w is |height| on the wrong side; each side moves 3/4 of it.
            REVERSED_PUSH_FRACTION * (-height)
        } else {
            count.flat += 1;
            // Raise the height to 2·A_flat/base, half on each side.
            0.5 * (2.0 * FLAT_AREA_PX2 / base_len - height)
        };
        positions_px[w] += normal * shift;
        positions_px[u] -= normal * shift;
        positions_px[v] -= normal * shift;
    }
    count
}
