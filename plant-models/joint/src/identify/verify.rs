//! Checks of an identification against its own data, beyond the local
//! curvature that the 1σ comes from (issue 28). The 1σ of a fit says how
//! sharply the cost curves at the point the minimiser stopped; it cannot
//! see a wrong basin, a model that absorbs an error elsewhere (a driver
//! fixed at a wrong turn-on), or a direction the log did not excite but
//! the curvature happens to pin. These checks use the data instead:
//!
//! - **Halves** ([`halves`]): each stage's fit is moved by one
//!   Gauss–Newton step on the residuals of the first half of its log
//!   segments alone, and on the second half alone. With a right model the
//!   two halves' estimates differ by noise (their 1σ, each from its own
//!   half, scaled by the full fit's ratio of the 1σ used to the
//!   white-noise one); a parameter whose halves differ by more than
//!   [`HALVES_MAX_Z`] of that is not determined by the log, whatever its
//!   curvature. A half that does not determine a parameter (its own 1σ
//!   infinite) cannot disagree: the check passes it. Every stage has it:
//!   the thermal and mechanics stages split their 10 s segments, the wire
//!   stage its rows' fixed-time segments (its lag episodes, numbered
//!   sensor after sensor, are not in time order).
//! - **Starts** ([`starts_disagree`]): a stage fitted from several starting
//!   points has several minima; one whose cost is within
//!   [`STARTS_MAX_DELTA_CHI2`] (in units of the best fit's residual
//!   variance) of the best but whose parameter lies more than
//!   [`STARTS_MAX_Z`] of its 1σ away shows the data do not choose
//!   between them.
//! - **The driver against its currents** ([`driver_check`]): where the log
//!   has coil currents, the identified driver must predict them; a driver
//!   whose turn-on stayed at a prior the currents contradict makes every
//!   thermal and mechanical parameter fitted through it suspect.
//! - **The angle noise floor** ([`camera_noise_floor_deg`]), from the
//!   camera frames themselves, which the held-out verdict compares the
//!   prediction errors with ([`FIT_MARGIN`], [`HELDOUT_MARGIN`]).
//!
//! Not done here: a profile of the cost along each parameter (refits with
//! the parameter moved), which costs a stage's fit per parameter and
//! direction; coverage calibrated on a campaign of seeded twins.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::log::ExcitationLog;
use super::replay::PlaneMap;
use super::PlaneModel;

/// Largest difference between the two halves' estimates of a parameter,
/// in units of the 1σ of that difference, that counts as agreement: a
/// normal difference exceeds 3σ in 0.27 % of logs, so across the ≈ 15
/// parameters of a plane a right model is flagged in ≈ 4 % of logs.
pub const HALVES_MAX_Z: f64 = 3.0;

/// Another start's minimum within this many units of the residual
/// variance of the best (Δχ² for one parameter at ≈ 2σ) counts as equally
/// good.
pub const STARTS_MAX_DELTA_CHI2: f64 = 4.0;

/// An equally good minimum further than this many 1σ from the best in a
/// parameter leaves that parameter undetermined.
pub const STARTS_MAX_Z: f64 = 3.0;

/// The identified plane must fit the fitted part within this multiple of
/// the camera's noise floor: a right model leaves the noise (ratio ≈ 1).
pub const FIT_MARGIN: f64 = 1.5;

/// The identified plane must predict the held-out part within this
/// multiple of the camera's noise floor.
pub const HELDOUT_MARGIN: f64 = 2.0;

/// The identified plane's held-out rms must not exceed the prior's by
/// more than this factor: a prior that is already right predicts as well
/// as the fit, within the noise of two rms over the same frames.
pub const PRIOR_MARGIN: f64 = 1.1;

/// A driver must predict the logged currents within this multiple of the
/// current noise, plus [`DRIVER_MARGIN_A`].
pub const DRIVER_MAX_Z: f64 = 3.0;

