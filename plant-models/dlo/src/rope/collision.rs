//! Self-collision of the rope (Shi & Payandeh §IV, L1320–1360): a
//! bounding-volume hierarchy of spheres built bottom-up over the segments,
//! explored in two copies from the top down; segments closer than 2r
//! (except immediate neighbours) collide. A collision is answered by the
//! repulsion force of Eq. 2 and the Coulomb friction of Eq. 1 and 4, both
//! applied as impulses to the four end points (Eq. 19–23), and by the
//! position shift of Fig. 6 (each segment moved r − d/2 + ε/2 away).
//!
//! Cost (issue 34), not the paper's: the tree's shape is fixed by the
//! number of segments, so it is refitted, not rebuilt; node pairs whose
//! segment pairs all lie within the excluded index gap are not explored;
//! and a sweep over the leaves first certifies when there is no contact
//! at all (a hanging rope), so that the tree is searched only when there
//! is one. The contacts, and their order, are those of the plain search.
//!
//! Generalisations, stated: points of infinite mass (pinned) take no
//! impulse and no shift, and the others share it so that the closest points
//! still separate as Eq. 19 prescribes (with four equal masses this is
//! Eq. 19–23 exactly). The friction impulse is capped at the one that stops
//! the tangential relative motion within the step: with μ = 10 (Table I)
//! an explicit Coulomb force would otherwise reverse the sliding and
//! chatter.
use super::forces::V3;

/// The smallest index distance j − i at which two segments of rest length
/// `rest_length_m` can be apart in space on a straight rope: (j − i − 1)
/// segments lie between them, so they are tested for contact only when
/// (j − i − 1)·l_r ≥ 2r. The paper excludes the immediate neighbours
/// (L1333), which is this rule when l_r ≥ 2r (Table I: l_r = 0.102 m at
/// N = 50, 2r = 0.1 m). With shorter segments (N > 51 at Table I's l and
/// r) segment i and i + 2 overlap on a straight rope; testing them would
/// push every rope apart on every step (issue 29: N = 60 hung 31 % low).
pub fn contact_index_gap(rest_length_m: f64, radius_m: f64) -> usize {
    let between = (2.0 * radius_m / rest_length_m - 1e-9).ceil().max(1.0);
    1 + between as usize
}

/// A bounding sphere.
#[derive(Debug, Clone, Copy)]
struct Sphere {
    centre: V3,
    radius: f64,
}

impl Sphere {
    fn overlaps(&self, o: &Sphere) -> bool {
        (self.centre - o.centre).norm_squared() <= (self.radius + o.radius).powi(2)
    }
    /// The smallest sphere enclosing both.
    fn merge(&self, o: &Sphere) -> Sphere {
        let d = o.centre - self.centre;
        let dist = d.norm();
        if dist + o.radius <= self.radius {
            return *self;
        }
        if dist + self.radius <= o.radius {
            return *o;
        }
        let radius = 0.5 * (dist + self.radius + o.radius);
        let centre = self.centre + d * ((radius - self.radius) / dist);
        Sphere { centre, radius }
    }
}

#[derive(Debug, Clone, Copy)]
struct Node {
    sphere: Sphere,
    /// Children, or `None` for a leaf.
    children: Option<(usize, usize)>,
    /// Leaf: its segment.
    segment: usize,
    /// The segments under the node: `first..=last` (a contiguous run of
    /// the chain, since each level merges neighbours).
    first: usize,
    last: usize,
}

/// The sphere tree over the rope's segments. Its shape depends only on the
/// number of segments, so it is laid out once and then refitted every step
/// (each sphere recomputed bottom-up from the points, O(N)); the spheres
/// are the ones a fresh build gives, bit for bit.
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    /// Leaves first (segment order), then each level's merged nodes; a
    /// node's children come before it.
    nodes: Vec<Node>,
    root: Option<usize>,
    /// Segments the shape was laid out for.
    leaves: usize,
    level: Vec<usize>,
    next: Vec<usize>,
    stack: Vec<(usize, usize)>,
    /// The sweep of [`Bvh::find_contacts`]: the leaves' intervals along
    /// one axis, sorted by their low ends (the order kept from step to
    /// step).
    sweep: Vec<Interval>,
}

