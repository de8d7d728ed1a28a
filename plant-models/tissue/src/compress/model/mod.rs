//! The compressed body: the phantom's geometry, mesh and markers, the
//! geometric model under A1/A2, and the FEM between plates.
pub mod geometric;
pub mod phantom;
pub mod plates;
