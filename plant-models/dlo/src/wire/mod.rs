//! The static differential-geometry model of Wakamatsu et al. (seed 000,
//! L674–1161): linear objects (wires) with flexure, torsion, extension and
//! gravity, and inextensible belts by the fishbone model, each found as the
//! minimum of its potential energy under geometric constraints.
//!
//! - [`basis`]: the Ritz basis (Eq. 16–20);
//! - [`frame`]: Euler angles, the rotation A and the rates ω (Eq. 1–2);
//! - [`optimize`]: the multiplier method with BFGS (L800, L809);
//! - [`linear`]: the wire (Eq. 3–15, knots Eq. 21–24);
//! - [`belt`]: the fishbone belt (Eq. 31–61);
//! - [`strip`]: the fishbone belt on straight segments, developable
//!   everywhere (the default belt solver);
//! - [`problem`]: a static problem as a file states it (one wire, one
//!   belt, or the end-distance sequence) and its solution.
pub mod basis;
pub mod belt;
pub mod frame;
pub mod linear;
pub mod optimize;
pub mod problem;
pub mod strip;

pub use linear::{Constraint, WireParams, WireProblem, WireShape};
