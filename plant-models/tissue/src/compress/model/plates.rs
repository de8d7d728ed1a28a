//! The finite-element model of the compression: the body between two
//! rigid plates that move towards each other, displacement-controlled, the
//! chest wall (the flat base z = 0) fixed in z only (Kita §III, L2439).
//!
//! What is modelled: the shared linear-elastic tetrahedral FEM
//! ([`plant_common::fem`]) stepped in small plate increments on the current
//! geometry (an updated-Lagrangian sequence of small-strain problems), so
//! the 27 % compression to 80 mm is followed as large deformation.
//! Contact is sticking: a node that reaches a plate is put on it and then
//! moves with it (y follows the plate, x and z stay) — Kita's "Dirichlet
//! boundary conditions applied to the nodes touched to the plates". Within
//! an increment, nodes that end up beyond a plate join the contact set and
//! the increment is solved again (an active-set loop).
//!
//! Instability is detected by name: an element that turns inside out
//! stops the run with an error naming the gap, never a NaN.
//!
//! Left out: the stress carried from one increment to the next (no
//! geometric stiffness: each increment is a small-strain problem on the
//! current shape, a hypoelastic approximation), sliding contact, friction
//! laws, gravity, hyperelastic gel behaviour, self-contact.
use super::phantom::{BodyMesh, SemiEllipsoid};
use crate::error::{check_range, Result, TissueError};
use plant_common::fem::{element_stiffness, tet_volume, ElasticSystem, LinearElastic};

/// How the compression is stepped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlateSchedule {
    /// Plate travel per increment (mm, each plate).
    pub step_mm: f64,
    /// Most active-set passes per increment.
    pub max_contact_passes: usize,
}

impl Default for PlateSchedule {
    /// 1 mm per plate per increment (a discretisation choice: a finer mesh
    /// with half the step moves the geometric model's mean marker error by
    /// 0.1 mm at 80 mm, README).
    fn default() -> Self {
        PlateSchedule {
            step_mm: 1.0,
            max_contact_passes: 10,
        }
    }
}

/// The body at one plate gap.
#[derive(Clone, Debug, PartialEq)]
pub struct PlateState {
    /// Distance between the plates (mm).
    pub gap_mm: f64,
    /// Node positions (mm).
    pub nodes_mm: Vec<[f64; 3]>,
    /// Nodes stuck to a plate.
    pub in_contact: Vec<bool>,
    /// Force on one plate (N, accumulated over the increments).
    pub plate_force_n: f64,
    /// Increments taken from the start.
    pub increments: usize,
}

/// The compression run: the mesh and its states at the requested gaps.
#[derive(Clone, Debug, PartialEq)]
pub struct PlateRun {
    /// The undeformed mesh.
    pub mesh: BodyMesh,
    /// One state per requested gap, in order.
    pub states: Vec<PlateState>,
}

/// Compresses `mesh` of `body` between plates to each gap of `gaps_mm`
/// (decreasing, each below the body's width 2b).
pub fn compress(
    body: &SemiEllipsoid,
    mesh: &BodyMesh,
    material: LinearElastic,
    gaps_mm: &[f64],
    schedule: &PlateSchedule,
) -> Result<PlateRun> {
    check_inputs(body, material, gaps_mm, schedule)?;
    let n = mesh.nodes_mm.len();
    let scale = body.semi_axes_mm.iter().copied().fold(0.0, f64::max);
    let step = Increment {
        mesh,
        material,
        on_base: mesh
            .nodes_mm
            .iter()
            .map(|p| p[2].abs() <= 1e-9 * scale)
            .collect(),
        scale,
        max_contact_passes: schedule.max_contact_passes,
    };
    let mut x = mesh.nodes_mm.clone();
    let mut contact = vec![false; n];
    let mut half = body.semi_axes_mm[1];
    let mut force = 0.0;
    let mut increments = 0;
    let mut states = Vec::new();
    let initial_vol: Vec<f64> = mesh
        .tets
        .iter()
        .map(|t| tet_volume(t.map(|i| mesh.nodes_mm[i])))
        .collect();
    for &gap in gaps_mm {
        let target = 0.5 * gap;
        while half > target + 1e-12 {
            let new_half = (half - schedule.step_mm).max(target);
            let du = step.solve(&x, &mut contact, new_half)?;
            force += plate_force(mesh, &x, &du, &contact, material);
            for i in 0..n {
                for c in 0..3 {
                    x[i][c] += du[i][c];
                }
            }
            check_shape(mesh, &x, &initial_vol, new_half)?;
            half = new_half;
            increments += 1;
        }
        states.push(PlateState {
            gap_mm: gap,
            nodes_mm: x.clone(),
            in_contact: contact.clone(),
            plate_force_n: force,
            increments,
        });
    }
    Ok(PlateRun {
        mesh: mesh.clone(),
        states,
    })
}

/// Refuses a material, step or gap sequence the run cannot follow.
fn check_inputs(
    body: &SemiEllipsoid,
    material: LinearElastic,
    gaps_mm: &[f64],
    schedule: &PlateSchedule,
) -> Result<()> {
    material.validate()?;
    check_range(
        "step_mm",
        schedule.step_mm,
        1e-3,
        50.0,
        "must be 0.001 to 50 mm",
    )?;
    let width = 2.0 * body.semi_axes_mm[1];
    let mut last = width;
    for &g in gaps_mm {
        check_range(
            "gaps_mm",
            g,
            0.05 * width,
            width,
            "each gap must be below the body's width and above 5 % of it",
        )?;
        if g >= last && last < width {
            return Err(TissueError::InvalidParameter {
                name: "gaps_mm",
                value: g,
                reason: "gaps must decrease",
            });
        }
        last = g;
    }
    Ok(())
}

