//! A 3-D scalar volume image (an MR volume of Zhang's paper) and its
//! NIfTI-1 reader and writer.
//!
//! Voxel `(x, y, z)` is stored at `x + nx (y + ny z)` (x fastest, as in
//! NIfTI files). Positions are in millimetres with voxel `(0, 0, 0)` at the
//! origin: voxel `(i, j, k)` is centred at `(i dx, j dy, k dz)`.
//!
//! Why NIfTI through the `nifti` crate: NIfTI-1 is what MR converters,
//! ITK, FSL and 3D Slicer read and write, so a real calf or breast volume
//! can be fed in as it comes; the crate reads every scalar datatype in
//! either byte order, applies `scl_slope`/`scl_inter` and reads `.nii.gz`,
//! which a hand-written 348-byte header parser would have to get right
//! case by case. Volumes are written as float32 `.nii` (or `.nii.gz` by
//! the file name) with `pixdim` in millimetres.
//!
//! Left out: the qform/sform orientation (the volume is taken in its voxel
//! axes), 4-D series (refused: one time point per file), complex and RGB
//! data (refused by name).
use crate::error::{Result, TissueError};
use std::path::Path;

/// A 3-D scalar volume, intensities as f32, voxel spacing in mm.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    dims: [usize; 3],
    spacing_mm: [f64; 3],
    data: Vec<f32>,
}

impl Volume {
    /// A volume of `dims` voxels with `data` in x-fastest order; refuses a
    /// wrong length, a non-positive spacing and non-finite voxels (named
    /// by index; `what` names the volume in errors).
    pub fn new(dims: [usize; 3], spacing_mm: [f64; 3], data: Vec<f32>, what: &str) -> Result<Self> {
        if dims.contains(&0) {
            return Err(TissueError::VolumeShape {
                what: what.into(),
                reason: format!(
                    "{}×{}×{} voxels: every side needs at least one",
                    dims[0], dims[1], dims[2]
                ),
            });
        }
        let n = dims[0] * dims[1] * dims[2];
        if data.len() != n {
            return Err(TissueError::VolumeShape {
                what: what.into(),
                reason: format!(
                    "{} values for {}×{}×{} = {n} voxels",
                    data.len(),
                    dims[0],
                    dims[1],
                    dims[2]
                ),
            });
        }
        for (axis, &s) in ["x", "y", "z"].iter().zip(&spacing_mm) {
            if !(s.is_finite() && s > 0.0) {
                return Err(TissueError::VolumeShape {
                    what: what.into(),
                    reason: format!(
                        "voxel spacing along {axis} is {} mm: must be finite and > 0",
                        plant_common::short_number(s)
                    ),
                });
            }
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            let [x, y, z] = unravel(dims, i);
            return Err(TissueError::NonFiniteVoxel {
                what: what.into(),
                x,
                y,
                z,
            });
        }
        Ok(Volume {
            dims,
            spacing_mm,
            data,
        })
    }

    /// A volume of zeros.
    pub fn zeros(dims: [usize; 3], spacing_mm: [f64; 3]) -> Self {
        Volume {
            dims,
            spacing_mm,
            data: vec![0.0; dims[0] * dims[1] * dims[2]],
        }
    }

    /// Voxels along x, y, z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Voxel spacing (mm) along x, y, z.
    pub fn spacing_mm(&self) -> [f64; 3] {
        self.spacing_mm
    }

