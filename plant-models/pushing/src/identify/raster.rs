//! Occupancy images and the pixel F-score of §VII-B (Eq. 16–19).
//!
//! Shapes are rasterised onto a fixed grid of square cells; a cell is
//! occupied when its centre lies inside the shape. With `cell_px = 1` a cell
//! is one camera pixel as in the seed; larger cells trade resolution for
//! speed. The mesh is rasterised triangle by triangle (the union), a tracked
//! contour as a polygon (even–odd rule).
use crate::error::{check_positive, PushError, Result};
use crate::mesh::Mesh;
use crate::V2;
use serde::{Deserialize, Serialize};

/// A grid of square cells covering a region of the image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RasterGrid {
    /// Lower-left corner, px.
    pub origin_px: V2,
    /// Cell side, px.
    pub cell_px: f64,
    pub nx: usize,
    pub ny: usize,
}

impl RasterGrid {
    /// A grid covering [lo, hi] with cells of `cell_px`.
    pub fn covering(lo_px: V2, hi_px: V2, cell_px: f64) -> Result<Self> {
        check_positive("cell_px", cell_px)?;
        let span = hi_px - lo_px;
        if !(span.x.is_finite() && span.y.is_finite()) || span.x <= 0.0 || span.y <= 0.0 {
            return Err(PushError::InvalidParameter {
                name: "raster region",
                value: span.x.min(span.y),
                reason: "must have a positive finite size",
            });
        }
        let nx = (span.x / cell_px).ceil() as usize;
        let ny = (span.y / cell_px).ceil() as usize;
        if nx.saturating_mul(ny) > 50_000_000 {
            return Err(PushError::InvalidParameter {
                name: "cell_px",
                value: cell_px,
                reason: "too small for the region (over 5e7 cells)",
            });
        }
        Ok(Self {
            origin_px: lo_px,
            cell_px,
            nx,
            ny,
        })
    }

    /// An empty image on this grid.
    pub fn empty(&self) -> Bitmap {
        Bitmap {
            nx: self.nx,
            ny: self.ny,
            words_per_row: self.nx.div_ceil(64),
            bits: vec![0; self.nx.div_ceil(64) * self.ny],
        }
    }

    /// Centre of cell (i, j), px.
    #[inline]
    pub fn cell_centre(&self, i: usize, j: usize) -> V2 {
        V2::new(
            self.origin_px.x + (i as f64 + 0.5) * self.cell_px,
            self.origin_px.y + (j as f64 + 0.5) * self.cell_px,
        )
    }

    /// Range of cell indices whose centres lie in [lo, hi] along x (or y).
    #[inline]
    fn index_range(&self, lo: f64, hi: f64, origin: f64, n: usize) -> Option<(usize, usize)> {
        self.index_range_inv(lo, hi, origin, n, 1.0 / self.cell_px)
    }

    /// [`Self::index_range`] with the reciprocal cell size precomputed.
    #[inline]
    fn index_range_inv(
        &self,
        lo: f64,
        hi: f64,
        origin: f64,
        n: usize,
        inv_cell: f64,
    ) -> Option<(usize, usize)> {
        let a = ceil_fast((lo - origin) * inv_cell - 0.5);
        let b = floor_fast((hi - origin) * inv_cell - 0.5);
        if !(a.is_finite() && b.is_finite()) || b < 0.0 || a > (n as f64 - 1.0) || a > b {
            return None;
        }
        Some((a.max(0.0) as usize, (b.min(n as f64 - 1.0)) as usize))
    }
}

/// A binary image, one bit per cell, rows of 64-bit words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Bitmap {
    pub nx: usize,
    pub ny: usize,
    words_per_row: usize,
    bits: Vec<u64>,
}

impl Bitmap {
    pub fn clear(&mut self) {
        self.bits.iter_mut().for_each(|w| *w = 0);
    }
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> bool {
        self.bits[j * self.words_per_row + i / 64] >> (i % 64) & 1 == 1
    }
    /// Sets cells i0..=i1 of row j.
    #[inline]
    fn set_span(&mut self, j: usize, i0: usize, i1: usize) {
        let row = j * self.words_per_row;
        let (w0, w1) = (i0 / 64, i1 / 64);
        for w in w0..=w1 {
            let lo = if w == w0 { i0 % 64 } else { 0 };
            let hi = if w == w1 { i1 % 64 } else { 63 };
            self.bits[row + w] |= span_mask(lo, hi);
        }
    }
    /// Toggles cells i0..=i1 of row j (even–odd polygon filling).
    #[inline]
    fn toggle_span(&mut self, j: usize, i0: usize, i1: usize) {
        let row = j * self.words_per_row;
        let (w0, w1) = (i0 / 64, i1 / 64);
        for w in w0..=w1 {
            let lo = if w == w0 { i0 % 64 } else { 0 };
            let hi = if w == w1 { i1 % 64 } else { 63 };
            self.bits[row + w] ^= span_mask(lo, hi);
        }
    }
    /// Number of occupied cells.
    pub fn count(&self) -> u64 {
        self.bits.iter().map(|w| w.count_ones() as u64).sum()
    }
}

/// `x.floor()` without the libm call the baseline x86-64 target makes
/// (no SSE4.1 `roundsd`): exact for |x| < 2⁵², falls back otherwise.
#[inline(always)]
fn floor_fast(x: f64) -> f64 {
    if x.abs() < 4.5e15 {
        let t = x as i64 as f64;
        if t > x {
            t - 1.0
        } else {
            t
        }
    } else {
        x.floor()
    }
}

