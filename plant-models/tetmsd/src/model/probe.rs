//! The haptic probe: what a user does to the object in one tick (the
//! manipulation parameters of the seed's packet), when a grip starts and
//! ends, the force the user feels, and scripted stylus trajectories (there
//! is no haptic device here).
//!
//! The seed's packet (L2650–2655) carries the stylus tip, the tetrahedron
//! "held by users", the node "manipulated by users" and that node's
//! position: a user grips one node of the tetrahedron the stylus entered
//! and moves it. Here:
//! * **Contact starts** when the tip lies in a tetrahedron by Eq. 3
//!   ([`locate`]) on the current (deformed) shape. The gripped node is the
//!   vertex of that tetrahedron nearest to the tip among the vertices that
//!   are on the surface, not on the support and not held by the other
//!   user as far as this site knows (two grips on one node fight: the
//!   node goes where site 1 puts it, and site 0 feels the pull between
//!   them; with the peer's latest grip excluded that happens only when
//!   both grab within one network delay).
//! * **During contact** the node follows the tip with the offset it had at
//!   the first touch (so the grip starts without a jump), and the user
//!   feels the network's force on that node (Eq. 1), which pushes the
//!   stylus back out.
//! * **Contact ends** when the tip is back above the point where it
//!   entered, along the node's rest normal (push-only contact: no pulling
//!   the surface out, no adhesion).
//! * **The felt force at 1 kHz** comes from the latest deformation result
//!   by a first-order local model, `F(x) = F₀ − K₀(x − x₀)`, with `K₀` the
//!   node's own stiffness ([`VoigtModel::node_stiffness`]): between two
//!   deformation updates the force follows the stylus instead of holding
//!   still.
//!
//! Left out: friction and sliding of the grip over the surface, more than
//! one node per user, the stylus's own shape.
use super::locate::locate;
use super::voigt::VoigtModel;
use super::V3;
use crate::error::{Result, TetError};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

/// A user's grip on the object during one tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grip {
    /// The tetrahedron the stylus entered (the "tetrahedron ID held by users").
    pub tet: u16,
    /// The node the user moves (the "node ID manipulated by users").
    pub node: u16,
    /// Where that node is at the end of the tick (m).
    pub node_m: V3,
}

/// What one user does to the object in one tick: the content of a
/// manipulation packet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Manipulation {
    /// The stylus tip (m).
    pub tip_m: V3,
    /// The grip, if the stylus is in contact.
    pub grip: Option<Grip>,
}

impl Manipulation {
    /// A stylus at `tip_m` touching nothing.
    pub fn free(tip_m: V3) -> Self {
        Manipulation { tip_m, grip: None }
    }
}

/// What the probe needs to know about the object besides its current
/// shape: its tetrahedra, which nodes may be gripped, rest normals.
#[derive(Clone, Debug)]
pub struct ContactGeometry {
    tets: Vec<[u32; 4]>,
    grippable: Vec<bool>,
    rest_normals: Vec<V3>,
}

impl ContactGeometry {
    /// The contact geometry of a model: surface nodes off the support are
    /// grippable.
    pub fn of(model: &VoigtModel) -> Self {
        let mesh = model.mesh();
        ContactGeometry {
            tets: mesh.tets.clone(),
            grippable: (0..mesh.node_count())
                .map(|i| mesh.on_boundary[i] && !model.is_fixed(i))
                .collect(),
            rest_normals: mesh.rest_normals(),
        }
    }

    /// Number of tetrahedra.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// Whether node `i` may be gripped.
    pub fn grippable(&self, i: usize) -> bool {
        self.grippable.get(i).copied().unwrap_or(false)
    }

    /// Whether `node` is a vertex of `tet` (both inside the mesh).
    pub fn tet_has_node(&self, tet: usize, node: usize) -> bool {
        self.tets
            .get(tet)
            .is_some_and(|t| t.contains(&(node as u32)))
    }
}

/// A grip in progress: the packet fields plus what decides its end.
#[derive(Clone, Copy, Debug)]
struct Active {
    tet: u16,
    node: u16,
    /// Node position minus tip position at the first touch.
    offset_m: V3,
    /// Where the tip entered.
    entry_m: V3,
    /// The node's outward rest normal.
    normal: V3,
}

