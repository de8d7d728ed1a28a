//! One run of the joint: the closed loop in process or with a board, its
//! summary, the streamed trace and what a run prints.
pub mod report;
pub mod sim;
pub mod trace;
