//! Small-strain linear-elastic FEM on 4-node tetrahedra, shared by the
//! systems that need a volume solve: the DGFM of seed 002
//! (`viscoelastic::fem` fixes surface nodes and applies forces) and the
//! breast-compression twin of seed 000 (`tissue::compress` prescribes plate
//! displacements per component and steps the geometry).
//!
//! What is modelled: isotropic linear elasticity (`LinearElastic`), the
//! element stiffness `K_e = V Bᵀ D B` of a linear tetrahedron, assembly of
//! the free equations with any set of degrees of freedom prescribed (to
//! zero or to a displacement), and a skyline (profile) Cholesky after a
//! reverse Cuthill–McKee ordering of the nodes: the cost is O(n·b²) instead
//! of the dense O(n³). The factor is checked against nalgebra's dense
//! Cholesky in the tests.
//!
//! Left out: large deformation (callers that need it step the geometry),
//! inertia (quasi-static), contact (callers decide what is prescribed),
//! other element types.
use nalgebra::{SMatrix, SVector};
use thiserror::Error;

/// Why an FEM assembly or solve refused its input.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum FemError {
    /// A material constant is NaN/infinite or outside its range.
    #[error("invalid parameter `{name}` = {}: {reason}", crate::short_number(*.value))]
    InvalidParameter {
        /// Parameter name as the user knows it.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// What the valid range is.
        reason: &'static str,
    },
    /// A tetrahedron has (near) zero volume or a node index out of range.
    #[error("tetrahedron {tet} is degenerate or uses a node that does not exist")]
    DegenerateTet {
        /// Index of the tetrahedron.
        tet: usize,
    },
    /// The stiffness matrix is not positive definite (a free rigid motion).
    #[error("FEM stiffness is not positive definite at equation {equation}: the body is not held against every rigid motion")]
    NotPositiveDefinite {
        /// Index of the pivot that failed.
        equation: usize,
    },
    /// Two series that must line up do not.
    #[error("length mismatch: {what} has {got} entries, expected {expected}")]
    LengthMismatch {
        /// Which series.
        what: &'static str,
        /// Its length.
        got: usize,
        /// The length it should have.
        expected: usize,
    },
}

/// Result alias of the FEM module.
pub type Result<T> = core::result::Result<T, FemError>;

/// Isotropic linear-elastic material.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinearElastic {
    /// Young's modulus E (Pa).
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio ν (dimensionless, in (−1, 0.5)).
    pub poisson_ratio: f64,
}

impl Default for LinearElastic {
    /// Soft rubber toy (estimate; seed 002 gives no material constants):
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
    /// Checks E > 0 (finite) and ν in (−1, 0.5).
    pub fn validate(&self) -> Result<()> {
        let e = self.youngs_modulus_pa;
        if !(e.is_finite() && e > 0.0) {
            return Err(FemError::InvalidParameter {
                name: "youngs_modulus_pa",
                value: e,
                reason: "must be finite and > 0",
            });
        }
        let nu = self.poisson_ratio;
        if !(nu.is_finite() && nu > -1.0 && nu < 0.5) {
            return Err(FemError::InvalidParameter {
                name: "poisson_ratio",
                value: nu,
                reason: "must be in (-1, 0.5)",
            });
        }
        Ok(())
    }

    /// The 6×6 isotropic elasticity matrix in Voigt order
    /// (xx, yy, zz, yz, xz, xy) with engineering shear strains.
    pub fn d_matrix(&self) -> SMatrix<f64, 6, 6> {
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

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// Signed volume of a tetrahedron (positive when `p[3]` lies on the side
/// of the triangle `p[0] p[1] p[2]` that its counter-clockwise normal
/// points to).
pub fn tet_volume(p: [[f64; 3]; 4]) -> f64 {
    let (a, b, c) = (sub(p[1], p[0]), sub(p[2], p[0]), sub(p[3], p[0]));
    (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0])
        + a[2] * (b[0] * c[1] - b[1] * c[0]))
        / 6.0
}

