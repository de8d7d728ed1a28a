//! The Voigt mass-spring-damper network on a tetrahedral mesh (Yamaguchi
//! Eq. 1–2, seed 000 L2594–2603).
//!
//! Every mesh edge `ij` is a Voigt element, a spring `k` parallel to a
//! damper `c` (Fig. 3; "a tetrahedron consists of the six elements"). With
//! `l_ij` the current and `L_ij` the rest length and `e_ij` the unit vector
//! from `j` to `i`, the force on node `i` is (Eq. 1)
//! `F_i = −Σ_j (k(l_ij − L_ij) + c·l̇_ij) e_ij`, and every node moves by
//! `M_i P̈_i = F_i + F_i^ext` (Eq. 2). Eq. 1 prints `c·l_ij`; the damper
//! acts on the rate `l̇_ij = e_ij·(v_i − v_j)`, which is what a Voigt
//! element is (Fig. 3), so the code uses `l̇`.
//!
//! Choices the seed leaves open (stated here, estimates in
//! [`VoigtMaterial`]):
//! * **Element constants from moduli.** The seed sets "visco-elastic
//!   parameters, elastic parameters and initial length" per edge (L2631)
//!   without values. Here `k_e = κ·V_e/L_e²` and `c_e = η·V_e/L_e²`, with
//!   `V_e` the volume of the tetrahedra sharing the edge: the usual scaling
//!   that makes the network's stiffness independent of the refinement
//!   level (a lattice of such springs has an elasticity tensor
//!   proportional to κ at every level). The ratio `c_e/k_e = η/κ` is the
//!   same for every element (stiffness-proportional damping).
//! * **Masses** are lumped: a quarter of each adjacent tetrahedron's mass.
//! * **Support.** The cube rests on its bottom face `z = 0`, whose nodes
//!   are held fixed. No gravity (the rest shape is the supported shape).
//! * **Integration** is semi-implicit (symplectic) Euler at a fixed step:
//!   `v += h·F/M`, then `x += h·v`, deterministic and in a fixed order, so
//!   two replicas fed the same inputs stay bit-identical. One replica step
//!   is one 1 kHz haptic tick ([`TICK_S`]), split into as many equal
//!   substeps as stability needs (see [`VoigtModel::substeps`]).
//! * **Manipulation.** A user's held node ([`Hold`]) moves linearly from
//!   its position at the start of the tick to the held position over the
//!   substeps, with the matching velocity, as the seed's "deformation by
//!   manipulation" sets a node to the position in the packet. It moves at
//!   most [`MAX_HOLD_SPEED_M_S`] · 1 ms per tick towards the target: a
//!   stylus never moves that fast, but a target can jump (two users hold
//!   the same node and one lets go; a peer's packet after a gap), and an
//!   unbounded jump would fling the node. When both users hold one node,
//!   site 1's hold wins (holds apply in site order).
//!
//! Instability (a non-finite or runaway node, a collapsed edge) is reported
//! as [`TetError::Unstable`] with the tick, never as silent NaN.
use super::mesh::CubeMesh;
use super::{c3, c3_mut, V3};
use crate::error::{check_positive, check_range, Result, TetError};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// One replica step: a 1 kHz haptic tick (seed L2667: "the update rate of
/// the haptic thread is 1000 Hz").
pub const TICK_S: f64 = 1e-3;

/// Fraction of the explicit stability limit (in ω²) used by the substep
/// size: room for the stiffening of stretched springs (up to k(1 − L/l)
/// across them) and for the error of the estimated largest frequency.
const STABILITY_SAFETY: f64 = 0.5;

/// Fastest a held node moves towards its target (m/s). Estimate: hand
/// motions with a desktop stylus stay well below 0.5 m/s (a brisk stroke
/// across a 6 cm object in 0.2 s is 0.3 m/s).
pub const MAX_HOLD_SPEED_M_S: f64 = 0.5;

/// Power iterations of the stability estimate.
const POWER_ITERATIONS: u32 = 150;

/// A node further than this many cube sides from its rest position means
/// the integration has blown up.
const RUNAWAY_SIDES: f64 = 10.0;

/// Material constants of the network. The seed gives none: every default is
/// an estimate, stated with its reasoning.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VoigtMaterial {
    /// κ (Pa): element stiffness `k_e = κ·V_e/L_e²`. Estimate: 20 kPa gives
    /// the cube an effective modulus of soft tissue (1–30 kPa), the kind
    /// of object the seed's needle insertion touches.
    pub stiffness_modulus_pa: f64,
    /// η (Pa·s): element damping `c_e = η·V_e/L_e²`. Estimate: 30 Pa·s
    /// damps the cube's slowest mode (≈ 25 Hz) at a ratio near 0.1, so a
    /// release rings for a few periods, as a soft block does.
    pub damping_modulus_pa_s: f64,
    /// Density (kg/m³). Estimate: 1000, water-like soft tissue.
    pub density_kg_m3: f64,
}

