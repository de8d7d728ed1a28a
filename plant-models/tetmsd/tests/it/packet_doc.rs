//! `docs/tetmsd-packet.md` says what the codec does: every example packet
//! on the page is the encoder's bytes (and decodes back to the same
//! packet), the configuration-hash input and hash are what the code
//! computes, and the page names every field at the bytes the code uses.
//! Change the codec and the page together.
use plant_tetmsd::model::probe::{Grip, Manipulation};
use plant_tetmsd::model::voigt::State;
use plant_tetmsd::model::V3;
use plant_tetmsd::packet::{
    fnv1a, Acks, Bye, ByeReason, Copies, Echo, Hello, Message, Packet, SackReport, SessionFields,
    Stage, Stamp, StampEcho, StateChunk, COPY_BYTES, INPUT_BYTES, MAX_BLOCKS, PACKET_BYTES,
    SACK_MORE, TICK_US, VERSION,
};

fn doc() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/tetmsd-packet.md");
    std::fs::read_to_string(path).expect("docs/tetmsd-packet.md")
}

/// The default scenario's session: level 6, a 60 mm cube, κ 20 kPa,
/// η 30 Pa·s, 1000 kg/m³.
fn fields() -> SessionFields {
    SessionFields {
        level: 6,
        tick_us: TICK_US,
        side_m: 0.06,
        stiffness_modulus_pa: 20e3,
        damping_modulus_pa_s: 30.0,
        density_kg_m3: 1000.0,
    }
}

/// The ack example: site 0 has site 1's ticks below 5000, then 5001–5009
/// and 5012–5039 (5000, 5010 and 5011 are missing).
fn ack_example() -> Packet {
    let mut blocks = [(0u16, 0u16); MAX_BLOCKS];
    blocks[0] = (1, 10);
    blocks[1] = (12, 40);
    // Map bits b = offset − 1 for offsets 1–9 and 12–15; more beyond 15.
    let map = (0..9).chain(11..15).fold(0u16, |m, b| m | (1 << b));
    Packet {
        site: 0,
        message: Message::Ack {
            from: 5000,
            acks: Acks {
                ack: 5000,
                sack: map | SACK_MORE,
            },
            report: SackReport {
                frontier: 40,
                count: 2,
                blocks,
            },
        },
    }
}

/// The copies example: tick 1235 carries ticks 1233 (free, the tip at
/// 0.02, 0.03, 0.062) and 1234 (the input example's grip).
fn copies_example() -> Copies {
    let mut c = Copies::none();
    c.push(1233, Manipulation::free(V3::new(0.02, 0.03, 0.062)));
    c.push(
        1234,
        Manipulation {
            tip_m: V3::new(0.02, 0.03, 0.0595),
            grip: Some(Grip {
                tet: 377,
                node: 98,
                node_m: V3::new(0.015, 0.03, 0.0595),
            }),
        },
    );
    c
}

/// The example packets of the page, as the encoder writes them.
fn examples() -> Vec<(&'static str, Packet)> {
    let f = fields();
    vec![
        (
            "input",
            Packet {
                site: 1,
                message: Message::Input {
                    tick: 1234,
                    acks: Acks {
                        ack: 1229,
                        sack: 0b101,
                    },
                    input: Manipulation {
                        tip_m: V3::new(0.02, 0.03, 0.0595),
                        grip: Some(Grip {
                            tet: 377,
                            node: 98,
                            node_m: V3::new(0.015, 0.03, 0.0595),
                        }),
                    },
                    stamp: Stamp {
                        sent_us: 1_234_250,
                        echo: Some(StampEcho {
                            sent_us: 1_229_310,
                            hold_us: 420,
                        }),
                    },
                    copies: Copies::none(),
                },
            },
        ),
        (
            "input with copies",
            Packet {
                site: 1,
                message: Message::Input {
                    tick: 1235,
                    acks: Acks {
                        ack: 1229,
                        sack: 0b101,
                    },
                    input: Manipulation::free(V3::new(0.02, 0.03, 0.061)),
                    stamp: Stamp {
                        sent_us: 1_235_250,
                        echo: None,
                    },
                    copies: copies_example(),
                },
            },
        ),
        (
            "hello",
            Packet {
                site: 1,
                message: Message::Hello(Hello {
                    stage: Stage::Hello {
                        committed_tick: None,
                    },
                    serial: 1,
                    echo: None,
                    fields: f,
                    config_hash: f.hash(),
                    nonce: 0x1234_abcd,
                }),
            },
        ),
        (
            "go",
            Packet {
                site: 0,
                message: Message::Hello(Hello {
                    stage: Stage::Go { clock_us: -15_000 },
                    serial: 4,
                    echo: Some(Echo {
                        serial: 3,
                        hold_us: 120,
                    }),
                    fields: f,
                    config_hash: f.hash(),
                    nonce: 0x0bad_cafe,
                }),
            },
        ),
        ("ack", ack_example()),
        (
            "bye stopping",
            Packet {
                site: 1,
                message: Message::Bye {
                    next_tick: 60_000,
                    acks: Acks {
                        ack: 59_990u32 as u16,
                        sack: 0,
                    },
                    bye: Bye::Stopping(ByeReason::User),
                },
            },
        ),
        (
            "bye done",
            Packet {
                site: 0,
                message: Message::Bye {
                    next_tick: 60_000,
                    acks: Acks {
                        ack: 60_000u32 as u16,
                        sack: 0,
                    },
                    bye: Bye::Done {
                        reason: ByeReason::Peer,
                        end_tick: 60_000,
                        state_hash: 0x8877_6655_4433_2211,
                    },
                },
            },
        ),
        (
            "state node",
            Packet {
                site: 0,
                message: Message::State {
                    tick: 30_000,
                    chunk: StateChunk::Node {
                        index: 3,
                        count: 729,
                        x_m: V3::new(0.0225, 0.0, 0.0),
                        v_m_s: V3::new(0.0, 0.0, 0.0),
                    },
                },
            },
        ),
        (
            "state summary",
            Packet {
                site: 0,
                message: Message::State {
                    tick: 30_000,
                    chunk: StateChunk::Summary {
                        count: 729,
                        state_hash: 0x0123_4567_89ab_cdef,
                        clock_us: 30_512_345,
                    },
                },
            },
        ),
    ]
}

