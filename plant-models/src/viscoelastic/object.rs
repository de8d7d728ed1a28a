//! Viscoelastic evaluation of a DGFM object (seed 002 Eq. 4–12, §4.2, §5)
//! and its 1 kHz haptic driver with a 30 Hz display output.
//!
//! The update itself is the portable core's: Rayleigh columns call
//! [`firmware::viscoelastic::rayleigh_displacement_step`] per (i, j) pair
//! (Eq. 12 with tractions, see the core's note on Eq. 12); tensor columns
//! use [`firmware::viscoelastic::ThreeElementTensor::from_dgfm_entry`]
//! (Eq. 5–6, 9–10) fed the nodal force `f_j = α_j p_j`. This module is the
//! *runtime-sized* driver around them (option (b) of the design): the core's
//! `ViscoDgfm` needs the vertex count at compile time, a mesh loaded at run
//! time does not have one. It keeps the same active-column rule as the core
//! (seed §5): a column is active while traction is applied or while
//! `max_i |x_ij|∞` exceeds the rest threshold.
//!
//! Parameters are per column (the seed's column spreading, §4.2): column j
//! uses the ratio r_j and damping (b_j or B_j) of vertex j for every row i.
//!
//! Left out: the seed's non-square display/haptic DGFMs and Loop
//! subdivision (display = haptic mesh here), collision detection (the
//! contact vertex or triangle is given), the quasi-static model on the
//! haptic device (the device gets the same viscoelastic answer).
use super::dgfm::Dgfm;
use super::error::{Result, VeError};
use firmware::linalg::{Mat3, Vec3};
use firmware::viscoelastic::{
    rayleigh_displacement_step, RayleighParams, ThreeElementTensor, TimeStep,
};

/// Rest threshold on `max_i |x_ij|∞` below which an unloaded column leaves
/// the active list (m). The seed uses 1e-3 in its own mesh units (§5); for
/// an object in metres we use 1 µm, below any display resolution (estimate).
pub const DEFAULT_REST_THRESHOLD_M: f64 = 1.0e-6;

/// Haptic loop period (s): the seed's ~1000 Hz haptic rate (§3, req. 4).
pub const HAPTIC_PERIOD_S: f64 = 1.0e-3;
/// Display period (s): the seed's ~30 Hz visual rate (§3, req. 4).
pub const DISPLAY_PERIOD_S: f64 = 1.0 / 30.0;

/// Per-column viscoelastic parameters of an object.
#[derive(Clone, Debug, PartialEq)]
pub enum ColumnParams {
    /// Stiffness ratio + Rayleigh damping per column (Eq. 9–12).
    Rayleigh(Vec<RayleighParams<f64>>),
    /// Stiffness ratio + general damping tensor per column (Eq. 5–6, 9–10):
    /// `ratios[j]` and `damping_n_s_per_m[j]` (N·s/m).
    Tensor {
        /// Stiffness ratio r_j per column.
        ratios: Vec<f64>,
        /// Damping tensor B_j per column (N·s/m).
        damping_n_s_per_m: Vec<Mat3<f64>>,
    },
}

impl ColumnParams {
    /// The same Rayleigh parameters for every column.
    pub fn uniform_rayleigh(n: usize, ratio: f64, b_s: f64) -> Result<Self> {
        let p = RayleighParams::new(ratio, b_s)
            .map_err(|e| VeError::Core(e, "uniform Rayleigh parameters"))?;
        Ok(ColumnParams::Rayleigh(vec![p; n]))
    }

    /// Number of columns.
    pub fn len(&self) -> usize {
        match self {
            ColumnParams::Rayleigh(p) => p.len(),
            ColumnParams::Tensor { ratios, .. } => ratios.len(),
        }
    }

