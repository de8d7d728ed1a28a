//! The spline model: bases and axes, Gramians, the smoothing problem and
//! its two solvers, curves and surfaces with their functionals.
pub mod basis;
pub mod curve;
pub mod fit;
pub mod gramian;
pub mod surface;