impl Default for VoigtMaterial {
    fn default() -> Self {
        VoigtMaterial {
            stiffness_modulus_pa: 20e3,
            damping_modulus_pa_s: 30.0,
            density_kg_m3: 1000.0,
        }
    }
}

impl VoigtMaterial {
    /// Checks every constant (named in the error).
    pub fn validate(&self) -> Result<()> {
        check_positive("stiffness_modulus_pa", self.stiffness_modulus_pa)?;
        check_range(
            "damping_modulus_pa_s",
            self.damping_modulus_pa_s,
            0.0,
            f64::MAX,
            "must be finite and >= 0",
        )?;
        check_positive("density_kg_m3", self.density_kg_m3)?;
        Ok(())
    }
}

/// One element's ends and constants, packed.
#[derive(Clone, Copy, Debug)]
struct Packed {
    i: u32,
    j: u32,
    rest_m: f64,
    k_n_per_m: f64,
    c_n_s_per_m: f64,
}

/// A node held at a position for one tick (a user's manipulation).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hold {
    /// The held node.
    pub node: u32,
    /// Where it is at the end of the tick (m).
    pub target_m: V3,
}

/// Positions and velocities of every node after `tick` steps.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Ticks computed since the rest state.
    pub tick: u64,
    /// Node positions (m).
    pub x_m: Vec<V3>,
    /// Node velocities (m/s).
    pub v_m_s: Vec<V3>,
}

impl State {
    /// FNV-1a hash of the exact bits of every position and velocity and of
    /// the tick: equal hashes for bit-identical replicas.
    pub fn bit_hash(&self) -> u64 {
        let mut h: u64 = 0xcbf2_9ce4_8422_2325;
        let mut eat = |w: u64| {
            for b in w.to_le_bytes() {
                h ^= u64::from(b);
                h = h.wrapping_mul(0x0000_0100_0000_01b3);
            }
        };
        eat(self.tick);
        for p in self.x_m.iter().chain(&self.v_m_s) {
            for c in p.iter() {
                eat(c.to_bits());
            }
        }
        h
    }

    /// Largest distance between corresponding nodes of two states (m).
    pub fn max_distance_m(&self, other: &State) -> f64 {
        self.x_m
            .iter()
            .zip(&other.x_m)
            .map(|(a, b)| (a - b).norm())
            .fold(0.0, f64::max)
    }
}

/// Energies of a state (J).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Energy {
    /// Σ ½ M v².
    pub kinetic_j: f64,
    /// Σ ½ k (l − L)².
    pub elastic_j: f64,
}

/// The Voigt network of a mesh: topology, element constants, masses,
/// support and the integration step.
#[derive(Clone, Debug)]
pub struct VoigtModel {
    mesh: CubeMesh,
    material: VoigtMaterial,
    rest_length_m: Vec<f64>,
    stiffness_n_per_m: Vec<f64>,
    damping_n_s_per_m: Vec<f64>,
    /// The same per-element data packed for the hot loop (one 32-byte
    /// record per element instead of four arrays).
    packed: Vec<Packed>,
    mass_kg: Vec<f64>,
    /// 1/M for free nodes, 0 for fixed ones.
    inverse_mass: Vec<f64>,
    fixed: Vec<bool>,
    /// Incident edges of every node (CSR: `node_edges[node_start[i]..node_start[i+1]]`).
    node_start: Vec<usize>,
    node_edges: Vec<u32>,
    substeps: u32,
}

impl VoigtModel {
    /// The network of `mesh` with `material`, its bottom face held fixed.
    pub fn new(mesh: CubeMesh, material: VoigtMaterial) -> Result<Self> {
        let fixed = mesh.bottom_nodes();
        Self::with_fixed(mesh, material, fixed)
    }

