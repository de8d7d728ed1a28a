//! The voxel/lattice structure of the paper's Model 1 and its local-volume
//! variant (L1645–1690, L2155–2165): point masses on a regular grid, every
//! pair of corners of every voxel joined by a basic element.
//!
//! Each voxel owns its 28 corner pairs: 12 edges and 12 face diagonals
//! (*on* the voxel) and 4 body diagonals (*in* it); the neighbour set of a
//! mass is therefore its 26 grid neighbours (L1660). An edge shared by
//! four voxels carries four voxels' contributions, as a finite-element
//! assembly would; contributions of the same class between the same two
//! masses are merged into one element (exact, see
//! [`ElementConstants::plus`]).
//!
//! The local volume condition (Models 2 and 4) replaces each voxel's four
//! long elements, the body diagonals, by half elements: a mass at the
//! voxel's centre joined to its eight corners (L2158–2161, "longer four
//! elements are eliminated, their half elements are added"). A half
//! element is half as long, hence twice as stiff and viscous. The centre
//! masses count in N (M = M_obj/N, L1667–1678).
//!
//! Axes: x and z horizontal, y up; the grid is `nodes[0] × nodes[1] ×
//! nodes[2]` masses, the paper's "6 × 4 × 6" order (4 is the height).
use std::collections::HashMap;

use serde::{Deserialize, Serialize};

use crate::error::{bad_setting, check_positive, Result};
use crate::model::effective::{class_factors_m, family_of};
use crate::model::element::ElementConstants;
use crate::model::params::{ElementClass, LatticeParams};

pub use crate::model::vec3::V3;

/// The paper's four model variants (L1850–1860).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum VolumeMode {
    /// Model 1: no volume condition.
    #[default]
    None,
    /// Model 2: local volume condition (half elements to voxel centres).
    Local,
    /// Model 3: global volume condition (Pascal pressure on the surface).
    Global,
    /// Model 4: both.
    Both,
}

impl VolumeMode {
    /// Whether voxels get centre masses and half elements.
    pub fn local(self) -> bool {
        matches!(self, VolumeMode::Local | VolumeMode::Both)
    }
    /// Whether the surface carries the volume-feedback pressure.
    pub fn global(self) -> bool {
        matches!(self, VolumeMode::Global | VolumeMode::Both)
    }
    /// The paper's model number.
    pub fn model_number(self) -> u8 {
        match self {
            VolumeMode::None => 1,
            VolumeMode::Local => 2,
            VolumeMode::Global => 3,
            VolumeMode::Both => 4,
        }
    }
    /// Snake-case name.
    pub fn name(self) -> &'static str {
        match self {
            VolumeMode::None => "none",
            VolumeMode::Local => "local",
            VolumeMode::Global => "global",
            VolumeMode::Both => "both",
        }
    }
}

/// One element: two masses, the rest length, the class whose parameters
/// it takes and how many voxel contributions it carries (half elements
/// count 2; on non-cubic voxels each contribution is its family's share,
/// see [`crate::model::effective`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ElementDef {
    pub i: u32,
    pub j: u32,
    pub rest_m: f64,
    pub class: ElementClass,
    pub weight: f64,
}

/// A lattice (or any structure of masses and basic elements).
#[derive(Clone, Debug)]
pub struct Lattice {
    /// Grid masses per axis (x, y up, z); [0, 0, 0] for a custom structure.
    pub nodes: [usize; 3],
    /// Block size (m) per axis.
    pub size_m: [f64; 3],
    /// Volume variant the structure was built for.
    pub volume_mode: VolumeMode,
    /// Rest positions: grid masses first (index `i + nx·(j + ny·k)`), then
    /// voxel centres (local volume condition).
    pub rest_m: Vec<V3>,
    /// Number of grid masses (the rest are voxel centres).
    pub grid_masses: usize,
    /// Elements.
    pub elements: Vec<ElementDef>,
    /// Outward-oriented surface triangles.
    pub surface: Vec<[u32; 3]>,
    /// Horizontal tributary area of each mass (m²): what its contact with
    /// the table or plate stands for ("opposite area", L2269).
    pub tributary_area_m2: Vec<f64>,
    /// Edge of a voxel (geometric mean of the spacings, m): the h of the
    /// element constants (times each element's weight).
    pub voxel_edge_m: f64,
    /// Voxels facing the surface, and all voxels.
    pub surface_voxels: usize,
    pub voxels: usize,
}

