//! Streaming least-squares fits for calibrating the wire-sensor laws
//! (seed 000, last paper: the coefficients of Eq. 2–5 were "obtained by
//! angle calibrations" against camera images).
//!
//! The accumulators keep only power sums, so a board can calibrate itself
//! from a sweep without storing it, and the host tool uses the same code.
//! Sums are kept in `f64` about a caller-chosen centre (the mid-range of the
//! insertions) to keep the normal equations well conditioned.

/// Why a fit could not be computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum FitError {
    /// Too few distinct samples for the number of coefficients.
    TooFewSamples,
    /// The samples do not determine the coefficients (e.g. all x equal).
    Degenerate,
    /// A sample or the centre was NaN or infinite.
    NonFiniteSample,
}

impl core::fmt::Display for FitError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            FitError::TooFewSamples => "too few samples for the number of coefficients",
            FitError::Degenerate => "the samples do not determine the coefficients (all x equal?)",
            FitError::NonFiniteSample => "a sample or a fitted coefficient is not finite",
        })
    }
}

impl core::error::Error for FitError {}

/// Accumulates samples for `y = a x² + b x + c` (Eq. 2) or, with
/// [`PolyFit::linear`], `y = g x + o` (Eq. 3).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PolyFit {
    degree: usize,
    centre: f64,
    /// Σ t^k for k = 0..4, with t = x − centre.
    sx: [f64; 5],
    /// Σ y t^k for k = 0..2.
    sxy: [f64; 3],
    rejected: u32,
}

impl PolyFit {
    /// A quadratic fit with samples centred on `centre` (use the expected
    /// mid-range of x; any finite value gives the same answer in exact
    /// arithmetic).
    pub fn quadratic(centre: f64) -> Self {
        Self::with_degree(2, centre)
    }

    /// A straight-line fit.
    pub fn linear(centre: f64) -> Self {
        Self::with_degree(1, centre)
    }

    fn with_degree(degree: usize, centre: f64) -> Self {
        let centre = if centre.is_finite() { centre } else { 0.0 };
        Self {
            degree,
            centre,
            sx: [0.0; 5],
            sxy: [0.0; 3],
            rejected: 0,
        }
    }

    /// Adds one sample; non-finite samples are counted and skipped.
    pub fn add(&mut self, x: f64, y: f64) {
        if !(x.is_finite() && y.is_finite()) {
            self.rejected = self.rejected.saturating_add(1);
            return;
        }
        let t = x - self.centre;
        let mut p = 1.0;
        for (k, sx) in self.sx.iter_mut().enumerate() {
            *sx += p;
            if let Some(sxy) = self.sxy.get_mut(k) {
                *sxy += y * p;
            }
            p *= t;
        }
    }

    /// Number of samples accepted.
    pub fn count(&self) -> u64 {
        self.samples() as u64
    }

    /// Σ t⁰: the number of samples, as the sums hold it.
    fn samples(&self) -> f64 {
        let [n, ..] = self.sx;
        n
    }

    /// Number of non-finite samples skipped.
    pub fn rejected(&self) -> u32 {
        self.rejected
    }

    /// Solves the normal equations. Returns `[a, b, c]` of `a x² + b x + c`
    /// (for a linear fit `a = 0`, so `b` is the slope and `c` the offset),
    /// in the caller's original x (the centring is undone).
    pub fn solve(&self) -> Result<[f64; 3], FitError> {
        let n = self.degree + 1;
        if self.samples() < n as f64 {
            return Err(FitError::TooFewSamples);
        }
        // Normal matrix M[r][c] = Σ t^(r+c), rhs[r] = Σ y t^r, unknowns
        // q0 + q1 t + q2 t².
        let mut m = [[0.0f64; 4]; 3];
        for ((r, row), rhs) in m.iter_mut().enumerate().zip(self.sxy).take(n) {
            for (c, v) in row.iter_mut().enumerate().take(n) {
                *v = self.sx.get(r + c).copied().unwrap_or(0.0);
            }
            if let Some(last) = row.last_mut() {
                *last = rhs;
            }
        }
        let [q0, q1, q2] = solve_small(&mut m, n)?;
        // Undo the centring: y = q0 + q1 (x − x0) + q2 (x − x0)².
        let x0 = self.centre;
        let a = q2;
        let b = q1 - 2.0 * q2 * x0;
        let c = q0 - q1 * x0 + q2 * x0 * x0;
        if a.is_finite() && b.is_finite() && c.is_finite() {
            Ok([a, b, c])
        } else {
            Err(FitError::NonFiniteSample)
        }
    }
}

