//! Linear-elastic tetrahedral FEM of the object's volume, used once to
//! compute the DGFM (seed 002 §2; the seed takes its DGFM from measurements
//! [LPW02] or from an FEM/BEM solve [BNC96, JP99]; we use the FEM).
//!
//! What is modelled: small-strain isotropic linear elasticity with 4-node
//! linear tetrahedra; the volume is filled by a *layered radial*
//! tetrahedralisation: the surface is copied inward as shells scaled about
//! the vertex mean, every (triangle × shell gap) prism is split into three
//! tetrahedra with the minimum-index diagonal rule (so neighbouring prisms
//! share faces), and the innermost shell is joined to the centre. This is
//! exact for any surface that is star-shaped about its vertex mean, which
//! is checked (every tetrahedron must have positive volume); other shapes
//! are rejected with an error rather than meshed wrongly. A general
//! constrained Delaunay mesher (TetGen-like) is left out.
//!
//! The stiffness matrix is solved by a skyline (profile) Cholesky after a
//! reverse Cuthill–McKee ordering: the cost is O(n·b²) instead of the dense
//! O(n³), which keeps the ~1,800-equation default object quick even in a
//! debug build. It is checked against nalgebra's dense Cholesky in tests.
//!
//! Left out: large deformation (the seed, too, is linear small-strain),
//! inertia (quasi-static, as the DGFM), contact between parts of the object.
use super::mesh::{cross, dot, sub, SurfaceMesh};
use crate::linalg::reverse_cuthill_mckee;
pub use crate::linalg::SkylineCholesky;
use crate::viscoelastic::error::{check_positive, Result, VeError};
use nalgebra::{SMatrix, SVector};
use rayon::prelude::*;

/// Isotropic linear-elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearElastic {
    /// Young's modulus E (Pa).
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio ν (dimensionless, in (−1, 0.5)).
    pub poisson_ratio: f64,
}

impl Default for LinearElastic {
    /// Soft rubber toy (estimate; the seed gives no material constants):
    /// E = 200 kPa, ν = 0.45 (nearly incompressible rubber, kept below 0.5
    /// because linear tetrahedra lock as ν → 0.5).
    fn default() -> Self {
        LinearElastic {
            youngs_modulus_pa: 2.0e5,
            poisson_ratio: 0.45,
        }
    }
}

impl LinearElastic {
    fn validate(&self) -> Result<()> {
        check_positive("youngs_modulus_pa", self.youngs_modulus_pa)?;
        let nu = self.poisson_ratio;
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(VeError::InvalidParameter {
                name: "poisson_ratio",
                value: nu,
                reason: "must be in (-1, 0.5)",
            });
        }
        Ok(())
    }

    /// The 6×6 isotropic elasticity matrix in Voigt order
    /// (xx, yy, zz, yz, xz, xy) with engineering shear strains.
    fn d_matrix(&self) -> SMatrix<f64, 6, 6> {
        let (e, nu) = (self.youngs_modulus_pa, self.poisson_ratio);
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = e / (2.0 * (1.0 + nu));
        let mut d = SMatrix::<f64, 6, 6>::zeros();
        for i in 0..3 {
            for j in 0..3 {
                d[(i, j)] = lambda;
            }
            d[(i, i)] = lambda + 2.0 * mu;
            d[(i + 3, i + 3)] = mu;
        }
        d
    }
}

/// A tetrahedral volume mesh whose first `surface_nodes` nodes are the
/// surface mesh's vertices, in the same order.
#[derive(Clone, Debug)]
pub struct TetMesh {
    /// Node positions (m).
    pub nodes_m: Vec<[f64; 3]>,
    /// Tetrahedra as node indices (positively oriented).
    pub tets: Vec<[usize; 4]>,
    /// Number of surface nodes (the first nodes).
    pub surface_nodes: usize,
}

/// Default inner shells of the layered tetrahedralisation, as scale factors
/// about the vertex mean (a discretisation choice: two interior layers plus
/// the centre; on the default object, three layers [0.75, 0.5, 0.25] change
/// the trace of the DGFM diagonal blocks by at most 13.7 % — measured once,
/// a discretisation error left in, not a tested bound).
pub const DEFAULT_SHELL_SCALES: [f64; 2] = [0.65, 0.3];

