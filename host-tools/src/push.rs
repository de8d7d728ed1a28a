//! What `softjoint push` (seed 001) does before and after the pushing
//! crate's experiments: the push prepared (the ground truth recorded, or
//! a `--video` CSV read) with its bounds checked, the model's settings
//! and parameter files read, and `simulate`'s per-frame table. The
//! program and the Python package both take them from here; each names
//! the settings in its own words (`--nx` on the command line, `nx` in
//! Python) through a [`Names`] function.
use anyhow::{bail, Result};
use plant_pushing::error::PushError;
use plant_pushing::evaluate::{EvalSetup, PreparedVideo};
use plant_pushing::evolution::CalibrationResult;
use plant_pushing::experiment::SimulateReport;
use plant_pushing::forces::MaterialParams;
use plant_pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial, Video};
use plant_pushing::scenario::{PushScenario, PushSite};
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};
use plant_pushing::video_csv::parse_video_csv;

use crate::input::from_json;
use crate::progress;

/// A setting's name as the caller's user calls it, given its name here:
/// `ref_element_px`, `nx`, `ny` or `cell_px`.
pub type Names<'a> = &'a dyn Fn(&str) -> String;

/// The block's material: it chooses the generated ground truth, the
/// camera scale (§VIII-A) and the seed's default parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Material {
    Sponge,
    Plasticine,
}

impl Material {
    /// The material called `name` (`sponge`, `plasticine`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "sponge" => Some(Material::Sponge),
            "plasticine" => Some(Material::Plasticine),
            _ => None,
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Material::Sponge => "sponge",
            Material::Plasticine => "plasticine",
        }
    }

    pub fn reference(self) -> ReferenceMaterial {
        match self {
            Material::Sponge => ReferenceMaterial::SPONGE,
            Material::Plasticine => ReferenceMaterial::PLASTICINE,
        }
    }

    /// The seed's parameters of the material: Fig. 14 (sponge) or Fig. 15
    /// (plasticine).
    pub fn seed_params(self) -> MaterialParams {
        match self {
            Material::Sponge => MaterialParams::SEED_FIG14_SPONGE,
            Material::Plasticine => MaterialParams::SEED_FIG15_PLASTICINE,
        }
    }
}

/// The push site called `name` (`middle-long`, `corner`, `middle-short`).
pub fn site_from_name(name: &str) -> Option<PushSite> {
    [
        PushSite::MiddleLongSide,
        PushSite::NearCorner,
        PushSite::MiddleShortSide,
    ]
    .into_iter()
    .find(|s| s.name() == name)
}

/// Which push: a material pushed at a site, either recorded from the
/// finite-element ground truth (elements of `ref_element_px`, noise
/// seeded by `noise_seed`) or read from a video CSV's text and name.
#[derive(Clone, Copy, Debug)]
pub struct PushSource<'a> {
    pub material: Material,
    pub site: PushSite,
    /// `(text, name)` of a `frame,force_n,x_px,y_px` CSV.
    pub video: Option<(&'a str, &'a str)>,
    pub ref_element_px: f64,
    pub noise_seed: u64,
}

/// The model's mesh (squares along the long and short sides) and the
/// F-score's raster cell (px).
#[derive(Clone, Copy, Debug)]
pub struct ModelGrid {
    pub nx: usize,
    pub ny: usize,
    pub cell_px: f64,
}

impl ModelGrid {
    fn setup(self) -> EvalSetup {
        EvalSetup {
            nx: self.nx,
            ny: self.ny,
            cell_px: self.cell_px,
        }
    }
}

/// The simulator's settings: the integrator, the driving mode and the
/// §VI-E repair of reversed and flat triangles, the rest the default.
pub fn sim_config(integrator: Integrator, mode: DrivingMode, repair: bool) -> SimConfig {
    SimConfig {
        integrator,
        mode,
        geometric_repair: repair,
        ..SimConfig::default()
    }
}

