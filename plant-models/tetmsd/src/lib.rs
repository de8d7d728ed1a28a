//! Yamaguchi et al.'s haptic communication (seed 000 L2523–2846, SEED000
//! §2): two users at two sites touch and deform one soft object; each site
//! runs its own copy of a tetrahedral Voigt mass-spring-damper model, and
//! the sites keep their copies identical by exchanging 64-byte manipulation
//! packets.
//!
//! - [`model`]: the object — a cube meshed by newest-vertex bisection at
//!   refinement levels 3–9 ([`mesh`]), the Voigt network of Eq. 1–2
//!   ([`voigt`]), Eq. 3's sub-volume point location ([`locate`]), the
//!   probe's grip and contact force ([`probe`]) and a Newton static solver
//!   that is the reference for indentation ([`statics`]).
//! - [`session`]: the replicated session as pure, testable logic — the
//!   packet codec ([`packet`]), sequence numbers, acknowledgements and
//!   retransmission ([`link`]), the network emulator with the paper's
//!   round-trip profiles ([`netem`]), the two replicas with a deterministic
//!   update order ([`replica`]) and a whole two-site session in virtual
//!   time over the codec ([`pair`]), both users on one model without a
//!   network ([`local`]), the scenario file ([`scenario`]), and the
//!   real-time runtime that drives these same types from threads at
//!   1 kHz / deformation / 30 Hz and UDP sockets ([`realtime`]), with the
//!   report every kind of run gives ([`report`]).
//!
//! What is modelled: a soft cube on a fixed support, deformed by one held
//! node per user; replicas that agree bit for bit once they have the same
//! packets; the paper's measured latencies with loss and reordering.
//! What is left out: the seed's adaptive (dynamic) refinement during a run,
//! the volume rendering, a real haptic device (probe trajectories are
//! scripted), gravity, self-collision. Each submodule says more.
//!
//! Units: metres, seconds, newtons, kilograms; names carry them.

pub mod error;
pub mod model;
pub mod session;

pub use error::{Result, TetError};
pub use model::{locate, mesh, probe, statics, voigt, V3};
pub use session::{
    control, link, local, netem, packet, pair, paths, realtime, replica, report, scenario,
};
