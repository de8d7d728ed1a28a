//! Identification of the joint's plant from a user's own excitation log
//! (issue 20): the parameters a lab cannot read off a datasheet, staged so
//! each stage is well posed, with uncertainties, the parameters the log
//! does not determine named, and a held-out validation.
//!
//! Stages, per plane (the 3D joint's planes are independent in the model,
//! so α and β are identified apart):
//! 1. **Electrical and thermal** (only where the log has coil currents
//!    and resistances): the driver's transconductance g and turn-on
//!    voltage by linear least squares of the current on the input over the
//!    steady, unsaturated rows, chosen by their input, not by the noisy
//!    current ([`regression`]); then the convection coefficient h (the thermal
//!    time constant) and the four transformation temperatures by fitting
//!    the coil's own thermal and phase model, heated by the *measured*
//!    current, to the measured resistance (the resistance is the phase:
//!    R = ξR_M + (1 − ξ)R_A). Mechanics plays no part, so this is cheap and
//!    cannot be confused by the sponge.
//! 2. **Mechanics and stress**: the whole plane replayed from the logged
//!    driver inputs ([`replay`]), fitted to the camera angles (and the
//!    resistances where logged): the four temperatures again together with
//!    the Clausius–Clapeyron slope (the coil stress comes from the
//!    mechanics, so the slope can only be seen here), h (stage 1 saw the
//!    temperatures without the stress shift, which biases h by ≈ 20 % when
//!    the slope is 0.08 K/MPa), the sponge's modulus and damping and the
//!    link inertia; g stays at stage 1's value, or
//!    joins this stage when stage 1 could not fit it (no electrical
//!    columns, or no spread of unsaturated inputs in the fitted part).
//!    It runs from four starting points picked on a coarse (h, slope) grid
//!    after a pre-fit of the sponge, and keeps the best fit
//!    (`mechanics_starts`): from stage 1's values alone it can settle
//!    in a wrong basin.
//! 3. **Wire jamming**: the buckling gain and the two lag ceilings, fitted
//!    to the wire readings with the stage-2 plant moving the link; the
//!    model side is the expected reading over the random stick events
//!    ([`replay::expected_wire_readings`]).
//!
//! Each stage is Levenberg–Marquardt ([`lm`]). A parameter's 1σ is the
//! larger of the Gauss–Newton one and the block-robust one over log
//! segments ([`lm::block_robust_std`]: 10 s segments, lag episodes for
//! the wires) — for the wires also of the spread over the log's draw of
//! stick events, by a linearised parametric bootstrap over the stick
//! realisations (`wire_systematic`) — combined in quadrature with the
//! errors a stage's data cannot average out ([`lm::systematic_shift`]):
//! for the wires a reading offset of ±½ coder count and the noise of the
//! mean over realisations; for the mechanics, which hold stage 1's
//! driver fixed, that driver's own 1σ (`driver_systematic`); see
//! `stage`. A parameter whose 1σ exceeds its threshold
//! ([`params::Param::scale`]) is **not identifiable from this log**: it is
//! reported as such, put back to its prior value and the stage is fitted
//! again without it. The fit uses the first `fit_fraction` of the log; the
//! rest is held out, and the identified plane predicts it from the logged
//! inputs alone (the replay runs the whole log from t = 0): predicted vs
//! recorded camera angle, rms and max error in degrees.
//!
//! Never fitted (fixed at the prior, i.e. the plant file given or the
//! defaults): coil spring rates and rest lengths, resistivities, geometry,
//! link mass, ambient temperature, latent heat, the sponge's stiffness ratio
//! and shear fraction, the wires' geometry and the *random* stick events'
//! rate and sizes (the wire stage averages over sticks at the prior's).
//! Left out: the 3D joint's coupling between planes (the model has none);
//! the weighting between the angle and resistance residuals is a priori
//! (0.1° and 0.02 Ω), not estimated.

pub mod hidden;
pub mod lm;
pub mod log;
pub mod params;
pub mod plan;
pub mod probe;
pub mod regression;
pub mod replay;
mod stage;
pub mod twin;
pub mod units;
pub mod verify;

use rayon::prelude::*;
use serde::Serialize;

use crate::{Joint2dParams, Joint3dParams, PlantError, WireSensorParams};
pub use lm::{LmOptions, LmResult, StopFlag};
pub use log::{ElectricalNoise, ExcitationLog, LogRecorder, Observation};
pub use params::{Param, Scale};
pub use plan::ExcitationPlan;
use plant_common::csv_input::CsvError;
pub use replay::{replay, PlaneMap, PlaneModel, Prediction};
use stage::{with_coords, Found, Stage};
pub use units::{mechanics_cost, StartFit, StartFits, StartUnit};

/// Why identification failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum IdentifyError {
    /// The log file.
    #[error(transparent)]
    Csv(#[from] CsvError),
    /// The log's content.
    #[error("log: {0}")]
    Log(String),
    /// A parameter set the plant refuses (prior or fitted).
    #[error("plant: {0}")]
    Plant(PlantError),
    /// A replay went unstable.
    #[error("replay unstable: {0} is not finite")]
    Unstable(String),
    /// Fewer residuals than parameters.
    #[error(
        "{residuals} data points cannot determine {parameters} parameters: record a longer log"
    )]
    TooFewData {
        /// Residuals.
        residuals: usize,
        /// Parameters.
        parameters: usize,
    },
    /// The caller asked the fit to stop ([`LmOptions::stop`]).
    #[error("the fit was stopped before it finished")]
    Stopped,
    /// A fit run elsewhere ([`units`]): its error as it was said there, or
    /// why it could not be run or taken.
    #[error("{0}")]
    Remote(String),
}

impl From<PlantError> for IdentifyError {
    fn from(e: PlantError) -> Self {
        IdentifyError::Plant(e)
    }
}

/// Secant updates of the Jacobian between forward-difference ones in the
/// mechanics stage's fits where they difference it
/// (`IdentifyOptions::derivative_jacobians` off; [`lm::minimise`]). Its
/// evaluations are most of an identification's CPU; with 2 updates they
/// fell by 6–73 % per plane on the logs measured (docs/benchmarks.md,
/// "Identification with secant updates"), the estimates within 0.9 σ of
/// the textbook method's. With 4 (session 50) the campaigns of twins
/// 0..20 (standard and adapted plans) took 8 % less CPU with the same
/// verdicts and coverage and the ignored twins 13 % less, though single planes vary both ways (one
/// 600 s log's β fit took 52 % more replays; docs/benchmarks.md,
/// "Four secant updates"). The thermal and wire stages difference
/// every iteration (cheap replays; the wire stage's cost is rugged in its
/// stick realisations).
pub const SECANT_UPDATES: usize = 4;

/// Secant updates between the Jacobians a replay carrying derivatives
/// gives ([`IdentifyOptions::derivative_jacobians`]; the mechanics
/// stage's default). Such a Jacobian costs about 4.3 plain replays
/// instead of nine, and a fit takes a new one only where an updated one
/// no longer finds a lower cost (a mechanics fit takes 15–20 steps, so
/// ten is as many as it uses). Against four: 9.4–9.8 against 10.5–10.6
/// CPU-s on the hidden scenario's 240 s log, and on the campaign of
/// twins 0..20 (adapted plans) the same verdicts as differences, 40 of
/// 40 planes verified, where four updates left one plane (twin 5's β, a
/// knife edge between nearly equal minima) failing its held-out check;
/// on new twins (20..40) the same verdicts as differences too
/// (docs/benchmarks.md, session 53).
pub const DERIVATIVE_SECANT_UPDATES: usize = 10;

