//! The phantom experiment of Kita §IV on the twin: the 286 markers
//! compressed to 100 and 80 mm by the FEM model and by the geometric
//! model, the facts the paper observed (Fig. 8, L2456–2470) and the
//! geometric model's marker error against the FEM.
//!
//! Markers are carried by the FEM through the shape functions of the
//! tetrahedron holding them (Zhang's Eq. 9–11, [`shape_functions`]). A
//! marker is "under the plates" when its chord along y is wider than the
//! gap (the plates press that column directly — the paper's X = 60–100);
//! the others are "outer".
use super::super::model::geometric::compress_point;
use super::super::model::phantom::{BodyMesh, SemiEllipsoid, MARKER_SPACING_MM};
use super::super::model::plates::{compress, volume_ratios, PlateSchedule, PlateState};
use crate::error::{check_range, Result, TissueError};
use crate::field::model::shape::shape_functions;
use plant_common::fem::LinearElastic;
use serde::{Deserialize, Serialize};

/// A compression experiment (a TOML scenario of `softjoint tissue compress`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CompressionSpec {
    /// Semi-axes (mm) along x (chest wall), y (compression), z (height);
    /// the paper's phantom is 130 × 110 × 70 mm (L2456).
    pub semi_axes_mm: [f64; 3],
    /// Plate gaps (mm), decreasing (L2456: 100 and 80).
    pub gaps_mm: Vec<f64>,
    /// Plate travel per increment, each plate (mm).
    pub step_mm: f64,
    /// Mesh cells per unit of the mapped box (2n along x and y, n along z).
    pub mesh_divisions: usize,
    /// Young's modulus (Pa) of the gel: estimate (soft silicone/skin gel,
    /// 10–50 kPa). The displacements of a displacement-driven linear body
    /// do not depend on it; the plate force does.
    pub youngs_modulus_pa: f64,
    /// Poisson's ratio: estimate (a gel is nearly incompressible; linear
    /// tetrahedra lock as ν → 0.5, so 0.45).
    pub poisson_ratio: f64,
}

impl Default for CompressionSpec {
    fn default() -> Self {
        CompressionSpec {
            semi_axes_mm: [65.0, 55.0, 70.0],
            gaps_mm: vec![100.0, 80.0],
            step_mm: 1.0,
            mesh_divisions: 6,
            youngs_modulus_pa: 2.0e4,
            poisson_ratio: 0.45,
        }
    }
}

/// What happened at one plate gap.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageReport {
    /// Plate gap (mm).
    pub gap_mm: f64,
    /// Plate increments from the start.
    pub increments: usize,
    /// Mesh nodes stuck to the plates.
    pub contact_nodes: usize,
    /// Force on one plate (N), from the FEM.
    pub plate_force_n: f64,
    /// Markers under the plates.
    pub markers_pressed: usize,
    /// Markers outside the pressed columns.
    pub markers_outer: usize,
    /// Largest |u_y| of the mid-plane markers (mm), FEM: A2 in y.
    pub midplane_max_abs_uy_mm: f64,
    /// Mean |u_x| of the mid-plane markers (mm), FEM: A2 in x.
    pub midplane_mean_abs_ux_mm: f64,
    /// Mean |u_z| of the mid-plane markers (mm), FEM: A2 in z.
    pub midplane_mean_abs_uz_mm: f64,
    /// Mean |u_y| and |u_x| of the pressed markers off the mid-plane (mm).
    pub pressed_mean_abs_uy_mm: f64,
    /// See `pressed_mean_abs_uy_mm`.
    pub pressed_mean_abs_ux_mm: f64,
    /// Mean |u_x| and |u_y| of the outer markers off the mid-plane (mm).
    pub outer_mean_abs_ux_mm: f64,
    /// See `outer_mean_abs_ux_mm`.
    pub outer_mean_abs_uy_mm: f64,
    /// Fraction of pressed markers (off the mid-plane) moving more in y than x.
    pub pressed_y_dominant: f64,
    /// Fraction of outer markers (off the mid-plane) moving more in x than y.
    pub outer_x_dominant: f64,
    /// Mean volume ratio J of the elements under the plates (FEM).
    pub volume_ratio_pressed: f64,
    /// Mean volume ratio J of the other elements (FEM).
    pub volume_ratio_outer: f64,
    /// Geometric model vs FEM, over all markers (mm): mean, RMS, max.
    pub geometric_error_mean_mm: f64,
    /// See `geometric_error_mean_mm`.
    pub geometric_error_rms_mm: f64,
    /// See `geometric_error_mean_mm`.
    pub geometric_error_max_mm: f64,
    /// Mean geometric-model error of the pressed and the outer markers (mm).
    pub geometric_error_pressed_mean_mm: f64,
    /// See `geometric_error_pressed_mean_mm`.
    pub geometric_error_outer_mean_mm: f64,
}

