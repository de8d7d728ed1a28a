//! Tetrahedral meshes of a cube at refinement levels, by newest-vertex
//! bisection (Maubach's algorithm): the "binary tree of a set of tetrahedra
//! without any cracks" of the seed's adaptive volume model (Yamaguchi,
//! seed 000 L2627–2631, after Takama et al. [12]).
//!
//! What is modelled: level 0 is the cube cut into the six Kuhn tetrahedra
//! around its main diagonal (every one runs corner (0,0,0) → (1,1,1) along
//! the three axes in one of the six orders). Each level bisects *every*
//! tetrahedron once at its refinement edge, numbered as Maubach does: a
//! tetrahedron `(x0, x1, x2, x3)` with tag `k` splits at the midpoint `z`
//! of `x0–xk` into `(x0 … x(k−1), z, x(k+1) … x3)` and
//! `(x1 … xk, z, x(k+1) … x3)`, both with tag `k − 1` (3 after 1). Uniform
//! bisection of a Kuhn cube stays conforming (no hanging nodes, checked by
//! the tests: every inner face is shared by exactly two tetrahedra) and
//! every three levels reproduce the Kuhn pattern at half the size, so level
//! `3m` is the regular `(2^m + 1)³` grid with each cell cut into six Kuhn
//! tetrahedra: **level 3 has 27 nodes and level 9 has 729**, the seed's
//! 729-node level 9 (L2664). The seed's level 3 has 24 nodes; no conforming
//! bisection of a cube has 24 (levels 2, 3, 4 have 15, 27, 35), so the
//! difference is noted as a deviation. Every tetrahedron of level `L` has
//! volume side³ / (6·2^L).
//!
//! Left out: the seed's *adaptive* refinement during the run (edges split
//! by their expansion rate, L2633–2636); meshes here are uniform at a
//! chosen level. Non-cube input meshes (the seed's tooth).
use super::V3;
use crate::error::{check_positive, Result, TetError};
use std::collections::HashMap;

/// Finest level built (level 12: 4,913 nodes, 24,576 tetrahedra). The
/// packet carries node and tetrahedron numbers in 16 bits, so every mesh
/// here must stay below 65,535 of each.
pub const MAX_LEVEL: u32 = 12;

/// Coarsest level with interior nodes on every face (the seed's initial level).
pub const SEED_MIN_LEVEL: u32 = 3;
/// The seed's finest level (729 nodes).
pub const SEED_MAX_LEVEL: u32 = 9;

/// A cube `[0, side]³` cut into tetrahedra by uniform bisection.
#[derive(Clone, Debug)]
pub struct CubeMesh {
    /// Edge length of the cube (m).
    pub side_m: f64,
    /// Refinement level (bisections of every tetrahedron since level 0).
    pub level: u32,
    /// Rest positions of the nodes (m).
    pub nodes_m: Vec<V3>,
    /// Tetrahedra as node indices, positively oriented
    /// (`(x1−x0)·((x2−x0)×(x3−x0)) > 0`).
    pub tets: Vec<[u32; 4]>,
    /// Edges (`i < j`), sorted: the Voigt elements, six per tetrahedron
    /// and shared between neighbours.
    pub edges: Vec<[u32; 2]>,
    /// Boundary triangles, counter-clockwise seen from outside.
    pub boundary_faces: Vec<[u32; 3]>,
    /// Whether a node lies on the cube's surface.
    pub on_boundary: Vec<bool>,
}

/// A tetrahedron during bisection: vertices in Maubach order and its tag.
#[derive(Clone, Copy)]
struct Simplex {
    v: [u32; 4],
    tag: usize,
}

/// Signed volume of a tetrahedron (m³): `(b−a)·((c−a)×(d−a)) / 6`.
pub fn signed_volume_m3(a: V3, b: V3, c: V3, d: V3) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