/// A leaf's extent along the sweep's axis.
#[derive(Debug, Clone, Copy)]
struct Interval {
    low: f64,
    high: f64,
    segment: usize,
}

/// One pair of colliding segments and its closest points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Contact {
    /// First segment (points i, i+1).
    pub seg_a: usize,
    /// Second segment (points j, j+1), j > i + 1.
    pub seg_b: usize,
    /// Fraction a of point C along segment a.
    pub a: f64,
    /// Fraction b of point E along segment b.
    pub b: f64,
    /// Distance s between the centre lines at C and E, m.
    pub distance_m: f64,
    /// Unit vector n̂ from E to C.
    pub normal: V3,
}

/// The sphere of segment `i` (points i, i+1): centre at its midpoint,
/// radius l/2 + r.
fn leaf_sphere(x: &[V3], i: usize, radius_m: f64) -> Sphere {
    Sphere {
        centre: 0.5 * (x[i] + x[i + 1]),
        radius: 0.5 * (x[i + 1] - x[i]).norm() + radius_m,
    }
}

impl Bvh {
    /// Fits the tree to the points: leaves are the segments' spheres, each
    /// level merges neighbours in pairs (an odd one is carried up). The
    /// shape is laid out when the number of segments changes; otherwise
    /// only the spheres are recomputed, in the same order.
    pub fn build(&mut self, x: &[V3], radius_m: f64) {
        if self.needs_lay_out(x) {
            self.lay_out(x, radius_m);
        } else {
            self.fit_leaves(x, radius_m);
            self.fit_inner();
        }
    }

    /// Whether the shape is not laid out for this many segments.
    fn needs_lay_out(&self, x: &[V3]) -> bool {
        self.root.is_none() || self.leaves != x.len().saturating_sub(1)
    }

    /// Recomputes the leaves' spheres (the first `leaves` nodes).
    fn fit_leaves(&mut self, x: &[V3], radius_m: f64) {
        for (i, node) in self.nodes[..self.leaves].iter_mut().enumerate() {
            node.sphere = leaf_sphere(x, i, radius_m);
        }
    }

    /// Recomputes the merged nodes' spheres from the leaves up.
    fn fit_inner(&mut self) {
        for k in self.leaves..self.nodes.len() {
            if let Some((l, r)) = self.nodes[k].children {
                self.nodes[k].sphere = self.nodes[l].sphere.merge(&self.nodes[r].sphere);
            }
        }
    }

    /// [`Bvh::build`] then [`Bvh::self_contacts`], with the same result,
    /// but first a cheaper test on the leaves alone: when no two segments
    /// at least the gap apart have overlapping spheres (the tree search's
    /// own leaf test) and centre lines closer than 2r, the tree search
    /// would find nothing, so the merged spheres are not refitted and the
    /// tree is not searched. The test is a sweep along the axis of largest
    /// extent of the segments' midpoints over the leaves' intervals, sorted
    /// by insertion from the last step's order (nearly sorted, so O(N) for
    /// a rope that moves little per step). When it finds a contact, the
    /// tree search runs as before and gives the contacts in its order.
    pub fn find_contacts(
        &mut self,
        x: &[V3],
        radius_m: f64,
        index_gap: usize,
        out: &mut Vec<Contact>,
    ) {
        if self.needs_lay_out(x) {
            self.lay_out(x, radius_m);
        } else {
            self.fit_leaves(x, radius_m);
            if !self.leaves_may_touch(x, 2.0 * radius_m, index_gap.max(2)) {
                return;
            }
            self.fit_inner();
        }
        self.self_contacts(x, radius_m, index_gap, out);
    }