/// The whole experiment.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CompressionReport {
    /// Markers (286 in the paper's phantom).
    pub markers: usize,
    /// Mesh nodes.
    pub nodes: usize,
    /// Mesh tetrahedra.
    pub tetrahedra: usize,
    /// One report per gap.
    pub stages: Vec<StageReport>,
}

/// Marker positions at one gap.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerStage {
    /// Plate gap (mm).
    pub gap_mm: f64,
    /// Where the FEM puts each marker (mm).
    pub fem_mm: Vec<[f64; 3]>,
    /// Where the geometric model puts each marker (mm).
    pub geometric_mm: Vec<[f64; 3]>,
    /// Whether each marker is under the plates.
    pub pressed: Vec<bool>,
}

/// Everything a run produces.
#[derive(Clone, Debug, PartialEq)]
pub struct CompressionOutcome {
    /// The body.
    pub body: SemiEllipsoid,
    /// The undeformed mesh.
    pub mesh: BodyMesh,
    /// FEM node positions at each gap (mm).
    pub node_states_mm: Vec<Vec<[f64; 3]>>,
    /// Initial marker positions (mm).
    pub markers_mm: Vec<[f64; 3]>,
    /// Marker positions at each gap.
    pub stages: Vec<MarkerStage>,
    /// The summary.
    pub report: CompressionReport,
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 {
        f64::NAN
    } else {
        s / n as f64
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// Runs the experiment: the body, its markers, the FEM at every gap and
/// the geometric model, and the facts.
pub fn run(spec: &CompressionSpec) -> Result<CompressionOutcome> {
    let body = SemiEllipsoid {
        semi_axes_mm: spec.semi_axes_mm,
    };
    body.validate()?;
    check_range(
        "youngs_modulus_pa",
        spec.youngs_modulus_pa,
        1.0,
        1e12,
        "must be 1 Pa to 1 TPa",
    )?;
    let mesh = body.mesh(spec.mesh_divisions)?;
    let markers = body.markers();
    let located = locate_markers(&body, &mesh, &markers)?;
    let material = LinearElastic {
        youngs_modulus_pa: spec.youngs_modulus_pa,
        poisson_ratio: spec.poisson_ratio,
    };
    let schedule = PlateSchedule {
        step_mm: spec.step_mm,
        ..PlateSchedule::default()
    };
    let plates = compress(&body, &mesh, material, &spec.gaps_mm, &schedule)?;
    let mut stages = Vec::new();
    let mut reports = Vec::new();
    for state in &plates.states {
        let stage = marker_stage(&body, &mesh, &markers, &located, state);
        reports.push(stage_report(&body, &mesh, &markers, state, &stage));
        stages.push(stage);
    }
    Ok(CompressionOutcome {
        body,
        node_states_mm: plates.states.iter().map(|s| s.nodes_mm.clone()).collect(),
        report: CompressionReport {
            markers: markers.len(),
            nodes: mesh.nodes_mm.len(),
            tetrahedra: mesh.tets.len(),
            stages: reports,
        },
        mesh,
        markers_mm: markers,
        stages,
    })
}

/// Each marker's tetrahedron and shape functions in the initial mesh.
fn locate_markers(
    body: &SemiEllipsoid,
    mesh: &BodyMesh,
    markers: &[[f64; 3]],
) -> Result<Vec<(usize, [f64; 4])>> {
    markers
        .iter()
        .enumerate()
        .map(|(k, m)| {
            mesh.tets
                .iter()
                .enumerate()
                .find_map(|(t, tet)| {
                    let n = shape_functions(tet.map(|i| mesh.nodes_mm[i]), *m)?;
                    n.iter().all(|&w| w >= -1e-9).then_some((t, n))
                })
                .ok_or_else(|| TissueError::Compression {
                    gap_mm: 2.0 * body.semi_axes_mm[1],
                    reason: format!(
                        "marker {k} at {m:?} mm lies outside the mesh: use more mesh_divisions"
                    ),
                })
        })
        .collect()
}

/// Where the FEM (through the `located` shape functions) and the
/// geometric model put each marker at `state`'s gap, and which markers
/// are under the plates.
fn marker_stage(
    body: &SemiEllipsoid,
    mesh: &BodyMesh,
    markers: &[[f64; 3]],
    located: &[(usize, [f64; 4])],
    state: &PlateState,
) -> MarkerStage {
    let h = 0.5 * state.gap_mm;
    let fem: Vec<[f64; 3]> = located
        .iter()
        .map(|(t, n)| {
            let tet = mesh.tets[*t];
            std::array::from_fn(|a| (0..4).map(|k| n[k] * state.nodes_mm[tet[k]][a]).sum())
        })
        .collect();
    let geo: Vec<[f64; 3]> = markers
        .iter()
        .map(|m| compress_point(body, *m, h))
        .collect();
    let pressed: Vec<bool> = markers
        .iter()
        .map(|m| body.chord_half_width_mm(m[0], m[2]) > h)
        .collect();
    MarkerStage {
        gap_mm: state.gap_mm,
        fem_mm: fem,
        geometric_mm: geo,
        pressed,
    }
}

/// The facts of one gap: the paper's observations on the FEM markers
/// (mid-plane, pressed vs outer, volume ratios) and the geometric model's
/// error against the FEM.
fn stage_report(
    body: &SemiEllipsoid,
    mesh: &BodyMesh,
    markers: &[[f64; 3]],
    state: &PlateState,
    stage: &MarkerStage,
) -> StageReport {
    let (fem, geo, pressed) = (&stage.fem_mm, &stage.geometric_mm, &stage.pressed);
    let u: Vec<[f64; 3]> = fem
        .iter()
        .zip(markers)
        .map(|(f, m)| [f[0] - m[0], f[1] - m[1], f[2] - m[2]])
        .collect();
    let mid = |k: usize| markers[k][1].abs() < 0.5 * MARKER_SPACING_MM;
    let all = 0..markers.len();
    let midplane: Vec<usize> = all.clone().filter(|&k| markers[k][1] == 0.0).collect();
    let off_p: Vec<usize> = all.clone().filter(|&k| pressed[k] && !mid(k)).collect();
    let off_o: Vec<usize> = all.clone().filter(|&k| !pressed[k] && !mid(k)).collect();
    let frac = |set: &[usize], f: &dyn Fn(usize) -> bool| {
        set.iter().filter(|&&k| f(k)).count() as f64 / set.len().max(1) as f64
    };
    let (volume_ratio_pressed, volume_ratio_outer) = volume_ratio_means(body, mesh, state);
    let err: Vec<f64> = fem.iter().zip(geo).map(|(f, g)| dist(*f, *g)).collect();
    let err_where = |want: bool| {
        mean(
            err.iter()
                .zip(pressed)
                .filter(|(_, p)| **p == want)
                .map(|(e, _)| *e),
        )
    };
    StageReport {
        gap_mm: state.gap_mm,
        increments: state.increments,
        contact_nodes: state.in_contact.iter().filter(|c| **c).count(),
        plate_force_n: state.plate_force_n,
        markers_pressed: pressed.iter().filter(|p| **p).count(),
        markers_outer: pressed.iter().filter(|p| !**p).count(),
        midplane_max_abs_uy_mm: midplane.iter().map(|&k| u[k][1].abs()).fold(0.0, f64::max),
        midplane_mean_abs_ux_mm: mean(midplane.iter().map(|&k| u[k][0].abs())),
        midplane_mean_abs_uz_mm: mean(midplane.iter().map(|&k| u[k][2].abs())),
        pressed_mean_abs_uy_mm: mean(off_p.iter().map(|&k| u[k][1].abs())),
        pressed_mean_abs_ux_mm: mean(off_p.iter().map(|&k| u[k][0].abs())),
        outer_mean_abs_ux_mm: mean(off_o.iter().map(|&k| u[k][0].abs())),
        outer_mean_abs_uy_mm: mean(off_o.iter().map(|&k| u[k][1].abs())),
        pressed_y_dominant: frac(&off_p, &|k| u[k][1].abs() > u[k][0].abs()),
        outer_x_dominant: frac(&off_o, &|k| u[k][0].abs() > u[k][1].abs()),
        volume_ratio_pressed,
        volume_ratio_outer,
        geometric_error_mean_mm: mean(err.iter().copied()),
        geometric_error_rms_mm: mean(err.iter().map(|e| e * e)).sqrt(),
        geometric_error_max_mm: err.iter().copied().fold(0.0, f64::max),
        geometric_error_pressed_mean_mm: err_where(true),
        geometric_error_outer_mean_mm: err_where(false),
    }
}

/// Mean volume ratio J of the elements under the plates and of the
/// others at `state` (an element is under the plates when the chord
/// through its initial centroid is wider than the gap).
fn volume_ratio_means(body: &SemiEllipsoid, mesh: &BodyMesh, state: &PlateState) -> (f64, f64) {
    let h = 0.5 * state.gap_mm;
    let centroid = |t: &[usize; 4]| -> [f64; 3] {
        std::array::from_fn(|a| t.iter().map(|&i| mesh.nodes_mm[i][a]).sum::<f64>() / 4.0)
    };
    let j = volume_ratios(mesh, state);
    let tet_pressed: Vec<bool> = mesh
        .tets
        .iter()
        .map(|t| {
            let c = centroid(t);
            body.chord_half_width_mm(c[0], c[2]) > h
        })
        .collect();
    let mean_where = |want: bool| {
        mean(
            j.iter()
                .zip(&tet_pressed)
                .filter(|(_, p)| **p == want)
                .map(|(v, _)| *v),
        )
    };
    (mean_where(true), mean_where(false))
}
