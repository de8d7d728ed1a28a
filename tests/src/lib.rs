//! Shared helpers for the cross-crate integration tests in `tests/tests/`.
#![deny(unsafe_code)]

pub use host_tools::pty_board::{BoardFaults, BoardState, PtyBoard};