/// Absolute slack of the driver check (A): what the replay's mean input
/// over a row does not resolve at a step's edge.
pub const DRIVER_MARGIN_A: f64 = 0.005;

/// Each coordinate's disagreement between the halves of a stage's data:
/// `(shift of the first half, shift of the second, z)`, the shifts in the
/// minimiser's coordinates from the full fit, z the difference in units
/// of its 1σ (0 where a half does not determine the coordinate).
/// `block[i]` is residual i's log segment, in time order; the first half
/// is the segments below the middle one. `used_over_white` per
/// coordinate: the full fit's 1σ used over its white-noise 1σ.
pub fn halves(
    jac: &[Vec<f64>],
    r: &[f64],
    block: &[usize],
    used_over_white: &[f64],
) -> Vec<(f64, f64, f64)> {
    let n = jac.len();
    let m = r.len();
    let blocks = block.iter().max().map_or(0, |b| b + 1);
    if block.len() != m || blocks < 4 || n == 0 {
        return vec![(0.0, 0.0, 0.0); n];
    }
    let mid = blocks / 2;
    let half = |first: bool| -> Option<(Vec<f64>, Vec<f64>)> {
        let rows: Vec<usize> = (0..m).filter(|&i| (block[i] < mid) == first).collect();
        let mh = rows.len();
        if mh <= n + 1 {
            return None;
        }
        let jm = DMatrix::from_fn(mh, n, |i, j| jac[j][rows[i]]);
        let rv = DVector::from_iterator(mh, rows.iter().map(|&i| r[i]));
        let jtj = jm.transpose() * &jm;
        let svd = jtj.clone().svd(true, true);
        let smax = svd.singular_values.max();
        let (u, vt) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
        let mut pinv = DMatrix::<f64>::zeros(n, n);
        let mut undetermined = vec![false; n];
        for k in 0..n {
            let s = svd.singular_values[k];
            if s > 1e-10 * smax && s > 0.0 {
                pinv += (u.column(k) * vt.row(k)) / s;
            } else {
                for (j, flag) in undetermined.iter_mut().enumerate() {
                    if vt[(k, j)].abs() > 1e-3 {
                        *flag = true;
                    }
                }
            }
        }
        let step = -(&pinv * (jm.transpose() * &rv));
        // The half's own residuals after its step set its noise.
        let after = &rv + &jm * &step;
        let sigma2 = after.norm_squared() / (mh - n) as f64;
        let sd: Vec<f64> = (0..n)
            .map(|j| {
                if undetermined[j] {
                    f64::INFINITY
                } else {
                    (sigma2 * pinv[(j, j)].max(0.0)).sqrt() * used_over_white[j].max(1.0)
                }
            })
            .collect();
        Some((step.iter().copied().collect(), sd))
    };
    let (Some((a, sa)), Some((b, sb))) = (half(true), half(false)) else {
        return vec![(0.0, 0.0, 0.0); n];
    };
    (0..n)
        .map(|j| {
            let sd = sa[j].hypot(sb[j]);
            let z = if sd.is_finite() && sd > 0.0 {
                (a[j] - b[j]).abs() / sd
            } else {
                0.0
            };
            (a[j], b[j], z)
        })
        .collect()
}

/// Per coordinate, the first other minimum (coordinates, cost) of a
/// stage's starts that is as good as the best (`best_cost`, `m`
/// residuals, `n` coordinates) but lies more than [`STARTS_MAX_Z`] of
/// `sd` away: (its coordinate, its Δχ²).
pub fn starts_disagree(
    best_x: &[f64],
    best_cost: f64,
    others: &[(Vec<f64>, f64)],
    sd: &[f64],
    m: usize,
) -> Vec<Option<(f64, f64)>> {
    let n = best_x.len();
    let sigma2 = best_cost / m.saturating_sub(n).max(1) as f64;
    (0..n)
        .map(|j| {
            others.iter().find_map(|(x, cost)| {
                let dchi2 = (cost - best_cost) / sigma2.max(1e-300);
                let far = (x[j] - best_x[j]).abs() > STARTS_MAX_Z * sd[j];
                (dchi2 <= STARTS_MAX_DELTA_CHI2 && far).then_some((x[j], dchi2))
            })
        })
        .collect()
}

