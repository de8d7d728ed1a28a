//! The measured-object pipeline of seed §4–5, in the order it runs:
//!
//! 1. [`object_dgfm`]: the DGFM of a mesh resting on its support (the
//!    lowest [`DEFAULT_SUPPORT_HEIGHT_FRACTION`] of its height), from the
//!    linear-elastic FEM;
//! 2. [`Campaign::simulate`]: synthetic ground truth at every N-th traction
//!    vertex and the simulated probe trials that measure it;
//! 3. [`Campaign::identify`]: per-trial fits, per-vertex estimates, and the
//!    columns spread over the whole object (Rayleigh or tensor damping);
//! 4. [`probe_beside_reference`]: a scripted probe at 1 kHz on a haptic
//!    model (in `softjoint`, the firmware's real-time update, which this
//!    crate must not depend on) beside the plant's exact reference, and how
//!    far the two end apart.
//!
//! The ground truth is synthetic (estimates, not measurements): Rayleigh b
//! larger in the middle of the object than at its ends, like the seed's
//! triceratops (Fig. 9), stiffness ratio from the seed's Fig. 8 fit.
use crate::dgfm::{support_below, Dgfm, DEFAULT_SUPPORT_HEIGHT_FRACTION};
use crate::error::Result;
use crate::estimate::{estimate_all, spread_columns, VertexEstimate};
use crate::fem::{LinearElastic, DEFAULT_SHELL_SCALES};
use crate::fit::{fit_trials, NelderMeadOptions, Weighting};
use crate::measure::{simulate_campaign, ProbeProtocol, Trial, VertexTruth};
use crate::object::{
    run_script, Contact, DisplayFrame, HapticLoop, HapticSample, ProbeEvent, TractionModel,
    HAPTIC_PERIOD_S,
};
use crate::{ColumnParams, SurfaceMesh, ViscoObject};

/// Stiffness ratio of the synthetic ground truth (the seed's Fig. 8 fit).
pub const TRUTH_STIFFNESS_RATIO: f64 = 0.29;

/// Probe speed of the simulated campaign (m/s).
pub const CAMPAIGN_SPEED_M_PER_S: f64 = 20.0e-3;

/// Step 1: the DGFM of `mesh` on its support.
pub fn object_dgfm(mesh: SurfaceMesh) -> Result<Dgfm> {
    let fixed = support_below(&mesh, DEFAULT_SUPPORT_HEIGHT_FRACTION);
    Dgfm::from_mesh(mesh, LinearElastic::default(), fixed, &DEFAULT_SHELL_SCALES)
}

/// Step 2's result: the ground truth and the trials that measured it.
#[derive(Clone, Debug)]
pub struct Campaign {
    /// The truth at every probed traction vertex.
    pub truths: Vec<VertexTruth>,
    /// The simulated probe trials.
    pub trials: Vec<Trial>,
}

/// Step 3's result: what was estimated and the object's columns.
#[derive(Clone, Debug)]
pub struct IdentifiedObject {
    /// Per-vertex estimates (vertices whose trials were fitted).
    pub estimates: Vec<VertexEstimate>,
    /// The columns spread over every traction vertex.
    pub params: ColumnParams,
    /// Damping magnitude per mesh vertex (N·s/m; 0 on the support).
    pub damping_per_vertex_n_s_per_m: Vec<f64>,
}

impl Campaign {
    /// Step 2: truth at every `probe_every`-th traction vertex (at least
    /// 1), probed at [`CAMPAIGN_SPEED_M_PER_S`] with noise seeded by
    /// `seed`.
    pub fn simulate(dgfm: &Dgfm, probe_every: usize, seed: u64) -> Result<Self> {
        let truths = synthetic_truth(dgfm, probe_every)?;
        let protocol = ProbeProtocol {
            speeds_m_per_s: vec![CAMPAIGN_SPEED_M_PER_S],
            ..ProbeProtocol::default()
        };
        let trials = simulate_campaign(dgfm, &truths, &protocol, seed)?;
        Ok(Campaign { truths, trials })
    }

    /// The 1D parameters (k1, k2, b) that generated `trial`, if it belongs
    /// to this campaign.
    pub fn trial_scalars(&self, trial: &Trial) -> Option<(f64, f64, f64)> {
        self.truths
            .iter()
            .find(|v| v.vertex == trial.vertex)
            .map(|truth| truth.trial_scalars(trial.direction))
    }

    /// Step 3: fit every trial with the seed's weighting, estimate each
    /// probed vertex, and spread the columns (`tensor`: general damping
    /// tensors instead of Rayleigh damping).
    pub fn identify(&self, dgfm: &Dgfm, tensor: bool) -> Result<IdentifiedObject> {
        let fits = fit_trials(&self.trials, Weighting::Seed, NelderMeadOptions::default());
        let estimates = estimate_all(dgfm, &self.trials, &fits)?;
        let params = spread_columns(dgfm.len(), &estimates, 1.0, tensor)?;
        let magnitude = params.damping_magnitude_n_s_per_m(dgfm);
        let mut per_vertex = vec![0.0; dgfm.mesh().len()];
        for (j, &v) in dgfm.traction_vertices().iter().enumerate() {
            per_vertex[v] = magnitude[j];
        }
        Ok(IdentifiedObject {
            estimates,
            params,
            damping_per_vertex_n_s_per_m: per_vertex,
        })
    }
}

