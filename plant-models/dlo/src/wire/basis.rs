//! The Ritz basis of Wakamatsu et al. (Eq. 16–20, L790–806): every profile
//! (an Euler angle, the strain, the belt's rib parameter) is a sum of
//! 1, s and sin/cos(2πis/L) for i = 1..harmonics (the paper: 4), sampled on
//! a uniform grid of the object's length.

/// Basis functions and their derivatives on a grid over [0, 1] (the
/// models work in units of the object's length).
#[derive(Debug, Clone)]
pub struct Basis {
    /// Number of functions n = 2 + 2·harmonics.
    pub n: usize,
    /// Grid points s_k = k/m, k = 0..=m.
    pub s: Vec<f64>,
    /// e_i(s_k), row k.
    pub e: Vec<Vec<f64>>,
    /// de_i/ds(s_k), row k.
    pub de: Vec<Vec<f64>>,
    /// Trapezoid weights of the grid.
    pub w: Vec<f64>,
}

impl Basis {
    /// Eq. 20 with `harmonics` sine/cosine pairs on `intervals` intervals.
    pub fn new(harmonics: usize, intervals: usize) -> Self {
        let n = 2 + 2 * harmonics;
        let s: Vec<f64> = (0..=intervals)
            .map(|k| k as f64 / intervals as f64)
            .collect();
        let e = s.iter().map(|&x| values(harmonics, x)).collect();
        let de = s.iter().map(|&x| derivatives(harmonics, x)).collect();
        let h = 1.0 / intervals as f64;
        let w = (0..=intervals)
            .map(|k| if k == 0 || k == intervals { 0.5 * h } else { h })
            .collect();
        Self { n, s, e, de, w }
    }

    /// Harmonics of this basis.
    pub fn harmonics(&self) -> usize {
        (self.n - 2) / 2
    }

    /// Grid spacing.
    pub fn h(&self) -> f64 {
        1.0 / (self.s.len() - 1) as f64
    }
}

/// e(s) at any s in units of the length.
pub fn values(harmonics: usize, s: f64) -> Vec<f64> {
    let mut v = vec![1.0, s];
    for i in 1..=harmonics {
        let a = 2.0 * std::f64::consts::PI * i as f64 * s;
        v.push(a.sin());
        v.push(a.cos());
    }
    v
}

/// de/ds(s).
pub fn derivatives(harmonics: usize, s: f64) -> Vec<f64> {
    let mut v = vec![0.0, 1.0];
    for i in 1..=harmonics {
        let k = 2.0 * std::f64::consts::PI * i as f64;
        let a = k * s;
        v.push(k * a.cos());
        v.push(-k * a.sin());
    }
    v
}

/// d²e/ds²(s).
pub fn second_derivatives(harmonics: usize, s: f64) -> Vec<f64> {
    let mut v = vec![0.0, 0.0];
    for i in 1..=harmonics {
        let k = 2.0 * std::f64::consts::PI * i as f64;
        let a = k * s;
        v.push(-k * k * a.sin());
        v.push(-k * k * a.cos());
    }
    v
}

/// a · e.
pub fn dot(a: &[f64], e: &[f64]) -> f64 {
    a.iter().zip(e).map(|(a, e)| a * e).sum()
}
