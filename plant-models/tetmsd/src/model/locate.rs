//! Which tetrahedron holds a point: the seed's sub-volume test (Yamaguchi
//! Eq. 3, seed 000 L2608–2618).
//!
//! Eq. 3 gives the volume of a tetrahedron OABC from its edge vectors
//! `OA = a`, `OB = b`, `OC = c` as
//! `V = |a1b2c3 + a2b3c1 + a3b1c2 − a1b3c2 − a3b2c1 − a2b1c3| / 6`.
//! A stylus point `P` cuts the tetrahedron into four (P replacing each
//! vertex in turn); P is inside when the four volumes add up to the
//! tetrahedron's. In floating point the sum is compared with a relative
//! tolerance [`EQ3_REL_TOL`]: a point outside by a barycentric amount `λ`
//! makes the sum exceed `V` by `2|λ|V`, so the tolerance admits points
//! within `EQ3_REL_TOL / 2` (in barycentric terms) outside a face.
//!
//! Left out: a spatial index. [`locate`] scans the tetrahedra (after an
//! axis-aligned box test), which at the seed's largest mesh (3,072
//! tetrahedra) costs tens of microseconds and only runs while a probe is
//! near the object and not yet in contact.
use super::{c3, V3};

/// Relative tolerance of the Eq. 3 volume comparison: far above the
/// rounding of five 3×3 determinants (≈ 1e-15 relative) and far below any
/// distance that matters for a stylus (1e-12 of a tetrahedron's size).
pub const EQ3_REL_TOL: f64 = 1e-12;

/// Eq. 3: the volume of tetrahedron OABC from the components of
/// `a = A − O`, `b = B − O`, `c = C − O`, exactly as printed.
pub fn volume_eq3(o: V3, a: V3, b: V3, c: V3) -> f64 {
    let (o, a, b, c) = (c3(&o), c3(&a), c3(&b), c3(&c));
    let (a1, a2, a3) = (a[0] - o[0], a[1] - o[1], a[2] - o[2]);
    let (b1, b2, b3) = (b[0] - o[0], b[1] - o[1], b[2] - o[2]);
    let (c1, c2, c3) = (c[0] - o[0], c[1] - o[1], c[2] - o[2]);
    (a1 * b2 * c3 + a2 * b3 * c1 + a3 * b1 * c2 - a1 * b3 * c2 - a3 * b2 * c1 - a2 * b1 * c3).abs()
        / 6.0
}

/// The four sub-volumes of Fig. 5: `p` in place of each vertex in turn.
pub fn sub_volumes(t: &[V3; 4], p: V3) -> [f64; 4] {
    [
        volume_eq3(p, t[1], t[2], t[3]),
        volume_eq3(t[0], p, t[2], t[3]),
        volume_eq3(t[0], t[1], p, t[3]),
        volume_eq3(t[0], t[1], t[2], p),
    ]
}

/// Eq. 3's collision test: whether `p` lies in tetrahedron `t` (faces,
/// edges and vertices included). A degenerate (flat) tetrahedron holds
/// nothing.
pub fn contains_eq3(t: &[V3; 4], p: V3) -> bool {
    let v = volume_eq3(t[0], t[1], t[2], t[3]);
    // A flat (or NaN) tetrahedron holds nothing.
    if v.is_nan() || v <= 0.0 {
        return false;
    }
    let s: f64 = sub_volumes(t, p).iter().sum();
    s <= v * (1.0 + EQ3_REL_TOL)
}

/// The first tetrahedron (lowest index) of `tets` over `positions` that
/// holds `p` by Eq. 3, or `None`. On a shared face both neighbours hold
/// the point; the lower index is the deterministic choice.
pub fn locate(positions: &[V3], tets: &[[u32; 4]], p: V3) -> Option<usize> {
    tets.iter().position(|tet| {
        let t = tet.map(|i| positions[i as usize]);
        let (q, pc) = (t.map(|v| c3(&v)), c3(&p));
        let inside_box = (0..3).all(|a| {
            let lo = q[0][a].min(q[1][a]).min(q[2][a].min(q[3][a]));
            let hi = q[0][a].max(q[1][a]).max(q[2][a].max(q[3][a]));
            let pad = (hi - lo) * EQ3_REL_TOL;
            pc[a] >= lo - pad && pc[a] <= hi + pad
        });
        inside_box && contains_eq3(&t, p)
    })
}

#[cfg(test)]
mod tests {
    //! Eq. 3 against an independent barycentric sign test (face
    //! orientations from cross and dot products, not the Eq. 3 expansion).
    use super::*;
    use crate::model::mesh::CubeMesh;
    use plant_common::rng;
    use rand::{Rng, RngCore};