impl CubeMesh {
    /// The cube of edge `side_m` at refinement `level` (0..=[`MAX_LEVEL`]).
    pub fn new(level: u32, side_m: f64) -> Result<Self> {
        if level > MAX_LEVEL {
            return Err(TetError::LevelOutOfRange {
                level,
                min: 0,
                max: MAX_LEVEL,
            });
        }
        check_positive("side_m", side_m)?;
        let mut nodes: Vec<V3> = (0..8)
            .map(|c| {
                V3::new(
                    f64::from(c & 1),
                    f64::from((c >> 1) & 1),
                    f64::from((c >> 2) & 1),
                ) * side_m
            })
            .collect();
        // The six Kuhn tetrahedra: corner 0 → +e_a → +e_b → +e_c = corner 7.
        let mut simplices: Vec<Simplex> = [
            [0, 1, 2],
            [0, 2, 1],
            [1, 0, 2],
            [1, 2, 0],
            [2, 0, 1],
            [2, 1, 0],
        ]
        .iter()
        .map(|order: &[u32; 3]| {
            let mut v = [0u32; 4];
            let mut corner = 0u32;
            for (i, axis) in order.iter().enumerate() {
                corner |= 1 << axis;
                v[i + 1] = corner;
            }
            Simplex { v, tag: 3 }
        })
        .collect();
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        for _ in 0..level {
            let mut next = Vec::with_capacity(2 * simplices.len());
            for s in &simplices {
                next.extend(bisect(s, &mut nodes, &mut midpoints));
            }
            simplices = next;
        }
        let tets: Vec<[u32; 4]> = simplices
            .iter()
            .map(|s| {
                let mut v = s.v;
                let p = v.map(|i| nodes[i as usize]);
                if signed_volume_m3(p[0], p[1], p[2], p[3]) < 0.0 {
                    v.swap(0, 1);
                }
                v
            })
            .collect();
        let mut edges: Vec<[u32; 2]> = tets
            .iter()
            .flat_map(|t| {
                [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
                    .map(|(a, b)| [t[a].min(t[b]), t[a].max(t[b])])
            })
            .collect();
        edges.sort_unstable();
        edges.dedup();
        let (boundary_faces, on_boundary) = boundary(&tets, &nodes);
        Ok(CubeMesh {
            side_m,
            level,
            nodes_m: nodes,
            tets,
            edges,
            boundary_faces,
            on_boundary,
        })
    }

    /// Number of nodes.
    pub fn node_count(&self) -> usize {
        self.nodes_m.len()
    }

    /// Rest positions of tetrahedron `t`'s vertices.
    pub fn tet_points(&self, t: usize) -> [V3; 4] {
        self.tets[t].map(|i| self.nodes_m[i as usize])
    }

    /// Total volume (m³).
    pub fn volume_m3(&self) -> f64 {
        (0..self.tets.len())
            .map(|t| {
                let p = self.tet_points(t);
                signed_volume_m3(p[0], p[1], p[2], p[3])
            })
            .sum()
    }

    /// For every edge, the summed volume of the tetrahedra that share it
    /// (m³): the volume a Voigt element stands for.
    pub fn edge_volumes_m3(&self) -> Vec<f64> {
        let index: HashMap<[u32; 2], usize> = self
            .edges
            .iter()
            .enumerate()
            .map(|(k, e)| (*e, k))
            .collect();
        let mut vol = vec![0.0; self.edges.len()];
        for (t, tet) in self.tets.iter().enumerate() {
            let p = self.tet_points(t);
            let v = signed_volume_m3(p[0], p[1], p[2], p[3]);
            for (a, b) in [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)] {
                let key = [tet[a].min(tet[b]), tet[a].max(tet[b])];
                if let Some(&k) = index.get(&key) {
                    vol[k] += v;
                }
            }
        }
        vol
    }

    /// Lumped node masses (kg): a quarter of each adjacent tetrahedron's
    /// mass at uniform density.
    pub fn lumped_masses_kg(&self, density_kg_m3: f64) -> Vec<f64> {
        let mut m = vec![0.0; self.nodes_m.len()];
        for (t, tet) in self.tets.iter().enumerate() {
            let p = self.tet_points(t);
            let quarter = density_kg_m3 * signed_volume_m3(p[0], p[1], p[2], p[3]) / 4.0;
            for &i in tet {
                m[i as usize] += quarter;
            }
        }
        m
    }

