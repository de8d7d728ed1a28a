//! Where results go. Every result `softjoint` writes — CSV, SVG, JSON and
//! TOML files, and the JSON, CSV or text it prints — leaves through this
//! module, which guarantees three things:
//!
//! 1. **No non-finite number.** A NaN or ±∞ in a result is a defect
//!    upstream (an instability, an overflow, a division by zero); it is
//!    refused here, naming the file, the line and column or the field,
//!    rather than written for someone to find later. How each kind is
//!    checked:
//!    - CSV: every field of every data line that reads as a number
//!      (`NaN`, `inf`, `1e999` included) must be finite; the error names
//!      the header's column.
//!    - SVG and other text: every word that reads as a number must be
//!      finite (the plot module already leaves non-finite coordinates out;
//!      this catches numbers printed into labels).
//!    - JSON and TOML: the value is walked before it is serialised
//!      ([`finite::first_non_finite`]), because serde_json writes NaN as
//!      `null`; the error names the field's path.
//! 2. **Files a user keeps are written atomically** ([`AtomicFile`]): a
//!    temporary file in the same directory, renamed over the target only
//!    when complete, so a failed write (disk full, `ulimit -f`, an
//!    interrupted run) leaves the previous file as it was. Commands that
//!    compute for long create the [`AtomicFile`] (or [`check_dir`] their
//!    output directory) first, so an unwritable path is refused before the
//!    work, not after it.
//! 3. **Printing never panics.** [`outln!`](crate::outln) and
//!    [`out!`](crate::out) print like `println!`/`print!`, but a failed
//!    write (`> /dev/full`, a closed pipe) is a [`StdoutError`] returned
//!    with `?`.
//!
//! Streamed traces (`sim`/`hil --csv`, the console's telemetry CSV) are
//! the exception to 2: they are written as the run goes (`crate::run::trace`)
//! and say whether they are complete. They are not the exception to 1:
//! each value is checked with [`check_number`] before it is formatted, and
//! a missing angle estimate is an empty field ([`estimate_field`]).
//!
//! `tests/writers_check_finite.rs` holds every file write and every print
//! of the program to this module.
use std::fmt;
use std::io::{self, Write as _};
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

mod atomic;
pub mod finite;
mod fixed;

#[cfg(test)]
pub(crate) use atomic::fifo_and_reader;
pub use atomic::{check_dir, check_file, check_files_in, create_dir, AtomicFile};
pub use fixed::{fixed, push_fixed};

/// A write to standard output failed.
#[derive(Debug, thiserror::Error)]
#[error("cannot write to standard output: {0}")]
pub struct StdoutError(pub io::Error);

impl StdoutError {
    /// Whether the reader went away (`softjoint … | head -1`): shells
    /// report that as SIGPIPE, not as an error.
    pub fn is_broken_pipe(&self) -> bool {
        self.0.kind() == io::ErrorKind::BrokenPipe
    }
}

/// Writes formatted text to standard output (what [`outln!`](crate::outln)
/// and [`out!`](crate::out) expand to).
pub fn stdout(args: fmt::Arguments) -> Result<(), StdoutError> {
    io::stdout().lock().write_fmt(args).map_err(StdoutError)
}

/// Flushes standard output; a program calls it before it exits so that a
/// last line without a newline cannot fail unseen.
pub fn flush_stdout() -> Result<(), StdoutError> {
    io::stdout().lock().flush().map_err(StdoutError)
}

/// `println!` that returns a failed write with `?` instead of panicking.
#[macro_export]
macro_rules! outln {
    () => { $crate::output::stdout(format_args!("\n"))? };
    ($($arg:tt)*) => {
        $crate::output::stdout(format_args!("{}\n", format_args!($($arg)*)))?
    };
}

/// `print!` that returns a failed write with `?` instead of panicking.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::output::stdout(format_args!($($arg)*))? };
}

/// A result that would have carried a non-finite number.
#[derive(Debug, thiserror::Error)]
pub struct NonFinite {
    /// The file (or `standard output`).
    pub target: String,
    /// Where in it: `line 12, column \`ux_m\``, or a JSON field path.
    pub place: String,
    /// The offending text or value.
    pub value: String,
}