/// Settings of an identification.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyOptions {
    /// Share of the log (from its start) the fit uses; the rest validates.
    pub fit_fraction: f64,
    /// Substep of the replays (s).
    pub substep_s: f64,
    /// Minimiser settings.
    pub lm: LmOptions,
    /// A priori noise of a camera angle (deg), the angle residuals' scale.
    pub angle_sigma_deg: f64,
    /// A priori noise of a resistance reading (Ω).
    pub resistance_sigma_ohm: f64,
    /// Random realisations of the stick events the wire stage averages
    /// over ([`replay::expected_wire_readings`]); each costs a pass of the
    /// wire model (not the plane) over the log per evaluation.
    pub stick_realisations: usize,
    /// The mechanics stage's Jacobians from one replay carrying the
    /// derivatives with respect to every fitted parameter
    /// ([`replay::replay_sensitivities`]) instead of one replay per
    /// parameter moved (forward differences), with
    /// `derivative_secant_updates` secant updates between them instead of
    /// `lm.secant_updates`. On by default (session 53): a third less CPU
    /// on the twins' campaign with the same verdicts (docs/benchmarks.md);
    /// off, the fits are those of session 52 and before to the bit.
    pub derivative_jacobians: bool,
    /// Secant updates between derived Jacobians
    /// ([`DERIVATIVE_SECANT_UPDATES`] by default).
    pub derivative_secant_updates: usize,
}

impl Default for IdentifyOptions {
    fn default() -> Self {
        Self {
            fit_fraction: 0.75,
            substep_s: 1e-3,
            lm: LmOptions {
                secant_updates: SECANT_UPDATES,
                ..LmOptions::default()
            },
            angle_sigma_deg: 0.1,
            resistance_sigma_ohm: 0.02,
            stick_realisations: replay::STICK_REALISATIONS,
            derivative_jacobians: true,
            derivative_secant_updates: DERIVATIVE_SECANT_UPDATES,
        }
    }
}

/// One identified parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Estimate {
    /// Which.
    pub param: Param,
    /// Its field in the plane's parameters.
    pub field: String,
    /// Unit.
    pub unit: String,
    /// The value written to the plant file (the prior where not
    /// identifiable).
    pub value: f64,
    /// The fit's own value: `value` where identifiable; for a parameter
    /// not identifiable, what the fit found before it was put back.
    pub fitted: f64,
    /// The prior (plant file given, or default).
    pub prior: f64,
    /// 1σ (same unit; +∞ where the log does not determine it): the larger
    /// of the white-noise and the block-robust one (module docs).
    pub std: f64,
    /// The white-noise (Gauss–Newton) 1σ alone, for comparison: it assumes
    /// independent residuals and a right model.
    pub white_std: f64,
    /// Whether the log determines it: 1σ within the parameter's
    /// threshold, and the data's own checks passed ([`verify`]: the
    /// halves of the log agree, no equally good fit from another start
    /// lies far from it).
    pub identifiable: bool,
    /// The stage that fitted it.
    pub stage: String,
    /// Why it is not identifiable, or why it is not verified.
    pub reason: Option<String>,
    /// False where a check of the whole plane casts doubt on it although
    /// its stage determined it: it was fitted through a driver the logged
    /// currents contradict ([`Verdict`]).
    pub verified: bool,
    /// How far the data pulled it from the prior: (value − prior) / 1σ
    /// (0 where not identifiable).
    pub pull_sigma: f64,
}

/// One stage's fit.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageReport {
    /// Name.
    pub name: String,
    /// Minimiser iterations (both passes).
    pub iterations: usize,
    /// Plain replays (the residuals once each; forward differences one
    /// per parameter).
    pub evaluations: usize,
    /// Replays carrying the derivatives with respect to every fitted
    /// parameter, each giving a Jacobian (the mechanics stage; one costs
    /// about four to five plain replays, docs/benchmarks.md).
    pub derivative_replays: usize,
    /// Residuals.
    pub residuals: usize,
    /// rms of the scaled residuals at the optimum.
    pub rms_scaled: f64,
    /// The minimiser's last pass ran out of iterations: the estimates may
    /// not be the optimum (raise `LmOptions::max_iterations`).
    pub stopped_by_budget: bool,
    /// Starting points of the first fit (the best result was kept).
    pub starts: usize,
    /// Which of them (0-based, best-ranked first) the kept fit ran from.
    pub best_start: usize,
}

/// A held-out camera frame: recorded and predicted angle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Frame {
    /// Capture time (s).
    pub t_s: f64,
    /// Camera angle (deg).
    pub recorded_deg: f64,
    /// The identified plane's prediction (deg).
    pub predicted_deg: f64,
}

/// Prediction error of the identified plane.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Validation {
    /// rms angle error over the fitted part (deg).
    pub fit_rms_deg: f64,
    /// rms angle error over the held-out part (deg).
    pub heldout_rms_deg: f64,
    /// Largest held-out angle error (deg).
    pub heldout_max_deg: f64,
    /// Where the held-out part starts (s).
    pub heldout_from_s: f64,
    /// rms over the held-out part of the prior model (before
    /// identification), for comparison (deg); none when the prior's replay
    /// went unstable.
    pub prior_heldout_rms_deg: Option<f64>,
    /// rms over the fitted part of the prior model (deg), as
    /// `prior_heldout_rms_deg`.
    pub prior_fit_rms_deg: Option<f64>,
    /// Every frame of the log with its prediction.
    pub frames: Vec<Frame>,
}

/// What identification found for one plane.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlaneReport {
    /// "theta", "alpha" or "beta".
    pub plane: String,
    /// The parameters, in stage order.
    pub estimates: Vec<Estimate>,
    /// The stages run.
    pub stages: Vec<StageReport>,
    /// Held-out validation.
    pub validation: Validation,
    /// Whether the identified plane passed the checks against its data.
    pub verdict: Verdict,
}

/// The checks of an identified plane against its own data (issue 28).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    /// Every check passed and every parameter reported identifiable is
    /// verified. False: the plant is **unverified**, `failures` says why.
    pub verified: bool,
    /// The camera's angle noise estimated from the log's frames (deg);
    /// none with too few frames.
    pub camera_noise_deg: Option<f64>,
    /// The fit's rms must stay within this multiple of the noise
    /// ([`verify::FIT_MARGIN`]).
    pub fit_margin: f64,
    /// The held-out rms must stay within this multiple of the noise
    /// ([`verify::HELDOUT_MARGIN`]), and not above the prior's.
    pub heldout_margin: f64,
    /// The identified driver against the logged currents, where logged.
    pub driver: Option<verify::DriverCheck>,
    /// The failed checks, one sentence each.
    pub failures: Vec<String>,
}

impl PlaneReport {
    /// The estimate of `p`, if fitted.
    pub fn estimate(&self, p: Param) -> Option<&Estimate> {
        self.estimates.iter().find(|e| e.param == p)
    }
}

/// Parameters never fitted (see the module docs), for reports.
pub const NEVER_FITTED: &[&str] = &[
    "coil spring rates and rest lengths",
    "resistivities (R_M, R_A), wire diameter and length",
    "coil and wire geometry",
    "link mass and centre of mass",
    "ambient temperature and latent heat",
    "sponge stiffness ratio and shear fraction",
    "wire stick-event rate and sizes (random; the wire stage averages over them at the prior's rate and sizes)",
];

/// Identifies the 2D joint from `log`, starting from `prior`.
pub fn identify_2d(
    log: &ExcitationLog,
    prior: &Joint2dParams,
    opts: &IdentifyOptions,
) -> Result<(Joint2dParams, Vec<PlaneReport>), IdentifyError> {
    identify_2d_with(log, prior, opts, None)
}

