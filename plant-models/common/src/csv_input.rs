//! The one CSV reader for numeric data files (sweeps, force and displacement
//! series, probe scripts, push videos), built on the `csv` crate.
//!
//! Accepted: a header line, then data rows; a UTF-8 byte-order mark (as
//! Excel writes it), CRLF or LF line ends, blank lines, lines starting with
//! `#` (comments), spaces around fields, quoted fields. Every value must be
//! a finite number. Every error names the file, the 1-based line and, for a
//! value, its column; long offending text is quoted only in part.
use rayon::prelude::*;
use std::fmt;

/// Why a CSV file could not be read.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CsvError {
    /// The file (or a label for text that came from elsewhere).
    pub file: String,
    /// 1-based line.
    pub line: usize,
    /// The column, for an error in a value.
    pub column: Option<String>,
    /// What is wrong.
    pub reason: String,
}

impl fmt::Display for CsvError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.column {
            Some(c) => write!(
                f,
                "{}:{}: column `{c}`: {}",
                self.file, self.line, self.reason
            ),
            None => write!(f, "{}:{}: {}", self.file, self.line, self.reason),
        }
    }
}

impl std::error::Error for CsvError {}

/// At most this many characters of a user's text go into a message.
const QUOTE_CHARS: usize = 40;

/// `text` for an error message: whole if short, else its start and "…".
pub fn excerpt(text: &str) -> String {
    if text.chars().count() <= QUOTE_CHARS {
        text.to_string()
    } else {
        let head: String = text.chars().take(QUOTE_CHARS).collect();
        format!("{head}…")
    }
}

/// One data row: its values in header order, and where it was.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    /// 1-based line of the row in the file.
    pub line: usize,
    /// One finite value per header column.
    pub values: Vec<f64>,
}

/// A numeric table: the header's column names and the data rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The file (or label) the table came from, for messages.
    pub file: String,
    /// 1-based line of the header.
    pub header_line: usize,
    /// Column names, trimmed.
    pub columns: Vec<String>,
    /// Data rows.
    pub rows: Vec<Row>,
}

impl Table {
    /// An error at `line` (and in `column`, if given) of this table's file.
    pub fn error(&self, line: usize, column: Option<&str>, reason: impl Into<String>) -> CsvError {
        CsvError {
            file: self.file.clone(),
            line,
            column: column.map(str::to_string),
            reason: reason.into(),
        }
    }

    /// The index of column `name`, or an error at the header that lists
    /// the columns there are.
    pub fn column(&self, name: &str) -> Result<usize, CsvError> {
        self.columns.iter().position(|c| c == name).ok_or_else(|| {
            self.error(
                self.header_line,
                None,
                format!(
                    "missing column `{name}` (the header has: {})",
                    excerpt(&self.columns.join(", "))
                ),
            )
        })
    }

    /// True when the table has a column `name`.
    pub fn has(&self, name: &str) -> bool {
        self.columns.iter().any(|c| c == name)
    }

    /// The values of column `index` down the rows.
    pub fn values(&self, index: usize) -> Vec<f64> {
        self.rows
            .iter()
            .map(|r| r.values.get(index).copied().unwrap_or(f64::NAN))
            .collect()
    }

    /// Refuses a table with fewer than `n` data rows.
    pub fn require_rows(&self, n: usize, why: &str) -> Result<(), CsvError> {
        if self.rows.len() < n {
            return Err(self.error(
                self.header_line,
                None,
                format!("need at least {n} data rows {why}, got {}", self.rows.len()),
            ));
        }
        Ok(())
    }
}

