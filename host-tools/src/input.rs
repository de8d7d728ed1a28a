//! Reading the TOML and JSON files a user gives (scenarios, calibrations,
//! parameter files): one way, with errors that say `file:line:column`, the
//! reason, and at most a short excerpt of the offending text (a 3 MB line
//! used to be echoed twice into stderr).
//!
//! Unknown keys are refused by the input structs
//! (`#[serde(deny_unknown_fields)]`); duplicate keys by the TOML parser,
//! and for JSON by [`from_json`], which checks every object of the file
//! before serde_json's last-one-wins can hide one.
use std::collections::HashSet;
use std::fmt;

use anyhow::anyhow;
use plant_common::csv_input::excerpt;
use serde::de::{self, DeserializeOwned, DeserializeSeed, MapAccess, SeqAccess, Visitor};

/// 1-based line and column of byte `at` in `text`, and that line.
fn locate(text: &str, at: usize) -> (usize, usize, &str) {
    let at = at.min(text.len());
    let start = text[..at].rfind('\n').map_or(0, |i| i + 1);
    let end = text[at..].find('\n').map_or(text.len(), |i| at + i);
    let line = text[..start].matches('\n').count() + 1;
    let column = text[start..at].chars().count() + 1;
    (line, column, &text[start..end])
}

/// Up to 60 characters of `line` around `column` (1-based, in chars).
fn near(line: &str, column: usize) -> String {
    let chars: Vec<char> = line.trim_end_matches('\r').chars().collect();
    if chars.len() <= 60 {
        return chars.iter().collect();
    }
    let from = column.saturating_sub(20).min(chars.len());
    let to = (from + 60).min(chars.len());
    let mut s: String = chars[from..to].iter().collect();
    if from > 0 {
        s.insert(0, '…');
    }
    if to < chars.len() {
        s.push('…');
    }
    s
}

/// Parses TOML `text` of `file` into `T` (a leading byte-order mark, as
/// Windows editors write it, is dropped).
pub fn from_toml<T: DeserializeOwned>(text: &str, file: &str) -> anyhow::Result<T> {
    let text = plant_common::strip_bom(text);
    toml::from_str(text).map_err(|e| {
        let message = excerpt_lines(e.message());
        match e.span() {
            Some(span) => {
                let (line, column, src) = locate(text, span.start);
                anyhow!(
                    "{file}:{line}:{column}: {message} (near `{}`)",
                    near(src, column)
                )
            }
            None => anyhow!("{file}: {message}"),
        }
    })
}

/// A parser's message, each line cut to a readable length (messages quote
/// the offending value, which may be huge).
fn excerpt_lines(message: &str) -> String {
    message
        .trim_end()
        .lines()
        .map(|l| {
            if l.chars().count() > 200 {
                let head: String = l.chars().take(200).collect();
                format!("{head}…")
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

/// Parses JSON `text` of `file` into `T`, refusing duplicate keys in any
/// object first (a leading byte-order mark is dropped).
pub fn from_json<T: DeserializeOwned>(text: &str, file: &str) -> anyhow::Result<T> {
    let text = plant_common::strip_bom(text);
    let json_error = |e: serde_json::Error| {
        let full = e.to_string();
        let suffix = format!(" at line {} column {}", e.line(), e.column());
        let message = excerpt_lines(full.strip_suffix(&suffix).unwrap_or(&full));
        let src = text.lines().nth(e.line().saturating_sub(1)).unwrap_or("");
        if e.line() == 0 {
            anyhow!("{file}: {message}")
        } else {
            anyhow!(
                "{file}:{}:{}: {message} (near `{}`)",
                e.line(),
                e.column(),
                near(src, e.column())
            )
        }
    };
    let mut de = serde_json::Deserializer::from_str(text);
    UniqueKeys {
        path: String::new(),
    }
    .deserialize(&mut de)
    .map_err(json_error)?;
    serde_json::from_str(text).map_err(json_error)
}

/// Walks a JSON document and fails at the first object that has a key
/// twice, naming its path.
struct UniqueKeys {
    path: String,
}

impl<'de> DeserializeSeed<'de> for UniqueKeys {
    type Value = ();
    fn deserialize<D: de::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

macro_rules! accept_scalars {
    ($($method:ident: $ty:ty),* $(,)?) => {
        $(fn $method<E: de::Error>(self, _v: $ty) -> Result<(), E> { Ok(()) })*
    };
}

impl<'de> Visitor<'de> for UniqueKeys {
    type Value = ();

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON value")
    }

    accept_scalars!(
        visit_bool: bool,
        visit_i64: i64,
        visit_u64: u64,
        visit_f64: f64,
        visit_str: &str,
    );

    fn visit_unit<E: de::Error>(self) -> Result<(), E> {
        Ok(())
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        let mut i = 0usize;
        while seq
            .next_element_seed(UniqueKeys {
                path: format!("{}[{i}]", self.path),
            })?
            .is_some()
        {
            i += 1;
        }
        Ok(())
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = HashSet::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = if self.path.is_empty() {
                key.clone()
            } else {
                format!("{}.{key}", self.path)
            };
            if !seen.insert(key) {
                return Err(de::Error::custom(format!(
                    "duplicate key `{}`: a value given twice would silently be the last one",
                    excerpt(&path)
                )));
            }
            map.next_value_seed(UniqueKeys { path })?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(serde::Deserialize, Debug)]
    #[serde(deny_unknown_fields)]
    struct P {
        #[allow(dead_code)]
        k: f64,
    }

    #[test]
    fn json_duplicate_and_unknown_keys_are_named() {
        let e = from_json::<P>("{\"k\": 1,\n \"k\": 2}", "p.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.json:2:") && e.contains("duplicate key `k`"),
            "{e}"
        );
        let e = from_json::<serde_json::Value>(r#"{"a": [{"x": 1, "x": 1}]}"#, "q.json")
            .unwrap_err()
            .to_string();
        assert!(e.contains("duplicate key `a[0].x`"), "{e}");
        let e = from_json::<P>(r#"{"k": 1, "kk": 2}"#, "p.json")
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown field `kk`"), "{e}");
        assert!(from_json::<P>(r#"{"k": -1.5}"#, "p.json").is_ok());
    }

    #[test]
    fn toml_errors_give_file_line_column_and_an_excerpt_only() {
        let long = format!("a = 1\nname = \"{}", "x".repeat(3_000_000));
        let e = from_toml::<toml::Value>(&long, "s.toml")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("s.toml:2:"), "{}", &e[..100]);
        assert!(e.len() < 500, "{} bytes", e.len());
        let e = from_toml::<toml::Value>("a = 1\na = 2\n", "s.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("s.toml:2:") && e.contains("duplicate key"),
            "{e}"
        );
    }
}