/// The prior's model of the 2D joint's plane, as identification replays it.
pub fn prior_model_2d(prior: &Joint2dParams, opts: &IdentifyOptions) -> PlaneModel {
    PlaneModel {
        plane: prior.plane.clone(),
        wires: vec![prior.wire.clone()],
        settle_s: prior.sim.settle_s,
        substep_s: opts.substep_s,
    }
}

/// The prior's model of the 3D joint's plane `p` (0: α, 1: β), as
/// identification replays it.
pub fn prior_model_3d(prior: &Joint3dParams, p: usize, opts: &IdentifyOptions) -> PlaneModel {
    let map = PlaneMap::of(2, p);
    PlaneModel {
        plane: if p == 0 {
            prior.alpha.clone()
        } else {
            prior.beta.clone()
        },
        wires: map
            .sensors
            .iter()
            .map(|&s| prior.wires[s].clone())
            .collect(),
        settle_s: prior.sim.settle_s,
        substep_s: opts.substep_s,
    }
}

/// [`identify_2d`] with the mechanics stage's starts run by `elsewhere`
/// (work units, [`units`]) where given: the same result.
pub fn identify_2d_with(
    log: &ExcitationLog,
    prior: &Joint2dParams,
    opts: &IdentifyOptions,
    elsewhere: Option<&dyn StartFits>,
) -> Result<(Joint2dParams, Vec<PlaneReport>), IdentifyError> {
    if log.planes != 1 {
        return Err(IdentifyError::Log(
            "a 3D log (α and β columns) given for the 2D joint".into(),
        ));
    }
    let model = prior_model_2d(prior, opts);
    let (m, report) = identify_plane(log, PlaneMap::of(1, 0), model, "theta", opts, elsewhere)?;
    let mut out = prior.clone();
    out.plane = m.plane;
    out.wire = m.wires[0].clone();
    out.validate()?;
    Ok((out, vec![report]))
}

/// Identifies the 3D joint from `log` (α and β apart, in parallel).
pub fn identify_3d(
    log: &ExcitationLog,
    prior: &Joint3dParams,
    opts: &IdentifyOptions,
) -> Result<(Joint3dParams, Vec<PlaneReport>), IdentifyError> {
    identify_3d_with(log, prior, opts, None)
}

/// [`identify_3d`] with the mechanics stage's starts run by `elsewhere`
/// (work units, [`units`]) where given: the same result.
pub fn identify_3d_with(
    log: &ExcitationLog,
    prior: &Joint3dParams,
    opts: &IdentifyOptions,
    elsewhere: Option<&dyn StartFits>,
) -> Result<(Joint3dParams, Vec<PlaneReport>), IdentifyError> {
    if log.planes != 2 {
        return Err(IdentifyError::Log(
            "a 2D log (θ columns) given for the 3D joint".into(),
        ));
    }
    let results: Vec<Result<(PlaneModel, PlaneReport), IdentifyError>> =
        [(0, "alpha"), (1, "beta")]
            .into_par_iter()
            .map(|(p, name)| {
                let model = prior_model_3d(prior, p, opts);
                identify_plane(log, PlaneMap::of(2, p), model, name, opts, elsewhere)
            })
            .collect();
    let mut out = prior.clone();
    let mut reports = Vec::new();
    for (p, r) in results.into_iter().enumerate() {
        let (m, rep) = r?;
        let map = PlaneMap::of(2, p);
        for (slot, w) in map.sensors.iter().zip(m.wires) {
            out.wires[*slot] = w;
        }
        if p == 0 {
            out.alpha = m.plane;
        } else {
            out.beta = m.plane;
        }
        reports.push(rep);
    }
    out.validate()?;
    Ok((out, reports))
}

/// Camera frames of rows `0..rows`, once each: (capture time, angle).
fn frames(log: &ExcitationLog, plane: usize, rows: usize) -> Vec<(f64, f64)> {
    let mut out: Vec<(f64, f64)> = Vec::new();
    let mut last = f64::NEG_INFINITY;
    for k in 0..rows.min(log.len()) {
        let c = log.cam_capture_s[k];
        if c >= 0.0 && c > last {
            out.push((c, log.cam_deg[k][plane]));
            last = c;
        }
    }
    out
}

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

/// Length of the log segments (s) over which the block-robust 1σ groups
/// residuals (see `stage`): longer than the plan's transients (a pulse
/// and its cooling, ≈ 5–10 s; a wire's lag lasts until the next pull) so
/// that residuals correlated in time fall mostly in one segment, short
/// enough for 45 segments in the fitted part of a 10-minute log.
pub const UNCERTAINTY_BLOCK_S: f64 = 10.0;

/// Fewest segments in the fitted part: a shorter log gets shorter
/// segments (the compact 60 s plan: 2.25 s), since a sandwich over a few
/// segments is itself too uncertain to judge by.
pub const UNCERTAINTY_MIN_BLOCKS: usize = 20;

/// Segment indices (from `first`) of one wire's rows by lag episode: a new
/// segment starts once the wire has been pulled back from the deepest
/// insertion of the present segment by more than 1.5 times the lag
/// ceiling there plus the longest stick (so the lag, random sticks
/// included, is gone in the recorded joint as in the model, even with
/// ceilings 50 % off). `ideal_mm` is the geometric insertion per row.
fn lag_episodes(ideal_mm: &[f64], wire: &WireSensorParams, first: usize) -> Vec<usize> {
    let j = &wire.jam;
    let rest = wire.geometry.insertion_at_rest_mm;
    let mut id = first;
    let mut deepest = f64::NEG_INFINITY;
    ideal_mm
        .iter()
        .map(|&d| {
            deepest = deepest.max(d);
            let ceiling = j.max_lag_mm + j.max_lag_per_mm * (deepest - rest).max(0.0);
            if deepest - d > 1.5 * ceiling + j.stick_max_mm {
                id += 1;
                deepest = d;
            }
            id
        })
        .collect()
}

/// Stress slopes of the mechanics stage's starting grid (K/MPa): from
/// near "off" across NiTi's 0.07–0.14 K/MPa (README, parameter table).
/// A choice, not fitted to the twin: the grid does not contain the hidden
/// plant's slope.
pub const START_SLOPES_K_PER_MPA: [f64; 6] = [0.02, 0.045, 0.07, 0.095, 0.12, 0.145];

/// Factors on stage 1's convection coefficient in the same grid. Stage 1
/// sees the temperatures without the stress shift, which biases its h
/// upwards (by 37 % on the 10-minute 2D twin, slope 0.08 K/MPa), hence
/// the grid leans low.
pub const START_CONVECTION_FACTORS: [f64; 4] = [0.65, 0.8, 1.0, 1.2];

/// Starting points kept from the grid (a Levenberg–Marquardt fit runs
/// from each; the lowest cost wins). Four, not two as before issue 28's
/// campaign: on its twin 10 β (turn-on 1.82 V, so the sustained levels
/// barely heat the coils) the grid ranked the start that leads to the
/// truth's basin fourth, and the best of two settled with h +17 %,
/// A_s/A_f 0.6/1.8 K low and the slope −27 %, each 4–23σ off by its 1σ,
/// at Δχ² ≈ 350 above the truth's minimum — a local minimum no check
/// of that plane could see. The two extra fits run beside the first two
/// (rayon), and the starts check then compares four minima.
pub const MECHANICS_STARTS: usize = 4;

/// Iterations of the sponge's pre-fit before the grid.
const SPONGE_PREFIT_ITERATIONS: usize = 10;

