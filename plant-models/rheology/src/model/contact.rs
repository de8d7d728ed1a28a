//! The rig: the table under the block and the rigid plate or indenter that
//! pushes it from above (L2199–2216, L2264–2270), shared by the lattice and
//! by the reference block of `identify` (the same physical rig).
//!
//! What is modelled, per mass:
//! * non-penetration of the table (y = 0; a mass resting on it touches it)
//!   and of the plate's lower face (masses under its footprint) by
//!   penalty forces proportional to the mass's "opposite area" (its
//!   horizontal tributary area times the fraction of it under the plate),
//!   so that the plate's force is shared among the masses it touches as
//!   F1 = F_n·S1/S_n (L2269) when they are pressed equally;
//! * static and kinetic Coulomb friction (μ_s F, μ_k F; L2211) against
//!   either body: a stuck mass is held at an anchor by a stiff tangential
//!   spring until its force exceeds μ_s·F_n; a sliding one feels μ_k·F_n
//!   against its motion until it slows below the stick speed;
//! * pull-off (L2199–2205): a mass that touched the plate stays bonded to
//!   it by a Voigt unit when the plate withdraws; the bond is dropped for
//!   good once the relative velocity exceeds V_t;
//! * a force-driven plate (the paper's type B pushing, L2279): the force
//!   F_n(t) is shared among the top masses under the plate as F_n·S_i/S_n.
//!
//! Every contact force is linear in the end-of-step velocity v' over a
//! step, `f = r − D v'`, so the implicit step can carry it in its matrix
//! (`D` symmetric positive semi-definite) and the explicit step evaluates
//! it at v' = vⁿ with no look-ahead. Left out: contact between parts of the
//! block, plate tilt, friction in force-driven mode.
use crate::model::vec3::M3;
use serde::{Deserialize, Serialize};

use crate::error::{bad_setting, check_non_negative, check_positive, Result};
use crate::model::lattice::V3;

/// Friction, penalty and pull-off constants (all estimates: the seed gives
/// the laws, not the numbers).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactParams {
    /// μ_s (estimate: wet dough on steel or wood, 0.6).
    pub mu_static: f64,
    /// μ_k (estimate 0.4).
    pub mu_kinetic: f64,
    /// Penalty stiffness per unit opposite area (kPa/mm). Estimate:
    /// 10,000 kPa/mm, so that a 100 kPa contact pressure penetrates 10 µm.
    pub penalty_kpa_per_mm: f64,
    /// Pull-off Voigt spring per unit area (kPa/mm); 0 disables pull-off.
    /// Estimate: 1 kPa/mm (a dough bond of ~1 kPa over a millimetre).
    pub pull_off_kpa_per_mm: f64,
    /// Pull-off Voigt damper per unit area (kPa·s/mm). Estimate 0.1.
    pub pull_off_damping_kpa_s_per_mm: f64,
    /// V_t: the bond is dropped above this relative speed (mm/s; L2205).
    /// Estimate 5 mm/s.
    pub pull_off_speed_mm_s: f64,
    /// A sliding mass sticks again below this tangential speed (mm/s).
    /// Estimate 0.1 mm/s.
    pub stick_speed_mm_s: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self {
            mu_static: 0.6,
            mu_kinetic: 0.4,
            penalty_kpa_per_mm: 1e4,
            pull_off_kpa_per_mm: 1.0,
            pull_off_damping_kpa_s_per_mm: 0.1,
            pull_off_speed_mm_s: 5.0,
            stick_speed_mm_s: 0.1,
        }
    }
}

impl ContactParams {
    /// Checks every constant; names the field.
    pub fn validate(&self) -> Result<()> {
        check_non_negative("contact.mu_static", self.mu_static)?;
        check_non_negative("contact.mu_kinetic", self.mu_kinetic)?;
        if self.mu_kinetic > self.mu_static {
            return Err(bad_setting(
                "contact.mu_kinetic",
                "must not exceed contact.mu_static",
            ));
        }
        check_positive("contact.penalty_kpa_per_mm", self.penalty_kpa_per_mm)?;
        check_non_negative("contact.pull_off_kpa_per_mm", self.pull_off_kpa_per_mm)?;
        check_non_negative(
            "contact.pull_off_damping_kpa_s_per_mm",
            self.pull_off_damping_kpa_s_per_mm,
        )?;
        check_positive("contact.pull_off_speed_mm_s", self.pull_off_speed_mm_s)?;
        check_positive("contact.stick_speed_mm_s", self.stick_speed_mm_s)?;
        Ok(())
    }
    fn penalty(&self) -> f64 {
        self.penalty_kpa_per_mm * 1e6
    }
}

