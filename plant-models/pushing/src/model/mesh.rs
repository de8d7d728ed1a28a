//! Triangular meshes of the 2D block face (§VI-A, §VIII-A of the seed).
//!
//! The block is a rectangle of `nx × ny` squares; every square is cut along
//! one diagonal, alternating from square to square ("star" or union-jack
//! pattern), so that every other interior vertex carries springs in eight
//! directions and the diagonal bias of a one-way cut cancels (§VIII-A).
//! Springs are the triangle edges. Lengths are in image pixels (px), the
//! unit the seed's simulations and its flat-triangle threshold (2.0 units,
//! §VII-A) are expressed in. Masses are not stored: all are 1 (§VII-A).
use crate::error::{PushError, Result};
use crate::V2;

/// 2D cross product (z component), px².
#[inline]
pub fn cross(a: V2, b: V2) -> f64 {
    a.x * b.y - a.y * b.x
}

/// Signed area of triangle (a, b, c), px²; positive when counter-clockwise.
#[inline]
pub fn signed_area(a: V2, b: V2, c: V2) -> f64 {
    0.5 * cross(b - a, c - a)
}

/// A triangle mesh with its rest geometry. Triangles are stored counter-
/// clockwise at rest; `edges` are the unique triangle edges (the springs).
#[derive(Debug, Clone, PartialEq)]
pub struct Mesh {
    /// Rest positions, px.
    pub rest_positions_px: Vec<V2>,
    /// Triangles as vertex indices, counter-clockwise at rest.
    pub triangles: Vec<[usize; 3]>,
    /// Springs (unique edges), smaller index first, sorted.
    pub edges: Vec<[usize; 2]>,
    /// Original rest length D0 of every spring, px.
    pub rest_lengths_px: Vec<f64>,
    /// 1/D0² of every spring, px⁻² (the normalisation of Eq. 20).
    pub inv_rest_lengths_sq: Vec<f64>,
    /// Rest area A0 of every triangle, px².
    pub rest_areas_px2: Vec<f64>,
    /// Rest angle φ0 at each corner of every triangle, rad; corner `c` of
    /// triangle `[a, b, c']` is at vertex `tri[c]`.
    pub rest_angles_rad: Vec<[f64; 3]>,
    /// (cos φ0, sin φ0) of every entry of `rest_angles_rad`: the angle
    /// forces compare the current corner with its rest angle by rotation,
    /// which needs no arctangent for small deviations.
    pub rest_angle_cos_sin: Vec<[[f64; 2]; 3]>,
    /// Outer boundary as a counter-clockwise loop of vertex indices.
    pub boundary_loop: Vec<usize>,
}

/// Smallest rest area accepted for a triangle when building a mesh, px².
/// Below this a triangle is degenerate (estimate, far below the seed's 2.0
/// flat threshold so that fine reference meshes stay valid).
const MIN_REST_AREA_PX2: f64 = 1e-6;

/// Most squares along a side of [`Mesh::grid`] (a bound on memory and time).
pub const MAX_SQUARES_PER_SIDE: usize = 2000;