    /// The network with the nodes flagged in `fixed` held in place (none:
    /// a free body).
    pub fn with_fixed(mesh: CubeMesh, material: VoigtMaterial, fixed: Vec<bool>) -> Result<Self> {
        material.validate()?;
        if fixed.len() != mesh.node_count() {
            return Err(TetError::InvalidParameter {
                name: "fixed",
                value: fixed.len() as f64,
                reason: "needs one flag per node",
            });
        }
        let volume = mesh.edge_volumes_m3();
        let rest_length_m: Vec<f64> = mesh
            .edges
            .iter()
            .map(|e| (mesh.nodes_m[e[0] as usize] - mesh.nodes_m[e[1] as usize]).norm())
            .collect();
        let per_length2: Vec<f64> = volume
            .iter()
            .zip(&rest_length_m)
            .map(|(v, l)| v / (l * l))
            .collect();
        let stiffness_n_per_m: Vec<f64> = per_length2
            .iter()
            .map(|g| material.stiffness_modulus_pa * g)
            .collect();
        let damping_n_s_per_m: Vec<f64> = per_length2
            .iter()
            .map(|g| material.damping_modulus_pa_s * g)
            .collect();
        let mass_kg = mesh.lumped_masses_kg(material.density_kg_m3);
        let inverse_mass = mass_kg
            .iter()
            .zip(&fixed)
            .map(|(m, &f)| if f { 0.0 } else { 1.0 / m })
            .collect();
        let n = mesh.node_count();
        let mut degree = vec![0usize; n];
        for e in &mesh.edges {
            degree[e[0] as usize] += 1;
            degree[e[1] as usize] += 1;
        }
        let mut node_start = vec![0usize; n + 1];
        for i in 0..n {
            node_start[i + 1] = node_start[i] + degree[i];
        }
        let mut fill = node_start.clone();
        let mut node_edges = vec![0u32; node_start[n]];
        for (k, e) in mesh.edges.iter().enumerate() {
            for &i in e {
                node_edges[fill[i as usize]] = k as u32;
                fill[i as usize] += 1;
            }
        }
        let packed = mesh
            .edges
            .iter()
            .enumerate()
            .map(|(e, edge)| Packed {
                i: edge[0],
                j: edge[1],
                rest_m: rest_length_m[e],
                k_n_per_m: stiffness_n_per_m[e],
                c_n_s_per_m: damping_n_s_per_m[e],
            })
            .collect();
        let mut model = VoigtModel {
            mesh,
            material,
            packed,
            rest_length_m,
            stiffness_n_per_m,
            damping_n_s_per_m,
            mass_kg,
            inverse_mass,
            fixed,
            node_start,
            node_edges,
            substeps: 1,
        };
        model.substeps = model.stable_substeps();
        Ok(model)
    }

    /// Substeps per tick for stability. For one mode of angular frequency
    /// ω under stiffness-proportional damping (`c/k = τ = η/κ`), symplectic
    /// Euler with step h is stable iff `ω²(h² + 2hτ) < 4`. The largest ω²
    /// of the network at rest (M⁻¹K) is estimated by power iteration
    /// ([`POWER_ITERATIONS`] matrix-free products from a fixed start, so the
    /// same on every machine), raised by 10 % because the Rayleigh quotient
    /// approaches it from below, and capped by the Gershgorin-type bound
    /// `max_i 2Σ_j k_ij / M_i` (from `xᵀKx ≤ Σ_e 2k_e(|x_i|² + |x_j|²)`),
    /// which is 3× too pessimistic on these meshes. The step is chosen at
    /// [`STABILITY_SAFETY`] of the limit, which leaves room for the
    /// stiffening of stretched springs.
    fn stable_substeps(&self) -> u32 {
        let n = self.mesh.node_count();
        let mut bound: f64 = 0.0;
        for i in 0..n {
            if self.fixed[i] {
                continue;
            }
            let k: f64 = self
                .incident(i)
                .iter()
                .map(|&e| self.stiffness_n_per_m[e as usize])
                .sum();
            bound = bound.max(2.0 * k / self.mass_kg[i]);
        }
        if bound <= 0.0 {
            return 1;
        }
        // Power iteration on M^-1/2 K M^-1/2 with K at rest: Σ_e k eeᵀ.
        let scale: Vec<f64> = (0..n)
            .map(|i| {
                if self.fixed[i] {
                    0.0
                } else {
                    1.0 / self.mass_kg[i].sqrt()
                }
            })
            .collect();
        let mut u: Vec<V3> = (0..n)
            .map(|i| V3::new(1.0, -0.7, 0.3 + (i % 7) as f64 * 0.1) * scale[i].signum())
            .collect();
        let mut ku = vec![V3::zeros(); n];
        let mut estimate = 0.0;
        for _ in 0..POWER_ITERATIONS {
            let norm = u.iter().map(|w| w.norm_squared()).sum::<f64>().sqrt();
            if norm == 0.0 {
                return 1;
            }
            u.iter_mut().for_each(|w| *w /= norm);
            ku.iter_mut().for_each(|w| *w = V3::zeros());
            for (e, edge) in self.mesh.edges.iter().enumerate() {
                let (i, j) = (edge[0] as usize, edge[1] as usize);
                let d = self.mesh.nodes_m[i] - self.mesh.nodes_m[j];
                let unit = d / d.norm();
                let f = unit
                    * (self.stiffness_n_per_m[e] * unit.dot(&(u[i] * scale[i] - u[j] * scale[j])));
                ku[i] += f * scale[i];
                ku[j] -= f * scale[j];
            }
            estimate = ku.iter().zip(&u).map(|(a, b)| a.dot(b)).sum();
            std::mem::swap(&mut u, &mut ku);
        }
        let omega2_max = (1.1 * estimate).min(bound);
        let tau = self.material.damping_modulus_pa_s / self.material.stiffness_modulus_pa;
        let h = -tau + (tau * tau + 4.0 * STABILITY_SAFETY / omega2_max).sqrt();
        ((TICK_S / h).ceil() as u32).max(1)
    }

