//! The matching variants on a synthetic twin, scored against the known
//! field — errors the paper could not report (its Table I has only the
//! registration RMS of Eq. 12).
//!
//! For each variant: the number of matches and tetrahedra (Table I's
//! columns), matches whose endpoint misses the true position by more than
//! one in-plane voxel ("wrong"), the endpoint error at the matches and of
//! the dense field against `φ(p) − p`, Eq. 12, and Horn's rotation against
//! the true one. Dense errors and Eq. 12 are taken over the voxels every
//! variant's tetrahedra cover, so a variant with a larger hull is not
//! scored on extra (harder) voxels.
use super::horn::{horn, rotation_difference_deg};
use super::matching::Consistency;
use super::pipeline::{features, measure_from, rms_slices, Features, FieldParams, MeasuredField};
use crate::error::Result;
use crate::field::model::shape::{rms_difference, DenseField};
use crate::field::model::synth::Twin;
use crate::field::model::volume::Volume;
use nalgebra::Matrix3;

/// How one matching variant did on a twin.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct VariantReport {
    /// The variant.
    pub consistency: Consistency,
    /// Potential matches (Table I: 771 with, 827 without the constraint).
    pub matches: usize,
    /// Delaunay tetrahedra (Table I: 4344 and 4798).
    pub tetrahedra: usize,
    /// Tetrahedra the measured motion turns inside out.
    pub folded_tetrahedra: usize,
    /// Matches more than one in-plane voxel from the true position.
    pub wrong_matches: usize,
    /// RMS endpoint error at the matches (mm).
    pub match_endpoint_rms_mm: f64,
    /// Mean endpoint error at the matches (mm).
    pub match_endpoint_mean_mm: f64,
    /// RMS endpoint error of the dense field on the common voxels (mm).
    pub dense_endpoint_rms_mm: f64,
    /// Mean endpoint error of the dense field on the common voxels (mm).
    pub dense_endpoint_mean_mm: f64,
    /// Eq. 12 on the common voxels of the paper's slices.
    pub registration_rms: f64,
    /// Horn's rotation angle (degrees).
    pub horn_angle_deg: f64,
    /// Angle between Horn's rotation and Horn's rotation of the true
    /// motion of the same points (degrees): the rigid part of the true
    /// field there, which includes the net rotation of the non-rigid warp.
    pub rotation_error_deg: f64,
}

/// The comparison on one twin.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TwinReport {
    /// IV feature points.
    pub features_initial: usize,
    /// FV feature points.
    pub features_deformed: usize,
    /// IV points with at least one candidate.
    pub with_candidates: usize,
    /// Mean number of candidates of an IV point that has any.
    pub mean_candidates: f64,
    /// The applied rotation angle (degrees); the rigid part Horn finds in
    /// the true field differs by the non-rigid warp's net rotation.
    pub true_rotation_deg: f64,
    /// Largest true displacement at the IV feature points (mm).
    pub max_true_displacement_mm: f64,
    /// Dense-field points scored (initial frame, every variant covers them).
    pub dense_points: usize,
    /// Voxels of Eq. 12 (deformed frame, every variant covers them).
    pub registration_voxels: usize,
    /// Eq. 12 without registration (deformed vs initial volume).
    pub rms_unregistered: f64,
    /// Eq. 12 with the true field (the floor set by noise and resampling).
    pub rms_true_field: f64,
    /// One report per variant, in the order asked.
    pub variants: Vec<VariantReport>,
}

fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// Runs `variants` on `twin` with shared features; returns the report and
/// each variant's measured field.
pub fn compare_on_twin(
    twin: &Twin,
    params: &FieldParams,
    variants: &[Consistency],
) -> Result<(TwinReport, Features, Vec<MeasuredField>)> {
    let feats = features(&twin.initial, &twin.deformed, params)?;
    let mut measured = Vec::new();
    for &c in variants {
        let mut p = *params;
        p.matching.consistency = c;
        measured.push(measure_from(&feats, &p)?);
    }
    let cover = Coverage::of(twin, &measured);
    let floors = Floors::of(twin, &cover);
    let reports = measured
        .iter()
        .enumerate()
        .map(|(k, m)| score_variant(twin, &feats, &cover, k, m, variants[k]))
        .collect();
    let max_true_displacement_mm = feats
        .initial
        .iter()
        .map(|f| norm(twin.warp.displacement_mm(f.position_mm)))
        .fold(0.0, f64::max);
    let r_true = Matrix3::from_fn(|r, c| twin.warp.rotation()[r][c]);
    let report = TwinReport {
        features_initial: feats.initial.len(),
        features_deformed: feats.deformed.len(),
        with_candidates: feats.candidates.iter().filter(|c| !c.is_empty()).count(),
        mean_candidates: mean_candidates(&feats),
        true_rotation_deg: rotation_difference_deg(&Matrix3::identity(), &r_true),
        max_true_displacement_mm,
        dense_points: cover.dense_voxels.len(),
        registration_voxels: floors.registration_voxels,
        rms_unregistered: floors.rms_unregistered,
        rms_true_field: floors.rms_true_field,
        variants: reports,
    };
    Ok((report, feats, measured))
}

/// The voxels every variant covers: each variant's dense field, every
/// other in-plane voxel of the initial frame that all dense fields reach
/// (with the true field there), and each variant's warped initial volume
/// with the deformed-frame voxels all of them reach (Eq. 12).
struct Coverage {
    dense: Vec<DenseField>,
    dense_voxels: Vec<usize>,
    true_at: Vec<[f64; 3]>,
    warped: Vec<(Volume, Vec<bool>)>,
    registration: Vec<bool>,
}

impl Coverage {
    fn of(twin: &Twin, measured: &[MeasuredField]) -> Coverage {
        let iv = &twin.initial;
        let dims = iv.dims();
        let sp = iv.spacing_mm();
        let dense: Vec<_> = measured.iter().map(|m| m.field.dense(dims, sp)).collect();
        let n = dims[0] * dims[1] * dims[2];
        let step = 2usize; // every other voxel in-plane for the dense error
        let dense_voxels: Vec<usize> = (0..n)
            .filter(|&i| {
                let x = i % dims[0];
                let y = (i / dims[0]) % dims[1];
                x % step == 0
                    && y % step == 0
                    && dense.iter().all(|d| d.displacement_mm[i].is_some())
            })
            .collect();
        let true_at: Vec<[f64; 3]> = dense_voxels
            .iter()
            .map(|&i| {
                let v = crate::field::model::volume::unravel(dims, i);
                twin.warp.displacement_mm(iv.position_mm(v))
            })
            .collect();
        let warped: Vec<(Volume, Vec<bool>)> = measured.iter().map(|m| m.field.warp(iv)).collect();
        let mut registration = vec![true; n];
        for (_, mask) in &warped {
            for (c, m) in registration.iter_mut().zip(mask) {
                *c &= *m;
            }
        }
        Coverage {
            dense,
            dense_voxels,
            true_at,
            warped,
            registration,
        }
    }
}

/// Eq. 12 without registration and with the true field, on the common
/// voxels: the ceiling and the floor a variant is judged between.
struct Floors {
    rms_unregistered: f64,
    registration_voxels: usize,
    rms_true_field: f64,
}

impl Floors {
    fn of(twin: &Twin, cover: &Coverage) -> Floors {
        let iv = &twin.initial;
        let fv = &twin.deformed;
        let dims = iv.dims();
        let sp = iv.spacing_mm();
        let n = dims[0] * dims[1] * dims[2];
        let common_reg = &cover.registration;
        let slices = rms_slices(dims[2]);
        let (rms_unregistered, registration_voxels) =
            rms_difference(fv, iv, common_reg, slices.clone()).unwrap_or((f64::NAN, 0));
        let mut by_truth = Volume::zeros(dims, sp);
        let mut truth_mask = common_reg.clone();
        for i in 0..n {
            if common_reg[i] {
                let v = crate::field::model::volume::unravel(dims, i);
                match iv.sample_mm(twin.warp.backward_mm(fv.position_mm(v))) {
                    Some(val) => by_truth.data_mut()[i] = val,
                    None => truth_mask[i] = false,
                }
            }
        }
        let rms_true_field = rms_difference(fv, &by_truth, &truth_mask, slices)
            .map(|r| r.0)
            .unwrap_or(f64::NAN);
        Floors {
            rms_unregistered,
            registration_voxels,
            rms_true_field,
        }
    }
}

