//! The paper's objective S: the sum of distances from the captured
//! surface points to the virtual object at the frame times (L1734–1738),
//! and the sum of force differences over the keeping period (L2249–2252).
//!
//! S = w_shape·S_shape + w_force·S_force, with S_shape in cm (the paper's
//! unit: its S ≈ 2350 for 14,551 points is 1.6 mm per point) and S_force
//! in N summed over the sensor's samples in the window. The paper
//! calibrates by one or the other (shape in the first deck, force in the
//! second); the default weights are shape only.
//!
//! The distance of a point to the lattice is to its surface triangles at
//! that frame (two per surface quad of the lattice), found through a
//! uniform grid of triangle boxes searched in growing shells — exact, like
//! the paper's Lin–Canny search (L1736, L2229), not an approximation.
use serde::Serialize;

use crate::error::{Result, RheologyError};
use crate::identify::measurement::{ForceSample, Measurement};
use crate::model::lattice::{Lattice, V3};
pub use crate::model::scenario::Objective;
use crate::model::scenario::Run;
use crate::model::sim::escape_sphere;

/// S and its parts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Score {
    /// The weighted sum (+∞ when the run was unstable).
    pub s: f64,
    /// Σ point distances (cm).
    pub shape_cm: f64,
    /// Σ |F_measured − F_model| over the window's samples (N).
    pub force_n: f64,
    /// Points and samples compared.
    pub points: usize,
    pub samples: usize,
}

impl Score {
    /// Mean distance per point (mm).
    pub fn mean_distance_mm(&self) -> f64 {
        10.0 * self.shape_cm / self.points.max(1) as f64
    }
    /// Mean force difference per sample (N).
    pub fn mean_force_error_n(&self) -> f64 {
        self.force_n / self.samples.max(1) as f64
    }
}

/// The largest S_shape (cm) a stable run of `lattice` can score against
/// `m`: every node of a stable run stays inside the escape sphere (centre
/// c, radius R; checked each step), so a point p lies at most |p − c| + R
/// from the nearest surface triangle (no further than from any of its
/// corners). The sum of that over the measured points, in cm.
pub fn shape_cm_bound(lattice: &Lattice, m: &Measurement) -> f64 {
    let (centre, escape_m) = escape_sphere(lattice);
    m.frames
        .iter()
        .flat_map(|f| &f.points_m)
        .map(|p| 100.0 * ((*p - centre).norm() + escape_m))
        .sum()
}

/// Refuses a shape weight for which S can overflow a double against this
/// measurement: `shape_per_cm` × [`shape_cm_bound`] must be finite, so
/// that a stable run's S_shape term always is (issue 31: 1e308 per cm
/// gave S = ∞, a stable run reported as unstable). The force term has no
/// such bound before a run (the model's force is bounded only by its
/// stability); [`score`] refuses it if it overflows.
pub fn check_weights(lattice: &Lattice, m: &Measurement, obj: &Objective) -> Result<()> {
    if obj.shape_per_cm > 0.0 && !(obj.shape_per_cm * shape_cm_bound(lattice, m)).is_finite() {
        return Err(RheologyError::InvalidParameter {
            name: "objective.shape_per_cm".into(),
            value: obj.shape_per_cm,
            reason: "times the largest S_shape a stable run can have against the measured \
                     points (each at its distance from the block plus the escape distance) \
                     overflows a double; lower the weight",
        });
    }
    Ok(())
}

/// Scores a model run against a measurement, forces over the keeping
/// period `force_window_s`. Frames are matched by time (the model's frame
/// nearest each measured one); a run that stopped early scores +∞. A
/// stable run whose weighted S is not finite is an error naming the
/// weight of the term that overflowed, never an S of +∞ (which would read
/// as an unstable run).
pub fn score(
    surface: &[[u32; 3]],
    run: &Run,
    m: &Measurement,
    obj: &Objective,
    force_window_s: [f64; 2],
) -> Result<Score> {
    let mut out = Score {
        s: f64::INFINITY,
        shape_cm: 0.0,
        force_n: 0.0,
        points: 0,
        samples: 0,
    };
    if run.instability.is_some() || run.t_s.is_empty() {
        return Ok(out);
    }
    if obj.shape_per_cm > 0.0 {
        let mut grid = TriangleGrid::default();
        for frame in &m.frames {
            let Some(model) = run.frames.iter().min_by(|a, b| {
                (a.t_s - frame.t_s)
                    .abs()
                    .total_cmp(&(b.t_s - frame.t_s).abs())
            }) else {
                return Ok(out);
            };
            grid.build(surface, &model.positions_m);
            for p in &frame.points_m {
                out.shape_cm += 100.0 * grid.distance(p, surface, &model.positions_m);
            }
            out.points += frame.points_m.len();
        }
    }
    if obj.force_per_n > 0.0 {
        let [w0, w1] = force_window_s;
        for s in m.forces.iter().filter(|s| s.t_s >= w0 && s.t_s <= w1) {
            out.force_n += (s.force_n - interpolate(run, s)).abs();
            out.samples += 1;
        }
    }
    out.s = weighted(obj, &out)?;
    Ok(out)
}

