//! A recorded push as CSV, so that tracked contours and force readings from
//! elsewhere (or from [`crate::reference`]) can be scored and calibrated on.
//!
//! One row per contour point: `frame,force_n,x_px,y_px`. Frames are numbered
//! 0, 1, 2, … without gaps, rows of a frame are consecutive and list its
//! contour in order, and every row of a frame repeats the same force
//! reading (N, along the push direction). Lines starting with `#` and blank
//! lines are skipped. The scenario (block, finger path, frame interval) is
//! not in the file: the caller supplies it and the frame count must match.
use crate::error::{PushError, Result};
use crate::reference::Video;
use crate::scenario::PushScenario;
use crate::V2;
use std::fmt::Write as _;

/// The header line written and expected.
pub const HEADER: &str = "frame,force_n,x_px,y_px";

/// Writes `video` in the format above.
pub fn write_video_csv(video: &Video) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# push video: material {}, site {}",
        video.material,
        video.scenario.site.name()
    );
    let _ = writeln!(s, "{HEADER}");
    for (f, (contour, force)) in video.contours_px.iter().zip(&video.forces_n).enumerate() {
        for p in contour {
            let _ = writeln!(s, "{f},{force},{},{}", p.x, p.y);
        }
    }
    s
}

fn bad(file: &str, line: usize, reason: impl Into<String>) -> PushError {
    PushError::MalformedInput {
        location: format!("{file}:{line}"),
        reason: reason.into(),
    }
}

impl From<plant_common::csv_input::CsvError> for PushError {
    fn from(e: plant_common::csv_input::CsvError) -> Self {
        PushError::MalformedInput {
            location: format!("{}:{}", e.file, e.line),
            reason: match e.column {
                Some(c) => format!("column `{c}`: {}", e.reason),
                None => e.reason,
            },
        }
    }
}

/// Largest |contour coordinate| a video may hold (px). A camera frame is a
/// few thousand pixels; coordinates far beyond overflowed the block's mesh
/// (`vertex 2 has a non-finite coordinate`, naming no file or line). A
/// million pixels is far outside any frame (estimate).
pub const MAX_COORDINATE_PX: f64 = 1e6;

/// Parses a video CSV (named `file` in errors) for `scenario`, labelled
/// `material`.
pub fn parse_video_csv(
    text: &str,
    file: &str,
    scenario: &PushScenario,
    material: &str,
) -> Result<Video> {
    scenario.validate()?;
    let table = plant_common::csv_input::read_numeric(text, file)?;
    if table.columns != ["frame", "force_n", "x_px", "y_px"] {
        return Err(bad(
            file,
            table.header_line,
            format!(
                "expected the header `{HEADER}`, found `{}`",
                plant_common::csv_input::excerpt(&table.columns.join(","))
            ),
        ));
    }
    let mut contours: Vec<Vec<V2>> = Vec::new();
    let mut forces: Vec<f64> = Vec::new();
    for row in &table.rows {
        let [f, force, x, y] = row.values[..] else {
            return Err(bad(file, row.line, "expected 4 columns"));
        };
        if !(f >= 0.0 && f.fract() == 0.0 && f < usize::MAX as f64) {
            return Err(bad(
                file,
                row.line,
                format!(
                    "frame `{}` is not a non-negative integer",
                    plant_common::short_number(f)
                ),
            ));
        }
        for (v, column) in [(x, "x_px"), (y, "y_px")] {
            if v.abs() > MAX_COORDINATE_PX {
                return Err(PushError::from(table.error(
                    row.line,
                    Some(column),
                    format!(
                        "{} px is outside any camera frame (|value| <= {} px)",
                        plant_common::short_number(v),
                        plant_common::short_number(MAX_COORDINATE_PX)
                    ),
                )));
            }
        }
        let frame = f as usize;
        if frame == contours.len() {
            contours.push(Vec::new());
            forces.push(force);
        } else if frame + 1 != contours.len() {
            return Err(bad(
                file,
                row.line,
                format!(
                    "frame {frame} out of order (expected {} or {})",
                    contours.len().saturating_sub(1),
                    contours.len()
                ),
            ));
        } else if forces[frame] != force {
            return Err(bad(
                file,
                row.line,
                format!(
                    "frame {frame} has two force readings ({} and {force})",
                    forces[frame]
                ),
            ));
        }
        contours[frame].push(V2::new(x, y));
    }
    let video = Video {
        material: material.to_string(),
        scenario: *scenario,
        contours_px: contours,
        forces_n: forces,
    };
    video.validate()?;
    Ok(video)
}