/// Reads CSV `text` (named `file` in errors) as a header and rows of
/// finite numbers.
pub fn read_numeric(text: &str, file: &str) -> Result<Table, CsvError> {
    let err = |line: usize, column: Option<&str>, reason: String| CsvError {
        file: file.to_string(),
        line,
        column: column.map(str::to_string),
        reason,
    };
    let mut reader = csv_reader(text);
    let mut records = reader.records();
    let lines = LineCounter::new(text);
    let line_at = |byte: usize| lines.record_line(byte);
    let line_of = |r: &csv::StringRecord| r.position().map_or(0, |p| line_at(p.byte() as usize));
    let header = loop {
        match records.next() {
            None => return Err(err(1, None, "empty file: expected a header line".into())),
            Some(Err(e)) => return Err(err(csv_line(&e, &line_at), None, csv_reason(&e))),
            Some(Ok(r)) if r.iter().all(str::is_empty) => continue,
            Some(Ok(r)) => break r,
        }
    };
    let header_line = line_of(&header);
    let columns: Vec<String> = header.iter().map(str::to_string).collect();
    if let Some(empty) = columns.iter().position(String::is_empty) {
        return Err(err(
            header_line,
            None,
            format!("header column {} has no name", empty + 1),
        ));
    }
    drop(records);
    // Past the header, a text without quotes, and whose carriage returns
    // all end lines, is lines of comma-separated fields: it is split here
    // (the csv crate's record machinery was 3,700 instructions a row as
    // `StringRecord`s, most of a contour file's reading; issue 34), a
    // large one in pieces on rayon's threads. Any other text is read by
    // the csv crate as byte records into one buffer.
    let rest_at = reader.position().byte() as usize;
    let rows = if let Some(rest) = text.get(rest_at..).filter(|rest| plain_lines(rest)) {
        // The line of `rest`'s first byte, counted as `LineCounter` would.
        let first_line = 1 + text.as_bytes()[..rest_at]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        plain_rows(rest, first_line, &columns, file)?
    } else {
        let mut rows = Vec::new();
        let mut record = csv::ByteRecord::new();
        loop {
            match reader.read_byte_record(&mut record) {
                Ok(true) => {}
                Ok(false) => break,
                Err(e) => return Err(err(csv_line(&e, &line_at), None, csv_reason(&e))),
            }
            // The text is a `str` and records split at ASCII bytes, so
            // every field is UTF-8 (were one not, it would be refused as
            // not a number, never taken as blank).
            let fields: Vec<&str> = record
                .iter()
                .map(|f| std::str::from_utf8(f).unwrap_or("\u{fffd}"))
                .collect();
            if is_blank(&fields) {
                continue;
            }
            let start = record.position().map_or(0, |p| p.byte() as usize);
            rows.push(data_row(&fields, line_at(start), &columns, file)?);
        }
        rows
    };
    Ok(Table {
        file: file.to_string(),
        header_line,
        columns,
        rows,
    })
}

/// The csv crate's reader of the format read here: no header row of its
/// own (the first non-blank record is the header), `#` comment lines,
/// fields trimmed, rows of any length (checked against the header here).
fn csv_reader(text: &str) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_reader(text.as_bytes())
}

/// Texts at least this long are split into pieces read side by side.
const PARALLEL_BYTES: usize = 1 << 16;

/// The rows of plain lines `rest` (see [`plain_lines`]) whose first line
/// is line `first_line` of the file: blank and comment lines skipped,
/// each line's fields trimmed of ASCII space. A long text is cut at line
/// ends into pieces read on rayon's threads, each counting its lines from
/// the newlines before it; the first error in file order is returned.
fn plain_rows(
    rest: &str,
    first_line: usize,
    columns: &[String],
    file: &str,
) -> Result<Vec<Row>, CsvError> {
    let pieces = if rest.len() < PARALLEL_BYTES {
        1
    } else {
        rayon::current_num_threads().clamp(1, rest.len() / (PARALLEL_BYTES / 2))
    };
    plain_rows_in(rest, first_line, columns, file, pieces)
}

