//! Closed triangulated surface meshes: a generated default object, OBJ
//! reading/writing, validation and node areas α_j (seed 002 Eq. 2).
//!
//! What is modelled: a closed, consistently oriented (outward normals),
//! two-manifold triangle mesh in metres. Node areas are the barycentric
//! lumping of the adjacent triangle areas (one third each), which is the
//! consistent nodal load of a uniform traction on linear triangles.
//!
//! Left out: texture/normal data in OBJ files (ignored), non-manifold or
//! open meshes (rejected), meshes with holes.
use crate::error::{Result, VeError};
use std::collections::HashMap;
use std::fmt::Write as _;

/// What a mesh check found at fault.
#[derive(Clone, Copy, Debug)]
enum Culprit {
    Vertex(usize),
    Triangle(usize),
    Whole,
}

/// A closed triangle surface mesh, positions in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceMesh {
    /// Vertex positions (m).
    pub vertices_m: Vec<[f64; 3]>,
    /// Triangles as vertex indices, counter-clockwise seen from outside.
    pub triangles: Vec<[usize; 3]>,
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub(crate) fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub(crate) fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

/// Default object: a rubber-toy-sized blob (estimate: the seed's triceratops
/// is a hand-sized toy). Semi-axes in metres.
pub const BLOB_SEMI_AXES_M: [f64; 3] = [0.06, 0.04, 0.035];
/// Latitude rings and segments of the default blob: 14 × 14 + 2 poles = 198
/// vertices, close to the seed's 193-vertex triceratops (Table 2).
pub const BLOB_RINGS: usize = 14;
/// Segments per ring of the default blob.
pub const BLOB_SEGMENTS: usize = 14;

impl SurfaceMesh {
    /// The shipped default object: an ellipsoidal blob with a lobed waist
    /// (so that vertices differ in stiffness), 198 vertices, 392 triangles.
    pub fn default_object() -> Self {
        Self::blob(BLOB_RINGS, BLOB_SEGMENTS, BLOB_SEMI_AXES_M)
    }

    /// A latitude–longitude blob with `rings` rings of `segments` vertices
    /// plus two poles, semi-axes `semi_axes_m`, radius modulated by
    /// `1 + 0.15 cos(2φ) sin²θ` (a shape choice, not a physical constant).
    pub fn blob(rings: usize, segments: usize, semi_axes_m: [f64; 3]) -> Self {
        let rings = rings.max(2);
        let segments = segments.max(3);
        let mut v = Vec::with_capacity(rings * segments + 2);
        v.push([0.0, 0.0, semi_axes_m[2]]);
        for r in 0..rings {
            let theta = std::f64::consts::PI * (r as f64 + 1.0) / (rings as f64 + 1.0);
            for s in 0..segments {
                let phi = 2.0 * std::f64::consts::PI * s as f64 / segments as f64;
                let lobe = 1.0 + 0.15 * (2.0 * phi).cos() * theta.sin().powi(2);
                v.push([
                    semi_axes_m[0] * lobe * theta.sin() * phi.cos(),
                    semi_axes_m[1] * lobe * theta.sin() * phi.sin(),
                    semi_axes_m[2] * theta.cos(),
                ]);
            }
        }
        v.push([0.0, 0.0, -semi_axes_m[2]]);
        let bottom = v.len() - 1;
        let at = |r: usize, s: usize| 1 + r * segments + (s % segments);
        let mut t = Vec::new();
        for s in 0..segments {
            t.push([0, at(0, s), at(0, s + 1)]);
        }
        for r in 0..rings - 1 {
            for s in 0..segments {
                t.push([at(r, s), at(r + 1, s), at(r + 1, s + 1)]);
                t.push([at(r, s), at(r + 1, s + 1), at(r, s + 1)]);
            }
        }
        for s in 0..segments {
            t.push([bottom, at(rings - 1, s + 1), at(rings - 1, s)]);
        }
        SurfaceMesh {
            vertices_m: v,
            triangles: t,
        }
    }

    /// An axis-aligned cube `[0, side]³` with `n × n` quads per face, each
    /// split into two triangles (used for the FEM patch test).
    pub fn cube(n: usize, side_m: f64) -> Self {
        let n = n.max(1);
        let mut index: HashMap<[i64; 3], usize> = HashMap::new();
        let mut v = Vec::new();
        let mut t = Vec::new();
        let mut id = |p: [i64; 3], v: &mut Vec<[f64; 3]>| {
            *index.entry(p).or_insert_with(|| {
                v.push([
                    p[0] as f64 * side_m / n as f64,
                    p[1] as f64 * side_m / n as f64,
                    p[2] as f64 * side_m / n as f64,
                ]);
                v.len() - 1
            })
        };
        let ni = n as i64;
        // (axis normal, fixed coordinate, outward sign)
        for axis in 0..3 {
            for &(c, sign) in &[(0i64, -1i64), (ni, 1)] {
                let (a1, a2) = ((axis + 1) % 3, (axis + 2) % 3);
                for i in 0..ni {
                    for j in 0..ni {
                        let corner = |di: i64, dj: i64| {
                            let mut p = [0i64; 3];
                            p[axis] = c;
                            p[a1] = i + di;
                            p[a2] = j + dj;
                            p
                        };
                        let q = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                        let q: Vec<usize> = q.iter().map(|p| id(*p, &mut v)).collect();
                        // (a1, a2, axis) is right-handed, so CCW in (a1, a2) faces +axis.
                        if sign > 0 {
                            t.push([q[0], q[1], q[2]]);
                            t.push([q[0], q[2], q[3]]);
                        } else {
                            t.push([q[0], q[2], q[1]]);
                            t.push([q[0], q[3], q[2]]);
                        }
                    }
                }
            }
        }
        SurfaceMesh {
            vertices_m: v,
            triangles: t,
        }
    }