    /// Orientation of `d` against the plane `a b c`: `(b−a)×(c−a)·(d−a)`.
    fn orient(a: V3, b: V3, c: V3, d: V3) -> f64 {
        let (a, b, c, d) = (c3(&a), c3(&b), c3(&c), c3(&d));
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        let w = [d[0] - a[0], d[1] - a[1], d[2] - a[2]];
        (u[1] * v[2] - u[2] * v[1]) * w[0]
            + (u[2] * v[0] - u[0] * v[2]) * w[1]
            + (u[0] * v[1] - u[1] * v[0]) * w[2]
    }

    /// The orientation of the tetrahedron and of the four with `p` in
    /// place of each vertex.
    fn orientations(t: &[V3; 4], p: V3) -> (f64, [f64; 4]) {
        (
            orient(t[0], t[1], t[2], t[3]),
            [
                orient(p, t[1], t[2], t[3]),
                orient(t[0], p, t[2], t[3]),
                orient(t[0], t[1], p, t[3]),
                orient(t[0], t[1], t[2], p),
            ],
        )
    }

    /// Barycentric coordinates by the sign test's orientations.
    fn barycentric(t: &[V3; 4], p: V3) -> [f64; 4] {
        let (whole, o) = orientations(t, p);
        o.map(|v| v / whole)
    }

    /// Sign test: inside or on the boundary iff no sub-orientation has the
    /// opposite sign of the whole (exact when the orientations are).
    fn sign_test(t: &[V3; 4], p: V3) -> bool {
        let (whole, o) = orientations(t, p);
        o.iter().all(|v| *v * whole.signum() >= 0.0)
    }

    /// A random index order of the four vertices.
    fn shuffled<R: Rng>(r: &mut R) -> [usize; 4] {
        let mut idx = [0usize, 1, 2, 3];
        for i in (1..4).rev() {
            idx.swap(i, r.gen_range(0..=i));
        }
        idx
    }

    /// Random real-valued point by kind: 0 anywhere in a box 1.5 times the
    /// tetrahedron's, 1 on a face, 2 on an edge, 3 at a vertex, 4 inside.
    fn sample<R: Rng>(r: &mut R, t: &[V3; 4], kind: u32) -> V3 {
        let used = match kind {
            1 => 3,
            2 => 2,
            3 => 1,
            4 => 4,
            _ => {
                let lo = t.iter().fold(V3::repeat(f64::INFINITY), |m, q| m.inf(q));
                let hi = t
                    .iter()
                    .fold(V3::repeat(f64::NEG_INFINITY), |m, q| m.sup(q));
                let span = hi - lo;
                let u = V3::new(r.gen(), r.gen(), r.gen());
                return lo - span * 0.25 + span.component_mul(&u) * 1.5;
            }
        };
        let idx = shuffled(r);
        let mut w = [0.0; 4];
        for &k in &idx[..used] {
            w[k] = r.gen::<f64>();
        }
        let s: f64 = w.iter().sum();
        if s == 0.0 {
            return t[idx[0]];
        }
        (0..4).fold(V3::zeros(), |p, k| p + t[k] * (w[k] / s))
    }

    #[test]
    fn eq3_agrees_with_the_sign_test_on_a_million_exact_points() {
        // Integer vertices in [−64, 64] and points whose coordinates are
        // multiples of 1/32 (face, edge and vertex points built from
        // weights that sum to a power of two): every determinant is exact
        // in f64, so points *on* faces and vertices are exactly on them and
        // the two tests must agree on every point, with no tolerance band.
        let mut r = rng::stream(0x5EED, rng::TETMSD_TEST_BASE);
        let (mut inside, mut boundary, mut outside) = (0u32, 0u32, 0u32);
        let mut points = 0u32;
        while points < 1_000_000 {
            let t: [V3; 4] = std::array::from_fn(|_| {
                V3::new(
                    f64::from(r.gen_range(-64..=64)),
                    f64::from(r.gen_range(-64..=64)),
                    f64::from(r.gen_range(-64..=64)),
                )
            });
            if orient(t[0], t[1], t[2], t[3]) == 0.0 {
                continue;
            }
            for _ in 0..100 {
                // One 64-bit draw per point (the ChaCha stream is slow in
                // unoptimised test builds): kind, vertex order and weights
                // from its bits.
                let mut bits = r.next_u64();
                let mut take = |n: u64| {
                    let v = bits % n;
                    bits /= n;
                    v
                };
                let kind = take(5);
                // Power-of-two weight totals keep the points dyadic.
                let q = t.map(|v| c3(&v));
                let p = if kind == 0 {
                    // Anywhere in the tetrahedron's box grown by a quarter
                    // of its size each way, on the 1/32 grid.
                    let mut p = [0.0; 3];
                    for (a, c) in p.iter_mut().enumerate() {
                        let lo = q.iter().map(|v| v[a]).fold(f64::INFINITY, f64::min);
                        let hi = q.iter().map(|v| v[a]).fold(f64::NEG_INFINITY, f64::max);
                        let span = (hi - lo) as u64;
                        *c = (32.0 * lo - 8.0 * span as f64 + take(48 * span + 1) as f64) / 32.0;
                    }
                    V3::from(p)
                } else {
                    let mut w = [0u64; 4];
                    let mut idx = [0usize, 1, 2, 3];
                    for i in (1..4).rev() {
                        idx.swap(i, take(i as u64 + 1) as usize);
                    }
                    let used = [3, 2, 1, 4][kind as usize - 1];
                    let mut left = 32u64;
                    for &j in &idx[..used - 1] {
                        w[j] = take(left + 1);
                        left -= w[j];
                    }
                    w[idx[used - 1]] = left;
                    let mut p = [0.0; 3];
                    for (v, wj) in q.iter().zip(w) {
                        for a in 0..3 {
                            p[a] += v[a] * (wj as f64 / 32.0);
                        }
                    }
                    V3::from(p)
                };
                let eq3 = contains_eq3(&t, p);
                let (whole, o) = orientations(&t, p);
                let sign = o.iter().all(|v| *v * whole.signum() >= 0.0);
                assert_eq!(eq3, sign, "tet {t:?} point {p:?}");
                if o.contains(&0.0) && sign {
                    boundary += 1;
                } else if sign {
                    inside += 1;
                } else {
                    outside += 1;
                }
                points += 1;
            }
        }
        // The sample covers all three cases in earnest.
        assert!(boundary > 300_000 && inside > 100_000 && outside > 100_000);
    }