    /// True when there are no columns.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Damping magnitude per column for display (the seed's Fig. 9): the
    /// Rayleigh coefficient b_j (s) times ‖K_jj‖_F, or ‖B_j‖_F (N·s/m).
    pub fn damping_magnitude_n_s_per_m(&self, dgfm: &Dgfm) -> Vec<f64> {
        let frob = |m: &Mat3<f64>| m.0.iter().flatten().map(|v| v * v).sum::<f64>().sqrt();
        match self {
            ColumnParams::Rayleigh(p) => p
                .iter()
                .enumerate()
                .map(|(j, q)| q.b_s() * dgfm.stiffness(j, j).map(|k| frob(&k)).unwrap_or(0.0))
                .collect(),
            ColumnParams::Tensor {
                damping_n_s_per_m, ..
            } => damping_n_s_per_m.iter().map(frob).collect(),
        }
    }
}

enum Update {
    Rayleigh(Vec<RayleighParams<f64>>),
    /// Column-major precomputed pairs for one fixed step.
    Tensor {
        pairs: Vec<ThreeElementTensor<f64>>,
        h: TimeStep<f64>,
    },
}

struct ActiveColumn {
    column: usize,
    traction_pa: Vec3<f64>,
    x_m: Vec<Vec3<f64>>,
}

/// A viscoelastic object: traction in, displacement out, over its DGFM.
pub struct ViscoObject {
    dgfm: Dgfm,
    update: Update,
    active: Vec<ActiveColumn>,
    rest_threshold_m: f64,
}

impl ViscoObject {
    /// An object over `dgfm` with per-column `params`. Tensor parameters are
    /// precomputed for the fixed step `h` (the seed notes, §5, that the
    /// general form is only real-time for a constant step); Rayleigh ones
    /// work with any step.
    pub fn new(dgfm: Dgfm, params: ColumnParams, h: TimeStep<f64>) -> Result<Self> {
        let n = dgfm.len();
        if params.len() != n {
            return Err(VeError::LengthMismatch {
                what: "column parameters",
                got: params.len(),
                expected: n,
            });
        }
        let update = match params {
            ColumnParams::Rayleigh(p) => Update::Rayleigh(p),
            ColumnParams::Tensor {
                ratios,
                damping_n_s_per_m,
            } => {
                if damping_n_s_per_m.len() != n {
                    return Err(VeError::LengthMismatch {
                        what: "damping tensors",
                        got: damping_n_s_per_m.len(),
                        expected: n,
                    });
                }
                let mut pairs = Vec::with_capacity(n * n);
                for j in 0..n {
                    for i in 0..n {
                        pairs.push(
                            ThreeElementTensor::from_dgfm_entry(
                                dgfm.xi(i, j),
                                dgfm.areas_m2()[j],
                                ratios[j],
                                damping_n_s_per_m[j],
                                h,
                            )
                            .map_err(|e| {
                                VeError::Core(e, "tensor pair (check Ξ_ij invertible, ratio > 0)")
                            })?,
                        );
                    }
                }
                Update::Tensor { pairs, h }
            }
        };
        Ok(ViscoObject {
            dgfm,
            update,
            active: Vec::new(),
            rest_threshold_m: DEFAULT_REST_THRESHOLD_M,
        })
    }

    /// The DGFM.
    pub fn dgfm(&self) -> &Dgfm {
        &self.dgfm
    }

    /// Changes the rest threshold (m, finite, ≥ 0).
    pub fn set_rest_threshold_m(&mut self, threshold_m: f64) -> Result<()> {
        self.rest_threshold_m = super::error::check_non_negative("rest_threshold_m", threshold_m)?;
        Ok(())
    }

    /// Applies traction `p` (Pa) to DGFM column `j` from the next step on
    /// (zero releases it; it stays active until relaxed).
    pub fn set_traction(&mut self, j: usize, traction_pa: Vec3<f64>) -> Result<()> {
        let n = self.dgfm.len();
        if j >= n {
            return Err(VeError::VertexNotInTractionSet { vertex: j, n });
        }
        if !traction_pa.is_finite() {
            return Err(VeError::Core(
                firmware::viscoelastic::ViscoError::NonFiniteInput,
                "traction",
            ));
        }
        if let Some(col) = self.active.iter_mut().find(|c| c.column == j) {
            col.traction_pa = traction_pa;
        } else if !traction_pa.is_zero() {
            self.active.push(ActiveColumn {
                column: j,
                traction_pa,
                x_m: vec![Vec3::zero(); n],
            });
        }
        Ok(())
    }

