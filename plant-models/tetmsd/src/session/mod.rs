//! The replicated session as pure logic: time is passed in (µs), nothing
//! here opens a socket or starts a thread, so every part is tested
//! deterministically and the real-time runtime (`host-tools`) reuses it.
//!
//! - [`packet`]: the 64-byte manipulation packet, byte for byte.
//! - [`link`]: sequence numbers, acknowledgements, retransmission.
//! - [`netem`]: the network emulator and the seed's round-trip tables.
//! - [`replica`]: committed and speculative replicas, the update order,
//!   divergence.
//! - [`pair`]: two sites in virtual time over the codec.
//! - [`scenario`]: the session scenario (object, network, stylus paths).
pub mod link;
pub mod netem;
pub mod packet;
pub mod pair;
pub mod replica;
pub mod scenario;
