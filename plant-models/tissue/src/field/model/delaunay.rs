//! Delaunay tetrahedralisation of the matched feature points (Zhang
//! §III-A, L479–519).
//!
//! The paper grows its tetrahedra from a first triangle, adding for each
//! front triangle the point whose circumsphere is empty and closest
//! (gift wrapping). We build the same Delaunay tetrahedralisation (it is
//! unique for points in general position) by Bowyer–Watson insertion:
//! each point removes the tetrahedra whose circumsphere strictly contains
//! it and fills the cavity with tetrahedra to the cavity's boundary faces.
//! Points are located by a visibility walk from the last new tetrahedron,
//! in an order sorted along a Morton curve, so insertion is about
//! O(n log n) rather than the wrapping's O(n²).
//!
//! Robustness: the orientation and in-sphere tests are Shewchuk's adaptive
//! exact predicates (the `robust` crate). Feature points sit near a voxel
//! lattice, where five points on one sphere are common; a deterministic
//! jitter of 1e-6 of the point cloud's size (stream
//! `rng::TISSUE_DELAUNAY_JITTER`) breaks those ties for the triangulation,
//! while the tetrahedra keep the original points. Exactly repeated points
//! are inserted once (the later copies are reported).
//!
//! Left out: constrained faces, removal of slivers at the convex hull
//! (they carry the field there like any other tetrahedron).
use crate::error::{Result, TissueError};
use plant_common::rng;
use rand::Rng;
use robust::{insphere, orient3d, Coord3D};
use std::collections::HashMap;

const NONE: usize = usize::MAX;

