//! Portable control core for SMA-driven, loosely coupled robotic joints.
//!
//! This crate is `no_std`, allocation-free and panic-free on its control
//! paths. The same code runs on a Cortex-M board, in the firmware image under
//! QEMU, and inside the host simulator (with the `std` feature). Time and
//! step sizes are always arguments: nothing here reads a clock.
//!
//! Modules:
//! - [`control`]: the antagonistic P(+I) laws of Shibata et al. (seed 000,
//!   last paper, Eq. 1 and the 2D/3D pair laws) and their driver outputs;
//! - [`estimate`]: wire-sensor angle estimation (Eq. 2–5) with threshold
//!   switching, and the least-squares fits that calibrate it ([`fit`]);
//! - [`sensor`]: the wire-sensor trait and validity checks;
//! - [`supervisor`]: thermal budget, fault flags and the latched safe state;
//! - [`joint`]: one complete control step (estimate → control → supervise);
//! - [`viscoelastic`]: the 3-element model of seed 002 (Eq. 3–12) in scalar,
//!   tensor, Rayleigh and multi-vertex DGFM forms.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![deny(unsafe_code)]
#![warn(missing_docs)]

#[macro_use]
mod fmt;

pub mod app;
pub mod control;
pub mod estimate;
pub mod fit;
pub mod joint;
pub mod linalg;
pub mod protocol;
pub mod real;
pub mod sensor;
pub mod supervisor;
pub mod viscoelastic;