/// Largest grid accepted (masses per axis): far beyond the paper's 11.
pub const MAX_NODES_PER_AXIS: usize = 64;

impl Lattice {
    /// The lattice of `nodes` masses per axis filling a block of `size_m`.
    pub fn grid(nodes: [usize; 3], size_m: [f64; 3], volume_mode: VolumeMode) -> Result<Self> {
        for (a, (&n, &s)) in nodes.iter().zip(&size_m).enumerate() {
            let axis = ["x", "y", "z"][a];
            if !(2..=MAX_NODES_PER_AXIS).contains(&n) {
                return Err(bad_setting(
                    &format!("grid.{axis}"),
                    format!("needs 2..={MAX_NODES_PER_AXIS} masses along each axis, got {n}"),
                ));
            }
            check_positive(&format!("size_cm.{axis}"), s)?;
        }
        let [nx, ny, nz] = nodes;
        let h = [
            size_m[0] / (nx - 1) as f64,
            size_m[1] / (ny - 1) as f64,
            size_m[2] / (nz - 1) as f64,
        ];
        // Each element family's share of a voxel, relative to the voxel
        // edge h̄ the element constants are built with: 1 for cubic voxels,
        // chosen so that the stiffness is the cubic lattice's otherwise.
        let voxel_edge_m = (h[0] * h[1] * h[2]).cbrt();
        let share = class_factors_m(h)?.map(|g| g / voxel_edge_m);
        let id = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
        let mut rest_m = grid_positions(nodes, h);
        let grid_masses = rest_m.len();
        let mut merged: Vec<ElementDef> = Vec::new();
        let mut index: HashMap<(u32, u32, ElementClass), usize> = HashMap::new();
        let mut add = |a: u32, b: u32, class: ElementClass, weight: f64, rest: &[V3]| {
            let key = (a.min(b), a.max(b), class);
            match index.get(&key) {
                Some(&e) => merged[e].weight += weight,
                None => {
                    index.insert(key, merged.len());
                    merged.push(ElementDef {
                        i: key.0,
                        j: key.1,
                        rest_m: (rest[b as usize] - rest[a as usize]).norm(),
                        class,
                        weight,
                    });
                }
            }
        };
        let (mut voxels, mut surface_voxels) = (0, 0);
        for vk in 0..nz - 1 {
            for vj in 0..ny - 1 {
                for vi in 0..nx - 1 {
                    voxels += 1;
                    let surf = vi == 0
                        || vj == 0
                        || vk == 0
                        || vi == nx - 2
                        || vj == ny - 2
                        || vk == nz - 2;
                    surface_voxels += usize::from(surf);
                    let corner = |c: usize| id(vi + (c & 1), vj + ((c >> 1) & 1), vk + (c >> 2));
                    let centre = if volume_mode.local() {
                        rest_m.push(V3::new(
                            (vi as f64 + 0.5) * h[0],
                            (vj as f64 + 0.5) * h[1],
                            (vk as f64 + 0.5) * h[2],
                        ));
                        Some((rest_m.len() - 1) as u32)
                    } else {
                        None
                    };
                    for a in 0..8usize {
                        for b in a + 1..8 {
                            let differing = (a ^ b).count_ones();
                            if differing < 3 {
                                add(
                                    corner(a),
                                    corner(b),
                                    ElementClass::of(surf, false),
                                    share[family_of(a, b)],
                                    &rest_m,
                                );
                            } else if centre.is_none() {
                                add(
                                    corner(a),
                                    corner(b),
                                    ElementClass::of(surf, true),
                                    share[7],
                                    &rest_m,
                                );
                            }
                        }
                        if let Some(c) = centre {
                            add(
                                corner(a),
                                c,
                                ElementClass::of(surf, true),
                                2.0 * share[7],
                                &rest_m,
                            );
                        }
                    }
                }
            }
        }
        let surface = box_surface(nodes, &rest_m);
        let tributary_area_m2 = tributary_areas(nodes, h, rest_m.len());
        Ok(Self {
            nodes,
            size_m,
            volume_mode,
            rest_m,
            grid_masses,
            elements: merged,
            surface,
            tributary_area_m2,
            voxel_edge_m,
            surface_voxels,
            voxels,
        })
    }