/// Variant `k` (`consistency`, field `m`) against the truth.
fn score_variant(
    twin: &Twin,
    feats: &Features,
    cover: &Coverage,
    k: usize,
    m: &MeasuredField,
    consistency: Consistency,
) -> VariantReport {
    let fv = &twin.deformed;
    let sp = twin.initial.spacing_mm();
    let voxel_mm = sp[0].max(sp[1]);
    let slices = rms_slices(twin.initial.dims()[2]);
    let errs: Vec<f64> = m
        .matches
        .iter()
        .map(|mm| {
            let p = feats.initial[mm.initial].position_mm;
            let q = feats.deformed[mm.deformed].position_mm;
            let t = twin.warp.forward_mm(p);
            norm([q[0] - t[0], q[1] - t[1], q[2] - t[2]])
        })
        .collect();
    let nm = errs.len().max(1) as f64;
    let dense_errs: Vec<f64> = cover
        .dense_voxels
        .iter()
        .zip(&cover.true_at)
        .map(|(&i, t)| {
            let u = cover.dense[k].displacement_mm[i].unwrap_or([f32::NAN; 3]);
            norm([
                f64::from(u[0]) - t[0],
                f64::from(u[1]) - t[1],
                f64::from(u[2]) - t[2],
            ])
        })
        .collect();
    let nd = dense_errs.len().max(1) as f64;
    let registration_rms = rms_difference(fv, &cover.warped[k].0, &cover.registration, slices)
        .map(|r| r.0)
        .unwrap_or(f64::NAN);
    VariantReport {
        consistency,
        matches: m.matches.len(),
        tetrahedra: m.field.tets.len(),
        folded_tetrahedra: m.folded_tets,
        wrong_matches: errs.iter().filter(|&&e| e > voxel_mm).count(),
        match_endpoint_rms_mm: (errs.iter().map(|e| e * e).sum::<f64>() / nm).sqrt(),
        match_endpoint_mean_mm: errs.iter().sum::<f64>() / nm,
        dense_endpoint_rms_mm: (dense_errs.iter().map(|e| e * e).sum::<f64>() / nd).sqrt(),
        dense_endpoint_mean_mm: dense_errs.iter().sum::<f64>() / nd,
        registration_rms,
        horn_angle_deg: m.rigid.angle_deg(),
        rotation_error_deg: rotation_error_deg(twin, feats, m),
    }
}

/// Angle (degrees) between Horn's rotation of the matches and Horn's
/// rotation of the true motion of the same points.
fn rotation_error_deg(twin: &Twin, feats: &Features, m: &MeasuredField) -> f64 {
    let a: Vec<[f64; 3]> = m
        .matches
        .iter()
        .map(|mm| feats.initial[mm.initial].position_mm)
        .collect();
    let b: Vec<[f64; 3]> = a.iter().map(|p| twin.warp.forward_mm(*p)).collect();
    match horn(&a, &b) {
        Ok(t) => rotation_difference_deg(&m.rigid.rotation, &t.rotation),
        Err(_) => f64::NAN,
    }
}

/// Mean number of candidates of an IV point that has any.
fn mean_candidates(feats: &Features) -> f64 {
    let with: Vec<usize> = feats
        .candidates
        .iter()
        .map(Vec::len)
        .filter(|&l| l > 0)
        .collect();
    with.iter().sum::<usize>() as f64 / with.len().max(1) as f64
}
