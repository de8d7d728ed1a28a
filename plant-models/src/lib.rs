//! Physics for the simulator: the SMA-driven loosely coupled joint and the
//! deformable objects it handles. Everything here is std and deterministic:
//! random effects take an explicit seeded RNG.
#![deny(unsafe_code)]
pub mod joint;
pub mod pushing;
pub mod viscoelastic;