    /// Number of vertices.
    pub fn len(&self) -> usize {
        self.vertices_m.len()
    }

    /// True when the mesh has no vertices.
    pub fn is_empty(&self) -> bool {
        self.vertices_m.is_empty()
    }

    /// Area of triangle `t` (m²).
    pub fn triangle_area_m2(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangles[t].map(|i| self.vertices_m[i]);
        0.5 * norm(cross(sub(b, a), sub(c, a)))
    }

    /// Node areas α_j (m²): one third of each adjacent triangle's area.
    pub fn node_areas_m2(&self) -> Vec<f64> {
        let mut alpha = vec![0.0; self.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let a3 = self.triangle_area_m2(t) / 3.0;
            for &i in tri {
                alpha[i] += a3;
            }
        }
        alpha
    }

    /// Outward unit normal at each vertex (area-weighted face normals).
    pub fn vertex_normals(&self) -> Vec<[f64; 3]> {
        let mut n = vec![[0.0; 3]; self.len()];
        for tri in &self.triangles {
            let [a, b, c] = tri.map(|i| self.vertices_m[i]);
            let f = cross(sub(b, a), sub(c, a));
            for &i in tri {
                for k in 0..3 {
                    n[i][k] += f[k];
                }
            }
        }
        n.into_iter()
            .map(|v| {
                let l = norm(v);
                if l > 0.0 {
                    [v[0] / l, v[1] / l, v[2] / l]
                } else {
                    [0.0, 0.0, 1.0]
                }
            })
            .collect()
    }

    /// Mean of the vertex positions (m).
    pub fn vertex_mean_m(&self) -> [f64; 3] {
        let n = self.len().max(1) as f64;
        let mut c = [0.0; 3];
        for v in &self.vertices_m {
            for k in 0..3 {
                c[k] += v[k] / n;
            }
        }
        c
    }

    /// Checks that the mesh is usable: finite coordinates, valid indices,
    /// no degenerate triangle, every edge shared by exactly two triangles in
    /// opposite directions (closed, consistently oriented two-manifold),
    /// every vertex used, and positive enclosed volume (outward normals).
    pub fn validate(&self) -> Result<()> {
        self.check().map_err(|(_, m)| VeError::InvalidMesh(m))
    }

    /// [`SurfaceMesh::validate`], saying which vertex or triangle is at
    /// fault (for a reader to name its line).
    fn check(&self) -> core::result::Result<(), (Culprit, String)> {
        let bad = |s: String| Err((Culprit::Whole, s));
        if self.len() < 4 || self.triangles.len() < 4 {
            return bad(format!(
                "{} vertices / {} triangles: a closed surface needs at least 4 of each",
                self.len(),
                self.triangles.len()
            ));
        }
        if let Some(i) = self
            .vertices_m
            .iter()
            .position(|v| !v.iter().all(|c| c.is_finite()))
        {
            return Err((
                Culprit::Vertex(i),
                format!("vertex {i} has a non-finite coordinate"),
            ));
        }
        let scale = self.bounding_size_m();
        // Areas and volumes go as the size squared and cubed: a mesh whose
        // cube overflows cannot be measured (each coordinate finite, the
        // areas not: such a mesh was refused for a "(near) zero area").
        if !scale.powi(3).is_finite() {
            let far = self
                .vertices_m
                .iter()
                .enumerate()
                .max_by(|a, b| {
                    let m = |v: &[f64; 3]| v.iter().fold(0.0f64, |x, c| x.max(c.abs()));
                    m(a.1).total_cmp(&m(b.1))
                })
                .map_or(0, |(i, _)| i);
            return Err((
                Culprit::Vertex(far),
                format!(
                    "vertex {far} lies {} m out: the mesh spans {} m, so its volume overflows (coordinates are in metres)",
                    plant_common::short_number(self.vertices_m[far].iter().fold(0.0f64, |x, c| x.max(c.abs()))),
                    plant_common::short_number(scale)
                ),
            ));
        }
        let mut used = vec![false; self.len()];
        let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            let at = |m: String| Err((Culprit::Triangle(t), m));
            for &i in tri {
                if i >= self.len() {
                    return at(format!(
                        "triangle {t} uses vertex {i}, but there are only {}",
                        self.len()
                    ));
                }
                used[i] = true;
            }
            if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
                return at(format!("triangle {t} repeats a vertex"));
            }
            if self.triangle_area_m2(t) <= 1e-12 * scale * scale {
                return at(format!("triangle {t} has (near) zero area"));
            }
            for k in 0..3 {
                *edges.entry((tri[k], tri[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &count) in &edges {
            if count != 1 || edges.get(&(b, a)).copied() != Some(1) {
                return bad(format!(
                    "edge {a}-{b} is not shared by exactly two oppositely oriented triangles (open, non-manifold or inconsistently oriented surface)"
                ));
            }
        }
        if let Some(i) = used.iter().position(|u| !u) {
            return Err((
                Culprit::Vertex(i),
                format!("vertex {i} is not used by any triangle"),
            ));
        }
        if self.signed_volume_m3() <= 0.0 {
            return bad("enclosed volume is not positive: triangles must be counter-clockwise seen from outside".into());
        }
        Ok(())
    }

    /// Largest extent of the bounding box (m).
    pub fn bounding_size_m(&self) -> f64 {
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for v in &self.vertices_m {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
    }

    /// Enclosed volume (m³) by the divergence theorem.
    pub fn signed_volume_m3(&self) -> f64 {
        self.triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| self.vertices_m[i]);
                dot(a, cross(b, c)) / 6.0
            })
            .sum()
    }

