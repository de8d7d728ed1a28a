//! One run of the joint: a scenario resolved once into a run
//! specification ([`spec`]) of a [`joint`] with its estimation laws ([`laws`], fitted to a
//! [`sweep`] when asked and kept between runs by [`law_cache`]), run by the one closed loop ([`sim`]; `hil` runs
//! the same loop with a board) on its [`schedule`], recorded row by row
//! ([`record`]) into a [`summary`] and a streamed [`trace`], and reported
//! ([`report`]).
pub mod joint;
pub mod law_cache;
pub mod laws;
pub mod record;
pub mod report;
pub mod schedule;
pub mod sim;
pub mod spec;
pub mod summary;
pub mod sweep;
pub mod trace;
