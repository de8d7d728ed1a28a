//! The 64-byte manipulation packet, laid out as the seed lays it out
//! (Yamaguchi §5.1, seed 000 L2650–2655): the stylus tip (8 B × 3), the
//! tetrahedron ID held by the user (8 B), the node ID manipulated by the
//! user (8 B) and that node's position (8 B × 3): 24 + 8 + 8 + 24 = 64
//! bytes.
//!
//! `docs/tetmsd-packet.md` specifies it for other implementations (held to
//! this code by `plant-models/tests/tetmsd_packet_doc.rs`).
//!
//! The seed gives no header. The two ID fields are 64-bit words whose
//! indices need 16 bits (the largest mesh here has 24,576 tetrahedra), so
//! the header lives in their upper bytes and the packet stays exactly 64
//! bytes with every field where the paper puts it. All numbers are
//! little-endian:
//!
//! | bytes | field |
//! |---|---|
//! | 0–7, 8–15, 16–23 | stylus tip x, y, z: f64, metres (a `Hello` carries the configuration hash, u64, in 0–7 and zeros in 8–23) |
//! | 24–25 | tetrahedron index, u16; `0xFFFF` = no contact |
//! | 26 | protocol version, u8: [`VERSION`] |
//! | 27 | bits 0–1 message kind (0 input, 1 hello, 2 ack, 3 bye), bit 2 sending site (0 or 1), bits 3–7 zero |
//! | 28–31 | sequence number, u32: the sender's 1 kHz tick this input belongs to (for ack/bye: its next tick) |
//! | 32–33 | node index, u16; `0xFFFF` = no contact |
//! | 34–35 | ack: low 16 bits of the number of the peer's ticks received without a gap |
//! | 36–37 | selective ack: bit b set = the peer's tick ack + 1 + b has arrived |
//! | 38–39 | CRC-16/IBM-3740 (CCITT-FALSE: poly 0x1021, init 0xFFFF) of bytes 0–37 and 40–63 |
//! | 40–47, 48–55, 56–63 | held node x, y, z: f64, metres (zeros without contact) |
//!
//! Decoding refuses, and names, every packet that is not exactly what the
//! encoder would write: a wrong length, another version, set reserved
//! bits, a bad CRC, a non-finite coordinate, a tetrahedron without a node
//! (or the reverse), and non-zero bytes where a message has none
//! ([`Malformed`]); [`DecodeStats`] counts the refusals by reason. Because
//! the format is canonical, `encode(decode(b)) == b` for every accepted
//! `b`. The mesh-dependent checks (index inside the mesh, node a vertex of
//! the tetrahedron, node off the support) are [`Packet::check_against`].
use crate::model::probe::{ContactGeometry, Grip, Manipulation};
use crate::model::V3;
use crc::{Crc, CRC_16_IBM_3740};
use std::fmt;

/// Bytes in a packet.
pub const PACKET_BYTES: usize = 64;
/// The protocol version this code speaks.
pub const VERSION: u8 = 1;
/// "No tetrahedron" / "no node" in an index field.
pub const NONE_INDEX: u16 = 0xFFFF;

const CRC16: Crc<u16> = Crc::<u16>::new(&CRC_16_IBM_3740);

/// What a packet says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Message {
    /// The sender's manipulation for tick `seq`.
    Input(Manipulation),
    /// Start of a session: the sender's configuration hash (mesh level,
    /// material, cube): both sites must run the same model.
    Hello {
        /// Hash of the sender's configuration.
        config_hash: u64,
    },
    /// Acknowledgements only (a sender with no new input).
    Ack,
    /// The sender has everything it needs and everything it sent was
    /// acknowledged: it is about to leave.
    Bye,
}

/// A decoded packet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Packet {
    /// Sending site, 0 or 1.
    pub site: u8,
    /// Sequence number (see the table in the module docs).
    pub seq: u32,
    /// Low 16 bits of the count of the peer's ticks received without a gap.
    pub ack: u16,
    /// Selective acknowledgements after `ack` (bit b: tick ack + 1 + b).
    pub sack: u16,
    /// The message.
    pub message: Message,
}

