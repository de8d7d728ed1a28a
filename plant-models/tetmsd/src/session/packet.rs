//! The 64-byte packet, laid out as the seed lays out its manipulation
//! packet (Yamaguchi §5.1, seed 000 L2650–2655): the stylus tip (8 B × 3),
//! the tetrahedron ID held by the user (8 B), the node ID manipulated by
//! the user (8 B) and that node's position (8 B × 3): 24 + 8 + 8 + 24 = 64
//! bytes. Every other message of the session (handshake, acknowledgements,
//! state transfer, bye) is a 64-byte packet too, with the same header.
//!
//! `docs/tetmsd-packet.md` specifies every kind byte for byte for other
//! implementations (held to this code by
//! `plant-models/tetmsd/tests/it/packet_doc.rs`).
//!
//! The seed gives no header. The two ID fields are 64-bit words whose
//! indices need 16 bits (the largest mesh here has 24,576 tetrahedra), so
//! the header lives in their upper bytes and an input packet keeps every
//! field where the paper puts it. All numbers are little-endian. The
//! header, common to every kind:
//!
//! | bytes | field |
//! |---|---|
//! | 26 | protocol version, u8: [`VERSION`] |
//! | 27 | bits 0–2 kind (0 input, 1 hello, 2 ack, 3 bye, 4 state), bit 3 sending site, bits 4–7 zero |
//! | 28–31 | u32: the tick (input: its tick; ack: the first tick its blocks describe; bye: the sender's next tick; state: the state's tick; hello: stage and serial) |
//! | 34–37 | acknowledgements (input, ack, bye): [`Acks`]; hello: the echo; state: zero |
//! | 38–39 | CRC-16/IBM-3740 (CCITT-FALSE: poly 0x1021, init 0xFFFF) of bytes 0–37 and 40 to the end |
//!
//! and bytes 0–25, 32–33 and 40–63 are the kind's own ([`Message`]). An
//! input packet goes on after its 64 bytes with a [`STAMP_BYTES`]-byte
//! timestamp echo ([`Stamp`], version 4: its send time and the echo of
//! a send time of the peer's, for round trips that need no guess about
//! which packet delivered a tick), then [`COPY_BYTES`]-byte copies of the
//! sender's inputs of up to [`MAX_COPIES`] earlier ticks ([`Copies`],
//! version 3): forward redundancy, so that a lost packet's input comes in
//! the next one instead of waiting for a resend.
//!
//! Decoding refuses, and names, every packet that is not exactly what the
//! encoder would write: a wrong length, copies out of order or out of
//! reach, another version, set reserved
//! bits, a kind, stage or reason this version does not define, a bad CRC,
//! a non-finite number, a tetrahedron without a node (or the reverse),
//! selective-ack blocks out of order, and non-zero bytes where a message
//! has none ([`Malformed`]); [`DecodeStats`] counts the refusals by reason.
//! Because the format is canonical, `encode(decode(b)) == b` for every
//! accepted `b`. The checks that need the session's mesh (index inside the
//! mesh, node a vertex of the tetrahedron, node off the support, a state of
//! the mesh's size) are [`Packet::check_against`].
use crate::model::probe::{ContactGeometry, Grip, Manipulation};
use crate::model::V3;
use crc::{Crc, CRC_16_IBM_3740};
use std::fmt;

/// Bytes in a packet (an input packet has [`STAMP_BYTES`] more, and
/// [`COPY_BYTES`] more per copy).
pub const PACKET_BYTES: usize = 64;
/// The protocol version this code speaks: 3 added the copies of earlier
/// inputs after an input packet's 64 bytes, 4 the timestamp echo before
/// them.
pub const VERSION: u8 = 4;
/// Bytes of an input packet's timestamp echo ([`Stamp`]), after its 64.
pub const STAMP_BYTES: usize = 12;
/// Bytes of an input packet without copies.
pub const INPUT_BYTES: usize = PACKET_BYTES + STAMP_BYTES;
/// Bytes of one copied input after an input packet's stamp.
pub const COPY_BYTES: usize = 56;
/// Most copies one input packet may carry: 16 keeps the datagram at 972
/// bytes, inside the 1,232-byte UDP payload every IPv6 path carries
/// (1,280-byte minimum MTU less 48 bytes of headers) without
/// fragmentation.
pub const MAX_COPIES: usize = 16;
/// The longest datagram of this version (an input with [`MAX_COPIES`]).
pub const MAX_DATAGRAM_BYTES: usize = INPUT_BYTES + MAX_COPIES * COPY_BYTES;
/// A stamp's hold when it echoes nothing (its echoed send time is then
/// zero).
pub const NO_ECHO: u32 = u32::MAX;
/// "No tetrahedron" / "no node" in an index field.
pub const NONE_INDEX: u16 = 0xFFFF;
/// The haptic tick this version runs at (µs): one input per millisecond.
pub const TICK_US: u16 = 1000;
/// Selective-ack blocks one ack packet carries.
pub const MAX_BLOCKS: usize = 12;
/// Ticks after the cumulative ack that the 15-bit map of [`Acks::sack`]
/// describes.
pub const SACK_MAP_TICKS: u32 = 15;
/// Bit 15 of [`Acks::sack`]: the receiver holds ticks beyond the map.
pub const SACK_MORE: u16 = 0x8000;
/// A hello's "no committed tick" (the sender is fresh).
pub const NO_TICK: u32 = u32::MAX;

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// The acknowledgement words of an input, ack or bye packet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Acks {
    /// Low 16 bits of the number of the peer's ticks received without a
    /// gap (every tick below it has arrived; the tick it names has not).
    pub ack: u16,
    /// Bits 0–14: the peer's tick `ack + 1 + b` has arrived; bit 15
    /// ([`SACK_MORE`]): the receiver holds ticks beyond `ack + 15`.
    pub sack: u16,
}

/// The timestamp echo of an input packet (version 4; after RFC 7323
/// §3–4, the TCP timestamps option): the sender's send time, and the send
/// time of one input packet of the peer's that arrived, with how long it
/// waited here. The peer's sample `now − echoed − hold` is that packet's
/// trip and this one's, whatever tick it delivered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Stamp {
    /// The sender's clock when it sent this packet: µs, modulo 2³².
    pub sent_us: u32,
    /// The echo, if one is due.
    pub echo: Option<StampEcho>,
}

/// The echoed half of a [`Stamp`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StampEcho {
    /// The [`Stamp::sent_us`] of the peer's packet echoed (the peer's
    /// clock).
    pub sent_us: u32,
    /// µs between that packet's arrival and this packet's sending (below
    /// [`NO_ECHO`]).
    pub hold_us: u32,
}

/// Copies of earlier inputs an input packet carries (forward
/// redundancy): each one's tick and manipulation, ticks ascending, each
/// 1–[`MAX_COPIES`] ticks before the packet's own.
#[derive(Clone, Copy, Debug)]
pub struct Copies {
    count: u8,
    items: [(u32, Manipulation); MAX_COPIES],
}

impl Copies {
    /// No copies.
    pub fn none() -> Self {
        Copies {
            count: 0,
            items: [(0, Manipulation::free(V3::zeros())); MAX_COPIES],
        }
    }