/// The synthetic truth at every `every`-th traction vertex: Rayleigh b
/// from 0.5 s in the middle (x = 0) down to 0.1 s at the ends.
fn synthetic_truth(dgfm: &Dgfm, every: usize) -> Result<Vec<VertexTruth>> {
    let mesh = dgfm.mesh();
    let x_max = mesh
        .vertices_m
        .iter()
        .map(|v| v[0].abs())
        .fold(0.0, f64::max)
        .max(1e-12);
    let mut out = Vec::new();
    for j in (0..dgfm.len()).step_by(every.max(1)) {
        let x = mesh.vertices_m[dgfm.traction_vertices()[j]][0].abs() / x_max;
        out.push(VertexTruth::from_dgfm(
            dgfm,
            j,
            TRUTH_STIFFNESS_RATIO,
            0.1 + 0.4 * (1.0 - x),
        )?);
    }
    Ok(out)
}

/// The default probe script: 1 N straight down on the highest traction
/// vertex for 0.5 s, then release (`None` when no vertex is free).
pub fn default_probe_script(dgfm: &Dgfm) -> Option<Vec<ProbeEvent>> {
    let vertices = &dgfm.mesh().vertices_m;
    let top = (0..dgfm.mesh().len())
        .filter(|&v| !dgfm.fixed()[v])
        .max_by(|&a, &b| vertices[a][2].total_cmp(&vertices[b][2]))?;
    Some(vec![
        ProbeEvent {
            time_s: 0.0,
            contact: Some(Contact::Vertex(top)),
            force_n: [0.0, 0.0, -1.0],
        },
        ProbeEvent {
            time_s: 0.5,
            contact: None,
            force_n: [0.0; 3],
        },
    ])
}

/// Step 4's result: the haptic model's samples and display frames, the
/// reference's samples, and how far apart they are.
#[derive(Clone, Debug)]
pub struct ProbeRun {
    /// The haptic model's samples, one per 1 ms step.
    pub samples: Vec<HapticSample>,
    /// The haptic model's display frames (30 Hz).
    pub frames: Vec<DisplayFrame>,
    /// The exact reference's samples.
    pub exact_samples: Vec<HapticSample>,
    /// Haptic model against the exact reference.
    pub difference: ModelDifference,
}

/// Step 4: runs `events` for `duration_s` on the plant's exact reference
/// and on the haptic model that `model` builds from the same DGFM and
/// columns at [`HAPTIC_PERIOD_S`].
pub fn probe_beside_reference<M: TractionModel>(
    dgfm: &Dgfm,
    params: &ColumnParams,
    events: &[ProbeEvent],
    duration_s: f64,
    model: impl FnOnce(Dgfm, &ColumnParams) -> Result<M>,
) -> Result<ProbeRun> {
    let reference = ViscoObject::new(dgfm.clone(), params.clone(), HAPTIC_PERIOD_S)?;
    let mut exact = HapticLoop::new(reference)?;
    let exact_samples = run_script(&mut exact, events, duration_s)?;
    let mut haptic = HapticLoop::new(model(dgfm.clone(), params)?)?;
    let samples = run_script(&mut haptic, events, duration_s)?;
    let difference = ModelDifference::of(&samples, &exact_samples, &haptic.frames, &exact.frames);
    Ok(ProbeRun {
        samples,
        frames: haptic.frames,
        exact_samples,
        difference,
    })
}

/// How far a haptic model's displacements are from the exact reference's
/// over a run: largest distance (m) and that relative to the largest
/// reference displacement, at the contact and over all vertices of the
/// display frames.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelDifference {
    pub contact_m: f64,
    pub contact_rel: f64,
    pub frames_m: f64,
    pub frames_rel: f64,
}

impl ModelDifference {
    /// The difference of `model` from `exact`, sample by sample and frame
    /// by frame.
    pub fn of(
        model: &[HapticSample],
        exact: &[HapticSample],
        model_frames: &[DisplayFrame],
        exact_frames: &[DisplayFrame],
    ) -> Self {
        let dist = |a: [f64; 3], b: [f64; 3]| {
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
        };
        let norm = |a: [f64; 3]| dist(a, [0.0; 3]);
        let (mut contact_m, mut contact_max) = (0.0f64, 0.0f64);
        for (c, e) in model.iter().zip(exact) {
            contact_m = contact_m.max(dist(c.contact_displacement_m, e.contact_displacement_m));
            contact_max = contact_max.max(norm(e.contact_displacement_m));
        }
        let (mut frames_m, mut frames_max) = (0.0f64, 0.0f64);
        for (c, e) in model_frames.iter().zip(exact_frames) {
            for (a, b) in c.displacement_m.iter().zip(&e.displacement_m) {
                frames_m = frames_m.max(dist(*a, *b));
                frames_max = frames_max.max(norm(*b));
            }
        }
        let rel = |d: f64, m: f64| if m > 0.0 { d / m } else { 0.0 };
        ModelDifference {
            contact_m,
            contact_rel: rel(contact_m, contact_max),
            frames_m,
            frames_rel: rel(frames_m, frames_max),
        }
    }
}