    /// A custom structure (single elements, columns) for tests and
    /// experiments: masses, elements and tributary areas given directly,
    /// no surface.
    pub fn custom(rest_m: Vec<V3>, elements: Vec<ElementDef>, voxel_edge_m: f64) -> Self {
        let n = rest_m.len();
        Self {
            nodes: [0; 3],
            size_m: [0.0; 3],
            volume_mode: VolumeMode::None,
            grid_masses: n,
            tributary_area_m2: vec![voxel_edge_m * voxel_edge_m; n],
            rest_m,
            elements,
            surface: Vec::new(),
            voxel_edge_m,
            surface_voxels: 0,
            voxels: 0,
        }
    }

    /// Number of masses (N of M = M_obj/N).
    pub fn masses(&self) -> usize {
        self.rest_m.len()
    }

    /// Grid spacing per axis (m).
    pub fn spacing_m(&self) -> [f64; 3] {
        let mut h = [0.0; 3];
        for ((h, &n), &size) in h.iter_mut().zip(&self.nodes).zip(&self.size_m) {
            if n > 1 {
                *h = size / (n - 1) as f64;
            }
        }
        h
    }

    /// Index of grid mass (i, j, k).
    pub fn node_index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.nodes[0] * (j + self.nodes[1] * k)
    }

    /// The element constants for `params` (every voxel contribution of the
    /// element's class, summed).
    pub fn element_constants(&self, params: &LatticeParams) -> Vec<ElementConstants> {
        self.elements
            .iter()
            .map(|e| {
                ElementConstants::from_params(params.get(e.class), self.voxel_edge_m, e.weight)
            })
            .collect()
    }

    /// Volume enclosed by the surface at positions `x` (m³).
    pub fn volume_m3(&self, x: &[V3]) -> f64 {
        enclosed_volume_m3(&self.surface, x)
    }
}

/// The rest positions of a grid of `nodes` masses at spacings `h` (m),
/// index `i + nx·(j + ny·k)`.
fn grid_positions(nodes: [usize; 3], h: [f64; 3]) -> Vec<V3> {
    let [nx, ny, nz] = nodes;
    let mut rest_m = Vec::with_capacity(nx * ny * nz);
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                rest_m.push(V3::new(i as f64 * h[0], j as f64 * h[1], k as f64 * h[2]));
            }
        }
    }
    rest_m
}

/// The horizontal tributary areas (m²) of a grid's masses (halved on the
/// x and z boundaries), then of `masses − grid masses` voxel centres.
fn tributary_areas(nodes: [usize; 3], h: [f64; 3], masses: usize) -> Vec<f64> {
    let [nx, ny, nz] = nodes;
    let w = |n: usize, i: usize, h: f64| if i == 0 || i == n - 1 { h / 2.0 } else { h };
    let mut areas: Vec<f64> = (0..nx * ny * nz)
        .map(|g| {
            let (i, k) = (g % nx, g / (nx * ny));
            w(nx, i, h[0]) * w(nz, k, h[2])
        })
        .collect();
    areas.resize(masses, h[0] * h[2]);
    areas
}

