//! Portable control core for SMA-driven, loosely coupled robotic joints.
//!
//! This crate is `no_std`, allocation-free and panic-free on its control
//! paths. The same code runs on a Cortex-M board, in the firmware image under
//! QEMU, and inside the host simulator (with the `std` feature). Time is
//! always an argument, as an integer monotonic [`time::Instant`]: nothing
//! here reads a clock, and nothing here loses resolution with uptime.
//!
//! Modules:
//! - [`control`]: the antagonistic P(+I) laws of Shibata et al. (seed 000,
//!   last paper, Eq. 1 and the 2D/3D pair laws) and their driver outputs;
//! - [`estimate`]: wire-sensor angle estimation (Eq. 2–5) with threshold
//!   switching, and the least-squares fits that calibrate it ([`fit`]);
//! - [`sensor`]: the wire-sensor trait, validity checks, and the extension
//!   of a board's 16-bit quadrature counters;
//! - [`supervisor`]: thermal budget, fault flags and the latched safe state;
//! - [`joint`]: one complete control step (estimate → control → supervise);
//! - [`time`]: integer microsecond instants and durations;
//! - [`app`]: the board's protocol state machine; [`protocol`]: the wire
//!   format; [`watchdog`]: the loop-stall policy behind a board's hardware
//!   watchdog;
//! - [`viscoelastic`]: the 3-element model of seed 002 (Eq. 3–12) in scalar,
//!   tensor, Rayleigh and multi-vertex DGFM forms.
#![cfg_attr(not(any(test, feature = "std")), no_std)]
#![warn(missing_docs)]
// The control step must not have a panicking path: no unwrap/expect/panic!,
// no indexing that can go out of bounds (use `get`, iterators, or arrays
// whose indices are checked by type). Tests may use all of them.
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing
    )
)]

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
pub mod time;
pub mod viscoelastic;
pub mod watchdog;