/// The mechanics stage's starting points, and the replays spent finding
/// them. From stage 1's values alone, Levenberg–Marquardt can settle in a
/// basin with h far high and the slope far low (on the 10-minute 2D twin:
/// h +38 %, slope −46 %, sponge modulus −27 %, at 2.6 times the truth's
/// cost), because h and the slope trade along a long curved valley. So:
/// 1. the sponge's modulus and damping are fitted alone first (at most
///    [`SPONGE_PREFIT_ITERATIONS`]), the rest at `model`: a sponge 40 %
///    off misranks the grid (the angles' scale is wrong everywhere);
/// 2. the cost of every point of the (h, slope) grid
///    ([`START_CONVECTION_FACTORS`] × h of `model`,
///    [`START_SLOPES_K_PER_MPA`]) and of `model` itself, in parallel;
/// 3. the [`MECHANICS_STARTS`] cheapest with distinct slopes, best first
///    (ties in grid order). A point whose replay fails is left out.
///
/// The grid keeps stage 1's temperatures, which include the mean stress
/// shift, so its costs favour low slopes; the fits from each start, not
/// the grid's ranking, decide.
fn mechanics_starts<F>(model: &PlaneModel, residuals: &F) -> (Vec<PlaneModel>, usize)
where
    F: Fn(&PlaneModel) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    let mut model = model.clone();
    let mut evaluations = 0;
    // The pre-fit's cost at its result, which is the grid's first point.
    let mut cost_at_model = None;
    let sponge = [Param::SpongeModulus, Param::SpongeDamping];
    if sponge.iter().all(|p| p.get(&model).is_finite()) {
        let base = model.clone();
        let apply = |x: &[f64]| with_coords(&base, &sponge, x);
        let x0: Vec<f64> = sponge.iter().map(|p| p.to_coord(p.get(&base))).collect();
        let opts = LmOptions {
            max_iterations: SPONGE_PREFIT_ITERATIONS,
            ..LmOptions::default()
        };
        // A pre-fit that fails leaves the sponge as it was: the stage's
        // own fits report any real failure. Its minimum alone is used:
        // not the Jacobian there (`Minimum::finish`), two replays more.
        if let Ok(r) = lm::minimise(&|x: &[f64]| residuals(&apply(x)), &x0, opts) {
            evaluations += r.evaluations;
            model = apply(&r.x);
            cost_at_model = Some(r.cost);
        }
    }
    let h0 = Param::Convection.get(&model);
    let mut grid = vec![model.clone()];
    for f in START_CONVECTION_FACTORS {
        for s in START_SLOPES_K_PER_MPA {
            let mut m = model.clone();
            Param::Convection.set(&mut m, f * h0);
            Param::StressShift.set(&mut m, s);
            grid.push(m);
        }
    }
    let costs: Vec<Option<f64>> = grid
        .par_iter()
        .enumerate()
        .map(|(k, m)| {
            let cost = match cost_at_model.filter(|_| k == 0) {
                Some(known) => Some(known),
                None => residuals(m)
                    .ok()
                    .map(|r| r.iter().map(|x| x * x).sum::<f64>()),
            };
            cost.filter(|c| c.is_finite())
        })
        .collect();
    evaluations += grid.len() - usize::from(cost_at_model.is_some());
    let mut order: Vec<usize> = (0..grid.len()).filter(|&k| costs[k].is_some()).collect();
    order.sort_by(|&a, &b| {
        costs[a]
            .partial_cmp(&costs[b])
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut out: Vec<PlaneModel> = Vec::new();
    for k in order {
        let s = Param::StressShift.get(&grid[k]);
        if out.iter().all(|m| Param::StressShift.get(m) != s) {
            out.push(grid[k].clone());
        }
        if out.len() == MECHANICS_STARTS {
            break;
        }
    }
    (out, evaluations)
}

/// The staged identification of one plane (see the module docs); the
/// mechanics stage's starts run by `elsewhere` where given (the same
/// result; [`units`]).
pub fn identify_plane(
    log: &ExcitationLog,
    map: PlaneMap,
    prior: PlaneModel,
    name: &str,
    opts: &IdentifyOptions,
    elsewhere: Option<&dyn StartFits>,
) -> Result<(PlaneModel, PlaneReport), IdentifyError> {
    let part = FitPart::new(log, map, opts.fit_fraction)?;
    let mut found = Found {
        model: prior.clone(),
        estimates: Vec::new(),
        stages: Vec::new(),
    };
    let mut driver = None;
    if log.has_electrical() {
        driver = electrical_stage(&part, &prior, &mut found);
        thermal_stage(&part, &prior, opts, &mut found)?;
    }
    mechanics_stage(&part, &prior, opts, driver.as_ref(), &mut found, elsewhere)?;
    wire_stage(&part, &prior, opts, &mut found)?;
    let validation = validate(&part, &found.model, &prior)?;
    let verdict = verdict(&part, &found.model, &validation, &mut found.estimates);
    Ok((
        found.model,
        PlaneReport {
            plane: name.into(),
            estimates: found.estimates,
            stages: found.stages,
            validation,
            verdict,
        },
    ))
}

/// The checks of the identified `model` against its data ([`Verdict`]):
/// the fit and held-out rms against the camera's noise floor with the
/// margins of [`verify`], the held-out rms against the prior's, and the
/// driver against the logged currents (a driver the currents contradict
/// leaves every thermal and mechanical parameter unverified). Also sets
/// each estimate's pull from the prior.
fn verdict(
    part: &FitPart,
    model: &PlaneModel,
    v: &Validation,
    estimates: &mut [Estimate],
) -> Verdict {
    let mut failures = Vec::new();
    let noise = verify::camera_noise_floor_deg(part.log, part.map.plane, part.log.len());
    let (fm, hm) = (verify::FIT_MARGIN, verify::HELDOUT_MARGIN);
    match noise {
        Some(n) => {
            if v.fit_rms_deg > fm * n {
                failures.push(format!(
                    "the fit's rms {:.3}° is above {fm} × the camera's noise ({n:.3}°): the model does not fit its own data",
                    v.fit_rms_deg
                ));
            }
            let held_out = v.frames.iter().any(|f| f.t_s >= v.heldout_from_s);
            if held_out && v.heldout_rms_deg > hm * n {
                failures.push(format!(
                    "the held-out rms {:.3}° is above {hm} × the camera's noise ({n:.3}°)",
                    v.heldout_rms_deg
                ));
            }
        }
        None => failures.push("too few camera frames to judge the fit against the noise".into()),
    }
    if let Some(p) = v.prior_heldout_rms_deg {
        if v.heldout_rms_deg > verify::PRIOR_MARGIN * p {
            failures.push(format!(
                "the held-out rms {:.3}° is above {} × the prior's {p:.3}°: the identification made the plant worse",
                v.heldout_rms_deg,
                verify::PRIOR_MARGIN
            ));
        }
    }
    if let Some(p) = v.prior_fit_rms_deg {
        if v.fit_rms_deg > verify::PRIOR_MARGIN * p {
            failures.push(format!(
                "the fit's rms {:.3}° is above {} × the prior's {p:.3}° on the same frames: the fit ended worse than the prior it started from",
                v.fit_rms_deg,
                verify::PRIOR_MARGIN
            ));
        }
    }
    let driver = verify::driver_check(part.log, part.map, model, part.rows);
    if let Some(d) = driver.as_ref().filter(|d| !d.passed) {
        let why = format!(
            "fitted through a driver (g {:.3} A/V, turn-on {:.3} V) that mispredicts the logged currents by {:.1} mA rms (noise {:.1} mA)",
            model.plane.driver.transconductance_a_v,
            model.plane.driver.turn_on_v,
            1e3 * d.rms_error_a,
            1e3 * d.noise_a
        );
        failures.push(format!(
            "{why}: the thermal and mechanical parameters are conditional on a wrong driver"
        ));
        for e in estimates
            .iter_mut()
            .filter(|e| e.identifiable && (e.stage == "thermal" || e.stage == "mechanics"))
        {
            e.verified = false;
            e.reason = Some(why.clone());
        }
    }
    // A plane whose log moved it too little to determine any thermal or
    // mechanical parameter keeps its prior there: reporting it verified
    // would call a plant identified that was not.
    let physical = |e: &Estimate| e.stage == "thermal" || e.stage == "mechanics";
    if estimates.iter().any(physical) && !estimates.iter().any(|e| physical(e) && e.identifiable) {
        failures.push(
            "the log determines none of the plane's thermal and mechanical parameters (each is named not identifiable): the plane is its prior, not identified; record holds that move it"
                .into(),
        );
    }
    for e in estimates.iter_mut() {
        e.pull_sigma = if e.identifiable && e.std > 0.0 {
            (e.value - e.prior) / e.std
        } else {
            0.0
        };
    }
    Verdict {
        verified: failures.is_empty(),
        camera_noise_deg: noise,
        fit_margin: fm,
        heldout_margin: hm,
        driver,
        failures,
    }
}

/// The log as one plane's stages see it: the plane's columns, the rows
/// fitted (the rest is held out) and the log segments over which the
/// block-robust 1σ groups residuals (see [`Stage`]).
struct FitPart<'a> {
    log: &'a ExcitationLog,
    map: PlaneMap,
    /// Rows `0..rows` are fitted.
    rows: usize,
    /// Length of a segment (s): [`UNCERTAINTY_BLOCK_S`], shorter for a
    /// log too short for [`UNCERTAINTY_MIN_BLOCKS`] of them, never shorter
    /// than a row.
    block_s: f64,
}

