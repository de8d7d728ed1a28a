//! Tracked contours from CSV: one row per contour point, grouped into
//! frames by an optional `frame` column (one frame without it).
//!
//! Two layouts (the header decides):
//! * signatures: `angle_rad,radius`, optionally with the centre
//!   `centre_x,centre_y` (default 0, 0) — the paper's form;
//! * points: `x,y`, in order along the contour.
//!
//! Read through the one CSV reader ([`plant_common::csv_input`]), so comments,
//! BOM, CRLF and quoting work and every value is a finite number; errors
//! name the file and line. Per frame: at least 3 points; within a frame no
//! two points at the same angle (signatures) or the same place in a row
//! (points).
use crate::error::{ContourError, Result};
use crate::identify::tracked::{Point, Signature, DUPLICATE_ANGLE_RAD, MIN_CONTOUR_POINTS};
use plant_common::csv_input::{read_numeric, Row, Table};
use std::f64::consts::TAU;

/// One frame of tracked contour data.
#[derive(Debug, Clone, PartialEq)]
pub enum FrameData {
    /// Radii at angles about a centre.
    Signature(Signature),
    /// Points in order along the contour.
    Points(Vec<Point>),
}

impl FrameData {
    /// Number of points.
    pub fn len(&self) -> usize {
        match self {
            FrameData::Signature(s) => s.radii.len(),
            FrameData::Points(p) => p.len(),
        }
    }

    /// True without points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The points of the contour (a signature's in order of angle).
    pub fn points(&self) -> Vec<Point> {
        match self {
            FrameData::Points(p) => p.clone(),
            FrameData::Signature(s) => {
                let mut order: Vec<usize> = (0..s.radii.len()).collect();
                order.sort_by(|&a, &b| s.angles_rad[a].total_cmp(&s.angles_rad[b]));
                let pts = s.points();
                order.into_iter().map(|k| pts[k]).collect()
            }
        }
    }
}

/// Contour data read from a file.
#[derive(Debug, Clone, PartialEq)]
pub struct ContourData {
    /// The file, for messages.
    pub file: String,
    /// (frame number, data), in increasing frame number.
    pub frames: Vec<(f64, FrameData)>,
}

/// Reads contour data from CSV `text` named `file`.
pub fn read_contour_csv(text: &str, file: &str) -> Result<ContourData> {
    let table = read_numeric(text, file).map_err(csv_error)?;
    table
        .require_rows(MIN_CONTOUR_POINTS, "(one contour of 3 points)")
        .map_err(csv_error)?;
    let frame_col = table
        .has("frame")
        .then(|| table.column("frame"))
        .transpose()
        .map_err(csv_error)?;
    let layout = Layout::of(&table)?;
    // Group rows by frame, keeping file order within a frame (a stable
    // sort by frame number).
    let key_of = |r: &Row| frame_col.map_or(0.0, |c| r.values[c]);
    let mut sorted: Vec<&Row> = table.rows.iter().collect();
    sorted.sort_by(|a, b| key_of(a).total_cmp(&key_of(b)));
    let mut frames = Vec::new();
    for group in sorted.chunk_by(|a, b| key_of(a) == key_of(b)) {
        let key = key_of(group[0]);
        let name = format!("{file}: frame {}", plant_common::short_number(key));
        if group.len() < MIN_CONTOUR_POINTS {
            return Err(ContourError::TooFewPoints {
                location: format!("{name} (line {})", group[0].line),
                got: group.len(),
                needed: MIN_CONTOUR_POINTS,
                why: "a closed contour",
            });
        }
        let data = match layout {
            Layout::Signature {
                angle,
                radius,
                centre,
            } => signature_frame(&table, group, key, &name, (angle, radius, centre))?,
            Layout::Points { x, y } => points_frame(file, group, key, x, y)?,
        };
        frames.push((key, data));
    }
    Ok(ContourData {
        file: file.to_string(),
        frames,
    })
}

/// Which layout a table has, as its column indices.
#[derive(Clone, Copy)]
enum Layout {
    /// `angle_rad,radius`, optionally `centre_x,centre_y`.
    Signature {
        angle: usize,
        radius: usize,
        centre: Option<(usize, usize)>,
    },
    /// `x,y`.
    Points { x: usize, y: usize },
}

impl Layout {
    /// The layout the header names; an error if it names both or neither.
    fn of(table: &Table) -> Result<Layout> {
        let signature = table.has("angle_rad") || table.has("radius");
        let points = table.has("x") || table.has("y");
        if signature == points {
            return Err(ContourError::MalformedInput {
                location: format!("{}:{}", table.file, table.header_line),
                reason: format!(
                    "expected the columns `angle_rad,radius` (optionally `centre_x,centre_y`) or `x,y`, each optionally with `frame`; the header has: {}",
                    table.columns.join(", ")
                ),
            });
        }
        let column = |name: &str| table.column(name).map_err(csv_error);
        if signature {
            let (angle, radius) = (column("angle_rad")?, column("radius")?);
            let centre = if table.has("centre_x") || table.has("centre_y") {
                Some((column("centre_x")?, column("centre_y")?))
            } else {
                None
            };
            Ok(Layout::Signature {
                angle,
                radius,
                centre,
            })
        } else {
            Ok(Layout::Points {
                x: column("x")?,
                y: column("y")?,
            })
        }
    }
}

