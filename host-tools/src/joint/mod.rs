//! What the program does for the joint besides running it: the wire
//! sensors' calibration fits, excitation sessions for identification, and
//! the gains search.
pub mod calibrate;
pub mod excite;
pub mod identify_run;
pub mod tune;
