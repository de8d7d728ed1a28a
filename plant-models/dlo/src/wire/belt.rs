//! The inextensible belt by the fishbone model (Wakamatsu et al. §V–VI,
//! L906–1072).
//!
//! The spine (the centre line along the length) carries the Euler angles
//! φ, θ, ψ; its position is x(u) = ∫η du (Eq. 31). The rib lines, straight
//! lines across the belt, make the angle α with the spine, β = tan α
//! (Eq. 43–45, 54). Developability and inextensibility give ω_ξ = 0
//! (Eq. 48), ω_η + ω_ζ β = 0 (Eq. 55) and |dβ/du| ≤ 2/V (Eq. 56), which
//! the paper imposes at 16 points u = iL_u/15 (L1049). The energy is Eq. 57,
//! R_f/2 ∫ (ω_ζ² + ω_η²)²/ω_ζ² du, used in the form R_f/2 ∫ ω_ζ²(1 + β²)² du,
//! which equals it wherever Eq. 55 holds and, unlike the printed form, is
//! defined on the flat belt (ω_ζ = 0) the solve starts from.
//!
//! The paper's example (Eq. 58–61): L_u = 1, width L_v = 0.1, R_f = 1, one end
//! at the origin in the natural frame, the other at [0, 0.7, 0]L_u turned by
//! π/6 about x, β = 0 at both ends. The problem is symmetric under x → −x;
//! the solve starts from a slight bow towards +x, the side of the paper's
//! highest point [0.3, 0.4, −0.01]L_u (L1058).
//!
//! **Two discretisations.** The default, `method = "segments"`
//! ([`super::strip`]), cuts the spine into straight segments on which
//! Eq. 48 and 55 hold exactly, so the surface is developable everywhere.
//! `method = "ritz"` is the paper's form: Euler angles and β in the Eq. 20
//! basis, with Eq. 48, 55 and 56 at the collocation points only.
//!
//! **Ritz basis size.** With the paper's 4 harmonics (10 functions per
//! profile, 40 unknowns), the example has 43 independent equality
//! conditions:
//! * 4 of Eq. 59, 3 of Eq. 58, 3 of Eq. 60 and 1 of Eq. 61;
//! * 32 of Eq. 48 and 55 at the 16 points.
//!
//! The multiplier method then ends with a violation of 0.03–0.5 and no
//! shape, so 6 harmonics (56 unknowns) is the Ritz default. Even so, the
//! solved spine bends in its own plane between the points (rms ω_ξ ≈ 1.4 ×
//! rms ω_ζ), and its top depends on the basis and on the start (README).
//!
//! Internally lengths are in units of L_u and energy in units of R_f/L_u:
//! the shape cannot depend on a constant R_f (L1070–1072), and a test checks
//! that the solve is the same when R_f is scaled.
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::basis::{self, Basis};
use super::frame::{euler_angles, omega_partials, omegas, rotation_and_partials};
use super::optimize::{self, Kind, Problem, Settings, Solution};
use super::strip::{CompiledStrip, END_ROWS};
use super::verify::Checks;
use crate::error::{check_positive, check_range, Result};

type V3 = Vector3<f64>;

/// A belt and its end conditions (defaults: the paper's Fig. 10 example).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BeltProblem {
    /// Length L_u, m (L1046: 1).
    pub length_m: f64,
    /// Width L_v, m (L1046: 0.1).
    pub width_m: f64,
    /// Flexural rigidity of the spine R_f, N·m² (L1046: 1).
    pub flexural_rigidity_n_m2: f64,
    /// Position of the far end of the spine, m (Eq. 58: [0, 0.7, 0] L_u).
    pub end_m: [f64; 3],
    /// Rotation of the far end about x, rad (Eq. 60: π/6).
    pub end_turn_rad: f64,
    /// Points where Eq. 48, 55, 56 are imposed, `method = "ritz"` only
    /// (L1049: 16).
    pub collocation_points: usize,
    /// Ritz harmonics, `method = "ritz"` only (Eq. 20 has 4; the default is
    /// 6, see the module doc).
    pub harmonics: usize,
    /// Segments (`method = "segments"`; 120, from the convergence study in
    /// the README) or integration intervals (`method = "ritz"`).
    pub intervals: usize,
    /// Initial bow of the spine towards +x (ψ amplitude, rad): picks the
    /// side of the mirror-symmetric pair of solutions.
    pub initial_bow_rad: f64,
    /// `segments` (default): straight segments with Eq. 48 and 55 exact
    /// everywhere ([`super::strip`]), `intervals` of them; `ritz`: the
    /// paper's Euler angles in the Eq. 20 basis with Eq. 48, 55 and 56 at
    /// `collocation_points` (developable only at those points).
    pub method: BeltMethod,
}

/// How the belt is discretised.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum BeltMethod {
    /// Straight segments, developable everywhere (the default).
    #[default]
    Segments,
    /// The paper's Ritz basis with collocation points.
    Ritz,
}

impl Default for BeltProblem {
    fn default() -> Self {
        Self {
            length_m: 1.0,
            width_m: 0.1,
            flexural_rigidity_n_m2: 1.0,
            end_m: [0.0, 0.7, 0.0],
            end_turn_rad: std::f64::consts::PI / 6.0,
            collocation_points: 16,
            harmonics: 6,
            intervals: 120,
            initial_bow_rad: 0.2,
            method: BeltMethod::Segments,
        }
    }
}