/// A piecewise-linear function of time, constant before its first and
/// after its last point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Schedule {
    /// (t in s, value) with strictly increasing t.
    pub points: Vec<(f64, f64)>,
}

impl Schedule {
    /// Checks the points; `name` is the field for messages.
    pub fn new(name: &str, points: Vec<(f64, f64)>) -> Result<Self> {
        if points.is_empty() {
            return Err(bad_setting(name, "needs at least one [t_s, value] point"));
        }
        for (k, &(t, v)) in points.iter().enumerate() {
            if !(t.is_finite() && v.is_finite()) {
                return Err(bad_setting(
                    &format!("{name}[{k}]"),
                    "time and value must be finite numbers",
                ));
            }
            if t < 0.0 {
                return Err(bad_setting(&format!("{name}[{k}]"), "time must be >= 0"));
            }
            if k > 0 && t <= points[k - 1].0 {
                return Err(bad_setting(
                    &format!("{name}[{k}]"),
                    "times must increase strictly",
                ));
            }
        }
        Ok(Self { points })
    }

    /// The value at `t`.
    pub fn at(&self, t: f64) -> f64 {
        let p = &self.points;
        if t <= p[0].0 {
            return p[0].1;
        }
        for w in p.windows(2) {
            let ((t0, v0), (t1, v1)) = (w[0], w[1]);
            if t <= t1 {
                return v0 + (v1 - v0) * (t - t0) / (t1 - t0);
            }
        }
        p[p.len() - 1].1
    }

    /// The slope at `t` (the right-hand one at a knot).
    pub fn slope(&self, t: f64) -> f64 {
        for w in self.points.windows(2) {
            let ((t0, v0), (t1, v1)) = (w[0], w[1]);
            if t >= t0 && t < t1 {
                return (v1 - v0) / (t1 - t0);
            }
        }
        0.0
    }

    /// The largest value.
    pub fn max_value(&self) -> f64 {
        self.points
            .iter()
            .map(|p| p.1)
            .fold(f64::NEG_INFINITY, f64::max)
    }
}

/// How the plate moves.
#[derive(Clone, Debug, PartialEq)]
pub enum PlateDrive {
    /// Depth of the plate's face below the block's rest top (m) over time
    /// (the paper's pushing by displacement, type A).
    Depth(Schedule),
    /// Downward force (N) over time (pushing by force, type B).
    Force(Schedule),
}

/// A rigid rectangular plate or indenter above the block.
#[derive(Clone, Debug, PartialEq)]
pub struct Plate {
    /// Centre of the footprint (x, z) (m).
    pub centre_xz_m: [f64; 2],
    /// Footprint size (x, z) (m); larger than the block for a full plate.
    pub footprint_m: [f64; 2],
    /// The block's rest top (m): depth 0.
    pub top_m: f64,
    pub drive: PlateDrive,
}

impl Plate {
    /// Height of the plate's face (m) at `t`, for a depth-driven plate.
    pub fn face_y_m(&self, t: f64) -> Option<f64> {
        match &self.drive {
            PlateDrive::Depth(s) => Some(self.top_m - s.at(t)),
            PlateDrive::Force(_) => None,
        }
    }

    fn face_velocity(&self, t: f64) -> f64 {
        match &self.drive {
            PlateDrive::Depth(s) => -s.slope(t),
            PlateDrive::Force(_) => 0.0,
        }
    }

    /// Whether the point (x, z) lies under the footprint (edges included).
    pub fn covers_point(&self, x: f64, z: f64) -> bool {
        let inside = |c: f64, pc: f64, pw: f64| (c - pc).abs() <= pw / 2.0 * (1.0 + 1e-12);
        inside(x, self.centre_xz_m[0], self.footprint_m[0])
            && inside(z, self.centre_xz_m[1], self.footprint_m[1])
    }