impl fmt::Display for NonFinite {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "refusing to write {}: {} would be `{}`, not a finite number (the computation behind it failed; nothing was written)",
            self.target, self.place, self.value
        )
    }
}

/// The first word of `text` that reads as a number and is not finite.
///
/// Only a word that could parse to a non-finite value is parsed: one with
/// a letter (`inf`, `NaN`, an exponent such as `1e999`) or one too long
/// for a finite f64 (a string of digits, signs and points without a
/// letter is finite up to 308 digits: `f64::MAX` ≈ 1.8·10³⁰⁸). Every number
/// an output writes is such a word, so parsing every word cost the
/// contour fit's frames more than the fit itself.
fn non_finite_word(text: &str) -> Option<&str> {
    text.split(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.' | '_')))
        .filter(|w| could_be_non_finite(w))
        .find(|w| w.parse::<f64>().is_ok_and(|v| !v.is_finite()))
}

/// Whether a word of digits, letters, signs, points and underscores could
/// parse as a non-finite f64 (see [`non_finite_word`]).
fn could_be_non_finite(word: &str) -> bool {
    word.len() > 300 || word.bytes().any(|b| b.is_ascii_alphabetic())
}

/// Whether some word of `text` (split as [`non_finite_word`] splits) reads
/// as a non-finite number: one pass over the bytes, the common answer
/// "no" without splitting lines and fields. Every word the line-by-line
/// checks look at is a word of the whole text (newlines, commas and
/// blanks all end words), so where this finds none they find none; where
/// it finds one they run to name its place (issue 34: the line-by-line
/// scan was a quarter of the contour fit command).
fn may_hold_non_finite(text: &str) -> bool {
    let bytes = text.as_bytes();
    let mut start = 0;
    let mut letter = false;
    for (i, &b) in bytes.iter().enumerate() {
        let class = WORD_BYTE[usize::from(b)];
        if class != 0 {
            letter |= class == LETTER;
            continue;
        }
        if (letter || i - start > 300) && non_finite_word(&text[start..i]).is_some() {
            return true;
        }
        start = i + 1;
        letter = false;
    }
    (letter || bytes.len() - start > 300) && non_finite_word(&text[start..]).is_some()
}

/// [`WORD_BYTE`]'s class of an ASCII letter; other word bytes (digits,
/// `+ - . _`) are 1 and separators 0.
const LETTER: u8 = 2;

/// The class of each byte in [`non_finite_word`]'s split, as a table (a
/// third of the per-byte cost of the two tests it replaces).
const WORD_BYTE: [u8; 256] = {
    let mut t = [0u8; 256];
    let mut b = 0;
    while b < 256 {
        let c = b as u8;
        t[b] = if c.is_ascii_alphabetic() {
            LETTER
        } else if c.is_ascii_digit() || matches!(c, b'+' | b'-' | b'.' | b'_') {
            1
        } else {
            0
        };
        b += 1;
    }
    t
};

/// Checks CSV text (header line first; `#` lines are comments).
pub fn check_csv(target: &str, text: &str) -> Result<(), NonFinite> {
    if !may_hold_non_finite(text) {
        return Ok(());
    }
    let mut header: Option<Vec<&str>> = None;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let Some(columns) = &header else {
            header = Some(line.split(',').map(str::trim).collect());
            continue;
        };
        for (k, field) in line.split(',').enumerate() {
            if let Some(w) = non_finite_word(field.trim()) {
                let column = columns
                    .get(k)
                    .map(|c| format!(", column `{c}`"))
                    .unwrap_or_else(|| format!(", field {}", k + 1));
                return Err(NonFinite {
                    target: target.to_string(),
                    place: format!("line {}{column}", i + 1),
                    value: w.to_string(),
                });
            }
        }
    }
    Ok(())
}

/// An angle estimate for a CSV field with `decimals` decimals, or an empty
/// field when there is none: the control core reports "no estimate yet"
/// (before every sensor a law reads has delivered) as NaN, which is a
/// missing value, not a failed computation.
pub fn estimate_field(estimate_deg: f64, decimals: usize) -> String {
    if estimate_deg.is_nan() {
        String::new()
    } else {
        format!("{estimate_deg:.decimals$}")
    }
}