/// The solved belt, in SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct BeltShape {
    /// u along the spine, m.
    pub u_m: Vec<f64>,
    /// Spine positions, m.
    pub spine_m: Vec<V3>,
    /// The two long edges (Eq. 44), m.
    pub edges_m: [Vec<V3>; 2],
    /// β = tan α along the spine.
    pub beta: Vec<f64>,
    /// Euler angles along the spine, rad.
    pub euler_rad: Vec<[f64; 3]>,
    /// The highest point of the object: the point of the surface with the
    /// largest x (refined between samples, see [`curve_top`]), m.
    pub highest_m: V3,
    /// Energy, J.
    pub energy_j: f64,
    /// Largest violation of the constraints (lengths in m, the rest
    /// dimensionless).
    pub max_violation: f64,
    pub solution: Solution,
    /// The answer's own evidence (issue 29): constraints, stationarity,
    /// stability and, from [`BeltProblem::solve_verified`], the change to
    /// a discretisation twice as fine; see [`Checks`].
    pub checks: Checks,
}

impl BeltShape {
    /// Whether every check holds: only then is the answer converged.
    pub fn verified(&self) -> bool {
        self.checks.verified()
    }
}

/// Segments of the first, coarse solve of the segment method.
const COARSE_SEGMENTS: usize = 30;

/// The belt compiled for the solver (dimensionless).
pub struct CompiledBelt {
    p: BeltProblem,
    basis: Basis,
    n: usize,
    kinds: Vec<Kind>,
    colloc: Vec<f64>,
    width: f64,
}

/// Solver settings for belts: longer inner and outer loops than the
/// defaults (with 400 BFGS iterations per outer step the example settles
/// on another local minimum, highest point [0.11, 0.49] L_u).
pub fn belt_settings() -> Settings {
    Settings {
        max_inner: 2000,
        max_outer: 60,
        ..Settings::default()
    }
}

impl BeltProblem {
    /// Checks every field; the error names the bad one.
    pub fn validate(&self) -> Result<()> {
        check_positive("length_m", self.length_m)?;
        check_range("width_m", self.width_m, 1e-9, 0.5 * self.length_m)?;
        check_positive("flexural_rigidity_n_m2", self.flexural_rigidity_n_m2)?;
        for v in self.end_m {
            check_range("end_m", v, -self.length_m, self.length_m)?;
        }
        if V3::new(self.end_m[0], self.end_m[1], self.end_m[2]).norm() > self.length_m {
            return Err(crate::DloError::InvalidScenario(
                "end_m: the ends are farther apart than the belt is long".into(),
            ));
        }
        check_range("end_turn_rad", self.end_turn_rad, -10.0, 10.0)?;
        check_range(
            "collocation_points",
            self.collocation_points as f64,
            2.0,
            200.0,
        )?;
        check_range("harmonics", self.harmonics as f64, 0.0, 12.0)?;
        check_range("intervals", self.intervals as f64, 16.0, 2000.0)?;
        check_range("initial_bow_rad", self.initial_bow_rad, -1.0, 1.0)?;
        Ok(())
    }

    /// Compiles the problem.
    pub fn compile(&self) -> Result<CompiledBelt> {
        self.validate()?;
        let basis = Basis::new(self.harmonics, self.intervals);
        let m = self.collocation_points;
        let mut kinds = vec![Kind::Equality; 4 + 3 + 6 + 1 + 2 * m];
        kinds.extend(vec![Kind::Inequality; 2 * m]);
        Ok(CompiledBelt {
            n: basis.n,
            basis,
            kinds,
            colloc: (0..m).map(|i| i as f64 / (m - 1) as f64).collect(),
            width: self.width_m / self.length_m,
            p: self.clone(),
        })
    }

    /// Solves from the flat belt with the initial bow. The shape carries
    /// the checks that can be made at this discretisation (constraints,
    /// stationarity, stability); [`Self::solve_verified`] adds the
    /// discretisation check.
    pub fn solve(&self, settings: &Settings) -> Result<BeltShape> {
        if self.method == BeltMethod::Segments {
            return Ok(self.solve_segments(settings)?.0);
        }
        let c = self.compile()?;
        let mut x0 = vec![0.0; c.vars()];
        // ψ(u) = −bow·sin(2πu): at θ = 0, η = (−sin(φ+ψ), cos(φ+ψ), 0).
        x0[2 * c.n + 2] = -self.initial_bow_rad;
        let sol = optimize::solve(&c, x0, settings)?;
        Ok(c.shape(sol, settings.tolerance))
    }

