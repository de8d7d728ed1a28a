//! The clamped–clamped elastica from its closed form (Love, §263; the
//! pendulum analogy), written apart from the solver and sharing no code
//! with it: the independent reference of the wire tests and of the
//! randomised campaign (`examples/wire_campaign.rs` includes this file).
//!
//! An inextensible, unshearable wire of length L and flexural rigidity
//! R_f, both ends clamped on one axis, the ends brought to a distance
//! l < L. The first (symmetric) buckling mode is one full period of the
//! pendulum θ'' = −λ² sin θ: sin(θ/2) = k·sn(λs, k) with λ = 4K(k)/L, so
//!
//! * l / L = 2E(k)/K(k) − 1,
//! * U = R_f/2 ∫θ'² ds = 32 R_f K (E − (1 − k²)K) / L,
//! * the deflection at mid-length is ∫₀^{L/2} sin θ ds = kL/K,
//!
//! with K, E the complete elliptic integrals of the first and second kind
//! of modulus k. Small k: U → 4π²R_f k²/L and L − l → k²L, i.e. the Euler
//! load 4π²R_f/L² times the shortening.

/// K(k) and E(k) by the arithmetic–geometric mean (A&S 17.6).
pub fn complete_elliptic(k: f64) -> (f64, f64) {
    let (mut a, mut b, mut c) = (1.0f64, (1.0 - k * k).sqrt(), k);
    let mut sum = 0.5 * c * c;
    let mut power = 1.0;
    while c.abs() > 1e-16 {
        let (an, bn) = (0.5 * (a + b), (a * b).sqrt());
        c = 0.5 * (a - b);
        a = an;
        b = bn;
        power *= 2.0;
        sum += 0.5 * power * c * c;
    }
    let big_k = std::f64::consts::PI / (2.0 * a);
    (big_k, big_k * (1.0 - sum))
}

/// The elastica with its ends at `l_fraction` of the length.
#[derive(Debug, Clone, Copy)]
pub struct Elastica {
    /// Modulus k = sin(θ_max/2).
    pub k: f64,
    /// Energy, J.
    pub energy_j: f64,
    /// Deflection at mid-length, m.
    pub mid_deflection_m: f64,
}

/// The first mode for l/L in (−0.73, 1) (below, the lobes pass through
/// each other: the figure eight at l/L ≈ −0.73 is outside this family).
pub fn clamped(length_m: f64, rf_n_m2: f64, l_fraction: f64) -> Elastica {
    assert!(l_fraction < 1.0 && l_fraction > -0.7);
    // 2E/K − 1 falls from 1 (k = 0) monotonically: bisection on k.
    let (mut lo, mut hi) = (0.0f64, 1.0 - 1e-12);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        let (big_k, big_e) = complete_elliptic(mid);
        if 2.0 * big_e / big_k - 1.0 > l_fraction {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let k = 0.5 * (lo + hi);
    let (big_k, big_e) = complete_elliptic(k);
    Elastica {
        k,
        energy_j: 32.0 * rf_n_m2 * big_k * (big_e - (1.0 - k * k) * big_k) / length_m,
        mid_deflection_m: k * length_m / big_k,
    }
}

#[test]
fn the_reference_meets_its_own_limits() {
    // K(0) = E(0) = π/2; K(1/√2) = 1.8540746773013719 (A&S Table 17.1).
    let (k0, e0) = complete_elliptic(0.0);
    assert!((k0 - std::f64::consts::FRAC_PI_2).abs() < 1e-15 && (e0 - k0).abs() < 1e-15);
    let (k1, e1) = complete_elliptic(std::f64::consts::FRAC_1_SQRT_2);
    assert!((k1 - 1.854_074_677_301_371_9).abs() < 1e-13);
    assert!((e1 - 1.350_643_881_047_675_5).abs() < 1e-13);
    // Small shortening: the Euler load times the shortening.
    let e = clamped(1.0, 1.0, 1.0 - 1e-6);
    assert!(e.k > 0.0 && e.k < 2e-3, "{e:?}");
    let euler = 4.0 * std::f64::consts::PI.powi(2) * 1e-6;
    assert!((e.energy_j - euler).abs() < 1e-5 * euler, "{e:?}");
}
