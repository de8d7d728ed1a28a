//! Plain-text input for the viscoelastic tools: numeric CSV with a header,
//! checked line by line (missing columns, wrong field counts, non-numbers,
//! NaN/∞, time that does not strictly increase), and the probe-script CSV.
//! Every error names the file, the 1-based line and the reason.
use super::error::{Result, VeError};
use super::object::{Contact, ProbeEvent};

/// Named numeric columns read from a CSV file.
#[derive(Clone, Debug, PartialEq)]
pub struct Columns {
    /// Column names, in the order asked for.
    pub names: Vec<String>,
    /// Values per asked column.
    pub values: Vec<Vec<f64>>,
}

impl Columns {
    /// The values of column `name` (which must have been asked for).
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .map(|i| self.values[i].as_slice())
    }
}

/// The header names of a CSV text (first non-empty, non-comment line).
pub fn header(text: &str) -> Vec<String> {
    text.lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#'))
        .map(|l| l.split(',').map(|s| s.trim().to_string()).collect())
        .unwrap_or_default()
}

/// Reads the columns `wanted` from CSV `text` (`file` names it in errors).
/// Blank lines and lines starting with `#` are skipped. If `time_column`
/// is given it must strictly increase.
pub fn read_columns(
    text: &str,
    file: &str,
    wanted: &[&str],
    time_column: Option<&str>,
) -> Result<Columns> {
    let err = |line: usize, reason: String| VeError::Parse {
        file: file.to_string(),
        line,
        reason,
    };
    let mut lines = text.lines().enumerate().filter(|(_, l)| {
        let t = l.trim();
        !t.is_empty() && !t.starts_with('#')
    });
    let Some((hline, head)) = lines.next() else {
        return Err(err(1, "empty file: expected a header line".into()));
    };
    let names: Vec<&str> = head.split(',').map(str::trim).collect();
    let mut idx = Vec::new();
    for w in wanted {
        match names.iter().position(|n| n == w) {
            Some(i) => idx.push(i),
            None => {
                return Err(err(
                    hline + 1,
                    format!("missing column `{w}` (header has: {})", names.join(", ")),
                ));
            }
        }
    }
    let mut values = vec![Vec::new(); wanted.len()];
    let time_pos = time_column.and_then(|t| wanted.iter().position(|w| *w == t));
    for (k, line) in lines {
        let line_no = k + 1;
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(err(
                line_no,
                format!(
                    "{} fields, but the header has {}",
                    fields.len(),
                    names.len()
                ),
            ));
        }
        for (c, &i) in idx.iter().enumerate() {
            let s = fields[i];
            let v: f64 = s
                .parse()
                .map_err(|_| err(line_no, format!("`{}` = `{s}` is not a number", wanted[c])))?;
            if !v.is_finite() {
                return Err(err(
                    line_no,
                    format!("`{}` = `{s}` is not finite (NaN or infinite)", wanted[c]),
                ));
            }
            if Some(c) == time_pos {
                if let Some(&prev) = values[c].last() {
                    if v <= prev {
                        return Err(err(
                            line_no,
                            format!("time must strictly increase: {v} after {prev}"),
                        ));
                    }
                    if !(v - prev).is_finite() {
                        return Err(err(
                            line_no,
                            format!(
                                "`{}` = {}: the step from {} is not finite (the times are too far apart for f64)",
                                wanted[c],
                                crate::short_number(v),
                                crate::short_number(prev)
                            ),
                        ));
                    }
                }
            }
            values[c].push(v);
        }
    }
    if values.first().is_none_or(|v| v.len() < 2) {
        return Err(err(hline + 1, "need at least 2 data rows".into()));
    }
    Ok(Columns {
        names: wanted.iter().map(|s| s.to_string()).collect(),
        values,
    })
}

/// The 1-based line numbers of the data rows of CSV `text` (the lines
/// after the header that are neither blank nor comments), in order: entry
/// `k` is the line of the `k`-th value [`read_columns`] returns.
pub fn data_line_numbers(text: &str) -> Vec<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim().starts_with('#'))
        .map(|(k, _)| k + 1)
        .skip(1)
        .collect()
}

/// Reads a probe script: columns `time_s,vertex,fx_n,fy_n,fz_n`; from each
/// row's time on the probe pushes mesh vertex `vertex` with that force, or
/// releases the object when `vertex` is −1.
pub fn read_probe_script(text: &str, file: &str, mesh_vertices: usize) -> Result<Vec<ProbeEvent>> {
    let cols = read_columns(
        text,
        file,
        &["time_s", "vertex", "fx_n", "fy_n", "fz_n"],
        Some("time_s"),
    )?;
    let get = |n: &str| cols.get(n).unwrap_or(&[]);
    let (t, v, fx, fy, fz) = (
        get("time_s"),
        get("vertex"),
        get("fx_n"),
        get("fy_n"),
        get("fz_n"),
    );
    let data_lines = data_line_numbers(text);
    let mut events = Vec::with_capacity(t.len());
    for k in 0..t.len() {
        let vertex = v[k];
        let contact = if vertex == -1.0 {
            None
        } else if vertex >= 0.0 && vertex.fract() == 0.0 && (vertex as usize) < mesh_vertices {
            Some(Contact::Vertex(vertex as usize))
        } else {
            return Err(VeError::Parse {
                file: file.to_string(),
                line: data_lines.get(k).copied().unwrap_or(0),
                reason: format!(
                    "vertex {vertex} is not −1 or a mesh vertex index below {mesh_vertices}"
                ),
            });
        };
        events.push(ProbeEvent {
            time_s: t[k],
            contact,
            force_n: [fx[k], fy[k], fz[k]],
        });
    }
    Ok(events)
}