    /// The segment solve, and the same belt on half the segments, solved
    /// on the way. From the bow on a coarse strip (at most 30 segments),
    /// refined to N/2 segments and then to N: straight from the bow, a fine
    /// strip's BFGS meets shallow minima of high energy (README).
    fn solve_segments(&self, settings: &Settings) -> Result<(BeltShape, BeltShape)> {
        self.validate()?;
        let strip = |segments| {
            CompiledStrip::new(&BeltProblem {
                intervals: segments,
                ..self.clone()
            })
        };
        let from_bow = |c: &CompiledStrip| -> Result<Solution> {
            let sol = optimize::solve(c, c.start(self.initial_bow_rad), settings)?;
            Ok(polished(c, sol, settings))
        };
        let (n, half_n) = (self.intervals, self.intervals / 2);
        let first = strip(n.min(COARSE_SEGMENTS));
        let first_sol = from_bow(&first)?;
        let half = strip(half_n);
        // N/2 resampled from the first strip (coarser or finer) and solved;
        // N refined from N/2 when that is finer than the first strip, else
        // from the first.
        let half_sol = if half_n == first.segments {
            first_sol.clone()
        } else {
            refine(&half, &first, &first_sol, settings)?
        };
        let full = strip(n);
        let full_sol = if n == first.segments {
            first_sol
        } else if half_n > first.segments {
            refine(&full, &half, &half_sol, settings)?
        } else {
            refine(&full, &first, &first_sol, settings)?
        };
        Ok((
            strip_shape(&full, full_sol, settings.tolerance),
            strip_shape(&half, half_sol, settings.tolerance),
        ))
    }

    /// [`Self::solve`], then the discretisation check (issue 29): the
    /// belt solved on a second discretisation must pass its own checks,
    /// and the energy (relative) and every spine and edge point (in units
    /// of L_u, at the same u) may differ by at most
    /// [`super::verify::DISCRETISATION_TOLERANCE`] between the two.
    ///
    /// * Segments: the second is **half** as fine (N/2 segments, solved on
    ///   the way to N). The change from N/2 to N overstates the error at N
    ///   (for an error falling like h², it is three times it), so a pass is
    ///   conservative; doubling instead would cost a solve on 2N segments,
    ///   which took minutes at N = 240 and did not reach stationarity
    ///   there (README).
    /// * `method = "ritz"`: twice as fine: harmonics (at most 12),
    ///   intervals and collocation points (2m − 1, keeping the old ones)
    ///   doubled, solved from the answer.
    pub fn solve_verified(&self, settings: &Settings) -> Result<BeltShape> {
        if self.method == BeltMethod::Segments {
            let (mut shape, half) = self.solve_segments(settings)?;
            record_discretisation(&mut shape, &half, self.length_m);
            return Ok(shape);
        }
        let mut shape = self.solve(settings)?;
        let mut fine = self.clone();
        fine.intervals = (2 * self.intervals).min(2000);
        fine.harmonics = (2 * self.harmonics).clamp(1, 12);
        fine.collocation_points = (2 * self.collocation_points - 1).min(200);
        let (cc, cf) = (self.compile()?, fine.compile()?);
        let mut x0 = vec![0.0; cf.vars()];
        for b in 0..4 {
            x0[b * cf.n..b * cf.n + cc.n]
                .copy_from_slice(&shape.solution.x[b * cc.n..(b + 1) * cc.n]);
        }
        let f = cf.shape(optimize::solve(&cf, x0, settings)?, settings.tolerance);
        record_discretisation(&mut shape, &f, self.length_m);
        Ok(shape)
    }
}

/// The solution `coarse_sol` of `coarse` carried onto `fine` and solved
/// there: the multiplier method from the resampled unknowns, with the
/// end conditions' multipliers kept (the same rows at any N; cold ones let
/// the first BFGS pass flatten the belt), then the Newton polish.
fn refine(
    fine: &CompiledStrip,
    coarse: &CompiledStrip,
    coarse_sol: &Solution,
    settings: &Settings,
) -> Result<Solution> {
    let start = fine.resample(coarse, &coarse_sol.x);
    let mut lam = vec![0.0; fine.kinds().len()];
    lam[..END_ROWS].copy_from_slice(&coarse_sol.multipliers[..END_ROWS]);
    let sol = optimize::solve_warm(fine, start, Some((&lam, settings.rho0)), settings)?;
    Ok(polished(fine, sol, settings))
}

/// `sol` after the Newton polish of its KKT conditions, started from
/// least-squares multipliers ([`least_squares_multipliers`]); when that
/// polish fails, up to three more rounds of the multiplier method from the
/// answer with ρ started afresh, each polished. Without a polish the
/// multiplier method's answer stands, and its checks say how far from
/// stationary it is.
fn polished(problem: &CompiledStrip, sol: Solution, settings: &Settings) -> Solution {
    let tol = settings.tolerance;
    let mut sol = sol;
    for _ in 0..4 {
        let start = least_squares_multipliers(problem, &sol, tol);
        if let Some(p) = optimize::polish(problem, &start, tol) {
            return p;
        }
        match optimize::solve_warm(
            problem,
            sol.x.clone(),
            Some((&sol.multipliers, settings.rho0)),
            settings,
        ) {
            Ok(again) => sol = again,
            Err(_) => break,
        }
    }
    sol
}