fn hex(b: &[u8]) -> String {
    b.chunks(8)
        .map(|c| {
            c.iter()
                .map(|x| format!("{x:02x}"))
                .collect::<Vec<_>>()
                .join(" ")
        })
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn the_example_packets_are_the_encoders_bytes() {
    let d = doc();
    for (name, p) in examples() {
        let bytes = p.encode();
        let len = match &p.message {
            Message::Input { copies, .. } => INPUT_BYTES + COPY_BYTES * copies.len(),
            _ => PACKET_BYTES,
        };
        assert_eq!(bytes.len(), len);
        let h = hex(&bytes);
        assert!(
            d.contains(&format!("```\n{h}\n```")),
            "docs/tetmsd-packet.md must show the {name} example as:\n{h}"
        );
        assert_eq!(Packet::decode(&bytes), Ok(p), "{name}");
    }
}

/// The page's hash input, written out independently of
/// `SessionFields::hash`, gives the page's hash; and the code's hash is
/// the same.
#[test]
fn the_configuration_hash_is_fnv1a_of_the_pages_37_bytes() {
    let d = doc();
    let f = fields();
    let mut input = vec![VERSION];
    input.extend_from_slice(&6u16.to_le_bytes());
    input.extend_from_slice(&1000u16.to_le_bytes());
    for v in [0.06f64, 20e3, 30.0, 1000.0] {
        input.extend_from_slice(&v.to_le_bytes());
    }
    assert_eq!(input.len(), 37);
    let shown = hex(&input);
    assert!(
        d.contains(&format!("```\n{shown}\n```")),
        "docs/tetmsd-packet.md must show the hash input as:\n{shown}"
    );
    // FNV-1a by its definition, byte by byte.
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in &input {
        h = (h ^ u64::from(*b)).wrapping_mul(0x100_0000_01b3);
    }
    assert_eq!(f.hash(), h);
    assert_eq!(fnv1a(&input), h);
    assert!(
        d.contains(&format!("0x{h:016x}")),
        "docs/tetmsd-packet.md must give the hash 0x{h:016x}"
    );
    // FNV-1a's published vector: "a" → 0xaf63dc4c8601ec8c.
    assert_eq!(fnv1a(b"a"), 0xaf63_dc4c_8601_ec8c);
}

/// The page's state-hash example: a two-node state hashed by the rule the
/// page gives (tick, then every position, then every velocity, as u64
/// words of their bits, little-endian, through FNV-1a).
#[test]
fn the_state_hash_follows_the_pages_rule() {
    let d = doc();
    let s = State {
        tick: 7,
        x_m: vec![V3::new(0.0, 0.0, 0.0), V3::new(0.06, 0.0, 0.0)],
        v_m_s: vec![V3::zeros(), V3::new(0.0, 0.0, -0.001)],
    };
    let mut bytes = 7u64.to_le_bytes().to_vec();
    for p in s.x_m.iter().chain(&s.v_m_s) {
        for c in p.iter() {
            bytes.extend_from_slice(&c.to_bits().to_le_bytes());
        }
    }
    let h = fnv1a(&bytes);
    assert_eq!(s.bit_hash(), h);
    assert!(
        d.contains(&format!("0x{h:016x}")),
        "docs/tetmsd-packet.md must give the state hash 0x{h:016x}"
    );
}

#[test]
fn the_page_names_every_field_where_the_code_puts_it() {
    let d = doc();
    for needle in [
        "| 26 | protocol version",
        "| 27 | kind and site",
        "| 28–31 | tick",
        "| 34–37 | acknowledgements",
        "| 38–39 | CRC-16",
        "CRC-16/IBM-3740",
        "| 0–23 | stylus tip",
        "| 24–25 | tetrahedron index",
        "| 32–33 | node index",
        "| 40–63 | held node",
        "| 40–47 | density_kg_m3",
        "| 48–55 | configuration hash",
        "| 56–59 | nonce",
        "| 60–63 | stage word",
        "| 24–25 | block count",
        "| 32–33 | frontier",
        "| 40–47 | end tick",
        "| 48–55 | state hash",
        "| 8–15 | session clock",
        "| 0–1 | ticks back",
        "| 2–3 | tetrahedron index",
        "| 4–5 | node index",
        "| 6–7 | zero",
        "| 8–31 | stylus tip",
        "| 32–55 | held node",
        "| 64–67 | send time",
        "| 68–71 | echoed send time",
        "| 72–75 | hold",
    ] {
        assert!(
            d.contains(needle),
            "docs/tetmsd-packet.md must say: {needle}"
        );
    }
    assert!(d.contains(&format!("version byte is {VERSION}")));
}
