//! The dynamic rope of Shi & Payandeh (seed 000, L1162–1594): a chain of
//! mass points with linear, torsional and swivel springs and dampers,
//! desk contact, self-collision through a sphere tree, force propagation
//! and grasping tools coupled through a spring-damper.
//!
//! - [`params`]: Table I and the estimates the paper leaves open;
//! - [`forces`]: the internal forces, Eq. 5–16;
//! - [`collision`]: the bounding-volume hierarchy, closest points, and the
//!   impulse distribution of Eq. 19–23;
//! - [`sim`]: the rope in time (Euler step, desk, tools, propagation,
//!   collisions, instability detection);
//! - [`script`]: scripted hands (grasp, move, release) and the knotting
//!   and unknotting scenarios;
//! - [`verify`]: a run's self-checks (overlap, force balance, stability,
//!   rest, time step) and its verified/UNVERIFIED status.
//!
//! Left out: the haptic devices themselves (scripted hands drive the
//! virtual coupling; the device force −s·f is computed and reported),
//! static friction (the paper has none either, L1207), gripper geometry
//! (a hand grabs the nearest point within its reach instead of
//! intersecting a jaw triangle with the tree), rendering.
pub mod collision;
pub mod forces;
pub mod params;
pub mod script;
pub mod sim;
pub mod verify;

pub use forces::V3;
pub use params::{RopeModel, RopeParams};
pub use sim::{Desk, Rope, Tool};