/// Why a packet was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Malformed {
    /// Not 64 bytes.
    WrongLength,
    /// Another protocol version.
    BadVersion,
    /// Reserved bits set (kind byte bits 3–7).
    ReservedBits,
    /// The CRC does not match.
    BadCrc,
    /// A coordinate is NaN or infinite.
    NonFinite,
    /// A tetrahedron without a node or a node without a tetrahedron.
    InconsistentGrip,
    /// Bytes a message does not use are not zero.
    NonCanonical,
    /// The tetrahedron or node index is outside this session's mesh.
    IndexOutOfRange,
    /// The node is not a vertex of the tetrahedron, or may not be held
    /// (inside the object or on the support).
    BadGrip,
    /// The sending site is this site or the hello's configuration differs.
    WrongPeer,
}

impl Malformed {
    /// Every reason, in [`DecodeStats`] order.
    pub const ALL: [Malformed; 10] = [
        Malformed::WrongLength,
        Malformed::BadVersion,
        Malformed::ReservedBits,
        Malformed::BadCrc,
        Malformed::NonFinite,
        Malformed::InconsistentGrip,
        Malformed::NonCanonical,
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
            Malformed::NonFinite => "non_finite",
            Malformed::InconsistentGrip => "inconsistent_grip",
            Malformed::NonCanonical => "non_canonical",
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
            Malformed::WrongLength => "not 64 bytes long",
            Malformed::BadVersion => "another protocol version",
            Malformed::ReservedBits => "reserved bits set",
            Malformed::BadCrc => "CRC mismatch",
            Malformed::NonFinite => "a coordinate is not finite",
            Malformed::InconsistentGrip => {
                "a tetrahedron without a node or a node without a tetrahedron"
            }
            Malformed::NonCanonical => "unused bytes are not zero",
            Malformed::IndexOutOfRange => "tetrahedron or node outside the mesh",
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
    counts: [u64; 10],
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
    let c = |k: usize| {
        let mut w = [0u8; 8];
        w.copy_from_slice(&b[8 * k..8 * k + 8]);
        f64::from_le_bytes(w)
    };
    V3::new(c(0), c(1), c(2))
}

fn crc_of(b: &[u8; PACKET_BYTES]) -> u16 {
    let mut d = CRC16.digest();
    d.update(&b[..38]);
    d.update(&b[40..]);
    d.finalize()
}

impl Packet {
    /// The 64 bytes of this packet.
    pub fn encode(&self) -> [u8; PACKET_BYTES] {
        let mut b = [0u8; PACKET_BYTES];
        let (kind, tet, node) = match &self.message {
            Message::Input(m) => {
                put_f64s(&mut b[0..24], m.tip_m);
                match m.grip {
                    Some(g) => {
                        put_f64s(&mut b[40..64], g.node_m);
                        (0u8, g.tet, g.node)
                    }
                    None => (0, NONE_INDEX, NONE_INDEX),
                }
            }
            Message::Hello { config_hash } => {
                b[0..8].copy_from_slice(&config_hash.to_le_bytes());
                (1, NONE_INDEX, NONE_INDEX)
            }
            Message::Ack => (2, NONE_INDEX, NONE_INDEX),
            Message::Bye => (3, NONE_INDEX, NONE_INDEX),
        };
        b[24..26].copy_from_slice(&tet.to_le_bytes());
        b[26] = VERSION;
        b[27] = kind | ((self.site & 1) << 2);
        b[28..32].copy_from_slice(&self.seq.to_le_bytes());
        b[32..34].copy_from_slice(&node.to_le_bytes());
        b[34..36].copy_from_slice(&self.ack.to_le_bytes());
        b[36..38].copy_from_slice(&self.sack.to_le_bytes());
        let crc = crc_of(&b);
        b[38..40].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Decodes and checks the structure of a received datagram.
    pub fn decode(bytes: &[u8]) -> Result<Packet, Malformed> {
        let b: &[u8; PACKET_BYTES] = bytes.try_into().map_err(|_| Malformed::WrongLength)?;
        if b[26] != VERSION {
            return Err(Malformed::BadVersion);
        }
        if b[27] & !0b111 != 0 {
            return Err(Malformed::ReservedBits);
        }
        if crc_of(b) != u16::from_le_bytes([b[38], b[39]]) {
            return Err(Malformed::BadCrc);
        }
        let u16_at = |k: usize| u16::from_le_bytes([b[k], b[k + 1]]);
        let (tet, node) = (u16_at(24), u16_at(32));
        let zero = |r: std::ops::Range<usize>| b[r].iter().all(|&x| x == 0);
        let message = match b[27] & 0b11 {
            0 => {
                let tip_m = get_f64s(&b[0..24]);
                if !tip_m.iter().all(|c| c.is_finite()) {
                    return Err(Malformed::NonFinite);
                }
                let grip = match (tet == NONE_INDEX, node == NONE_INDEX) {
                    (true, true) => {
                        if !zero(40..64) {
                            return Err(Malformed::NonCanonical);
                        }
                        None
                    }
                    (false, false) => {
                        let node_m = get_f64s(&b[40..64]);
                        if !node_m.iter().all(|c| c.is_finite()) {
                            return Err(Malformed::NonFinite);
                        }
                        Some(Grip { tet, node, node_m })
                    }
                    _ => return Err(Malformed::InconsistentGrip),
                };
                Message::Input(Manipulation { tip_m, grip })
            }
            kind => {
                if tet != NONE_INDEX || node != NONE_INDEX || !zero(40..64) {
                    return Err(Malformed::NonCanonical);
                }
                match kind {
                    1 => {
                        if !zero(8..24) {
                            return Err(Malformed::NonCanonical);
                        }
                        let mut h = [0u8; 8];
                        h.copy_from_slice(&b[0..8]);
                        Message::Hello {
                            config_hash: u64::from_le_bytes(h),
                        }
                    }
                    _ if !zero(0..24) => return Err(Malformed::NonCanonical),
                    2 => Message::Ack,
                    _ => Message::Bye,
                }
            }
        };
        Ok(Packet {
            site: (b[27] >> 2) & 1,
            seq: u32::from_le_bytes([b[28], b[29], b[30], b[31]]),
            ack: u16_at(34),
            sack: u16_at(36),
            message,
        })
    }

    /// The checks that need the session's mesh: indices inside it, the
    /// node a grippable vertex of the tetrahedron.
    pub fn check_against(&self, geometry: &ContactGeometry, nodes: usize) -> Result<(), Malformed> {
        if let Message::Input(Manipulation { grip: Some(g), .. }) = &self.message {
            let (tet, node) = (usize::from(g.tet), usize::from(g.node));
            if tet >= geometry.tet_count() || node >= nodes {
                return Err(Malformed::IndexOutOfRange);
            }
            if !geometry.tet_has_node(tet, node) || !geometry.grippable(node) {
                return Err(Malformed::BadGrip);
            }
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

    fn message() -> impl Strategy<Value = Message> {
        prop_oneof![
            (
                v3(),
                proptest::option::of((0u16..0xFFFF, 0u16..0xFFFF, v3()))
            )
                .prop_map(|(tip_m, g)| Message::Input(Manipulation {
                    tip_m,
                    grip: g.map(|(tet, node, node_m)| Grip { tet, node, node_m }),
                })),
            any::<u64>().prop_map(|config_hash| Message::Hello { config_hash }),
            Just(Message::Ack),
            Just(Message::Bye),
        ]
    }

    fn packet() -> impl Strategy<Value = Packet> {
        (0u8..2, any::<u32>(), any::<u16>(), any::<u16>(), message()).prop_map(
            |(site, seq, ack, sack, message)| Packet {
                site,
                seq,
                ack,
                sack,
                message,
            },
        )
    }

    /// Bit-exact equality (f64 `==` would call 0.0 and −0.0 equal).
    fn same_bits(a: &Packet, b: &Packet) -> bool {
        a.encode() == b.encode() && format!("{a:?}") == format!("{b:?}")
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

        #[test]
        fn every_packet_is_64_bytes_and_round_trips_bit_exactly(p in packet()) {
            let b = p.encode();
            prop_assert_eq!(b.len(), PACKET_BYTES);
            let q = Packet::decode(&b).unwrap();
            prop_assert!(same_bits(&p, &q), "{:?} vs {:?}", p, q);
            if let (Message::Input(m), Message::Input(n)) = (p.message, q.message) {
                for (x, y) in m.tip_m.iter().zip(n.tip_m.iter()) {
                    prop_assert_eq!(x.to_bits(), y.to_bits());
                }
            }
        }

        #[test]
        fn arbitrary_bytes_are_refused_with_a_reason_or_are_canonical(
            bytes in proptest::collection::vec(any::<u8>(), 0..130)
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
            p in packet(), at in 0usize..64, value in any::<u8>()
        ) {
            // Change any byte, then repair the CRC: what remains is refused
            // for its structure unless it is again a canonical packet.
            let mut b = p.encode();
            b[at] = value;
            let crc = crc_of(&b);
            b[38..40].copy_from_slice(&crc.to_le_bytes());
            if let Ok(q) = Packet::decode(&b) {
                prop_assert_eq!(q.encode(), b);
            }
        }
    }

    #[test]
    fn every_one_and_two_bit_error_is_caught() {
        let p = Packet {
            site: 1,
            seq: 123_456,
            ack: 7,
            sack: 0b1010,
            message: Message::Input(Manipulation {
                tip_m: V3::new(0.021, 0.033, 0.0598),
                grip: Some(Grip {
                    tet: 1234,
                    node: 321,
                    node_m: V3::new(0.0225, 0.03, 0.0598),
                }),
            }),
        };
        let b = p.encode();
        let mut stats = DecodeStats::default();
        let mut tried = 0;
        for i in 0..512 {
            for j in i..512 {
                let mut c = b;
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
            seq: 5,
            ack: 0,
            sack: 0,
            message: Message::Ack,
        }
        .encode();
        assert_eq!(Packet::decode(&ok[..63]), Err(Malformed::WrongLength));
        let mut v = ok;
        v[26] = 2;
        assert_eq!(Packet::decode(&v), Err(Malformed::BadVersion));
        let resealed = |mut b: [u8; 64]| {
            let crc = crc_of(&b);
            b[38..40].copy_from_slice(&crc.to_le_bytes());
            b
        };
        let mut r = ok;
        r[27] |= 0x80;
        assert_eq!(Packet::decode(&r), Err(Malformed::ReservedBits));
        let mut n = ok;
        n[3] = 1;
        assert_eq!(Packet::decode(&resealed(n)), Err(Malformed::NonCanonical));
        let input = Packet {
            message: Message::Input(Manipulation::free(V3::new(1.0, 2.0, 3.0))),
            ..Packet::decode(&ok).unwrap()
        }
        .encode();
        let mut nan = input;
        nan[0..8].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_eq!(Packet::decode(&resealed(nan)), Err(Malformed::NonFinite));
        let mut half = input;
        half[24..26].copy_from_slice(&3u16.to_le_bytes());
        assert_eq!(
            Packet::decode(&resealed(half)),
            Err(Malformed::InconsistentGrip)
        );
        assert_eq!(Malformed::BadCrc.to_string(), "CRC mismatch");
        let stats = DecodeStats::default();
        assert_eq!(stats.by_reason().count(), Malformed::ALL.len());
    }

    #[test]
    fn grips_are_checked_against_the_mesh() {
        use crate::model::mesh::CubeMesh;
        use crate::model::voigt::{VoigtMaterial, VoigtModel};
        let model = crate::model::voigt::VoigtModel::new(
            CubeMesh::new(3, 0.06).unwrap(),
            VoigtMaterial::default(),
        )
        .unwrap();
        let _: &VoigtModel = &model;
        let g = ContactGeometry::of(&model);
        let n = model.mesh().node_count();
        let with = |tet: u16, node: u16| Packet {
            site: 0,
            seq: 0,
            ack: 0,
            sack: 0,
            message: Message::Input(Manipulation {
                tip_m: V3::zeros(),
                grip: Some(Grip {
                    tet,
                    node,
                    node_m: V3::zeros(),
                }),
            }),
        };
        // A top-face node and a tetrahedron that has it.
        let top = model.mesh().nearest_node(V3::new(0.03, 0.03, 0.06));
        let tet = model
            .mesh()
            .tets
            .iter()
            .position(|t| t.contains(&(top as u32)))
            .unwrap();
        assert_eq!(with(tet as u16, top as u16).check_against(&g, n), Ok(()));
        assert_eq!(
            with(48, 0).check_against(&g, n),
            Err(Malformed::IndexOutOfRange)
        );
        assert_eq!(
            with(0, 27).check_against(&g, n),
            Err(Malformed::IndexOutOfRange)
        );
        let other = model
            .mesh()
            .tets
            .iter()
            .position(|t| !t.contains(&(top as u32)))
            .unwrap();
        assert_eq!(
            with(other as u16, top as u16).check_against(&g, n),
            Err(Malformed::BadGrip)
        );
        // A support node (z = 0) may not be held.
        let bottom = model.mesh().nearest_node(V3::zeros());
        let t0 = model
            .mesh()
            .tets
            .iter()
            .position(|t| t.contains(&(bottom as u32)))
            .unwrap();
        assert_eq!(
            with(t0 as u16, bottom as u16).check_against(&g, n),
            Err(Malformed::BadGrip)
        );
    }
}
