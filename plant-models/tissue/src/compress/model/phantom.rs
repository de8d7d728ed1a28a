//! The phantom twin of Kita §IV (L2456): a semi-ellipsoid of human-skin
//! gel, 130 (major) × 110 (minor) × 70 (height) mm, with 286 metal markers
//! on a regular lattice inside, compressed between two plates to 100 and
//! 80 mm.
//!
//! Axes follow the paper's Fig. 8: x along the major axis (along the chest
//! wall), y the compression direction (the minor axis), z the height away
//! from the flat base (the chest wall, z = 0).
//!
//! The volume mesh maps a structured grid of the box [−1, 1]² × [0, 1]
//! onto the half ball by `q ↦ q |q|∞ / |q|₂` (box shells become spheres)
//! and scales it by the semi-axes; each grid cell is split into six
//! tetrahedra around a main diagonal, mirrored across the planes x = 0 and
//! y = 0 so that the mesh has the body's symmetry (neighbouring cells
//! still share faces). The base z = 0 stays the flat base.
//!
//! Markers: the paper gives their number (286) and "regular intervals";
//! the spacing is ours: an 11 mm lattice (x offset by half a step, y
//! through the mid-plane, z from 10 mm) kept 4 mm inside the surface holds
//! exactly 286.
use crate::error::{check_range, Result, TissueError};
use plant_common::fem::{tet_volume, HEX_TETS};

/// The paper's phantom: semi-axes (mm) along x, y, z (L2456).
pub const PHANTOM_SEMI_AXES_MM: [f64; 3] = [65.0, 55.0, 70.0];
/// Marker count of the paper's phantom (L2456).
pub const PHANTOM_MARKERS: usize = 286;
/// Marker lattice spacing (mm): ours, chosen to hold 286 markers.
pub const MARKER_SPACING_MM: f64 = 11.0;
/// Markers keep this far inside the surface (mm), ours.
pub const MARKER_MARGIN_MM: f64 = 4.0;
/// Height of the lowest marker layer (mm), ours.
pub const MARKER_BASE_MM: f64 = 10.0;

/// A semi-ellipsoid body.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SemiEllipsoid {
    /// Semi-axes (mm) along x, y (compression), z (height).
    pub semi_axes_mm: [f64; 3],
}

impl SemiEllipsoid {
    /// The paper's phantom.
    pub fn phantom() -> Self {
        SemiEllipsoid {
            semi_axes_mm: PHANTOM_SEMI_AXES_MM,
        }
    }

    /// Checks the semi-axes.
    pub fn validate(&self) -> Result<()> {
        for (a, name) in
            self.semi_axes_mm
                .iter()
                .zip(["semi_axes_mm x", "semi_axes_mm y", "semi_axes_mm z"])
        {
            check_range(name, *a, 1.0, 1e4, "must be 1 to 10000 mm")?;
        }
        Ok(())
    }

    /// Half the width along y of the chord through (x, ·, z): the body
    /// spans |y| ≤ this there (0 outside).
    pub fn chord_half_width_mm(&self, x: f64, z: f64) -> f64 {
        let [a, b, c] = self.semi_axes_mm;
        let s = 1.0 - (x / a).powi(2) - (z / c).powi(2);
        if s > 0.0 {
            b * s.sqrt()
        } else {
            0.0
        }
    }

    /// Whether a point lies inside (z ≥ 0).
    pub fn contains(&self, p: [f64; 3]) -> bool {
        let [a, b, c] = self.semi_axes_mm;
        p[2] >= 0.0 && (p[0] / a).powi(2) + (p[1] / b).powi(2) + (p[2] / c).powi(2) <= 1.0
    }

    /// Volume (mm³).
    pub fn volume_mm3(&self) -> f64 {
        let [a, b, c] = self.semi_axes_mm;
        2.0 / 3.0 * std::f64::consts::PI * a * b * c
    }

    /// The marker lattice (see the module docs): 286 markers in the
    /// paper's phantom.
    pub fn markers(&self) -> Vec<[f64; 3]> {
        let [a, b, c] = self.semi_axes_mm;
        let (s, m) = (MARKER_SPACING_MM, MARKER_MARGIN_MM);
        let inner = |p: [f64; 3]| {
            (p[0] / (a - m)).powi(2) + (p[1] / (b - m)).powi(2) + (p[2] / (c - m)).powi(2) <= 1.0
        };
        let nx = (a / s).ceil() as i64 + 1;
        let ny = (b / s).ceil() as i64 + 1;
        let nz = (c / s).ceil() as i64 + 1;
        let mut out = Vec::new();
        for k in 0..nz {
            for j in -ny..=ny {
                for i in -nx..=nx {
                    let p = [
                        (i as f64 + 0.5) * s,
                        j as f64 * s,
                        MARKER_BASE_MM + k as f64 * s,
                    ];
                    if inner(p) {
                        out.push(p);
                    }
                }
            }
        }
        out
    }

