//! The value checks every model's parameter validation shares: each returns
//! the value, or the reason it is refused, which a system wraps into its own
//! error together with the parameter's name.

/// A named parameter refused by a check: its name as the user knows it, the
/// value, and the reason. Each system wraps it into its own error.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("invalid parameter `{name}` = {}: {reason}", crate::short_number(*.value))]
pub struct ParamError {
    /// Parameter name as the user knows it.
    pub name: &'static str,
    /// The rejected value.
    pub value: f64,
    /// What the valid range is.
    pub reason: &'static str,
}

/// `value` when finite and > 0, else a [`ParamError`] naming it.
pub fn named_positive(name: &'static str, value: f64) -> Result<f64, ParamError> {
    positive(value).map_err(|reason| ParamError {
        name,
        value,
        reason,
    })
}

/// `value` when finite and ≥ 0, else a [`ParamError`] naming it.
pub fn named_non_negative(name: &'static str, value: f64) -> Result<f64, ParamError> {
    non_negative(value).map_err(|reason| ParamError {
        name,
        value,
        reason,
    })
}

/// Finite and strictly positive.
pub fn positive(value: f64) -> Result<f64, &'static str> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err("must be finite and > 0")
    }
}

/// Finite and ≥ 0.
pub fn non_negative(value: f64) -> Result<f64, &'static str> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err("must be finite and >= 0")
    }
}

/// Finite and inside `[min, max]`.
pub fn in_range(value: f64, min: f64, max: f64) -> Result<f64, &'static str> {
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