/// `sol` with its multipliers replaced by those that best balance the
/// energy gradient, min ‖∇U + Σλ∇c‖ over the equalities and the
/// inequalities within 10·`tolerance` of their bound (the others 0). The
/// multiplier method's own multipliers, after ρ has grown to 1e9, can be
/// far from these, and the polish's Hessian of the Lagrangian, which
/// depends on them, then sends its first Newton step astray.
fn least_squares_multipliers<P: Problem>(problem: &P, sol: &Solution, tolerance: f64) -> Solution {
    use nalgebra::{DMatrix, DVector};
    let (n, kinds) = (problem.vars(), problem.kinds());
    let m = kinds.len();
    let (mut c, mut jac) = (vec![0.0; m], vec![vec![0.0; n]; m]);
    problem.constraints(&sol.x, &mut c, &mut jac);
    let mut g = vec![0.0; n];
    problem.energy(&sol.x, &mut g);
    let rows: Vec<usize> = (0..m)
        .filter(|&r| kinds[r] == Kind::Equality || c[r] > -10.0 * tolerance)
        .collect();
    let jt = DMatrix::from_fn(n, rows.len(), |i, q| jac[rows[q]][i]);
    let svd = jt.svd(true, true);
    let cut = 1e-10 * svd.singular_values.max();
    let mut out = sol.clone();
    if let Ok(l) = svd.solve(&-DVector::from_vec(g), cut) {
        out.multipliers.iter_mut().for_each(|v| *v = 0.0);
        for (q, &r) in rows.iter().enumerate() {
            out.multipliers[r] = l[q];
        }
    }
    out
}

/// Records in `shape.checks` the change between `shape` and `other`, a
/// solve of the same belt on another discretisation (compared at the
/// samples of the coarser of the two, the finer one interpolated linearly
/// in u), or that `other` failed its own checks.
fn record_discretisation(shape: &mut BeltShape, other: &BeltShape, length_m: f64) {
    if !other.verified() {
        shape.checks.fine_solve_failed = true;
        return;
    }
    let scale = shape.energy_j.abs().max(f64::MIN_POSITIVE);
    shape.checks.discretisation_energy = Some((other.energy_j - shape.energy_j).abs() / scale);
    let (coarse, fine) = if other.u_m.len() < shape.u_m.len() {
        (other, &*shape)
    } else {
        (&*shape, other)
    };
    let at = |curve: &[V3], u: f64| {
        let last = fine.u_m.len() - 1;
        let pos = (u / length_m * last as f64).clamp(0.0, last as f64);
        let k = (pos.floor() as usize).min(last - 1);
        let t = pos - k as f64;
        curve[k] * (1.0 - t) + curve[k + 1] * t
    };
    let curves = |b: &BeltShape| {
        [
            b.spine_m.clone(),
            b.edges_m[0].clone(),
            b.edges_m[1].clone(),
        ]
    };
    let moved = curves(coarse)
        .iter()
        .zip(curves(fine).iter())
        .flat_map(|(c, f)| {
            let at = &at;
            c.iter()
                .zip(&coarse.u_m)
                .map(move |(p, &u)| (p - at(f, u)).norm() / length_m)
        })
        .fold(0.0, f64::max);
    shape.checks.discretisation_position = Some(moved);
}

/// The largest-x point of a sampled curve, refined by the parabola
/// through the sample with the largest x and its two neighbours (the
/// samples are 1/`intervals` apart; the top is flat, so y and z of the
/// raw sample would carry half a sample spacing of error).
pub fn curve_top(curve: &[V3]) -> V3 {
    let Some((k, _)) = curve
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.x.total_cmp(&b.1.x))
    else {
        return V3::zeros();
    };
    if k == 0 || k + 1 == curve.len() {
        return curve[k];
    }
    let (a, b, c) = (curve[k - 1], curve[k], curve[k + 1]);
    let d = a.x - 2.0 * b.x + c.x;
    if d >= 0.0 {
        return b;
    }
    // Vertex of the parabola through (−1, a.x), (0, b.x), (1, c.x).
    let t = (0.5 * (a.x - c.x) / d).clamp(-1.0, 1.0);
    let q =
        |fa: f64, fb: f64, fc: f64| fb + 0.5 * t * (fc - fa) + 0.5 * t * t * (fa - 2.0 * fb + fc);
    V3::new(q(a.x, b.x, c.x), q(a.y, b.y, c.y), q(a.z, b.z, c.z))
}

/// The highest point of the surface: the top of whichever of the spine
/// and the two edges reaches farthest in x (on a rib, x is linear in the
/// distance from the spine, so the surface's top lies on an edge or on the
/// spine).
fn surface_top(spine: &[V3], edges: &[Vec<V3>; 2]) -> V3 {
    [curve_top(spine), curve_top(&edges[0]), curve_top(&edges[1])]
        .into_iter()
        .max_by(|a, b| a.x.total_cmp(&b.x))
        .unwrap_or_else(V3::zeros)
}

/// Edges of Eq. 44 from node frames, β and spine positions.
fn edges_from_frames(
    frames: impl Iterator<Item = (V3, V3)>,
    beta: &[f64],
    spine: &[V3],
    half: f64,
) -> [Vec<V3>; 2] {
    let mut edges = [Vec::new(), Vec::new()];
    for (k, (eta, zeta)) in frames.enumerate() {
        // Eq. 44: ±V/(2 cos α) r, r = −η sin α + ζ cos α = cos α (ζ − βη).
        let rib = (zeta - eta * beta[k]) * half;
        edges[0].push(spine[k] + rib);
        edges[1].push(spine[k] - rib);
    }
    edges
}