/// The section through the middle of a grid of `nodes` (x, y, z) at
/// positions `x` (grid nodes first, index `i + nx·(j + ny·k)`): nx × ny
/// points, row by row in j, the mean of the two middle layers when nz is
/// even.
pub fn mid_section(nodes: [usize; 3], x: &[V3]) -> Vec<V3> {
    let [nx, ny, nz] = nodes;
    let (k0, k1) = if nz % 2 == 1 {
        (nz / 2, nz / 2)
    } else {
        (nz / 2 - 1, nz / 2)
    };
    let mut out = Vec::with_capacity(nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            let a = x[i + nx * (j + ny * k0)];
            let b = x[i + nx * (j + ny * k1)];
            out.push((a + b) * 0.5);
        }
    }
    out
}

/// The distinct masses on a surface (sorted).
pub fn surface_nodes(surface: &[[u32; 3]]) -> Vec<usize> {
    let mut n: Vec<usize> = surface.iter().flatten().map(|&v| v as usize).collect();
    n.sort_unstable();
    n.dedup();
    n
}

/// Volume enclosed by outward triangles (divergence theorem).
pub fn enclosed_volume_m3(surface: &[[u32; 3]], x: &[V3]) -> f64 {
    surface
        .iter()
        .map(|t| x[t[0] as usize].dot(&x[t[1] as usize].cross(&x[t[2] as usize])))
        .sum::<f64>()
        / 6.0
}

/// Adds ∂V/∂x_i of the enclosed volume to `grad` (m²).
pub fn volume_gradient(surface: &[[u32; 3]], x: &[V3], grad: &mut [V3]) {
    for g in grad.iter_mut() {
        *g = V3::zeros();
    }
    for t in surface {
        let [a, b, c] = t.map(|i| i as usize);
        grad[a] += x[b].cross(&x[c]) / 6.0;
        grad[b] += x[c].cross(&x[a]) / 6.0;
        grad[c] += x[a].cross(&x[b]) / 6.0;
    }
}

