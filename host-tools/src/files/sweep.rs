//! Sweep files: wire insertions beside reference angles (CSV), the input of
//! `softjoint calibrate wire` and what `sim --calibration-sweep` writes.
use std::path::Path;

use anyhow::{bail, Context};
use plant_joint::identify::log::{MAX_ANGLE_DEG, MAX_INSERTION_MM};

/// One calibration sample: insertions (mm) and reference angles (deg).
#[derive(Clone, Debug, PartialEq)]
pub struct SweepRow {
    /// Insertions d1..dS (mm).
    pub d_mm: Vec<f64>,
    /// Reference angles: [θ] (2D) or [α, β] (3D).
    pub angle_deg: Vec<f64>,
}

/// Header of a 3D sweep file.
pub const HEADER_3D: &str = "d1_mm,d2_mm,d3_mm,d4_mm,alpha_deg,beta_deg";
/// Header of a 2D sweep file.
pub const HEADER_2D: &str = "d_mm,theta_deg";

/// Writes a sweep as CSV (3D if rows have 4 insertions, else 2D).
pub fn write_sweep(path: &Path, rows: &[SweepRow]) -> anyhow::Result<()> {
    let three_d = rows.first().map(|r| r.d_mm.len() == 4).unwrap_or(true);
    let mut s = String::new();
    s.push_str(if three_d { HEADER_3D } else { HEADER_2D });
    s.push('\n');
    for r in rows {
        let cells: Vec<String> = r
            .d_mm
            .iter()
            .chain(r.angle_deg.iter())
            .map(|v| format!("{v:.5}"))
            .collect();
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    crate::output::write_csv(path, &s)
}

/// Reads a sweep CSV; a bad row is an error naming the file and line.
pub fn read_sweep(path: &Path) -> anyhow::Result<Vec<SweepRow>> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    parse_sweep_named(&text, &path.display().to_string())
}

/// Parses sweep CSV text (header required: 3D or 2D columns, any order);
/// errors are labelled `sweep`.
pub fn parse_sweep(text: &str) -> anyhow::Result<Vec<SweepRow>> {
    parse_sweep_named(text, "sweep")
}

fn parse_sweep_named(text: &str, file: &str) -> anyhow::Result<Vec<SweepRow>> {
    let table = plant_common::csv_input::read_numeric(text, file)?;
    let find = |names: &[&str]| -> Option<Vec<usize>> {
        names
            .iter()
            .map(|n| table.columns.iter().position(|c| c == n))
            .collect()
    };
    let (d_cols, a_cols) = match (
        find(&["d1_mm", "d2_mm", "d3_mm", "d4_mm"]),
        find(&["alpha_deg", "beta_deg"]),
        find(&["d_mm"]),
        find(&["theta_deg"]),
    ) {
        (Some(d), Some(a), _, _) => (d, a),
        (_, _, Some(d), Some(a)) => (d, a),
        _ => bail!(
            "{file}:{}: the header must have the columns `{HEADER_3D}` (3D) or `{HEADER_2D}` (2D) in any order; it has: {}",
            table.header_line,
            plant_common::csv_input::excerpt(&table.columns.join(", "))
        ),
    };
    let mut rows = Vec::with_capacity(table.rows.len());
    for row in &table.rows {
        // The firmware estimates in f32: a value it cannot hold would only
        // surface later as an unusable fit.
        for (v, name) in row.values.iter().zip(&table.columns) {
            if !(*v as f32).is_finite() {
                bail!(
                    "{}",
                    table.error(
                        row.line,
                        Some(name),
                        format!(
                            "{v:e} is outside the f32 range the firmware computes in (|value| <= {:e})",
                            f32::MAX
                        )
                    )
                );
            }
        }
        // An outlier (a unit slip, a corrupted reading) is refused by row
        // rather than fitted: one row at 1e30° made `a` = 5e25.
        let bounds = [
            (&d_cols, MAX_INSERTION_MM, "mm", "a wire's insertion"),
            (&a_cols, MAX_ANGLE_DEG, "°", "any bend of the joint"),
        ];
        for (cols, limit, unit, what) in bounds {
            for &c in cols.iter() {
                let v = row.values[c];
                if v.abs() > limit {
                    bail!(
                        "{}",
                        table.error(
                            row.line,
                            Some(&table.columns[c]),
                            format!(
                                "{} {unit} is beyond {what} (|value| ≤ {} {unit})",
                                plant_common::short_number(v),
                                plant_common::short_number(limit)
                            )
                        )
                    );
                }
            }
        }
        rows.push(SweepRow {
            d_mm: d_cols.iter().map(|&c| row.values[c]).collect(),
            angle_deg: a_cols.iter().map(|&c| row.values[c]).collect(),
        });
    }
    table.require_rows(10, "to calibrate")?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_errors_name_the_line() {
        let e = parse_sweep("d_mm,theta_deg\n1,2\n3,x\n")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "sweep:3: column `theta_deg`: `x` is not a number");
        let e = parse_sweep("d_mm,theta_deg\n1,2\n3\n")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "sweep:3: 1 fields, but the header has 2");
        let e = parse_sweep("foo,bar\n").unwrap_err().to_string();
        assert!(e.starts_with("sweep:1: the header must have"), "{e}");
        let e = parse_sweep("d_mm,theta_deg\n1,NaN\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("sweep:2: column `theta_deg`"), "{e}");
        assert!(parse_sweep("").is_err());
        // An Excel export (byte-order mark, CRLF) reads like a plain file.
        let mut excel = String::from("\u{feff}d_mm,theta_deg\r\n");
        for i in 0..12 {
            excel.push_str(&format!("{},{}\r\n", f64::from(i) * 0.1, f64::from(i)));
        }
        assert_eq!(parse_sweep(&excel).unwrap().len(), 12);
    }
}