    /// Whether two leaves `gap` or more apart along the chain pass the
    /// tree search's leaf tests (spheres overlap, centre lines closer than
    /// `reach_m`). An interval is widened by 1 nm plus 1e-9 of its
    /// coordinate so that no pair the sphere test accepts is lost to
    /// rounding in the sweep.
    fn leaves_may_touch(&mut self, x: &[V3], reach_m: f64, gap: usize) -> bool {
        let n = self.leaves;
        let leaves = &self.nodes[..n];
        let (mut lo, mut hi) = (leaves[0].sphere.centre, leaves[0].sphere.centre);
        for node in leaves {
            let c = &node.sphere.centre;
            (lo.x, hi.x) = (
                if c.x < lo.x { c.x } else { lo.x },
                if c.x > hi.x { c.x } else { hi.x },
            );
            (lo.y, hi.y) = (
                if c.y < lo.y { c.y } else { lo.y },
                if c.y > hi.y { c.y } else { hi.y },
            );
            (lo.z, hi.z) = (
                if c.z < lo.z { c.z } else { lo.z },
                if c.z > hi.z { c.z } else { hi.z },
            );
        }
        let extent = hi - lo;
        let axis = if extent.x >= extent.y && extent.x >= extent.z {
            0
        } else if extent.y >= extent.z {
            1
        } else {
            2
        };
        if self.sweep.len() != n {
            self.sweep.clear();
            self.sweep.extend((0..n).map(|segment| Interval {
                low: 0.0,
                high: 0.0,
                segment,
            }));
        }
        for iv in self.sweep.iter_mut() {
            let sphere = &leaves[iv.segment].sphere;
            let c = match axis {
                0 => sphere.centre.x,
                1 => sphere.centre.y,
                _ => sphere.centre.z,
            };
            let half = sphere.radius + 1e-9 * (1.0 + c.abs() + sphere.radius);
            (iv.low, iv.high) = (c - half, c + half);
        }
        let sweep = &mut self.sweep[..];
        for a in 1..n {
            if sweep[a - 1].low <= sweep[a].low {
                continue; // already in place (the common case)
            }
            let iv = sweep[a];
            let mut b = a;
            while b > 0 && sweep[b - 1].low > iv.low {
                sweep[b] = sweep[b - 1];
                b -= 1;
            }
            sweep[b] = iv;
        }
        for (a, iv) in sweep.iter().enumerate() {
            for other in &sweep[a + 1..] {
                if other.low > iv.high {
                    break;
                }
                let (i, j) = (iv.segment.min(other.segment), iv.segment.max(other.segment));
                if j >= i + gap
                    && leaves[i].sphere.overlaps(&leaves[j].sphere)
                    && segment_contact(x, i, j, reach_m).is_some()
                {
                    return true;
                }
            }
        }
        false
    }

    /// Builds the tree from scratch (shape and spheres).
    fn lay_out(&mut self, x: &[V3], radius_m: f64) {
        self.nodes.clear();
        self.level.clear();
        for i in 0..x.len().saturating_sub(1) {
            self.nodes.push(Node {
                sphere: leaf_sphere(x, i, radius_m),
                children: None,
                segment: i,
                first: i,
                last: i,
            });
            self.level.push(i);
        }
        while self.level.len() > 1 {
            self.next.clear();
            for pair in self.level.chunks(2) {
                if let [l, r] = *pair {
                    let sphere = self.nodes[l].sphere.merge(&self.nodes[r].sphere);
                    self.nodes.push(Node {
                        sphere,
                        children: Some((l, r)),
                        segment: usize::MAX,
                        first: self.nodes[l].first,
                        last: self.nodes[r].last,
                    });
                    self.next.push(self.nodes.len() - 1);
                } else {
                    self.next.push(pair[0]);
                }
            }
            std::mem::swap(&mut self.level, &mut self.next);
        }
        self.root = self.level.first().copied();
        self.leaves = x.len().saturating_sub(1);
    }

    /// Whether some segment under `ia` and some other under `ib` are at
    /// least `gap` apart along the chain. Two distinct nodes met in the
    /// search cover disjoint runs, so the farthest pair spans from the
    /// earlier run's first segment to the later run's last.
    fn reaches(&self, ia: usize, ib: usize, gap: usize) -> bool {
        let (a, b) = (&self.nodes[ia], &self.nodes[ib]);
        let span = if a.first <= b.first {
            b.last - a.first
        } else {
            a.last - b.first
        };
        span >= gap
    }