fn c3(p: [f64; 3]) -> Coord3D<f64> {
    Coord3D {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

/// Sign of the volume of (a, b, c, d): > 0 when d lies on the side of the
/// plane (a, b, c) that the right-handed normal (b − a) × (c − a) points to.
fn orient(a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]) -> f64 {
    -orient3d(c3(a), c3(b), c3(c), c3(d))
}

#[derive(Clone, Copy, Debug)]
struct Tet {
    v: [usize; 4],
    /// Neighbour across the face opposite `v[i]`.
    n: [usize; 4],
    alive: bool,
}

/// The result: tetrahedra over the input points, positively oriented.
#[derive(Clone, Debug, PartialEq)]
pub struct Tetrahedralisation {
    /// Tetrahedra as indices into the input points.
    pub tets: Vec<[usize; 4]>,
    /// Input points that repeat an earlier one exactly (not inserted).
    pub duplicates: Vec<usize>,
}

struct Builder {
    pts: Vec<[f64; 3]>,
    tets: Vec<Tet>,
    free: Vec<usize>,
    last: usize,
}

impl Builder {
    fn face(&self, t: usize, i: usize) -> [usize; 3] {
        let v = self.tets[t].v;
        // Faces ordered so that the opposite vertex is on the positive side
        // for a positively oriented tetrahedron.
        match i {
            0 => [v[1], v[3], v[2]],
            1 => [v[0], v[2], v[3]],
            2 => [v[0], v[3], v[1]],
            _ => [v[0], v[1], v[2]],
        }
    }

    fn in_sphere(&self, t: usize, p: [f64; 3]) -> bool {
        let v = self.tets[t].v.map(|i| self.pts[i]);
        let o = orient3d(c3(v[0]), c3(v[1]), c3(v[2]), c3(v[3]));
        insphere(c3(v[0]), c3(v[1]), c3(v[2]), c3(v[3]), c3(p)) * o > 0.0
    }

    fn add(&mut self, t: Tet) -> usize {
        if let Some(i) = self.free.pop() {
            self.tets[i] = t;
            i
        } else {
            self.tets.push(t);
            self.tets.len() - 1
        }
    }

    /// A live tetrahedron containing `p` (closed), by a visibility walk;
    /// falls back to a scan if the walk does not end.
    fn locate(&self, p: [f64; 3]) -> Option<usize> {
        let mut t = self.last;
        if !self.tets.get(t).is_some_and(|x| x.alive) {
            t = self.tets.iter().position(|x| x.alive)?;
        }
        let mut steps = 0;
        'walk: while steps < 4 * self.tets.len() + 16 {
            steps += 1;
            for i in 0..4 {
                let f = self.face(t, i).map(|k| self.pts[k]);
                if orient(f[0], f[1], f[2], p) < 0.0 {
                    let nb = self.tets[t].n[i];
                    if nb == NONE {
                        return None;
                    }
                    t = nb;
                    continue 'walk;
                }
            }
            return Some(t);
        }
        (0..self.tets.len()).find(|&t| {
            self.tets[t].alive
                && (0..4).all(|i| {
                    let f = self.face(t, i).map(|k| self.pts[k]);
                    orient(f[0], f[1], f[2], p) >= 0.0
                })
        })
    }

    fn insert(&mut self, pi: usize) -> Result<()> {
        let p = self.pts[pi];
        let start = self.locate(p).ok_or_else(|| {
            TissueError::Delaunay(format!("point {pi} lies outside the enclosing tetrahedron"))
        })?;
        // Cavity: tetrahedra whose circumsphere strictly contains p.
        let mut in_cavity: HashMap<usize, ()> = HashMap::new();
        let mut stack = vec![start];
        in_cavity.insert(start, ());
        let mut cavity = Vec::new();
        while let Some(t) = stack.pop() {
            cavity.push(t);
            for i in 0..4 {
                let nb = self.tets[t].n[i];
                if nb != NONE && !in_cavity.contains_key(&nb) && self.in_sphere(nb, p) {
                    in_cavity.insert(nb, ());
                    stack.push(nb);
                }
            }
        }
        // New tetrahedra on the cavity's boundary faces.
        let mut new_tets = Vec::new();
        let mut boundary = Vec::new();
        for &t in &cavity {
            for i in 0..4 {
                let nb = self.tets[t].n[i];
                if nb == NONE || !in_cavity.contains_key(&nb) {
                    boundary.push((self.face(t, i), nb, t));
                }
            }
        }
        for &t in &cavity {
            self.tets[t].alive = false;
        }
        let mut edge_owner: HashMap<(usize, usize), (usize, usize)> = HashMap::new();
        for (f, nb, old) in boundary {
            let fp = f.map(|k| self.pts[k]);
            if orient(fp[0], fp[1], fp[2], p) <= 0.0 {
                return Err(TissueError::Delaunay(format!(
                    "point {pi} is coplanar with a face of its cavity (degenerate input the jitter did not break)"
                )));
            }
            // Face f is oriented with the removed vertex on its positive
            // side, and p is on that side too: (f0, f1, f2, p) is positive.
            let t = self.add(Tet {
                v: [f[0], f[1], f[2], pi],
                n: [NONE, NONE, NONE, nb],
                alive: true,
            });
            if nb != NONE {
                let back = (0..4).find(|&j| self.tets[nb].n[j] == old);
                if let Some(j) = back {
                    self.tets[nb].n[j] = t;
                }
            }
            // Faces through p: opposite v[0], v[1], v[2]; each is the edge
            // of f not containing that vertex.
            for (i, (a, b)) in [(f[1], f[2]), (f[0], f[2]), (f[0], f[1])]
                .into_iter()
                .enumerate()
            {
                let key = (a.min(b), a.max(b));
                if let Some((other, oi)) = edge_owner.remove(&key) {
                    self.tets[t].n[i] = other;
                    self.tets[other].n[oi] = t;
                } else {
                    edge_owner.insert(key, (t, i));
                }
            }
            new_tets.push(t);
        }
        if let Some(&t) = new_tets.last() {
            self.last = t;
        }
        Ok(())
    }
}