impl<'a> FitPart<'a> {
    /// The first `fit_fraction` (0.2..=1) of `log`, for the plane `map`.
    fn new(
        log: &'a ExcitationLog,
        map: PlaneMap,
        fit_fraction: f64,
    ) -> Result<Self, IdentifyError> {
        if !(0.2..=1.0).contains(&fit_fraction) {
            return Err(IdentifyError::Log(format!(
                "fit fraction must be 0.2..=1, got {}",
                plant_common::short_number(fit_fraction)
            )));
        }
        let rows = ((log.len() as f64) * fit_fraction).round() as usize;
        let block_s = UNCERTAINTY_BLOCK_S
            .min(rows as f64 * log.period_s / UNCERTAINTY_MIN_BLOCKS as f64)
            .max(log.period_s);
        Ok(Self {
            log,
            map,
            rows,
            block_s,
        })
    }

    /// The segment of time `t_s`.
    fn block_of(&self, t_s: f64) -> usize {
        (t_s / self.block_s).floor().max(0.0) as usize
    }

    /// The segments of residuals laid out as `series` series of the fitted
    /// rows, one after the other (thermal: per coil; wires: per sensor).
    fn row_blocks(&self, series: usize) -> Vec<usize> {
        (0..series)
            .flat_map(|_| (0..self.rows).map(|k| self.block_of(k as f64 * self.log.period_s)))
            .collect()
    }
}

/// Stage 1a: the driver's transconductance and turn-on voltage by linear
/// regression of the logged current ([`regression::driver_regression`]);
/// None (and nothing found) when the fitted part has no spread of
/// unsaturated inputs or no current column.
fn electrical_stage(
    part: &FitPart,
    prior: &PlaneModel,
    found: &mut Found,
) -> Option<regression::DriverFit> {
    let Some(fit) =
        regression::driver_regression(part.log, part.map, part.rows, &prior.plane.driver)
    else {
        turn_on_not_determined(part, prior, found);
        return None;
    };
    let (g, sd_g, v_on, sd_v) = (fit.g, fit.sd_g(), fit.turn_on_v(), fit.sd_turn_on());
    Param::Transconductance.set(&mut found.model, g);
    Param::TurnOn.set(&mut found.model, v_on);
    for (p, v, sd) in [
        (Param::Transconductance, g, sd_g),
        (Param::TurnOn, v_on, sd_v),
    ] {
        let coord_sd = match p.scale() {
            Scale::Log { .. } => sd / v,
            Scale::Linear { .. } => sd,
        };
        found.estimates.push(Estimate {
            param: p,
            field: p.field().into(),
            unit: p.unit().into(),
            value: v,
            fitted: v,
            prior: p.get(prior),
            std: sd,
            white_std: sd,
            identifiable: p.determined(coord_sd),
            stage: "electrical".into(),
            reason: (!p.determined(coord_sd))
                .then(|| "1σ above its threshold: too little spread of unsaturated inputs".into()),
            verified: true,
            pull_sigma: 0.0,
        });
    }
    found.stages.push(StageReport {
        name: "electrical".into(),
        iterations: 1,
        evaluations: 0,
        derivative_replays: 0,
        residuals: 0,
        rms_scaled: 0.0,
        stopped_by_budget: false,
        starts: 1,
        best_start: 0,
    });
    Some(fit)
}

/// The driver's turn-on named not identifiable where the log has currents
/// but no spread of unsaturated ones to regress (it stays at the prior),
/// with what the currents do say: the highest input at which the coils
/// carried no current and the lowest at which they did.
fn turn_on_not_determined(part: &FitPart, prior: &PlaneModel, found: &mut Found) {
    let Some(seen) = verify::driver_check(part.log, part.map, prior, part.rows) else {
        return;
    };
    let short = |v: Option<f64>| v.map_or("none".to_string(), plant_common::short_number);
    let p = Param::TurnOn;
    found.estimates.push(Estimate {
        param: p,
        field: p.field().into(),
        unit: p.unit().into(),
        value: p.get(prior),
        fitted: p.get(prior),
        prior: p.get(prior),
        std: f64::INFINITY,
        white_std: f64::INFINITY,
        identifiable: false,
        stage: "electrical".into(),
        reason: Some(format!(
            "the coils never carried an unsaturated current to regress (highest input with no current: {} V; lowest with a current: {} V): add inputs between those levels",
            short(seen.highest_off_v),
            short(seen.lowest_on_v)
        )),
        verified: true,
        pull_sigma: 0.0,
    });
}

/// Stage 1b: the convection coefficient and the four transformation
/// temperatures, from the coils' own thermal and phase model heated by the
/// measured current, fitted to the measured resistance (only where both
/// were logged).
fn thermal_stage(
    part: &FitPart,
    prior: &PlaneModel,
    opts: &IdentifyOptions,
    found: &mut Found,
) -> Result<(), IdentifyError> {
    let (log, map, fit_rows) = (part.log, part.map, part.rows);
    let cur = log.current_a.as_ref().map(|c| c[..fit_rows].to_vec());
    let res = log.resistance_ohm.as_ref().map(|c| c[..fit_rows].to_vec());
    let (Some(cur), Some(res)) = (cur, res) else {
        return Ok(());
    };
    let sigma = opts.resistance_sigma_ohm;
    let thermal = |m: &PlaneModel| -> Result<Vec<f64>, IdentifyError> {
        let mut out = Vec::with_capacity(2 * cur.len());
        for &c in &map.coils {
            let i: Vec<f64> = cur.iter().map(|r| r[c]).collect();
            let pred = replay::replay_thermal(&m.plane.coil, &i, log.period_s, m.substep_s)?;
            out.extend(pred.iter().zip(&res).map(|(p, r)| (p - r[c]) / sigma));
        }
        Ok(out)
    };
    let blocks = part.row_blocks(map.coils.len());
    Stage {
        name: "thermal",
        free: &[
            Param::Convection,
            Param::AusteniteStart,
            Param::AusteniteFinish,
            Param::MartensiteStart,
            Param::MartensiteFinish,
        ],
        residuals: thermal,
        blocks: &blocks,
        systematic: &|_: &PlaneModel| Ok(Vec::new()),
        resampled: &|_: &PlaneModel| Ok(Vec::new()),
        starts: &[],
        halves: Some(&blocks),
        elsewhere: None,
        secant: false,
        jacobian: None,
    }
    .run(found, prior, opts)
}