    /// Pushes the pair (ia, ib) unless every segment pair under it is
    /// excluded by the index gap (then it holds no contact).
    fn push_pair(&mut self, ia: usize, ib: usize, gap: usize) {
        if self.reaches(ia, ib, gap) {
            self.stack.push((ia, ib));
        }
    }

    /// Every pair of segments at least `index_gap` apart along the chain
    /// (j ≥ i + index_gap; see [`contact_index_gap`]) whose centre lines are
    /// closer than `2·radius_m`, found by exploring two copies of the tree
    /// from the top down (L1330). A pair of nodes all of whose segment
    /// pairs lie within the gap is not explored (it cannot hold a contact);
    /// the contacts are appended to `out` in the order of the full search.
    /// The tree must have been fitted to `x` by [`Bvh::build`] (after
    /// [`Bvh::find_contacts`] its merged spheres may be stale).
    pub fn self_contacts(
        &mut self,
        x: &[V3],
        radius_m: f64,
        index_gap: usize,
        out: &mut Vec<Contact>,
    ) {
        let Some(root) = self.root else {
            return;
        };
        let gap = index_gap.max(2);
        self.stack.clear();
        self.push_pair(root, root, gap);
        let reach = 2.0 * radius_m;
        while let Some((ia, ib)) = self.stack.pop() {
            let (na, nb) = (self.nodes[ia], self.nodes[ib]);
            if ia == ib {
                if let Some((l, r)) = na.children {
                    self.push_pair(l, l, gap);
                    self.push_pair(l, r, gap);
                    self.push_pair(r, r, gap);
                }
                continue;
            }
            if !na.sphere.overlaps(&nb.sphere) {
                continue;
            }
            match (na.children, nb.children) {
                (None, None) => {
                    let (i, j) = (na.segment.min(nb.segment), na.segment.max(nb.segment));
                    // No segment collides with itself, its immediate
                    // neighbours (L1333), or segments within reach along
                    // the chain (`contact_index_gap`).
                    if j < i + gap {
                        continue;
                    }
                    if let Some(c) = segment_contact(x, i, j, reach) {
                        out.push(c);
                    }
                }
                (Some((l, r)), None) => {
                    self.push_pair(l, ib, gap);
                    self.push_pair(r, ib, gap);
                }
                (None, Some((l, r))) => {
                    self.push_pair(ia, l, gap);
                    self.push_pair(ia, r, gap);
                }
                (Some((al, ar)), Some((bl, br))) => {
                    if na.sphere.radius >= nb.sphere.radius {
                        self.push_pair(al, ib, gap);
                        self.push_pair(ar, ib, gap);
                    } else {
                        self.push_pair(ia, bl, gap);
                        self.push_pair(ia, br, gap);
                    }
                }
            }
        }
    }
}

/// The contact of segments i and j (points i, i+1 and j, j+1) if their
/// centre lines are closer than `reach_m`.
fn segment_contact(x: &[V3], i: usize, j: usize, reach_m: f64) -> Option<Contact> {
    let (a, b, ca, cb) = closest_points(x[i], x[i + 1], x[j], x[j + 1]);
    let d = ca - cb;
    let s = d.norm();
    if s < reach_m {
        let normal = if s > 1e-12 {
            d / s
        } else {
            // Centre lines touch: any direction normal to segment a
            // separates them.
            any_normal(x[i + 1] - x[i])
        };
        Some(Contact {
            seg_a: i,
            seg_b: j,
            a,
            b,
            distance_m: s,
            normal,
        })
    } else {
        None
    }
}

/// A unit vector normal to `d`.
fn any_normal(d: V3) -> V3 {
    let t = if d.x.abs() < 0.9 { V3::x() } else { V3::y() };
    let n = d.cross(&t);
    let len = n.norm();
    if len > 0.0 {
        n / len
    } else {
        V3::z()
    }
}

