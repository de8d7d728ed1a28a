//! A simulator of the seed's probe measurements (§4: ACME probing, force at
//! 1 kHz, one vertex, one direction, one speed per trial).
//!
//! Each trial pushes a vertex at constant velocity along a direction û to a
//! depth, then holds. The object's response at the probed vertex is the
//! 3-element *tensor* model of its self-pair (seed Eq. 7–8) with
//! `K1 = (1+r)/r K`, `K2 = (1+r) K`, `B = b K` (Eq. 9–11;
//! `K = K_ii = α_i Ξ_ii⁻¹` from the DGFM), integrated exactly by the plant's
//! own 3-element code ([`Element`]): with `B = b K` the tensor equation
//! `B ẋ = K2 (u − x) − K1 x` is `b ẋ = (1+r) u − (1+r + (1+r)/r) x` on every
//! axis, and the force is `K (1+r)(u − x)`. The
//! force sensor reports the magnitude of the force, scaled by the growing
//! contact area at the start of loading (the reason for the seed's
//! weighting, §4.1 and Fig. 8), plus Gaussian noise; the force direction f̂
//! is the mean force direction over the hold.
//!
//! With Rayleigh truth the force stays parallel to K û, so a trial is an
//! exact 1D 3-element response with scalars `(k1, k2, b)·|K û|`
//! ([`VertexTruth::trial_scalars`]) — that is what the fits must recover.
//!
//! Left out: friction and slip of the probe, probe compliance, the
//! neighbouring vertices' contribution to the measured force, the stereo
//! displacement measurements used for the static DGFM.
use crate::dgfm::Dgfm;
use crate::error::{check_non_negative, check_positive, Result, VeError};
use crate::{Mat3, Vec3};
use plant_common::three_element::{Element, StepLength};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use rayon::prelude::*;

/// Ground-truth viscoelastic parameters of one vertex (Rayleigh form).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexTruth {
    /// DGFM index of the vertex.
    pub vertex: usize,
    /// Stiffness tensor K_ii (N/m).
    pub stiffness_n_per_m: Mat3,
    /// Stiffness ratio r = k2/k1.
    pub ratio: f64,
    /// Rayleigh coefficient b (s): B = b K.
    pub rayleigh_b_s: f64,
}

impl VertexTruth {
    /// Truth at DGFM vertex `i` of `dgfm` with ratio `r` and Rayleigh `b_s`.
    pub fn from_dgfm(dgfm: &Dgfm, i: usize, ratio: f64, rayleigh_b_s: f64) -> Result<Self> {
        check_positive("ratio", ratio)?;
        check_non_negative("rayleigh_b_s", rayleigh_b_s)?;
        let stiffness_n_per_m = dgfm.stiffness(i, i).ok_or(VeError::InvalidParameter {
            name: "vertex",
            value: i as f64,
            reason: "Ξ_ii is singular",
        })?;
        Ok(VertexTruth {
            vertex: i,
            stiffness_n_per_m,
            ratio,
            rayleigh_b_s,
        })
    }

    /// k1 = (1+r)/r and k2 = 1+r (Eq. 9–10 multipliers of K).
    pub fn multipliers(&self) -> (f64, f64) {
        ((1.0 + self.ratio) / self.ratio, 1.0 + self.ratio)
    }

    /// Damping tensor B = b K (N·s/m, Eq. 11).
    pub fn damping_tensor_n_s_per_m(&self) -> Mat3 {
        self.stiffness_n_per_m * self.rayleigh_b_s
    }

    /// The 1D 3-element scalars (k1 N/m, k2 N/m, b N·s/m) of a trial along
    /// unit direction `dir`: `(k1, k2, b)·|K û|`.
    pub fn trial_scalars(&self, dir: [f64; 3]) -> (f64, f64, f64) {
        let g = (self.stiffness_n_per_m * Vec3::from(dir)).norm();
        let (k1, k2) = self.multipliers();
        (k1 * g, k2 * g, self.rayleigh_b_s * g)
    }
}