    /// The intensities, x fastest.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The intensities, mutable (for generators and filters in this crate).
    pub(crate) fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }

    /// Linear index of voxel `(x, y, z)`.
    pub fn index(&self, x: usize, y: usize, z: usize) -> usize {
        x + self.dims[0] * (y + self.dims[1] * z)
    }

    /// Intensity of voxel `(x, y, z)` (must be inside).
    pub fn at(&self, x: usize, y: usize, z: usize) -> f32 {
        self.data[self.index(x, y, z)]
    }

    /// Position (mm) of voxel `(x, y, z)`.
    pub fn position_mm(&self, v: [usize; 3]) -> [f64; 3] {
        std::array::from_fn(|a| v[a] as f64 * self.spacing_mm[a])
    }

    /// Continuous voxel coordinates of a position (mm).
    pub fn to_voxel(&self, p_mm: [f64; 3]) -> [f64; 3] {
        std::array::from_fn(|a| p_mm[a] / self.spacing_mm[a])
    }

    /// Whether a position (mm) lies inside the voxel-centre box.
    pub fn contains_mm(&self, p_mm: [f64; 3]) -> bool {
        let v = self.to_voxel(p_mm);
        (0..3).all(|a| v[a] >= 0.0 && v[a] <= (self.dims[a] - 1) as f64)
    }

    /// Trilinear intensity at a position (mm); `None` outside the
    /// voxel-centre box.
    pub fn sample_mm(&self, p_mm: [f64; 3]) -> Option<f32> {
        let v = self.to_voxel(p_mm);
        let mut base = [0usize; 3];
        let mut frac = [0.0f64; 3];
        for a in 0..3 {
            let hi = (self.dims[a] - 1) as f64;
            if !(v[a] >= 0.0 && v[a] <= hi) {
                return None;
            }
            let f = v[a].floor().min((self.dims[a] as f64 - 2.0).max(0.0));
            base[a] = f as usize;
            frac[a] = v[a] - f;
        }
        let step = |a: usize| usize::from(self.dims[a] > 1);
        let mut acc = 0.0f64;
        for corner in 0..8 {
            let off = [corner & 1, (corner >> 1) & 1, (corner >> 2) & 1];
            let mut w = 1.0;
            let mut idx = [0usize; 3];
            for a in 0..3 {
                w *= if off[a] == 1 { frac[a] } else { 1.0 - frac[a] };
                idx[a] = base[a] + off[a] * step(a);
            }
            if w != 0.0 {
                acc += w * f64::from(self.at(idx[0], idx[1], idx[2]));
            }
        }
        Some(acc as f32)
    }

    /// A Gaussian-smoothed copy, standard deviation `sigma_mm` per axis
    /// (0 leaves an axis alone); separable, kernels cut at 3σ, borders
    /// replicated.
    pub fn gaussian_blur(&self, sigma_mm: [f64; 3]) -> Volume {
        let mut out = self.clone();
        for (a, (s, sp)) in sigma_mm.iter().zip(&self.spacing_mm).enumerate() {
            let sigma_vox = s / sp;
            if sigma_vox > 0.0 && self.dims[a] > 1 {
                blur_axis(&mut out.data, self.dims, a, sigma_vox);
            }
        }
        out
    }

    /// Reads a NIfTI-1 volume (`.nii`, `.nii.gz`, or a `.hdr`/`.img`
    /// pair). A 4-D file with one time point is accepted; more are refused,
    /// as are complex and RGB data and NaN voxels (named by index).
    pub fn read_nifti(path: &Path) -> Result<Volume> {
        use nifti::{IntoNdArray, NiftiObject, NiftiVolume, ReaderOptions};
        let name = path.display().to_string();
        let file_err = |reason: String| TissueError::VolumeFile {
            path: name.clone(),
            reason,
        };
        let obj = ReaderOptions::new()
            .read_file(path)
            .map_err(|e| file_err(nifti_reason(&e)))?;
        let header = obj.header().clone();
        let volume = obj.into_volume();
        let dim: Vec<usize> = volume.dim().iter().map(|&d| usize::from(d)).collect();
        let extra: usize = dim.iter().skip(3).product();
        if dim.len() < 3 || dim[..3].contains(&0) || extra != 1 {
            return Err(TissueError::VolumeShape {
                what: name,
                reason: format!(
                    "dimensions {dim:?}: a single 3-D volume is needed (one time point)"
                ),
            });
        }
        let dims = [dim[0], dim[1], dim[2]];
        let mut spacing_mm = [0.0; 3];
        let unit_mm = match header.xyzt_units & 0x07 {
            1 => 1000.0, // metres
            3 => 1e-3,   // micrometres
            _ => 1.0,    // millimetres, or unknown (taken as mm)
        };
        for (a, s) in spacing_mm.iter_mut().enumerate() {
            *s = f64::from(header.pixdim[a + 1]).abs() * unit_mm;
        }
        let array = volume
            .into_ndarray::<f32>()
            .map_err(|e| file_err(e.to_string()))?;
        // The array is indexed [x, y, z, …]; its transpose iterates x fastest.
        let data: Vec<f32> = array.t().iter().copied().collect();
        Volume::new(dims, spacing_mm, data, &name)
    }

    /// Writes the volume as float32 NIfTI-1 (`.nii`, or `.nii.gz` when the
    /// name ends so), spacing in `pixdim` with millimetre units.
    pub fn write_nifti(&self, path: &Path) -> Result<()> {
        use ndarray::ShapeBuilder;
        let name = path.display().to_string();
        let header = nifti::NiftiHeader {
            pixdim: [
                1.0,
                self.spacing_mm[0] as f32,
                self.spacing_mm[1] as f32,
                self.spacing_mm[2] as f32,
                1.0,
                1.0,
                1.0,
                1.0,
            ],
            xyzt_units: 2, // NIFTI_UNITS_MM
            descrip: b"softjoint tissue volume".to_vec(),
            ..Default::default()
        };
        let array = ndarray::Array3::from_shape_vec(
            (self.dims[0], self.dims[1], self.dims[2]).f(),
            self.data.clone(),
        )
        .map_err(|e| TissueError::VolumeFile {
            path: name.clone(),
            reason: e.to_string(),
        })?;
        nifti::writer::WriterOptions::new(path)
            .reference_header(&header)
            .write_nifti(&array)
            .map_err(|e| TissueError::VolumeFile {
                path: name,
                reason: nifti_reason(&e),
            })
    }
}

/// Voxel `(x, y, z)` of linear index `i`.
pub fn unravel(dims: [usize; 3], i: usize) -> [usize; 3] {
    [
        i % dims[0],
        (i / dims[0]) % dims[1],
        i / (dims[0] * dims[1]),
    ]
}