/// One user's probe: turns stylus positions into manipulations.
#[derive(Clone, Debug, Default)]
pub struct Probe {
    active: Option<Active>,
}

impl Probe {
    /// A probe touching nothing.
    pub fn new() -> Self {
        Probe::default()
    }

    /// Whether the probe grips a node.
    pub fn in_contact(&self) -> bool {
        self.active.is_some()
    }

    /// The manipulation for a stylus at `tip_m` over the object's current
    /// node positions `x_m`; `taken` is a node the other user holds.
    pub fn update(
        &mut self,
        tip_m: V3,
        geometry: &ContactGeometry,
        x_m: &[V3],
        taken: Option<u16>,
    ) -> Manipulation {
        if let Some(a) = self.active {
            if (tip_m - a.entry_m).dot(&a.normal) > 0.0 {
                self.active = None;
                return Manipulation::free(tip_m);
            }
            return Manipulation {
                tip_m,
                grip: Some(Grip {
                    tet: a.tet,
                    node: a.node,
                    node_m: tip_m + a.offset_m,
                }),
            };
        }
        // Cheap rejection: outside the object's bounding box.
        let lo = x_m.iter().fold(V3::repeat(f64::INFINITY), |m, p| m.inf(p));
        let hi = x_m
            .iter()
            .fold(V3::repeat(f64::NEG_INFINITY), |m, p| m.sup(p));
        if (0..3).any(|a| tip_m[a] < lo[a] || tip_m[a] > hi[a]) {
            return Manipulation::free(tip_m);
        }
        let Some(t) = locate(x_m, &geometry.tets, tip_m) else {
            return Manipulation::free(tip_m);
        };
        let node = geometry.tets[t]
            .iter()
            .map(|&i| i as usize)
            .filter(|&i| geometry.grippable[i] && taken != Some(i as u16))
            .min_by(|&i, &j| {
                let (di, dj) = ((x_m[i] - tip_m).norm(), (x_m[j] - tip_m).norm());
                di.total_cmp(&dj).then(i.cmp(&j))
            });
        let Some(node) = node else {
            return Manipulation::free(tip_m);
        };
        let a = Active {
            tet: t as u16,
            node: node as u16,
            offset_m: x_m[node] - tip_m,
            entry_m: tip_m,
            normal: geometry.rest_normals[node],
        };
        self.active = Some(a);
        Manipulation {
            tip_m,
            grip: Some(Grip {
                tet: a.tet,
                node: a.node,
                node_m: x_m[node],
            }),
        }
    }
}

/// The network's reaction at a gripped node, as the deformation computed
/// it, and the local model that carries it between deformation updates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeReaction {
    /// The node.
    pub node: u16,
    /// Its position when the reaction was computed (m).
    pub position_m: V3,
    /// The force of the network on it (N): what the user feels.
    pub force_n: V3,
    /// Its own stiffness `−∂F/∂x` (N/m).
    pub stiffness_n_per_m: Matrix3<f64>,
}

impl NodeReaction {
    /// The reaction at `node` of a model in the shape `x_m` moving at `v_m_s`.
    pub fn of(model: &VoigtModel, x_m: &[V3], v_m_s: &[V3], node: u16) -> Self {
        let i = usize::from(node);
        NodeReaction {
            node,
            position_m: x_m[i],
            force_n: model.node_force(x_m, v_m_s, i),
            stiffness_n_per_m: model.node_stiffness(x_m, i),
        }
    }

    /// The force felt with the node at `node_m` (first-order local model).
    pub fn force_at(&self, node_m: V3) -> V3 {
        self.force_n - self.stiffness_n_per_m * (node_m - self.position_m)
    }
}

/// A point of a scripted stylus path (mm, in the cube's frame: the cube
/// spans `[0, side]³`, its top face is `z = side`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    /// Time (s).
    pub t_s: f64,
    /// Stylus x (mm).
    pub x_mm: f64,
    /// Stylus y (mm).
    pub y_mm: f64,
    /// Stylus z (mm).
    pub z_mm: f64,
}