    /// Releases every traction.
    pub fn release_all(&mut self) {
        for c in &mut self.active {
            c.traction_pa = Vec3::zero();
        }
    }

    /// Number of active columns.
    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    /// Current traction on column j (Pa; zero if inactive).
    pub fn traction_pa(&self, j: usize) -> Vec3<f64> {
        self.active
            .iter()
            .find(|c| c.column == j)
            .map(|c| c.traction_pa)
            .unwrap_or_else(Vec3::zero)
    }

    /// Advances one step of `h` and writes `u_i = Σ_j u_ij` (m) for every
    /// traction vertex into `out` (length n). No allocation.
    pub fn step(&mut self, h: TimeStep<f64>, out: &mut [Vec3<f64>]) -> Result<()> {
        let n = self.dgfm.len();
        if out.len() != n {
            return Err(VeError::LengthMismatch {
                what: "displacement output",
                got: out.len(),
                expected: n,
            });
        }
        out.iter_mut().for_each(|u| *u = Vec3::zero());
        match &self.update {
            Update::Rayleigh(params) => {
                for col in &mut self.active {
                    let j = col.column;
                    let (p, q) = (col.traction_pa, params[j]);
                    for ((u, x), blk) in out
                        .iter_mut()
                        .zip(col.x_m.iter_mut())
                        .zip(self.dgfm.xi_column(j))
                    {
                        *u = *u + rayleigh_displacement_step(blk, p, q, h, x);
                    }
                }
            }
            Update::Tensor { pairs, h: h_fixed } => {
                if h != *h_fixed {
                    return Err(VeError::InvalidParameter {
                        name: "h",
                        value: h.seconds(),
                        reason: "tensor damping is precomputed for one fixed step (seed §5); rebuild the object for another",
                    });
                }
                for col in &mut self.active {
                    let j = col.column;
                    let f = col.traction_pa.scale(self.dgfm.areas_m2()[j]);
                    let column_pairs = &pairs[j * n..(j + 1) * n];
                    for ((u, x), pair) in out.iter_mut().zip(col.x_m.iter_mut()).zip(column_pairs) {
                        *u = *u + pair.step_displacement(x, f);
                    }
                }
            }
        }
        let threshold = self.rest_threshold_m;
        self.active
            .retain(|c| !c.traction_pa.is_zero() || c.x_m.iter().any(|x| x.max_abs() > threshold));
        Ok(())
    }
}

/// Where the haptic proxy touches the object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Contact {
    /// At a mesh vertex.
    Vertex(usize),
    /// Inside a mesh triangle, at barycentric coordinates (summing to 1).
    Triangle {
        /// Triangle index.
        triangle: usize,
        /// Barycentric weights of its three vertices.
        barycentric: [f64; 3],
    },
}

/// One haptic-rate sample.
#[derive(Clone, Debug, PartialEq)]
pub struct HapticSample {
    /// Time at the end of the step (s).
    pub time_s: f64,
    /// Applied probe force (N).
    pub force_n: [f64; 3],
    /// Displacement of the contact point (m), barycentric over the contact.
    pub contact_displacement_m: [f64; 3],
}

/// One display-rate frame: every mesh vertex.
#[derive(Clone, Debug, PartialEq)]
pub struct DisplayFrame {
    /// Time (s).
    pub time_s: f64,
    /// Displacement per mesh vertex (m); zero on Λu.
    pub displacement_m: Vec<[f64; 3]>,
    /// Applied force per mesh vertex (N).
    pub force_n: Vec<[f64; 3]>,
}