/// How the probe is driven and sensed.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeProtocol {
    /// Indentation depth (m). Estimate: a few mm on a hand-sized toy.
    pub depth_m: f64,
    /// Probe speeds (m/s); the seed has low- and high-speed sets (Table 2).
    /// Estimate: 5 and 20 mm/s.
    pub speeds_m_per_s: Vec<f64>,
    /// Hold after the loading ramp (s). Estimate: 0.5 s, ~9 relaxation times
    /// of the seed's Fig. 8 fit.
    pub hold_s: f64,
    /// Force sampling period (s): 1 kHz (seed §4).
    pub sample_period_s: f64,
    /// Force-sensor noise standard deviation (N). Estimate: the resolution
    /// class of a small 6-axis F/T sensor (ATI Nano17: 1/320 N ≈ 3 mN),
    /// rounded up to 5 mN; the seed does not name ACME's sensor.
    pub force_noise_std_n: f64,
    /// Depth fraction over which the contact area grows to full (the
    /// measured force is scaled by `min(1, u / (fraction · depth))`).
    /// Estimate: 30 %.
    pub contact_growth_fraction: f64,
    /// Tilt of the off-normal directions from the inward normal (rad).
    /// Estimate: 30°.
    pub tilt_rad: f64,
    /// Number of off-normal directions around the normal (plus the normal).
    pub tilted_directions: usize,
}

impl Default for ProbeProtocol {
    fn default() -> Self {
        ProbeProtocol {
            depth_m: 3.0e-3,
            speeds_m_per_s: vec![5.0e-3, 20.0e-3],
            hold_s: 0.5,
            sample_period_s: 1.0e-3,
            force_noise_std_n: 5.0e-3,
            contact_growth_fraction: 0.3,
            tilt_rad: 30f64.to_radians(),
            tilted_directions: 4,
        }
    }
}

impl ProbeProtocol {
    fn validate(&self) -> Result<()> {
        check_positive("depth_m", self.depth_m)?;
        check_non_negative("hold_s", self.hold_s)?;
        check_positive("sample_period_s", self.sample_period_s)?;
        check_non_negative("force_noise_std_n", self.force_noise_std_n)?;
        check_non_negative("contact_growth_fraction", self.contact_growth_fraction)?;
        check_non_negative("tilt_rad", self.tilt_rad)?;
        if self.speeds_m_per_s.is_empty() {
            return Err(VeError::InvalidParameter {
                name: "speeds_m_per_s",
                value: 0.0,
                reason: "need at least one speed",
            });
        }
        for &v in &self.speeds_m_per_s {
            check_positive("speeds_m_per_s", v)?;
        }
        Ok(())
    }

    /// Unit probe directions at a vertex with outward normal `n`: −n and
    /// `tilted_directions` directions tilted by `tilt_rad` around it.
    pub fn directions(&self, outward_normal: [f64; 3]) -> Vec<[f64; 3]> {
        let n = -Vec3::from(outward_normal).normalize();
        // Any unit vector orthogonal to n, then the third axis.
        let helper = if n[0].abs() < 0.9 {
            Vec3::new(1.0, 0.0, 0.0)
        } else {
            Vec3::new(0.0, 1.0, 0.0)
        };
        let e1 = n.cross(&helper).normalize();
        let e2 = n.cross(&e1);
        let mut dirs = vec![n.into()];
        for k in 0..self.tilted_directions {
            let phi = 2.0 * std::f64::consts::PI * k as f64 / self.tilted_directions as f64;
            let d =
                n * self.tilt_rad.cos() + (e1 * phi.cos() + e2 * phi.sin()) * self.tilt_rad.sin();
            dirs.push(d.into());
        }
        dirs
    }
}

/// One probe trial: one vertex, one direction, one speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Trial {
    /// DGFM index of the probed vertex.
    pub vertex: usize,
    /// Unit displacement direction û of the probe.
    pub direction: [f64; 3],
    /// Probe speed (m/s).
    pub speed_m_per_s: f64,
    /// Sample times (s), 1 kHz from 0.
    pub time_s: Vec<f64>,
    /// Probe displacement along û (m).
    pub displacement_m: Vec<f64>,
    /// Measured force magnitude (N).
    pub force_n: Vec<f64>,
    /// Measured unit force direction f̂ (mean over the hold).
    pub force_direction: [f64; 3],
}