    /// The tetrahedral mesh with `n` cells per unit of the box (2n along
    /// x and y, n along z).
    pub fn mesh(&self, n: usize) -> Result<BodyMesh> {
        self.validate()?;
        check_range("mesh_divisions", n as f64, 1.0, 40.0, "must be 1 to 40")?;
        let [a, b, c] = self.semi_axes_mm;
        let (nx, nz) = (2 * n + 1, n + 1);
        let id = |i: usize, j: usize, k: usize| i + nx * (j + nx * k);
        let mut nodes = Vec::with_capacity(nx * nx * nz);
        for k in 0..nz {
            for j in 0..nx {
                for i in 0..nx {
                    let q = [
                        -1.0 + i as f64 / n as f64,
                        -1.0 + j as f64 / n as f64,
                        k as f64 / n as f64,
                    ];
                    let inf = q.iter().map(|v| v.abs()).fold(0.0, f64::max);
                    let two = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                    let f = if two > 0.0 { inf / two } else { 0.0 };
                    nodes.push([a * q[0] * f, b * q[1] * f, c * q[2] * f]);
                }
            }
        }
        let mut tets = Vec::with_capacity(6 * (nx - 1) * (nx - 1) * (nz - 1));
        for k in 0..nz - 1 {
            for j in 0..nx - 1 {
                for i in 0..nx - 1 {
                    // Cells below the mid-planes x = 0 and y = 0 use the
                    // mirrored split, so the mesh is symmetric about both
                    // (faces on the planes are split the same either side).
                    let (fx, fy) = (i < n, j < n);
                    let corner = |dx: usize, dy: usize, dz: usize| {
                        let dx = if fx { 1 - dx } else { dx };
                        let dy = if fy { 1 - dy } else { dy };
                        id(i + dx, j + dy, k + dz)
                    };
                    let v = [
                        corner(0, 0, 0),
                        corner(1, 0, 0),
                        corner(1, 1, 0),
                        corner(0, 1, 0),
                        corner(0, 0, 1),
                        corner(1, 0, 1),
                        corner(1, 1, 1),
                        corner(0, 1, 1),
                    ];
                    for t in HEX_TETS {
                        let mut tet = t.map(|x| v[x]);
                        let vol = tet_volume(tet.map(|x| nodes[x]));
                        if vol < 0.0 {
                            tet.swap(0, 1);
                        }
                        if vol.abs() <= 1e-9 * a * b * c / (n * n * n) as f64 {
                            return Err(TissueError::Compression {
                                gap_mm: 2.0 * b,
                                reason: format!("the mapped mesh has a flat tetrahedron in cell ({i}, {j}, {k})"),
                            });
                        }
                        tets.push(tet);
                    }
                }
            }
        }
        Ok(BodyMesh {
            nodes_mm: nodes,
            tets,
        })
    }
}

/// A tetrahedral body mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct BodyMesh {
    /// Node positions (mm).
    pub nodes_mm: Vec<[f64; 3]>,
    /// Tetrahedra, positively oriented.
    pub tets: Vec<[usize; 4]>,
}

impl BodyMesh {
    /// Total volume (mm³).
    pub fn volume_mm3(&self) -> f64 {
        self.tets
            .iter()
            .map(|t| tet_volume(t.map(|i| self.nodes_mm[i])))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_phantom_holds_286_markers_inside() {
        let body = SemiEllipsoid::phantom();
        let m = body.markers();
        assert_eq!(m.len(), PHANTOM_MARKERS);
        assert!(m.iter().all(|p| body.contains(*p)));
        // The mid-plane y = 0 holds a layer of them (for the A2 check).
        assert!(m.iter().filter(|p| p[1] == 0.0).count() > 40);
    }

    #[test]
    fn the_mesh_fills_the_semi_ellipsoid() {
        let body = SemiEllipsoid::phantom();
        let coarse = body.mesh(4).unwrap().volume_mm3();
        let fine = body.mesh(10).unwrap().volume_mm3();
        let exact = body.volume_mm3();
        // Inscribed polyhedra: below the exact volume, closer when finer.
        assert!(coarse < fine && fine < exact, "{coarse} {fine} {exact}");
        assert!((exact - fine) / exact < 0.03, "{fine} vs {exact}");
        let mesh = body.mesh(6).unwrap();
        assert!(mesh
            .nodes_mm
            .iter()
            .all(|p| p[2] >= 0.0 && body.contains(p.map(|v| v * 0.999_999))));
    }
}