/// The pushing library's name of each setting named by [`Names`].
const LIBRARY_NAMES: [(&str, &str); 4] = [
    ("element_size_px", "ref_element_px"),
    ("nx", "nx"),
    ("ny", "ny"),
    ("cell_px", "cell_px"),
];

/// A pushing error in the caller's words: a parameter the user set is
/// called by the caller's name for it (`element_size_px` was shown for
/// `--ref-element-px`).
pub fn named(e: PushError, names: Names) -> anyhow::Error {
    let name_of = |name: &str| {
        LIBRARY_NAMES
            .iter()
            .find(|(n, _)| *n == name)
            .map(|(_, ours)| names(ours))
    };
    let short = plant_common::short_number;
    match e {
        PushError::InvalidParameter {
            name,
            value,
            reason,
        } if name_of(name).is_some() => {
            anyhow::anyhow!(
                "{} {}: {reason}",
                name_of(name).unwrap_or_default(),
                short(value)
            )
        }
        PushError::OutOfRange {
            name,
            value,
            min,
            max,
        } if name_of(name).is_some() => anyhow::anyhow!(
            "{} {}: must be within {}..={}",
            name_of(name).unwrap_or_default(),
            short(value),
            short(min),
            short(max)
        ),
        other => other.into(),
    }
}

/// Smallest `ref_element_px`: below ≈ 2 px the ground truth ran for
/// minutes (issue 12); 8 px is the default.
pub const MIN_REF_ELEMENT_PX: f64 = 2.0;

/// Peak memory of the model per square of its `nx × ny` mesh (bytes)
/// and besides it: the maximum resident set of `softjoint push simulate`
/// at `--nx 200 --ny 100` (28 MB) and `--nx 400 --ny 200` (59 MB) over
/// its 17 MB at the start (VmHWM of /proc/PID/status), ≈ 530–600 B a
/// square; rounded up.
const MODEL_BYTES_PER_SQUARE: u64 = 700;
const MODEL_BYTES_BESIDES: u64 = 32_000_000;

/// The mesh's size checked before any work (the ground truth is seconds
/// of finite elements): each side within the model's 1..=2000 squares,
/// and the memory the mesh needs within the memory there is.
pub fn check_grid(g: &ModelGrid, names: Names) -> Result<()> {
    let max = plant_pushing::mesh::MAX_SQUARES_PER_SIDE;
    for (name, n) in [("nx", g.nx), ("ny", g.ny)] {
        if !(1..=max).contains(&n) {
            bail!("{} {n}: must be 1..={max} squares", names(name));
        }
    }
    let squares = (g.nx * g.ny) as u64;
    crate::memory::check_fits(
        &format!(
            "{} {} {} {} ({squares} squares)",
            names("nx"),
            g.nx,
            names("ny"),
            g.ny
        ),
        squares * MODEL_BYTES_PER_SQUARE + MODEL_BYTES_BESIDES,
    )
}

/// The push `src` names: its video CSV read, or the ground truth recorded
/// (a spinner on stderr unless `quiet`).
pub fn load_video(src: &PushSource, names: Names, quiet: bool) -> Result<Video> {
    let mat = src.material.reference();
    let scenario = PushScenario::seed(src.site, mat.scale_px_per_m)?;
    if let Some((text, name)) = src.video {
        return Ok(parse_video_csv(
            text,
            name,
            &scenario,
            src.material.label(),
        )?);
    }
    if src.ref_element_px.is_nan() || src.ref_element_px < MIN_REF_ELEMENT_PX {
        bail!(
            "{} {}: must be at least {MIN_REF_ELEMENT_PX} px (the finite-element ground truth's time grows about as the cube of 1/size: below 2 px it runs for minutes; the default is 8 px)",
            names("ref_element_px"),
            plant_common::short_number(src.ref_element_px)
        );
    }
    let cfg = ReferenceConfig {
        element_size_px: src.ref_element_px,
        seed: src.noise_seed,
        ..ReferenceConfig::default()
    };
    let spinner = progress::spinner(
        &format!(
            "recording the ground-truth push ({} px elements)",
            src.ref_element_px
        ),
        quiet,
    );
    let video = record_push(src.material.label(), mat, &scenario, &cfg);
    spinner.finish_and_clear();
    video.map_err(|e| named(e, names))
}

