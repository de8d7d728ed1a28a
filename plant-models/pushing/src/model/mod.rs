//! The mass-spring block of seed 001 and the push it undergoes: the model
//! being calibrated.
pub mod collision;
pub mod forces;
pub mod mesh;
pub mod plasticity;
pub mod scenario;
pub mod sim;
pub mod vec2;