impl Mesh {
    /// Builds and validates a mesh from vertices and triangles. Clockwise
    /// triangles are re-ordered to counter-clockwise. Errors name the first
    /// bad vertex or triangle.
    pub fn new(rest_positions_px: Vec<V2>, triangles: Vec<[usize; 3]>) -> Result<Self> {
        if rest_positions_px.len() < 3 {
            return Err(PushError::InvalidMesh(format!(
                "needs at least 3 vertices, got {}",
                rest_positions_px.len()
            )));
        }
        if triangles.is_empty() {
            return Err(PushError::InvalidMesh("has no triangles".into()));
        }
        for (i, p) in rest_positions_px.iter().enumerate() {
            if !p.x.is_finite() || !p.y.is_finite() {
                return Err(PushError::InvalidMesh(format!(
                    "vertex {i} has a non-finite coordinate ({}, {})",
                    p.x, p.y
                )));
            }
        }
        let n = rest_positions_px.len();
        let mut tris = Vec::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            let [a, b, c] = *tri;
            if a >= n || b >= n || c >= n {
                return Err(PushError::InvalidMesh(format!(
                    "triangle {t} refers to vertex {} but there are only {n}",
                    a.max(b).max(c)
                )));
            }
            if a == b || b == c || a == c {
                return Err(PushError::InvalidMesh(format!(
                    "triangle {t} repeats a vertex: [{}, {}, {}]",
                    tri[0], tri[1], tri[2]
                )));
            }
            let area = signed_area(
                rest_positions_px[a],
                rest_positions_px[b],
                rest_positions_px[c],
            );
            if area.abs() < MIN_REST_AREA_PX2 {
                return Err(PushError::InvalidMesh(format!(
                    "triangle {t} is degenerate (area {area:e} px²)"
                )));
            }
            tris.push(if area > 0.0 { [a, b, c] } else { [a, c, b] });
        }
        let mut edges: Vec<[usize; 2]> = tris
            .iter()
            .flat_map(|&[a, b, c]| [[a, b], [b, c], [c, a]])
            .map(|[u, v]| if u < v { [u, v] } else { [v, u] })
            .collect();
        edges.sort_unstable();
        edges.dedup();
        // Every vertex must belong to a triangle, or it would float freely.
        let mut used = vec![false; n];
        for e in &edges {
            used[e[0]] = true;
            used[e[1]] = true;
        }
        if let Some(i) = used.iter().position(|u| !u) {
            return Err(PushError::InvalidMesh(format!(
                "vertex {i} belongs to no triangle"
            )));
        }
        let rest_lengths_px = edges
            .iter()
            .map(|&[u, v]| (rest_positions_px[v] - rest_positions_px[u]).norm())
            .collect::<Vec<f64>>();
        let inv_rest_lengths_sq = rest_lengths_px.iter().map(|d0| 1.0 / (d0 * d0)).collect();
        let rest_areas_px2 = tris
            .iter()
            .map(|&[a, b, c]| {
                signed_area(
                    rest_positions_px[a],
                    rest_positions_px[b],
                    rest_positions_px[c],
                )
            })
            .collect();
        let rest_angles_rad = tris
            .iter()
            .map(|tri| {
                let mut ang = [0.0; 3];
                for (k, a) in ang.iter_mut().enumerate() {
                    let (i, j, l) = corner(tri, k);
                    *a = corner_angle(
                        rest_positions_px[i],
                        rest_positions_px[j],
                        rest_positions_px[l],
                    );
                }
                ang
            })
            .collect::<Vec<[f64; 3]>>();
        let rest_angle_cos_sin = rest_angles_rad
            .iter()
            .map(|a| a.map(|phi| [phi.cos(), phi.sin()]))
            .collect();
        let boundary_loop = boundary_loop(n, &tris)?;
        Ok(Self {
            rest_positions_px,
            triangles: tris,
            edges,
            rest_lengths_px,
            inv_rest_lengths_sq,
            rest_areas_px2,
            rest_angles_rad,
            rest_angle_cos_sin,
            boundary_loop,
        })
    }

    /// A rectangular block `width_px × height_px` with lower-left corner at
    /// `origin_px`, cut into `nx × ny` squares with alternating diagonals.
    pub fn grid(
        origin_px: V2,
        width_px: f64,
        height_px: f64,
        nx: usize,
        ny: usize,
    ) -> Result<Self> {
        if nx == 0 {
            return Err(PushError::InvalidParameter {
                name: "nx",
                value: 0.0,
                reason: "needs at least one square",
            });
        }
        if ny == 0 {
            return Err(PushError::InvalidParameter {
                name: "ny",
                value: 0.0,
                reason: "needs at least one square",
            });
        }
        if nx > MAX_SQUARES_PER_SIDE || ny > MAX_SQUARES_PER_SIDE {
            return Err(PushError::InvalidParameter {
                name: if nx > MAX_SQUARES_PER_SIDE {
                    "nx"
                } else {
                    "ny"
                },
                value: nx.max(ny) as f64,
                reason: "more than 2000 squares per side",
            });
        }
        crate::error::check_positive("width_px", width_px)?;
        crate::error::check_positive("height_px", height_px)?;
        if !origin_px.x.is_finite() || !origin_px.y.is_finite() {
            return Err(PushError::InvalidParameter {
                name: "origin_px",
                value: f64::NAN,
                reason: "must be finite",
            });
        }
        let idx = |i: usize, j: usize| j * (nx + 1) + i;
        let mut pos = Vec::with_capacity((nx + 1) * (ny + 1));
        for j in 0..=ny {
            for i in 0..=nx {
                pos.push(V2::new(
                    origin_px.x + width_px * i as f64 / nx as f64,
                    origin_px.y + height_px * j as f64 / ny as f64,
                ));
            }
        }
        let mut tris = Vec::with_capacity(2 * nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
                if (i + j) % 2 == 0 {
                    tris.push([a, b, c]);
                    tris.push([a, c, d]);
                } else {
                    tris.push([a, b, d]);
                    tris.push([b, c, d]);
                }
            }
        }
        Self::new(pos, tris)
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest_positions_px.len()
    }

    /// Total signed area of the mesh for the given positions, px².
    pub fn total_area_px2(&self, positions_px: &[V2]) -> f64 {
        self.triangles
            .iter()
            .map(|&[a, b, c]| signed_area(positions_px[a], positions_px[b], positions_px[c]))
            .sum()
    }

    /// The boundary polygon for the given positions, px.
    pub fn contour_px(&self, positions_px: &[V2]) -> Vec<V2> {
        self.boundary_loop
            .iter()
            .map(|&i| positions_px[i])
            .collect()
    }
}

