//! `docs/protocol.md` says what the message table says: every message's
//! type byte, name, direction, length and fields (names, element types and
//! array lengths, in order), the error codes, the frame sizes and the
//! schema hash. A third-party client is written from that page alone.
use firmware::protocol::*;

fn page() -> String {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/protocol.md");
    std::fs::read_to_string(path).expect("docs/protocol.md")
}

/// The table rows (cells, trimmed) of the section headed `heading`.
fn rows(page: &str, heading: &str) -> Vec<Vec<String>> {
    let start = page
        .find(heading)
        .unwrap_or_else(|| panic!("no section {heading}"));
    page[start..]
        .lines()
        .skip(1)
        .take_while(|l| !l.starts_with('#'))
        .filter(|l| {
            l.starts_with("| ")
                && !l.starts_with("| type")
                && !l.starts_with("| code")
                && !l.starts_with("| offset")
        })
        .map(|l| {
            l.trim_matches('|')
                .split(" | ")
                .map(|c| c.trim().to_string())
                .collect()
        })
        .collect()
}

/// The fields a row's cell lists: each `` `type name` `` or
/// `` `type name[N]` `` as (type, name, N).
fn fields(cell: &str) -> Vec<(String, String, usize)> {
    cell.split('`')
        .skip(1)
        .step_by(2)
        .map(|f| {
            let (ty, rest) = f.split_once(' ').unwrap_or_else(|| panic!("field `{f}`"));
            match rest.split_once('[') {
                Some((name, n)) => (
                    ty.to_string(),
                    name.to_string(),
                    n.trim_end_matches(']').parse().expect("array length"),
                ),
                None => (ty.to_string(), rest.to_string(), 1),
            }
        })
        .collect()
}

#[test]
fn the_message_tables_match_the_message_definitions() {
    let page = page();
    let mut seen = Vec::new();
    for (heading, direction) in [
        ("### 4.1 Host → board", Direction::ToBoard),
        ("### 4.2 Board → host", Direction::ToHost),
    ] {
        for row in rows(&page, heading) {
            let kind = u8::from_str_radix(row[0].trim_start_matches("0x"), 16).expect("type byte");
            let spec = MESSAGES
                .iter()
                .find(|m| m.kind == kind)
                .unwrap_or_else(|| panic!("the page lists {kind:#04x}, which is no message"));
            assert_eq!(row[1], spec.name, "name of {kind:#04x}");
            assert_eq!(
                spec.direction, direction,
                "{} is in the wrong table",
                spec.name
            );
            assert_eq!(row[2], spec.len.to_string(), "length of {}", spec.name);
            let documented = if row[3] == "—" {
                Vec::new()
            } else {
                fields(&row[3])
            };
            let declared: Vec<(String, String, usize)> = spec
                .fields
                .iter()
                .map(|f| (f.doc_type.to_string(), f.name.to_string(), f.count))
                .collect();
            assert_eq!(documented, declared, "fields of {}", spec.name);
            seen.push(kind);
        }
    }
    for spec in MESSAGES {
        assert_eq!(
            seen.iter().filter(|k| **k == spec.kind).count(),
            1,
            "{} must be listed exactly once",
            spec.name
        );
    }
}

#[test]
fn the_error_codes_sizes_and_hash_match() {
    let page = page();
    let codes = rows(&page, "### 4.3 Error codes");
    assert_eq!(codes.len(), ErrorCode::ALL.len());
    for (row, code) in codes.iter().zip(ErrorCode::ALL) {
        assert_eq!(row[0], (code as u8).to_string());
        assert_eq!(row[1], code.name());
    }
    let hash = format!("{SCHEMA_HASH:#010X}").replace("0X", "0x");
    for quoted in [
        format!("longest payload (type byte included, CRC not) is **{MAX_PAYLOAD}**"),
        format!("at most **{MAX_ENCODED}** bytes before the delimiter,\n**{MAX_FRAME}** with it"),
        format!("More than **{MAX_ENCODED}** bytes before a delimiter"),
        format!("For version {PROTOCOL_VERSION} it is **{hash}**"),
        format!("# The softjoint serial protocol, version {PROTOCOL_VERSION}"),
    ] {
        assert!(
            page.contains(&quoted),
            "docs/protocol.md must say: {quoted}"
        );
    }
    // The law layout of §4.4: 11 fields, 32 bytes, as the codec writes it.
    let law = rows(&page, "### 4.4 Estimation law");
    assert_eq!(law.len(), 11);
    assert_eq!(SetCalibration::LEN, 2 + 32);
}
