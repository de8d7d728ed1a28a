//! The driver's line i = g·(v − v_on) from the logged currents (stage 1a
//! of [`super`]): which rows it may use, the fit, and its covariance.
//!
//! **Rows are chosen by the input, never by the measured current.** The
//! line holds only between turn-on and the channel's limit, so rows
//! near either end must be left out; choosing them by the *noisy*
//! reading keeps, at a level whose true current sits near a cut, only the
//! readings whose noise happened to fall on the near side, which moves
//! that level's mean and with it g (issue 28's campaign: g 4–14σ off on
//! three planes whose 1.9 V level carried ≈ 0.43 A against the 0.425 A
//! cut). So a first fit on the rows whose reading lies inside the cuts
//! only places the line; the rows are then chosen by the current the line
//! predicts from their input (every row at one level in, or every one
//! out) and the line refitted until the choice stops changing. Rows whose
//! input steps within them or next to them are left out too: a row's mean
//! input and mean current do not lie on the line when the input crossed
//! turn-on or the limit inside the row.
//!
//! The fit is ordinary least squares with the white-noise covariance: the
//! readings' noise is independent from row to row (the recorder draws it
//! per row); the covariance of (g, b), b = −g·v_on, is kept whole so that
//! later stages can carry the driver's uncertainty ([`DriverFit::shifts`]).

use super::log::ExcitationLog;
use super::replay::PlaneMap;
use crate::DriverParams;

/// Lowest current (A) a row may carry, by the line's prediction, to be
/// regressed: clear of turn-on, where a row's mean is not on the line
/// if the input crossed turn-on within it.
pub const MIN_CURRENT_A: f64 = 0.02;

/// Share of the channel's limit (the lower of its current limit and the
/// supply's saturation through the logged coil resistance) that a row
/// may carry, by the line's prediction.
pub const MAX_LIMIT_SHARE: f64 = 0.85;

/// Largest change of a row's input from its neighbours (V) for the row to
/// count as steady: the plans' ramps move 1–2 × 10⁻⁴ V per 10 ms row, a
/// step tenths of a volt.
pub const STEADY_INPUT_V: f64 = 0.01;

/// Refits at most (each with the rows the last line chose).
const MAX_REFITS: usize = 10;

/// The driver's line: i = g·v + b, with the covariance of (g, b).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriverFit {
    /// Transconductance (A/V).
    pub g: f64,
    /// Intercept (A): b = −g·v_on.
    pub b: f64,
    /// Covariance of (g, b): [[var g, cov], [cov, var b]].
    pub cov: [[f64; 2]; 2],
    /// Rows × coils regressed.
    pub points: usize,
}

impl DriverFit {
    /// Turn-on voltage (V).
    pub fn turn_on_v(&self) -> f64 {
        -self.b / self.g
    }

    /// 1σ of g (A/V).
    pub fn sd_g(&self) -> f64 {
        self.cov[0][0].max(0.0).sqrt()
    }

    /// 1σ of the turn-on (V), to first order in (g, b) with their
    /// correlation: ∂v_on/∂g = b/g², ∂v_on/∂b = −1/g.
    pub fn sd_turn_on(&self) -> f64 {
        let (dg, db) = (self.b / (self.g * self.g), -1.0 / self.g);
        let var =
            dg * dg * self.cov[0][0] + 2.0 * dg * db * self.cov[0][1] + db * db * self.cov[1][1];
        var.max(0.0).sqrt()
    }

    /// The driver moved by 1σ along each principal axis of the (g, b)
    /// covariance: (g, turn-on) of two drivers whose differences from the
    /// fit are independent errors of one standard deviation each, for a
    /// later stage to propagate (their effects add in quadrature).
    pub fn shifts(&self) -> [(f64, f64); 2] {
        let [[a, c], [_, d]] = self.cov;
        let mean = 0.5 * (a + d);
        let root = (0.25 * (a - d) * (a - d) + c * c).sqrt();
        let axis = |lambda: f64| -> (f64, f64) {
            // An eigenvector of [[a, c], [c, d]] for `lambda`.
            let (x, y) = if c.abs() > 1e-300 {
                (lambda - d, c)
            } else if (lambda - a).abs() <= (lambda - d).abs() {
                (1.0, 0.0)
            } else {
                (0.0, 1.0)
            };
            let n = x.hypot(y).max(1e-300);
            let s = lambda.max(0.0).sqrt();
            let (g, b) = (self.g + s * x / n, self.b + s * y / n);
            (g, -b / g)
        };
        [axis(mean + root), axis(mean - root)]
    }
}

/// Whether row `k`'s input on `coil` is steady (module docs).
fn steady(log: &ExcitationLog, k: usize, coil: usize) -> bool {
    let v = log.volts[k][coil];
    let near = |j: usize| (log.volts[j][coil] - v).abs() <= STEADY_INPUT_V;
    (k == 0 || near(k - 1)) && (k + 1 >= log.len() || near(k + 1))
}