/// Checks one number that a streaming writer is about to put at `line`,
/// column `column()` of `target` (the column is named only when the check
/// fails, so the check costs one comparison per value).
pub fn check_number(
    target: &Path,
    line: u64,
    column: impl FnOnce() -> String,
    value: f64,
) -> Result<(), NonFinite> {
    if value.is_finite() {
        return Ok(());
    }
    Err(NonFinite {
        target: target.display().to_string(),
        place: format!("line {line}, column `{}`", column()),
        value: value.to_string(),
    })
}

/// Checks any other text (SVG, tables): every word that reads as a
/// number must be finite.
pub fn check_text(target: &str, text: &str) -> Result<(), NonFinite> {
    if !may_hold_non_finite(text) {
        return Ok(());
    }
    for (i, line) in text.lines().enumerate() {
        if let Some(w) = non_finite_word(line) {
            return Err(NonFinite {
                target: target.to_string(),
                place: format!("line {}", i + 1),
                value: plant_common::csv_input::excerpt(w),
            });
        }
    }
    Ok(())
}

/// Checks a value that will be serialised (JSON, TOML).
pub fn check_value<T: Serialize + ?Sized>(target: &str, value: &T) -> anyhow::Result<()> {
    check_field(target, "", value)
}

/// [`check_value`] of a value that will be field `prefix` of its output.
fn check_field<T: Serialize + ?Sized>(target: &str, prefix: &str, value: &T) -> anyhow::Result<()> {
    match finite::first_non_finite(value).map_err(anyhow::Error::msg)? {
        None => Ok(()),
        Some(found) => {
            let sep = if prefix.is_empty() || found.path.is_empty() || found.path.starts_with('[') {
                ""
            } else {
                "."
            };
            let path = format!("{prefix}{sep}{}", found.path);
            Err(NonFinite {
                target: target.to_string(),
                place: if path.is_empty() {
                    "the value".into()
                } else {
                    format!("field `{path}`")
                },
                value: found.value.to_string(),
            }
            .into())
        }
    }
}

/// Output text that has passed the finite-number check of its kind. A
/// command that renders and checks all its files before it writes the
/// first (so that a refused one leaves nothing behind) writes these with
/// [`write_checked`], which does not scan them a second time (issue 34:
/// the second scan of the contour fit's files was a tenth of its time).
#[derive(Debug)]
pub struct CheckedText {
    text: String,
}

impl CheckedText {
    /// CSV text after [`check_csv`].
    pub fn csv(target: &str, text: String) -> Result<Self, NonFinite> {
        check_csv(target, &text)?;
        Ok(Self { text })
    }

    /// SVG or other text after [`check_text`].
    pub fn text(target: &str, text: String) -> Result<Self, NonFinite> {
        check_text(target, &text)?;
        Ok(Self { text })
    }

    /// Pretty JSON of `value` after [`check_value`], as [`json`].
    pub fn json<T: Serialize + ?Sized>(target: &str, value: &T) -> anyhow::Result<Self> {
        Ok(Self {
            text: json(target, value)?,
        })
    }

    /// Pretty JSON of `object`, as [`json`] writes it: every field was
    /// checked when it was added ([`JsonObject::field`]), so the object is
    /// not walked again.
    pub fn json_object(object: &JsonObject) -> anyhow::Result<Self> {
        Ok(Self {
            text: object.text()?,
        })
    }

    /// The text.
    pub fn as_str(&self) -> &str {
        &self.text
    }
}

/// Writes text that passed its check, atomically.
pub fn write_checked(path: &Path, text: &CheckedText) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit_checked(text)
}

