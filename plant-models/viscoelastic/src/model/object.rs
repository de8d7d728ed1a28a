//! Viscoelastic evaluation of a DGFM object (seed 002 Eq. 4–12, §4.2, §5):
//! the plant's reference, and its 1 kHz haptic driver with a 30 Hz display
//! output.
//!
//! Every (i, j) pair is the 3-element model integrated exactly
//! ([`three_element`](super::three_element)): Rayleigh columns as the
//! scalar creep element on the static response `y = Ξ_ij p_j` (Eq. 12's
//! substitution, solved exactly), tensor columns with the column's
//! relaxation-rate tensor ([`TensorColumn`]: the seed's Eq. 5–6 on the
//! diagonal; see there why not the literal `B_·,k = B_k` spreading). A
//! traction set for a step
//! is held over that step (piecewise constant in time), so the answer does
//! not depend on the step length. The firmware's DGFM update (implicit
//! first order, seed §3) is tested against this one; the two share no code.
//!
//! The active-column rule is the seed's (§5): a column is active while
//! traction is applied or while `max_i |x_ij|∞` exceeds the rest
//! threshold. Parameters are per column (the seed's column spreading,
//! §4.2): column j uses the ratio r_j and damping (b_j or B_j) of vertex j
//! for every row i.
//!
//! [`HapticLoop`] drives any [`TractionModel`] — this reference, or (in
//! `host-tools`) the firmware's real-time update — at the seed's rates.
//!
//! Left out: the seed's non-square display/haptic DGFMs and Loop
//! subdivision (display = haptic mesh here), collision detection (the
//! contact vertex or triangle is given), the quasi-static model on the
//! haptic device (the device gets the same viscoelastic answer).
use super::dgfm::Dgfm;
use super::three_element::{ExactStep, RayleighColumn, StepLength, TensorColumn};
use crate::error::{check_non_negative, check_positive, Result, VeError};
use crate::{Mat3, Vec3};

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
    Rayleigh(Vec<RayleighColumn>),
    /// Stiffness ratio + general damping tensor per column (Eq. 5–6, 9–10):
    /// `ratios[j]` and `damping_n_s_per_m[j]` (N·s/m).
    Tensor {
        /// Stiffness ratio r_j per column.
        ratios: Vec<f64>,
        /// Damping tensor B_j per column (N·s/m).
        damping_n_s_per_m: Vec<Mat3>,
    },
}

impl ColumnParams {
    /// The same Rayleigh parameters for every column.
    pub fn uniform_rayleigh(n: usize, ratio: f64, b_s: f64) -> Result<Self> {
        Ok(ColumnParams::Rayleigh(vec![
            RayleighColumn::new(ratio, b_s)?;
            n
        ]))
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
        match self {
            ColumnParams::Rayleigh(p) => p
                .iter()
                .enumerate()
                .map(|(j, q)| q.b_s() * dgfm.stiffness(j, j).map(|k| k.norm()).unwrap_or(0.0))
                .collect(),
            ColumnParams::Tensor {
                damping_n_s_per_m, ..
            } => damping_n_s_per_m.iter().map(|b| b.norm()).collect(),
        }
    }
}

/// What the haptic loop needs of an object model: tractions in,
/// displacements out, over a DGFM.
pub trait TractionModel {
    /// The DGFM the model evaluates.
    fn dgfm(&self) -> &Dgfm;
    /// Applies traction `p` (Pa) to DGFM column `j` from the next step on
    /// (zero releases it; it stays active until relaxed).
    fn set_traction(&mut self, j: usize, traction_pa: Vec3) -> Result<()>;
    /// Current traction on column j (Pa; zero if inactive).
    fn traction_pa(&self, j: usize) -> Vec3;
    /// Number of active columns.
    fn active_count(&self) -> usize;
    /// Advances one step of `h_s` and writes `u_i = Σ_j u_ij` (m) for every
    /// traction vertex into `out` (length n).
    fn step(&mut self, h_s: f64, out: &mut [Vec3]) -> Result<()>;
}

enum Update {
    Rayleigh {
        params: Vec<RayleighColumn>,
        /// The exact step of every column for `h` (recomputed when the
        /// step changes).
        steps: Vec<ExactStep>,
        h: StepLength,
    },
    /// Per-column precomputed updates for one fixed step.
    Tensor {
        columns: Vec<TensorColumn>,
        h: StepLength,
    },
}