/// The camera's angle noise (deg, 1σ) on `plane`, from the frames of rows
/// `0..rows` alone: the median absolute second difference of consecutive
/// frames, ×1.4826 for a normal's σ, over √6 (a second difference of
/// white noise has 6 times its variance). The joint's motion between
/// frames 33 ms apart is smooth, so it adds little to most second
/// differences and the median ignores the few where a pulse starts. None
/// with fewer than 20 frames.
pub fn camera_noise_floor_deg(log: &ExcitationLog, plane: usize, rows: usize) -> Option<f64> {
    let frames = super::frames(log, plane, rows);
    if frames.len() < 20 {
        return None;
    }
    let mut d2: Vec<f64> = frames
        .windows(3)
        .map(|w| (w[2].1 - 2.0 * w[1].1 + w[0].1).abs())
        .collect();
    d2.sort_by(f64::total_cmp);
    let median = d2[d2.len() / 2];
    Some(1.4826 * median / 6f64.sqrt())
}

/// The driver of `model` against the logged currents of its plane over
/// rows `0..rows`, where logged.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DriverCheck {
    /// rms of (predicted − logged) current over the rows with an input
    /// (A).
    pub rms_error_a: f64,
    /// The currents' noise (A, 1σ): their rms over rows with no input.
    pub noise_a: f64,
    /// Whether the error is within [`DRIVER_MAX_Z`] × noise +
    /// [`DRIVER_MARGIN_A`].
    pub passed: bool,
    /// Highest input seen with no current (< 3 × noise + 5 mA), if any
    /// (V).
    pub highest_off_v: Option<f64>,
    /// Lowest input seen with a current (V), if any.
    pub lowest_on_v: Option<f64>,
}