/// A scripted stylus path: straight lines between waypoints, held at the
/// ends, optionally repeating.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    points: Vec<(f64, V3)>,
    repeat_s: Option<f64>,
}

impl Trajectory {
    /// A path through `waypoints` (times strictly increasing, all finite);
    /// with `repeat_s` the path restarts every `repeat_s` seconds, which
    /// must not be shorter than its last waypoint's time. `name` labels
    /// errors (a file and table).
    pub fn new(waypoints: &[Waypoint], repeat_s: Option<f64>, name: &str) -> Result<Self> {
        if waypoints.is_empty() {
            return Err(TetError::Malformed {
                location: name.into(),
                reason: "needs at least one waypoint".into(),
            });
        }
        let mut points = Vec::with_capacity(waypoints.len());
        for (k, w) in waypoints.iter().enumerate() {
            for (field, v) in [
                ("t_s", w.t_s),
                ("x_mm", w.x_mm),
                ("y_mm", w.y_mm),
                ("z_mm", w.z_mm),
            ] {
                if !v.is_finite() {
                    return Err(TetError::Malformed {
                        location: format!("{name}, waypoint {}", k + 1),
                        reason: format!("{field} must be a finite number, got {v}"),
                    });
                }
            }
            if let Some(&(t_prev, _)) = points.last() {
                if w.t_s <= t_prev {
                    return Err(TetError::Malformed {
                        location: format!("{name}, waypoint {}", k + 1),
                        reason: format!(
                            "t_s = {} does not come after the previous waypoint's {t_prev}",
                            w.t_s
                        ),
                    });
                }
            }
            points.push((w.t_s, V3::new(w.x_mm, w.y_mm, w.z_mm) * 1e-3));
        }
        if let Some(r) = repeat_s {
            let last = points[points.len() - 1].0;
            if !(r.is_finite() && r > 0.0 && r >= last) {
                return Err(TetError::Malformed {
                    location: format!("{name}, repeat_s"),
                    reason: format!(
                        "must be finite, > 0 and at least the last waypoint's t_s ({last}), got {r}"
                    ),
                });
            }
        }
        Ok(Trajectory { points, repeat_s })
    }

