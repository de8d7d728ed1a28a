//! The rheology lattice of seed 000 (Noborio): the model being calibrated.
pub mod contact;
pub mod effective;
pub mod element;
pub mod lattice;
pub mod params;
pub mod scenario;
pub mod sim;
pub mod solver;
pub mod vec3;