/// Writes several files that passed their checks, each atomically as
/// [`write_checked`] writes it. When every target is a regular file (or a
/// new path), each text goes into its temporary file and is flushed to
/// disk side by side, then each is renamed over its target in the order
/// given: a file that cannot be created or written then leaves every
/// file of the set as it was (a rename that fails leaves those before it
/// replaced). All the new files are on disk at once before the renames.
/// A set with a device or FIFO among its targets is written one file
/// after another, as [`write_checked`] would (never side by side: two
/// outputs may reach one device, and a FIFO waits for its reader).
pub fn write_checked_all(files: &[(PathBuf, &CheckedText)]) -> anyhow::Result<()> {
    let mut atomics = files
        .iter()
        .map(|(path, _)| AtomicFile::create(path))
        .collect::<anyhow::Result<Vec<_>>>()?;
    if !atomics.iter().all(AtomicFile::replaces) {
        drop(atomics);
        for (path, text) in files {
            write_checked(path, text)?;
        }
        return Ok(());
    }
    let staged: Vec<anyhow::Result<()>> = atomics
        .par_iter_mut()
        .zip(files.par_iter())
        .map(|(file, (_, text))| file.stage(text))
        .collect();
    // The first failure in the order given.
    staged.into_iter().collect::<anyhow::Result<()>>()?;
    for (file, (_, text)) in atomics.into_iter().zip(files) {
        file.commit_checked(text)?;
    }
    Ok(())
}

/// Writes a CSV file, atomically, after [`check_csv`].
pub fn write_csv(path: &Path, text: &str) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit_csv(text)
}

/// Writes an SVG (or other text) file, atomically, after [`check_text`].
pub fn write_svg(path: &Path, text: &str) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit_svg(text)
}

/// Pretty JSON of `value` after [`check_value`] (`target` names where it
/// goes, for the error).
pub fn json<T: Serialize + ?Sized>(target: &str, value: &T) -> anyhow::Result<String> {
    check_value(target, value)?;
    Ok(serde_json::to_string_pretty(value)?)
}

/// Writes `text` (a file the caller formatted: TOML, a report) atomically,
/// after the same check as an SVG's: no non-finite number in it.
pub fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit_svg(text)
}

/// `value` as one line of compact JSON (no newline) after the same check
/// as [`json`]: a message of a line protocol (the Ray drivers').
pub fn json_line<T: Serialize + ?Sized>(target: &str, value: &T) -> anyhow::Result<String> {
    check_value(target, value)?;
    Ok(serde_json::to_string(value)?)
}

/// Writes `value` as a pretty JSON file, atomically.
pub fn write_json<T: Serialize + ?Sized>(path: &Path, value: &T) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit_json(value)
}

/// Writes `value` as TOML after `header` (comment lines), atomically.
pub fn write_toml<T: Serialize + ?Sized>(
    path: &Path,
    header: &str,
    value: &T,
) -> anyhow::Result<()> {
    AtomicFile::create(path)?.commit_toml(header, value)
}

/// Prints `value` as pretty JSON on standard output.
pub fn print_json<T: Serialize + ?Sized>(value: &T) -> anyhow::Result<()> {
    let text = json("standard output", value)?;
    crate::outln!("{text}");
    Ok(())
}

/// `value` as TOML after `header` (comment lines), after [`check_value`]
/// (`target` names where it goes, for the error).
pub fn toml<T: Serialize + ?Sized>(
    target: &str,
    header: &str,
    value: &T,
) -> anyhow::Result<String> {
    check_value(target, value)?;
    Ok(format!("{header}{}", toml::to_string_pretty(value)?))
}

/// Prints `value` as TOML after `header` on standard output.
pub fn print_toml<T: Serialize + ?Sized>(header: &str, value: &T) -> anyhow::Result<()> {
    let text = toml("standard output", header, value)?;
    crate::out!("{text}");
    Ok(())
}

/// Prints CSV text on standard output after [`check_csv`].
pub fn print_csv(text: &str) -> anyhow::Result<()> {
    check_csv("standard output", text)?;
    crate::out!("{text}");
    Ok(())
}

/// A JSON object built field by field, each checked as it is added (the
/// checked form of `serde_json::json!({…})`, which turns NaN into `null`
/// before anything could see it). Keys come out sorted.
#[derive(Default)]
pub struct JsonObject(serde_json::Map<String, serde_json::Value>);

impl JsonObject {
    /// An empty object.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `key`: `value`, refusing a non-finite number anywhere in it.
    pub fn field<T: Serialize + ?Sized>(mut self, key: &str, value: &T) -> anyhow::Result<Self> {
        check_field("the JSON summary", key, value)?;
        self.0.insert(key.to_string(), serde_json::to_value(value)?);
        Ok(self)
    }