/// Closest points of segments p0p1 and q0q1: fractions (a, b) and the points.
pub fn closest_points(p0: V3, p1: V3, q0: V3, q1: V3) -> (f64, f64, V3, V3) {
    let d1 = p1 - p0;
    let d2 = q1 - q0;
    let r = p0 - q0;
    let a = d1.norm_squared();
    let e = d2.norm_squared();
    let f = d2.dot(&r);
    let (s, t);
    if a <= 1e-300 && e <= 1e-300 {
        return (0.0, 0.0, p0, q0);
    }
    if a <= 1e-300 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(&r);
        if e <= 1e-300 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let mut s0 = if denom > 1e-14 * a * e {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t0 = 0.0;
                s0 = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t0 = 1.0;
                s0 = ((b - c) / a).clamp(0.0, 1.0);
            }
            s = s0;
            t = t0;
        }
    }
    (s, t, p0 + d1 * s, q0 + d2 * t)
}

/// Inverse masses and the weights of one contact's four points
/// (A, B of segment a; C, D of segment b).
pub(crate) struct ContactPoints {
    pub idx: [usize; 4],
    /// Barycentric weights with the side's sign: +(1−a), +a, −(1−b), −b.
    pub w: [f64; 4],
    /// Σ w_k² · inverse mass_k (the "W" of the generalised Eq. 19).
    pub denom: f64,
}

impl ContactPoints {
    pub fn new(c: &Contact, inv_mass: &[f64]) -> Self {
        let idx = [c.seg_a, c.seg_a + 1, c.seg_b, c.seg_b + 1];
        let w = [1.0 - c.a, c.a, -(1.0 - c.b), -c.b];
        let denom = (0..4).map(|k| w[k] * w[k] * inv_mass[idx[k]]).sum();
        Self { idx, w, denom }
    }

    /// Relative velocity v_C − v_E (L1214: linear interpolation).
    pub fn relative(&self, v: &[V3]) -> V3 {
        (0..4).map(|k| v[self.idx[k]] * self.w[k]).sum()
    }