    #[test]
    fn eq3_agrees_with_the_sign_test_on_continuous_points_outside_a_thin_band() {
        // Real-valued vertices and points: rounding makes "on the face"
        // approximate, so both tests carry a tolerance; they must agree on
        // every point whose nearest barycentric coordinate is further than
        // 1e-9 from zero, and on face, edge and vertex points built from
        // the vertices (within rounding of the face).
        let mut r = rng::stream(0x5EED, rng::TETMSD_TEST_BASE + 1);
        let mut band = 0u32;
        for _ in 0..1_000 {
            let t: [V3; 4] = std::array::from_fn(|_| {
                V3::new(
                    r.gen_range(-1.0..1.0),
                    r.gen_range(-1.0..1.0),
                    r.gen_range(-1.0..1.0),
                )
            });
            if orient(t[0], t[1], t[2], t[3]).abs() < 1e-3 {
                continue;
            }
            for _ in 0..100 {
                let kind = r.gen_range(0..5);
                let p = sample(&mut r, &t, kind);
                let lambda = barycentric(&t, p);
                let near = lambda.iter().map(|l| l.abs()).fold(f64::INFINITY, f64::min);
                let tolerant_sign = lambda.iter().all(|l| *l >= -EQ3_REL_TOL / 2.0);
                let eq3 = contains_eq3(&t, p);
                if kind >= 1 {
                    assert!(eq3 && tolerant_sign, "kind {kind}: {lambda:?}");
                } else if near > 1e-9 {
                    assert_eq!(eq3, tolerant_sign, "{lambda:?}");
                } else {
                    band += 1;
                }
            }
        }
        assert!(band < 5, "{band} random points in the 1e-9 band");
    }

    #[test]
    fn locate_finds_the_tetrahedron_and_nothing_outside() {
        let m = CubeMesh::new(5, 1.0).unwrap();
        let mut r = rng::stream(1, rng::TETMSD_TEST_BASE + 2);
        for _ in 0..2000 {
            let p = V3::new(
                r.gen_range(-0.2..1.2),
                r.gen_range(-0.2..1.2),
                r.gen_range(-0.2..1.2),
            );
            let inside_cube = p.iter().all(|c| (0.0..=1.0).contains(c));
            match locate(&m.nodes_m, &m.tets, p) {
                Some(t) => {
                    assert!(inside_cube, "{p:?} found in {t}");
                    assert!(sign_test(&m.tet_points(t), p));
                    // No earlier tetrahedron holds it.
                    assert!((0..t).all(|u| !sign_test(&m.tet_points(u), p)));
                }
                None => assert!(!inside_cube, "{p:?} inside the cube but not found"),
            }
        }
        // A node belongs to the first tetrahedron that uses it.
        let n = 17;
        let first = m.tets.iter().position(|t| t.contains(&(n as u32))).unwrap();
        assert_eq!(locate(&m.nodes_m, &m.tets, m.nodes_m[n]), Some(first));
        let flat = [V3::zeros(), V3::x(), V3::y(), V3::x() + V3::y()];
        assert!(!contains_eq3(&flat, V3::zeros()));
    }
}