/// [`plain_rows`] in `pieces` pieces. Each piece numbers its lines from
/// 0 and counts them; the pieces are then joined in order, each one's
/// lines moved on by those of the pieces before it (so no piece counts
/// the text before it again).
fn plain_rows_in(
    rest: &str,
    first_line: usize,
    columns: &[String],
    file: &str,
    pieces: usize,
) -> Result<Vec<Row>, CsvError> {
    // Cut points: after the first newline at or past each equal share.
    let mut cuts = vec![0];
    for k in 1..pieces.max(1) {
        let from = (rest.len() * k / pieces).max(*cuts.last().unwrap_or(&0));
        let cut = rest.as_bytes()[from..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(rest.len(), |i| from + i + 1);
        cuts.push(cut);
    }
    cuts.push(rest.len());
    // A piece's rows and error with lines counted from its start, and its
    // number of lines (each piece but the last ends in a newline: no empty
    // tail line, and its lines are its newlines).
    let read_piece = |k: usize| -> (Vec<Row>, Option<CsvError>, usize) {
        let (a, b) = (cuts[k], cuts[k + 1]);
        let mut rows = Vec::new();
        let mut fields: Vec<&str> = Vec::new();
        let mut lines = 0;
        for raw in rest[a..b].split_terminator('\n') {
            let line = lines;
            lines += 1;
            let l = raw.strip_suffix('\r').unwrap_or(raw);
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            fields.clear();
            fields.extend(l.split(',').map(str::trim_ascii));
            if is_blank(&fields) {
                continue;
            }
            match data_row(&fields, line, columns, file) {
                Ok(row) => rows.push(row),
                Err(e) => return (rows, Some(e), lines),
            }
        }
        (rows, None, lines)
    };
    let read: Vec<_> = (0..cuts.len() - 1)
        .into_par_iter()
        .map(read_piece)
        .collect();
    let mut rows = Vec::new();
    let mut base = first_line;
    for (mut piece, error, lines) in read {
        if let Some(mut e) = error {
            e.line += base;
            return Err(e);
        }
        for r in &mut piece {
            r.line += base;
        }
        rows.append(&mut piece);
        base += lines;
    }
    Ok(rows)
}

/// Whether every field is empty once trimmed of Unicode space (a blank
/// row, skipped).
fn is_blank(fields: &[&str]) -> bool {
    fields.iter().all(|f| f.trim().is_empty())
}

/// One data row's values from its fields (trimmed of ASCII space), at
/// `line`, or the error naming line and column. The text is a `str`, so
/// every field is UTF-8; a field that does not parse once trimmed of ASCII
/// space is trimmed of Unicode space (as a `StringRecord` is) before it
/// is refused.
fn data_row(fields: &[&str], line: usize, columns: &[String], file: &str) -> Result<Row, CsvError> {
    let err = |column: &str, reason: String| CsvError {
        file: file.to_string(),
        line,
        column: Some(column.to_string()),
        reason,
    };
    if fields.len() != columns.len() {
        return Err(CsvError {
            file: file.to_string(),
            line,
            column: None,
            reason: format!(
                "{} fields, but the header has {}",
                fields.len(),
                columns.len()
            ),
        });
    }
    let mut values = Vec::with_capacity(columns.len());
    for (&field, name) in fields.iter().zip(columns) {
        let parsed = field.parse().or_else(|e| {
            let unicode_trimmed = field.trim();
            if unicode_trimmed.len() < field.len() {
                unicode_trimmed.parse()
            } else {
                Err(e)
            }
        });
        let v: f64 = parsed
            .map_err(|_| err(name, format!("`{}` is not a number", excerpt(field.trim()))))?;
        if !v.is_finite() {
            return Err(err(
                name,
                format!(
                    "`{}` is not finite (NaN or infinite)",
                    excerpt(field.trim())
                ),
            ));
        }
        values.push(v);
    }
    Ok(Row { line, values })
}

/// Whether `text` has no quote and no carriage return but before a line
/// feed: then its lines are its records and commas its field separators.
fn plain_lines(text: &str) -> bool {
    let b = text.as_bytes();
    !b.iter()
        .enumerate()
        .any(|(i, &c)| c == b'"' || (c == b'\r' && b.get(i + 1) != Some(&b'\n')))
}

/// Line numbers of records, counted as the reader goes: records come in
/// file order, so each count starts where the last one stopped and reading
/// a file stays linear in its length (counting from the start for every
/// record made a 40,000-row file take 11 s).
struct LineCounter<'a> {
    text: &'a str,
    /// A byte offset and the 1-based line it is on.
    at: std::cell::Cell<(usize, usize)>,
}