/// `x.ceil()`, see [`floor_fast`].
#[inline(always)]
fn ceil_fast(x: f64) -> f64 {
    if x.abs() < 4.5e15 {
        let t = x as i64 as f64;
        if t < x {
            t + 1.0
        } else {
            t
        }
    } else {
        x.ceil()
    }
}

/// Bits lo..=hi of a word set (lo ≤ hi < 64).
#[inline]
fn span_mask(lo: usize, hi: usize) -> u64 {
    let upper = if hi == 63 {
        u64::MAX
    } else {
        (1u64 << (hi + 1)) - 1
    };
    upper & !((1u64 << lo) - 1)
}

/// Fills the triangle's cells (either orientation) into `img`: a cell is
/// filled when its centre lies inside or on the triangle. Rows are walked
/// with the edges' precomputed slopes.
pub fn fill_triangle(grid: &RasterGrid, img: &mut Bitmap, a: V2, b: V2, c: V2) {
    // Sort by y: p0 lowest, p2 highest.
    let (mut p0, mut p1, mut p2) = (a, b, c);
    if p1.y < p0.y {
        core::mem::swap(&mut p0, &mut p1);
    }
    if p2.y < p1.y {
        core::mem::swap(&mut p1, &mut p2);
    }
    if p1.y < p0.y {
        core::mem::swap(&mut p0, &mut p1);
    }
    let Some((j0, j1)) = grid.index_range(p0.y, p2.y, grid.origin_px.y, grid.ny) else {
        return;
    };
    let inv_cell = 1.0 / grid.cell_px;
    let slope = |p: V2, q: V2| {
        if q.y > p.y {
            (q.x - p.x) / (q.y - p.y)
        } else {
            0.0
        }
    };
    let (s02, s01, s12) = (slope(p0, p2), slope(p0, p1), slope(p1, p2));
    for j in j0..=j1 {
        let y = grid.origin_px.y + (j as f64 + 0.5) * grid.cell_px;
        let xa = p0.x + (y - p0.y) * s02;
        let xb = if y < p1.y {
            p0.x + (y - p0.y) * s01
        } else {
            p1.x + (y - p1.y) * s12
        };
        let (xmin, xmax) = if xa <= xb { (xa, xb) } else { (xb, xa) };
        if let Some((i0, i1)) =
            grid.index_range_inv(xmin, xmax, grid.origin_px.x, grid.nx, inv_cell)
        {
            img.set_span(j, i0, i1);
        }
    }
}

/// Rasterises the union of the mesh's triangles at `positions_px`.
pub fn rasterise_mesh(grid: &RasterGrid, img: &mut Bitmap, mesh: &Mesh, positions_px: &[V2]) {
    img.clear();
    for &[a, b, c] in &mesh.triangles {
        fill_triangle(grid, img, positions_px[a], positions_px[b], positions_px[c]);
    }
}

/// Rasterises a closed polygon (even–odd rule).
pub fn rasterise_polygon(grid: &RasterGrid, img: &mut Bitmap, polygon_px: &[V2]) {
    img.clear();
    let n = polygon_px.len();
    if n < 3 {
        return;
    }
    let mut xs: Vec<f64> = Vec::with_capacity(16);
    for j in 0..grid.ny {
        let y = grid.origin_px.y + (j as f64 + 0.5) * grid.cell_px;
        xs.clear();
        for k in 0..n {
            let p = polygon_px[k];
            let q = polygon_px[(k + 1) % n];
            // Half-open rule so a vertex on the scan line counts once.
            if (p.y <= y) != (q.y <= y) {
                xs.push(p.x + (y - p.y) * (q.x - p.x) / (q.y - p.y));
            }
        }
        xs.sort_by(|a, b| a.total_cmp(b));
        for pair in xs.chunks_exact(2) {
            if let Some((i0, i1)) = grid.index_range(pair[0], pair[1], grid.origin_px.x, grid.nx) {
                img.toggle_span(j, i0, i1);
            }
        }
    }
}

/// Pixel counts and F-score of one frame (Eq. 16–18).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameScore {
    pub true_positive: u64,
    pub false_positive: u64,
    pub false_negative: u64,
    /// F = 1 / (1 + (FN + FP) / (2 TP)); 0 when TP = 0.
    pub f_score: f64,
}

/// Compares a prediction with the ground truth (same grid).
pub fn f_score(truth: &Bitmap, predicted: &Bitmap) -> FrameScore {
    debug_assert_eq!(truth.bits.len(), predicted.bits.len());
    let (mut tp, mut fp, mut fneg) = (0u64, 0u64, 0u64);
    for (t, p) in truth.bits.iter().zip(&predicted.bits) {
        tp += (t & p).count_ones() as u64;
        fp += (!t & p).count_ones() as u64;
        fneg += (t & !p).count_ones() as u64;
    }
    let f = if tp == 0 {
        0.0
    } else {
        1.0 / (1.0 + (fneg + fp) as f64 / (2.0 * tp as f64))
    };
    FrameScore {
        true_positive: tp,
        false_positive: fp,
        false_negative: fneg,
        f_score: f,
    }
}

/// Running mean μ(F) after every frame (Eq. 19 as the mean over the frames
/// so far, as the text below it defines).
pub fn running_mean(f_per_frame: &[f64]) -> Vec<f64> {
    let mut sum = 0.0;
    f_per_frame
        .iter()
        .enumerate()
        .map(|(i, f)| {
            sum += f;
            sum / (i + 1) as f64
        })
        .collect()
}