    /// Adds the copy of `tick`'s `input` (after the ones there; ticks
    /// must ascend). False when [`MAX_COPIES`] are already there.
    pub fn push(&mut self, tick: u32, input: Manipulation) -> bool {
        let k = usize::from(self.count);
        if k >= MAX_COPIES {
            return false;
        }
        self.items[k] = (tick, input);
        self.count += 1;
        true
    }

    /// The copies, ticks ascending.
    pub fn as_slice(&self) -> &[(u32, Manipulation)] {
        &self.items[..usize::from(self.count)]
    }

    /// How many.
    pub fn len(&self) -> usize {
        usize::from(self.count)
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }
}

impl Default for Copies {
    fn default() -> Self {
        Copies::none()
    }
}

impl PartialEq for Copies {
    fn eq(&self, other: &Self) -> bool {
        self.as_slice() == other.as_slice()
    }
}

/// What both sites must run identically: the hello carries it, and a site
/// refuses a peer whose fields differ, naming them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SessionFields {
    /// Refinement level of the cube.
    pub level: u16,
    /// The haptic tick (µs); [`TICK_US`] in this version.
    pub tick_us: u16,
    /// Cube edge (m).
    pub side_m: f64,
    /// κ (Pa).
    pub stiffness_modulus_pa: f64,
    /// η (Pa·s).
    pub damping_modulus_pa_s: f64,
    /// Density (kg/m³).
    pub density_kg_m3: f64,
}

impl SessionFields {
    /// The configuration hash: 64-bit FNV-1a (offset basis
    /// 0xcbf29ce484222325, prime 0x100000001b3) of the 37 bytes version
    /// (u8), level (u16), tick_us (u16), side_m, stiffness_modulus_pa,
    /// damping_modulus_pa_s, density_kg_m3 (f64 each), little-endian.
    pub fn hash(&self) -> u64 {
        let mut bytes = Vec::with_capacity(37);
        bytes.push(VERSION);
        bytes.extend_from_slice(&self.level.to_le_bytes());
        bytes.extend_from_slice(&self.tick_us.to_le_bytes());
        for v in [
            self.side_m,
            self.stiffness_modulus_pa,
            self.damping_modulus_pa_s,
            self.density_kg_m3,
        ] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
        fnv1a(&bytes)
    }

    /// The fields in which `peer` differs from `self`, each as
    /// `name: ours X, the peer's Y` (empty when they agree bit for bit).
    pub fn mismatches(&self, peer: &SessionFields) -> Vec<String> {
        let mut out = Vec::new();
        if self.level != peer.level {
            out.push(format!(
                "level: ours {}, the peer's {}",
                self.level, peer.level
            ));
        }
        if self.tick_us != peer.tick_us {
            out.push(format!(
                "tick_us: ours {}, the peer's {}",
                self.tick_us, peer.tick_us
            ));
        }
        for (name, a, b) in [
            ("side_m", self.side_m, peer.side_m),
            (
                "stiffness_modulus_pa",
                self.stiffness_modulus_pa,
                peer.stiffness_modulus_pa,
            ),
            (
                "damping_modulus_pa_s",
                self.damping_modulus_pa_s,
                peer.damping_modulus_pa_s,
            ),
            ("density_kg_m3", self.density_kg_m3, peer.density_kg_m3),
        ] {
            if a.to_bits() != b.to_bits() {
                out.push(format!("{name}: ours {a:e}, the peer's {b:e}"));
            }
        }
        out
    }
}

/// 64-bit FNV-1a of `bytes`.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// The stage of a hello.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// 0: looking for the peer; the sender's committed tick if it runs a
    /// session, `None` when it is fresh.
    Hello {
        /// The sender's committed tick.
        committed_tick: Option<u32>,
    },
    /// 1: the sender runs the session and sends its committed state at
    /// `state_tick` in state packets (to a fresh peer that restarted).
    StateFollows {
        /// The state's tick.
        state_tick: u32,
    },
    /// 2: the sender has the whole state of `state_tick` and its hash
    /// matched.
    StateReceived {
        /// The state's tick.
        state_tick: u32,
    },
    /// 3: site 0 starts a new session: its tick 0 begins `-clock_us` µs
    /// after it sent this packet (`clock_us` is its session clock then).
    Go {
        /// Site 0's session clock when it sent this (µs; negative before
        /// its tick 0).
        clock_us: i32,
    },
}

/// The round-trip echo of a hello: the last serial heard from the peer
/// and how long it was held before this reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Echo {
    /// The peer's hello serial.
    pub serial: u16,
    /// µs between its arrival and this packet's sending (≤ 65,534).
    pub hold_us: u16,
}

/// A handshake packet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hello {
    /// Stage.
    pub stage: Stage,
    /// The sender's hello counter.
    pub serial: u16,
    /// The echo of the peer's last hello, if one was heard.
    pub echo: Option<Echo>,
    /// The sender's session.
    pub fields: SessionFields,
    /// [`SessionFields::hash`] as the sender computes it.
    pub config_hash: u64,
    /// The sender's process incarnation (random per start).
    pub nonce: u32,
}

/// Selective acknowledgement ranges: which peer ticks after the
/// cumulative ack have arrived.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SackReport {
    /// The receiver's highest received tick + 1, as an offset from the
    /// cumulative count.
    pub frontier: u16,
    /// Blocks used.
    pub count: u8,
    /// `[start, end)` offsets from the cumulative count, ascending, each
    /// start after the previous end; unused ones zero.
    pub blocks: [(u16, u16); MAX_BLOCKS],
}

impl SackReport {
    /// The blocks in use.
    pub fn used(&self) -> &[(u16, u16)] {
        &self.blocks[..usize::from(self.count).min(MAX_BLOCKS)]
    }
}

/// Why a site stops.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ByeReason {
    /// 0: its duration is over.
    Duration,
    /// 1: its user stopped it (SIGINT, SIGTERM).
    User,
    /// 2: its peer stopped.
    Peer,
    /// 3: it failed.
    Failure,
}

impl ByeReason {
    /// In words.
    pub fn describe(self) -> &'static str {
        match self {
            ByeReason::Duration => "its duration is over",
            ByeReason::User => "its user stopped it",
            ByeReason::Peer => "its peer stopped",
            ByeReason::Failure => "it failed",
        }
    }
}

/// A bye.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bye {
    /// 0: the sender makes no more inputs (its ticks end where the
    /// header's tick says).
    Stopping(ByeReason),
    /// 1: the sender's committed replica reached the session's end tick
    /// (the smaller of the two sites' tick counts) with this hash.
    Done {
        /// Why the sender stopped.
        reason: ByeReason,
        /// The end tick.
        end_tick: u64,
        /// [`crate::model::voigt::State::bit_hash`] of the committed replica there.
        state_hash: u64,
    },
}

