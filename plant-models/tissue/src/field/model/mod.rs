//! What the field measurement works on and builds: the volume image, the
//! synthetic twins with their known warp, the Delaunay tetrahedra over the
//! matches and the dense field by shape functions (Zhang §III).
pub mod delaunay;
pub mod shape;
pub mod synth;
pub mod volume;