    /// Adds `key`: an array of `objects`, each checked field by field when
    /// it was built (so neither walked nor copied again).
    pub fn objects(mut self, key: &str, objects: Vec<JsonObject>) -> Self {
        let items = objects
            .into_iter()
            .map(|o| serde_json::Value::Object(o.0))
            .collect();
        self.0
            .insert(key.to_string(), serde_json::Value::Array(items));
        self
    }

    /// The fields of `value` (a report struct), each checked as
    /// [`field`](Self::field) checks it; more fields may follow.
    pub fn of<T: Serialize + ?Sized>(value: &T) -> anyhow::Result<Self> {
        check_field("the JSON summary", "", value)?;
        match serde_json::to_value(value)? {
            serde_json::Value::Object(fields) => Ok(Self(fields)),
            other => anyhow::bail!("the JSON summary is not an object: {other}"),
        }
    }

    /// Prints the object on standard output.
    pub fn print(self) -> anyhow::Result<()> {
        print_json(&self.0)
    }

    /// The object as pretty JSON text (what [`print`](Self::print) prints,
    /// without the newline).
    pub fn text(&self) -> anyhow::Result<String> {
        Ok(serde_json::to_string_pretty(&self.0)?)
    }
}

/// A field already added (`Value::Null` if there is none), for a text
/// report made from the same checked object.
impl std::ops::Index<&str> for JsonObject {
    type Output = serde_json::Value;

    fn index(&self, key: &str) -> &serde_json::Value {
        self.0.get(key).unwrap_or(&serde_json::Value::Null)
    }
}

