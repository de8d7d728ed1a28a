//! The viscoelastic object itself: geometry, FEM, DGFM and the 3-element
//! evaluation (the plant).
pub mod dgfm;
pub mod fem;
pub mod mesh;
pub mod object;
pub use plant_common::three_element;