/// One plate increment: the FEM on the current shape with the contact
/// nodes on the plates and the chest wall fixed in z, repeated while the
/// contact set grows (the active-set loop).
struct Increment<'a> {
    mesh: &'a BodyMesh,
    material: LinearElastic,
    /// Nodes on the chest wall (z = 0), fixed in z.
    on_base: Vec<bool>,
    /// The body's largest semi-axis (mm), the scale of the tolerances.
    scale: f64,
    max_contact_passes: usize,
}

impl Increment<'_> {
    /// The displacement (mm) of every node from `x` (mm) when the plates
    /// move to ±`new_half`; `contact` grows by the nodes that reach them.
    fn solve(&self, x: &[[f64; 3]], contact: &mut [bool], new_half: f64) -> Result<Vec<[f64; 3]>> {
        let n = x.len();
        for _pass in 0..self.max_contact_passes {
            for i in 0..n {
                if !contact[i] && x[i][1].abs() > new_half {
                    contact[i] = true;
                }
            }
            let du = self.solve_with_contact(x, contact, new_half)?;
            // Nodes the increment pushes beyond a plate join the contact.
            let mut added = false;
            for i in 0..n {
                if !contact[i] && (x[i][1] + du[i][1]).abs() > new_half + 1e-9 * self.scale {
                    contact[i] = true;
                    added = true;
                }
            }
            if !added {
                return Ok(du);
            }
        }
        Err(TissueError::Compression {
            gap_mm: 2.0 * new_half,
            reason: format!(
                "the contact set did not settle in {} passes; use a smaller step_mm",
                self.max_contact_passes
            ),
        })
    }

    /// The FEM solve for a fixed contact set: contact nodes move to their
    /// plate in y and stay in x and z, chest-wall nodes stay in z.
    fn solve_with_contact(
        &self,
        x: &[[f64; 3]],
        contact: &[bool],
        new_half: f64,
    ) -> Result<Vec<[f64; 3]>> {
        let n = x.len();
        let mut prescribed = vec![false; 3 * n];
        let mut values = vec![0.0; 3 * n];
        for i in 0..n {
            if contact[i] {
                let side = x[i][1].signum();
                prescribed[3 * i..3 * i + 3].fill(true);
                values[3 * i + 1] = side * new_half - x[i][1];
            }
            if self.on_base[i] {
                prescribed[3 * i + 2] = true;
            }
        }
        let sys =
            ElasticSystem::new(x, &self.mesh.tets, self.material, &prescribed).map_err(|e| {
                TissueError::Compression {
                    gap_mm: 2.0 * new_half,
                    reason: format!("the stiffness could not be factored ({e})"),
                }
            })?;
        Ok(sys.solve(&[], &values)?)
    }
}

/// Stops the run, naming the gap, when a node position is no longer
/// finite or an element turned inside out (volume ≤ 1e-6 of its initial).
fn check_shape(mesh: &BodyMesh, x: &[[f64; 3]], initial_vol: &[f64], new_half: f64) -> Result<()> {
    if let Some(v) = x.iter().flatten().find(|v| !v.is_finite()) {
        return Err(TissueError::Compression {
            gap_mm: 2.0 * new_half,
            reason: format!("a node position became {v}"),
        });
    }
    if let Some(k) = mesh
        .tets
        .iter()
        .zip(initial_vol)
        .position(|(t, v0)| tet_volume(t.map(|i| x[i])) <= 1e-6 * v0)
    {
        return Err(TissueError::Compression {
            gap_mm: 2.0 * new_half,
            reason: format!(
                "tetrahedron {k} turned inside out: use a finer mesh or a smaller step_mm"
            ),
        });
    }
    Ok(())
}

/// The force (N) the increment `du` (mm) adds on the upper plate (y > 0),
/// from the element forces `K_e du_e` on the current shape (E in Pa, so
/// lengths go to metres).
fn plate_force(
    mesh: &BodyMesh,
    x_mm: &[[f64; 3]],
    du_mm: &[[f64; 3]],
    contact: &[bool],
    material: LinearElastic,
) -> f64 {
    let d = material.d_matrix();
    let mut f = 0.0;
    for t in &mesh.tets {
        if !t.iter().any(|&i| contact[i] && x_mm[i][1] > 0.0) {
            continue;
        }
        let p = t.map(|i| x_mm[i].map(|v| v * 1e-3));
        let Some(ke) = element_stiffness(p, &d) else {
            continue;
        };
        let u = nalgebra::SVector::<f64, 12>::from_fn(|r, _| du_mm[t[r / 3]][r % 3] * 1e-3);
        let fe = ke * u;
        for (a, &i) in t.iter().enumerate() {
            if contact[i] && x_mm[i][1] > 0.0 {
                // The plate pushes the body towards −y: the reaction is the
                // body's internal force on the node, towards +y on the plate.
                f -= fe[3 * a + 1];
            }
        }
    }
    f
}

/// Element volume ratio J = V / V₀ of every tetrahedron in `state`.
pub fn volume_ratios(mesh: &BodyMesh, state: &PlateState) -> Vec<f64> {
    mesh.tets
        .iter()
        .map(|t| tet_volume(t.map(|i| state.nodes_mm[i])) / tet_volume(t.map(|i| mesh.nodes_mm[i])))
        .collect()
}