/// The 1 kHz haptic loop: force at a contact in, contact displacement out,
/// and a display frame every 1/30 s.
pub struct HapticLoop {
    object: ViscoObject,
    h: TimeStep<f64>,
    step_count: u64,
    frames_emitted: u64,
    loaded: Vec<(usize, f64)>,
    u: Vec<Vec3<f64>>,
    /// Display frames emitted so far.
    pub frames: Vec<DisplayFrame>,
}

impl HapticLoop {
    /// A loop at the seed's haptic rate (1 ms steps).
    pub fn new(object: ViscoObject) -> Result<Self> {
        let h = TimeStep::new(HAPTIC_PERIOD_S).map_err(|e| VeError::Core(e, "haptic period"))?;
        let n = object.dgfm().len();
        Ok(HapticLoop {
            object,
            h,
            step_count: 0,
            frames_emitted: 0,
            loaded: Vec::with_capacity(3),
            u: vec![Vec3::zero(); n],
            frames: Vec::new(),
        })
    }

    /// The object.
    pub fn object(&self) -> &ViscoObject {
        &self.object
    }

    /// Time at the end of the last step (s).
    pub fn time_s(&self) -> f64 {
        self.step_count as f64 * self.h.seconds()
    }

    /// Mesh vertices under the contact and their weights (up to 3; the
    /// count is returned beside them, so nothing is allocated per step).
    fn contact_weights(&self, contact: Contact) -> Result<([(usize, f64); 3], usize)> {
        let mesh = self.object.dgfm().mesh();
        match contact {
            Contact::Vertex(v) if v < mesh.len() => Ok(([(v, 1.0), (0, 0.0), (0, 0.0)], 1)),
            Contact::Vertex(v) => Err(VeError::VertexNotInTractionSet {
                vertex: v,
                n: mesh.len(),
            }),
            Contact::Triangle {
                triangle,
                barycentric,
            } => {
                let tri = mesh
                    .triangles
                    .get(triangle)
                    .ok_or(VeError::InvalidParameter {
                        name: "triangle",
                        value: triangle as f64,
                        reason: "no such triangle",
                    })?;
                let sum: f64 = barycentric.iter().sum();
                if !(barycentric.iter().all(|w| w.is_finite() && *w >= 0.0)
                    && (sum - 1.0).abs() < 1e-9)
                {
                    return Err(VeError::InvalidParameter {
                        name: "barycentric",
                        value: sum,
                        reason: "weights must be >= 0 and sum to 1",
                    });
                }
                Ok((
                    [
                        (tri[0], barycentric[0]),
                        (tri[1], barycentric[1]),
                        (tri[2], barycentric[2]),
                    ],
                    3,
                ))
            }
        }
    }

