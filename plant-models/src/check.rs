//! The value checks every model's parameter validation shares: each returns
//! the value, or the reason it is refused, which a system wraps into its own
//! error together with the parameter's name.

/// Finite and strictly positive.
pub(crate) fn positive(value: f64) -> Result<f64, &'static str> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err("must be finite and > 0")
    }
}

/// Finite and ≥ 0.
pub(crate) fn non_negative(value: f64) -> Result<f64, &'static str> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err("must be finite and >= 0")
    }
}

/// Finite and inside `[min, max]`.
pub(crate) fn in_range(value: f64, min: f64, max: f64) -> Result<f64, &'static str> {
    if !value.is_finite() {
        Err("must be a finite number")
    } else if value < min || value > max {
        Err("outside its allowed range")
    } else {
        Ok(value)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_check_refuses_nan_infinity_and_its_own_bounds() {
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            assert!(positive(bad).is_err());
            assert!(non_negative(bad).is_err());
            assert_eq!(in_range(bad, 0.0, 1.0), Err("must be a finite number"));
        }
        assert_eq!(positive(0.0), Err("must be finite and > 0"));
        assert_eq!(positive(1e-300), Ok(1e-300));
        assert_eq!(non_negative(-1e-300), Err("must be finite and >= 0"));
        assert_eq!(non_negative(0.0), Ok(0.0));
        assert_eq!(in_range(1.5, 0.0, 1.0), Err("outside its allowed range"));
        assert_eq!(in_range(-0.5, 0.0, 1.0), Err("outside its allowed range"));
        assert_eq!(in_range(1.0, 0.0, 1.0), Ok(1.0));
    }
}
