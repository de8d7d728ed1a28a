//! `docs/tetmsd-packet.md` says what the codec does: its example packets
//! are the encoder's bytes, and it names every field at the bytes the code
//! uses. Change the codec and the page together.
use plant_tetmsd::model::probe::{Grip, Manipulation};
use plant_tetmsd::model::V3;
use plant_tetmsd::packet::{Message, Packet, PACKET_BYTES, VERSION};

fn doc() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/tetmsd-packet.md");
    std::fs::read_to_string(path).expect("docs/tetmsd-packet.md")
}

/// The example packets of the page, as the encoder writes them.
fn examples() -> [(&'static str, Packet); 2] {
    [
        (
            "input",
            Packet {
                site: 1,
                seq: 1234,
                ack: 1229,
                sack: 0b0000_0000_0000_0101,
                message: Message::Input(Manipulation {
                    tip_m: V3::new(0.02, 0.03, 0.0595),
                    grip: Some(Grip {
                        tet: 377,
                        node: 98,
                        node_m: V3::new(0.015, 0.03, 0.0595),
                    }),
                }),
            },
        ),
        (
            "hello",
            Packet {
                site: 0,
                seq: 0,
                ack: 0,
                sack: 0,
                message: Message::Hello {
                    config_hash: 0x0123_4567_89ab_cdef,
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
        assert_eq!(bytes.len(), PACKET_BYTES);
        let h = hex(&bytes);
        assert!(
            d.contains(&h),
            "docs/tetmsd-packet.md must show the {name} example as:\n{h}"
        );
        assert_eq!(Packet::decode(&bytes), Ok(p));
    }
}

#[test]
fn the_page_names_every_field_where_the_code_puts_it() {
    let d = doc();
    for needle in [
        "| 0–23 | stylus tip",
        "| 24–25 | tetrahedron index",
        "| 26 | protocol version",
        "| 27 | kind and site",
        "| 28–31 | sequence number",
        "| 32–33 | node index",
        "| 34–35 | ack",
        "| 36–37 | selective ack",
        "| 38–39 | CRC-16",
        "| 40–63 | held node",
        "CRC-16/IBM-3740",
    ] {
        assert!(
            d.contains(needle),
            "docs/tetmsd-packet.md must say: {needle}"
        );
    }
    assert!(d.contains(&format!("version byte is {VERSION}")));
}