/// Normalised Gaussian kernel of standard deviation `sigma` (samples),
/// cut at 3σ.
pub(crate) fn gaussian_kernel(sigma: f64) -> Vec<f64> {
    let r = (3.0 * sigma).ceil().max(1.0) as i64;
    let mut k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    for v in &mut k {
        *v /= s;
    }
    k
}

/// Convolves `data` (x-fastest, `dims`) along `axis` with a Gaussian,
/// borders replicated.
pub(crate) fn blur_axis(data: &mut [f32], dims: [usize; 3], axis: usize, sigma: f64) {
    let k = gaussian_kernel(sigma);
    let r = (k.len() / 2) as i64;
    let n = dims[axis];
    let stride = match axis {
        0 => 1,
        1 => dims[0],
        _ => dims[0] * dims[1],
    };
    let mut line = vec![0.0f64; n];
    let lines: Vec<usize> = (0..data.len()).filter(|&i| (i / stride) % n == 0).collect();
    for start in lines {
        for (j, l) in line.iter_mut().enumerate() {
            *l = f64::from(data[start + j * stride]);
        }
        for j in 0..n as i64 {
            let mut acc = 0.0;
            for (t, w) in k.iter().enumerate() {
                let s = (j + t as i64 - r).clamp(0, n as i64 - 1) as usize;
                acc += w * line[s];
            }
            data[start + j as usize * stride] = acc as f32;
        }
    }
}

/// A NIfTI error in words: the nifti crate shows an I/O error in its
/// debug form (`Io(Os { code: 2, kind: NotFound, … })`), so that one is
/// taken apart here.
fn nifti_reason(e: &nifti::error::NiftiError) -> String {
    match e {
        nifti::error::NiftiError::Io(io) => io.to_string(),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {

    /// A missing file is said in words, not as `Io(Os { … })`.
    #[test]
    fn a_missing_volume_file_is_named_in_words() {
        let e = Volume::read_nifti(Path::new("/nonexistent/a.nii"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/a.nii"), "{e}");
        assert!(e.contains("No such file or directory"), "{e}");
        assert!(!e.contains("Io(") && !e.contains("Os {"), "{e}");
    }

    use super::*;

    fn ramp(dims: [usize; 3]) -> Volume {
        let data = (0..dims[0] * dims[1] * dims[2])
            .map(|i| {
                let [x, y, z] = unravel(dims, i);
                (x as f32) + 10.0 * y as f32 - 3.5 * z as f32
            })
            .collect();
        Volume::new(dims, [0.5, 0.75, 2.0], data, "ramp").unwrap()
    }

    #[test]
    fn trilinear_sampling_is_exact_on_a_linear_ramp() {
        let v = ramp([6, 5, 4]);
        let p = [1.3, 2.2, 3.9]; // mm
        let want = 1.3 / 0.5 + 10.0 * 2.2 / 0.75 - 3.5 * 3.9 / 2.0;
        let got = f64::from(v.sample_mm(p).unwrap());
        assert!((got - want).abs() < 1e-4, "{got} vs {want}");
        assert!(v.sample_mm([-0.01, 0.0, 0.0]).is_none());
        assert!(v.sample_mm([2.5, 3.0, 6.0]).is_some());
    }

    #[test]
    fn blur_keeps_a_constant_and_a_linear_ramp_away_from_borders() {
        let v = ramp([20, 3, 3]);
        let b = v.gaussian_blur([0.8, 0.0, 0.0]);
        for x in 6..14 {
            assert!((b.at(x, 1, 1) - v.at(x, 1, 1)).abs() < 1e-3, "x = {x}");
        }
    }

    #[test]
    fn nifti_round_trip_keeps_shape_spacing_and_values() {
        let dir = tempfile::tempdir().unwrap();
        for name in ["v.nii", "v.nii.gz"] {
            let path = dir.path().join(name);
            let v = ramp([7, 5, 3]);
            v.write_nifti(&path).unwrap();
            let back = Volume::read_nifti(&path).unwrap();
            assert_eq!(back, v, "{name}");
        }
    }

    #[test]
    fn bad_volumes_are_refused_by_name() {
        let e = Volume::new([2, 2, 2], [1.0; 3], vec![0.0; 7], "a").unwrap_err();
        assert!(
            e.to_string().contains("7 values for 2×2×2 = 8 voxels"),
            "{e}"
        );
        let mut d = vec![0.0; 8];
        d[5] = f32::NAN;
        let e = Volume::new([2, 2, 2], [1.0; 3], d, "b.nii").unwrap_err();
        assert_eq!(
            e.to_string(),
            "b.nii: voxel (1, 0, 1) is not a finite number"
        );
        let e = Volume::new([2, 2, 2], [1.0, 0.0, 1.0], vec![0.0; 8], "c").unwrap_err();
        assert!(e.to_string().contains("spacing along y"), "{e}");
        let e = Volume::read_nifti(Path::new("/nonexistent/x.nii")).unwrap_err();
        assert!(e.to_string().starts_with("/nonexistent/x.nii: "), "{e}");
    }
}