/// One packet of a state transfer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StateChunk {
    /// Node `index` of `count`: its position and velocity.
    Node {
        /// The node.
        index: u16,
        /// Nodes in the state.
        count: u16,
        /// Position (m).
        x_m: V3,
        /// Velocity (m/s).
        v_m_s: V3,
    },
    /// The state's hash and the sender's session clock.
    Summary {
        /// Nodes in the state.
        count: u16,
        /// [`crate::model::voigt::State::bit_hash`] of the state.
        state_hash: u64,
        /// The sender's session clock when it sent this (µs; tick k
        /// starts at k · 1000).
        clock_us: i64,
    },
}

/// What a packet says.
#[derive(Clone, Copy, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // an input's copies (1.2 kB) kept inline so that packets stay Copy; one is built per tick
pub enum Message {
    /// Kind 0: the sender's manipulation for `tick`, and copies of
    /// earlier ones.
    Input {
        /// The sender's haptic tick.
        tick: u32,
        /// Acknowledgements of the peer's ticks.
        acks: Acks,
        /// The manipulation.
        input: Manipulation,
        /// The timestamp echo.
        stamp: Stamp,
        /// Copies of the sender's inputs of earlier ticks.
        copies: Copies,
    },
    /// Kind 1: the handshake.
    Hello(Hello),
    /// Kind 2: acknowledgements with selective-ack ranges.
    Ack {
        /// The first of the peer's ticks the blocks describe (the
        /// cumulative count in the first packet of a report, the end of the
        /// previous packet's last block in the next ones).
        from: u32,
        /// Acknowledgements.
        acks: Acks,
        /// Ranges.
        report: SackReport,
    },
    /// Kind 3: leaving.
    Bye {
        /// The sender's next tick (after a `Stopping`: its tick count).
        next_tick: u32,
        /// Acknowledgements.
        acks: Acks,
        /// Stage and reason.
        bye: Bye,
    },
    /// Kind 4: part of a committed state.
    State {
        /// The state's tick.
        tick: u32,
        /// The part.
        chunk: StateChunk,
    },
}

/// A decoded packet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Packet {
    /// Sending site, 0 or 1.
    pub site: u8,
    /// The message.
    pub message: Message,
}

/// Why a packet was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Malformed {
    /// Not 64 bytes (an input: not 76 + 56·n, n ≤ 16).
    WrongLength,
    /// Another protocol version.
    BadVersion,
    /// Reserved bits set (byte 27 bits 4–7).
    ReservedBits,
    /// The CRC does not match.
    BadCrc,
    /// A kind, stage or reason this version does not define.
    UnknownValue,
    /// A number is NaN or infinite.
    NonFinite,
    /// A tetrahedron without a node or a node without a tetrahedron.
    InconsistentGrip,
    /// Bytes a message does not use are not zero.
    NonCanonical,
    /// Selective-ack blocks out of order, empty or beyond the frontier.
    BadBlocks,
    /// Copies of inputs not 1–16 ticks before the packet's own, or not
    /// ascending.
    BadCopies,
    /// An index outside this session's mesh (or a state of another size).
    IndexOutOfRange,
    /// The node is not a vertex of the tetrahedron, or may not be held
    /// (inside the object or on the support).
    BadGrip,
    /// The sending site is this site, or the peer runs another
    /// configuration.
    WrongPeer,
}

impl Malformed {
    /// Every reason, in [`DecodeStats`] order.
    pub const ALL: [Malformed; 13] = [
        Malformed::WrongLength,
        Malformed::BadVersion,
        Malformed::ReservedBits,
        Malformed::BadCrc,
        Malformed::UnknownValue,
        Malformed::NonFinite,
        Malformed::InconsistentGrip,
        Malformed::NonCanonical,
        Malformed::BadBlocks,
        Malformed::BadCopies,
        Malformed::IndexOutOfRange,
        Malformed::BadGrip,
        Malformed::WrongPeer,
    ];

    /// A short name (JSON keys, CSV columns).
    pub fn name(self) -> &'static str {
        match self {
            Malformed::WrongLength => "wrong_length",
            Malformed::BadVersion => "bad_version",
            Malformed::ReservedBits => "reserved_bits",
            Malformed::BadCrc => "bad_crc",
            Malformed::UnknownValue => "unknown_value",
            Malformed::NonFinite => "non_finite",
            Malformed::InconsistentGrip => "inconsistent_grip",
            Malformed::NonCanonical => "non_canonical",
            Malformed::BadBlocks => "bad_blocks",
            Malformed::BadCopies => "bad_copies",
            Malformed::IndexOutOfRange => "index_out_of_range",
            Malformed::BadGrip => "bad_grip",
            Malformed::WrongPeer => "wrong_peer",
        }
    }

    fn index(self) -> usize {
        Malformed::ALL.iter().position(|m| *m == self).unwrap_or(0)
    }
}

impl fmt::Display for Malformed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = match self {
            Malformed::WrongLength => "not 64 bytes long (an input: 76 + 56 per copy, 16 at most)",
            Malformed::BadVersion => "another protocol version",
            Malformed::ReservedBits => "reserved bits set",
            Malformed::BadCrc => "CRC mismatch",
            Malformed::UnknownValue => "a kind, stage or reason this version does not define",
            Malformed::NonFinite => "a number is not finite",
            Malformed::InconsistentGrip => {
                "a tetrahedron without a node or a node without a tetrahedron"
            }
            Malformed::NonCanonical => "unused bytes are not zero",
            Malformed::BadBlocks => "selective-ack blocks out of order or beyond the frontier",
            Malformed::BadCopies => "input copies not 1-16 ticks back in ascending order",
            Malformed::IndexOutOfRange => "an index outside the mesh, or a state of another size",
            Malformed::BadGrip => "the node is not a grippable vertex of the tetrahedron",
            Malformed::WrongPeer => "not from the peer, or the peer runs another configuration",
        };
        f.write_str(text)
    }
}

impl std::error::Error for Malformed {}

/// Refused packets counted by reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DecodeStats {
    counts: [u64; 13],
}

impl DecodeStats {
    /// Counts one refusal.
    pub fn record(&mut self, why: Malformed) {
        self.counts[why.index()] += 1;
    }

    /// Refusals for one reason.
    pub fn count(&self, why: Malformed) -> u64 {
        self.counts[why.index()]
    }

    /// All refusals.
    pub fn total(&self) -> u64 {
        self.counts.iter().sum()
    }

    /// (name, count) for every reason.
    pub fn by_reason(&self) -> impl Iterator<Item = (&'static str, u64)> + '_ {
        Malformed::ALL.iter().map(|m| (m.name(), self.count(*m)))
    }
}

fn put_f64s(out: &mut [u8], v: V3) {
    for (k, c) in v.iter().enumerate() {
        out[8 * k..8 * k + 8].copy_from_slice(&c.to_le_bytes());
    }
}

fn get_f64s(b: &[u8]) -> V3 {
    V3::new(f64_at(b, 0), f64_at(b, 8), f64_at(b, 16))
}

fn u16_at(b: &[u8], k: usize) -> u16 {
    u16::from_le_bytes([b[k], b[k + 1]])
}

fn u32_at(b: &[u8], k: usize) -> u32 {
    u32::from_le_bytes([b[k], b[k + 1], b[k + 2], b[k + 3]])
}

fn u64_at(b: &[u8], k: usize) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[k..k + 8]);
    u64::from_le_bytes(w)
}

