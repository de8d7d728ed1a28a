//! Shared helpers for the cross-crate integration tests in `tests/tests/`.
#![deny(unsafe_code)]

pub use host_tools::pty_board::{BoardFaults, BoardState, PtyBoard};

use std::time::Duration;

use firmware::protocol::Message;
use host_tools::link::{Link, Port};

/// Puts a board into lockstep at 1 kHz, armed, with α's target set:
/// handshake, optional link timeout, `HilStart`, `ClearFaults` (faults from
/// free-running mode with no sensors), `SetTarget`, `Arm`.
pub fn start_lockstep<P: Port>(
    link: &mut Link<P>,
    link_timeout_ms: Option<u16>,
    alpha_target_deg: f32,
    timeout: Duration,
) {
    host_tools::hil::handshake(link).expect("handshake");
    if let Some(ms) = link_timeout_ms {
        link.command(&Message::SetLinkTimeout { timeout_ms: ms }, timeout, 5)
            .expect("link timeout");
    }
    link.command(&Message::HilStart { period_us: 1000 }, timeout, 5)
        .expect("HilStart");
    link.command(&Message::ClearFaults, timeout, 5)
        .expect("ClearFaults");
    link.command(
        &Message::SetTarget {
            plane: 0,
            target_deg: alpha_target_deg,
        },
        timeout,
        5,
    )
    .expect("SetTarget");
    link.command(&Message::Arm, timeout, 5).expect("Arm");
}