fn tet_volume(p: [[f64; 3]; 4]) -> f64 {
    dot(sub(p[1], p[0]), cross(sub(p[2], p[0]), sub(p[3], p[0]))) / 6.0
}

impl TetMesh {
    /// Layered radial tetrahedralisation of a validated surface (see the
    /// module docs). `shell_scales` must be strictly decreasing in (0, 1).
    pub fn layered(mesh: &SurfaceMesh, shell_scales: &[f64]) -> Result<Self> {
        mesh.validate()?;
        let mut last = 1.0;
        for &s in shell_scales {
            if !(s.is_finite() && s > 0.0 && s < last) {
                return Err(VeError::InvalidParameter {
                    name: "shell_scales",
                    value: s,
                    reason: "must be strictly decreasing inside (0, 1)",
                });
            }
            last = s;
        }
        let v = mesh.len();
        let c = mesh.vertex_mean_m();
        let mut nodes = mesh.vertices_m.clone();
        for &s in shell_scales {
            for p in &mesh.vertices_m {
                nodes.push([
                    c[0] + s * (p[0] - c[0]),
                    c[1] + s * (p[1] - c[1]),
                    c[2] + s * (p[2] - c[2]),
                ]);
            }
        }
        nodes.push(c);
        let centre = nodes.len() - 1;
        let layers = shell_scales.len() + 1;
        let mut tets = Vec::with_capacity(mesh.triangles.len() * (3 * shell_scales.len() + 1));
        for tri in &mesh.triangles {
            // Sort the triangle's vertices by index for the min-index rule.
            let mut s = *tri;
            s.sort_unstable();
            let [a, b, cc] = s;
            for l in 0..layers - 1 {
                let (o, i) = (l * v, (l + 1) * v);
                // Prism outer (a,b,c) → inner (a',b',c'); diagonals a–b', a–c', b–c'.
                tets.push([o + a, o + b, o + cc, i + cc]);
                tets.push([o + a, o + b, i + b, i + cc]);
                tets.push([o + a, i + a, i + b, i + cc]);
            }
            let inner = (layers - 1) * v;
            tets.push([inner + a, inner + b, inner + cc, centre]);
        }
        let scale = mesh.bounding_size_m();
        for (k, t) in tets.iter_mut().enumerate() {
            let vol = tet_volume(t.map(|n| nodes[n]));
            if vol < 0.0 {
                t.swap(0, 1);
            }
            if vol.abs() <= 1e-12 * scale.powi(3) {
                return Err(VeError::InvalidMesh(format!(
                    "tetrahedron {k} is degenerate: the surface is not star-shaped about its vertex mean, which the layered tetrahedralisation needs"
                )));
            }
        }
        // Star-shapedness: every surface triangle must face away from the centre.
        for (k, tri) in mesh.triangles.iter().enumerate() {
            let [a, b, cc] = tri.map(|i| mesh.vertices_m[i]);
            if dot(sub(a, c), cross(sub(b, a), sub(cc, a))) <= 0.0 {
                return Err(VeError::InvalidMesh(format!(
                    "triangle {k} faces the vertex mean: the surface is not star-shaped about it, which the layered tetrahedralisation needs"
                )));
            }
        }
        Ok(TetMesh {
            nodes_m: nodes,
            tets,
            surface_nodes: v,
        })
    }

    /// Total volume (m³).
    pub fn volume_m3(&self) -> f64 {
        self.tets
            .iter()
            .map(|t| tet_volume(t.map(|n| self.nodes_m[n])))
            .sum()
    }
}