impl Serialize for JsonObject {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.0.serialize(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An array of objects added whole (`objects`, not walked or copied
    /// again) is the same JSON as the same objects added as a field, and
    /// a checked object's text is what `json` writes of it.
    #[test]
    fn objects_added_whole_are_the_same_json_as_a_field_of_them() {
        #[derive(serde::Serialize)]
        struct Inner {
            zeta: f64,
            alpha: Vec<f64>,
            name: &'static str,
            none: Option<f64>,
        }
        let parts = || -> Vec<JsonObject> {
            (0..3)
                .map(|k| {
                    JsonObject::new()
                        .field("frame", &(k as f64))
                        .unwrap()
                        .field(
                            "signature",
                            &Inner {
                                zeta: 0.1 * k as f64,
                                alpha: vec![1.0, 2.5e-9, -3.0],
                                name: "a\"b",
                                none: None,
                            },
                        )
                        .unwrap()
                })
                .collect()
        };
        let whole = JsonObject::new()
            .field("model", "signature")
            .unwrap()
            .objects("splines", parts());
        let fielded = JsonObject::new()
            .field("model", "signature")
            .unwrap()
            .field("splines", &parts())
            .unwrap();
        assert_eq!(whole.text().unwrap(), fielded.text().unwrap());
        assert_eq!(
            CheckedText::json_object(&whole).unwrap().as_str(),
            json("t", &fielded).unwrap()
        );
        // A part with a non-finite number never becomes an object.
        assert!(JsonObject::new().field("x", &[1.0, f64::NAN]).is_err());
    }

    #[test]
    fn csv_names_line_and_column_of_a_non_finite_field() {
        let ok = "t_s,x_m\n# comment\n0,1e-3\n1,-2\n";
        assert!(check_csv("f.csv", ok).is_ok());
        for (bad, line, column, value) in [
            ("t_s,x_m\n0,1\n1,NaN\n", 3, "x_m", "NaN"),
            ("t_s,x_m\n\n0,inf\n", 3, "x_m", "inf"),
            ("t_s,x_m\n-inf,0\n", 2, "t_s", "-inf"),
            ("t_s,x_m\n0,1e999\n", 2, "x_m", "1e999"),
        ] {
            let e = check_csv("f.csv", bad).unwrap_err();
            assert_eq!(e.place, format!("line {line}, column `{column}`"), "{bad}");
            assert_eq!(e.value, value);
            let text = e.to_string();
            assert!(
                text.contains("f.csv") && text.contains("not a finite number"),
                "{text}"
            );
        }
        // Words that merely contain the letters are not numbers.
        assert!(check_csv("f.csv", "label,info\nnanny,infinite_loop\n").is_ok());
    }

    /// The scanner that parses only words with a letter or of over 300
    /// characters finds, on random text of number-like words, exactly
    /// the word that parsing every word finds.
    #[test]
    fn the_word_scanner_finds_what_parsing_every_word_finds() {
        use rand::{Rng, SeedableRng};
        fn parse_every_word(text: &str) -> Option<&str> {
            text.split(|c: char| !(c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.' | '_')))
                .find(|w| w.parse::<f64>().is_ok_and(|v| !v.is_finite()))
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(45);
        let pieces = [
            "0", "1", "9", "-", "+", ".", "e", "E", "_", "inf", "NaN", "infinity", "x", " ", ",",
        ];
        let mut non_finite_found = 0;
        for _ in 0..20_000 {
            let n = rng.gen_range(1..12);
            let mut text: String = (0..n)
                .map(|_| pieces[rng.gen_range(0..pieces.len())])
                .collect();
            if rng.gen_bool(0.05) {
                // Long digit strings: finite up to 308 digits, inf from 309.
                let digits = rng.gen_range(295..320);
                text.push(' ');
                text.extend(std::iter::repeat_n('9', digits));
            }
            let fast = non_finite_word(&text);
            assert_eq!(fast, parse_every_word(&text), "{text:?}");
            non_finite_found += usize::from(fast.is_some());
        }
        // Both outcomes are exercised, so the comparison can fail.
        assert!(
            non_finite_found > 1_000 && non_finite_found < 19_000,
            "{non_finite_found}"
        );
        let long = "9".repeat(309);
        assert_eq!(non_finite_word(&long), Some(long.as_str()));
        assert_eq!(non_finite_word(&"9".repeat(308)), None);
    }

    /// The one-pass screen of a whole file says "may hold one" exactly
    /// when the line-by-line scan of its words finds one, on random
    /// multi-line text with separators of every kind (commas, blanks,
    /// `<`, `"`, non-ASCII letters, whose bytes are not word bytes).
    #[test]
    fn the_whole_text_screen_agrees_with_the_word_scan() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(34);
        let pieces = [
            "0", "7", "-", "+", ".", "e", "_", "inf", "NaN", "x", " ", ",", "\n", "<", "\"", "é",
            "∞", "µ",
        ];
        let mut found = 0;
        for _ in 0..20_000 {
            let n = rng.gen_range(0..16);
            let mut text: String = (0..n)
                .map(|_| pieces[rng.gen_range(0..pieces.len())])
                .collect();
            if rng.gen_bool(0.05) {
                text.push(if rng.gen_bool(0.5) { ',' } else { 'é' });
                text.extend(std::iter::repeat_n('9', rng.gen_range(295..320)));
            }
            let by_lines = text.lines().any(|l| non_finite_word(l).is_some());
            assert_eq!(may_hold_non_finite(&text), by_lines, "{text:?}");
            found += usize::from(by_lines);
            // And the checks give what the line-by-line scan alone gives.
            assert_eq!(check_text("t", &text).is_err(), by_lines, "{text:?}");
        }
        assert!(found > 1_000 && found < 19_000, "{found}");
    }

    #[test]
    fn text_and_values_are_checked_too() {
        assert!(check_text("a.svg", "<text>F = 0.500</text>").is_ok());
        let e = check_text("a.svg", "<svg>\n<text>F = NaN</text>").unwrap_err();
        assert_eq!((e.place.as_str(), e.value.as_str()), ("line 2", "NaN"));
        assert!(check_text("a.svg", r#"<path d="M1.0,inf"/>"#).is_err());
        let e = check_value("out.json", &serde_json::json!({"a": [1.0]})).map(|_| ());
        assert!(e.is_ok());
        let e = json("out.json", &[1.0, f64::NAN]).unwrap_err().to_string();
        assert!(e.contains("out.json") && e.contains("field `[1]`"), "{e}");
        let e = JsonObject::new()
            .field("mean_f", &f64::INFINITY)
            .err()
            .map(|e| format!("{e:#}"))
            .unwrap();
        assert!(e.contains("mean_f") && e.contains("inf"), "{e}");
    }
}