/// A frame of signature rows (`columns`: angle, radius and the centre's
/// columns if any): one centre, no two points at one angle.
fn signature_frame(
    table: &Table,
    rows: &[&Row],
    key: f64,
    name: &str,
    columns: (usize, usize, Option<(usize, usize)>),
) -> Result<FrameData> {
    let (angle, radius, centre) = columns;
    let angles: Vec<f64> = rows.iter().map(|r| r.values[angle]).collect();
    let radii: Vec<f64> = rows.iter().map(|r| r.values[radius]).collect();
    let centre = match centre {
        Some((cx, cy)) => {
            let c = (rows[0].values[cx], rows[0].values[cy]);
            if let Some(r) = rows.iter().find(|r| (r.values[cx], r.values[cy]) != c) {
                return Err(table_error(
                    table,
                    r.line,
                    "the centre (centre_x, centre_y) changes within a frame",
                ));
            }
            c
        }
        None => (0.0, 0.0),
    };
    check_distinct_angles(&table.file, rows, &angles, key)?;
    Ok(FrameData::Signature(Signature::new(
        name, centre, &angles, &radii,
    )?))
}

/// No two of a frame's angles within [`DUPLICATE_ANGLE_RAD`] of each
/// other (around the circle); the error names both lines.
fn check_distinct_angles(file: &str, rows: &[&Row], angles: &[f64], key: f64) -> Result<()> {
    let mut order: Vec<usize> = (0..angles.len()).collect();
    order.sort_by(|&a, &b| {
        angles[a]
            .rem_euclid(TAU)
            .total_cmp(&angles[b].rem_euclid(TAU))
    });
    for w in 0..order.len() {
        let (i, j) = (order[w], order[(w + 1) % order.len()]);
        let mut gap = angles[j].rem_euclid(TAU) - angles[i].rem_euclid(TAU);
        if w + 1 == order.len() {
            gap += TAU;
        }
        if gap.abs() < DUPLICATE_ANGLE_RAD {
            let (a, b) = (rows[i.min(j)].line, rows[i.max(j)].line);
            return Err(ContourError::DuplicateParameter {
                location: format!(
                    "{file}:{b}: frame {} (same angle as line {a})",
                    plant_common::short_number(key)
                ),
                axis: "angle",
                value: angles[i.max(j)],
                first: i.min(j),
                second: i.max(j),
            });
        }
    }
    Ok(())
}

/// A frame of point rows: consecutive points (around the contour) differ.
fn points_frame(file: &str, rows: &[&Row], key: f64, x: usize, y: usize) -> Result<FrameData> {
    let pts: Vec<Point> = rows.iter().map(|r| (r.values[x], r.values[y])).collect();
    for k in 0..pts.len() {
        let next = (k + 1) % pts.len();
        if pts[k] == pts[next] {
            let (a, b) = (rows[k.min(next)].line, rows[k.max(next)].line);
            return Err(ContourError::DuplicateParameter {
                location: format!(
                    "{file}:{b}: frame {} (same point as line {a}; consecutive points must differ)",
                    plant_common::short_number(key)
                ),
                axis: "point",
                value: k as f64,
                first: k.min(next),
                second: k.max(next),
            });
        }
    }
    Ok(FrameData::Points(pts))
}

fn csv_error(e: plant_common::csv_input::CsvError) -> ContourError {
    ContourError::MalformedInput {
        location: match &e.column {
            Some(c) => format!("{}:{}: column `{c}`", e.file, e.line),
            None => format!("{}:{}", e.file, e.line),
        },
        reason: e.reason,
    }
}

fn table_error(table: &Table, line: usize, reason: &str) -> ContourError {
    ContourError::MalformedInput {
        location: format!("{}:{line}", table.file),
        reason: reason.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_grouped_and_bad_rows_named_by_line() {
        let text = "frame,angle_rad,radius\n1,0,1\n0,0,2\n1,2,1\n0,2,2\n1,4,1\n0,4,2\n";
        let d = read_contour_csv(text, "a.csv").unwrap();
        assert_eq!(d.frames.len(), 2);
        assert_eq!(d.frames[0].0, 0.0);
        assert_eq!(d.frames[0].1.len(), 3);
        let e = read_contour_csv("angle_rad,radius\n0,1\n1,1\n1,2\n", "b.csv").unwrap_err();
        assert!(
            e.to_string().contains("b.csv:4") && e.to_string().contains("line 3"),
            "{e}"
        );
        let e = read_contour_csv("angle_rad,radius\n0,1\n1,nan\n2,2\n", "c.csv").unwrap_err();
        assert!(
            e.to_string().contains("c.csv:3") && e.to_string().contains("radius"),
            "{e}"
        );
        let e = read_contour_csv("frame,x,y\n0,0,0\n0,1,0\n1,0,0\n1,1,0\n1,1,1\n", "d.csv")
            .unwrap_err();
        assert!(
            e.to_string().contains("frame 0") && e.to_string().contains("too few points"),
            "{e}"
        );
        let e = read_contour_csv("x,radius\n0,0\n1,0\n1,1\n", "e.csv").unwrap_err();
        assert!(e.to_string().contains("expected the columns"), "{e}");
        let e = read_contour_csv("x,y\n0,0\n1,0\n1,0\n", "f.csv").unwrap_err();
        assert!(
            e.to_string().contains("f.csv:4") && e.to_string().contains("same point as line 3"),
            "{e}"
        );
        let e = read_contour_csv(
            "angle_rad,radius,centre_x,centre_y\n0,1,0,0\n1,1,0,1\n2,2,0,0\n",
            "g.csv",
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("g.csv:3") && e.to_string().contains("centre"),
            "{e}"
        );
    }
}