/// The parameters the mechanics stage fits (g joins them where stage 1
/// could not fit the driver).
const MECHANICS_PARAMS: [Param; 9] = [
    Param::Convection,
    Param::AusteniteStart,
    Param::AusteniteFinish,
    Param::MartensiteStart,
    Param::MartensiteFinish,
    Param::StressShift,
    Param::SpongeModulus,
    Param::SpongeDamping,
    Param::LinkInertia,
];

/// Stage 2: mechanics and the stress slope from the camera angles (and
/// the resistances where logged), from the starting points of
/// [`mechanics_starts`]; g joins it when stage 1 could not fit it. Where
/// stage 1 fitted the driver (`driver`), the mechanics hold it fixed, so
/// its uncertainty is carried into theirs ([`driver_systematic`]).
fn mechanics_stage(
    part: &FitPart,
    prior: &PlaneModel,
    opts: &IdentifyOptions,
    driver: Option<&regression::DriverFit>,
    found: &mut Found,
    elsewhere: Option<&dyn StartFits>,
) -> Result<(), IdentifyError> {
    let fit_frames = frames(part.log, part.map.plane, part.rows);
    let mech = mechanics_residuals(part, opts, &fit_frames);
    let mech_jacobian = mechanics_jacobian(part, opts, &fit_frames);
    // The mechanics residuals' layout: the fitted frames, then the
    // resistances row by row (both coils). Were a frame to have no
    // prediction, the lengths would differ and `Stage` would fall back to
    // the white-noise 1σ.
    let mut mech_blocks: Vec<usize> = fit_frames.iter().map(|(t, _)| part.block_of(*t)).collect();
    if part.log.resistance_ohm.is_some() {
        for k in 0..part.rows {
            mech_blocks.extend([part.block_of(k as f64 * part.log.period_s); 2]);
        }
    }
    let mut free = MECHANICS_PARAMS.to_vec();
    // Without a driver regression (no current column, or no spread of
    // unsaturated inputs in the fitted part) g is fitted here, from the
    // angles and resistances, as for a log without electrical columns;
    // the turn-on voltage then stays at its prior, unreported.
    if driver.is_none() {
        free.insert(0, Param::Transconductance);
    }
    // Stage 1's h and temperatures were fitted without the stress (which
    // needs the mechanics); they start stage 2, whose estimates replace
    // them.
    found.estimates.retain(|e| !free.contains(&e.param));
    // The slope starts inside its range so the first Jacobian sees both
    // signs of change.
    if Param::StressShift.get(&found.model) <= 0.0 {
        Param::StressShift.set(&mut found.model, 0.02);
    }
    let (mut starts, mut start_evaluations) = mechanics_starts(&found.model, &mech);
    // The prior is a candidate too (with stage 1's driver): where it fits
    // better than every start of the grid, the fit runs from it as well,
    // so the stage never ends worse than the prior it started from.
    let at_prior = with_coords(&found.model, &free, &stage::coords(&free, prior));
    let cost = |m: &PlaneModel| {
        mech(m)
            .ok()
            .map(|r| r.iter().map(|x| x * x).sum::<f64>())
            .filter(|c| c.is_finite())
    };
    if let (Some(c_prior), best) = (cost(&at_prior), starts.first().and_then(cost)) {
        start_evaluations += 2;
        if best.is_none_or(|b| c_prior < b) {
            starts.push(at_prior);
        }
    }
    Stage {
        name: "mechanics",
        free: &free,
        residuals: &mech,
        blocks: &mech_blocks,
        systematic: &driver_systematic(driver, &mech),
        resampled: &|_: &PlaneModel| Ok(Vec::new()),
        starts: &starts,
        halves: Some(&mech_blocks),
        elsewhere: elsewhere.map(|fits| stage::Elsewhere {
            fits,
            plane: part.map.plane,
        }),
        secant: true,
        jacobian: if opts.derivative_jacobians {
            Some(&mech_jacobian)
        } else {
            None
        },
    }
    .run(found, prior, opts)?;
    if let Some(st) = found.stages.last_mut() {
        st.evaluations += start_evaluations;
    }
    Ok(())
}

/// The driver's uncertainty as errors the mechanics cannot average out:
/// the mechanics hold stage 1's g and turn-on fixed, and a driver 1σ off
/// changes every current the replay drives the coils with, which the
/// mechanics then absorb (issue 28's campaign: h 8σ off on a plane whose
/// turn-on lay 10 mV above the plan's 1.85 V level, where the coils'
/// current depends on the turn-on more than on anything the mechanics
/// fit). For the model at the fit, the change of the residuals when the
/// driver moves by 1σ along each principal axis of its (g, b) covariance
/// ([`regression::DriverFit::shifts`]); none without a fitted driver.
fn driver_systematic<'a, F>(
    driver: Option<&'a regression::DriverFit>,
    residuals: &'a F,
) -> impl Fn(&PlaneModel) -> Result<Vec<Vec<f64>>, IdentifyError> + Sync + 'a
where
    F: Fn(&PlaneModel) -> Result<Vec<f64>, IdentifyError> + Sync,
{
    move |m: &PlaneModel| {
        let Some(d) = driver else {
            return Ok(Vec::new());
        };
        let at = residuals(m)?;
        d.shifts()
            .iter()
            .map(|&(g, v_on)| {
                let mut moved = m.clone();
                Param::Transconductance.set(&mut moved, g);
                Param::TurnOn.set(&mut moved, v_on);
                Ok(residuals(&moved)?
                    .iter()
                    .zip(&at)
                    .map(|(a, b)| a - b)
                    .collect())
            })
            .collect()
    }
}

/// The mechanics stage's residuals of a model: the plane replayed over
/// the fitted rows, its angle at each of `fit_frames` against the
/// camera's, then (where logged) its coil resistances row by row, each
/// scaled by its a priori noise.
fn mechanics_residuals<'a>(
    part: &'a FitPart,
    opts: &IdentifyOptions,
    fit_frames: &'a [(f64, f64)],
) -> impl Fn(&PlaneModel) -> Result<Vec<f64>, IdentifyError> + Sync + 'a {
    let (log, map, fit_rows) = (part.log, part.map, part.rows);
    let sig_a = opts.angle_sigma_deg;
    let sig_r = opts.resistance_sigma_ohm;
    move |m: &PlaneModel| -> Result<Vec<f64>, IdentifyError> {
        let pred = replay(m, log, map, fit_rows)?;
        let mut out: Vec<f64> = fit_frames
            .iter()
            .filter_map(|(t, a)| pred.angle_at(*t).map(|p| (p - a) / sig_a))
            .collect();
        if let Some(res) = &log.resistance_ohm {
            for (k, r) in pred.resistance_ohm.iter().enumerate() {
                for (j, &c) in map.coils.iter().enumerate() {
                    out.push((r[j] - res[k][c]) / sig_r);
                }
            }
        }
        Ok(out)
    }
}

/// A Jacobian's columns, one per parameter.
type Columns = Result<Vec<Vec<f64>>, IdentifyError>;