    /// One haptic step: the probe pushes with `force_n` at `contact` (or
    /// nothing touches the object). Returns the contact displacement (m).
    /// Allocation-free after the first frames (display frames allocate).
    pub fn step(&mut self, contact: Option<(Contact, [f64; 3])>) -> Result<[f64; 3]> {
        let (weights, count, force) = match contact {
            Some((c, f)) => {
                if !f.iter().all(|v| v.is_finite()) {
                    return Err(VeError::InvalidParameter {
                        name: "force_n",
                        value: f64::NAN,
                        reason: "must be finite",
                    });
                }
                let (w, n) = self.contact_weights(c)?;
                (w, n, f)
            }
            None => ([(0, 0.0); 3], 0, [0.0; 3]),
        };
        let weights = &weights[..count];
        // Release vertices that are no longer under the probe.
        for k in 0..self.loaded.len() {
            let v = self.loaded[k].0;
            if !weights.iter().any(|&(w, _)| w == v) {
                if let Ok(j) = self.object.dgfm().index_of(v) {
                    self.object.set_traction(j, Vec3::zero())?;
                }
            }
        }
        self.loaded.clear();
        for &(v, w) in weights {
            self.loaded.push((v, w));
            // A contact on Λu pushes on the support: no traction on the object.
            if let Ok(j) = self.object.dgfm().index_of(v) {
                let alpha = self.object.dgfm().areas_m2()[j];
                let traction = Vec3::new(force[0], force[1], force[2]).scale(w / alpha);
                if !traction.is_finite() {
                    return Err(VeError::InvalidParameter {
                        name: "force_n",
                        value: force.iter().fold(0.0, |m, f| f.abs().max(m)),
                        reason: "too large: divided by the contact vertex's area it is not a finite traction",
                    });
                }
                self.object.set_traction(j, traction)?;
            }
        }
        self.object.step(self.h, &mut self.u)?;
        self.step_count += 1;
        let mut out = [0.0; 3];
        for &(v, w) in &self.loaded {
            if let Ok(j) = self.object.dgfm().index_of(v) {
                for (o, c) in out.iter_mut().zip(self.u[j].0) {
                    *o += w * c;
                }
            }
        }
        let t = self.time_s();
        // A frame whenever a new 1/30 s display tick has been passed.
        let due = (t / DISPLAY_PERIOD_S + 1e-9).floor() as u64;
        if due >= self.frames_emitted {
            self.frames.push(self.display_frame(t));
            self.frames_emitted = due + 1;
        }
        Ok(out)
    }

    /// Displacement and applied force of every mesh vertex now.
    pub fn display_frame(&self, time_s: f64) -> DisplayFrame {
        let d = self.object.dgfm();
        let nv = d.mesh().len();
        let mut displacement_m = vec![[0.0; 3]; nv];
        let mut force_n = vec![[0.0; 3]; nv];
        for (j, &v) in d.traction_vertices().iter().enumerate() {
            displacement_m[v] = self.u[j].0;
            force_n[v] = self.object.traction_pa(j).scale(d.areas_m2()[j]).0;
        }
        DisplayFrame {
            time_s,
            displacement_m,
            force_n,
        }
    }
}

/// A piecewise-constant scripted probe: from `time_s` on, push with
/// `force_n` at `contact` (or release when `contact` is `None`).
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeEvent {
    /// Start time of this event (s).
    pub time_s: f64,
    /// Where the probe touches, or `None` for no contact.
    pub contact: Option<Contact>,
    /// Probe force (N).
    pub force_n: [f64; 3],
}

/// Runs `events` (sorted by time) on the loop for `duration_s`, returning
/// every haptic sample.
pub fn run_script(
    haptic: &mut HapticLoop,
    events: &[ProbeEvent],
    duration_s: f64,
) -> Result<Vec<HapticSample>> {
    super::error::check_positive("duration_s", duration_s)?;
    if events
        .windows(2)
        .any(|w| w[1].time_s.partial_cmp(&w[0].time_s) != Some(std::cmp::Ordering::Greater))
    {
        return Err(VeError::InvalidParameter {
            name: "probe events",
            value: f64::NAN,
            reason: "event times must be strictly increasing",
        });
    }
    let steps = (duration_s / HAPTIC_PERIOD_S).round() as u64;
    let mut samples = Vec::with_capacity(steps as usize);
    for k in 0..steps {
        let t = k as f64 * HAPTIC_PERIOD_S;
        let ev = events
            .iter()
            .enumerate()
            .take_while(|(_, e)| e.time_s <= t + 1e-12)
            .last();
        let input = ev.and_then(|(_, e)| e.contact.map(|c| (c, e.force_n)));
        let u = haptic.step(input).map_err(|error| match ev {
            Some((index, e)) => VeError::ProbeEvent {
                index,
                time_s: e.time_s,
                error: Box::new(error),
            },
            None => error,
        })?;
        samples.push(HapticSample {
            time_s: haptic.time_s(),
            force_n: input.map(|(_, f)| f).unwrap_or([0.0; 3]),
            contact_displacement_m: u,
        });
    }
    Ok(samples)
}