    /// The mesh.
    pub fn mesh(&self) -> &CubeMesh {
        &self.mesh
    }

    /// The material.
    pub fn material(&self) -> &VoigtMaterial {
        &self.material
    }

    /// Substeps per 1 ms tick.
    pub fn substeps(&self) -> u32 {
        self.substeps
    }

    /// Whether node `i` is held fixed by the support.
    pub fn is_fixed(&self, i: usize) -> bool {
        self.fixed[i]
    }

    /// Node masses (kg).
    pub fn masses_kg(&self) -> &[f64] {
        &self.mass_kg
    }

    /// Element stiffnesses k_e (N/m), in mesh edge order.
    pub fn stiffness_n_per_m(&self) -> &[f64] {
        &self.stiffness_n_per_m
    }

    /// Element damping constants c_e (N·s/m), in mesh edge order.
    pub fn damping_n_s_per_m(&self) -> &[f64] {
        &self.damping_n_s_per_m
    }

    /// Rest lengths L_e (m), in mesh edge order.
    pub fn rest_length_m(&self) -> &[f64] {
        &self.rest_length_m
    }

    /// The edges that meet at node `i`.
    pub fn incident(&self, i: usize) -> &[u32] {
        &self.node_edges[self.node_start[i]..self.node_start[i + 1]]
    }

    /// The rest state (tick 0, at rest).
    pub fn rest_state(&self) -> State {
        State {
            tick: 0,
            x_m: self.mesh.nodes_m.clone(),
            v_m_s: vec![V3::zeros(); self.mesh.node_count()],
        }
    }

    /// The force of element `e` on its first node (see [`element_force`]).
    #[inline]
    fn element_force(&self, e: usize, x: &[V3], v: &[V3]) -> Option<[f64; 3]> {
        element_force(&self.packed[e], x, v)
    }

    /// Eq. 1 for every node: the internal force (N) into `out`. Returns the
    /// first collapsed edge, if any.
    pub fn internal_forces(&self, x: &[V3], v: &[V3], out: &mut [V3]) -> Option<usize> {
        out.iter_mut().for_each(|f| *c3_mut(f) = [0.0; 3]);
        for (e, p) in self.packed.iter().enumerate() {
            let Some(f) = element_force(p, x, v) else {
                return Some(e);
            };
            let a = c3_mut(&mut out[p.i as usize]);
            a[0] += f[0];
            a[1] += f[1];
            a[2] += f[2];
            let b = c3_mut(&mut out[p.j as usize]);
            b[0] -= f[0];
            b[1] -= f[1];
            b[2] -= f[2];
        }
        None
    }

    /// Eq. 1 at one node (N), from its incident elements only.
    pub fn node_force(&self, x: &[V3], v: &[V3], i: usize) -> V3 {
        let mut f = V3::zeros();
        for &e in self.incident(i) {
            if let Some(fe) = self.element_force(e as usize, x, v) {
                let fe = V3::from(fe);
                f += if self.mesh.edges[e as usize][0] as usize == i {
                    fe
                } else {
                    -fe
                };
            }
        }
        f
    }

    /// The stiffness of one element seen from its ends, `∂F_j/∂x_i` for
    /// `i ≠ j` (and minus `∂F_i/∂x_i`): `k(eeᵀ + (1 − L/l)(I − eeᵀ))`.
    pub fn element_tangent(&self, e: usize, x: &[V3]) -> Matrix3<f64> {
        let [i, j] = self.mesh.edges[e].map(|n| n as usize);
        let d = x[i] - x[j];
        let l = d.norm();
        let unit = d / l;
        let eet = unit * unit.transpose();
        (eet + (Matrix3::identity() - eet) * (1.0 - self.rest_length_m[e] / l))
            * self.stiffness_n_per_m[e]
    }

    /// The node's own stiffness `−∂F_i/∂x_i` (N/m) with every other node
    /// held: what a probe holding node `i` feels for a small extra motion.
    pub fn node_stiffness(&self, x: &[V3], i: usize) -> Matrix3<f64> {
        self.incident(i)
            .iter()
            .map(|&e| self.element_tangent(e as usize, x))
            .sum()
    }