/// The Jacobian of [`mechanics_residuals`] with respect to the
/// coordinates of `active` at a model, from one replay carrying their
/// derivatives ([`replay::replay_sensitivities`]) instead of one replay
/// per parameter moved (issue 34); `None` where a parameter is not one a
/// replay carries.
fn mechanics_jacobian<'a>(
    part: &'a FitPart,
    opts: &IdentifyOptions,
    fit_frames: &'a [(f64, f64)],
) -> impl Fn(&PlaneModel, &[Param]) -> Option<Columns> + Sync + 'a {
    let (log, map, fit_rows) = (part.log, part.map, part.rows);
    let sig_a = opts.angle_sigma_deg;
    let sig_r = opts.resistance_sigma_ohm;
    move |m: &PlaneModel, active: &[Param]| {
        if active.is_empty() || !active.iter().all(|p| replay::carries_derivative(*p)) {
            return None;
        }
        Some((|| {
            // The substep boundary of each frame, as Prediction::angle_at
            // finds it.
            let (_, h_s) = replay::split(log.period_s, m.substep_s);
            let at: Vec<usize> = fit_frames
                .iter()
                .map(|(t, _)| (t / h_s - 1e-6).ceil().max(0.0) as usize)
                .collect();
            let s = replay::replay_sensitivities(m, log, map, fit_rows, active, &at)?;
            let frames = s.angle_deg.len();
            Ok(active
                .iter()
                .enumerate()
                .map(|(j, _)| {
                    let mut col: Vec<f64> = s.angle_deg_d[j][..frames]
                        .iter()
                        .map(|d| d / sig_a)
                        .collect();
                    if log.resistance_ohm.is_some() {
                        for r in &s.resistance_ohm_d[j] {
                            col.extend(r.iter().map(|d| d / sig_r));
                        }
                    }
                    col
                })
                .collect())
        })())
    }
}

/// Stage 3: wire jamming from the wire readings. The jamming parameters
/// do not move the link, so the wires' paths come from one replay of the
/// stage-2 plane; each evaluation then averages the random sensor over
/// stick events along them (`replay` module docs).
fn wire_stage(
    part: &FitPart,
    prior: &PlaneModel,
    opts: &IdentifyOptions,
    found: &mut Found,
) -> Result<(), IdentifyError> {
    let (log, map, fit_rows) = (part.log, part.map, part.rows);
    let paths = replay::replay_with_wire_paths(&found.model, log, map, fit_rows)?;
    let sticks = replay::StickEvents::draw(
        &found.model.wires,
        &paths,
        fit_rows,
        opts.stick_realisations,
    )?;
    let wire = |m: &PlaneModel| -> Result<Vec<f64>, IdentifyError> {
        let expected = sticks.realisations(&m.wires, &paths)?;
        let mut out = Vec::with_capacity(map.sensors.len() * fit_rows);
        for (j, &s) in map.sensors.iter().enumerate() {
            out.extend(
                expected[j]
                    .0
                    .iter()
                    .enumerate()
                    .map(|(k, p)| (p - log.wire_mm[k][s]) / 0.01),
            );
        }
        Ok(out)
    };
    let episodes = wire_episodes(part, &paths, &found.model.wires);
    let systematic = wire_systematic(part, &paths, &sticks, false);
    let resampled = wire_systematic(part, &paths, &sticks, true);
    Stage {
        name: "wire jamming",
        free: &[Param::JamGain, Param::JamMaxLag, Param::JamLagPerMm],
        residuals: wire,
        blocks: &episodes,
        systematic: &systematic,
        resampled: &resampled,
        starts: &[],
        halves: Some(&part.row_blocks(map.sensors.len())),
        elsewhere: None,
        secant: false,
        jacobian: None,
    }
    .run(found, prior, opts)
}

/// The wire residuals' segments: lag episodes, not fixed times, since a
/// stick's extra lag lasts until the wire is pulled clear, so residuals
/// are correlated over a whole push ([`lag_episodes`]); numbered on from
/// one sensor to the next.
fn wire_episodes(part: &FitPart, paths: &Prediction, wires: &[WireSensorParams]) -> Vec<usize> {
    let n = paths.substeps_per_row;
    let mut ids = Vec::with_capacity(part.map.sensors.len() * part.rows);
    for (path, w) in paths.wire_path_mm.iter().zip(wires) {
        let per_row: Vec<f64> = (0..part.rows).map(|k| path[k * n]).collect();
        let first = ids.iter().max().map_or(0, |b: &usize| b + 1);
        ids.extend(lag_episodes(&per_row, w, first));
    }
    ids
}

/// The wire stage's errors beyond the white noise of its readings, for
/// the model at the fit, as changes of every residual (see `Stage`).
///
/// With `data_draws` false, the systematic ones. A coder reads whole
/// counts, and a joint returns to nearly the same rest pose after each
/// move, so the rounding there is nearly the same every time: an offset
/// of the readings the fit cannot average out, uniform within ±½ count
/// (1σ = count/√12), one per sensor. The mean over a finite number K of
/// stick realisations is itself noisy: realisation r's deviation from
/// the mean, scaled by 1/√(K(K − 1)), is one more such change, so that
/// their shifts add up to the variance of the mean's shift.
///
/// With `data_draws` true, the log's own draw of stick events (`Stage`'s
/// `resampled`): the recorded wire stuck where it happened to, once,
/// and the fit compares that one draw with the mean over draws, so the
/// estimate moves with the draw. Each realisation's deviation from the
/// mean is such a draw; scaled by 1/√(K − 1), their shifts add up to the
/// variance of the estimate over draws of the log (a linearised
/// parametric bootstrap). Issue 28's campaign: without it, e₁ came out
/// 4–11σ off on five planes whose lag episodes (a dozen pushes) were too
/// few for the block-robust 1σ to see the draw's effect, and with the
/// stick events switched off the same fits were within 1σ.
fn wire_systematic<'a>(
    part: &'a FitPart,
    paths: &'a Prediction,
    sticks: &'a replay::StickEvents,
    data_draws: bool,
) -> impl Fn(&PlaneModel) -> Result<Vec<Vec<f64>>, IdentifyError> + Sync + 'a {
    let (map, fit_rows) = (part.map, part.rows);
    move |m: &PlaneModel| -> Result<Vec<Vec<f64>>, IdentifyError> {
        let mut out: Vec<Vec<f64>> = Vec::new();
        if !data_draws {
            out.extend(m.wires.iter().enumerate().map(|(j, w)| {
                let per = w.mm_per_count / 12f64.sqrt() / 0.01;
                (0..map.sensors.len())
                    .flat_map(|i| std::iter::repeat_n(if i == j { per } else { 0.0 }, fit_rows))
                    .collect()
            }));
        }
        let sensors = sticks.realisations(&m.wires, paths)?;
        let k = sensors.first().map_or(0, |s| s.1.len());
        if k > 1 {
            let draws = if data_draws { 1.0 } else { k as f64 };
            let scale = 1.0 / (0.01 * (draws * (k - 1) as f64).sqrt());
            for r in 0..k {
                let mut v = Vec::with_capacity(sensors.len() * fit_rows);
                for (mean, runs) in &sensors {
                    v.extend(runs[r].iter().zip(mean).map(|(x, m)| (x - m) * scale));
                }
                out.push(v);
            }
        }
        Ok(out)
    }
}