    /// Fraction of a `cell_m` rectangle centred at (x, z) under the plate.
    pub fn coverage(&self, x: f64, z: f64, cell_m: [f64; 2]) -> f64 {
        let overlap = |c: f64, w: f64, pc: f64, pw: f64| {
            ((c + w / 2.0).min(pc + pw / 2.0) - (c - w / 2.0).max(pc - pw / 2.0)).max(0.0)
        };
        overlap(x, cell_m[0], self.centre_xz_m[0], self.footprint_m[0])
            * overlap(z, cell_m[1], self.centre_xz_m[1], self.footprint_m[1])
            / (cell_m[0] * cell_m[1])
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Tangential {
    Free,
    Stuck([f64; 2]),
    Sliding,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct NodeState {
    table: Tangential,
    plate: Tangential,
    bonded: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Body {
    Table,
    Plate,
    Bond,
    Load,
}

#[derive(Clone, Copy, Debug)]
struct Active {
    node: usize,
    body: Body,
    /// f = r − d·v' on the node.
    r: V3,
    d: M3,
}

/// What every contact of one step shares: the penalty stiffness per
/// area (N/m per m²), μ_k, the look-ahead (s) and the plate face's
/// velocity (m/s).
#[derive(Clone, Copy, Debug)]
struct StepContact {
    penalty: f64,
    mu_kinetic: f64,
    lookahead_s: f64,
    face_v: f64,
}

impl StepContact {
    /// The tangential part of a contact in `state` with normal stiffness
    /// `stiff` and normal force estimate `fn_est`: a stuck mass's anchor
    /// spring, a sliding one's kinetic friction as a damper.
    #[inline]
    fn tangential(&self, state: Tangential, stiff: f64, xn: &V3, vn: &V3, fn_est: f64) -> (M3, V3) {
        let h = self.lookahead_s;
        let mut d = M3::zeros();
        let mut r = V3::zeros();
        match state {
            Tangential::Stuck(anchor) => {
                d[(0, 0)] = stiff * h;
                d[(2, 2)] = stiff * h;
                r.x = stiff * (anchor[0] - xn.x);
                r.z = stiff * (anchor[1] - xn.z);
            }
            Tangential::Sliding => {
                let speed = (vn.x * vn.x + vn.z * vn.z).sqrt().max(1e-6);
                let c = self.mu_kinetic * fn_est / speed;
                d[(0, 0)] = c;
                d[(2, 2)] = c;
            }
            Tangential::Free => {}
        }
        (d, r)
    }
}

/// The tangential state of a mass that starts touching a body at `xn`:
/// stuck at its anchor, or sliding when there is no static friction
/// (μ_s = 0 cannot hold it for even one step).
fn first_touch(mu_static: f64, xn: &V3) -> Tangential {
    if mu_static > 0.0 {
        Tangential::Stuck([xn.x, xn.z])
    } else {
        Tangential::Sliding
    }
}

/// Contacts of every mass with the table and the plate.
#[derive(Clone, Debug)]
pub struct Contacts {
    params: ContactParams,
    plate: Option<Plate>,
    areas_m2: Vec<f64>,
    cell_m: [f64; 2],
    top_nodes: Vec<usize>,
    states: Vec<NodeState>,
    active: Vec<Active>,
    plate_face_next: Option<f64>,
    plate_velocity: f64,
}

impl Contacts {
    /// Contacts for `areas_m2.len()` masses with horizontal tributary
    /// areas `areas_m2` (their coverage squares are `cell_m` wide);
    /// `top_nodes` take a force-driven plate's load.
    pub fn new(
        params: ContactParams,
        plate: Option<Plate>,
        areas_m2: Vec<f64>,
        cell_m: [f64; 2],
        top_nodes: Vec<usize>,
    ) -> Result<Self> {
        params.validate()?;
        let n = areas_m2.len();
        Ok(Self {
            params,
            plate,
            areas_m2,
            cell_m,
            top_nodes,
            states: vec![
                NodeState {
                    table: Tangential::Free,
                    plate: Tangential::Free,
                    bonded: false,
                };
                n
            ],
            active: Vec::new(),
            plate_face_next: None,
            plate_velocity: 0.0,
        })
    }

    /// The plate, if any.
    pub fn plate(&self) -> Option<&Plate> {
        self.plate.as_ref()
    }

    /// Linearises every contact force over the step to `t_next`.
    /// `lookahead_s` is the step for the implicit scheme (penetration
    /// predicted at the end of the step) and 0 for the explicit one.
    pub fn prepare(&mut self, t_next: f64, lookahead_s: f64, x: &[V3], v: &[V3]) {
        self.active.clear();
        let face = self.plate.as_ref().and_then(|p| p.face_y_m(t_next));
        let face_v = self
            .plate
            .as_ref()
            .map(|p| p.face_velocity(t_next - 1e-12))
            .unwrap_or(0.0);
        self.plate_face_next = face;
        self.plate_velocity = face_v;
        let step = StepContact {
            penalty: self.params.penalty(),
            mu_kinetic: self.params.mu_kinetic,
            lookahead_s,
            face_v,
        };
        for n in 0..x.len() {
            let (xn, vn) = (&x[n], &v[n]);
            self.touch_table(n, xn, vn, &step);
            if let Some(face) = face {
                self.touch_plate(n, xn, vn, face, &step);
            }
        }
        self.load_top_masses(t_next, x);
    }

    /// The table at y = 0 and mass `n`. In contact when the mass is in the
    /// table now or would be at the end of the step at its present
    /// velocity (a look-ahead alone would toggle a resting mass on and
    /// off).
    #[inline]
    fn touch_table(&mut self, n: usize, xn: &V3, vn: &V3, step: &StepContact) {
        let h = step.lookahead_s;
        let area = self.areas_m2[n];
        let pen = (-xn.y).max(-(xn.y + h * vn.y));
        let st = &mut self.states[n];
        // Resting on the table (y = 0, not moving away) counts as touching:
        // otherwise the first step of a run at rest has no table under it
        // and the whole block drops by dt²·(g + F/M) (issue 29).
        let resting = xn.y <= 0.0 && vn.y <= 0.0;
        if pen > 0.0 || resting {
            let stiff = step.penalty * area;
            if st.table == Tangential::Free {
                st.table = first_touch(self.params.mu_static, xn);
            }
            let (mut d, mut r) = step.tangential(st.table, stiff, xn, vn, stiff * pen);
            d[(1, 1)] += stiff * h;
            r.y += -stiff * xn.y;
            self.active.push(Active {
                node: n,
                body: Body::Table,
                r,
                d,
            });
        } else {
            st.table = Tangential::Free;
        }
    }

    /// A depth-driven plate whose face is at `face` (m) and mass `n`: in
    /// contact as with the table; once withdrawn, a bonded mass is held by
    /// its pull-off bond until the bond breaks.
    #[inline]
    fn touch_plate(&mut self, n: usize, xn: &V3, vn: &V3, face: f64, step: &StepContact) {
        let Some(plate) = &self.plate else {
            return;
        };
        let h = step.lookahead_s;
        let area = self.areas_m2[n];
        let st = &mut self.states[n];
        // Only a mass under the plate's footprint touches it. (Before issue
        // 29 a mass beside the plate whose cell overlapped the footprint by
        // a sliver touched it with that sliver's penalty, sank millimetres
        // into it and carried a share of the force that jumped when a mass
        // under the plate came back into contact.)
        let under = plate.covers_point(xn.x, xn.z);
        let cover = plate.coverage(xn.x, xn.z, self.cell_m);
        let stiff = step.penalty * area * cover;
        let pen = (xn.y - face).max(xn.y + h * vn.y - face);
        if under && pen > 0.0 {
            if st.plate == Tangential::Free {
                st.plate = first_touch(self.params.mu_static, xn);
            }
            if self.params.pull_off_kpa_per_mm > 0.0 {
                st.bonded = true;
            }
            let (mut d, mut r) = step.tangential(st.plate, stiff, xn, vn, stiff * pen);
            d[(1, 1)] += stiff * h;
            r.y += -stiff * (xn.y - face);
            self.active.push(Active {
                node: n,
                body: Body::Plate,
                r,
                d,
            });
            return;
        }
        st.plate = Tangential::Free;
        if !st.bonded {
            return;
        }
        let relative = (vn.y - step.face_v).abs();
        if !under || relative > self.params.pull_off_speed_mm_s * 1e-3 {
            st.bonded = false;
            return;
        }
        let k = self.params.pull_off_kpa_per_mm * 1e6 * area * cover;
        let c = self.params.pull_off_damping_kpa_s_per_mm * 1e6 * area * cover;
        let mut d = M3::zeros();
        d[(1, 1)] = k * h + c;
        let r = V3::new(0.0, k * (face - xn.y) + c * step.face_v, 0.0);
        self.active.push(Active {
            node: n,
            body: Body::Bond,
            r,
            d,
        });
    }

    /// A force-driven plate: F_n·S_i/S_n on the top masses under it.
    fn load_top_masses(&mut self, t_next: f64, x: &[V3]) {
        let Some(plate) = &self.plate else {
            return;
        };
        let PlateDrive::Force(s) = &plate.drive else {
            return;
        };
        let force = s.at(t_next);
        let shares: Vec<(usize, f64)> = self
            .top_nodes
            .iter()
            .map(|&n| {
                (
                    n,
                    self.areas_m2[n] * plate.coverage(x[n].x, x[n].z, self.cell_m),
                )
            })
            .filter(|s| s.1 > 0.0)
            .collect();
        let total: f64 = shares.iter().map(|s| s.1).sum();
        if total > 0.0 {
            for (n, s) in shares {
                self.active.push(Active {
                    node: n,
                    body: Body::Load,
                    r: V3::new(0.0, -force * s / total, 0.0),
                    d: M3::zeros(),
                });
            }
        }
    }

    /// `out += D v` (the contacts' part of the implicit operator).
    pub fn add_apply(&self, v: &[V3], out: &mut [V3]) {
        for a in &self.active {
            out[a.node] += a.d * v[a.node];
        }
    }

    /// Adds the contacts' 3×3 blocks to the operator's diagonal.
    pub fn add_diag(&self, diag: &mut [M3]) {
        for a in &self.active {
            diag[a.node] += a.d;
        }
    }

    /// `rhs += r` (the velocity-independent part of the contact forces).
    pub fn add_rhs(&self, rhs: &mut [V3]) {
        for a in &self.active {
            rhs[a.node] += a.r;
        }
    }

    /// Ends the step with end-of-step velocities `v_new` (the implicit
    /// step) or start-of-step ones (explicit) and positions `x_new`:
    /// updates stick/slip and returns the plate's downward force on the
    /// block (N; negative while pull-off bonds pull it).
    pub fn finish(&mut self, x_new: &[V3], v_new: &[V3]) -> f64 {
        let mut plate_force = 0.0;
        let (mu_s, stick) = (self.params.mu_static, self.params.stick_speed_mm_s * 1e-3);
        for a in &self.active {
            let f = a.r - a.d * v_new[a.node];
            let st = &mut self.states[a.node];
            let slot = match a.body {
                Body::Table => &mut st.table,
                Body::Plate => &mut st.plate,
                Body::Bond | Body::Load => {
                    plate_force -= f.y;
                    continue;
                }
            };
            if a.body == Body::Plate {
                plate_force -= f.y;
            }
            let normal = f.y.abs();
            let ft = (f.x * f.x + f.z * f.z).sqrt();
            let vn = v_new[a.node];
            let vt = (vn.x * vn.x + vn.z * vn.z).sqrt();
            *slot = match *slot {
                Tangential::Stuck(_) if ft > mu_s * normal => Tangential::Sliding,
                Tangential::Sliding if vt < stick && mu_s > 0.0 => {
                    Tangential::Stuck([x_new[a.node].x, x_new[a.node].z])
                }
                s => s,
            };
        }
        plate_force
    }

    /// The plate's face height at the end of the last prepared step (m),
    /// for a depth-driven plate.
    pub fn plate_face_m(&self) -> Option<f64> {
        self.plate_face_next
    }

    /// Masses bonded to the plate by pull-off (for reports and tests).
    pub fn bonded_count(&self) -> usize {
        self.states.iter().filter(|s| s.bonded).count()
    }

    /// Masses touching the plate in the last prepared step.
    pub fn plate_contacts(&self) -> usize {
        self.active
            .iter()
            .filter(|a| matches!(a.body, Body::Plate | Body::Load))
            .count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schedules_interpolate_and_refuse_bad_points_by_index() {
        let s = Schedule::new("plate.depth", vec![(0.0, 0.0), (1.0, 15.0), (3.0, 15.0)]).unwrap();
        assert_eq!(s.at(0.5), 7.5);
        assert_eq!(s.at(2.0), 15.0);
        assert_eq!(s.at(9.0), 15.0);
        assert_eq!(s.slope(0.2), 15.0);
        assert_eq!(s.slope(1.5), 0.0);
        let e = Schedule::new("plate.depth", vec![(0.0, 0.0), (0.0, 1.0)]).unwrap_err();
        assert!(e.to_string().contains("plate.depth[1]"), "{e}");
        let e = Schedule::new("plate.depth", vec![(0.0, f64::NAN)]).unwrap_err();
        assert!(e.to_string().contains("plate.depth[0]"), "{e}");
    }

    #[test]
    fn coverage_is_the_overlap_fraction_of_the_cell() {
        let p = Plate {
            centre_xz_m: [0.05, 0.05],
            footprint_m: [0.04, 0.04],
            top_m: 0.06,
            drive: PlateDrive::Depth(Schedule::new("d", vec![(0.0, 0.0)]).unwrap()),
        };
        let cell = [0.01, 0.01];
        assert!((p.coverage(0.05, 0.05, cell) - 1.0).abs() < 1e-12);
        assert!((p.coverage(0.03, 0.05, cell) - 0.5).abs() < 1e-12);
        assert!((p.coverage(0.03, 0.03, cell) - 0.25).abs() < 1e-12);
        assert_eq!(p.coverage(0.01, 0.05, cell), 0.0);
    }

    #[test]
    fn a_force_driven_plate_shares_its_force_by_opposite_area() {
        // Four top masses: two fully under the plate, one half, one outside.
        let p = Plate {
            centre_xz_m: [0.0, 0.0],
            footprint_m: [0.03, 0.01],
            top_m: 0.0,
            drive: PlateDrive::Force(Schedule::new("f", vec![(0.0, 10.0)]).unwrap()),
        };
        let x = vec![
            V3::new(-0.01, 0.0, 0.0),
            V3::new(0.0, 0.0, 0.0),
            V3::new(0.015, 0.0, 0.0),
            V3::new(0.04, 0.0, 0.0),
        ];
        let v = vec![V3::zeros(); 4];
        let mut c = Contacts::new(
            ContactParams::default(),
            Some(p),
            vec![1e-4; 4],
            [0.01, 0.01],
            vec![0, 1, 2, 3],
        )
        .unwrap();
        c.prepare(0.1, 0.0, &x, &v);
        let mut rhs = vec![V3::zeros(); 4];
        c.add_rhs(&mut rhs);
        // S = 1, 1, 0.5, 0 (× 1 cm²): F1 = 10·S1/2.5.
        assert!((rhs[0].y + 4.0).abs() < 1e-12);
        assert!((rhs[1].y + 4.0).abs() < 1e-12);
        assert!((rhs[2].y + 2.0).abs() < 1e-12);
        assert_eq!(rhs[3].y, 0.0);
        assert!((c.finish(&x, &v) - 10.0).abs() < 1e-12);
    }

    #[test]
    fn friction_sticks_then_slides_above_mu_s_and_pull_off_breaks_above_vt() {
        let params = ContactParams::default();
        let plate = Plate {
            centre_xz_m: [0.0, 0.0],
            footprint_m: [1.0, 1.0],
            top_m: 0.01,
            drive: PlateDrive::Depth(
                Schedule::new("d", vec![(0.0, 0.0), (1.0, 0.001), (2.0, -0.01)]).unwrap(),
            ),
        };
        let mut c = Contacts::new(params, Some(plate), vec![1e-4], [0.01, 0.01], vec![0]).unwrap();
        // A mass slightly into the table: stuck at its anchor.
        let x = vec![V3::new(0.0, -1e-6, 0.0)];
        let v = vec![V3::zeros()];
        c.prepare(0.001, 0.001, &x, &v);
        let mut rhs = vec![V3::zeros()];
        c.add_rhs(&mut rhs);
        let normal = 1e10 * 1e-4 * 1e-6;
        assert!((rhs[0].y - normal).abs() < 1e-12);
        // Pulled sideways beyond μ_s·N: it slides next step.
        let moved = vec![V3::new(0.7 * normal / (1e10 * 1e-4), -1e-6, 0.0)];
        c.prepare(0.002, 0.0, &moved, &v);
        c.finish(&moved, &v);
        assert_eq!(c.states[0].table, Tangential::Sliding);
        // The plate comes down onto a top mass at y = 0.01: bonded; when it
        // withdraws slowly the bond pulls, when fast it breaks.
        let top = vec![V3::new(0.0, 0.01, 0.0)];
        c.prepare(0.9, 0.0, &top, &v);
        assert!(c.states[0].bonded);
        let f = c.finish(&top, &v);
        assert!(f > 0.0, "pushing: {f}");
        // Withdrawing at 11 mm/s with the mass following it: still bonded.
        let below = vec![V3::new(0.0, 0.0095, 0.0)];
        let follow = vec![V3::new(0.0, 0.011, 0.0)];
        c.prepare(1.05, 0.0, &below, &follow);
        let f = c.finish(&below, &follow);
        assert!(f < 0.0, "the bond pulls the plate down: {f}");
        assert!(c.states[0].bonded);
        let fast = vec![V3::new(0.0, -0.02, 0.0)];
        c.prepare(1.1, 0.0, &below, &fast);
        assert!(
            !c.states[0].bonded,
            "relative speed above V_t drops the bond"
        );
    }
}
