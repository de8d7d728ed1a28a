//! `softjoint identify joint` as a library call: the identification of
//! a log from a prior (or the defaults), the plant file it writes and its
//! `--json` report, shared by the command and the Python package
//! (`softjoint.identify_joint`), so both give the same file and report.
use std::fmt::Write as _;

use plant_joint::identify::{self, IdentifyError, IdentifyOptions, PlaneReport, StartFits};
use plant_joint::{Joint2dParams, Joint3dParams};

use crate::files::plant::{uncertainties, PlantFile, PlantParams};
use crate::output;

/// What `--angles board-estimate` tells the reader with every result.
pub const BOARD_ESTIMATE_NOTE: &str = "angles: the board's wire-based estimates (est_*_deg), not a camera — the mechanics absorb the estimation law's error and the wires' jamming, and the jamming parameters are fitted against an angle read off the same wires (not independent)";

/// Why an identification gave no plant.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The identification's own error (a stop included).
    #[error(transparent)]
    Identify(#[from] IdentifyError),
    /// The prior is a plant file of the other joint than the log's.
    #[error("a {log} log, but the prior is a plant file for the other joint")]
    OtherJoint {
        /// "2D" or "3D": the log's joint.
        log: &'static str,
    },
}

/// An identified joint: its parameters and the planes' reports.
pub struct Identified {
    /// The joint's parameters.
    pub params: PlantParams,
    /// Per plane: estimates, stages, validation, verdict.
    pub reports: Vec<PlaneReport>,
    /// Rows of the log.
    pub rows: usize,
}

/// Refuses a log that nothing measures the angle in: no camera frame and
/// no coil resistances, read from the camera (`board_estimates` false).
pub fn check_angles(
    log: &identify::ExcitationLog,
    name: &str,
    board_estimates: bool,
) -> anyhow::Result<()> {
    if !board_estimates && !log.cam_capture_s.iter().any(|c| *c >= 0.0) && !log.has_electrical() {
        anyhow::bail!(
            "{name}: the log has no camera frame and no coil resistances, so nothing measures the angle the mechanics are fitted to; for a log recorded on a board (`console excite`), --angles board-estimate fits them to the board's own estimates"
        );
    }
    Ok(())
}

/// Identifies `log` from `prior` (the defaults of the log's joint without
/// one), the mechanics stage's starts run by `elsewhere` where given.
pub fn identify(
    log: &identify::ExcitationLog,
    prior: Option<PlantParams>,
    opts: &IdentifyOptions,
    elsewhere: Option<&dyn StartFits>,
) -> Result<Identified, RunError> {
    let (params, reports) = match (log.planes, prior) {
        (1, None) => {
            let (p, r) =
                identify::identify_2d_with(log, &Joint2dParams::default(), opts, elsewhere)?;
            (PlantParams::TwoD(p), r)
        }
        (1, Some(PlantParams::TwoD(prior))) => {
            let (p, r) = identify::identify_2d_with(log, &prior, opts, elsewhere)?;
            (PlantParams::TwoD(p), r)
        }
        (2, None) => {
            let (p, r) =
                identify::identify_3d_with(log, &Joint3dParams::default(), opts, elsewhere)?;
            (PlantParams::ThreeD(p), r)
        }
        (2, Some(PlantParams::ThreeD(prior))) => {
            let (p, r) = identify::identify_3d_with(log, &prior, opts, elsewhere)?;
            (PlantParams::ThreeD(p), r)
        }
        _ => {
            return Err(RunError::OtherJoint {
                log: if log.planes == 1 { "2D" } else { "3D" },
            })
        }
    };
    Ok(Identified {
        params,
        reports,
        rows: log.len(),
    })
}

impl Identified {
    /// Every plane's failed checks, "plane: why" (empty: verified).
    pub fn unverified(&self) -> Vec<String> {
        self.reports
            .iter()
            .flat_map(|r| {
                r.verdict
                    .failures
                    .iter()
                    .map(move |f| format!("{}: {f}", r.plane))
            })
            .collect()
    }

    /// The plant file: the parameters and each identified and verified
    /// parameter's 1σ.
    pub fn plant_file(&self) -> PlantFile {
        PlantFile::new(self.params.clone(), uncertainties(&self.reports))
    }

    /// The plant file's comment lines: what wrote it (from the log `log`)
    /// and each failed check.
    pub fn header(&self, log: &str) -> String {
        let mut header = format!(
            "# Written by `softjoint identify joint {log}`: the identified joint.\n# `[[uncertainty]]` lists each identified parameter's 1σ (softjoint tune samples them).\n",
        );
        for f in &self.unverified() {
            let _ = writeln!(header, "# UNVERIFIED: {f}");
        }
        header
    }

    /// The plant file's text as `identify joint` writes it.
    pub fn plant_text(&self, log: &str) -> anyhow::Result<String> {
        output::toml(
            "the identified plant file",
            &self.header(log),
            &self.plant_file(),
        )
    }

    /// The `--json` report: the log, its rows, the planes (without their
    /// frames), the verdict, what is never fitted, the plant file's path
    /// (null: not written) and where the angles came from.
    pub fn report(
        &self,
        log: &str,
        plant_file: Option<&str>,
        board_estimates: bool,
    ) -> anyhow::Result<output::JsonObject> {
        let unverified = self.unverified();
        let planes: Vec<PlaneReport> = self
            .reports
            .iter()
            .map(|p| {
                let mut p = p.clone();
                p.validation.frames.clear();
                p
            })
            .collect();
        output::JsonObject::new()
            .field("log", log)?
            .field("rows", &self.rows)?
            // A 1σ that is not finite (a parameter the log does not
            // determine at all; `identifiable` is false) is written as
            // null: JSON has no infinity, and the report must not fail.
            .field("planes", &serde_json::to_value(planes)?)?
            .field("verified", &unverified.is_empty())?
            .field("unverified_because", &unverified)?
            .field("never_fitted", &identify::NEVER_FITTED)?
            .field("plant_file", &plant_file)?
            .field(
                "angles",
                if board_estimates {
                    BOARD_ESTIMATE_NOTE
                } else {
                    "camera"
                },
            )
    }
}