/// Validation: the whole log replayed from t = 0 with the identified
/// `model` (and with the `prior`, for comparison), its angle against every
/// camera frame, the errors over the fitted and the held-out part.
fn validate(
    part: &FitPart,
    model: &PlaneModel,
    prior: &PlaneModel,
) -> Result<Validation, IdentifyError> {
    let (log, map) = (part.log, part.map);
    let all = frames(log, map.plane, log.len());
    let heldout_from_s = part.rows as f64 * log.period_s;
    let pred = replay(model, log, map, log.len())?;
    let prior_pred = replay(prior, log, map, log.len()).ok();
    let mut out_frames = Vec::with_capacity(all.len());
    for (t, a) in &all {
        if let Some(p) = pred.angle_at(*t) {
            out_frames.push(Frame {
                t_s: *t,
                recorded_deg: *a,
                predicted_deg: p,
            });
        }
    }
    let held = || out_frames.iter().filter(|f| f.t_s >= heldout_from_s);
    Ok(Validation {
        fit_rms_deg: rms(out_frames
            .iter()
            .filter(|f| f.t_s < heldout_from_s)
            .map(|f| f.predicted_deg - f.recorded_deg)),
        heldout_rms_deg: rms(held().map(|f| f.predicted_deg - f.recorded_deg)),
        heldout_max_deg: held()
            .map(|f| (f.predicted_deg - f.recorded_deg).abs())
            .fold(0.0, f64::max),
        heldout_from_s,
        prior_heldout_rms_deg: prior_pred.as_ref().map(|p| {
            rms(all
                .iter()
                .filter(|(t, _)| *t >= heldout_from_s)
                .filter_map(|(t, a)| p.angle_at(*t).map(|x| x - a)))
        }),
        prior_fit_rms_deg: prior_pred.as_ref().map(|p| {
            rms(all
                .iter()
                .filter(|(t, _)| *t < heldout_from_s)
                .filter_map(|(t, a)| p.angle_at(*t).map(|x| x - a)))
        }),
        frames: out_frames,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The mechanics Jacobian from a replay carrying derivatives (the
    /// stage's default since session 53) is the mechanics residuals' own:
    /// on a compact twin's log (with and without resistances), at a
    /// model with a stress slope, each parameter's column (the stage's
    /// nine; g too without the electrical columns) agrees with central
    /// differences of the residuals in the same
    /// coordinates, and the replay's angles are the plain replay's at the
    /// frames to the bit. Seen: within 1.3·10⁻⁴ of the differences' rms
    /// (g), 3·10⁻⁶ or less for the rest; a wrong coordinate scale (value
    /// against its logarithm) is off by order one, and frames taken one
    /// substep late already fail (1.7·10⁻³).
    #[test]
    fn the_derived_mechanics_jacobian_is_the_residuals_own() {
        // With the electrical columns the stage's nine parameters (g is
        // fitted by stage 1 then); without them (angles only) g too.
        for electrical in [true, false] {
            derived_jacobian_against_differences(electrical);
        }
    }

    /// The compact 2D twin's log (seed 3), with or without the electrical
    /// columns.
    fn compact_log(electrical: bool) -> ExcitationLog {
        let noise = ElectricalNoise {
            current_a: 0.002,
            resistance_ohm: 0.02,
        };
        let plan = ExcitationPlan::compact(1);
        twin::record_2d(&hidden::joint_2d(3), &plan, electrical, noise).unwrap()
    }

    /// At a slope of exactly 0 (the prior's, which the stage can start a
    /// fit from) the slope's column is the residuals' one-sided
    /// derivative, not 0: a plane skips the shift there, a dual must not
    /// (before, a fit started there never moved the slope and called it
    /// not excited). Against a forward difference (the plane refuses a
    /// negative slope); seen 2.4·10⁻⁴ of its rms.
    #[test]
    fn the_slope_column_is_not_lost_at_a_slope_of_zero() {
        let log = compact_log(true);
        let opts = IdentifyOptions::default();
        let part = FitPart::new(&log, PlaneMap::of(1, 0), opts.fit_fraction).unwrap();
        let fit_frames = frames(&log, 0, part.rows);
        let mech = mechanics_residuals(&part, &opts, &fit_frames);
        let jac = mechanics_jacobian(&part, &opts, &fit_frames);
        let mut model = prior_model_2d(&Joint2dParams::default(), &opts);
        assert_eq!(Param::StressShift.get(&model), 0.0, "the prior's slope");
        let active = MECHANICS_PARAMS.to_vec();
        let j = active
            .iter()
            .position(|p| *p == Param::StressShift)
            .unwrap();
        let derived = jac(&model, &active).unwrap().unwrap();
        let r0 = mech(&model).unwrap();
        let h = 1e-4;
        Param::StressShift.set(&mut model, h);
        let up = mech(&model).unwrap();
        let diff: Vec<f64> = up.iter().zip(&r0).map(|(u, r)| (u - r) / h).collect();
        let scale = rms(diff.iter().copied());
        let err = rms(diff.iter().zip(&derived[j]).map(|(d, g)| d - g));
        eprintln!("slope at 0: rms {scale:.3e}, rms of the difference {err:.3e}");
        assert!(scale > 0.0, "the residuals depend on the slope");
        assert!(
            err <= 1e-2 * scale,
            "derived against a forward difference {err:.3e}, rms {scale:.3e}"
        );
    }

    fn derived_jacobian_against_differences(electrical: bool) {
        let log = compact_log(electrical);
        let opts = IdentifyOptions::default();
        let map = PlaneMap::of(1, 0);
        let part = FitPart::new(&log, map, opts.fit_fraction).unwrap();
        let fit_frames = frames(&log, 0, part.rows);
        let (mech, jac) = (
            mechanics_residuals(&part, &opts, &fit_frames),
            mechanics_jacobian(&part, &opts, &fit_frames),
        );
        let mut model = prior_model_2d(&Joint2dParams::default(), &opts);
        Param::StressShift.set(&mut model, 0.07);
        // A driver strong enough for the plan's 1.9 V level to start the
        // antagonist's transformation (0.4 A, unsaturated): g then moves
        // the link where the currents are not logged.
        Param::Transconductance.set(&mut model, 2.0);
        let mut active = MECHANICS_PARAMS.to_vec();
        if !electrical {
            active.insert(0, Param::Transconductance);
        }
        let derived = jac(&model, &active)
            .expect("every parameter carried")
            .unwrap();
        let r0 = mech(&model).unwrap();
        assert_eq!(log.resistance_ohm.is_some(), electrical);
        assert_eq!(r0.len() > fit_frames.len(), electrical);

        // The values: the plain replay's, bit for bit, at every frame.
        let (_, h_s) = replay::split(log.period_s, model.substep_s);
        let at: Vec<usize> = fit_frames
            .iter()
            .map(|(t, _)| (t / h_s - 1e-6).ceil().max(0.0) as usize)
            .collect();
        let plain = replay(&model, &log, part.map, part.rows).unwrap();
        let s =
            replay::replay_sensitivities(&model, &log, part.map, part.rows, &active, &at).unwrap();
        assert_eq!(s.angle_deg.len(), at.len());
        for (k, (a, &i)) in s.angle_deg.iter().zip(&at).enumerate() {
            assert_eq!(a.to_bits(), plain.angle_deg[i].to_bits(), "frame {k}");
        }

        let x0 = stage::coords(&active, &model);
        for (j, p) in active.iter().enumerate() {
            // A relative step of 1e-4 in the value (as `link::tests`).
            let h = match p.scale() {
                Scale::Log { .. } => 1e-4,
                Scale::Linear { .. } => 1e-4 * x0[j].abs(),
            };
            let at_x = |dx: f64| {
                let mut x = x0.clone();
                x[j] += dx;
                mech(&with_coords(&model, &active, &x)).unwrap()
            };
            let (up, down) = (at_x(h), at_x(-h));
            let diff: Vec<f64> = up
                .iter()
                .zip(&down)
                .map(|(u, d)| (u - d) / (2.0 * h))
                .collect();
            assert_eq!(derived[j].len(), diff.len(), "{}", p.field());
            let scale = rms(diff.iter().copied());
            let err = rms(diff.iter().zip(&derived[j]).map(|(d, g)| d - g));
            eprintln!(
                "electrical {electrical}, {}: rms {scale:.3e}, rms of the difference {err:.3e}",
                p.field()
            );
            assert!(scale > 0.0, "{}: the residuals depend on it", p.field());
            assert!(
                err <= 1e-3 * scale,
                "{}: derived against central differences {err:.3e}, rms {scale:.3e}",
                p.field()
            );
        }
    }
}