impl<'a> LineCounter<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            text,
            at: std::cell::Cell::new((0, 1)),
        }
    }

    /// The 1-based line on which the record whose reading began at `byte`
    /// starts. The csv crate reports where it began reading — before the
    /// line end of the previous record, blank lines, comment lines and the
    /// byte-order mark — and counts lines without the comments, so the
    /// record's first byte is found here and its line counted from the
    /// text.
    fn record_line(&self, byte: usize) -> usize {
        let first = record_start(self.text, byte);
        let (mut from, mut line) = self.at.get();
        if first < from {
            // An earlier position (an error's): count from the start.
            (from, line) = (0, 1);
        }
        let between = self.text.get(from..first).unwrap_or("");
        line += between.bytes().filter(|&b| b == b'\n').count();
        self.at.set((first, line));
        line
    }
}

/// The first byte of the record whose reading began at `byte`: past line
/// ends, comment lines and the byte-order mark.
fn record_start(text: &str, mut byte: usize) -> usize {
    let bytes = text.as_bytes();
    loop {
        match bytes.get(byte..) {
            Some([b'\r' | b'\n', ..]) => byte += 1,
            Some([0xEF, 0xBB, 0xBF, ..]) if byte == 0 => byte += 3,
            Some([b'#', ..]) => {
                byte = text
                    .get(byte..)
                    .and_then(|rest| rest.find('\n'))
                    .map_or(bytes.len(), |nl| byte + nl + 1);
            }
            _ => break,
        }
    }
    byte.min(bytes.len())
}

fn csv_line(e: &csv::Error, line_at: &impl Fn(usize) -> usize) -> usize {
    e.position().map_or(0, |p| line_at(p.byte() as usize))
}