/// Interleaves the bits of three 21-bit integers (Morton order).
fn morton(q: [u64; 3]) -> u64 {
    let spread = |mut x: u64| {
        x &= 0x1f_ffff;
        x = (x | x << 32) & 0x1f00000000ffff;
        x = (x | x << 16) & 0x1f0000ff0000ff;
        x = (x | x << 8) & 0x100f00f00f00f00f;
        x = (x | x << 4) & 0x10c30c30c30c30c3;
        x = (x | x << 2) & 0x1249249249249249;
        x
    };
    spread(q[0]) | spread(q[1]) << 1 | spread(q[2]) << 2
}

/// The Delaunay tetrahedralisation of `points` (mm). Needs four points
/// that are not coplanar.
pub fn tetrahedralise(points: &[[f64; 3]], seed: u64) -> Result<Tetrahedralisation> {
    if points.len() < 4 {
        return Err(TissueError::TooFew {
            stage: "Delaunay tetrahedralisation",
            what: "points",
            got: points.len(),
            needed: 4,
        });
    }
    if let Some(i) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(TissueError::Delaunay(format!(
            "point {i} has a non-finite coordinate"
        )));
    }
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let size = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max).max(1e-9);
    let centre: [f64; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    let mut r = rng::stream(seed, rng::TISSUE_DELAUNAY_JITTER);
    let jitter = 1e-6 * size;
    let mut pts: Vec<[f64; 3]> = points
        .iter()
        .map(|p| p.map(|c| c + jitter * (2.0 * r.gen::<f64>() - 1.0)))
        .collect();
    // A super-tetrahedron far outside.
    let big = 1e3 * size;
    let n = pts.len();
    pts.push([centre[0] - big, centre[1] - big, centre[2] - big]);
    pts.push([centre[0] + 3.0 * big, centre[1] - big, centre[2] - big]);
    pts.push([centre[0] - big, centre[1] + 3.0 * big, centre[2] - big]);
    pts.push([centre[0] - big, centre[1] - big, centre[2] + 3.0 * big]);
    let mut b = Builder {
        pts,
        tets: vec![Tet {
            v: [n, n + 1, n + 2, n + 3],
            n: [NONE; 4],
            alive: true,
        }],
        free: Vec::new(),
        last: 0,
    };
    let mut order: Vec<usize> = (0..n).collect();
    let key = |i: usize| {
        morton(std::array::from_fn(|a| {
            (((points[i][a] - lo[a]) / size) * 2_097_151.0).clamp(0.0, 2_097_151.0) as u64
        }))
    };
    order.sort_by_key(|&i| (key(i), i));
    let mut seen: HashMap<[u64; 3], usize> = HashMap::new();
    let mut duplicates = Vec::new();
    for i in order {
        let bits = points[i].map(f64::to_bits);
        if seen.insert(bits, i).is_some() {
            duplicates.push(i);
            continue;
        }
        b.insert(i)?;
    }
    duplicates.sort_unstable();
    let tets: Vec<[usize; 4]> = b
        .tets
        .iter()
        .filter(|t| t.alive && t.v.iter().all(|&v| v < n))
        .map(|t| t.v)
        .collect();
    if tets.is_empty() {
        return Err(TissueError::Delaunay(
            "all points lie in one plane: no tetrahedron has volume".into(),
        ));
    }
    Ok(Tetrahedralisation { tets, duplicates })
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant_common::fem::tet_volume;
    use rand::SeedableRng;

    fn check_delaunay(points: &[[f64; 3]], tets: &[[usize; 4]], tol: f64) {
        for t in tets {
            let v = t.map(|i| points[i]);
            assert!(tet_volume(v) > 0.0, "negative or flat tetrahedron {t:?}");
            let o = orient3d(c3(v[0]), c3(v[1]), c3(v[2]), c3(v[3]));
            for (k, p) in points.iter().enumerate() {
                if t.contains(&k) {
                    continue;
                }
                // No point strictly inside a circumsphere (beyond the jitter).
                let s = insphere(c3(v[0]), c3(v[1]), c3(v[2]), c3(v[3]), c3(*p)) * o;
                if s > 0.0 {
                    let c = circumcentre(v);
                    let r = dist(c, v[0]);
                    assert!(
                        dist(c, *p) > r - tol,
                        "point {k} inside the sphere of {t:?}"
                    );
                }
            }
        }
    }

    fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
        (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
    }

    fn circumcentre(v: [[f64; 3]; 4]) -> [f64; 3] {
        let a = nalgebra::Matrix3::from_fn(|r, c| 2.0 * (v[r + 1][c] - v[0][c]));
        let b = nalgebra::Vector3::from_fn(|r, _| {
            (0..3)
                .map(|k| v[r + 1][k].powi(2) - v[0][k].powi(2))
                .sum::<f64>()
        });
        let x = a.lu().solve(&b).unwrap();
        [x[0], x[1], x[2]]
    }

    #[test]
    fn random_points_give_an_empty_sphere_tetrahedralisation_of_the_hull() {
        // 150 random points plus the 8 corners of their box: the hull is
        // the box, so the tetrahedra must fill its volume exactly.
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut pts: Vec<[f64; 3]> = (0..150)
            .map(|_| {
                [
                    r.gen::<f64>() * 40.0,
                    r.gen::<f64>() * 30.0,
                    r.gen::<f64>() * 20.0,
                ]
            })
            .collect();
        for c in 0..8 {
            pts.push([
                40.0 * (c & 1) as f64,
                30.0 * ((c >> 1) & 1) as f64,
                20.0 * ((c >> 2) & 1) as f64,
            ]);
        }
        let t = tetrahedralise(&pts, 1).unwrap();
        check_delaunay(&pts, &t.tets, 1e-4);
        let vol: f64 = t.tets.iter().map(|t| tet_volume(t.map(|i| pts[i]))).sum();
        assert!(
            (vol - 40.0 * 30.0 * 20.0).abs() < 1e-6 * vol,
            "volume {vol}"
        );
    }

    #[test]
    fn a_lattice_of_cospherical_points_is_handled() {
        // 5 × 4 × 3 lattice: every cell's 8 corners share one sphere.
        let mut pts = Vec::new();
        for k in 0..3 {
            for j in 0..4 {
                for i in 0..5 {
                    pts.push([i as f64 * 2.0, j as f64 * 2.0, k as f64 * 1.0]);
                }
            }
        }
        pts.push(pts[7]); // an exact duplicate
        let t = tetrahedralise(&pts, 3).unwrap();
        assert_eq!(t.duplicates, vec![60]);
        let vol: f64 = t.tets.iter().map(|t| tet_volume(t.map(|i| pts[i]))).sum();
        // Original (unjittered) points: cells may hold flat tetrahedra, but
        // the volume is the box's.
        assert!((vol - 8.0 * 6.0 * 2.0).abs() < 1e-6, "volume {vol}");
        assert!(t
            .tets
            .iter()
            .all(|tt| tet_volume(tt.map(|i| pts[i])) > -1e-9));
    }

    #[test]
    fn too_few_or_coplanar_points_are_refused() {
        assert!(tetrahedralise(&[[0.0; 3]; 3], 1).is_err());
        let flat: Vec<[f64; 3]> = (0..10).map(|i| [i as f64, (i * i) as f64, 0.0]).collect();
        // Jitter lifts the points off the plane; the original tetrahedra
        // are then (near) flat: either refused or of negligible volume.
        match tetrahedralise(&flat, 1) {
            Err(e) => assert!(
                e.to_string().contains("Delaunay") || e.to_string().contains("plane"),
                "{e}"
            ),
            Ok(t) => {
                let vol: f64 = t
                    .tets
                    .iter()
                    .map(|t| tet_volume(t.map(|i| flat[i])).abs())
                    .sum();
                assert!(vol < 1e-9, "{vol}");
            }
        }
    }
}