    /// Kinetic and elastic energy of a state.
    pub fn energy(&self, s: &State) -> Energy {
        let kinetic_j = s
            .v_m_s
            .iter()
            .zip(&self.mass_kg)
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum();
        let elastic_j = self
            .mesh
            .edges
            .iter()
            .enumerate()
            .map(|(k, e)| {
                let l = (s.x_m[e[0] as usize] - s.x_m[e[1] as usize]).norm();
                0.5 * self.stiffness_n_per_m[k] * (l - self.rest_length_m[k]).powi(2)
            })
            .sum();
        Energy {
            kinetic_j,
            elastic_j,
        }
    }

    /// Power dissipated by the dampers (W): Σ c l̇².
    pub fn damping_power_w(&self, s: &State) -> f64 {
        self.mesh
            .edges
            .iter()
            .enumerate()
            .map(|(k, e)| {
                let (i, j) = (e[0] as usize, e[1] as usize);
                let d = s.x_m[i] - s.x_m[j];
                let rate = d.dot(&(s.v_m_s[i] - s.v_m_s[j])) / d.norm();
                self.damping_n_s_per_m[k] * rate * rate
            })
            .sum()
    }

    /// One tick (Eq. 2 over [`Self::substeps`] substeps) with `holds`
    /// applied in order (a later hold of the same node wins; holds of
    /// support nodes are ignored). `forces` is scratch space.
    pub fn step(&self, s: &mut State, holds: &[Hold], forces: &mut Vec<V3>) -> Result<()> {
        let n = self.mesh.node_count();
        forces.resize(n, V3::zeros());
        // Held nodes: start, displacement over the tick, and velocity.
        let mut held: Vec<(usize, V3, V3)> = Vec::with_capacity(holds.len());
        for h in holds {
            let i = h.node as usize;
            if i >= n {
                return Err(TetError::IndexOutOfRange {
                    what: "node",
                    index: i,
                    len: n,
                });
            }
            if self.fixed[i] {
                continue;
            }
            held.retain(|(j, _, _)| *j != i);
            let mut delta = h.target_m - s.x_m[i];
            let reach = MAX_HOLD_SPEED_M_S * TICK_S;
            let len = delta.norm();
            if len > reach {
                delta *= reach / len;
            }
            held.push((i, s.x_m[i], delta));
        }
        let dt = TICK_S / f64::from(self.substeps);
        for &(i, _, delta) in &held {
            s.v_m_s[i] = delta / TICK_S;
        }
        for sub in 1..=self.substeps {
            if let Some(e) = self.internal_forces(&s.x_m, &s.v_m_s, forces) {
                return Err(TetError::Unstable {
                    tick: s.tick + 1,
                    what: format!("element {e} collapsed to zero length"),
                });
            }
            for ((x, v), (f, w)) in s
                .x_m
                .iter_mut()
                .zip(s.v_m_s.iter_mut())
                .zip(forces.iter().zip(&self.inverse_mass))
            {
                if *w != 0.0 {
                    let (x, v, f) = (c3_mut(x), c3_mut(v), c3(f));
                    let kick = dt * w;
                    for a in 0..3 {
                        v[a] += f[a] * kick;
                        x[a] += v[a] * dt;
                    }
                }
            }
            let frac = f64::from(sub) / f64::from(self.substeps);
            for &(i, start, delta) in &held {
                s.x_m[i] = start + delta * frac;
                s.v_m_s[i] = delta / TICK_S;
            }
        }
        s.tick += 1;
        self.check(s)
    }

    /// Instability detection after a tick.
    fn check(&self, s: &State) -> Result<()> {
        let limit = RUNAWAY_SIDES * self.mesh.side_m;
        for (i, (x, v)) in s.x_m.iter().zip(&s.v_m_s).enumerate() {
            let away = (x - self.mesh.nodes_m[i]).norm();
            if !(away <= limit && v.iter().all(|c| c.is_finite())) {
                return Err(TetError::Unstable {
                    tick: s.tick,
                    what: format!(
                        "node {i} is {} m from rest at {} m/s (limit {} m): the step is too large for these constants",
                        plant_common::short_number(away),
                        plant_common::short_number(v.norm()),
                        plant_common::short_number(limit)
                    ),
                });
            }
        }
        Ok(())
    }
}

