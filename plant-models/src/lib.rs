//! Physics for the simulator: the SMA-driven loosely coupled joint and the
//! deformable objects it handles. Everything here is std and deterministic:
//! random effects take an explicit seeded RNG.
#![deny(unsafe_code)]
pub mod joint;
pub mod pushing;
pub mod viscoelastic;

/// A number for an error message: as `{}` prints it, or in exponent form
/// when that would be a long run of digits (1e308 has 309).
pub fn short_number(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e15).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}