    /// Applies a change `delta` of the relative quantity (velocity or
    /// position of C relative to E) by distributing it to the four points
    /// in proportion to weight × inverse mass; returns false when every
    /// point is pinned.
    pub fn apply(&self, target: &mut [V3], inv_mass: &[f64], delta: V3) -> bool {
        if self.denom <= 0.0 {
            return false;
        }
        let j = delta / self.denom;
        for k in 0..4 {
            target[self.idx[k]] += j * (self.w[k] * inv_mass[self.idx[k]]);
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_points_of_crossing_segments() {
        let (a, b, ca, cb) = closest_points(
            V3::new(-1.0, 0.0, 0.0),
            V3::new(1.0, 0.0, 0.0),
            V3::new(0.5, -1.0, 0.3),
            V3::new(0.5, 1.0, 0.3),
        );
        assert!((a - 0.75).abs() < 1e-12 && (b - 0.5).abs() < 1e-12);
        assert!((ca - cb).norm() - 0.3 < 1e-12);
    }

    /// Points along a closed-form curve f(t), t = 0, dt, 2dt, …
    fn curve(n: usize, dt: f64, f: impl Fn(f64) -> V3) -> Vec<V3> {
        (0..n).map(|k| f(k as f64 * dt)).collect()
    }

    /// A random walk of `n` points with steps of length about `step_m`,
    /// turning sharply (a crumpled ball with many self-contacts), from a
    /// fixed-seed linear congruential generator.
    fn random_walk(n: usize, step_m: f64, seed: u64) -> Vec<V3> {
        let mut state = seed;
        let mut uniform = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        let mut p = V3::zeros();
        let mut x = vec![p];
        for _ in 1..n {
            let d = V3::new(uniform(), uniform(), uniform());
            p += d.normalize() * step_m * (0.5 + 0.5 * uniform().abs());
            x.push(p);
        }
        x
    }

    /// The test configurations: random crumpled walks, a tight helix
    /// (each turn touches the next), a trefoil knot with close crossings,
    /// a straight chain and a chain folded back on itself.
    fn configurations() -> Vec<(&'static str, Vec<V3>)> {
        vec![
            ("walk 60", random_walk(60, 0.1, 1)),
            ("walk 120", random_walk(120, 0.08, 7)),
            ("walk 33", random_walk(33, 0.05, 34)),
            (
                "helix",
                curve(90, 0.35, |t| {
                    V3::new(0.2 * t.cos(), 0.2 * t.sin(), 0.012 * t)
                }),
            ),
            (
                "trefoil",
                curve(80, std::f64::consts::TAU / 79.0, |t| {
                    V3::new(
                        t.sin() + 2.0 * (2.0 * t).sin(),
                        t.cos() - 2.0 * (2.0 * t).cos(),
                        -(3.0 * t).sin(),
                    ) * 0.06
                }),
            ),
            ("straight", curve(51, 0.102, |t| V3::new(0.0, 0.0, -t))),
            ("end to end", end_to_end()),
            (
                "near miss",
                curve(50, 0.1, |t| {
                    if t < 2.45 {
                        V3::new(0.0, t, 0.0)
                    } else {
                        V3::new(0.0, 4.9 - t, 0.101)
                    }
                }),
            ),
            (
                "one touch",
                curve(50, 0.1, |t| {
                    let z = if (t - 4.0).abs() < 0.01 { 0.099 } else { 0.12 };
                    if t < 2.45 {
                        V3::new(t, 0.0, 0.0)
                    } else {
                        V3::new(4.9 - t, 0.0, z)
                    }
                }),
            ),
            (
                "folded",
                curve(50, 0.1, |t| {
                    if t < 2.45 {
                        V3::new(t, 0.0, 0.0)
                    } else {
                        V3::new(4.9 - t, 0.07, 0.0)
                    }
                }),
            ),
        ]
    }

    /// A chain along x to (2, 0, 0), a detour up, over and down, and back
    /// along x to (2.09, 0, 0): its only contacts are its last segment
    /// meeting the first run's end nearly end to end along the sweep's
    /// axis, where the leaves' intervals overlap least.
    fn end_to_end() -> Vec<V3> {
        let mut x: Vec<V3> = (0..=20)
            .map(|k| V3::new(0.1 * k as f64, 0.0, 0.0))
            .collect();
        x.extend((1..=5).map(|k| V3::new(2.0, 0.0, 0.1 * k as f64)));
        x.extend((1..=5).map(|k| V3::new(2.0 + 0.1 * k as f64, 0.0, 0.5)));
        x.extend((1..=5).map(|k| V3::new(2.5, 0.0, 0.5 - 0.1 * k as f64)));
        x.extend((1..=4).map(|k| V3::new(2.5 - 0.1025 * k as f64, 0.0, 0.0)));
        x
    }

    /// All pairs i < j with j ≥ i + max(gap, 2) closer than 2r, by
    /// enumeration (no tree), in (i, j) order.
    fn brute_force(x: &[V3], r: f64, gap: usize) -> Vec<(usize, usize)> {
        let mut want = Vec::new();
        for i in 0..x.len() - 1 {
            for j in i + gap.max(2)..x.len() - 1 {
                let (_, _, ca, cb) = closest_points(x[i], x[i + 1], x[j], x[j + 1]);
                if (ca - cb).norm() < 2.0 * r {
                    want.push((i, j));
                }
            }
        }
        want
    }

    /// The search without the index-gap pruning (every pair of nodes is
    /// explored as before issue 34), written recursively in the order the
    /// stack search pops: for a node with itself (r, r), (l, r), (l, l);
    /// for a split, the right child first.
    fn unpruned(
        bvh: &Bvh,
        x: &[V3],
        r: f64,
        gap: usize,
        ia: usize,
        ib: usize,
        out: &mut Vec<Contact>,
    ) {
        let (na, nb) = (bvh.nodes[ia], bvh.nodes[ib]);
        if ia == ib {
            if let Some((cl, cr)) = na.children {
                unpruned(bvh, x, r, gap, cr, cr, out);
                unpruned(bvh, x, r, gap, cl, cr, out);
                unpruned(bvh, x, r, gap, cl, cl, out);
            }
            return;
        }
        if !na.sphere.overlaps(&nb.sphere) {
            return;
        }
        match (na.children, nb.children) {
            (None, None) => {
                let (i, j) = (na.segment.min(nb.segment), na.segment.max(nb.segment));
                if j >= i + gap.max(2) {
                    out.extend(segment_contact(x, i, j, 2.0 * r));
                }
            }
            (Some((al, ar)), _)
                if nb.children.is_none() || na.sphere.radius >= nb.sphere.radius =>
            {
                unpruned(bvh, x, r, gap, ar, ib, out);
                unpruned(bvh, x, r, gap, al, ib, out);
            }
            (_, Some((bl, br))) => {
                unpruned(bvh, x, r, gap, ia, br, out);
                unpruned(bvh, x, r, gap, ia, bl, out);
            }
            (Some(_), None) => unreachable!("handled by the guard above"),
        }
    }

    #[test]
    fn pruned_search_finds_the_brute_force_pairs_in_the_unpruned_order() {
        let r = 0.05;
        let mut many = 0;
        // One tree refitted through every configuration of a length, as
        // the rope uses it; its spheres must equal a fresh build's.
        let mut bvh = Bvh::default();
        let mut swept = Bvh::default();
        let (mut none, mut some) = (0, 0);
        for (name, x) in configurations() {
            let mut fresh = Bvh::default();
            fresh.build(&x, r);
            bvh.build(&x.iter().map(|p| p * 1.5).collect::<Vec<_>>(), r);
            bvh.build(&x, r);
            for (a, b) in bvh.nodes.iter().zip(&fresh.nodes) {
                let same = a.sphere.centre == b.sphere.centre && a.sphere.radius == b.sphere.radius;
                assert!(same && a.children == b.children, "{name}: refit differs");
            }
            for gap in [2, 3, 5] {
                let mut got = Vec::new();
                bvh.self_contacts(&x, r, gap, &mut got);
                let mut pairs: Vec<_> = got.iter().map(|c| (c.seg_a, c.seg_b)).collect();
                pairs.sort_unstable();
                assert_eq!(pairs, brute_force(&x, r, gap), "{name}, gap {gap}");
                let mut order = Vec::new();
                let root = bvh.root.unwrap();
                unpruned(&bvh, &x, r, gap, root, root, &mut order);
                assert_eq!(got, order, "{name}, gap {gap}: order");
                let mut found = Vec::new();
                swept.find_contacts(&x, r, gap, &mut found);
                assert_eq!(found, got, "{name}, gap {gap}: find_contacts");
                many = many.max(got.len());
                if got.is_empty() {
                    none += 1;
                } else {
                    some += 1;
                }
            }
        }
        assert!(many > 100, "no configuration with many contacts: {many}");
        assert!(
            none >= 5 && some >= 15,
            "{none} searches without contact, {some} with"
        );
    }

    #[test]
    fn bvh_finds_exactly_the_brute_force_pairs() {
        // A crumpled chain: compare the tree's pairs with all pairs.
        let mut x = Vec::new();
        let mut p = V3::zeros();
        for i in 0..57 {
            let t = i as f64;
            p += V3::new((0.7 * t).cos(), (1.3 * t).sin(), (0.37 * t).cos()) * 0.1;
            x.push(p);
        }
        let r = 0.05;
        let mut bvh = Bvh::default();
        bvh.build(&x, r);
        let mut got = Vec::new();
        bvh.self_contacts(&x, r, 2, &mut got);
        let mut got: Vec<(usize, usize)> = got.iter().map(|c| (c.seg_a, c.seg_b)).collect();
        got.sort_unstable();
        let mut want = Vec::new();
        for i in 0..x.len() - 1 {
            for j in i + 2..x.len() - 1 {
                let (_, _, ca, cb) = closest_points(x[i], x[i + 1], x[j], x[j + 1]);
                if (ca - cb).norm() < 2.0 * r {
                    want.push((i, j));
                }
            }
        }
        assert!(want.len() > 5, "test chain too loose: {}", want.len());
        assert_eq!(got, want);
    }
}
