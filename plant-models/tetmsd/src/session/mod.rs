//! The replicated session. The parts below [`realtime`] are pure logic:
//! time is passed in (µs), nothing there opens a socket or starts a
//! thread, so every part is tested deterministically; [`realtime`] drives
//! the same parts from threads and a UDP socket.
//!
//! - [`packet`]: the 64-byte manipulation packet, byte for byte.
//! - [`link`]: sequence numbers, acknowledgements, retransmission.
//! - [`control`]: the handshake, the session clock, state transfer to a
//!   restarted peer.
//! - [`netem`]: the network emulator and the seed's round-trip tables.
//! - [`replica`]: committed and speculative replicas, the update order,
//!   divergence.
//! - [`pair`]: two sites in virtual time over the codec.
//! - [`local`]: both users on one model, no network.
//! - [`paths`]: the link's figures on an emulated path against the path
//!   itself (round trip, resends, committed lag), and the table of paths.
//! - [`realtime`]: one site in real time (haptic 1 kHz, deformation,
//!   network, display 30 Hz), and two such sites in one process.
//! - [`report`]: what a site reports, in one shape for every mode.
//! - [`scenario`]: the session scenario (object, network, stylus paths).
pub mod control;
pub mod link;
pub mod local;
pub mod netem;
pub mod packet;
pub mod pair;
pub mod paths;
pub mod realtime;
pub mod replica;
pub mod report;
pub mod scenario;