/// S = shape_per_cm·S_shape + force_per_n·S_force of a stable run, or an
/// error naming the weight whose term (or the sum) is not finite.
fn weighted(obj: &Objective, sc: &Score) -> Result<f64> {
    let terms = [
        (
            "shape_per_cm",
            obj.shape_per_cm,
            "S_shape",
            sc.shape_cm,
            "cm",
        ),
        ("force_per_n", obj.force_per_n, "S_force", sc.force_n, "N"),
    ];
    let mut s = 0.0;
    for (name, w, term, value, unit) in terms {
        let part = w * value;
        if !part.is_finite() {
            return Err(RheologyError::InvalidSetting {
                name: format!("objective.{name}"),
                reason: format!(
                    "{name} × {term} = {} × {} {unit} is not a finite number (the run was \
                     stable); lower the weight",
                    plant_common::short_number(w),
                    plant_common::short_number(value)
                ),
            });
        }
        s += part;
    }
    if !s.is_finite() {
        return Err(RheologyError::InvalidSetting {
            name: "objective".into(),
            reason: "shape_per_cm·S_shape + force_per_n·S_force overflows a double (the run \
                     was stable); lower the weights"
                .into(),
        });
    }
    Ok(s)
}

/// The model's plate force at a sample's time (linear between steps).
fn interpolate(run: &Run, s: &ForceSample) -> f64 {
    let t = &run.t_s;
    let k = t.partition_point(|&x| x < s.t_s);
    if k == 0 {
        return run.plate_force_n[0];
    }
    if k >= t.len() {
        return run.plate_force_n[t.len() - 1];
    }
    let (t0, t1) = (t[k - 1], t[k]);
    let (f0, f1) = (run.plate_force_n[k - 1], run.plate_force_n[k]);
    f0 + (f1 - f0) * (s.t_s - t0) / (t1 - t0)
}

/// Distance from `p` to triangle (a, b, c) (closest-point regions, as in
/// Ericson, Real-Time Collision Detection §5.1.5).
pub fn point_triangle_distance(p: &V3, a: &V3, b: &V3, c: &V3) -> f64 {
    let (ab, ac, ap) = (*b - *a, *c - *a, *p - *a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.norm();
    }
    let bp = *p - *b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.norm();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (*p - (*a + ab * v)).norm();
    }
    let cp = *p - *c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.norm();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (*p - (*a + ac * w)).norm();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (*p - (*b + (*c - *b) * w)).norm();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (*p - (*a + ab * v + ac * w)).norm()
}

/// Triangles bucketed by their bounding boxes in a uniform grid.
#[derive(Clone, Debug, Default)]
pub struct TriangleGrid {
    lo: V3,
    cell: f64,
    dims: [usize; 3],
    start: Vec<u32>,
    items: Vec<u32>,
    counts: Vec<u32>,
}