struct ActiveColumn {
    column: usize,
    traction_pa: Vec3,
    x_m: Vec<Vec3>,
}

/// A viscoelastic object: traction in, displacement out, over its DGFM —
/// the plant's exact reference.
pub struct ViscoObject {
    dgfm: Dgfm,
    update: Update,
    active: Vec<ActiveColumn>,
    rest_threshold_m: f64,
}

impl ViscoObject {
    /// An object over `dgfm` with per-column `params`. Tensor parameters are
    /// precomputed for the fixed step `h_s` (the seed notes, §5, that the
    /// general form is only real-time for a constant step); Rayleigh ones
    /// work with any step.
    pub fn new(dgfm: Dgfm, params: ColumnParams, h_s: f64) -> Result<Self> {
        let h = StepLength::new(h_s)?;
        let n = dgfm.len();
        if params.len() != n {
            return Err(VeError::LengthMismatch {
                what: "column parameters",
                got: params.len(),
                expected: n,
            });
        }
        let update = match params {
            ColumnParams::Rayleigh(params) => Update::Rayleigh {
                steps: params.iter().map(|p| p.step(h)).collect(),
                params,
                h,
            },
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
                let mut columns = Vec::with_capacity(n);
                for j in 0..n {
                    let k = dgfm.stiffness(j, j).ok_or(VeError::InvalidParameter {
                        name: "Ξ_jj",
                        value: j as f64,
                        reason: "singular: the tensor form needs K_jj = α_j Ξ_jj⁻¹",
                    })?;
                    columns.push(
                        TensorColumn::new(k, damping_n_s_per_m[j], ratios[j], h).map_err(|e| {
                            VeError::Column {
                                column: j,
                                vertex: dgfm.traction_vertices()[j],
                                error: Box::new(e.into()),
                            }
                        })?,
                    );
                }
                Update::Tensor { columns, h }
            }
        };
        Ok(ViscoObject {
            dgfm,
            update,
            active: Vec::new(),
            rest_threshold_m: DEFAULT_REST_THRESHOLD_M,
        })
    }

    /// Changes the rest threshold (m, finite, ≥ 0).
    pub fn set_rest_threshold_m(&mut self, threshold_m: f64) -> Result<()> {
        self.rest_threshold_m = check_non_negative("rest_threshold_m", threshold_m)?;
        Ok(())
    }

    /// Releases every traction.
    pub fn release_all(&mut self) {
        for c in &mut self.active {
            c.traction_pa = Vec3::zeros();
        }
    }
}

impl TractionModel for ViscoObject {
    fn dgfm(&self) -> &Dgfm {
        &self.dgfm
    }

    fn set_traction(&mut self, j: usize, traction_pa: Vec3) -> Result<()> {
        let n = self.dgfm.len();
        if j >= n {
            return Err(VeError::VertexNotInTractionSet { vertex: j, n });
        }
        if !traction_pa.iter().all(|v| v.is_finite()) {
            return Err(VeError::InvalidParameter {
                name: "traction",
                value: f64::NAN,
                reason: "must be finite",
            });
        }
        if let Some(col) = self.active.iter_mut().find(|c| c.column == j) {
            col.traction_pa = traction_pa;
        } else if traction_pa != Vec3::zeros() {
            self.active.push(ActiveColumn {
                column: j,
                traction_pa,
                x_m: vec![Vec3::zeros(); n],
            });
        }
        Ok(())
    }

    fn traction_pa(&self, j: usize) -> Vec3 {
        self.active
            .iter()
            .find(|c| c.column == j)
            .map(|c| c.traction_pa)
            .unwrap_or_else(Vec3::zeros)
    }

    fn active_count(&self) -> usize {
        self.active.len()
    }

