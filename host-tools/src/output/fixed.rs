//! Fixed-point decimal text of an f64, `format!("{v:.d$}")` to the byte
//! but without the standard library's general algorithm: an output that
//! writes tens of thousands of numbers (the contour fit's fit.csv has four
//! per sample) spent a fifth of its time in it (issue 34).
//!
//! The value is `m·2^e` exactly; `m·10^d` fits in 128 bits for the
//! magnitudes and digit counts taken here, so the digits are the exact
//! product shifted by e and rounded half to even, as the standard
//! library rounds the exact binary value. Everything else (more than
//! [`MAX_DECIMALS`] decimals, |v| ≥ 10¹⁵, non-finite values) goes to the
//! standard formatter.
use std::fmt::Write as _;

/// Most decimals the exact path takes (10⁹ < 2³⁰: `m·10^d` < 2⁸³).
pub const MAX_DECIMALS: usize = 9;

/// Appends `v` with `decimals` digits after the point, as
/// `write!(out, "{v:.decimals$}")` would.
pub fn push_fixed(out: &mut String, v: f64, decimals: usize) {
    if decimals > MAX_DECIMALS || !v.is_finite() || v.abs() >= 1e15 {
        let _ = write!(out, "{v:.decimals$}");
        return;
    }
    let bits = v.to_bits();
    let negative = bits >> 63 == 1;
    let exponent = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1 << 52) - 1);
    let (m, e) = if exponent == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1 << 52), exponent - 1075)
    };
    // |v| < 10¹⁵ < 2⁵⁰, so e < −2: |v| = int + below/2^shift.
    let shift = (-e) as u32;
    let (mut int, below) = if shift < 64 {
        (m >> shift, m & ((1u64 << shift) - 1))
    } else {
        (0, m)
    };
    // The fraction's digits, below·10^d / 2^shift rounded half to even
    // (below·10^d < 2⁸³); a tie's parity is the last digit's (of int's
    // when there are no decimals, 10^d being even otherwise).
    let scale = 10u64.pow(decimals as u32);
    let scaled = u128::from(below) * u128::from(scale);
    let mut frac = if shift > 100 {
        // scaled < 2⁸³ ≤ 2^(shift−1): below half a unit.
        0
    } else {
        let q = (scaled >> shift) as u64;
        let rest = scaled & ((1u128 << shift) - 1);
        let half = 1u128 << (shift - 1);
        let last_odd = if decimals == 0 {
            int & 1 == 1
        } else {
            q & 1 == 1
        };
        if rest > half || (rest == half && last_odd) {
            q + 1
        } else {
            q
        }
    };
    if frac == scale {
        int += 1;
        frac = 0;
    }
    if negative {
        out.push('-');
    }
    let mut digits = itoa::Buffer::new();
    out.push_str(digits.format(int));
    if decimals > 0 {
        out.push('.');
        // frac < 10^d: 10^d + frac has d digits after its leading 1.
        out.push_str(&digits.format(scale + frac)[1..]);
    }
}

/// `v` with `decimals` digits after the point (see [`push_fixed`]).
pub fn fixed(v: f64, decimals: usize) -> String {
    let mut s = String::new();
    push_fixed(&mut s, v, decimals);
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn check(v: f64, d: usize) {
        assert_eq!(
            fixed(v, d),
            format!("{v:.d$}"),
            "{v:e} with {d} decimals ({:#x})",
            v.to_bits()
        );
    }

    /// Against the standard formatter: random bit patterns, random
    /// magnitudes over 10⁻¹² … 10¹⁶, exact ties (odd multiples of 2⁻ᵏ at
    /// half a unit of the last place), integers, zeros of both signs,
    /// subnormals, values that round to zero from below, and the
    /// non-finite ones.
    #[test]
    fn fixed_is_the_standard_formatting_to_the_byte() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(34);
        for _ in 0..300_000 {
            let d = rng.gen_range(0..=MAX_DECIMALS + 2);
            let v = f64::from_bits(rng.gen::<u64>());
            check(v, d);
            let mag = 10f64.powf(rng.gen_range(-12.0..16.0));
            let v = if rng.gen_bool(0.5) { mag } else { -mag } * rng.gen::<f64>();
            check(v, d);
            // k / 2^j: ties at half a unit of the d-th place occur when
            // 5^d divides k·2^(d−j)… exercise them broadly.
            let j = rng.gen_range(0..=40);
            let v = rng.gen_range(-1_000_000i64..1_000_000) as f64 / (1u64 << j) as f64;
            check(v, d);
            check((rng.gen_range(-1_000_000i64..1_000_000) as f64) * 0.5e-6, d);
        }
        for d in 0..=MAX_DECIMALS + 1 {
            for v in [
                0.0,
                -0.0,
                0.5,
                1.5,
                2.5,
                -2.5,
                0.0078125,
                -0.0078125,
                1.0 / 1024.0,
                f64::MIN_POSITIVE,
                -f64::MIN_POSITIVE / 3.0,
                5e-324,
                -1e-20,
                999_999.999_999_999_5,
                1e15 - 1.0,
                1e15,
                -1e15,
                f64::MAX,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ] {
                check(v, d);
            }
        }
    }
}
