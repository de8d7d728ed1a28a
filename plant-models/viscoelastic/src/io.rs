//! Plain-text input for the viscoelastic tools, read with the one CSV
//! reader ([`plant_common::csv_input`]): named numeric columns (with time that
//! must strictly increase) and the probe script. Every error names the
//! file, the 1-based line and the reason.
use crate::error::{Result, VeError};
use crate::object::{Contact, ProbeEvent};
use plant_common::csv_input::{read_numeric, CsvError, Table};

impl From<CsvError> for VeError {
    fn from(e: CsvError) -> Self {
        VeError::Parse {
            file: e.file,
            line: e.line,
            reason: match e.column {
                Some(c) => format!("column `{c}`: {}", e.reason),
                None => e.reason,
            },
        }
    }
}

/// Named numeric columns read from a CSV file.
#[derive(Clone, Debug, PartialEq)]
pub struct Columns {
    /// Column names, in the order asked for.
    pub names: Vec<String>,
    /// Values per asked column.
    pub values: Vec<Vec<f64>>,
    /// The 1-based line of each row.
    pub lines: Vec<usize>,
}

impl Columns {
    /// The values of column `name` (which must have been asked for).
    pub fn get(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .and_then(|i| self.values.get(i))
            .map(Vec::as_slice)
    }
}

/// The largest force a probe script may apply (N). The seed's haptic
/// probe presses a soft object with a few newtons, and no hand-held or
/// robot-finger probe of a deformable object reaches a kilonewton; the
/// bound refuses typos and unit slips (µN, dyn) before a run divides by
/// them, not forces a probe can make.
pub const MAX_PROBE_FORCE_N: f64 = 1e3;

/// The largest force a creep/relaxation trial may record (N): indentation
/// and compression trials of soft materials (tissue, food, gels) stay
/// below a few hundred newtons; 10 kN is a bench press's load cell.
pub const MAX_TRIAL_FORCE_N: f64 = 1e4;

/// The largest displacement a trial may record (m): a soft sample a metre
/// thick compressed through itself.
pub const MAX_TRIAL_DISPLACEMENT_M: f64 = 1.0;

/// Refuses a value of column `name` whose magnitude exceeds `limit`
/// (`unit`), naming the file, line and column and what the bound is for
/// (`what`).
pub fn check_magnitude(
    cols: &Columns,
    file: &str,
    name: &str,
    limit: f64,
    unit: &str,
    what: &str,
) -> Result<()> {
    let values = cols.get(name).unwrap_or(&[]);
    for (v, line) in values.iter().zip(&cols.lines) {
        if v.abs() > limit {
            return Err(VeError::Parse {
                file: file.to_string(),
                line: *line,
                reason: format!(
                    "column `{name}`: {} {unit} is beyond {what} (|{name}| ≤ {} {unit}); is it in another unit?",
                    plant_common::short_number(*v),
                    plant_common::short_number(limit)
                ),
            });
        }
    }
    Ok(())
}

/// Reads CSV `text` (`file` names it in errors) as a numeric table.
pub fn read_table(text: &str, file: &str) -> Result<Table> {
    Ok(read_numeric(text, file)?)
}

/// Reads the columns `wanted` from CSV `text` (`file` names it in errors).
/// If `time_column` is given it must strictly increase.
pub fn read_columns(
    text: &str,
    file: &str,
    wanted: &[&str],
    time_column: Option<&str>,
) -> Result<Columns> {
    columns_of(&read_table(text, file)?, wanted, time_column)
}

/// The columns `wanted` of `table`, at least 2 rows; `time_column`, if
/// given, must strictly increase in finite steps.
pub fn columns_of(table: &Table, wanted: &[&str], time_column: Option<&str>) -> Result<Columns> {
    let idx = wanted
        .iter()
        .map(|w| table.column(w))
        .collect::<std::result::Result<Vec<_>, _>>()?;
    table.require_rows(2, "(a series)")?;
    if let Some(tc) = time_column {
        let t = table.column(tc)?;
        for w in table.rows.windows(2) {
            let (prev, v) = (w[0].values[t], w[1].values[t]);
            if v <= prev {
                return Err(table
                    .error(
                        w[1].line,
                        Some(tc),
                        format!("time must strictly increase: {v} after {prev}"),
                    )
                    .into());
            }
            if !(v - prev).is_finite() {
                return Err(table
                    .error(
                        w[1].line,
                        Some(tc),
                        format!(
                            "{}: the step from {} is not finite (the times are too far apart for f64)",
                            plant_common::short_number(v),
                            plant_common::short_number(prev)
                        ),
                    )
                    .into());
            }
        }
    }
    Ok(Columns {
        names: wanted.iter().map(|s| s.to_string()).collect(),
        values: idx.iter().map(|&i| table.values(i)).collect(),
        lines: table.rows.iter().map(|r| r.line).collect(),
    })
}

/// A probe script: the events and the line of each.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeScript {
    /// The events, in time order.
    pub events: Vec<ProbeEvent>,
    /// The 1-based line of each event.
    pub lines: Vec<usize>,
}

/// Reads a probe script: columns `time_s,vertex,fx_n,fy_n,fz_n`; from each
/// row's time on the probe pushes mesh vertex `vertex` with that force, or
/// releases the object when `vertex` is −1.
pub fn read_probe_script(text: &str, file: &str, mesh_vertices: usize) -> Result<ProbeScript> {
    let cols = read_columns(
        text,
        file,
        &["time_s", "vertex", "fx_n", "fy_n", "fz_n"],
        Some("time_s"),
    )?;
    for axis in ["fx_n", "fy_n", "fz_n"] {
        check_magnitude(
            &cols,
            file,
            axis,
            MAX_PROBE_FORCE_N,
            "N",
            "any probe's force",
        )?;
    }
    let get = |n: &str| cols.get(n).unwrap_or(&[]);
    let (t, v, fx, fy, fz) = (
        get("time_s"),
        get("vertex"),
        get("fx_n"),
        get("fy_n"),
        get("fz_n"),
    );
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
                line: cols.lines[k],
                reason: format!(
                    "column `vertex`: {vertex} is not −1 or a mesh vertex index below {mesh_vertices}"
                ),
            });
        };
        events.push(ProbeEvent {
            time_s: t[k],
            contact,
            force_n: [fx[k], fy[k], fz[k]],
        });
    }
    Ok(ProbeScript {
        events,
        lines: cols.lines,
    })
}
