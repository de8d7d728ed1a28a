//! The discrete Green's function matrix (DGFM) of an object (seed 002 §2,
//! Eq. 1–2), computed from the tetrahedral FEM of its volume.
//!
//! Vertices are split into the displacement-constrained set Λu (held at
//! zero displacement: by default the ones the object rests on) and the
//! traction set Λv. For i, j ∈ Λv, `u_i = Σ_j Ξ_ij p_j` (Eq. 1) with the
//! traction `p_j` (Pa) acting on the node area α_j (m²): the nodal force is
//! `f_j = α_j p_j`, so `Ξ_ij = G_ij α_j` with `G` the FEM compliance (m/N)
//! and the stiffness tensor is `K_ij = α_j Ξ_ij⁻¹` (N/m, Eq. 2).
//!
//! Left out: the traction → traction and displacement → traction blocks of
//! the seed's Table 1 (reaction forces on Λu are not needed for display),
//! and non-zero prescribed displacements on Λu.
use super::fem::{FemSystem, LinearElastic, TetMesh, DEFAULT_SHELL_SCALES};
use super::mesh::SurfaceMesh;
use crate::error::{Result, VeError};
use crate::{Mat3, Vec3};

/// Fraction of the object's height, from the bottom, whose vertices rest
/// on the table and form Λu in the default object (estimate: a toy sitting
/// on its base).
pub const DEFAULT_SUPPORT_HEIGHT_FRACTION: f64 = 0.12;

/// A DGFM over the traction vertices Λv of a surface mesh.
#[derive(Clone, Debug)]
pub struct Dgfm {
    mesh: SurfaceMesh,
    fixed: Vec<bool>,
    traction_vertices: Vec<usize>,
    index_of: Vec<Option<usize>>,
    areas_m2: Vec<f64>,
    /// Column-major blocks: `xi_col[j * n + i] = Ξ_ij` (m/Pa).
    xi_col: Vec<Mat3>,
}

/// Flags the vertices within `fraction` of the height above the lowest one
/// (the object resting on a table).
pub fn support_below(mesh: &SurfaceMesh, fraction: f64) -> Vec<bool> {
    let (lo, hi) = mesh
        .vertices_m
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v[2]), hi.max(v[2]))
        });
    let limit = lo + fraction * (hi - lo);
    mesh.vertices_m.iter().map(|v| v[2] <= limit).collect()
}

impl Dgfm {
    /// The shipped default object: [`SurfaceMesh::default_object`], the
    /// default material and shells, resting on its lowest 12 %.
    pub fn default_object() -> Result<Self> {
        let mesh = SurfaceMesh::default_object();
        let fixed = support_below(&mesh, DEFAULT_SUPPORT_HEIGHT_FRACTION);
        Self::from_mesh(mesh, LinearElastic::default(), fixed, &DEFAULT_SHELL_SCALES)
    }

    /// Computes the DGFM of `mesh` (validated) filled with `material`, with
    /// `fixed[v]` marking Λu, from the layered FEM with `shell_scales`.
    pub fn from_mesh(
        mesh: SurfaceMesh,
        material: LinearElastic,
        fixed: Vec<bool>,
        shell_scales: &[f64],
    ) -> Result<Self> {
        if fixed.len() != mesh.len() {
            return Err(VeError::LengthMismatch {
                what: "fixed",
                got: fixed.len(),
                expected: mesh.len(),
            });
        }
        let tet = TetMesh::layered(&mesh, shell_scales)?;
        let fem = FemSystem::new(tet, material, &fixed)?;
        let all_areas = mesh.node_areas_m2();
        let traction_vertices: Vec<usize> = (0..mesh.len()).filter(|&v| !fixed[v]).collect();
        if traction_vertices.is_empty() {
            return Err(VeError::InvalidParameter {
                name: "fixed vertices",
                value: mesh.len() as f64,
                reason: "every vertex is fixed; Λv is empty",
            });
        }
        let mut index_of = vec![None; mesh.len()];
        for (k, &v) in traction_vertices.iter().enumerate() {
            index_of[v] = Some(k);
        }
        let areas_m2: Vec<f64> = traction_vertices.iter().map(|&v| all_areas[v]).collect();
        let g = fem.compliance_blocks(&traction_vertices, &traction_vertices);
        let mut xi_col = Vec::with_capacity(areas_m2.len() * areas_m2.len());
        for (col, &alpha) in g.iter().zip(&areas_m2) {
            for blk in col {
                // FEM blocks are row-major [[f64; 3]; 3].
                xi_col.push(Mat3::from_fn(|r, c| blk[r][c]) * alpha);
            }
        }
        Ok(Dgfm {
            mesh,
            fixed,
            traction_vertices,
            index_of,
            areas_m2,
            xi_col,
        })
    }

    /// The surface mesh.
    pub fn mesh(&self) -> &SurfaceMesh {
        &self.mesh
    }
    /// Λu flags per mesh vertex.
    pub fn fixed(&self) -> &[bool] {
        &self.fixed
    }
    /// Mesh indices of Λv, in DGFM order.
    pub fn traction_vertices(&self) -> &[usize] {
        &self.traction_vertices
    }
    /// Number of traction vertices n = |Λv|.
    pub fn len(&self) -> usize {
        self.traction_vertices.len()
    }
    /// True when Λv is empty (never, for a constructed DGFM).
    pub fn is_empty(&self) -> bool {
        self.traction_vertices.is_empty()
    }
    /// DGFM index of a mesh vertex, if it is in Λv.
    pub fn index_of(&self, mesh_vertex: usize) -> Result<usize> {
        self.index_of
            .get(mesh_vertex)
            .copied()
            .flatten()
            .ok_or(VeError::VertexNotInTractionSet {
                vertex: mesh_vertex,
                n: self.mesh.len(),
            })
    }
    /// Node areas α_j (m²) in DGFM order.
    pub fn areas_m2(&self) -> &[f64] {
        &self.areas_m2
    }
    /// Ξ_ij (m/Pa) for DGFM indices i, j.
    pub fn xi(&self, i: usize, j: usize) -> Mat3 {
        self.xi_col[j * self.len() + i]
    }
    /// Column j of Ξ: the blocks Ξ_ij for every row i.
    pub fn xi_column(&self, j: usize) -> &[Mat3] {
        let n = self.len();
        &self.xi_col[j * n..(j + 1) * n]
    }
    /// Stiffness tensor K_ij = α_j Ξ_ij⁻¹ (N/m, Eq. 2), `None` if Ξ_ij is singular.
    pub fn stiffness(&self, i: usize, j: usize) -> Option<Mat3> {
        self.xi(i, j).try_inverse().map(|m| m * self.areas_m2[j])
    }
    /// The elastic answer of Eq. 1, `u_i = Σ_j Ξ_ij p_j`, by a dense product.
    pub fn static_displacement(&self, tractions_pa: &[Vec3]) -> Result<Vec<Vec3>> {
        if tractions_pa.len() != self.len() {
            return Err(VeError::LengthMismatch {
                what: "tractions_pa",
                got: tractions_pa.len(),
                expected: self.len(),
            });
        }
        let mut u = vec![Vec3::zeros(); self.len()];
        for (j, p) in tractions_pa.iter().enumerate() {
            if *p == Vec3::zeros() {
                continue;
            }
            for (ui, blk) in u.iter_mut().zip(self.xi_column(j)) {
                *ui += blk * p;
            }
        }
        Ok(u)
    }
}
