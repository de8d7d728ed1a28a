//! A recorded push as CSV, so that tracked contours and force readings from
//! elsewhere (or from [`super::reference`]) can be scored and calibrated on.
//!
//! One row per contour point: `frame,force_n,x_px,y_px`. Frames are numbered
//! 0, 1, 2, … without gaps, rows of a frame are consecutive and list its
//! contour in order, and every row of a frame repeats the same force
//! reading (N, along the push direction). Lines starting with `#` and blank
//! lines are skipped. The scenario (block, finger path, frame interval) is
//! not in the file: the caller supplies it and the frame count must match.
use super::error::{PushError, Result};
use super::reference::Video;
use super::scenario::PushScenario;
use super::V2;
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

fn bad(line: usize, reason: impl Into<String>) -> PushError {
    PushError::MalformedInput {
        location: format!("line {line}"),
        reason: reason.into(),
    }
}

/// Parses a video CSV for `scenario`, labelled `material`.
pub fn parse_video_csv(text: &str, scenario: &PushScenario, material: &str) -> Result<Video> {
    scenario.validate()?;
    let mut contours: Vec<Vec<V2>> = Vec::new();
    let mut forces: Vec<f64> = Vec::new();
    let mut saw_header = false;
    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if !saw_header {
            let cols: Vec<&str> = line.split(',').map(str::trim).collect();
            if cols != ["frame", "force_n", "x_px", "y_px"] {
                return Err(bad(
                    line_no,
                    format!("expected the header `{HEADER}`, found `{line}`"),
                ));
            }
            saw_header = true;
            continue;
        }
        let cols: Vec<&str> = line.split(',').map(str::trim).collect();
        if cols.len() != 4 {
            return Err(bad(
                line_no,
                format!("expected 4 columns, found {}", cols.len()),
            ));
        }
        let frame: usize = cols[0].parse().map_err(|_| {
            bad(
                line_no,
                format!("frame `{}` is not a non-negative integer", cols[0]),
            )
        })?;
        let num = |k: usize, name: &str| -> Result<f64> {
            let v: f64 = cols[k]
                .parse()
                .map_err(|_| bad(line_no, format!("{name} `{}` is not a number", cols[k])))?;
            if !v.is_finite() {
                return Err(bad(line_no, format!("{name} is not finite")));
            }
            Ok(v)
        };
        let (force, x, y) = (num(1, "force_n")?, num(2, "x_px")?, num(3, "y_px")?);
        if frame == contours.len() {
            contours.push(Vec::new());
            forces.push(force);
        } else if frame + 1 != contours.len() {
            return Err(bad(
                line_no,
                format!(
                    "frame {frame} out of order (expected {} or {})",
                    contours.len().saturating_sub(1),
                    contours.len()
                ),
            ));
        } else if forces[frame] != force {
            return Err(bad(
                line_no,
                format!(
                    "frame {frame} has two force readings ({} and {force})",
                    forces[frame]
                ),
            ));
        }
        contours[frame].push(V2::new(x, y));
    }
    if !saw_header {
        return Err(bad(
            1,
            format!("empty file: expected the header `{HEADER}`"),
        ));
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