impl TriangleGrid {
    /// Buckets `surface` at positions `x`.
    pub fn build(&mut self, surface: &[[u32; 3]], x: &[V3]) {
        let (mut lo, mut hi) = (V3::repeat(f64::INFINITY), V3::repeat(f64::NEG_INFINITY));
        let mut edge = 0.0;
        for t in surface {
            let [a, b, c] = t.map(|n| x[n as usize]);
            lo = lo.inf(&a).inf(&b).inf(&c);
            hi = hi.sup(&a).sup(&b).sup(&c);
            edge += (b - a).norm() + (c - b).norm() + (a - c).norm();
        }
        let span = hi - lo;
        // Cells about a mean edge long, at most 64 per axis.
        let mean_edge = (edge / (3 * surface.len().max(1)) as f64).max(1e-9);
        let biggest = span.x.max(span.y).max(span.z);
        self.cell = mean_edge.max(biggest / 64.0);
        self.lo = lo;
        self.dims =
            [span.x, span.y, span.z].map(|s| ((s / self.cell).floor() as usize + 1).min(65));
        let ncell = self.dims[0] * self.dims[1] * self.dims[2];
        self.counts.clear();
        self.counts.resize(ncell + 1, 0);
        let boxes = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|n| x[n as usize]);
            (a.inf(&b).inf(&c), a.sup(&b).sup(&c))
        };
        for pass in 0..2 {
            if pass == 1 {
                // Prefix sums into starts.
                self.start.clear();
                self.start.resize(ncell + 1, 0);
                for i in 0..ncell {
                    self.start[i + 1] = self.start[i] + self.counts[i];
                }
                self.items.clear();
                self.items.resize(self.start[ncell] as usize, 0);
                self.counts.fill(0);
            }
            for (ti, t) in surface.iter().enumerate() {
                let (bl, bh) = boxes(t);
                let (i0, i1) = (self.index(&bl), self.index(&bh));
                for k in i0[2]..=i1[2] {
                    for j in i0[1]..=i1[1] {
                        for i in i0[0]..=i1[0] {
                            let c = i + self.dims[0] * (j + self.dims[1] * k);
                            if pass == 1 {
                                self.items[(self.start[c] + self.counts[c]) as usize] = ti as u32;
                            }
                            self.counts[c] += 1;
                        }
                    }
                }
            }
        }
    }

    fn index(&self, p: &V3) -> [usize; 3] {
        let rel = (*p - self.lo) / self.cell;
        [rel.x, rel.y, rel.z]
            .iter()
            .zip(self.dims)
            .map(|(&r, d)| (r.max(0.0).floor() as usize).min(d - 1))
            .collect::<Vec<_>>()
            .try_into()
            .unwrap_or([0, 0, 0])
    }

    /// Distance from `p` to the nearest triangle.
    pub fn distance(&self, p: &V3, surface: &[[u32; 3]], x: &[V3]) -> f64 {
        let c = self.index(p);
        let mut best = f64::INFINITY;
        let max_r = self.dims.iter().max().copied().unwrap_or(1);
        for r in 0..=max_r {
            let lo: [usize; 3] = [0, 1, 2].map(|a| c[a].saturating_sub(r));
            let hi: [usize; 3] = [0, 1, 2].map(|a| (c[a] + r).min(self.dims[a] - 1));
            for k in lo[2]..=hi[2] {
                for j in lo[1]..=hi[1] {
                    for i in lo[0]..=hi[0] {
                        let on_shell = [i, j, k].iter().zip(c).any(|(&q, cq)| q.abs_diff(cq) == r);
                        if !on_shell {
                            continue;
                        }
                        let cell = i + self.dims[0] * (j + self.dims[1] * k);
                        for &t in
                            &self.items[self.start[cell] as usize..self.start[cell + 1] as usize]
                        {
                            let [a, b, cc] = surface[t as usize].map(|n| x[n as usize]);
                            best = best.min(point_triangle_distance(p, &a, &b, &cc));
                        }
                    }
                }
            }
            // Triangles not yet seen lie in cells ≥ r + 1 away: at least
            // r cells from p.
            if best <= r as f64 * self.cell {
                break;
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::{Lattice, VolumeMode};
    use rand::{Rng, SeedableRng};

    #[test]
    fn point_triangle_distance_covers_every_region() {
        let (a, b, c) = (V3::zeros(), V3::new(1.0, 0.0, 0.0), V3::new(0.0, 1.0, 0.0));
        let d = |p: V3| point_triangle_distance(&p, &a, &b, &c);
        assert!((d(V3::new(0.2, 0.2, 0.5)) - 0.5).abs() < 1e-15); // face
        assert!((d(V3::new(-1.0, -1.0, 0.0)) - 2f64.sqrt()).abs() < 1e-15); // vertex a
        assert!((d(V3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-15); // vertex b
        assert!((d(V3::new(0.0, 3.0, 0.0)) - 2.0).abs() < 1e-15); // vertex c
        assert!((d(V3::new(0.5, -1.0, 0.0)) - 1.0).abs() < 1e-15); // edge ab
        assert!((d(V3::new(-2.0, 0.5, 0.0)) - 2.0).abs() < 1e-15); // edge ac
        assert!((d(V3::new(1.0, 1.0, 0.0)) - 0.5f64.sqrt()).abs() < 1e-15); // edge bc
    }

    #[test]
    fn the_grid_search_finds_the_same_distance_as_brute_force() {
        let lat = Lattice::grid([6, 4, 6], [0.1, 0.06, 0.1], VolumeMode::None).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        // A deformed lattice: dented top, bulging sides.
        let x: Vec<V3> = lat
            .rest_m
            .iter()
            .map(|p| {
                let dent = 0.015 * (-((p.x - 0.05).powi(2) + (p.z - 0.05).powi(2)) / 4e-4).exp();
                V3::new(p.x, p.y - dent * p.y / 0.06, p.z)
                    + V3::new(rng.gen::<f64>() - 0.5, rng.gen::<f64>() - 0.5, 0.0) * 0.004
            })
            .collect();
        let mut grid = TriangleGrid::default();
        grid.build(&lat.surface, &x);
        for _ in 0..2000 {
            let p = V3::new(
                rng.gen::<f64>() * 0.16 - 0.03,
                rng.gen::<f64>() * 0.1 - 0.02,
                rng.gen::<f64>() * 0.16 - 0.03,
            );
            let brute = lat
                .surface
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|n| x[n as usize]);
                    point_triangle_distance(&p, &a, &b, &c)
                })
                .fold(f64::INFINITY, f64::min);
            assert_eq!(grid.distance(&p, &lat.surface, &x), brute);
        }
    }
}
