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

/// The lines of the first fenced block after `marker`.
fn block_after(page: &str, marker: &str) -> Vec<String> {
    let start = page
        .find(marker)
        .unwrap_or_else(|| panic!("docs/protocol.md must say: {marker}"));
    page[start..]
        .lines()
        .skip_while(|l| !l.starts_with("```"))
        .skip(1)
        .take_while(|l| !l.starts_with("```"))
        .map(str::to_string)
        .collect()
}

/// Bytes on the wire of a field type as §3 and §4.4 name it.
fn doc_type_len(ty: &str) -> usize {
    match ty {
        "u8" => 1,
        "u16" | "i16" => 2,
        "u32" | "i32" | "f32" => 4,
        "law" => 32,
        other => panic!("no such field type {other}"),
    }
}

/// §5 quotes the text the schema hash is computed over, and says how the
/// lengths continue it: the hash computed here from the page alone — the
/// quoted text, and the lengths of §4's tables — is the board's.
#[test]
fn the_schema_hash_follows_from_the_page_alone() {
    let page = page();
    let text = block_after(&page, "hash (offset basis 0x811C9DC5").concat();
    assert_eq!(text, SCHEMA, "the quoted layout text");
    let fnv = |mut h: u32, bytes: &[u8]| {
        for b in bytes {
            h = (h ^ u32::from(*b)).wrapping_mul(0x0100_0193);
        }
        h
    };
    let mut h = fnv(0x811C_9DC5, text.as_bytes());
    // Messages in the order of the text, each with its §4 table row.
    let mut tables = rows(&page, "### 4.1 Host → board");
    tables.extend(rows(&page, "### 4.2 Board → host"));
    for segment in text.split('|').skip(1) {
        let Some(kind) = segment.split(' ').next().filter(|k| k.starts_with("0x")) else {
            continue; // the framing's trailer
        };
        let row = tables
            .iter()
            .find(|r| r[0] == kind)
            .unwrap_or_else(|| panic!("{kind} is in the text but in no table"));
        h = fnv(h, &row[2].parse::<u32>().unwrap().to_le_bytes());
        let cell = if row[3] == "—" { "" } else { &row[3] };
        for (ty, _, n) in fields(cell) {
            h = fnv(h, &((doc_type_len(&ty) * n) as u32).to_le_bytes());
        }
    }
    assert_eq!(h, SCHEMA_HASH, "{h:#010x}");
}

/// §7's boot state and default laws are what a fresh board reports.
#[test]
fn the_boot_state_and_default_laws_are_the_boards() {
    use firmware::app::App;
    use firmware::estimate::PlaneLaw;
    use firmware::time::Instant;
    let page = page();
    let mut app = App::new().unwrap();
    let now = Instant::from_millis(1);
    let Some(Message::Status(st)) = app.handle(GetStatus {}.into(), now) else {
        panic!("no status")
    };
    assert_eq!(
        (st.armed, st.mode, st.latched, st.drive_planes),
        (0, 0, 0, 0)
    );
    assert_eq!(
        (st.coil_mv, st.pair_mv, st.target_deg),
        ([0; 4], [0; 2], [0.0; 2])
    );
    assert_eq!((st.frames_ok, st.crc_errors, st.stale_seqs), (0, 0, 0));
    assert!(page.contains("**After reset** the board is in free-running mode, **disarmed**"));
    let table: Vec<_> = rows(&page, "**After reset**")
        .into_iter()
        .filter(|r| r[0] != "plane")
        .collect();
    assert_eq!(table.len(), 2, "{table:?}");
    for (plane, row) in (0u8..).zip(&table) {
        let Some(Message::Calibration(c)) = app.handle(GetCalibration { plane }.into(), now) else {
            panic!("no calibration")
        };
        let PlaneLaw::Differential { plus, minus, law } = c.law else {
            panic!("plane {plane}: {:?}", c.law)
        };
        let first = |cell: &str| cell.split(' ').next().unwrap().to_string();
        assert_eq!(first(&row[1]), "1", "kind");
        assert_eq!(first(&row[2]), plus.to_string());
        assert_eq!(first(&row[3]), minus.to_string());
        assert_eq!(row[4].parse::<f32>().unwrap(), law.gain);
        assert_eq!(row[5].parse::<f32>().unwrap(), law.offset);
    }
}

/// §8.4 gives the thermal model a host plans with: its constants are the
/// supervisor's, and the quoted trip and cool-down times follow from them.
#[test]
fn the_thermal_model_on_the_page_is_the_supervisors() {
    use firmware::control::DriverConfig;
    use firmware::supervisor::ThermalConfig;
    let page = page().split_whitespace().collect::<Vec<_>>().join(" ");
    let c = ThermalConfig::default();
    let d = DriverConfig::default();
    for quoted in [
        format!(
            "`I = clamp({} A/V × (V − {} V), 0, {} A)`",
            c.driver_gain_a_per_v,
            d.offset_v(),
            c.max_current_a
        ),
        format!(
            "`R = {} Ω`, `C = {} J/K`, `τ = {} s`",
            c.coil_resistance_ohm, c.heat_capacity_j_per_k, c.time_constant_s
        ),
        format!("may not exceed {} K", c.trip_rise_k),
        format!("until it has cooled to {} K", c.resume_rise_k),
    ] {
        assert!(
            page.contains(&quoted),
            "docs/protocol.md must say: {quoted}"
        );
    }
    let full_a = d.offset_v() + c.max_current_a / c.driver_gain_a_per_v;
    assert!(page.contains(&format!("0.5 A from {full_a:.3} V up")));
    let steady = c.max_current_a.powi(2) * c.coil_resistance_ohm * c.time_constant_s
        / c.heat_capacity_j_per_k;
    let trip_s = -c.time_constant_s * (1.0 - c.trip_rise_k / steady).ln();
    let cool_s = c.time_constant_s * (c.trip_rise_k / c.resume_rise_k).ln();
    for quoted in [
        format!("{steady:.0} K at 0.5 A"),
        format!("= {trip_s:.2} s"),
        format!("= {cool_s:.2} s"),
    ] {
        assert!(
            page.contains(&quoted),
            "docs/protocol.md must say: {quoted}"
        );
    }
}

/// The lockstep period's range on the page is the board's.
#[test]
fn the_lockstep_period_range_is_the_boards() {
    use firmware::app::LOCKSTEP_PERIOD_US;
    let page = page();
    let range = format!(
        "`HilStart{{period_us}}`, {}..={} {:03} µs",
        LOCKSTEP_PERIOD_US.start(),
        LOCKSTEP_PERIOD_US.end() / 1000,
        LOCKSTEP_PERIOD_US.end() % 1000
    );
    assert!(page.contains(&range), "docs/protocol.md must say: {range}");
    let table = format!(
        "`u32 period_us` ({}..={} {:03})",
        LOCKSTEP_PERIOD_US.start(),
        LOCKSTEP_PERIOD_US.end() / 1000,
        LOCKSTEP_PERIOD_US.end() % 1000
    );
    assert!(page.contains(&table), "docs/protocol.md must say: {table}");
}
