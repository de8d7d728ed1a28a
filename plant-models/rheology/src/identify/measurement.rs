//! A measured push: surface points per frame (the paper's stereo cameras,
//! L1711–1715) and plate forces per sample (its force sensor, L2232–2234),
//! with CSV files read through the one CSV reader.
//!
//! Files:
//! * surface points: `frame,time_s,x_cm,y_cm,z_cm`, one row per point;
//! * forces: `time_s,force_n`, one row per sample (the plate's downward
//!   force on the block).
use std::fmt::Write as _;

use crate::error::{Result, RheologyError};
use crate::model::lattice::V3;
use plant_common::csv_input::read_numeric;

/// The points seen on the block's surface at one time.
#[derive(Clone, Debug, PartialEq)]
pub struct PointFrame {
    /// Time (s).
    pub t_s: f64,
    /// Points (m).
    pub points_m: Vec<V3>,
}

/// One force-sensor sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceSample {
    pub t_s: f64,
    /// The plate's downward force on the block (N).
    pub force_n: f64,
}

/// A measured push.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Measurement {
    pub frames: Vec<PointFrame>,
    pub forces: Vec<ForceSample>,
}

impl Measurement {
    /// Total number of surface points over all frames.
    pub fn point_count(&self) -> usize {
        self.frames.iter().map(|f| f.points_m.len()).sum()
    }

    /// The frame times (s).
    pub fn frame_times_s(&self) -> Vec<f64> {
        self.frames.iter().map(|f| f.t_s).collect()
    }

    /// The surface points as CSV.
    pub fn points_csv(&self) -> String {
        let mut s = String::from("frame,time_s,x_cm,y_cm,z_cm\n");
        for (k, f) in self.frames.iter().enumerate() {
            for p in &f.points_m {
                let _ = writeln!(
                    s,
                    "{k},{},{:.5},{:.5},{:.5}",
                    f.t_s,
                    p.x * 100.0,
                    p.y * 100.0,
                    p.z * 100.0
                );
            }
        }
        s
    }

    /// The forces as CSV.
    pub fn forces_csv(&self) -> String {
        let mut s = String::from("time_s,force_n\n");
        for f in &self.forces {
            let _ = writeln!(s, "{:.6},{:.6}", f.t_s, f.force_n);
        }
        s
    }

    /// Reads the two CSV texts; `points_file` and `forces_file` name them
    /// in errors (file:line: column: reason).
    pub fn from_csv(
        points_text: &str,
        points_file: &str,
        forces_text: &str,
        forces_file: &str,
    ) -> Result<Self> {
        let malformed = |e: plant_common::csv_input::CsvError| RheologyError::MalformedInput {
            location: format!(
                "{}:{}{}",
                e.file,
                e.line,
                e.column
                    .map(|c| format!(": column `{c}`"))
                    .unwrap_or_default()
            ),
            reason: e.reason,
        };
        let t = read_numeric(points_text, points_file).map_err(malformed)?;
        t.require_rows(1, "of surface points").map_err(malformed)?;
        let cols =
            ["frame", "time_s", "x_cm", "y_cm", "z_cm"].map(|c| t.column(c).map_err(malformed));
        let [fc, tc, xc, yc, zc] = cols;
        let (fc, tc, xc, yc, zc) = (fc?, tc?, xc?, yc?, zc?);
        let mut frames: Vec<PointFrame> = Vec::new();
        for row in &t.rows {
            let v = &row.values;
            let frame = v[fc];
            if frame < 0.0 || frame.fract() != 0.0 {
                return Err(malformed(t.error(
                    row.line,
                    Some("frame"),
                    "must be a whole number >= 0",
                )));
            }
            let frame = frame as usize;
            if frame == frames.len() {
                frames.push(PointFrame {
                    t_s: v[tc],
                    points_m: Vec::new(),
                });
            } else if frame + 1 != frames.len() {
                return Err(malformed(t.error(
                    row.line,
                    Some("frame"),
                    format!(
                        "frames must be numbered 0, 1, 2, … in order; expected {} or {}",
                        frames.len().saturating_sub(1),
                        frames.len()
                    ),
                )));
            }
            let current = frames.len() - 1;
            if v[tc] != frames[current].t_s {
                return Err(malformed(t.error(
                    row.line,
                    Some("time_s"),
                    "every row of a frame must have the frame's time",
                )));
            }
            if current > 0 && frames[current].t_s <= frames[current - 1].t_s {
                return Err(malformed(t.error(
                    row.line,
                    Some("time_s"),
                    "frame times must increase",
                )));
            }
            frames[current]
                .points_m
                .push(V3::new(v[xc], v[yc], v[zc]) * 0.01);
        }
        let f = read_numeric(forces_text, forces_file).map_err(malformed)?;
        f.require_rows(2, "of force samples").map_err(malformed)?;
        let (tc, fcol) = (
            f.column("time_s").map_err(malformed)?,
            f.column("force_n").map_err(malformed)?,
        );
        let mut forces = Vec::with_capacity(f.rows.len());
        for row in &f.rows {
            let s = ForceSample {
                t_s: row.values[tc],
                force_n: row.values[fcol],
            };
            if let Some(prev) = forces.last() {
                let prev: &ForceSample = prev;
                if s.t_s <= prev.t_s {
                    return Err(malformed(f.error(
                        row.line,
                        Some("time_s"),
                        "sample times must increase",
                    )));
                }
            }
            forces.push(s);
        }
        Ok(Self { frames, forces })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measurements_round_trip_through_csv_and_bad_rows_are_named() {
        let m = Measurement {
            frames: vec![
                PointFrame {
                    t_s: 1.0,
                    points_m: vec![V3::new(0.01, 0.02, 0.03), V3::new(0.04, 0.05, 0.06)],
                },
                PointFrame {
                    t_s: 2.0,
                    points_m: vec![V3::new(0.07, 0.08, 0.09)],
                },
            ],
            forces: vec![
                ForceSample {
                    t_s: 0.002,
                    force_n: 1.5,
                },
                ForceSample {
                    t_s: 0.004,
                    force_n: -0.25,
                },
            ],
        };
        let back =
            Measurement::from_csv(&m.points_csv(), "p.csv", &m.forces_csv(), "f.csv").unwrap();
        assert_eq!(back.frames.len(), 2);
        assert_eq!(back.point_count(), 3);
        assert!((back.frames[1].points_m[0] - V3::new(0.07, 0.08, 0.09)).norm() < 1e-9);
        assert_eq!(back.forces, m.forces);
        let bad = "frame,time_s,x_cm,y_cm,z_cm\n0,1,0,0,0\n2,2,0,0,0\n";
        let e = Measurement::from_csv(bad, "p.csv", &m.forces_csv(), "f.csv").unwrap_err();
        assert!(e.to_string().starts_with("p.csv:3: column `frame`"), "{e}");
        let bad = "time_s,force_n\n0.1,1\n0.1,2\n";
        let e = Measurement::from_csv(&m.points_csv(), "p.csv", bad, "f.csv").unwrap_err();
        assert!(e.to_string().starts_with("f.csv:3: column `time_s`"), "{e}");
        let e =
            Measurement::from_csv("frame,time_s,x_cm\n0,1,2\n", "p.csv", bad, "f.csv").unwrap_err();
        assert!(e.to_string().contains("y_cm"), "{e}");
    }
}
