//! Shared helpers for the cross-crate integration tests in `tests/tests/`.

pub use host_tools::board::pty::{BoardFaults, BoardState, PtyBoard};

use std::time::Duration;

use firmware::protocol::{Arm, ClearFaults, HilStart, SetLinkTimeout, SetTarget};
use host_tools::board::link::{Link, Port};

/// Puts a board into lockstep at 1 kHz, armed, with α's target set:
/// handshake, optional link timeout, `HilStart`, `ClearFaults` (faults from
/// free-running mode with no sensors), `SetTarget`, `Arm`.
pub fn start_lockstep<P: Port>(
    link: &mut Link<P>,
    link_timeout_ms: Option<u16>,
    alpha_target_deg: f32,
    timeout: Duration,
) {
    host_tools::board::hil::handshake(link).expect("handshake");
    if let Some(timeout_ms) = link_timeout_ms {
        link.command(&SetLinkTimeout { timeout_ms }.into(), timeout, 5)
            .expect("link timeout");
    }
    link.command(&HilStart { period_us: 1000 }.into(), timeout, 5)
        .expect("HilStart");
    link.command(&ClearFaults {}.into(), timeout, 5)
        .expect("ClearFaults");
    link.command(
        &SetTarget {
            plane: 0,
            target_deg: alpha_target_deg,
        }
        .into(),
        timeout,
        5,
    )
    .expect("SetTarget");
    link.command(&Arm {}.into(), timeout, 5).expect("Arm");
}
pub mod fault_campaign;
pub mod fault_injector;