/// Element stiffness of a linear tetrahedron: `K_e = V Bᵀ D B` (12×12,
/// node-major, xyz per node).
fn element_stiffness(p: [[f64; 3]; 4], d: &SMatrix<f64, 6, 6>) -> Option<SMatrix<f64, 12, 12>> {
    let j = SMatrix::<f64, 3, 3>::from_columns(&[
        SVector::<f64, 3>::from(sub(p[1], p[0])),
        SVector::<f64, 3>::from(sub(p[2], p[0])),
        SVector::<f64, 3>::from(sub(p[3], p[0])),
    ]);
    let vol = j.determinant().abs() / 6.0;
    // Rows of J⁻ᵀ... : grad N_k (k = 1..3) are the rows of J⁻¹.
    let jinv = j.try_inverse()?;
    let mut g = [[0.0; 3]; 4];
    for k in 0..3 {
        for c in 0..3 {
            g[k + 1][c] = jinv[(k, c)];
            g[0][c] -= jinv[(k, c)];
        }
    }
    let mut b = SMatrix::<f64, 6, 12>::zeros();
    for (n, gn) in g.iter().enumerate() {
        let (x, y, z) = (gn[0], gn[1], gn[2]);
        let col = 3 * n;
        b[(0, col)] = x;
        b[(1, col + 1)] = y;
        b[(2, col + 2)] = z;
        b[(3, col + 1)] = z;
        b[(3, col + 2)] = y;
        b[(4, col)] = z;
        b[(4, col + 2)] = x;
        b[(5, col)] = y;
        b[(5, col + 1)] = x;
    }
    Some(b.transpose() * d * b * vol)
}

/// Nodes with more neighbours than this are ordered last (see `FemSystem::new`).
const HUB_DEGREE: usize = 64;

/// The assembled and factored FEM of an object with some surface nodes
/// held fixed (the displacement-constrained set Λu).
#[derive(Clone, Debug)]
pub struct FemSystem {
    tet: TetMesh,
    /// First equation of each node, `None` for fixed nodes.
    dof_base: Vec<Option<usize>>,
    chol: SkylineCholesky,
}

impl FemSystem {
    /// Assembles and factors `K` for `tet` and `material`, with node `n`
    /// fixed (zero displacement) where `fixed_surface[n]` is true (one flag
    /// per surface node; interior nodes are free).
    pub fn new(tet: TetMesh, material: LinearElastic, fixed_surface: &[bool]) -> Result<Self> {
        material.validate()?;
        if fixed_surface.len() != tet.surface_nodes {
            return Err(VeError::LengthMismatch {
                what: "fixed_surface",
                got: fixed_surface.len(),
                expected: tet.surface_nodes,
            });
        }
        if !fixed_surface.iter().any(|&f| f) {
            return Err(VeError::InvalidParameter {
                name: "fixed vertices",
                value: 0.0,
                reason: "at least one surface vertex must be displacement-constrained (Λu), or the body floats",
            });
        }
        let n = tet.nodes_m.len();
        let mut keep = vec![true; n];
        for (k, &f) in fixed_surface.iter().enumerate() {
            keep[k] = !f;
        }
        let mut adj = vec![Vec::new(); n];
        for t in &tet.tets {
            for &a in t {
                for &b in t {
                    if a != b && !adj[a].contains(&b) {
                        adj[a].push(b);
                    }
                }
            }
        }
        // Hub nodes (the layered mesh's centre touches every innermost-shell
        // node) would make one huge BFS level; order them last instead, where
        // they cost one long row rather than a wide band.
        let hub: Vec<bool> = adj.iter().map(|a| a.len() > HUB_DEGREE).collect();
        let rcm_keep: Vec<bool> = keep.iter().zip(&hub).map(|(&k, &h)| k && !h).collect();
        let mut order = reverse_cuthill_mckee(&adj, &rcm_keep);
        order.extend((0..n).filter(|&i| keep[i] && hub[i]));
        let mut dof_base = vec![None; n];
        for (pos, &node) in order.iter().enumerate() {
            dof_base[node] = Some(3 * pos);
        }
        let neq = 3 * order.len();
        let mut first: Vec<usize> = (0..neq).collect();
        for t in &tet.tets {
            let bases: Vec<usize> = t.iter().filter_map(|&k| dof_base[k]).collect();
            if let Some(&lo) = bases.iter().min() {
                for &b in &bases {
                    for c in 0..3 {
                        first[b + c] = first[b + c].min(lo);
                    }
                }
            }
        }
        let mut chol = SkylineCholesky::with_profile(first);
        let d = material.d_matrix();
        for (k, t) in tet.tets.iter().enumerate() {
            let ke = element_stiffness(t.map(|i| tet.nodes_m[i]), &d)
                .ok_or_else(|| VeError::InvalidMesh(format!("tetrahedron {k} is degenerate")))?;
            for (a, &na) in t.iter().enumerate() {
                let Some(ba) = dof_base[na] else { continue };
                for (b, &nb) in t.iter().enumerate() {
                    let Some(bb) = dof_base[nb] else { continue };
                    for ca in 0..3 {
                        for cb in 0..3 {
                            let (i, j) = (ba + ca, bb + cb);
                            if j <= i {
                                chol.add(i, j, ke[(3 * a + ca, 3 * b + cb)]);
                            }
                        }
                    }
                }
            }
        }
        chol.factor().map_err(|e| VeError::NotPositiveDefinite {
            equation: e.equation,
        })?;
        Ok(FemSystem {
            tet,
            dof_base,
            chol,
        })
    }