    /// Outward unit normal at each surface node in the rest shape (the
    /// area-weighted mean of its boundary triangles' normals; zero inside).
    pub fn rest_normals(&self) -> Vec<V3> {
        let mut n = vec![V3::zeros(); self.nodes_m.len()];
        for f in &self.boundary_faces {
            let p = f.map(|i| self.nodes_m[i as usize]);
            let area2 = (p[1] - p[0]).cross(&(p[2] - p[0]));
            for &i in f {
                n[i as usize] += area2;
            }
        }
        for v in &mut n {
            let len = v.norm();
            if len > 0.0 {
                *v /= len;
            }
        }
        n
    }

    /// Nodes on the face `z = 0` (the face the cube rests on, held fixed).
    pub fn bottom_nodes(&self) -> Vec<bool> {
        self.nodes_m.iter().map(|p| p.z == 0.0).collect()
    }

    /// The node nearest to `p_m` in the rest shape (lowest index on ties).
    pub fn nearest_node(&self, p_m: V3) -> usize {
        let mut best = (f64::INFINITY, 0);
        for (i, q) in self.nodes_m.iter().enumerate() {
            let d = (q - p_m).norm_squared();
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }
}

/// Bisects `s` at its refinement edge, adding (or reusing) the midpoint.
fn bisect(
    s: &Simplex,
    nodes: &mut Vec<V3>,
    midpoints: &mut HashMap<(u32, u32), u32>,
) -> [Simplex; 2] {
    let k = s.tag;
    let (a, b) = (s.v[0], s.v[k]);
    let key = (a.min(b), a.max(b));
    let z = match midpoints.get(&key) {
        Some(&z) => z,
        None => {
            // Dyadic coordinates: the midpoint is exact.
            nodes.push((nodes[a as usize] + nodes[b as usize]) * 0.5);
            let z = (nodes.len() - 1) as u32;
            midpoints.insert(key, z);
            z
        }
    };
    let mut first = s.v;
    first[k] = z;
    let mut second = s.v;
    second[..k].copy_from_slice(&s.v[1..=k]);
    second[k] = z;
    let tag = if k > 1 { k - 1 } else { 3 };
    [Simplex { v: first, tag }, Simplex { v: second, tag }]
}

/// Boundary triangles (faces of exactly one tetrahedron), oriented outward,
/// and the surface flag of every node.
fn boundary(tets: &[[u32; 4]], nodes: &[V3]) -> (Vec<[u32; 3]>, Vec<bool>) {
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let key = |f: [u32; 3]| {
        let mut k = f;
        k.sort_unstable();
        k
    };
    let mut count: HashMap<[u32; 3], u32> = HashMap::new();
    for t in tets {
        for f in FACES {
            *count.entry(key(f.map(|i| t[i]))).or_insert(0) += 1;
        }
    }
    let mut faces = Vec::new();
    let mut on = vec![false; nodes.len()];
    for t in tets {
        // With a positive tetrahedron these index orders face outward.
        for f in FACES {
            let face = f.map(|i| t[i]);
            if count.get(&key(face)) == Some(&1) {
                for &i in &face {
                    on[i as usize] = true;
                }
                faces.push(face);
            }
        }
    }
    (faces, on)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn node_and_tetrahedron_counts_per_level() {
        // Level 3m is the (2^m + 1)³ grid: 27 at level 3, 729 at level 9 (the
        // seed's level 9, L2664; its level 3 has 24, see the module docs).
        let want_nodes = [8, 9, 15, 27, 35, 71, 125, 189, 429, 729];
        for (level, &n) in want_nodes.iter().enumerate() {
            let m = CubeMesh::new(level as u32, 1.0).unwrap();
            assert_eq!(m.node_count(), n, "level {level}");
            assert_eq!(m.tets.len(), 6 << level, "level {level}");
            // Euler characteristic of a ball: V − E + F − T = 1.
            let faces: HashSet<[u32; 3]> = m
                .tets
                .iter()
                .flat_map(|t| {
                    [[0, 1, 2], [0, 1, 3], [0, 2, 3], [1, 2, 3]].map(|f: [usize; 3]| {
                        let mut k = f.map(|i| t[i]);
                        k.sort_unstable();
                        k
                    })
                })
                .collect();
            let chi = m.node_count() as i64 - m.edges.len() as i64 + faces.len() as i64
                - m.tets.len() as i64;
            assert_eq!(chi, 1, "level {level}");
        }
    }

    #[test]
    fn every_level_is_a_conforming_partition_of_the_cube() {
        for level in 0..=9 {
            let side = 0.06;
            let m = CubeMesh::new(level, side).unwrap();
            let want = side.powi(3) / (6.0 * f64::from(1u32 << level));
            for t in 0..m.tets.len() {
                let p = m.tet_points(t);
                let v = signed_volume_m3(p[0], p[1], p[2], p[3]);
                assert!(
                    (v - want).abs() < 1e-12 * want,
                    "level {level} tet {t}: {v}"
                );
            }
            assert!((m.volume_m3() - side.powi(3)).abs() < 1e-12 * side.powi(3));
            // Conforming: boundary faces tile the six cube faces (area 6 s²)
            // and lie on them, pointing outward; every other face is shared
            // by exactly two tetrahedra (`boundary` counts once-only faces).
            let mut area = 0.0;
            for f in &m.boundary_faces {
                let p = f.map(|i| m.nodes_m[i as usize]);
                let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
                area += n.norm() / 2.0;
                let c = (p[0] + p[1] + p[2]) / 3.0 - V3::repeat(side / 2.0);
                assert!(n.dot(&c) > 0.0, "face {f:?} points inward");
                let on_face =
                    (0..3).any(|a| p.iter().all(|q| q[a] == 0.0) || p.iter().all(|q| q[a] == side));
                assert!(
                    on_face,
                    "level {level}: boundary face {f:?} inside the cube"
                );
            }
            assert!((area - 6.0 * side * side).abs() < 1e-12, "level {level}");
            for (i, p) in m.nodes_m.iter().enumerate() {
                let surface = (0..3).any(|a| p[a] == 0.0 || p[a] == side);
                assert_eq!(m.on_boundary[i], surface, "node {i} at {p:?}");
            }
        }
    }

    #[test]
    fn level_three_and_nine_are_the_regular_grids() {
        for (level, n) in [(3, 3), (6, 5), (9, 9)] {
            let m = CubeMesh::new(level, 1.0).unwrap();
            let h = 1.0 / f64::from(n - 1);
            let got: HashSet<[u64; 3]> = m
                .nodes_m
                .iter()
                .map(|p| [p.x, p.y, p.z].map(|c| (c / h).round() as u64))
                .collect();
            assert_eq!(got.len(), (n * n * n) as usize);
            for p in &m.nodes_m {
                for c in [p.x, p.y, p.z] {
                    assert_eq!((c / h).round() * h, c, "node off the grid");
                }
            }
            // Six Kuhn tetrahedra per cell: edges along the axes (h), the
            // face diagonals (h√2) and the one body diagonal (h√3) only.
            for e in &m.edges {
                let l = (m.nodes_m[e[0] as usize] - m.nodes_m[e[1] as usize]).norm() / h;
                assert!(
                    [1.0, 2f64.sqrt(), 3f64.sqrt()]
                        .iter()
                        .any(|w| (l - w).abs() < 1e-12),
                    "edge length {l} h"
                );
            }
        }
    }

    #[test]
    fn masses_normals_and_edge_volumes() {
        let m = CubeMesh::new(4, 0.05).unwrap();
        let mass: f64 = m.lumped_masses_kg(1000.0).iter().sum();
        assert!((mass - 1000.0 * 0.05f64.powi(3)).abs() < 1e-12);
        // Every tetrahedron has six edges: the edge volumes count each
        // tetrahedron six times.
        let ev: f64 = m.edge_volumes_m3().iter().sum();
        assert!((ev - 6.0 * m.volume_m3()).abs() < 1e-15);
        let n = m.rest_normals();
        let top = m.nearest_node(V3::new(0.025, 0.025, 0.05));
        assert!((n[top] - V3::z()).norm() < 1e-12);
        let corner = m.nearest_node(V3::new(0.05, 0.05, 0.05));
        assert!((n[corner].norm() - 1.0).abs() < 1e-12);
        assert!(n[corner].iter().all(|c| *c > 0.0));
        assert!(matches!(
            CubeMesh::new(13, 1.0),
            Err(TetError::LevelOutOfRange { level: 13, .. })
        ));
        assert!(CubeMesh::new(3, f64::NAN).is_err());
    }
}