/// Element stiffness of a linear tetrahedron: `K_e = V Bᵀ D B` (12×12,
/// node-major, xyz per node); `None` for a degenerate element.
pub fn element_stiffness(p: [[f64; 3]; 4], d: &SMatrix<f64, 6, 6>) -> Option<SMatrix<f64, 12, 12>> {
    let j = SMatrix::<f64, 3, 3>::from_columns(&[
        SVector::<f64, 3>::from(sub(p[1], p[0])),
        SVector::<f64, 3>::from(sub(p[2], p[0])),
        SVector::<f64, 3>::from(sub(p[3], p[0])),
    ]);
    let vol = j.determinant().abs() / 6.0;
    // grad N_k (k = 1..3) are the rows of J⁻¹.
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

/// The six tetrahedra of a hexahedral cell around its diagonal 0–6, as
/// corner indices; corners 0–3 go round the bottom face (x, then y) and
/// 4–7 the top face above them. Every cell split the same way (or mirrored
/// as a whole) shares faces with its neighbours. Orientation is not fixed:
/// callers check the sign of each volume.
pub const HEX_TETS: [[usize; 4]; 6] = [
    [0, 1, 2, 6],
    [0, 2, 3, 6],
    [0, 3, 7, 6],
    [0, 7, 4, 6],
    [0, 4, 5, 6],
    [0, 5, 1, 6],
];

use crate::linalg::reverse_cuthill_mckee;
use crate::linalg::SkylineCholesky;

/// Nodes with more neighbours than this are ordered last (see
/// [`ElasticSystem::new`]).
const HUB_DEGREE: usize = 64;

/// The assembled and factored stiffness of a tetrahedral body with some
/// degrees of freedom prescribed. Degree of freedom `3 n + c` is component
/// `c` (x, y, z) of node `n`.
#[derive(Clone, Debug)]
pub struct ElasticSystem {
    /// Equation of each degree of freedom, `None` where it is prescribed.
    equation: Vec<Option<usize>>,
    chol: SkylineCholesky,
    /// `(equation, prescribed dof, K entry)`: the coupling `K_fc` that
    /// moves prescribed displacements to the right-hand side.
    coupling: Vec<(usize, usize, f64)>,
}

impl ElasticSystem {
    /// Assembles and factors `K` over `tets` (node indices into `nodes_m`)
    /// for `material`, with `prescribed[3 n + c]` marking the degrees of
    /// freedom whose displacement is given (one flag per degree of freedom).
    ///
    /// Nodes are numbered by reverse Cuthill–McKee; hub nodes (a layered
    /// mesh's centre touches every innermost-shell node) would make one
    /// huge BFS level, so they are ordered last, where they cost one long
    /// row rather than a wide band.
    pub fn new(
        nodes_m: &[[f64; 3]],
        tets: &[[usize; 4]],
        material: LinearElastic,
        prescribed: &[bool],
    ) -> Result<Self> {
        material.validate()?;
        let n = nodes_m.len();
        if prescribed.len() != 3 * n {
            return Err(FemError::LengthMismatch {
                what: "prescribed degrees of freedom",
                got: prescribed.len(),
                expected: 3 * n,
            });
        }
        if let Some(k) = tets.iter().position(|t| t.iter().any(|&i| i >= n)) {
            return Err(FemError::DegenerateTet { tet: k });
        }
        let keep: Vec<bool> = (0..n)
            .map(|k| !(prescribed[3 * k] && prescribed[3 * k + 1] && prescribed[3 * k + 2]))
            .collect();
        let mut adj = vec![Vec::new(); n];
        for t in tets {
            for &a in t {
                for &b in t {
                    if a != b && !adj[a].contains(&b) {
                        adj[a].push(b);
                    }
                }
            }
        }
        let hub: Vec<bool> = adj.iter().map(|a| a.len() > HUB_DEGREE).collect();
        let rcm_keep: Vec<bool> = keep.iter().zip(&hub).map(|(&k, &h)| k && !h).collect();
        let mut order = reverse_cuthill_mckee(&adj, &rcm_keep);
        order.extend((0..n).filter(|&i| keep[i] && hub[i]));
        let mut equation = vec![None; 3 * n];
        let mut neq = 0;
        for &node in &order {
            for c in 0..3 {
                if !prescribed[3 * node + c] {
                    equation[3 * node + c] = Some(neq);
                    neq += 1;
                }
            }
        }
        let mut first: Vec<usize> = (0..neq).collect();
        for t in tets {
            let eqs: Vec<usize> = t
                .iter()
                .flat_map(|&k| {
                    (0..3)
                        .filter_map(|c| equation[3 * k + c])
                        .collect::<Vec<_>>()
                })
                .collect();
            if let Some(&lo) = eqs.iter().min() {
                for &e in &eqs {
                    first[e] = first[e].min(lo);
                }
            }
        }
        let mut chol = SkylineCholesky::with_profile(first);
        let mut coupling = Vec::new();
        let d = material.d_matrix();
        for (k, t) in tets.iter().enumerate() {
            let ke = element_stiffness(t.map(|i| nodes_m[i]), &d)
                .ok_or(FemError::DegenerateTet { tet: k })?;
            for (a, &na) in t.iter().enumerate() {
                for ca in 0..3 {
                    let Some(i) = equation[3 * na + ca] else {
                        continue;
                    };
                    for (b, &nb) in t.iter().enumerate() {
                        for cb in 0..3 {
                            let v = ke[(3 * a + ca, 3 * b + cb)];
                            match equation[3 * nb + cb] {
                                Some(j) if j <= i => chol.add(i, j, v),
                                Some(_) => {}
                                None => coupling.push((i, 3 * nb + cb, v)),
                            }
                        }
                    }
                }
            }
        }
        chol.factor().map_err(|e| FemError::NotPositiveDefinite {
            equation: e.equation,
        })?;
        Ok(ElasticSystem {
            equation,
            chol,
            coupling,
        })
    }

    /// Number of equations (free degrees of freedom).
    pub fn equations(&self) -> usize {
        self.equation.iter().filter(|e| e.is_some()).count()
    }

    /// Profile size of the factor (stored entries).
    pub fn profile_len(&self) -> usize {
        self.chol.profile_len()
    }

    /// Equation of degree of freedom `dof` (`None` when prescribed).
    pub fn equation_of(&self, dof: usize) -> Option<usize> {
        self.equation.get(dof).copied().flatten()
    }

    /// Solves `K x = b` for the free equations in place.
    pub fn solve_equations_in_place(&self, b: &mut [f64]) {
        self.chol.solve_in_place(b);
    }

    /// Static displacement (m) of every node under nodal forces `forces_n`
    /// (N, one per node, or fewer: the first nodes; forces on prescribed
    /// degrees of freedom go to the support) with the prescribed degrees of
    /// freedom at `prescribed_m[dof]` (m; entries of free ones are ignored;
    /// an empty slice prescribes zero).
    pub fn solve(&self, forces_n: &[[f64; 3]], prescribed_m: &[f64]) -> Result<Vec<[f64; 3]>> {
        let ndof = self.equation.len();
        if forces_n.len() > ndof / 3 {
            return Err(FemError::LengthMismatch {
                what: "forces_n",
                got: forces_n.len(),
                expected: ndof / 3,
            });
        }
        if !prescribed_m.is_empty() && prescribed_m.len() != ndof {
            return Err(FemError::LengthMismatch {
                what: "prescribed_m",
                got: prescribed_m.len(),
                expected: ndof,
            });
        }
        let mut rhs = vec![0.0; self.equations()];
        for (k, f) in forces_n.iter().enumerate() {
            for (c, &fc) in f.iter().enumerate() {
                if let Some(e) = self.equation[3 * k + c] {
                    rhs[e] = fc;
                }
            }
        }
        if !prescribed_m.is_empty() {
            for &(e, dof, kv) in &self.coupling {
                rhs[e] -= kv * prescribed_m[dof];
            }
        }
        self.chol.solve_in_place(&mut rhs);
        Ok((0..ndof / 3)
            .map(|k| {
                std::array::from_fn(|c| match self.equation[3 * k + c] {
                    Some(e) => rhs[e],
                    None => prescribed_m.get(3 * k + c).copied().unwrap_or(0.0),
                })
            })
            .collect())
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

    /// A unit cube of 5 × 5 × 5 nodes split into six tetrahedra per cell.
    fn cube_mesh(n: usize) -> (Vec<[f64; 3]>, Vec<[usize; 4]>) {
        let id = |i: usize, j: usize, k: usize| i + (n + 1) * (j + (n + 1) * k);
        let h = 1.0 / n as f64;
        let mut nodes = Vec::new();
        for k in 0..=n {
            for j in 0..=n {
                for i in 0..=n {
                    nodes.push([i as f64 * h, j as f64 * h, k as f64 * h]);
                }
            }
        }
        let mut tets = Vec::new();
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    let c = [
                        id(i, j, k),
                        id(i + 1, j, k),
                        id(i + 1, j + 1, k),
                        id(i, j + 1, k),
                        id(i, j, k + 1),
                        id(i + 1, j, k + 1),
                        id(i + 1, j + 1, k + 1),
                        id(i, j + 1, k + 1),
                    ];
                    for t in HEX_TETS {
                        let mut tet = t.map(|v| c[v]);
                        if tet_volume(tet.map(|v| nodes[v])) < 0.0 {
                            tet.swap(0, 1);
                        }
                        tets.push(tet);
                    }
                }
            }
        }
        (nodes, tets)
    }

    #[test]
    fn prescribed_affine_boundary_gives_the_affine_field_inside() {
        // Patch test with non-zero prescribed displacements: any affine
        // field is an exact equilibrium of linear elasticity (constant
        // stress, no body force), so prescribing it on the boundary nodes
        // must reproduce it at every interior node to round-off.
        let (nodes, tets) = cube_mesh(4);
        let field = |p: [f64; 3]| {
            [
                0.01 * p[0] - 0.02 * p[1] + 0.005 * p[2] + 0.001,
                0.003 * p[0] + 0.015 * p[1] - 0.01 * p[2],
                -0.004 * p[0] + 0.002 * p[1] - 0.03 * p[2] + 0.002,
            ]
        };
        let on_boundary = |p: [f64; 3]| p.iter().any(|&c| !(1e-12..=1.0 - 1e-12).contains(&c));
        let mut prescribed = vec![false; 3 * nodes.len()];
        let mut values = vec![0.0; 3 * nodes.len()];
        for (k, p) in nodes.iter().enumerate() {
            if on_boundary(*p) {
                for c in 0..3 {
                    prescribed[3 * k + c] = true;
                    values[3 * k + c] = field(*p)[c];
                }
            }
        }
        let mat = LinearElastic {
            youngs_modulus_pa: 1.0e4,
            poisson_ratio: 0.3,
        };
        let sys = ElasticSystem::new(&nodes, &tets, mat, &prescribed).unwrap();
        assert_eq!(sys.equations(), 3 * 27);
        let u = sys.solve(&[], &values).unwrap();
        for (k, p) in nodes.iter().enumerate() {
            let want = field(*p);
            for c in 0..3 {
                assert!(
                    (u[k][c] - want[c]).abs() < 1e-12,
                    "node {k} component {c}: {} vs {}",
                    u[k][c],
                    want[c]
                );
            }
        }
    }

    #[test]
    fn a_free_body_is_refused_by_name() {
        let (nodes, tets) = cube_mesh(1);
        let prescribed = vec![false; 3 * nodes.len()];
        let e =
            ElasticSystem::new(&nodes, &tets, LinearElastic::default(), &prescribed).unwrap_err();
        assert!(matches!(e, FemError::NotPositiveDefinite { .. }), "{e}");
        let bad = LinearElastic {
            youngs_modulus_pa: 1.0,
            poisson_ratio: 0.5,
        };
        let e = ElasticSystem::new(&nodes, &tets, bad, &prescribed).unwrap_err();
        assert!(e.to_string().contains("poisson_ratio"), "{e}");
    }
}