/// The outward triangles of the box faces of a grid (two per face quad).
fn box_surface(nodes: [usize; 3], rest: &[V3]) -> Vec<[u32; 3]> {
    let [nx, ny, _] = nodes;
    let id = |i: usize, j: usize, k: usize| (i + nx * (j + ny * k)) as u32;
    let mut tris = Vec::new();
    // For each axis a and side s, the face's quads over the other two axes.
    for a in 0..3 {
        let (b, c) = ((a + 1) % 3, (a + 2) % 3);
        for side in [0usize, nodes[a] - 1] {
            let outward = if side == 0 { -1.0 } else { 1.0 };
            for u in 0..nodes[b] - 1 {
                for w in 0..nodes[c] - 1 {
                    let at = |du: usize, dw: usize| {
                        let mut ijk = [0usize; 3];
                        ijk[a] = side;
                        ijk[b] = u + du;
                        ijk[c] = w + dw;
                        id(ijk[0], ijk[1], ijk[2])
                    };
                    let q = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
                    let p = |n: u32| rest[n as usize];
                    let normal = (p(q[1]) - p(q[0])).cross(&(p(q[2]) - p(q[0])));
                    let q = if normal[a] * outward > 0.0 {
                        q
                    } else {
                        [q[0], q[3], q[2], q[1]]
                    };
                    tris.push([q[0], q[1], q[2]]);
                    tris.push([q[0], q[2], q[3]]);
                }
            }
        }
    }
    tris
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_voxel_has_the_papers_28_elements_and_a_closed_surface() {
        let l = Lattice::grid([2, 2, 2], [0.01; 3], VolumeMode::None).unwrap();
        assert_eq!(l.elements.len(), 28);
        let inside = l
            .elements
            .iter()
            .filter(|e| e.class == ElementClass::SurfaceIn)
            .count();
        assert_eq!(inside, 4);
        assert!((l.volume_m3(&l.rest_m) - 1e-6).abs() < 1e-18);
        assert_eq!(l.surface.len(), 12);
        let local = Lattice::grid([2, 2, 2], [0.01; 3], VolumeMode::Local).unwrap();
        assert_eq!(local.masses(), 9);
        assert_eq!(local.elements.len(), 24 + 8);
        let half = local.elements.iter().find(|e| e.j == 8).unwrap();
        assert!((half.rest_m - 0.01 * 3f64.sqrt() / 2.0).abs() < 1e-15);
        assert_eq!(half.weight, 2.0);
    }

    #[test]
    fn the_papers_grids_count_elements_voxels_and_core() {
        // 6×4×6 (L1923): 13 neighbour directions, 5×3×5 voxels of which the
        // 3×1×3 inner ones are core.
        let l = Lattice::grid([6, 4, 6], [0.10, 0.06, 0.10], VolumeMode::None).unwrap();
        assert_eq!(l.voxels, 75);
        assert_eq!(l.surface_voxels, 66);
        let pairs: std::collections::HashSet<(u32, u32)> =
            l.elements.iter().map(|e| (e.i, e.j)).collect();
        assert_eq!(pairs.len(), 348 + 560 + 300);
        // Interior axis edges carry four voxels, face diagonals two.
        let total_weight: f64 = l.elements.iter().map(|e| e.weight).sum();
        assert_eq!(total_weight, 75.0 * 28.0);
        assert!((l.volume_m3(&l.rest_m) - 6e-4).abs() < 1e-15);
        let area: f64 = (0..l.grid_masses)
            .filter(|&g| (g / 6) % 4 == 3)
            .map(|g| l.tributary_area_m2[g])
            .sum();
        assert!(
            (area - 0.01).abs() < 1e-15,
            "top tributary areas sum to the top face"
        );
        // 11×7×11 (L1927): cost grows with the element count, ≈ 7.2×.
        let d = Lattice::grid([11, 7, 11], [0.10, 0.06, 0.10], VolumeMode::None).unwrap();
        let dp: std::collections::HashSet<(u32, u32)> =
            d.elements.iter().map(|e| (e.i, e.j)).collect();
        assert_eq!(dp.len(), 8706);
    }

    #[test]
    fn the_volume_gradient_is_the_derivative_of_the_volume() {
        let l = Lattice::grid([3, 2, 3], [0.02, 0.01, 0.02], VolumeMode::None).unwrap();
        let mut x = l.rest_m.clone();
        for (n, p) in x.iter_mut().enumerate() {
            p.x += 1e-3 * ((n * 7 % 5) as f64);
            p.y -= 5e-4 * ((n * 3 % 4) as f64);
        }
        let mut g = vec![V3::zeros(); x.len()];
        volume_gradient(&l.surface, &x, &mut g);
        let eps = 1e-7;
        for n in [0, 4, 9, 17] {
            for a in 0..3 {
                let mut xp = x.clone();
                xp[n][a] += eps;
                let mut xm = x.clone();
                xm[n][a] -= eps;
                let fd = (l.volume_m3(&xp) - l.volume_m3(&xm)) / (2.0 * eps);
                assert!((fd - g[n][a]).abs() < 1e-12, "node {n} axis {a}");
            }
        }
    }

    #[test]
    fn bad_grids_are_refused_by_name() {
        let e = Lattice::grid([1, 4, 6], [0.1, 0.06, 0.1], VolumeMode::None).unwrap_err();
        assert!(e.to_string().contains("grid.x"), "{e}");
        let e = Lattice::grid([6, 4, 6], [0.1, -0.06, 0.1], VolumeMode::None).unwrap_err();
        assert!(e.to_string().contains("size_cm.y"), "{e}");
    }
}