/// The segment solution as a shape in SI units, bowing towards +x. The
/// problem is symmetric under the reflection x → −x and a solve may settle
/// on either side; a shape on the −x side is reflected (points x → −x,
/// frames P·A·diag(−1, 1, 1), which keeps them right-handed, keeps η and ζ
/// the reflected tangent and width directions and β unchanged). The
/// largest violation also counts the far end's orientation error as an
/// angle.
fn strip_shape(c: &CompiledStrip, sol: Solution, tolerance: f64) -> BeltShape {
    let ch = c.chain(&sol.x);
    let l = c.p.length_m;
    let half = 0.5 * c.p.width_m;
    let build = |flip: f64| {
        let p = nalgebra::Matrix3::from_diagonal(&V3::new(flip, 1.0, 1.0));
        let frames: Vec<nalgebra::Matrix3<f64>> = ch.frames.iter().map(|a| p * a * p).collect();
        let spine: Vec<V3> = ch.x.iter().map(|x| p * x * l).collect();
        let edges = edges_from_frames(
            frames
                .iter()
                .map(|a| (a.column(1).into_owned(), a.column(2).into_owned())),
            &ch.beta,
            &spine,
            half,
        );
        (frames, spine, edges)
    };
    let (mut frames, mut spine, mut edges) = build(1.0);
    let reach = |side: f64, spine: &[V3], edges: &[Vec<V3>; 2]| {
        spine
            .iter()
            .chain(&edges[0])
            .chain(&edges[1])
            .map(|q| side * q.x)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    if reach(-1.0, &spine, &edges) > reach(1.0, &spine, &edges) {
        (frames, spine, edges) = build(-1.0);
    }
    let mut g = vec![0.0; sol.x.len()];
    let energy_j = c.p.flexural_rigidity_n_m2 / l * c.energy(&sol.x, &mut g);
    let n = c.segments;
    let max_violation = sol.max_violation.max(c.end_angle(&ch));
    BeltShape {
        checks: Checks::at(c, &sol, max_violation, tolerance),
        u_m: (0..=n).map(|i| i as f64 / n as f64 * l).collect(),
        euler_rad: frames.iter().map(euler_angles).collect(),
        highest_m: surface_top(&spine, &edges),
        beta: ch.beta.clone(),
        spine_m: spine,
        edges_m: edges,
        energy_j,
        max_violation,
        solution: sol,
    }
}

/// Angles and rates at one u.
struct Point {
    ang: [f64; 3],
    rate: [f64; 3],
    beta: f64,
    dbeta: f64,
}

impl CompiledBelt {
    fn point(&self, a: &[f64], e: &[f64], de: &[f64]) -> Point {
        let n = self.n;
        let q = |k: usize, v: &[f64]| basis::dot(&a[k * n..(k + 1) * n], v);
        Point {
            ang: [q(0, e), q(1, e), q(2, e)],
            rate: [q(0, de), q(1, de), q(2, de)],
            beta: q(3, e),
            dbeta: q(3, de),
        }
    }

    fn points(&self, a: &[f64]) -> Vec<Point> {
        (0..self.basis.s.len())
            .map(|k| self.point(a, &self.basis.e[k], &self.basis.de[k]))
            .collect()
    }

    /// Spine positions by the trapezoid rule.
    fn spine(&self, pts: &[Point]) -> Vec<V3> {
        let h = self.basis.h();
        let mut x = V3::zeros();
        let mut out = vec![x];
        let eta = |p: &Point| {
            rotation_and_partials(p.ang[0], p.ang[1], p.ang[2])[0]
                .column(1)
                .into_owned()
        };
        let mut prev = eta(&pts[0]);
        for p in &pts[1..] {
            let now = eta(p);
            x += (prev + now) * (0.5 * h);
            out.push(x);
            prev = now;
        }
        out
    }

    /// Turns a solution into the shape in SI units, with the checks made
    /// at this discretisation (constraints within `tolerance`).
    pub fn shape(&self, sol: Solution, tolerance: f64) -> BeltShape {
        let pts = self.points(&sol.x);
        let l = self.p.length_m;
        let spine: Vec<V3> = self.spine(&pts).iter().map(|x| x * l).collect();
        let beta: Vec<f64> = pts.iter().map(|p| p.beta).collect();
        let edges = edges_from_frames(
            pts.iter().map(|p| {
                let a = rotation_and_partials(p.ang[0], p.ang[1], p.ang[2])[0];
                (a.column(1).into_owned(), a.column(2).into_owned())
            }),
            &beta,
            &spine,
            0.5 * self.p.width_m,
        );
        let highest = surface_top(&spine, &edges);
        let mut g = vec![0.0; sol.x.len()];
        let energy_j = self.p.flexural_rigidity_n_m2 / l * self.energy(&sol.x, &mut g);
        BeltShape {
            u_m: self.basis.s.iter().map(|u| u * l).collect(),
            beta,
            euler_rad: pts.iter().map(|p| p.ang).collect(),
            spine_m: spine,
            edges_m: edges,
            highest_m: highest,
            energy_j,
            checks: Checks::at(self, &sol, sol.max_violation, tolerance),
            max_violation: sol.max_violation,
            solution: sol,
        }
    }
}

impl Problem for CompiledBelt {
    fn vars(&self) -> usize {
        4 * self.n
    }

    fn energy(&self, a: &[f64], grad: &mut [f64]) -> f64 {
        let n = self.n;
        let mut total = 0.0;
        for k in 0..self.basis.s.len() {
            let (e, de) = (&self.basis.e[k], &self.basis.de[k]);
            let p = self.point(a, e, de);
            let w = self.basis.w[k];
            let (st, ct) = p.ang[1].sin_cos();
            let wz = ct * p.rate[0] + p.rate[2];
            let b2 = 1.0 + p.beta * p.beta;
            total += w * 0.5 * wz * wz * b2 * b2;
            let d_wz = w * wz * b2 * b2;
            let d_beta = w * wz * wz * b2 * 2.0 * p.beta;
            for i in 0..n {
                grad[i] += d_wz * ct * de[i];
                grad[n + i] += d_wz * (-st * p.rate[0]) * e[i];
                grad[2 * n + i] += d_wz * de[i];
                grad[3 * n + i] += d_beta * e[i];
            }
        }
        total
    }

    fn kinds(&self) -> &[Kind] {
        &self.kinds
    }

    fn constraints(&self, a: &[f64], v: &mut [f64], jac: &mut [Vec<f64>]) {
        let n = self.n;
        let hm = self.p.harmonics;
        for row in jac.iter_mut() {
            row.iter_mut().for_each(|x| *x = 0.0);
        }
        let mut r = 0;
        // Eq. 59: all four profiles vanish at u = 0.
        let e0 = basis::values(hm, 0.0);
        for q in 0..4 {
            v[r] = basis::dot(&a[q * n..(q + 1) * n], &e0);
            jac[r][q * n..(q + 1) * n].copy_from_slice(&e0);
            r += 1;
        }
        // Eq. 58: ∫η du = end.
        let pts = self.points(a);
        let h = self.basis.h();
        let m = pts.len() - 1;
        let end = V3::new(self.p.end_m[0], self.p.end_m[1], self.p.end_m[2]) / self.p.length_m;
        let mut x = V3::zeros();
        let rows = r;
        for (k, p) in pts.iter().enumerate() {
            let c = if k == 0 || k == m { 0.5 * h } else { h };
            let [am, df, dt, dp] = rotation_and_partials(p.ang[0], p.ang[1], p.ang[2]);
            x += am.column(1) * c;
            let e = &self.basis.e[k];
            for d in 0..3 {
                for (q, dm) in [df, dt, dp].iter().enumerate() {
                    let coef = c * dm[(d, 1)];
                    for i in 0..n {
                        jac[rows + d][q * n + i] += coef * e[i];
                    }
                }
            }
        }
        for d in 0..3 {
            v[r] = x[d] - end[d];
            r += 1;
        }
        // Eq. 60: η and ζ at the far end (a turn about x).
        let e1 = basis::values(hm, 1.0);
        let p1 = self.point(a, &e1, &basis::derivatives(hm, 1.0));
        let [am, df, dt, dp] = rotation_and_partials(p1.ang[0], p1.ang[1], p1.ang[2]);
        let (s6, c6) = self.p.end_turn_rad.sin_cos();
        let target = [V3::new(0.0, c6, s6), V3::new(0.0, -s6, c6)];
        for (col, t) in [(1usize, target[0]), (2, target[1])] {
            for d in 0..3 {
                v[r] = am[(d, col)] - t[d];
                for (q, dm) in [df, dt, dp].iter().enumerate() {
                    for i in 0..n {
                        jac[r][q * n + i] += dm[(d, col)] * e1[i];
                    }
                }
                r += 1;
            }
        }
        // Eq. 61: β(L_u) = 0.
        v[r] = p1.beta;
        jac[r][3 * n..4 * n].copy_from_slice(&e1);
        r += 1;
        // Eq. 48 and 55 at the collocation points, then Eq. 56.
        let mut ineq = Vec::new();
        for &u in &self.colloc {
            let (e, de) = (basis::values(hm, u), basis::derivatives(hm, u));
            let p = self.point(a, &e, &de);
            let om = omegas(p.ang[1], p.ang[2], p.rate[0], p.rate[1], p.rate[2]);
            let part = omega_partials(p.ang[1], p.ang[2], p.rate[0], p.rate[1]);
            // ω_ξ = 0.
            v[r] = om.x;
            for i in 0..n {
                jac[r][n + i] += part[0].x * e[i];
                jac[r][2 * n + i] += part[1].x * e[i];
                jac[r][i] += part[2].x * de[i];
                jac[r][n + i] += part[3].x * de[i];
                jac[r][2 * n + i] += part[4].x * de[i];
            }
            r += 1;
            // ω_η + ω_ζ β = 0.
            v[r] = om.y + om.z * p.beta;
            for i in 0..n {
                let comb = |c: &V3| c.y + c.z * p.beta;
                jac[r][n + i] += comb(&part[0]) * e[i];
                jac[r][2 * n + i] += comb(&part[1]) * e[i];
                jac[r][i] += comb(&part[2]) * de[i];
                jac[r][n + i] += comb(&part[3]) * de[i];
                jac[r][2 * n + i] += comb(&part[4]) * de[i];
                jac[r][3 * n + i] += om.z * e[i];
            }
            r += 1;
            ineq.push((p.dbeta, de));
        }
        let limit = 2.0 / self.width;
        for (dbeta, de) in ineq {
            for sign in [1.0, -1.0] {
                v[r] = sign * dbeta - limit;
                for i in 0..n {
                    jac[r][3 * n + i] = sign * de[i];
                }
                r += 1;
            }
        }
        debug_assert_eq!(r, v.len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn belt_gradients_match_finite_differences() {
        let c = BeltProblem {
            intervals: 40,
            ..BeltProblem::default()
        }
        .compile()
        .unwrap();
        let n = c.vars();
        let x: Vec<f64> = (0..n)
            .map(|i| 0.2 * ((i as f64) * 0.9).cos() / (1.0 + (i % c.n) as f64))
            .collect();
        super::super::optimize::assert_derivatives_match_differences(&c, &x, 1e-6, None);
    }

    /// The paper's belt on 30 segments: its own checks pass (the answer is
    /// a stable KKT point of the 30-segment problem), but the discretisation
    /// check fails, as it should. The independent reference
    /// (`scripts/belt_reference.py`, README) moves the surface's top by
    /// 0.026 L_u in y from 30 to 60 segments, and by 0.0017 from 60 to
    /// 120: 30 segments are not converged to 1 %.
    #[test]
    fn a_coarse_belt_passes_its_own_checks_and_fails_the_discretisation_check() {
        let shape = BeltProblem {
            intervals: 30,
            ..BeltProblem::default()
        }
        .solve_verified(&belt_settings())
        .unwrap();
        let c = &shape.checks;
        assert_eq!(c.failures(), vec!["discretisation"], "{c:?}");
        assert!(!shape.verified());
        let moved = c.discretisation_position.unwrap();
        assert!(moved > 2.0 * c.discretisation_tolerance, "{c:?}");
        // The top agrees with the reference's 30-segment row to 2e-3 L_u
        // ([0.3070, 0.3940, −0.0184]; the midpoint rule differs at O(h²)).
        let top = shape.highest_m;
        assert!(
            (top - V3::new(0.3070, 0.3940, -0.0184)).abs().max() < 2e-3,
            "{top:?}"
        );
    }

    /// A belt answer stopped early, or moved off its equilibrium, fails the
    /// stationarity check; the answer it came from passes it.
    #[test]
    fn a_belt_stopped_early_or_perturbed_is_not_stationary() {
        let p = BeltProblem {
            intervals: 30,
            ..BeltProblem::default()
        };
        let settings = belt_settings();
        let good = p.solve(&settings).unwrap();
        assert!(good.checks.kkt_residual < 1e-9, "{:?}", good.checks);
        let c = CompiledStrip::new(&p);
        // Moved off: one segment's curvature changed by 0.01 rad/L_u, the
        // multipliers kept.
        let mut off = good.solution.clone();
        off.x[10] += 1e-2;
        let moved = Checks::at(&c, &off, 0.0, settings.tolerance);
        assert!(
            moved.failures().contains(&"stationarity (KKT)"),
            "{moved:?}"
        );
        assert!(moved.kkt_residual > 10.0 * moved.kkt_tolerance, "{moved:?}");
        // Stopped early: the multiplier method with 50 BFGS iterations per
        // outer step and 10 outer steps, not polished.
        let early_settings = Settings {
            max_inner: 50,
            max_outer: 10,
            ..settings
        };
        let early = optimize::solve(&c, c.start(p.initial_bow_rad), &early_settings).unwrap();
        let checks = Checks::at(&c, &early, early.max_violation, settings.tolerance);
        assert!(
            checks.failures().contains(&"stationarity (KKT)"),
            "{checks:?}"
        );
    }

    /// A known saddle: with both ends on the y axis and no end turn, the
    /// belt bends in one plane (β = 0) as the clamped–clamped elastica. Its
    /// second, antisymmetric mode (an S about the midpoint) is an
    /// equilibrium but unstable: it can fall to the first mode (the
    /// classical result for the clamped–clamped elastica; Maddocks 1984).
    /// Started on that S, the solve reaches a KKT point whose stability
    /// check fails; started on the bow, a stable one of lower energy.
    #[test]
    fn the_antisymmetric_mode_of_a_planar_belt_is_caught_as_a_saddle() {
        let p = BeltProblem {
            intervals: 30,
            end_turn_rad: 0.0,
            ..BeltProblem::default()
        };
        let settings = belt_settings();
        let c = CompiledStrip::new(&p);
        let tau = std::f64::consts::TAU;
        // ψ(u) = a(cos 2πu − cos 4πu), a = 0.77 for ∫ψ²/2 ≈ 0.3 L_u of
        // shortening: ψ(0) = ψ(1) = 0, x(1) = ∫ψ = 0,
        // and x(u) antisymmetric about u = ½; κ = ψ'.
        let mut z = vec![0.0; c.vars()];
        for (i, k) in z.iter_mut().take(c.segments).enumerate() {
            let u = (i as f64 + 0.5) / c.segments as f64;
            *k = 0.77 * (-tau * (tau * u).sin() + 2.0 * tau * (2.0 * tau * u).sin());
        }
        // Newton on the KKT conditions straight from the start (the
        // multiplier method's BFGS would leave the saddle).
        let mut g = vec![0.0; c.vars()];
        let start = Solution {
            energy: c.energy(&z, &mut g),
            x: z,
            max_violation: 1.0,
            penalty: 0.0,
            multipliers: vec![0.0; c.kinds().len()],
            rho: settings.rho0,
            outer_iterations: 0,
            inner_iterations: 0,
            converged: false,
        };
        let start = least_squares_multipliers(&c, &start, settings.tolerance);
        let sol = optimize::polish(&c, &start, settings.tolerance).expect("a KKT point");
        let s = strip_shape(&c, sol, settings.tolerance);
        let mid = s.spine_m[c.segments / 2];
        let reach = s.spine_m.iter().map(|q| q.x.abs()).fold(0.0, f64::max);
        assert!(
            mid.x.abs() < 1e-6 && reach > 0.05,
            "mid {mid:?}, reach {reach}"
        );
        assert!(s.spine_m.iter().all(|q| q.z.abs() < 1e-9), "not planar");
        assert_eq!(
            s.checks.failures(),
            vec!["stability (saddle)"],
            "{:?}",
            s.checks
        );
        assert!(s.checks.min_curvature < -1e3 * s.checks.stability_tolerance);
        let bow = p.solve(&settings).unwrap();
        assert!(bow.checks.failures().is_empty(), "{:?}", bow.checks);
        assert!(
            bow.energy_j < s.energy_j,
            "{} vs {}",
            bow.energy_j,
            s.energy_j
        );
        // The bow's answer is the planar clamped–clamped elastica (β = 0):
        // by elliptic integrals (k = 0.53648, scipy.special in a script,
        // and tests/it/elastica_ref.rs) U = 32 K(E − (1 − k²)K) R_f/L_u =
        // 12.8470 and the mid deflection k/K = 0.31431 L_u. Measured on 30
        // segments: 12.942 (0.74 % high, the 30-segment chain) and
        // 0.31493 (0.2 %).
        assert!(
            (bow.energy_j / 12.847024 - 1.0).abs() < 0.01,
            "{}",
            bow.energy_j
        );
        let mid = bow.spine_m[c.segments / 2].x;
        assert!((mid - 0.314313).abs() < 0.01 * 0.314313, "{mid}");
    }

    /// The paper's belt, verified (issue 29), and the same belt with R_f
    /// × 37: four segment solves (30, 60, 120 segments, then 120 again);
    /// minutes in a debug build. `cargo test --profile ci-opt -p plant-dlo
    /// --lib belt_ -- --ignored`
    #[test]
    #[ignore = "long in debug builds: run with --profile ci-opt (README)"]
    fn belt_highest_point_is_the_papers_and_does_not_move_with_r_f() {
        // L1058: the highest point of the object [0.3, 0.4, −0.01] L_u;
        // L1070–1072: the shape is independent of a constant R_f.
        let base = BeltProblem::default();
        let s1 = base.solve_verified(&belt_settings()).unwrap();
        // Every check holds: constraints, stationarity, stability, and the
        // change from 60 to 120 segments within 1 % (the reference moves
        // the top by 0.0017 L_u and the energy by 1e-4 between them).
        assert!(s1.verified(), "{:?}", s1.checks);
        assert!(s1.max_violation < 1e-6, "violation {}", s1.max_violation);
        let top = s1.highest_m;
        // Measured: [0.3066, 0.4183, −0.0240] L_u, the surface's top on an
        // edge. The margin in y is thin (0.0017 L_u); README.
        let paper = V3::new(0.3, 0.4, -0.01);
        let d = top - paper;
        assert!(d.abs().max() <= 0.02, "top of the surface {top:?}");
        // The independent reference (scripts/belt_reference.py: exact
        // integrals, SLSQP from 12 random starts) at N = 120:
        // [0.3065, 0.4184, −0.0240] L_u, energy 17.7059 R_f/L_u (ours uses
        // the midpoint rule: O(h²) apart).
        let reference = V3::new(0.3065, 0.4184, -0.0240);
        assert!((top - reference).abs().max() < 2e-3, "{top:?}");
        assert!(
            (s1.energy_j / 17.7059 - 1.0).abs() < 1e-3,
            "{}",
            s1.energy_j
        );
        let s2 = BeltProblem {
            flexural_rigidity_n_m2: 37.0,
            ..base.clone()
        }
        .solve(&belt_settings())
        .unwrap();
        assert!(
            (s1.highest_m - s2.highest_m).norm() < 1e-9,
            "{:?} vs {:?}",
            s1.highest_m,
            s2.highest_m
        );
        assert!((s2.energy_j / s1.energy_j - 37.0).abs() < 1e-6 * 37.0);
    }

    /// Why segments are the default: the paper's Ritz form with its 16
    /// collocation points solves to a surface whose spine bends in its own
    /// plane between the points (ω_ξ ≠ 0, Eq. 48 broken), more than it
    /// flexes out of plane. `cargo test --release -p plant-models --lib belt_ -- --ignored`
    #[test]
    #[ignore = "long in debug builds: run with --release (README)"]
    fn belt_ritz_with_the_papers_16_points_is_not_developable_between_them() {
        let p = BeltProblem {
            method: BeltMethod::Ritz,
            ..BeltProblem::default()
        };
        let c = p.compile().unwrap();
        let shape = p.solve(&belt_settings()).unwrap();
        assert!(shape.solution.converged);
        let (mut xi2, mut zeta2) = (0.0, 0.0);
        for q in c.points(&shape.solution.x) {
            let om = omegas(q.ang[1], q.ang[2], q.rate[0], q.rate[1], q.rate[2]);
            xi2 += om.x * om.x;
            zeta2 += om.z * om.z;
        }
        let ratio = (xi2 / zeta2).sqrt();
        // Measured: rms ω_ξ / rms ω_ζ = 1.4 (the Eq. 48 rate is zero at
        // the 16 points only).
        assert!(ratio > 0.5, "rms ω_ξ / rms ω_ζ = {ratio}");
    }
}