fn csv_reason(e: &csv::Error) -> String {
    match e.kind() {
        csv::ErrorKind::Utf8 { .. } => "not valid UTF-8 text".into(),
        _ => e.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn excel_files_with_a_bom_and_crlf_read_like_plain_ones() {
        let plain = "a,b\n1,2\n3,4\n";
        let excel = "\u{feff}a,b\r\n1,2\r\n3,4\r\n";
        let (p, e) = (
            read_numeric(plain, "p").unwrap(),
            read_numeric(excel, "e").unwrap(),
        );
        assert_eq!(p.columns, e.columns);
        assert_eq!(p.columns, ["a", "b"]);
        assert_eq!(p.rows, e.rows);
        assert_eq!(e.rows[1].line, 3);
    }

    #[test]
    fn comments_blanks_spaces_and_quotes_are_accepted_and_lines_counted() {
        let text = "# a sweep\n\n time_s ,\"x\"\n0, 1.5\n# pause\n\n1 ,2\n";
        let t = read_numeric(text, "f.csv").unwrap();
        assert_eq!(t.header_line, 3);
        assert_eq!(t.columns, ["time_s", "x"]);
        assert_eq!(t.rows.iter().map(|r| r.line).collect::<Vec<_>>(), [4, 7]);
        assert_eq!(t.values(1), [1.5, 2.0]);
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let e = read_numeric("a,b\n1,2\n3,x\n", "f.csv").unwrap_err();
        assert_eq!(e.to_string(), "f.csv:3: column `b`: `x` is not a number");
        let e = read_numeric("a,b\n1,2\n3\n", "f.csv").unwrap_err();
        assert_eq!(e.to_string(), "f.csv:3: 1 fields, but the header has 2");
        let e = read_numeric("a,b\n1,NaN\n", "f.csv").unwrap_err();
        assert!(e
            .to_string()
            .starts_with("f.csv:2: column `b`: `NaN` is not finite"));
        let e = read_numeric("", "f.csv").unwrap_err();
        assert_eq!(e.line, 1);
        let t = read_numeric("a,b\n1,2\n", "f.csv").unwrap();
        assert_eq!(
            t.column("c").unwrap_err().to_string(),
            "f.csv:1: missing column `c` (the header has: a, b)"
        );
        // A huge field is quoted only in part.
        let long = "9".repeat(5000) + "x";
        let e = read_numeric(&format!("a\n{long}\n"), "f.csv")
            .unwrap_err()
            .to_string();
        assert!(e.len() < 200, "{} characters", e.len());
    }

    #[test]
    fn line_numbers_of_a_long_file_are_counted_right() {
        // Comments, blank lines and CRLF among 5,000 rows; each row's line
        // as a count from the start of the text gives it.
        let mut text = String::from("# header next\r\nt,x\r\n");
        for k in 0..5000 {
            if k % 7 == 0 {
                text.push_str("# note\n\n");
            }
            text.push_str(&format!("{k},{}\r\n", k * 2));
        }
        let t = read_numeric(&text, "long.csv").unwrap();
        assert_eq!(t.rows.len(), 5000);
        for r in &t.rows {
            let needle = format!("\n{},", r.values[0] as u64);
            let at = text.find(&needle).unwrap() + 1;
            assert_eq!(r.line, text[..at].matches('\n').count() + 1);
        }
        // An error after many rows still names its line.
        let e = read_numeric(&format!("{text}oops,1\n"), "long.csv").unwrap_err();
        assert_eq!(e.line, text.matches('\n').count() + 1);
    }

    // The reading before issue 34's change, as the reference.
    /// Rows as (line, values), or the refusal as (line, what it names,
    /// the column it names).
    type Read = Result<Vec<(usize, Vec<f64>)>, (usize, String, Option<String>)>;
    fn by_string_records(text: &str) -> Read {
        let mut reader = csv_reader(text);
        let lines = LineCounter::new(text);
        let mut header: Option<Vec<String>> = None;
        let mut rows = Vec::new();
        for r in reader.records() {
            let r = r.map_err(|e| {
                (
                    csv_line(&e, &|b| lines.record_line(b)),
                    csv_reason(&e),
                    None,
                )
            })?;
            if r.iter().all(str::is_empty) {
                continue;
            }
            let line = r
                .position()
                .map_or(0, |p| lines.record_line(p.byte() as usize));
            let Some(names) = &header else {
                header = Some(r.iter().map(str::to_string).collect());
                continue;
            };
            if r.len() != names.len() {
                return Err((line, format!("{} fields", r.len()), None));
            }
            let mut values = Vec::new();
            for (f, name) in r.iter().zip(names) {
                match f.parse::<f64>() {
                    Ok(v) if v.is_finite() => values.push(v),
                    _ => return Err((line, format!("`{}`", excerpt(f)), Some(name.clone()))),
                }
            }
            rows.push((line, values));
        }
        if header.is_none() {
            return Err((1, "empty".into(), None));
        }
        Ok(rows)
    }

    /// Rows read as byte records give what reading each as a `StringRecord`
    /// gave (values, lines, skipped blank rows and the error's line,
    /// column and reason), on random files of numbers, blanks, Unicode
    /// space (U+00A0, U+3000), quotes, comments, CRLF, short rows and words.
    #[test]
    fn byte_records_read_as_string_records_did() {
        use rand::{Rng, SeedableRng};
        let pieces = [
            "1", "2.5", "-3e2", " ", "\u{a0}", "\u{3000}", ",", ",", "\n", "\r\n", "\"4\"", "#",
            "\r", "x", "NaN", "",
        ];
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(34);
        let (mut read, mut refused) = (0, 0);
        for case in 0..5_000 {
            // Rows of two padded numbers, now and then a random piece.
            let mut text = String::from("a , b\n");
            let pad = ["", " ", "\u{a0}", "\u{3000}"];
            for _ in 0..rng.gen_range(0..12) {
                for field in 0..2 {
                    text.push_str(pad[rng.gen_range(0..pad.len())]);
                    text.push_str(pieces[rng.gen_range(0..3)]);
                    text.push_str(pad[rng.gen_range(0..pad.len())]);
                    if rng.gen_bool(0.03) {
                        text.push_str(pieces[rng.gen_range(0..pieces.len())]);
                    }
                    text.push_str(if field == 0 { "," } else { "\n" });
                }
                if rng.gen_bool(0.05) {
                    text.push_str(["\n", "# c\n", " , \n", "\u{a0}\n"][rng.gen_range(0..4)]);
                }
            }
            let want = by_string_records(&text);
            let got = read_numeric(&text, "f.csv");
            match (&want, &got) {
                (Ok(rows), Ok(t)) => {
                    let got: Vec<_> = t.rows.iter().map(|r| (r.line, r.values.clone())).collect();
                    assert_eq!(&got, rows, "case {case}: {text:?}");
                    read += 1;
                }
                (Err((line, what, column)), Err(e)) => {
                    assert_eq!(e.line, *line, "case {case}: {text:?}: {e}");
                    assert_eq!(&e.column, column, "case {case}: {text:?}: {e}");
                    assert!(
                        e.reason.contains(what.as_str()),
                        "case {case}: {text:?}: {e} ({what})"
                    );
                    refused += 1;
                }
                _ => panic!("case {case}: {text:?}: {want:?} against {got:?}"),
            }
        }
        assert!(
            read > 500 && refused > 500,
            "{read} read, {refused} refused"
        );
    }

    /// A file long enough to be read in pieces on several threads gives
    /// the rows of the reference reading, and an error anywhere in it
    /// (first piece, a cut, the last line) the reference's line and reason.
    #[test]
    fn a_long_file_read_in_pieces_is_the_reference_reading() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(48);
        let mut text = String::from("# long\nt , x,y\n");
        let mut k = 0;
        while text.len() < 4 * PARALLEL_BYTES {
            match rng.gen_range(0..40) {
                0 => text.push_str("# note\n"),
                1 => text.push_str("\r\n"),
                2 => text.push_str(" ,\u{a0}, \n"),
                _ => text.push_str(&format!(
                    "{k}, {}\u{a0},{:e}\r\n",
                    rng.gen::<f64>(),
                    -1e3 * rng.gen::<f64>()
                )),
            }
            k += 1;
        }
        let want = by_string_records(&text).unwrap();
        let got = read_numeric(&text, "long.csv").unwrap();
        assert!(want.len() > 5_000, "{}", want.len());
        let got_rows: Vec<_> = got
            .rows
            .iter()
            .map(|r| (r.line, r.values.clone()))
            .collect();
        assert_eq!(got_rows, want);
        // A bad field at a random line, at a piece's likely cut (the
        // middle) and on the last line.
        let ends: Vec<usize> = text.match_indices('\n').map(|(i, _)| i).collect();
        let mut places: Vec<usize> = (0..20)
            .map(|_| ends[rng.gen_range(2..ends.len())])
            .collect();
        places.push(ends[ends.len() / 2]);
        places.push(*ends.last().unwrap());
        for at in places {
            let bad = format!("{}9,oops,1\n{}", &text[..=at], &text[at + 1..]);
            let (line, what, column) = by_string_records(&bad).unwrap_err();
            let e = read_numeric(&bad, "long.csv").unwrap_err();
            assert_eq!(
                (e.line, e.reason.contains(what.as_str()), &e.column),
                (line, true, &column),
                "{e}"
            );
        }
        // And in 1 to 7 pieces, whatever the machine's threads.
        let header_end = text.find("y\n").unwrap() + 2;
        let columns = ["t".to_string(), "x".to_string(), "y".to_string()];
        for pieces in 1..=7 {
            let rows = plain_rows_in(&text[header_end..], 3, &columns, "long.csv", pieces).unwrap();
            let got_rows: Vec<_> = rows.iter().map(|r| (r.line, r.values.clone())).collect();
            assert_eq!(got_rows, want, "{pieces} pieces");
            for &at in &[
                ends[ends.len() / 3],
                ends[ends.len() / 2],
                ends[2 * ends.len() / 3],
            ] {
                let bad = format!("{}9,oops,1\n{}", &text[..=at], &text[at + 1..]);
                let (line, _, column) = by_string_records(&bad).unwrap_err();
                let e =
                    plain_rows_in(&bad[header_end..], 3, &columns, "long.csv", pieces).unwrap_err();
                assert_eq!((e.line, e.column), (line, column), "{pieces} pieces");
            }
        }
    }
}