/// Least squares of `pts` (input V, current A); None with fewer than 10
/// points or no spread of inputs.
fn fit(pts: &[(f64, f64)]) -> Option<DriverFit> {
    if pts.len() < 10 {
        return None;
    }
    let n = pts.len() as f64;
    let mv = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let mi = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mv).powi(2)).sum();
    if sxx <= 1e-12 {
        return None;
    }
    let g = pts.iter().map(|p| (p.0 - mv) * (p.1 - mi)).sum::<f64>() / sxx;
    let b = mi - g * mv;
    let s2 = pts.iter().map(|p| (p.1 - b - g * p.0).powi(2)).sum::<f64>() / (n - 2.0);
    let var_g = s2 / sxx;
    Some(DriverFit {
        g,
        b,
        cov: [
            [var_g, -mv * var_g],
            [-mv * var_g, s2 / n + mv * mv * var_g],
        ],
        points: pts.len(),
    })
}

/// The driver's line over one plane's steady, unsaturated rows `0..rows`
/// (module docs); `prior` gives the channel's limit and the supply's
/// saturation. None without a current column, or when the rows do not
/// have the spread of unsaturated inputs a line needs.
pub fn driver_regression(
    log: &ExcitationLog,
    map: PlaneMap,
    rows: usize,
    prior: &DriverParams,
) -> Option<DriverFit> {
    let cur = log.current_a.as_ref()?;
    let rows = rows.min(log.len());
    let limit = |k: usize, c: usize| {
        let ohm = log
            .resistance_ohm
            .as_ref()
            .map_or(f64::INFINITY, |r| r[k][c]);
        MAX_LIMIT_SHARE * prior.max_current_a.min(prior.saturation_current_a(ohm))
    };
    let candidates: Vec<(usize, usize)> = (0..rows)
        .flat_map(|k| map.coils.iter().map(move |&c| (k, c)))
        .filter(|&(k, c)| log.volts[k][c] > 0.0 && steady(log, k, c))
        .collect();
    let point = |&(k, c): &(usize, usize)| (log.volts[k][c], cur[k][c]);
    // The first line only places the cuts: rows chosen by their reading.
    let first: Vec<(f64, f64)> = candidates
        .iter()
        .filter(|&&(k, c)| cur[k][c] > MIN_CURRENT_A && cur[k][c] < limit(k, c))
        .map(point)
        .collect();
    let mut line = fit(&first)?;
    let mut chosen: Vec<bool> = Vec::new();
    for _ in 0..MAX_REFITS {
        let now: Vec<bool> = candidates
            .iter()
            .map(|&(k, c)| {
                let i = line.g * log.volts[k][c] + line.b;
                i > MIN_CURRENT_A && i < limit(k, c)
            })
            .collect();
        if now == chosen {
            break;
        }
        let pts: Vec<(f64, f64)> = candidates
            .iter()
            .zip(&now)
            .filter(|(_, &keep)| keep)
            .map(|(kc, _)| point(kc))
            .collect();
        line = fit(&pts)?;
        chosen = now;
    }
    Some(line)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2D log whose coil 1 sees `volts` row by row, with the current of
    /// a driver g·(v − v_on) clamped at 0.5 A and `noise(k)` added.
    fn log_of(volts: &[f64], g: f64, v_on: f64, noise: impl Fn(usize) -> f64) -> ExcitationLog {
        let n = volts.len();
        let amps = |k: usize, v: f64| (g * (v - v_on)).clamp(0.0, 0.5) + noise(k);
        ExcitationLog {
            planes: 1,
            period_s: 0.01,
            t_s: (0..n).map(|k| k as f64 * 0.01).collect(),
            volts: volts.iter().map(|&v| [v, 0.0, 0.0, 0.0]).collect(),
            cam_capture_s: vec![-1.0; n],
            cam_deg: vec![[0.0; 2]; n],
            wire_mm: vec![[0.0; 4]; n],
            current_a: Some(
                volts
                    .iter()
                    .enumerate()
                    .map(|(k, &v)| [amps(k, v), 0.0, 0.0, 0.0])
                    .collect(),
            ),
            resistance_ohm: Some(vec![[5.0; 4]; n]),
        }
    }

    /// Deterministic pseudo-noise, nearly normal of σ 1 (twelve hashed
    /// uniforms ±½ summed).
    fn normal(k: usize) -> f64 {
        (0..12)
            .map(|i| {
                let mut z = ((12 * k + i) as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                z ^= z >> 31;
                z = z.wrapping_mul(0xBF58_476D_1CE4_E5B9);
                z ^= z >> 29;
                (z >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .sum()
    }

    /// One unsaturated level (the rest saturated pulses) cannot separate g
    /// from the turn-on voltage: the regression declines. A ramp's spread
    /// determines both.
    #[test]
    fn a_line_needs_a_spread_of_unsaturated_inputs() {
        let map = PlaneMap::of(1, 0);
        let (g, v_on) = (0.9, 1.7);
        let ripple = |k: usize| if k % 2 == 0 { 1e-3 } else { -1e-3 };
        let mut one_level = vec![3.0; 200];
        one_level.extend(vec![1.9; 500]);
        let d = DriverParams::default();
        assert!(driver_regression(&log_of(&one_level, g, v_on, ripple), map, 700, &d).is_none());

        let mut ramp = one_level.clone();
        ramp.extend((0..700).map(|k| 1.7 + 0.2 * k as f64 / 699.0));
        let f = driver_regression(&log_of(&ramp, g, v_on, ripple), map, ramp.len(), &d).unwrap();
        assert!((f.g - g).abs() < 0.01 * g && f.sd_g() < 0.005 * g, "{f:?}");
        assert!(
            (f.turn_on_v() - v_on).abs() < 0.01 && f.sd_turn_on() < 0.005,
            "{f:?}"
        );
    }

    /// Two steady levels, the upper one carrying 0.424 A, 1 mA under the
    /// cut at 0.85 × 0.5 A, with 2 mA of noise. Chosen by the reading,
    /// only the level's readings below the cut would be kept (69 %): its
    /// mean would fall by ≈ 1 mA (a normal truncated ½σ above its mean
    /// has its mean σ·φ(½)/Φ(½) = 0.51σ below) and g with it. Chosen by
    /// the input, the whole level is in, and g and the turn-on lie within
    /// 3σ of their truth, their 1σ being the least-squares one.
    #[test]
    fn rows_are_chosen_by_the_input_not_the_noisy_reading() {
        let map = PlaneMap::of(1, 0);
        let d = DriverParams::default();
        let (g, v_on) = (1.25, 1.56);
        // The upper level's input puts its current 1 mA under the cut.
        let upper = v_on + (MAX_LIMIT_SHARE * d.max_current_a - 0.001) / g;
        let mut volts = vec![1.7; 1500];
        volts.extend(vec![upper; 1500]);
        let log = log_of(&volts, g, v_on, |k| 0.002 * normal(k));
        let f = driver_regression(&log, map, volts.len(), &d).unwrap();
        assert!((f.g - g).abs() <= 3.0 * f.sd_g(), "{f:?}");
        assert!(
            (f.turn_on_v() - v_on).abs() <= 3.0 * f.sd_turn_on(),
            "{f:?}"
        );
        // The reading-chosen regression of before, for contrast: its g is
        // biased by many of its σ.
        let cur = log.current_a.as_ref().unwrap();
        let pts: Vec<(f64, f64)> = (0..volts.len())
            .filter(|&k| cur[k][0] > MIN_CURRENT_A && cur[k][0] < MAX_LIMIT_SHARE * 0.5)
            .map(|k| (volts[k], cur[k][0]))
            .collect();
        let old = fit(&pts).unwrap();
        assert!((old.g - g).abs() > 5.0 * old.sd_g(), "{old:?}");
    }

    /// A step that falls inside a row: the row's mean input and current
    /// are off the line, and the row is left out.
    #[test]
    fn rows_where_the_input_steps_are_left_out() {
        let mut volts = vec![0.0; 20];
        volts.extend(vec![1.9; 20]);
        volts[20] = 0.95;
        let log = log_of(&volts, 1.0, 1.7, |_| 0.0);
        assert!(steady(&log, 10, 0) && steady(&log, 30, 0));
        assert!(!steady(&log, 19, 0) && !steady(&log, 20, 0) && !steady(&log, 21, 0));
    }

    /// The principal-axis shifts carry the covariance: the spread of g
    /// and of the turn-on over the two shifts, added in quadrature, is
    /// their 1σ.
    #[test]
    fn the_shifts_carry_the_covariance() {
        let f = DriverFit {
            g: 1.2,
            b: -2.04,
            cov: [[4e-6, -6.8e-6], [-6.8e-6, 1.2e-5]],
            points: 100,
        };
        let s = f.shifts();
        let dg = s.iter().map(|x| (x.0 - f.g).powi(2)).sum::<f64>().sqrt();
        assert!((dg / f.sd_g() - 1.0).abs() < 1e-6, "{dg} {}", f.sd_g());
        let dv = s
            .iter()
            .map(|x| (x.1 - f.turn_on_v()).powi(2))
            .sum::<f64>()
            .sqrt();
        // First order: the shifts are 1σ, so the linearisation's error is
        // of the order of σ/g relative.
        assert!(
            (dv / f.sd_turn_on() - 1.0).abs() < 1e-2,
            "{dv} {}",
            f.sd_turn_on()
        );
    }
}