fn f64_at(b: &[u8], k: usize) -> f64 {
    f64::from_bits(u64_at(b, k))
}

fn put_u16(b: &mut [u8], k: usize, v: u16) {
    b[k..k + 2].copy_from_slice(&v.to_le_bytes());
}

fn put_u32(b: &mut [u8], k: usize, v: u32) {
    b[k..k + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u64(b: &mut [u8], k: usize, v: u64) {
    b[k..k + 8].copy_from_slice(&v.to_le_bytes());
}

fn crc_of(b: &[u8]) -> u16 {
    let mut d = CRC16.digest();
    d.update(&b[..38]);
    d.update(&b[40..]);
    d.finalize()
}

/// The byte offset of selective-ack block `k` (0–5 in bytes 0–23, 6–11 in
/// 40–63).
fn block_at(k: usize) -> usize {
    if k < 6 {
        4 * k
    } else {
        40 + 4 * (k - 6)
    }
}

fn put_acks(b: &mut [u8], a: Acks) {
    put_u16(b, 34, a.ack);
    put_u16(b, 36, a.sack);
}

fn get_acks(b: &[u8]) -> Acks {
    Acks {
        ack: u16_at(b, 34),
        sack: u16_at(b, 36),
    }
}

fn zero(b: &[u8], r: std::ops::Range<usize>) -> bool {
    b[r].iter().all(|&x| x == 0)
}

fn finite(v: V3) -> bool {
    v.iter().all(|c| c.is_finite())
}

fn encode_input(
    b: &mut [u8],
    tick: u32,
    acks: Acks,
    m: &Manipulation,
    stamp: &Stamp,
    copies: &Copies,
) {
    put_f64s(&mut b[0..24], m.tip_m);
    let (tet, node) = match m.grip {
        Some(g) => {
            put_f64s(&mut b[40..64], g.node_m);
            (g.tet, g.node)
        }
        None => (NONE_INDEX, NONE_INDEX),
    };
    put_u16(b, 24, tet);
    put_u32(b, 28, tick);
    put_u16(b, 32, node);
    put_acks(b, acks);
    put_u32(b, 64, stamp.sent_us);
    let (echoed, hold) = stamp.echo.map_or((0, NO_ECHO), |e| (e.sent_us, e.hold_us));
    put_u32(b, 68, echoed);
    put_u32(b, 72, hold);
    for (k, (t, c)) in copies.as_slice().iter().enumerate() {
        let r = &mut b[INPUT_BYTES + k * COPY_BYTES..INPUT_BYTES + (k + 1) * COPY_BYTES];
        put_u16(r, 0, tick.wrapping_sub(*t) as u16);
        let (tet, node) = match c.grip {
            Some(g) => {
                put_f64s(&mut r[32..56], g.node_m);
                (g.tet, g.node)
            }
            None => (NONE_INDEX, NONE_INDEX),
        };
        put_u16(r, 2, tet);
        put_u16(r, 4, node);
        put_f64s(&mut r[8..32], c.tip_m);
    }
}

/// A manipulation from its tip, tetrahedron, node and node position
/// fields (`node_b` the 24 bytes of the node position).
fn manipulation(tip_m: V3, tet: u16, node: u16, node_b: &[u8]) -> Result<Manipulation, Malformed> {
    if !finite(tip_m) {
        return Err(Malformed::NonFinite);
    }
    let grip = match (tet == NONE_INDEX, node == NONE_INDEX) {
        (true, true) => {
            if !zero(node_b, 0..24) {
                return Err(Malformed::NonCanonical);
            }
            None
        }
        (false, false) => {
            let node_m = get_f64s(node_b);
            if !finite(node_m) {
                return Err(Malformed::NonFinite);
            }
            Some(Grip { tet, node, node_m })
        }
        _ => return Err(Malformed::InconsistentGrip),
    };
    Ok(Manipulation { tip_m, grip })
}

fn encode_hello(b: &mut [u8], h: &Hello) {
    let f = &h.fields;
    for (k, v) in [f.side_m, f.stiffness_modulus_pa, f.damping_modulus_pa_s]
        .iter()
        .enumerate()
    {
        b[8 * k..8 * k + 8].copy_from_slice(&v.to_le_bytes());
    }
    put_u16(b, 24, f.level);
    let (stage, word) = match h.stage {
        Stage::Hello { committed_tick } => (0u8, committed_tick.unwrap_or(NO_TICK)),
        Stage::StateFollows { state_tick } => (1, state_tick),
        Stage::StateReceived { state_tick } => (2, state_tick),
        Stage::Go { clock_us } => (3, u32::from_le_bytes(clock_us.to_le_bytes())),
    };
    b[28] = stage;
    put_u16(b, 30, h.serial);
    put_u16(b, 32, f.tick_us);
    match h.echo {
        Some(e) => {
            put_u16(b, 34, e.serial);
            put_u16(b, 36, e.hold_us.min(0xFFFE));
        }
        None => put_u16(b, 36, 0xFFFF),
    }
    b[40..48].copy_from_slice(&f.density_kg_m3.to_le_bytes());
    put_u64(b, 48, h.config_hash);
    put_u32(b, 56, h.nonce);
    put_u32(b, 60, word);
}

fn encode_ack(b: &mut [u8], from: u32, acks: Acks, r: &SackReport) {
    put_u16(b, 24, u16::from(r.count));
    put_u32(b, 28, from);
    put_u16(b, 32, r.frontier);
    put_acks(b, acks);
    for (k, (start, end)) in r.used().iter().enumerate() {
        put_u16(b, block_at(k), *start);
        put_u16(b, block_at(k) + 2, *end);
    }
}

fn encode_bye(b: &mut [u8], next_tick: u32, acks: Acks, bye: &Bye) {
    let reason_code = |r: ByeReason| match r {
        ByeReason::Duration => 0u16,
        ByeReason::User => 1,
        ByeReason::Peer => 2,
        ByeReason::Failure => 3,
    };
    let (stage, reason) = match bye {
        Bye::Stopping(r) => (0u16, *r),
        Bye::Done {
            reason,
            end_tick,
            state_hash,
        } => {
            put_u64(b, 40, *end_tick);
            put_u64(b, 48, *state_hash);
            (1, *reason)
        }
    };
    put_u16(b, 24, stage);
    put_u32(b, 28, next_tick);
    put_u16(b, 32, reason_code(reason));
    put_acks(b, acks);
}

fn encode_state(b: &mut [u8], tick: u32, chunk: &StateChunk) {
    put_u32(b, 28, tick);
    match chunk {
        StateChunk::Node {
            index,
            count,
            x_m,
            v_m_s,
        } => {
            put_f64s(&mut b[0..24], *x_m);
            put_f64s(&mut b[40..64], *v_m_s);
            put_u16(b, 24, *index);
            put_u16(b, 32, *count);
        }
        StateChunk::Summary {
            count,
            state_hash,
            clock_us,
        } => {
            put_u64(b, 0, *state_hash);
            b[8..16].copy_from_slice(&clock_us.to_le_bytes());
            put_u16(b, 24, NONE_INDEX);
            put_u16(b, 32, *count);
        }
    }
}

fn decode_input(b: &[u8]) -> Result<Message, Malformed> {
    let input = manipulation(
        get_f64s(&b[0..24]),
        u16_at(b, 24),
        u16_at(b, 32),
        &b[40..64],
    )?;
    let tick = u32_at(b, 28);
    let (sent_us, echoed, hold_us) = (u32_at(b, 64), u32_at(b, 68), u32_at(b, 72));
    let echo = if hold_us == NO_ECHO {
        if echoed != 0 {
            return Err(Malformed::NonCanonical);
        }
        None
    } else {
        Some(StampEcho {
            sent_us: echoed,
            hold_us,
        })
    };
    let mut copies = Copies::none();
    let mut previous_back = u32::MAX;
    for r in b[INPUT_BYTES..].chunks(COPY_BYTES) {
        let back = u32::from(u16_at(r, 0));
        // Ticks ascending: each copy nearer the packet's own tick.
        if back == 0 || back as usize > MAX_COPIES || back >= previous_back || back > tick {
            return Err(Malformed::BadCopies);
        }
        if !zero(r, 6..8) {
            return Err(Malformed::NonCanonical);
        }
        previous_back = back;
        let m = manipulation(get_f64s(&r[8..32]), u16_at(r, 2), u16_at(r, 4), &r[32..56])?;
        copies.push(tick - back, m);
    }
    Ok(Message::Input {
        tick,
        acks: get_acks(b),
        input,
        stamp: Stamp { sent_us, echo },
        copies,
    })
}

fn decode_hello(b: &[u8]) -> Result<Message, Malformed> {
    let fields = SessionFields {
        level: u16_at(b, 24),
        tick_us: u16_at(b, 32),
        side_m: f64_at(b, 0),
        stiffness_modulus_pa: f64_at(b, 8),
        damping_modulus_pa_s: f64_at(b, 16),
        density_kg_m3: f64_at(b, 40),
    };
    let reals = [
        fields.side_m,
        fields.stiffness_modulus_pa,
        fields.damping_modulus_pa_s,
        fields.density_kg_m3,
    ];
    if !reals.iter().all(|v| v.is_finite()) {
        return Err(Malformed::NonFinite);
    }
    if b[29] != 0 {
        return Err(Malformed::NonCanonical);
    }
    let word = u32_at(b, 60);
    let stage = match b[28] {
        0 => Stage::Hello {
            committed_tick: (word != NO_TICK).then_some(word),
        },
        1 => Stage::StateFollows { state_tick: word },
        2 => Stage::StateReceived { state_tick: word },
        3 => Stage::Go {
            clock_us: i32::from_le_bytes(word.to_le_bytes()),
        },
        _ => return Err(Malformed::UnknownValue),
    };
    let (echo_serial, hold_us) = (u16_at(b, 34), u16_at(b, 36));
    let echo = if hold_us == 0xFFFF {
        if echo_serial != 0 {
            return Err(Malformed::NonCanonical);
        }
        None
    } else {
        Some(Echo {
            serial: echo_serial,
            hold_us,
        })
    };
    Ok(Message::Hello(Hello {
        stage,
        serial: u16_at(b, 30),
        echo,
        fields,
        config_hash: u64_at(b, 48),
        nonce: u32_at(b, 56),
    }))
}

fn decode_ack(b: &[u8]) -> Result<Message, Malformed> {
    let count = u16_at(b, 24);
    if usize::from(count) > MAX_BLOCKS {
        return Err(Malformed::BadBlocks);
    }
    let mut report = SackReport {
        frontier: u16_at(b, 32),
        count: count as u8,
        blocks: [(0, 0); MAX_BLOCKS],
    };
    let mut previous_end = 0u16;
    for k in 0..MAX_BLOCKS {
        let (start, end) = (u16_at(b, block_at(k)), u16_at(b, block_at(k) + 2));
        if k >= usize::from(count) {
            if start != 0 || end != 0 {
                return Err(Malformed::NonCanonical);
            }
            continue;
        }
        if start <= previous_end || end <= start || end > report.frontier {
            return Err(Malformed::BadBlocks);
        }
        report.blocks[k] = (start, end);
        previous_end = end;
    }
    Ok(Message::Ack {
        from: u32_at(b, 28),
        acks: get_acks(b),
        report,
    })
}

fn decode_bye(b: &[u8]) -> Result<Message, Malformed> {
    if !zero(b, 0..24) || !zero(b, 56..64) {
        return Err(Malformed::NonCanonical);
    }
    let reason = match u16_at(b, 32) {
        0 => ByeReason::Duration,
        1 => ByeReason::User,
        2 => ByeReason::Peer,
        3 => ByeReason::Failure,
        _ => return Err(Malformed::UnknownValue),
    };
    let bye = match u16_at(b, 24) {
        0 => {
            if !zero(b, 40..56) {
                return Err(Malformed::NonCanonical);
            }
            Bye::Stopping(reason)
        }
        1 => Bye::Done {
            reason,
            end_tick: u64_at(b, 40),
            state_hash: u64_at(b, 48),
        },
        _ => return Err(Malformed::UnknownValue),
    };
    Ok(Message::Bye {
        next_tick: u32_at(b, 28),
        acks: get_acks(b),
        bye,
    })
}

fn decode_state(b: &[u8]) -> Result<Message, Malformed> {
    if !zero(b, 34..38) {
        return Err(Malformed::NonCanonical);
    }
    let (index, count) = (u16_at(b, 24), u16_at(b, 32));
    if count == 0 || count == NONE_INDEX {
        return Err(Malformed::IndexOutOfRange);
    }
    let chunk = if index == NONE_INDEX {
        if !zero(b, 16..24) || !zero(b, 40..64) {
            return Err(Malformed::NonCanonical);
        }
        let mut clock = [0u8; 8];
        clock.copy_from_slice(&b[8..16]);
        StateChunk::Summary {
            count,
            state_hash: u64_at(b, 0),
            clock_us: i64::from_le_bytes(clock),
        }
    } else {
        if index >= count {
            return Err(Malformed::IndexOutOfRange);
        }
        let (x_m, v_m_s) = (get_f64s(&b[0..24]), get_f64s(&b[40..64]));
        if !finite(x_m) || !finite(v_m_s) {
            return Err(Malformed::NonFinite);
        }
        StateChunk::Node {
            index,
            count,
            x_m,
            v_m_s,
        }
    };
    Ok(Message::State {
        tick: u32_at(b, 28),
        chunk,
    })
}

impl Packet {
    /// The bytes of this packet: 64; an input [`INPUT_BYTES`], and
    /// [`COPY_BYTES`] more per copy it carries.
    pub fn encode(&self) -> Vec<u8> {
        let len = match &self.message {
            Message::Input { copies, .. } => INPUT_BYTES + copies.len() * COPY_BYTES,
            _ => PACKET_BYTES,
        };
        let mut b = vec![0u8; len];
        let kind = match &self.message {
            Message::Input {
                tick,
                acks,
                input,
                stamp,
                copies,
            } => {
                encode_input(&mut b, *tick, *acks, input, stamp, copies);
                0u8
            }
            Message::Hello(h) => {
                encode_hello(&mut b, h);
                1
            }
            Message::Ack { from, acks, report } => {
                encode_ack(&mut b, *from, *acks, report);
                2
            }
            Message::Bye {
                next_tick,
                acks,
                bye,
            } => {
                encode_bye(&mut b, *next_tick, *acks, bye);
                3
            }
            Message::State { tick, chunk } => {
                encode_state(&mut b, *tick, chunk);
                4
            }
        };
        b[26] = VERSION;
        b[27] = kind | ((self.site & 1) << 3);
        let crc = crc_of(&b);
        put_u16(&mut b, 38, crc);
        b
    }

    /// The input ticks this packet carries (its own and its copies'), if
    /// it is an input packet: what the emulators count.
    pub fn input_ticks(bytes: &[u8]) -> Option<(u32, impl Iterator<Item = u32> + '_)> {
        if bytes.len() < INPUT_BYTES || bytes[27] & 0b111 != 0 {
            return None;
        }
        let tick = u32_at(bytes, 28);
        let copies = bytes[INPUT_BYTES..]
            .chunks_exact(COPY_BYTES)
            .map(move |r| tick.wrapping_sub(u32::from(u16_at(r, 0))));
        Some((tick, copies))
    }

    /// Decodes and checks the structure of a received datagram.
    pub fn decode(bytes: &[u8]) -> Result<Packet, Malformed> {
        let b = bytes;
        let length_ok = if b.len() >= PACKET_BYTES && b[27] & 0b111 == 0 {
            let extra = b.len().saturating_sub(INPUT_BYTES);
            b.len() >= INPUT_BYTES && extra % COPY_BYTES == 0 && extra / COPY_BYTES <= MAX_COPIES
        } else {
            b.len() == PACKET_BYTES
        };
        if !length_ok {
            return Err(Malformed::WrongLength);
        }
        if b[26] != VERSION {
            return Err(Malformed::BadVersion);
        }
        if b[27] & 0xF0 != 0 {
            return Err(Malformed::ReservedBits);
        }
        if crc_of(b) != u16_at(b, 38) {
            return Err(Malformed::BadCrc);
        }
        let message = match b[27] & 0b111 {
            0 => decode_input(b)?,
            1 => decode_hello(b)?,
            2 => decode_ack(b)?,
            3 => decode_bye(b)?,
            4 => decode_state(b)?,
            _ => return Err(Malformed::UnknownValue),
        };
        Ok(Packet {
            site: (b[27] >> 3) & 1,
            message,
        })
    }

    /// The checks that need the session's mesh: indices inside it, the
    /// node a grippable vertex of the tetrahedron, a state of the mesh's
    /// node count.
    pub fn check_against(&self, geometry: &ContactGeometry, nodes: usize) -> Result<(), Malformed> {
        let grip_ok = |m: &Manipulation| -> Result<(), Malformed> {
            if let Some(g) = m.grip {
                let (tet, node) = (usize::from(g.tet), usize::from(g.node));
                if tet >= geometry.tet_count() || node >= nodes {
                    return Err(Malformed::IndexOutOfRange);
                }
                if !geometry.tet_has_node(tet, node) || !geometry.grippable(node) {
                    return Err(Malformed::BadGrip);
                }
            }
            Ok(())
        };
        match &self.message {
            Message::Input { input, copies, .. } => {
                grip_ok(input)?;
                for (_, c) in copies.as_slice() {
                    grip_ok(c)?;
                }
            }
            Message::State { chunk, .. } => {
                let count = match chunk {
                    StateChunk::Node { count, .. } | StateChunk::Summary { count, .. } => *count,
                };
                if usize::from(count) != nodes {
                    return Err(Malformed::IndexOutOfRange);
                }
            }
            _ => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn coordinate() -> impl Strategy<Value = f64> {
        // Any finite f64, signed zeros and subnormals included.
        any::<f64>().prop_filter("finite", |c| c.is_finite())
    }

    fn v3() -> impl Strategy<Value = V3> {
        (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| V3::new(x, y, z))
    }

    fn acks() -> impl Strategy<Value = Acks> {
        (any::<u16>(), any::<u16>()).prop_map(|(ack, sack)| Acks { ack, sack })
    }

    fn report() -> impl Strategy<Value = SackReport> {
        (
            proptest::collection::vec((1u16..200, 1u16..200), 0..=MAX_BLOCKS),
            0u16..100,
        )
            .prop_map(|(runs, extra)| {
                let mut r = SackReport::default();
                let mut at = 0u16;
                for (k, (gap, len)) in runs.iter().enumerate() {
                    let start = at + gap;
                    r.blocks[k] = (start, start + len);
                    at = start + len;
                }
                r.count = runs.len() as u8;
                r.frontier = at + extra;
                r
            })
    }

    fn fields() -> impl Strategy<Value = SessionFields> {
        (
            any::<u16>(),
            any::<u16>(),
            coordinate(),
            coordinate(),
            coordinate(),
            coordinate(),
        )
            .prop_map(|(level, tick_us, a, b, c, d)| SessionFields {
                level,
                tick_us,
                side_m: a,
                stiffness_modulus_pa: b,
                damping_modulus_pa_s: c,
                density_kg_m3: d,
            })
    }

    fn hello() -> impl Strategy<Value = Hello> {
        let stage = prop_oneof![
            proptest::option::of(0u32..NO_TICK).prop_map(|t| Stage::Hello { committed_tick: t }),
            any::<u32>().prop_map(|t| Stage::StateFollows { state_tick: t }),
            any::<u32>().prop_map(|t| Stage::StateReceived { state_tick: t }),
            any::<i32>().prop_map(|c| Stage::Go { clock_us: c }),
        ];
        let echo = proptest::option::of(
            (any::<u16>(), 0u16..0xFFFF).prop_map(|(serial, hold_us)| Echo { serial, hold_us }),
        );
        (
            stage,
            any::<u16>(),
            echo,
            fields(),
            any::<u64>(),
            any::<u32>(),
        )
            .prop_map(|(stage, serial, echo, fields, config_hash, nonce)| Hello {
                stage,
                serial,
                echo,
                fields,
                config_hash,
                nonce,
            })
    }

    fn reason() -> impl Strategy<Value = ByeReason> {
        prop_oneof![
            Just(ByeReason::Duration),
            Just(ByeReason::User),
            Just(ByeReason::Peer),
            Just(ByeReason::Failure)
        ]
    }

    fn bye() -> impl Strategy<Value = Bye> {
        prop_oneof![
            reason().prop_map(Bye::Stopping),
            (reason(), any::<u64>(), any::<u64>()).prop_map(|(reason, end_tick, state_hash)| {
                Bye::Done {
                    reason,
                    end_tick,
                    state_hash,
                }
            }),
        ]
    }

    fn chunk() -> impl Strategy<Value = StateChunk> {
        prop_oneof![
            (1u16..0xFFFF, any::<u16>(), v3(), v3()).prop_map(|(count, i, x_m, v_m_s)| {
                StateChunk::Node {
                    index: i % count,
                    count,
                    x_m,
                    v_m_s,
                }
            }),
            (1u16..0xFFFF, any::<u64>(), any::<i64>()).prop_map(|(count, state_hash, clock_us)| {
                StateChunk::Summary {
                    count,
                    state_hash,
                    clock_us,
                }
            }),
        ]
    }

    fn manipulation() -> impl Strategy<Value = Manipulation> {
        (
            v3(),
            proptest::option::of((0u16..0xFFFF, 0u16..0xFFFF, v3())),
        )
            .prop_map(|(tip_m, g)| Manipulation {
                tip_m,
                grip: g.map(|(tet, node, node_m)| Grip { tet, node, node_m }),
            })
    }

    /// An input of `tick` with copies of some of the 16 ticks before it.
    fn input_message() -> impl Strategy<Value = Message> {
        (
            any::<u32>(),
            acks(),
            manipulation(),
            proptest::collection::vec((any::<bool>(), manipulation()), MAX_COPIES),
            (
                any::<u32>(),
                proptest::option::of((any::<u32>(), 0..NO_ECHO)),
            ),
        )
            .prop_map(|(tick, acks, input, pick, (sent_us, echo))| {
                let mut copies = Copies::none();
                for (back, (keep, m)) in (1..=MAX_COPIES as u32).rev().zip(pick) {
                    if keep && back <= tick {
                        copies.push(tick - back, m);
                    }
                }
                let echo = echo.map(|(sent_us, hold_us)| StampEcho { sent_us, hold_us });
                Message::Input {
                    tick,
                    acks,
                    input,
                    stamp: Stamp { sent_us, echo },
                    copies,
                }
            })
    }

    fn message() -> impl Strategy<Value = Message> {
        prop_oneof![
            input_message(),
            hello().prop_map(Message::Hello),
            (any::<u32>(), acks(), report()).prop_map(|(from, acks, report)| Message::Ack {
                from,
                acks,
                report
            }),
            (any::<u32>(), acks(), bye()).prop_map(|(next_tick, acks, bye)| Message::Bye {
                next_tick,
                acks,
                bye
            }),
            (any::<u32>(), chunk()).prop_map(|(tick, chunk)| Message::State { tick, chunk }),
        ]
    }

    fn packet() -> impl Strategy<Value = Packet> {
        (0u8..2, message()).prop_map(|(site, message)| Packet { site, message })
    }

    /// Bit-exact equality (f64 `==` would call 0.0 and −0.0 equal).
    fn same_bits(a: &Packet, b: &Packet) -> bool {
        a.encode() == b.encode() && format!("{a:?}") == format!("{b:?}")
    }

    fn reseal(mut b: Vec<u8>) -> Vec<u8> {
        let crc = crc_of(&b);
        b[38..40].copy_from_slice(&crc.to_le_bytes());
        b
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

        #[test]
        fn every_packet_is_64_bytes_and_round_trips_bit_exactly(p in packet()) {
            let b = p.encode();
            let len = match &p.message {
                Message::Input { copies, .. } => INPUT_BYTES + COPY_BYTES * copies.len(),
                _ => PACKET_BYTES,
            };
            prop_assert_eq!(b.len(), len);
            let q = Packet::decode(&b).unwrap();
            prop_assert!(same_bits(&p, &q), "{:?} vs {:?}", p, q);
            prop_assert_eq!(p, q);
        }

        #[test]
        fn arbitrary_bytes_are_refused_with_a_reason_or_are_canonical(
            bytes in proptest::collection::vec(any::<u8>(), 0..200)
        ) {
            let mut stats = DecodeStats::default();
            match Packet::decode(&bytes) {
                Ok(p) => prop_assert_eq!(&p.encode()[..], &bytes[..]),
                Err(why) => {
                    stats.record(why);
                    prop_assert_eq!(stats.total(), 1);
                    prop_assert_eq!(stats.count(why), 1);
                }
            }
        }

        #[test]
        fn a_packet_with_a_valid_crc_but_a_broken_field_is_refused(
            p in packet(), at in 0usize..MAX_DATAGRAM_BYTES, value in any::<u8>()
        ) {
            // Change any byte, then repair the CRC: what remains is refused
            // for its structure unless it is again a canonical packet.
            let mut b = p.encode();
            let at = at % b.len();
            b[at] = value;
            if let Ok(q) = Packet::decode(&reseal(b.clone())) {
                prop_assert_eq!(q.encode(), reseal(b));
            }
        }
    }

    fn input_packet() -> Packet {
        Packet {
            site: 1,
            message: Message::Input {
                tick: 123_456,
                copies: Copies::none(),
                stamp: Stamp {
                    sent_us: 4_000_000_123,
                    echo: Some(StampEcho {
                        sent_us: 77,
                        hold_us: 310,
                    }),
                },
                acks: Acks {
                    ack: 7,
                    sack: 0b1010,
                },
                input: Manipulation {
                    tip_m: V3::new(0.021, 0.033, 0.0598),
                    grip: Some(Grip {
                        tet: 1234,
                        node: 321,
                        node_m: V3::new(0.0225, 0.03, 0.0598),
                    }),
                },
            },
        }
    }

    #[test]
    fn every_one_and_two_bit_error_is_caught() {
        let b = input_packet().encode();
        let mut stats = DecodeStats::default();
        let mut tried = 0;
        for i in 0..512 {
            for j in i..512 {
                let mut c = b.clone();
                c[i / 8] ^= 1 << (i % 8);
                if j != i {
                    c[j / 8] ^= 1 << (j % 8);
                }
                let why = Packet::decode(&c).expect_err("corruption accepted");
                stats.record(why);
                tried += 1;
            }
        }
        assert_eq!(stats.total(), tried);
        // A flipped version byte is refused as a version before the CRC.
        assert!(stats.count(Malformed::BadVersion) > 0);
        assert!(stats.count(Malformed::BadCrc) > 100_000);
    }

    #[test]
    fn named_refusals() {
        let ok = Packet {
            site: 0,
            message: Message::Ack {
                from: 5,
                acks: Acks::default(),
                report: SackReport::default(),
            },
        }
        .encode();
        assert_eq!(Packet::decode(&ok[..63]), Err(Malformed::WrongLength));
        let mut v = ok.clone();
        v[26] = 1;
        assert_eq!(Packet::decode(&v), Err(Malformed::BadVersion));
        let mut r = ok.clone();
        r[27] |= 0x80;
        assert_eq!(Packet::decode(&r), Err(Malformed::ReservedBits));
        let mut k = ok.clone();
        k[27] = 5;
        assert_eq!(Packet::decode(&reseal(k)), Err(Malformed::UnknownValue));
        let mut n = ok.clone();
        n[50] = 1;
        assert_eq!(Packet::decode(&reseal(n)), Err(Malformed::NonCanonical));
        // A block that starts at the missing tick, one past the frontier,
        // two that touch, a count above 12.
        for (count, blocks, frontier) in [
            (1u16, [(0u16, 3u16), (0, 0)], 10u16),
            (1, [(2, 11), (0, 0)], 10),
            (2, [(1, 3), (3, 5)], 10),
            (13, [(0, 0), (0, 0)], 10),
        ] {
            let mut a = ok.clone();
            a[24..26].copy_from_slice(&count.to_le_bytes());
            a[32..34].copy_from_slice(&frontier.to_le_bytes());
            for (k, (s, e)) in blocks.iter().enumerate() {
                a[4 * k..4 * k + 2].copy_from_slice(&s.to_le_bytes());
                a[4 * k + 2..4 * k + 4].copy_from_slice(&e.to_le_bytes());
            }
            assert_eq!(
                Packet::decode(&reseal(a)),
                Err(Malformed::BadBlocks),
                "{blocks:?}"
            );
        }
        let input = input_packet().encode();
        let mut nan = input.clone();
        nan[0..8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_eq!(Packet::decode(&reseal(nan)), Err(Malformed::NonFinite));
        let mut half = input.clone();
        half[32..34].copy_from_slice(&NONE_INDEX.to_le_bytes());
        assert_eq!(
            Packet::decode(&reseal(half)),
            Err(Malformed::InconsistentGrip)
        );
        // Copies: a record that is not a whole 56 bytes, copies on a
        // packet that is not an input, a copy 0 or 17 ticks back, two
        // copies out of order.
        let mut one = input_packet();
        if let Message::Input { copies, .. } = &mut one.message {
            copies.push(123_450, Manipulation::free(V3::zeros()));
        }
        let one = one.encode();
        assert_eq!(one.len(), INPUT_BYTES + COPY_BYTES);
        assert!(Packet::decode(&one).is_ok());
        assert_eq!(Packet::decode(&one[..100]), Err(Malformed::WrongLength));
        let mut long_ack = ok.clone();
        long_ack.extend_from_slice(&[0u8; COPY_BYTES]);
        assert_eq!(Packet::decode(&long_ack), Err(Malformed::WrongLength));
        for back in [0u16, 17] {
            let mut c = one.clone();
            c[INPUT_BYTES..INPUT_BYTES + 2].copy_from_slice(&back.to_le_bytes());
            assert_eq!(Packet::decode(&reseal(c)), Err(Malformed::BadCopies));
        }
        let mut two = one.clone();
        two.extend_from_slice(&one[INPUT_BYTES..]);
        assert_eq!(Packet::decode(&reseal(two)), Err(Malformed::BadCopies));
        // The stamp: an input of version 3's 64 bytes has none; "no echo"
        // (hold 0xFFFFFFFF) with an echoed time is not canonical; the
        // stamp is where the page puts it.
        assert_eq!(
            Packet::decode(&input[..PACKET_BYTES]),
            Err(Malformed::WrongLength)
        );
        assert_eq!(
            u32::from_le_bytes(input[64..68].try_into().unwrap()),
            4_000_000_123
        );
        assert_eq!(u32::from_le_bytes(input[68..72].try_into().unwrap()), 77);
        assert_eq!(u32::from_le_bytes(input[72..76].try_into().unwrap()), 310);
        let mut none = input.clone();
        none[72..76].copy_from_slice(&NO_ECHO.to_le_bytes());
        assert_eq!(
            Packet::decode(&reseal(none.clone())),
            Err(Malformed::NonCanonical)
        );
        none[68..72].copy_from_slice(&[0; 4]);
        assert!(Packet::decode(&reseal(none)).is_ok());
        // The CRC covers the copies.
        let mut flipped = one.clone();
        flipped[100] ^= 1;
        assert_eq!(Packet::decode(&flipped), Err(Malformed::BadCrc));
        assert_eq!(Malformed::BadCrc.to_string(), "CRC mismatch");
        let stats = DecodeStats::default();
        assert_eq!(stats.by_reason().count(), Malformed::ALL.len());
    }

    #[test]
    fn mismatched_fields_are_named_and_change_the_hash() {
        let a = SessionFields {
            level: 6,
            tick_us: TICK_US,
            side_m: 0.06,
            stiffness_modulus_pa: 20e3,
            damping_modulus_pa_s: 30.0,
            density_kg_m3: 1000.0,
        };
        assert!(a.mismatches(&a).is_empty());
        let b = SessionFields {
            level: 5,
            density_kg_m3: 1001.0,
            ..a
        };
        let named = a.mismatches(&b);
        assert_eq!(named.len(), 2, "{named:?}");
        assert!(
            named[0].starts_with("level: ours 6, the peer's 5"),
            "{named:?}"
        );
        assert!(named[1].starts_with("density_kg_m3"), "{named:?}");
        assert_ne!(a.hash(), b.hash());
        // −0.0 and 0.0 are different bits: a different configuration.
        let z = SessionFields { side_m: -0.0, ..a };
        let w = SessionFields { side_m: 0.0, ..a };
        assert_eq!(z.mismatches(&w).len(), 1);
        assert_ne!(z.hash(), w.hash());
        // FNV-1a's published test vectors: "" and "a".
        assert_eq!(fnv1a(b""), 0xcbf2_9ce4_8422_2325);
        assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn grips_and_states_are_checked_against_the_mesh() {
        use crate::model::mesh::CubeMesh;
        use crate::model::voigt::{VoigtMaterial, VoigtModel};
        let model =
            VoigtModel::new(CubeMesh::new(3, 0.06).unwrap(), VoigtMaterial::default()).unwrap();
        let g = ContactGeometry::of(&model);
        let n = model.mesh().node_count();
        let with = |tet: u16, node: u16| Packet {
            site: 0,
            message: Message::Input {
                tick: 0,
                acks: Acks::default(),
                stamp: Stamp::default(),
                copies: Copies::none(),
                input: Manipulation {
                    tip_m: V3::zeros(),
                    grip: Some(Grip {
                        tet,
                        node,
                        node_m: V3::zeros(),
                    }),
                },
            },
        };
        // A top-face node and a tetrahedron that has it.
        let top = model.mesh().nearest_node(V3::new(0.03, 0.03, 0.06));
        let tets = &model.mesh().tets;
        let holding = |node: usize, has: bool| {
            tets.iter()
                .position(|t| t.contains(&(node as u32)) == has)
                .unwrap() as u16
        };
        assert_eq!(
            with(holding(top, true), top as u16).check_against(&g, n),
            Ok(())
        );
        assert_eq!(
            with(48, 0).check_against(&g, n),
            Err(Malformed::IndexOutOfRange)
        );
        assert_eq!(
            with(0, 27).check_against(&g, n),
            Err(Malformed::IndexOutOfRange)
        );
        assert_eq!(
            with(holding(top, false), top as u16).check_against(&g, n),
            Err(Malformed::BadGrip)
        );
        // A support node (z = 0) may not be held.
        let bottom = model.mesh().nearest_node(V3::zeros());
        assert_eq!(
            with(holding(bottom, true), bottom as u16).check_against(&g, n),
            Err(Malformed::BadGrip)
        );
        // A state of another mesh's size.
        let state = |count: u16| Packet {
            site: 0,
            message: Message::State {
                tick: 9,
                chunk: StateChunk::Summary {
                    count,
                    state_hash: 1,
                    clock_us: 2,
                },
            },
        };
        assert_eq!(state(n as u16).check_against(&g, n), Ok(()));
        assert_eq!(
            state(n as u16 + 1).check_against(&g, n),
            Err(Malformed::IndexOutOfRange)
        );
    }
}