/// The push prepared for the model: the grid checked, the push loaded,
/// its truth rasterised and the model's mesh built.
pub fn prepare(
    src: &PushSource,
    grid: &ModelGrid,
    names: Names,
    quiet: bool,
) -> Result<PreparedVideo> {
    check_grid(grid, names)?;
    let video = load_video(src, names, quiet)?;
    PreparedVideo::new(video, &grid.setup()).map_err(|e| named(e, names))
}

/// Parameters from JSON `text` (`file` names it in errors): a bare
/// parameter object or `calibrate`'s `params.json` (which holds them
/// under `best_params`), checked valid.
pub fn params_from_json(text: &str, file: &str) -> Result<MaterialParams> {
    use anyhow::Context as _;
    let expected = "expected the eight model parameters (k_length, k_damping, k_area, k_angle, max_force, yield_strain, creep, max_alpha), or `calibrate`'s params.json";
    // Duplicate keys and syntax first (the form is chosen from a parsed
    // value, which would keep only the last of two equal keys).
    let value: serde_json::Value = from_json(text, file)?;
    let p = if value.get("best_params").is_some() {
        from_json::<CalibrationResult>(text, file)
            .with_context(|| format!("{file}: {expected}"))?
            .best_params
    } else {
        from_json::<MaterialParams>(text, file).with_context(|| format!("{file}: {expected}"))?
    };
    p.validate().with_context(|| format!("in {file}"))?;
    Ok(p)
}

/// `simulate`'s per-frame table (frames.csv): each frame's phase (`push`
/// or `retrieval`) and the numeric columns by name — `time_s`,
/// `finger_depth_px`, `sensed_force_n`, `force_used_n`, `f_score`,
/// `mean_f` (μ(F) up to the frame), the model's `contour_mean_px` and
/// `contour_max_px` and the undeformed block's `still_contour_mean_px`
/// and `still_contour_max_px`.
pub struct FrameTable {
    pub phase: Vec<&'static str>,
    pub columns: Vec<(&'static str, Vec<f64>)>,
}

/// The per-frame table of a simulated push.
pub fn frame_table(prep: &PreparedVideo, report: &SimulateReport) -> FrameTable {
    let sc = &prep.video.scenario;
    let tracking = &report.tracking;
    let mean = plant_pushing::raster::running_mean(&report.f_per_frame);
    let names = [
        "time_s",
        "finger_depth_px",
        "sensed_force_n",
        "force_used_n",
        "f_score",
        "mean_f",
        "contour_mean_px",
        "contour_max_px",
        "still_contour_mean_px",
        "still_contour_max_px",
    ];
    let mut columns: Vec<(&'static str, Vec<f64>)> =
        names.iter().map(|n| (*n, Vec::new())).collect();
    let mut phase = Vec::new();
    for (f, mean_f) in mean.iter().enumerate().take(prep.frame_count()) {
        let t = sc.frame_time_s(f);
        let (cm, cx) = tracking
            .model
            .as_ref()
            .map(|m| (m.mean_px_per_frame[f], m.max_px_per_frame[f]))
            .unwrap_or((f64::NAN, f64::NAN));
        phase.push(if sc.is_push_frame(f) {
            "push"
        } else {
            "retrieval"
        });
        let row = [
            t,
            sc.finger_depth_px(t),
            prep.video.forces_n[f],
            report.forces_n[f],
            report.f_per_frame[f],
            *mean_f,
            cm,
            cx,
            tracking.still.mean_px_per_frame[f],
            tracking.still.max_px_per_frame[f],
        ];
        for ((_, col), v) in columns.iter_mut().zip(row) {
            col.push(v);
        }
    }
    FrameTable { phase, columns }
}