    /// Parses Wavefront OBJ text: `v x y z` (metres) and `f a b c …`
    /// (1-based or negative indices, `a/b/c` forms accepted, polygons fan-
    /// triangulated). Other records are ignored. `source` names the input
    /// in errors. The result is validated.
    pub fn from_obj_str(text: &str, source: &str) -> Result<Self> {
        let err = |line: usize, reason: String| VeError::Parse {
            file: source.to_string(),
            line,
            reason,
        };
        let mut v: Vec<[f64; 3]> = Vec::new();
        let mut t: Vec<[usize; 3]> = Vec::new();
        // The line of every vertex and triangle, to name it in errors.
        let (mut v_lines, mut t_lines) = (Vec::new(), Vec::new());
        for (k, raw) in text.lines().enumerate() {
            let line_no = k + 1;
            let line = raw.split('#').next().unwrap_or("").trim();
            let mut it = line.split_whitespace();
            match it.next() {
                Some("v") => {
                    let c: Vec<&str> = it.collect();
                    if c.len() < 3 {
                        return Err(err(
                            line_no,
                            format!("vertex needs 3 coordinates, found {}", c.len()),
                        ));
                    }
                    let mut p = [0.0; 3];
                    for (slot, s) in p.iter_mut().zip(c.iter()) {
                        *slot = s.parse::<f64>().map_err(|_| {
                            err(
                                line_no,
                                format!(
                                    "vertex coordinate `{}` is not a number",
                                    plant_common::csv_input::excerpt(s)
                                ),
                            )
                        })?;
                        if !slot.is_finite() {
                            return Err(err(
                                line_no,
                                format!(
                                    "vertex coordinate `{}` is not finite",
                                    plant_common::csv_input::excerpt(s)
                                ),
                            ));
                        }
                    }
                    v.push(p);
                    v_lines.push(line_no);
                }
                Some("f") => {
                    let mut idx = Vec::new();
                    for s in it {
                        let first = s.split('/').next().unwrap_or("");
                        let i: i64 = first.parse().map_err(|_| {
                            err(
                                line_no,
                                format!(
                                    "face index `{}` is not an integer",
                                    plant_common::csv_input::excerpt(s)
                                ),
                            )
                        })?;
                        let resolved = if i > 0 {
                            i - 1
                        } else if i < 0 {
                            v.len() as i64 + i
                        } else {
                            -1
                        };
                        if resolved < 0 || resolved >= v.len() as i64 {
                            return Err(err(line_no, format!("face index {i} refers to no vertex defined so far ({} vertices)", v.len())));
                        }
                        idx.push(resolved as usize);
                    }
                    if idx.len() < 3 {
                        return Err(err(
                            line_no,
                            format!("face needs at least 3 vertices, found {}", idx.len()),
                        ));
                    }
                    for k in 1..idx.len() - 1 {
                        t.push([idx[0], idx[k], idx[k + 1]]);
                        t_lines.push(line_no);
                    }
                }
                _ => {}
            }
        }
        let mesh = SurfaceMesh {
            vertices_m: v,
            triangles: t,
        };
        mesh.check().map_err(|(culprit, m)| {
            let line = match culprit {
                Culprit::Vertex(i) => v_lines.get(i).copied(),
                Culprit::Triangle(k) => t_lines.get(k).copied(),
                Culprit::Whole => None,
            };
            match line {
                Some(line) => err(line, m),
                None => VeError::InvalidMesh(format!("{source}: {m}")),
            }
        })?;
        Ok(mesh)
    }

    /// Writes the mesh as OBJ text (metres, 1-based indices).
    pub fn to_obj_string(&self) -> String {
        let mut s = String::from("# softjoint viscoelastic object, metres\n");
        for v in &self.vertices_m {
            let _ = writeln!(s, "v {:e} {:e} {:e}", v[0], v[1], v[2]);
        }
        for t in &self.triangles {
            let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
        }
        s
    }
}
