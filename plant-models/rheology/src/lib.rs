//! Rheology lattice of a soft food-like object (seed 000, Noborio et al.,
//! the two slide decks at L1595–2359 of `000_591834fd72747d8a.txt`): a
//! block of dough as point masses on a regular grid joined by the paper's
//! basic element, pushed by a plate, and calibrated from a measured push
//! by the paper's randomized and genetic algorithms.
//!
//! [`model`] is the lattice being calibrated (elements, grid, volume
//! conditions, the rig's contacts, integrators, scenarios); [`identify`]
//! measures and identifies it (a continuum reference block standing in for
//! the recordings, the objective S, the searches).
//!
//! What is modelled: the basic element (Voigt K ‖ C1 in series with a
//! damper C2, length ratio a), M = M_obj/N masses under gravity, the
//! paper's four model variants (no, local, global, both volume
//! conditions), table and plate contact with Coulomb friction, pull-off
//! and area-shared plate force, explicit Euler as in the paper and a
//! linearly implicit Euler that is stable at the paper's step.
//!
//! What is left out: the stereo cameras and force sensor themselves (the
//! reference block hands over surface points and plate forces with noise),
//! the octree and FPGA speed-ups of the paper's future work, contact of the
//! block with itself, large rotations of the plate.
//!
//! Units: SI inside (m, kg, N, s); the paper's parameters in gf/cm² and
//! gf·s/cm² at the boundary (see [`model::params`]); scenario files in cm,
//! mm, g, ms as their field names say.

pub mod error;
pub mod identify;
pub mod model;

pub use error::{Instability, Result, RheologyError};
pub use model::{contact, effective, element, lattice, params, scenario, sim, solver};
