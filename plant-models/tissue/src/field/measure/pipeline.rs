//! The whole measurement of Zhang's paper on one volume pair: Harris
//! points in both volumes (1000 and 5000, Table I), matching, the rigid
//! part by Horn's method, Delaunay tetrahedra over the matches, the dense
//! field by shape functions and the registration error of Eq. 12.
use super::harris::{detect, FeaturePoint, HarrisParams};
use super::horn::{horn, RigidFit};
use super::matching::{candidates, relax, Match, MatchParams};
use crate::error::{Result, TissueError};
use crate::field::model::delaunay::tetrahedralise;
use crate::field::model::shape::{rms_difference, TetField};
use crate::field::model::volume::Volume;

/// Parameters of one measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FieldParams {
    /// Feature detector.
    pub harris: HarrisParams,
    /// Feature points in the initial volume (Table I: 1000).
    pub features_initial: usize,
    /// Feature points in the deformed volume (Table I: 5000).
    pub features_deformed: usize,
    /// Matching.
    pub matching: MatchParams,
    /// Seed of the Delaunay tie-breaking jitter.
    pub seed: u64,
}

impl Default for FieldParams {
    fn default() -> Self {
        FieldParams {
            harris: HarrisParams::default(),
            features_initial: 1000,
            features_deformed: 5000,
            matching: MatchParams::default(),
            seed: 1,
        }
    }
}

/// The feature points of a pair and the initial candidates (shared by the
/// matching variants of a comparison).
#[derive(Clone, Debug)]
pub struct Features {
    /// IV feature points, strongest first.
    pub initial: Vec<FeaturePoint>,
    /// FV feature points, strongest first.
    pub deformed: Vec<FeaturePoint>,
    /// Correlation candidates of each IV point.
    pub candidates: Vec<Vec<(usize, f64)>>,
}

/// A measured deformation field.
#[derive(Clone, Debug)]
pub struct MeasuredField {
    /// The potential match set.
    pub matches: Vec<Match>,
    /// The rigid part (Horn) of the matched motion.
    pub rigid: RigidFit,
    /// The field at the matched points over their Delaunay tetrahedra
    /// (total displacement: rigid and non-rigid).
    pub field: TetField,
    /// Matched points repeated exactly (not used by the tetrahedra).
    pub duplicate_points: usize,
    /// Tetrahedra the measured motion turns inside out.
    pub folded_tets: usize,
}

impl MeasuredField {
    /// The non-rigid part at each match: `x₂ − (R x₁ + t)` (Eq. 8 with
    /// Horn's translation too).
    pub fn non_rigid_mm(&self) -> Vec<[f64; 3]> {
        self.field
            .nodes_mm
            .iter()
            .zip(&self.field.displacement_mm)
            .map(|(p, d)| {
                let moved = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
                let r = self.rigid.apply(*p);
                [moved[0] - r[0], moved[1] - r[1], moved[2] - r[2]]
            })
            .collect()
    }
}

/// Detects the feature points of both volumes and their candidates.
pub fn features(iv: &Volume, fv: &Volume, params: &FieldParams) -> Result<Features> {
    if iv.dims() != fv.dims() {
        let d = |v: &Volume| format!("{}×{}×{}", v.dims()[0], v.dims()[1], v.dims()[2]);
        return Err(TissueError::VolumeShape {
            what: "deformed volume".into(),
            reason: format!(
                "{} voxels, but the initial volume has {}: the pair must share one grid",
                d(fv),
                d(iv)
            ),
        });
    }
    if iv.spacing_mm() != fv.spacing_mm() {
        return Err(TissueError::VolumeShape {
            what: "deformed volume".into(),
            reason: format!(
                "voxel spacing {:?} mm differs from the initial volume's {:?} mm",
                fv.spacing_mm(),
                iv.spacing_mm()
            ),
        });
    }
    let (initial, deformed) = rayon::join(
        || detect(iv, &params.harris, params.features_initial),
        || detect(fv, &params.harris, params.features_deformed),
    );
    let (initial, deformed) = (initial?, deformed?);
    let candidates = candidates(iv, fv, &initial, &deformed, &params.matching)?;
    Ok(Features {
        initial,
        deformed,
        candidates,
    })
}

/// Matches, the rigid part and the field, from detected features.
pub fn measure_from(features: &Features, params: &FieldParams) -> Result<MeasuredField> {
    let matches = relax(
        &features.initial,
        &features.deformed,
        &features.candidates,
        &params.matching,
    )?;
    if matches.len() < 4 {
        return Err(TissueError::TooFew {
            stage: "feature matching",
            what: "matches",
            got: matches.len(),
            needed: 4,
        });
    }
    let a: Vec<[f64; 3]> = matches
        .iter()
        .map(|m| features.initial[m.initial].position_mm)
        .collect();
    let b: Vec<[f64; 3]> = matches
        .iter()
        .map(|m| features.deformed[m.deformed].position_mm)
        .collect();
    let rigid = horn(&a, &b)?;
    let tet = tetrahedralise(&a, params.seed)?;
    let field = TetField {
        displacement_mm: a
            .iter()
            .zip(&b)
            .map(|(p, q)| [q[0] - p[0], q[1] - p[1], q[2] - p[2]])
            .collect(),
        nodes_mm: a,
        tets: tet.tets,
    };
    let folded_tets = field.folded_tets();
    Ok(MeasuredField {
        matches,
        rigid,
        field,
        duplicate_points: tet.duplicates.len(),
        folded_tets,
    })
}

/// The paper's slices for Eq. 12 (10 to 50 of 57), scaled to a volume of
/// `nz` slices.
pub fn rms_slices(nz: usize) -> std::ops::RangeInclusive<usize> {
    let lo = (10 * nz) / 57;
    let hi = ((50 * nz) / 57).max(lo);
    lo..=hi.min(nz.saturating_sub(1))
}

/// Eq. 12 between the deformed volume and the initial one deformed by
/// `field`, over `mask` (or the field's own coverage) in the paper's
/// slices; `(rms, voxels)`.
pub fn registration_rms(
    iv: &Volume,
    fv: &Volume,
    field: &TetField,
    mask: Option<&[bool]>,
) -> Option<(f64, usize)> {
    let (warped, covered) = field.warp(iv);
    let mask: Vec<bool> = match mask {
        Some(m) => m.iter().zip(&covered).map(|(a, b)| *a && *b).collect(),
        None => covered,
    };
    rms_difference(fv, &warped, &mask, rms_slices(iv.dims()[2]))
}

/// The whole measurement on a pair.
pub fn measure_field(
    iv: &Volume,
    fv: &Volume,
    params: &FieldParams,
) -> Result<(Features, MeasuredField)> {
    let f = features(iv, fv, params)?;
    let m = measure_from(&f, params)?;
    Ok((f, m))
}