/// Gaussian elimination with partial pivoting on an n×(n+1) augmented
/// system (n ≤ 3; the right-hand side is column 3). Pivots below a relative
/// tolerance mean the data do not determine the unknowns.
fn solve_small(m: &mut [[f64; 4]; 3], n: usize) -> Result<[f64; 3], FitError> {
    let n = n.min(3);
    let at = |m: &[[f64; 4]; 3], r: usize, c: usize| {
        m.get(r).and_then(|row| row.get(c)).copied().unwrap_or(0.0)
    };
    let scale = m
        .iter()
        .take(n)
        .flat_map(|r| r.iter().take(n))
        .fold(0.0f64, |a, v| a.max(v.abs()));
    if !(scale.is_finite() && scale > 0.0) {
        return Err(FitError::Degenerate);
    }
    let tol = scale * 1e-12;
    for col in 0..n {
        let mut piv = col;
        for r in col + 1..n {
            if at(m, r, col).abs() > at(m, piv, col).abs() {
                piv = r;
            }
        }
        if at(m, piv, col).abs() <= tol {
            return Err(FitError::Degenerate);
        }
        m.swap(col, piv);
        let Some((upper, lower)) = m.split_at_mut_checked(col + 1) else {
            return Err(FitError::Degenerate);
        };
        let Some(pivot) = upper.last() else {
            return Err(FitError::Degenerate);
        };
        let p = pivot.get(col).copied().unwrap_or(f64::NAN);
        for row in lower.iter_mut().take(n - col - 1) {
            let f = row.get(col).copied().unwrap_or(0.0) / p;
            for (x, pv) in row.iter_mut().zip(pivot.iter()).skip(col) {
                *x -= f * pv;
            }
        }
    }
    let mut q = [0.0f64; 3];
    for r in (0..n).rev() {
        let mut acc = at(m, r, 3);
        for (c, qc) in q.iter().enumerate().take(n).skip(r + 1) {
            acc -= at(m, r, c) * qc;
        }
        if let Some(qr) = q.get_mut(r) {
            *qr = acc / at(m, r, r);
        }
    }
    Ok(q)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quadratic_fit_recovers_the_papers_eq2_coefficients() {
        // Samples of Eq. 2 over the 2D sensor's range (≈ −3.5…3.9 mm for
        // ±20°), exact: the fit must return A, B, C to rounding.
        let mut fit = PolyFit::quadratic(0.2);
        for i in 0..=80 {
            let d = -3.5 + 7.4 * f64::from(i) / 80.0;
            fit.add(d, 0.349 * d * d - 5.525 * d + 0.753);
        }
        let [a, b, c] = fit.solve().unwrap();
        assert!(
            (a - 0.349).abs() < 1e-9 && (b + 5.525).abs() < 1e-9 && (c - 0.753).abs() < 1e-9,
            "{a} {b} {c}"
        );
    }

    #[test]
    fn linear_fit_recovers_the_papers_eq3_coefficients_under_noise() {
        // α = 2.727 (d3 − d1) + 0.323 with ±0.05° uniform-ish deterministic
        // noise; 401 samples. Tolerances: slope 0.2 %, offset 0.01°.
        let mut fit = PolyFit::linear(0.0);
        for i in 0..=400 {
            let diff = -7.0 + 14.0 * f64::from(i) / 400.0;
            let noise = 0.05 * ((f64::from(i) * 12.9898).sin() * 43758.5453).fract();
            fit.add(diff, 2.727 * diff + 0.323 + noise);
        }
        let [a, slope, offset] = fit.solve().unwrap();
        assert_eq!(a, 0.0);
        assert!((slope - 2.727).abs() < 2.727 * 2e-3, "slope {slope}");
        assert!((offset - 0.323).abs() < 1e-2, "offset {offset}");
    }

    #[test]
    fn degenerate_and_short_data_are_errors_not_garbage() {
        let mut fit = PolyFit::quadratic(0.0);
        fit.add(1.0, 2.0);
        assert_eq!(fit.solve(), Err(FitError::TooFewSamples));
        for _ in 0..10 {
            fit.add(1.0, 2.0); // every x equal
        }
        assert_eq!(fit.solve(), Err(FitError::Degenerate));
        fit.add(f64::NAN, 1.0);
        assert_eq!(fit.rejected(), 1);
        assert_eq!(fit.count(), 11);
    }
}