    /// The volume mesh.
    pub fn tet_mesh(&self) -> &TetMesh {
        &self.tet
    }

    /// Number of equations (3 × free nodes).
    pub fn equations(&self) -> usize {
        3 * self.dof_base.iter().filter(|b| b.is_some()).count()
    }

    /// Profile size of the factor (stored entries).
    pub fn profile_len(&self) -> usize {
        self.chol.profile_len()
    }

    /// Static displacement (m) of every node for nodal forces (N) on the
    /// surface nodes (`forces_n.len()` = surface nodes; forces on fixed
    /// nodes go to the support and are ignored).
    pub fn solve_surface_forces(&self, forces_n: &[[f64; 3]]) -> Result<Vec<[f64; 3]>> {
        if forces_n.len() != self.tet.surface_nodes {
            return Err(VeError::LengthMismatch {
                what: "forces_n",
                got: forces_n.len(),
                expected: self.tet.surface_nodes,
            });
        }
        let mut rhs = vec![0.0; self.equations()];
        for (k, f) in forces_n.iter().enumerate() {
            if let Some(b) = self.dof_base[k] {
                rhs[b..b + 3].copy_from_slice(f);
            }
        }
        self.chol.solve_in_place(&mut rhs);
        Ok(self
            .dof_base
            .iter()
            .map(|b| match b {
                Some(b) => [rhs[*b], rhs[b + 1], rhs[b + 2]],
                None => [0.0; 3],
            })
            .collect())
    }

    /// Compliance columns: for each free surface node `j` (in `columns`)
    /// and direction `c`, the displacement of the free surface nodes `rows`
    /// under a unit force on (j, c). Returns `g[col][row]` as 3×3 blocks
    /// `G_row,col` (m/N), row-major, computed in parallel over columns
    /// (each column is an independent solve, so the result is identical to
    /// a serial run).
    pub fn compliance_blocks(&self, rows: &[usize], columns: &[usize]) -> Vec<Vec<[[f64; 3]; 3]>> {
        columns
            .par_iter()
            .map(|&j| {
                let mut blocks = vec![[[0.0; 3]; 3]; rows.len()];
                let Some(bj) = self.dof_base[j] else {
                    return blocks;
                };
                for c in 0..3 {
                    let mut rhs = vec![0.0; self.equations()];
                    rhs[bj + c] = 1.0;
                    self.chol.solve_in_place(&mut rhs);
                    for (blk, &i) in blocks.iter_mut().zip(rows) {
                        if let Some(bi) = self.dof_base[i] {
                            for r in 0..3 {
                                blk[r][c] = rhs[bi + r];
                            }
                        }
                    }
                }
                blocks
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn element_stiffness_has_rigid_body_null_space() {
        let p = [
            [0.0, 0.0, 0.0],
            [0.02, 0.001, 0.0],
            [0.003, 0.015, 0.002],
            [0.001, 0.004, 0.018],
        ];
        let ke = element_stiffness(p, &LinearElastic::default().d_matrix()).unwrap();
        let scale = ke.amax();
        // Translation in x and a small rotation about z: zero force.
        let mut tx = SVector::<f64, 12>::zeros();
        let mut rz = SVector::<f64, 12>::zeros();
        for (n, q) in p.iter().enumerate() {
            tx[3 * n] = 1.0;
            rz[3 * n] = -q[1];
            rz[3 * n + 1] = q[0];
        }
        assert!((ke * tx).amax() < 1e-9 * scale);
        assert!((ke * rz).amax() < 1e-9 * scale * 0.02);
    }
}