/// Corner `k` of a triangle as (apex, next, previous) in counter-clockwise order.
#[inline]
pub fn corner(tri: &[usize; 3], k: usize) -> (usize, usize, usize) {
    (tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3])
}

/// Signed angle at apex `i` from edge i→j to edge i→k, rad, in (−π, π].
/// Equals the arccos form of Eq. 12 whenever the triangle is not reversed.
#[inline]
pub fn corner_angle(pi: V2, pj: V2, pk: V2) -> f64 {
    let e1 = pj - pi;
    let e2 = pk - pi;
    cross(e1, e2).atan2(e1.dot(&e2))
}

/// Chains the boundary edges (directed edges of CCW triangles whose reverse
/// is absent) into one loop. Meshes with holes or several pieces are refused.
fn boundary_loop(n: usize, tris: &[[usize; 3]]) -> Result<Vec<usize>> {
    let mut directed: Vec<(usize, usize)> = tris
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .collect();
    directed.sort_unstable();
    let has = |u: usize, v: usize, d: &[(usize, usize)]| d.binary_search(&(u, v)).is_ok();
    let mut next = vec![usize::MAX; n];
    let mut count = 0;
    for &(u, v) in &directed {
        if !has(v, u, &directed) {
            if next[u] != usize::MAX {
                return Err(PushError::InvalidMesh(format!(
                    "vertex {u} is pinched (two boundary edges leave it)"
                )));
            }
            next[u] = v;
            count += 1;
        }
    }
    let start = next
        .iter()
        .position(|&v| v != usize::MAX)
        .ok_or_else(|| PushError::InvalidMesh("has no boundary".into()))?;
    let mut lp = vec![start];
    let mut cur = next[start];
    while cur != start {
        if cur == usize::MAX || lp.len() > count {
            return Err(PushError::InvalidMesh(
                "boundary is not a single closed loop".into(),
            ));
        }
        lp.push(cur);
        cur = next[cur];
    }
    if lp.len() != count {
        return Err(PushError::InvalidMesh(format!(
            "boundary has {} edges but its outer loop only {} (holes or several pieces)",
            count,
            lp.len()
        )));
    }
    Ok(lp)
}