/// Simulates one trial of `truth` along `dir` at `speed`, noise from `rng`.
pub fn simulate_trial(
    truth: &VertexTruth,
    dir: [f64; 3],
    speed_m_per_s: f64,
    protocol: &ProbeProtocol,
    rng: &mut ChaCha8Rng,
) -> Result<Trial> {
    protocol.validate()?;
    check_positive("speed_m_per_s", speed_m_per_s)?;
    let (k1, k2) = truth.multipliers();
    let k = truth.stiffness_n_per_m;
    // The self-pair on every axis (module docs): multipliers of K.
    let step = Element::new(k1, k2, truth.rayleigh_b_s)?
        .relaxation_step(StepLength::new(protocol.sample_period_s)?);
    let ramp_s = protocol.depth_m / speed_m_per_s;
    let samples = ((ramp_s + protocol.hold_s) / protocol.sample_period_s).round() as usize + 1;
    let u_hat = Vec3::from(dir).normalize();
    let mut x = Vec3::zeros();
    let mut u_prev = Vec3::zeros();
    let mut time_s = Vec::with_capacity(samples);
    let mut displacement_m = Vec::with_capacity(samples);
    let mut force = Vec::with_capacity(samples);
    let mut hold_sum = Vec3::zeros();
    for s in 0..samples {
        let t = s as f64 * protocol.sample_period_s;
        let u = (speed_m_per_s * t).min(protocol.depth_m);
        let u_vec = u_hat * u;
        // The probe moves linearly between samples: exact for the ramp and
        // the hold.
        let f = if s == 0 {
            Vec3::zeros()
        } else {
            k * step.force(&mut x, u_prev, u_vec)
        };
        u_prev = u_vec;
        if t > ramp_s {
            hold_sum += f;
        }
        let contact = if protocol.contact_growth_fraction > 0.0 {
            (u / (protocol.contact_growth_fraction * protocol.depth_m)).min(1.0)
        } else {
            1.0
        };
        time_s.push(t);
        displacement_m.push(u);
        force.push(f.norm() * contact);
    }
    let sigma = protocol.force_noise_std_n;
    if sigma > 0.0 {
        let normal = Normal::new(0.0, sigma).map_err(|_| VeError::InvalidParameter {
            name: "noise",
            value: sigma,
            reason: "bad sigma",
        })?;
        for f in force.iter_mut() {
            *f += normal.sample(rng);
        }
    }
    let hold_dir = if hold_sum.norm() > 0.0 {
        hold_sum.normalize()
    } else {
        u_hat
    };
    Ok(Trial {
        vertex: truth.vertex,
        direction: u_hat.into(),
        speed_m_per_s,
        time_s,
        displacement_m,
        force_n: force,
        force_direction: hold_dir.into(),
    })
}

/// A measurement campaign: every vertex in `truths`, every direction of
/// the protocol (around each vertex's outward normal), every speed. Each
/// trial has its own RNG stream `(seed, trial index)`, so the result is the
/// same however it is scheduled (it is generated in parallel).
pub fn simulate_campaign(
    dgfm: &Dgfm,
    truths: &[VertexTruth],
    protocol: &ProbeProtocol,
    seed: u64,
) -> Result<Vec<Trial>> {
    let normals = dgfm.mesh().vertex_normals();
    let mut plan = Vec::new();
    for t in truths {
        let mesh_v =
            *dgfm
                .traction_vertices()
                .get(t.vertex)
                .ok_or(VeError::VertexNotInTractionSet {
                    vertex: t.vertex,
                    n: dgfm.len(),
                })?;
        for &speed in &protocol.speeds_m_per_s {
            for dir in protocol.directions(normals[mesh_v]) {
                plan.push((*t, dir, speed));
            }
        }
    }
    plan.par_iter()
        .enumerate()
        .map(|(k, (t, dir, speed))| {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            rng.set_stream(k as u64);
            simulate_trial(t, *dir, *speed, protocol, &mut rng)
        })
        .collect()
}