/// The force of element `p` on its first node (Eq. 1's term; its second
/// node gets the opposite), or `None` if the edge collapsed. Plain
/// component arithmetic: the hot loop of every tick, and fast in
/// unoptimised test builds too.
#[inline]
fn element_force(p: &Packed, x: &[V3], v: &[V3]) -> Option<[f64; 3]> {
    let (i, j) = (p.i as usize, p.j as usize);
    let (xi, xj, vi, vj) = (c3(&x[i]), c3(&x[j]), c3(&v[i]), c3(&v[j]));
    let d = [xi[0] - xj[0], xi[1] - xj[1], xi[2] - xj[2]];
    let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    // Collapsed (or NaN) edges have no direction.
    if l.is_nan() || l <= 1e-9 * p.rest_m {
        return None;
    }
    let inv = 1.0 / l;
    let unit = [d[0] * inv, d[1] * inv, d[2] * inv];
    let rate = unit[0] * (vi[0] - vj[0]) + unit[1] * (vi[1] - vj[1]) + unit[2] * (vi[2] - vj[2]);
    let magnitude = p.k_n_per_m * (l - p.rest_m) + p.c_n_s_per_m * rate;
    Some([
        -unit[0] * magnitude,
        -unit[1] * magnitude,
        -unit[2] * magnitude,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;
    use plant_common::rng;
    use rand::Rng;

    fn random_state(model: &VoigtModel, seed: u64, amplitude: f64) -> State {
        let mut r = rng::stream(seed, rng::TETMSD_TEST_BASE + 3);
        let mut s = model.rest_state();
        let side = model.mesh().side_m;
        for (x, v) in s.x_m.iter_mut().zip(s.v_m_s.iter_mut()) {
            *x += V3::new(
                r.gen_range(-1.0..1.0),
                r.gen_range(-1.0..1.0),
                r.gen_range(-1.0..1.0),
            ) * (amplitude * side);
            *v = V3::new(
                r.gen_range(-1.0..1.0),
                r.gen_range(-1.0..1.0),
                r.gen_range(-1.0..1.0),
            ) * 0.05;
        }
        s
    }

    fn free_model(level: u32, material: VoigtMaterial) -> VoigtModel {
        let mesh = CubeMesh::new(level, 0.06).unwrap();
        let n = mesh.node_count();
        VoigtModel::with_fixed(mesh, material, vec![false; n]).unwrap()
    }

    fn momenta(model: &VoigtModel, s: &State) -> (V3, V3) {
        let mut p = V3::zeros();
        let mut l = V3::zeros();
        for ((x, v), m) in s.x_m.iter().zip(&s.v_m_s).zip(model.masses_kg()) {
            p += v * *m;
            l += x.cross(&(v * *m));
        }
        (p, l)
    }

    #[test]
    fn internal_forces_sum_to_zero_and_have_no_moment() {
        for level in [3, 5, 9] {
            let model = free_model(level, VoigtMaterial::default());
            for seed in 0..5 {
                let s = random_state(&model, seed, 0.05);
                let mut f = vec![V3::zeros(); model.mesh().node_count()];
                assert!(model.internal_forces(&s.x_m, &s.v_m_s, &mut f).is_none());
                let scale: f64 = f.iter().map(|g| g.norm()).sum();
                let sum: V3 = f.iter().sum();
                let moment: V3 = s.x_m.iter().zip(&f).map(|(x, g)| x.cross(g)).sum();
                assert!(sum.norm() < 1e-14 * scale, "level {level}: ΣF = {sum}");
                assert!(
                    moment.norm() < 1e-14 * scale * 0.1,
                    "level {level}: Σx×F = {moment}"
                );
                // node_force (incident elements only) is the same force.
                for i in [0, 7, model.mesh().node_count() - 1] {
                    let one = model.node_force(&s.x_m, &s.v_m_s, i);
                    assert!((one - f[i]).norm() <= 1e-12 * f[i].norm().max(1e-12));
                }
            }
        }
    }

    #[test]
    fn spring_forces_are_minus_the_gradient_of_the_elastic_energy() {
        let material = VoigtMaterial {
            damping_modulus_pa_s: 0.0,
            ..VoigtMaterial::default()
        };
        let model = free_model(4, material);
        let mut s = random_state(&model, 7, 0.05);
        s.v_m_s.iter_mut().for_each(|v| *v = V3::zeros());
        let mut f = vec![V3::zeros(); model.mesh().node_count()];
        model.internal_forces(&s.x_m, &s.v_m_s, &mut f);
        let h = 1e-7;
        for i in [0, 5, 20, 34] {
            for a in 0..3 {
                let mut plus = s.clone();
                plus.x_m[i][a] += h;
                let mut minus = s.clone();
                minus.x_m[i][a] -= h;
                let de =
                    (model.energy(&plus).elastic_j - model.energy(&minus).elastic_j) / (2.0 * h);
                assert!(
                    (f[i][a] + de).abs() < 1e-6 * f[i].norm().max(1e-3),
                    "node {i} axis {a}"
                );
            }
            // The node stiffness is −∂F_i/∂x_i (central differences).
            let k = model.node_stiffness(&s.x_m, i);
            for a in 0..3 {
                let mut plus = s.clone();
                plus.x_m[i][a] += h;
                let mut minus = s.clone();
                minus.x_m[i][a] -= h;
                let fp = model.node_force(&plus.x_m, &plus.v_m_s, i);
                let fm = model.node_force(&minus.x_m, &minus.v_m_s, i);
                let col = -(fp - fm) / (2.0 * h);
                assert!(
                    (col - k.column(a)).norm() < 1e-5 * k.norm(),
                    "node {i} axis {a}"
                );
            }
        }
    }

    #[test]
    fn a_free_mesh_conserves_momentum() {
        // No support, no holds: internal forces only. Symplectic Euler
        // kicks with forces that cancel in pairs and are central, so both
        // momenta are conserved up to rounding, damping or not.
        let model = free_model(5, VoigtMaterial::default());
        let mut s = random_state(&model, 3, 0.05);
        let (p0, l0) = momenta(&model, &s);
        let mut scratch = Vec::new();
        for _ in 0..500 {
            model.step(&mut s, &[], &mut scratch).unwrap();
        }
        let (p1, l1) = momenta(&model, &s);
        let mass: f64 = model.masses_kg().iter().sum();
        // Scales: momentum of the whole mass at 0.05 m/s, and that times the side.
        let ps = mass * 0.05;
        assert!((p1 - p0).norm() < 1e-12 * ps, "ΔP = {}", (p1 - p0).norm());
        assert!(
            (l1 - l0).norm() < 1e-11 * ps * 0.06,
            "ΔL = {}",
            (l1 - l0).norm()
        );
        // The centre of mass moves at the initial momentum's velocity.
        assert!(p0.norm() > 1e-4 * ps);
    }

    /// A smooth start: a bend of 3 % of the side along x that grows with
    /// height, and a spin of 2 rad/s about the vertical axis.
    fn smooth_state(model: &VoigtModel) -> State {
        let mut s = model.rest_state();
        let side = model.mesh().side_m;
        let centre = V3::repeat(side / 2.0);
        for (x, v) in s.x_m.iter_mut().zip(s.v_m_s.iter_mut()) {
            let bend = (std::f64::consts::PI * x.z / side).sin();
            *v = V3::new(0.0, 0.0, 2.0).cross(&(*x - centre));
            x.x += 0.03 * side * bend;
        }
        s
    }

    #[test]
    fn undamped_energy_error_is_first_order_without_drift() {
        // Symplectic Euler conserves a modified energy: the true energy
        // oscillates in a band proportional to the step, with no drift.
        let material = VoigtMaterial {
            damping_modulus_pa_s: 0.0,
            ..VoigtMaterial::default()
        };
        let total = |m: &VoigtModel, s: &State| {
            let e = m.energy(s);
            e.kinetic_j + e.elastic_j
        };
        let run = |factor: u32| {
            let mut m = free_model(4, material);
            m.substeps *= factor;
            let mut s = smooth_state(&m);
            let e0 = total(&m, &s);
            let mut scratch = Vec::new();
            let (mut lo, mut hi) = (e0, e0);
            let (mut early, mut late) = (0.0, 0.0);
            for k in 0..2000 {
                m.step(&mut s, &[], &mut scratch).unwrap();
                let e = total(&m, &s);
                lo = lo.min(e);
                hi = hi.max(e);
                if k < 500 {
                    early += e / 500.0;
                } else if k >= 1500 {
                    late += e / 500.0;
                }
            }
            ((hi - lo) / e0, (late - early).abs() / e0)
        };
        let (band1, drift1) = run(1);
        let (band4, drift4) = run(4);
        // Measured: band 0.24 at the stability-chosen step (the step sits
        // near the stability limit, where symplectic Euler's energy
        // oscillation is large), 0.058 at a quarter of it; drift ≤ 0.0013.
        assert!(band1 < 0.3, "energy band {band1}");
        assert!(band4 < 0.35 * band1, "band {band4} at h/4 vs {band1} at h");
        assert!(
            drift1 < 0.2 * band1 && drift4 < 0.2 * band4,
            "drift {drift1}, {drift4}"
        );
    }

    #[test]
    fn damping_accounts_for_the_lost_energy() {
        // Energy now + energy dissipated by the dampers (trapezoid over the
        // tick-end states, with 4× the substeps to keep the scheme's own
        // O(h) error small) equals the start within 2 %.
        let mut damped = free_model(4, VoigtMaterial::default());
        damped.substeps *= 4;
        let total = |s: &State| {
            let e = damped.energy(s);
            e.kinetic_j + e.elastic_j
        };
        let mut s = random_state(&damped, 11, 0.01);
        let e0 = total(&s);
        let mut scratch = Vec::new();
        let mut lost = 0.0;
        let mut p_prev = damped.damping_power_w(&s);
        for _ in 0..300 {
            damped.step(&mut s, &[], &mut scratch).unwrap();
            let p = damped.damping_power_w(&s);
            lost += 0.5 * (p + p_prev) * TICK_S;
            p_prev = p;
        }
        let e1 = total(&s);
        assert!(e1 < 0.5 * e0, "damping removes energy: {e1} of {e0}");
        assert!(
            ((e1 + lost) - e0).abs() < 0.02 * e0,
            "balance {} vs {e0}",
            e1 + lost
        );
    }

    #[test]
    fn substeps_follow_the_stability_bound_and_blow_ups_are_named() {
        // The largest eigenvalue of M⁻¹K at rest by power iteration (K u
        // from a finite difference of the forces): the chosen substep is
        // stable for it, ω²(h² + 2hτ) < 4, and not wastefully small.
        for (level, want) in [(3, 1), (6, 2), (9, 4)] {
            let m = VoigtModel::new(
                CubeMesh::new(level, 0.06).unwrap(),
                VoigtMaterial::default(),
            )
            .unwrap();
            assert_eq!(m.substeps(), want, "level {level}");
            let n = m.mesh().node_count();
            let zero = vec![V3::zeros(); n];
            let mut u: Vec<V3> = (0..n)
                .map(|i| {
                    if m.is_fixed(i) {
                        V3::zeros()
                    } else {
                        V3::new(1.0, -0.5, (i % 7) as f64)
                    }
                })
                .collect();
            let mut lambda = 0.0;
            let mut f = vec![V3::zeros(); n];
            for _ in 0..400 {
                let norm = u.iter().map(|w| w.norm_squared()).sum::<f64>().sqrt();
                u.iter_mut().for_each(|w| *w /= norm);
                let eps = 1e-9;
                let x: Vec<V3> = (0..n)
                    .map(|i| m.mesh().nodes_m[i] + u[i] * (eps / m.masses_kg()[i].sqrt()))
                    .collect();
                m.internal_forces(&x, &zero, &mut f);
                // y = M^-1/2 K M^-1/2 u
                let y: Vec<V3> = (0..n)
                    .map(|i| {
                        if m.is_fixed(i) {
                            V3::zeros()
                        } else {
                            -f[i] / (eps * m.masses_kg()[i].sqrt())
                        }
                    })
                    .collect();
                lambda = y.iter().zip(&u).map(|(a, b)| a.dot(b)).sum();
                u = y;
            }
            let h = TICK_S / f64::from(m.substeps());
            let tau = m.material().damping_modulus_pa_s / m.material().stiffness_modulus_pa;
            let margin = lambda * (h * h + 2.0 * h * tau) / 4.0;
            assert!(
                margin < 1.0 && margin > 0.1,
                "level {level}: ω²(h²+2hτ)/4 = {margin}"
            );
        }
        // A stiffer material needs more substeps; forcing one substep at
        // 1000× the stiffness blows up and says so with the tick.
        let stiff = VoigtMaterial {
            stiffness_modulus_pa: 2e7,
            ..VoigtMaterial::default()
        };
        let mut m = VoigtModel::new(CubeMesh::new(4, 0.06).unwrap(), stiff).unwrap();
        assert!(m.substeps() > 10);
        m.substeps = 1;
        let mut s = random_state(&m, 1, 0.01);
        let mut scratch = Vec::new();
        let err = (0..100)
            .try_for_each(|_| m.step(&mut s, &[], &mut scratch))
            .unwrap_err();
        assert!(matches!(err, TetError::Unstable { .. }), "{err}");
        assert!(err.to_string().contains("unstable at tick"), "{err}");
        let bad = VoigtMaterial {
            density_kg_m3: -1.0,
            ..VoigtMaterial::default()
        };
        let e = VoigtModel::new(CubeMesh::new(3, 0.06).unwrap(), bad).unwrap_err();
        assert!(e.to_string().contains("density_kg_m3"), "{e}");
    }

    #[test]
    fn a_hold_moves_the_node_exactly_and_support_nodes_stay() {
        let m = VoigtModel::new(CubeMesh::new(3, 0.06).unwrap(), VoigtMaterial::default()).unwrap();
        let mut s = m.rest_state();
        let top = m.mesh().nearest_node(V3::new(0.03, 0.03, 0.06));
        let target = m.mesh().nodes_m[top] - V3::z() * 0.0004;
        let mut scratch = Vec::new();
        m.step(
            &mut s,
            &[Hold {
                node: top as u32,
                target_m: target,
            }],
            &mut scratch,
        )
        .unwrap();
        assert_eq!(s.x_m[top], target);
        assert!((s.v_m_s[top] + V3::z() * 0.4).norm() < 1e-12);
        for i in 0..m.mesh().node_count() {
            if m.is_fixed(i) {
                assert_eq!(s.x_m[i], m.mesh().nodes_m[i]);
            }
        }
        let err = m
            .step(
                &mut s,
                &[Hold {
                    node: 999,
                    target_m: target,
                }],
                &mut scratch,
            )
            .unwrap_err();
        assert!(matches!(err, TetError::IndexOutOfRange { index: 999, .. }));
    }
}