/// [`DriverCheck`] of `model` on `log` (None without a current column).
pub fn driver_check(
    log: &ExcitationLog,
    map: PlaneMap,
    model: &PlaneModel,
    rows: usize,
) -> Option<DriverCheck> {
    let cur = log.current_a.as_ref()?;
    let res = log.resistance_ohm.as_ref();
    let rows = rows.min(log.len());
    let (mut idle, mut idle_n) = (0.0, 0usize);
    for (volts, amps) in log.volts.iter().zip(cur).take(rows) {
        for &c in &map.coils {
            if volts[c] == 0.0 {
                idle += amps[c].powi(2);
                idle_n += 1;
            }
        }
    }
    let noise_a = if idle_n > 0 {
        (idle / idle_n as f64).sqrt()
    } else {
        0.0
    };
    let on_threshold = 3.0 * noise_a + DRIVER_MARGIN_A;
    let (mut err, mut n) = (0.0, 0usize);
    let (mut highest_off, mut lowest_on) = (None::<f64>, None::<f64>);
    let d = &model.plane.driver;
    for k in 1..rows {
        for &c in &map.coils {
            let v = log.volts[k][c];
            // Rows where the input changed are left out: the row's mean
            // input does not say when within it the step came.
            if v <= 0.0 || log.volts[k - 1][c] != v {
                continue;
            }
            let ohm = res.map_or(5.0, |r| r[k][c]);
            let i = cur[k][c];
            err += (d.current_a(v, ohm) - i).powi(2);
            n += 1;
            if i < on_threshold {
                highest_off = Some(highest_off.map_or(v, |h: f64| h.max(v)));
            } else {
                lowest_on = Some(lowest_on.map_or(v, |l: f64| l.min(v)));
            }
        }
    }
    if n == 0 {
        return None;
    }
    let rms_error_a = (err / n as f64).sqrt();
    Some(DriverCheck {
        rms_error_a,
        noise_a,
        passed: rms_error_a <= DRIVER_MAX_Z * noise_a + DRIVER_MARGIN_A,
        highest_off_v: highest_off,
        lowest_on_v: lowest_on,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-noise, uniform ±½ (a hash of the index).
    fn noise(k: usize, seed: u64) -> f64 {
        let mut z = (k as u64 ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15))
            .wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z ^= z >> 31;
        z = z.wrapping_mul(0x94D0_49BB_1331_11EB);
        (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// A straight line fitted to data that follow it: the halves agree.
    /// The same line fitted to data whose slope changes half-way (a model
    /// that is wrong in one half): the halves disagree on the slope by
    /// many of their 1σ, though the full fit's own 1σ is small.
    #[test]
    fn halves_agree_for_a_right_model_and_not_for_a_wrong_one() {
        let m = 400;
        let t: Vec<f64> = (0..m).map(|k| k as f64 / m as f64).collect();
        let block: Vec<usize> = (0..m).map(|k| k / 40).collect();
        let jac = vec![vec![1.0; m], t.clone()];
        // Least squares by the normal equations (the fit under test is
        // the halves' step, not this).
        let fit = |y: &[f64]| {
            let (n, st, stt) = (
                m as f64,
                t.iter().sum::<f64>(),
                t.iter().map(|x| x * x).sum::<f64>(),
            );
            let (sy, sty) = (
                y.iter().sum::<f64>(),
                t.iter().zip(y).map(|(a, b)| a * b).sum::<f64>(),
            );
            let det = n * stt - st * st;
            let b = (n * sty - st * sy) / det;
            let a = (sy - b * st) / n;
            t.iter()
                .zip(y)
                .map(|(x, y)| a + b * x - y)
                .collect::<Vec<f64>>()
        };
        let right: Vec<f64> = (0..m)
            .map(|k| 1.0 + 2.0 * t[k] + 0.01 * noise(k, 1))
            .collect();
        let z = halves(&jac, &fit(&right), &block, &[1.0, 1.0]);
        assert!(z.iter().all(|x| x.2 < 3.0), "{z:?}");
        let kinked: Vec<f64> = (0..m)
            .map(|k| 1.0 + 2.0 * t[k] + (t[k] - 0.5).max(0.0) + 0.01 * noise(k, 1))
            .collect();
        let z = halves(&jac, &fit(&kinked), &block, &[1.0, 1.0]);
        assert!(z[1].2 > 10.0, "{z:?}");
        // The first half's slope is 2, the second's 3: their steps from
        // the full fit differ by 1 (to the noise).
        assert!(((z[1].1 - z[1].0) - 1.0).abs() < 0.02, "{z:?}");
    }

    /// White noise of σ = 0.05° on a smooth motion: the floor is σ within
    /// 10 %.
    #[test]
    fn the_noise_floor_of_a_smooth_motion_is_its_noise() {
        let n = 3000;
        let mut log = ExcitationLog {
            planes: 1,
            period_s: 0.01,
            t_s: (0..n).map(|k| k as f64 * 0.01).collect(),
            volts: vec![[0.0; 4]; n],
            cam_capture_s: vec![-1.0; n],
            cam_deg: vec![[0.0; 2]; n],
            wire_mm: vec![[0.0; 4]; n],
            current_a: None,
            resistance_ohm: None,
        };
        for k in (0..n).step_by(3) {
            let t = k as f64 * 0.01;
            // Twelve uniforms ±½ sum to a nearly normal variable of σ 1
            // (the camera's noise is normal); scaled to σ = 0.05.
            let e = 0.05 * (0..12).map(|i| noise(12 * k + i, 9)).sum::<f64>();
            log.cam_capture_s[k] = t;
            log.cam_deg[k][0] = 5.0 * (0.5 * t).sin() + e;
        }
        let floor = camera_noise_floor_deg(&log, 0, n).unwrap();
        assert!((floor / 0.05 - 1.0).abs() < 0.1, "{floor}");
    }
}