    fn step(&mut self, h_s: f64, out: &mut [Vec3]) -> Result<()> {
        let h = StepLength::new(h_s)?;
        let n = self.dgfm.len();
        if out.len() != n {
            return Err(VeError::LengthMismatch {
                what: "displacement output",
                got: out.len(),
                expected: n,
            });
        }
        out.iter_mut().for_each(|u| *u = Vec3::zeros());
        match &mut self.update {
            Update::Rayleigh {
                params,
                steps,
                h: cached,
            } => {
                if h != *cached {
                    *steps = params.iter().map(|p| p.step(h)).collect();
                    *cached = h;
                }
                for col in &mut self.active {
                    let j = col.column;
                    let (p, step) = (col.traction_pa, steps[j]);
                    for ((u, x), blk) in out
                        .iter_mut()
                        .zip(col.x_m.iter_mut())
                        .zip(self.dgfm.xi_column(j))
                    {
                        // The static response, held over the step.
                        let y = blk * p;
                        *u += step.displacement(x, y, y);
                    }
                }
            }
            Update::Tensor { columns, h: fixed } => {
                if h != *fixed {
                    return Err(VeError::InvalidParameter {
                        name: "h",
                        value: h_s,
                        reason: "tensor damping is precomputed for one fixed step (seed §5); rebuild the object for another",
                    });
                }
                for col in &mut self.active {
                    let j = col.column;
                    let (p, column) = (col.traction_pa, &columns[j]);
                    for ((u, x), blk) in out
                        .iter_mut()
                        .zip(col.x_m.iter_mut())
                        .zip(self.dgfm.xi_column(j))
                    {
                        let y = blk * p;
                        *u += column.displacement(x, y, y);
                    }
                }
            }
        }
        let threshold = self.rest_threshold_m;
        self.active.retain(|c| {
            c.traction_pa != Vec3::zeros() || c.x_m.iter().any(|x| x.amax() > threshold)
        });
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
/// and a display frame every 1/30 s, over any [`TractionModel`].
pub struct HapticLoop<M = ViscoObject> {
    object: M,
    step_count: u64,
    frames_emitted: u64,
    loaded: Vec<(usize, f64)>,
    u: Vec<Vec3>,
    /// Display frames emitted so far.
    pub frames: Vec<DisplayFrame>,
}

impl<M: TractionModel> HapticLoop<M> {
    /// A loop at the seed's haptic rate (1 ms steps).
    pub fn new(object: M) -> Result<Self> {
        let n = object.dgfm().len();
        Ok(HapticLoop {
            object,
            step_count: 0,
            frames_emitted: 0,
            loaded: Vec::with_capacity(3),
            u: vec![Vec3::zeros(); n],
            frames: Vec::new(),
        })
    }

    /// The object.
    pub fn object(&self) -> &M {
        &self.object
    }

    /// Displacements of every traction vertex after the last step (m).
    pub fn displacements_m(&self) -> &[Vec3] {
        &self.u
    }

    /// Time at the end of the last step (s).
    pub fn time_s(&self) -> f64 {
        self.step_count as f64 * HAPTIC_PERIOD_S
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
                    self.object.set_traction(j, Vec3::zeros())?;
                }
            }
        }
        self.loaded.clear();
        for &(v, w) in weights {
            self.loaded.push((v, w));
            // A contact on Λu pushes on the support: no traction on the object.
            if let Ok(j) = self.object.dgfm().index_of(v) {
                let alpha = self.object.dgfm().areas_m2()[j];
                let traction = Vec3::from(force) * (w / alpha);
                if !traction.iter().all(|v| v.is_finite()) {
                    return Err(VeError::InvalidParameter {
                        name: "force_n",
                        value: force.iter().fold(0.0, |m, f| f.abs().max(m)),
                        reason: "too large: divided by the contact vertex's area it is not a finite traction",
                    });
                }
                self.object.set_traction(j, traction)?;
            }
        }
        self.object.step(HAPTIC_PERIOD_S, &mut self.u)?;
        self.step_count += 1;
        let mut out = [0.0; 3];
        for &(v, w) in &self.loaded {
            if let Ok(j) = self.object.dgfm().index_of(v) {
                for (o, c) in out.iter_mut().zip(self.u[j].iter()) {
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
            displacement_m[v] = self.u[j].into();
            force_n[v] = (self.object.traction_pa(j) * d.areas_m2()[j]).into();
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
pub fn run_script<M: TractionModel>(
    haptic: &mut HapticLoop<M>,
    events: &[ProbeEvent],
    duration_s: f64,
) -> Result<Vec<HapticSample>> {
    check_positive("duration_s", duration_s)?;
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
