//! Zhang's measurement as `softjoint tissue field` runs it: one or more
//! matching variants on the same feature points of a volume pair, each
//! with its rigid part, tetrahedra and Eq. 12, and — on a synthetic twin —
//! the errors against the true field ([`super::twin`]).
//!
//! The features and the first variant are timed together (the benchmark
//! figure: features, matching, Horn, tetrahedra); the other variants and
//! the comparison with the truth are not part of that time. On a twin the
//! comparison detects the features again, as a separate measurement.
use super::matching::Consistency;
use super::pipeline::{
    features, measure_from, registration_rms, Features, FieldParams, MeasuredField,
};
use super::twin::{compare_on_twin, TwinReport};
use crate::error::{Result, TissueError};
use crate::field::model::synth::Twin;
use crate::field::model::volume::Volume;
use serde::Serialize;
use std::time::Instant;

/// The two volumes of a measurement.
#[derive(Clone, Debug)]
pub enum VolumePair {
    /// Read from files: no truth to compare with.
    Files {
        /// The initial volume (IV).
        initial: Volume,
        /// The deformed volume (FV), on the same grid.
        deformed: Volume,
    },
    /// A synthetic twin with a known warp.
    Twin(Box<Twin>),
}

impl VolumePair {
    /// The initial volume (IV).
    pub fn initial(&self) -> &Volume {
        match self {
            VolumePair::Files { initial, .. } => initial,
            VolumePair::Twin(t) => &t.initial,
        }
    }

    /// The deformed volume (FV).
    pub fn deformed(&self) -> &Volume {
        match self {
            VolumePair::Files { deformed, .. } => deformed,
            VolumePair::Twin(t) => &t.deformed,
        }
    }

    /// The twin, when the pair is one.
    pub fn twin(&self) -> Option<&Twin> {
        match self {
            VolumePair::Files { .. } => None,
            VolumePair::Twin(t) => Some(t),
        }
    }
}

/// One matching variant in the summary (Table I's columns and Eq. 12).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VariantSummary {
    /// The variant's name (`direction`, `strength`, `as-printed`).
    pub matching: &'static str,
    /// Potential matches.
    pub matches: usize,
    /// Delaunay tetrahedra over the matches.
    pub tetrahedra: usize,
    /// Tetrahedra the measured motion turns inside out.
    pub folded_tetrahedra: usize,
    /// Horn's rotation angle (degrees).
    pub horn_angle_deg: f64,
    /// Horn's translation (mm).
    pub horn_translation_mm: [f64; 3],
    /// RMS residual of Horn's fit (mm).
    pub horn_rms_residual_mm: f64,
    /// Eq. 12 over the field's own coverage in the paper's slices (none
    /// when it covers no voxel there).
    pub registration_rms: Option<f64>,
    /// Voxels of that Eq. 12.
    pub registration_voxels: Option<usize>,
}

/// One matching variant's measured field and its summary.
#[derive(Clone, Debug)]
pub struct VariantField {
    /// The variant.
    pub consistency: Consistency,
    /// Matches, rigid part and field.
    pub measured: MeasuredField,
    /// The numbers the report prints.
    pub summary: VariantSummary,
}

/// What a measurement produces.
#[derive(Clone, Debug)]
pub struct FieldOutcome {
    /// The feature points of both volumes and their candidates.
    pub features: Features,
    /// One entry per variant, in the order asked (the first is the one
    /// the pictures and the dense field show).
    pub variants: Vec<VariantField>,
    /// Wall-clock time of the features and the first variant (s).
    pub measure_seconds: f64,
    /// On a twin: every variant against the true field.
    pub against_truth: Option<TwinReport>,
}

/// Measures `pair` with each of `variants` (at least one) on the same
/// feature points.
pub fn run(
    pair: &VolumePair,
    params: &FieldParams,
    variants: &[Consistency],
) -> Result<FieldOutcome> {
    let (iv, fv) = (pair.initial(), pair.deformed());
    let Some((&first, others)) = variants.split_first() else {
        return Err(TissueError::TooFew {
            stage: "field measurement",
            what: "matching variants",
            got: 0,
            needed: 1,
        });
    };
    let t0 = Instant::now();
    let feats = features(iv, fv, params)?;
    let mut fields = vec![measure_variant(&feats, params, first)?];
    let measure_seconds = t0.elapsed().as_secs_f64();
    for &c in others {
        fields.push(measure_variant(&feats, params, c)?);
    }
    let against_truth = match pair.twin() {
        Some(t) => Some(compare_on_twin(t, params, variants)?.0),
        None => None,
    };
    let variants = variants
        .iter()
        .zip(fields)
        .map(|(&consistency, measured)| VariantField {
            consistency,
            summary: summarise(iv, fv, consistency, &measured),
            measured,
        })
        .collect();
    Ok(FieldOutcome {
        features: feats,
        variants,
        measure_seconds,
        against_truth,
    })
}

/// Matching variant `c` of `params` on `feats`.
fn measure_variant(
    feats: &Features,
    params: &FieldParams,
    c: Consistency,
) -> Result<MeasuredField> {
    let mut p = *params;
    p.matching.consistency = c;
    measure_from(feats, &p)
}

/// The summary of one variant's field, with Eq. 12 on its own coverage.
fn summarise(iv: &Volume, fv: &Volume, c: Consistency, m: &MeasuredField) -> VariantSummary {
    let rms = registration_rms(iv, fv, &m.field, None);
    VariantSummary {
        matching: c.name(),
        matches: m.matches.len(),
        tetrahedra: m.field.tets.len(),
        folded_tetrahedra: m.folded_tets,
        horn_angle_deg: m.rigid.angle_deg(),
        horn_translation_mm: [
            m.rigid.translation_mm[0],
            m.rigid.translation_mm[1],
            m.rigid.translation_mm[2],
        ],
        horn_rms_residual_mm: m.rigid.rms_residual_mm,
        registration_rms: rms.map(|r| r.0),
        registration_voxels: rms.map(|r| r.1),
    }
}