    /// The stylus position at time `t_s` (m).
    pub fn at(&self, t_s: f64) -> V3 {
        let t = match self.repeat_s {
            Some(r) => t_s.rem_euclid(r),
            None => t_s,
        };
        let k = self.points.partition_point(|(tk, _)| *tk <= t);
        if k == 0 {
            return self.points[0].1;
        }
        if k == self.points.len() {
            return self.points[k - 1].1;
        }
        let ((t0, p0), (t1, p1)) = (self.points[k - 1], self.points[k]);
        p0 + (p1 - p0) * ((t - t0) / (t1 - t0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::mesh::CubeMesh;
    use crate::model::voigt::{Hold, VoigtMaterial};

    fn wp(t_s: f64, x_mm: f64, y_mm: f64, z_mm: f64) -> Waypoint {
        Waypoint {
            t_s,
            x_mm,
            y_mm,
            z_mm,
        }
    }

    #[test]
    fn a_press_grips_a_top_node_follows_the_tip_and_releases_above_entry() {
        let model =
            VoigtModel::new(CubeMesh::new(6, 0.06).unwrap(), VoigtMaterial::default()).unwrap();
        let geometry = ContactGeometry::of(&model);
        let mut s = model.rest_state();
        let mut probe = Probe::new();
        let mut scratch = Vec::new();
        // Down from 2 mm above the top at (21, 33) mm to 5 mm deep and back.
        let path = Trajectory::new(
            &[
                wp(0.0, 21.0, 33.0, 62.0),
                wp(0.5, 21.0, 33.0, 55.0),
                wp(1.0, 21.0, 33.0, 62.0),
            ],
            None,
            "test",
        )
        .unwrap();
        let mut first_touch = None;
        let mut released = None;
        let mut deepest_force = V3::zeros();
        for k in 0..1000u64 {
            let tip = path.at(k as f64 * 1e-3);
            let m = probe.update(tip, &geometry, &s.x_m, None);
            if let Some(g) = m.grip {
                first_touch.get_or_insert((k, g));
                let start = first_touch.unwrap().1;
                assert_eq!(g.node, start.node);
                // The node follows the tip with the first-touch offset.
                let offset = start.node_m - path.at(first_touch.unwrap().0 as f64 * 1e-3);
                assert!((g.node_m - (tip + offset)).norm() < 1e-15);
                model
                    .step(
                        &mut s,
                        &[Hold {
                            node: u32::from(g.node),
                            target_m: g.node_m,
                        }],
                        &mut scratch,
                    )
                    .unwrap();
                let r = NodeReaction::of(&model, &s.x_m, &s.v_m_s, g.node);
                if k == 500 {
                    deepest_force = r.force_n;
                }
            } else {
                if first_touch.is_some() && released.is_none() {
                    released = Some(k);
                }
                model.step(&mut s, &[], &mut scratch).unwrap();
            }
        }
        let (k0, g0) = first_touch.expect("the probe touched the top face");
        // Touch when the tip crosses z = 60 mm: 2 mm of 7 mm at 14 mm/s.
        assert!((142..=144).contains(&k0), "first touch at tick {k0}");
        let node = model.mesh().nodes_m[usize::from(g0.node)];
        assert_eq!(node.z, 0.06);
        assert!((node.xy() - V3::new(0.0225, 0.03, 0.0).xy()).norm() < 0.008);
        // Pushed 5 mm deep, the network pushes back up, by newtons.
        assert!(deepest_force.z > 0.05, "{deepest_force}");
        // Released when the tip comes back above its entry point.
        let r = released.expect("released");
        assert!((856..=858).contains(&r), "released at tick {r}");
    }

    #[test]
    fn the_local_model_is_exact_to_first_order() {
        let model =
            VoigtModel::new(CubeMesh::new(4, 0.06).unwrap(), VoigtMaterial::default()).unwrap();
        let mut s = model.rest_state();
        let node = model.mesh().nearest_node(V3::new(0.03, 0.03, 0.06));
        s.x_m[node].z -= 0.004;
        let r = NodeReaction::of(&model, &s.x_m, &s.v_m_s, node as u16);
        let dx = V3::new(1e-5, -2e-5, -3e-5);
        let mut moved = s.clone();
        moved.x_m[node] += dx;
        let exact = model.node_force(&moved.x_m, &moved.v_m_s, node);
        let err = (r.force_at(s.x_m[node] + dx) - exact).norm();
        let change = (exact - r.force_n).norm();
        assert!(err < 1e-3 * change, "error {err} of a change of {change}");
    }

    #[test]
    fn trajectories_interpolate_repeat_and_name_bad_waypoints() {
        let p = Trajectory::new(
            &[wp(0.0, 0.0, 0.0, 10.0), wp(2.0, 20.0, 0.0, 10.0)],
            Some(4.0),
            "site 0",
        )
        .unwrap();
        assert!((p.at(1.0) - V3::new(0.01, 0.0, 0.01)).norm() < 1e-15);
        assert!((p.at(3.0) - V3::new(0.02, 0.0, 0.01)).norm() < 1e-15);
        assert!((p.at(5.0) - V3::new(0.01, 0.0, 0.01)).norm() < 1e-15);
        assert!((p.at(-1.0) - V3::new(0.02, 0.0, 0.01)).norm() < 1e-15);
        let e = Trajectory::new(
            &[wp(1.0, 0.0, 0.0, 0.0), wp(1.0, 0.0, 0.0, 0.0)],
            None,
            "site 1",
        )
        .unwrap_err();
        assert!(e.to_string().contains("site 1, waypoint 2"), "{e}");
        let e = Trajectory::new(&[wp(0.0, f64::NAN, 0.0, 0.0)], None, "s").unwrap_err();
        assert!(e.to_string().contains("x_mm"), "{e}");
        let e = Trajectory::new(
            &[wp(0.0, 0.0, 0.0, 0.0), wp(3.0, 0.0, 0.0, 0.0)],
            Some(2.0),
            "s",
        )
        .unwrap_err();
        assert!(e.to_string().contains("repeat_s"), "{e}");
        assert!(Trajectory::new(&[], None, "s").is_err());
    }
}
