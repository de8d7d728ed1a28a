//! Measuring and identifying the block (seed 001 §V–VIII): the ground truth
//! that stands in for the seed's videos (a different, finer model), the
//! pixel F-score, the force regression, the evolutionary calibration,
//! material classification, the Table II protocol and video files; the
//! tracked contour as a periodic smoothing spline and the contour distance
//! where the block deforms ([`contour_score`]); the command line's three
//! experiments as calls that return reports ([`experiment`]).
pub mod classify;
pub mod contour_score;
pub mod evaluate;
pub mod evolution;
pub mod experiment;
pub mod force_regression;
pub mod raster;
pub mod reference;
pub mod table_ii;
pub mod video_csv;
