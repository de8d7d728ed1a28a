//! Feature matching by correlation and relaxation with the strength of
//! matches, with or without Zhang's direction-consistency constraint
//! (§II-B, Eq. 4–7).
//!
//! 1. **Initial matching.** Every feature `p` of the initial volume (IV)
//!    is paired with the features `p'` of the deformed volume (FV) inside
//!    its search cube (17 × 17 × 3 voxels, L571) whose zero-mean
//!    normalised correlation `cs` over 9 × 9 × 3 cubes (L571) reaches
//!    `min_correlation`.
//! 2. **Strength of a match (Eq. 4).**
//!    `SM(p, p') = cs(p, p') + α Σ_k cs(n_k, n'_k) w_k` over the IV
//!    features `n_k` within `neighbourhood_mm` of `p`, each with its best
//!    candidate `n'_k` within `neighbourhood_mm` of `p'`; `w_k = exp(−J_k)`
//!    (Eq. 5). `diff` is the relative distance difference
//!    `r = |d(p, n) − d(p', n')| / mean` over its limit `ε_r` (neighbours
//!    with `r ≥ ε_r` give nothing), after Zhang, Deriche, Faugeras & Luong
//!    (1995), whose relaxation the seed's refs. [13], [14] follow, with
//!    their `ε_r = 0.3`. The paper gives no α; we use `α = 1/|N(p)|`, so the
//!    support is a mean in [0, 1] like `cs`.
//! 3. **Direction of deformation fields (Eq. 6–7).** A displacement is
//!    quantised to one of 26 directions (each component's sign where it
//!    exceeds tan 22.5° of the largest, so the 8 planar states are 45°
//!    sectors as in Fig. 1); displacements under half a voxel have no
//!    direction. `A` is 0 for the same state, 1 below 90°, 2 at 90° (or no
//!    direction), 3 above; `O = A/3` (Eq. 7).
//! 4. **Relaxation.** Each round computes SM for the remaining candidates,
//!    keeps the pairs that are each other's best, fixes the strongest 60 %
//!    of them (Zhang et al.'s "some-winners-take-all") and deletes the
//!    candidates that conflict with a fixed pair; rounds repeat until no
//!    pair is added. The fixed pairs are the potential match set (PMS).
//!
//! **How J uses the direction.** Eq. 5 as printed sets `J = diff` when
//! `O = 0` and `J = O · diff` otherwise. Since `O ≤ 1`, that gives a
//! neighbour moving at an acute angle *more* weight than one moving the
//! same way, and an opposite one the same weight as a parallel one —
//! the reverse of the text's intent ("we expect to see more potential
//! matches … whose DODF are consistent"). [`Consistency::Direction`] reads
//! it as a penalty that grows with the angle class, `J = diff + A`
//! (one e-fold of weight per class); [`Consistency::DirectionAsPrinted`]
//! implements the printed form; [`Consistency::StrengthOnly`] is the
//! relaxation without the constraint (`J = diff`), the baseline of the
//! issue's comparison.
//!
//! Left out: the paper's dynamic search cube (its growth rule is not
//! given; the initial 17 × 17 × 3 size covers the motion of our twins).
use super::harris::FeaturePoint;
use crate::error::{check_positive, check_range, Result};
use crate::field::model::volume::Volume;
use std::collections::HashMap;

/// How the neighbours' support is weighted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Consistency {
    /// `J = diff`: strength of matches alone (no direction constraint).
    StrengthOnly,
    /// `J = diff + A`: the direction constraint as a growing penalty.
    Direction,
    /// Eq. 5 as printed: `J = diff` if `O = 0`, else `O · diff`.
    DirectionAsPrinted,
}

impl Consistency {
    /// All three, for comparisons.
    pub const ALL: [Consistency; 3] = [
        Consistency::StrengthOnly,
        Consistency::Direction,
        Consistency::DirectionAsPrinted,
    ];

    /// Short name (CLI, CSV, JSON).
    pub fn name(&self) -> &'static str {
        match self {
            Consistency::StrengthOnly => "strength",
            Consistency::Direction => "direction",
            Consistency::DirectionAsPrinted => "as-printed",
        }
    }

    fn j(&self, diff: f64, a: u8) -> f64 {
        match self {
            Consistency::StrengthOnly => diff,
            Consistency::Direction => diff + f64::from(a),
            Consistency::DirectionAsPrinted => {
                let o = f64::from(a) / 3.0;
                if a == 0 {
                    diff
                } else {
                    o * diff
                }
            }
        }
    }
}

/// Parameters of matching.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchParams {
    /// Half size of the correlation cube (voxels): 9 × 9 × 3 → 4, 4, 1 (L571).
    pub match_half_vox: [usize; 3],
    /// Half size of the search cube (voxels): 17 × 17 × 3 → 8, 8, 1 (L571).
    pub search_half_vox: [usize; 3],
    /// Smallest correlation of a candidate (estimate: low enough that most
    /// points keep more than one candidate under the twins' noise, so the
    /// relaxation has something to decide; Zhang et al. 1995 used 0.8 on
    /// photographs).
    pub min_correlation: f64,
    /// Radius of the neighbourhood N(p) (mm, estimate: about 30
    /// neighbours at the paper's 1000 points in a calf).
    pub neighbourhood_mm: f64,
    /// ε_r of the relative distance difference (Zhang et al. 1995: 0.3).
    pub relative_distance_limit: f64,
    /// Fraction of the mutual best pairs fixed per round (Zhang et al.
    /// 1995: 60 %).
    pub fix_fraction: f64,
    /// Displacements shorter than this (mm) have no direction (half an
    /// in-plane voxel of the paper's volumes).
    pub min_motion_mm: f64,
    /// Smallest strength SM of an accepted match: mutual best pairs below
    /// it are not fixed, so matches without support from consistent
    /// neighbours are rejected (estimate; the paper gives none; the README
    /// shows the comparison at 0.9, 1.1 and 1.3).
    pub min_strength: f64,
    /// Most relaxation rounds.
    pub max_rounds: usize,
    /// How neighbours are weighted.
    pub consistency: Consistency,
}

impl Default for MatchParams {
    fn default() -> Self {
        MatchParams {
            match_half_vox: [4, 4, 1],
            search_half_vox: [8, 8, 1],
            min_correlation: 0.5,
            neighbourhood_mm: 15.0,
            relative_distance_limit: 0.3,
            fix_fraction: 0.6,
            min_motion_mm: 0.4,
            min_strength: 1.1,
            max_rounds: 50,
            consistency: Consistency::Direction,
        }
    }
}

impl MatchParams {
    fn validate(&self) -> Result<()> {
        check_range(
            "min_correlation",
            self.min_correlation,
            -1.0,
            1.0,
            "must be -1 to 1",
        )?;
        check_positive("neighbourhood_mm", self.neighbourhood_mm)?;
        check_positive("relative_distance_limit", self.relative_distance_limit)?;
        check_range(
            "fix_fraction",
            self.fix_fraction,
            1e-6,
            1.0,
            "must be in (0, 1]",
        )?;
        check_range(
            "min_strength",
            self.min_strength,
            0.0,
            10.0,
            "must be 0 to 10",
        )?;
        check_range(
            "min_motion_mm",
            self.min_motion_mm,
            0.0,
            1e3,
            "must be 0 to 1000 mm",
        )?;
        Ok(())
    }
}

/// A match between IV feature `initial` and FV feature `deformed`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    /// Index into the IV features.
    pub initial: usize,
    /// Index into the FV features.
    pub deformed: usize,
    /// Correlation cs.
    pub correlation: f64,
    /// Strength SM when it was fixed.
    pub strength: f64,
}

/// The zero-mean, unit-norm cube around each feature (empty where the cube
/// leaves the volume or is flat).
fn cubes(vol: &Volume, pts: &[FeaturePoint], half: [usize; 3]) -> Vec<Vec<f32>> {
    let dims = vol.dims();
    pts.iter()
        .map(|f| {
            let v = f.voxel;
            if (0..3).any(|a| v[a] < half[a] || v[a] + half[a] >= dims[a]) {
                return Vec::new();
            }
            let mut c =
                Vec::with_capacity((2 * half[0] + 1) * (2 * half[1] + 1) * (2 * half[2] + 1));
            for z in v[2] - half[2]..=v[2] + half[2] {
                for y in v[1] - half[1]..=v[1] + half[1] {
                    for x in v[0] - half[0]..=v[0] + half[0] {
                        c.push(vol.at(x, y, z));
                    }
                }
            }
            let mean = c.iter().map(|&x| f64::from(x)).sum::<f64>() / c.len() as f64;
            let norm = c
                .iter()
                .map(|&x| (f64::from(x) - mean).powi(2))
                .sum::<f64>()
                .sqrt();
            if norm <= 1e-9 {
                return Vec::new();
            }
            c.iter()
                .map(|&x| ((f64::from(x) - mean) / norm) as f32)
                .collect()
        })
        .collect()
}

/// Candidates of every IV feature: `(FV index, correlation)`.
pub fn candidates(
    iv: &Volume,
    fv: &Volume,
    pts_iv: &[FeaturePoint],
    pts_fv: &[FeaturePoint],
    params: &MatchParams,
) -> Result<Vec<Vec<(usize, f64)>>> {
    params.validate()?;
    let ci = cubes(iv, pts_iv, params.match_half_vox);
    let cf = cubes(fv, pts_fv, params.match_half_vox);
    let s = params.search_half_vox;
    let cell = s.map(|h| (2 * h + 1) as i64);
    let key = |v: [usize; 3]| -> [i64; 3] { std::array::from_fn(|a| v[a] as i64 / cell[a]) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (j, f) in pts_fv.iter().enumerate() {
        grid.entry(key(f.voxel)).or_default().push(j);
    }
    Ok(pts_iv
        .iter()
        .enumerate()
        .map(|(i, f)| {
            let mut out = Vec::new();
            if ci[i].is_empty() {
                return out;
            }
            let k = key(f.voxel);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let Some(list) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                            continue;
                        };
                        for &j in list {
                            let g = pts_fv[j].voxel;
                            if (0..3).any(|a| g[a].abs_diff(f.voxel[a]) > s[a]) || cf[j].is_empty()
                            {
                                continue;
                            }
                            let cs: f64 = ci[i]
                                .iter()
                                .zip(&cf[j])
                                .map(|(a, b)| f64::from(*a) * f64::from(*b))
                                .sum();
                            if cs >= params.min_correlation {
                                out.push((j, cs));
                            }
                        }
                    }
                }
            }
            out.sort_by_key(|&(j, _)| j);
            out
        })
        .collect())
}

/// The 26-direction state of a displacement (Eq. 6): each component's
/// sign where it exceeds tan 22.5° of the largest; `[0; 3]` for no motion.
pub fn direction_state(d: [f64; 3], min_motion_mm: f64) -> [i8; 3] {
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if len < min_motion_mm || len == 0.0 {
        return [0; 3];
    }
    let big = d.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let t = (22.5f64).to_radians().tan() * big;
    d.map(|v| if v.abs() >= t { v.signum() as i8 } else { 0 })
}

/// The angle class A of Eq. 7 between two direction states: 0 same, 1
/// below 90°, 2 at 90° (or either without direction), 3 above.
pub fn angle_class(a: [i8; 3], b: [i8; 3]) -> u8 {
    if a == b {
        return 0;
    }
    if a == [0; 3] || b == [0; 3] {
        return 2;
    }
    let dot: i32 = (0..3).map(|k| i32::from(a[k]) * i32::from(b[k])).sum();
    match dot.signum() {
        1 => 1,
        0 => 2,
        _ => 3,
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// IV neighbours of every IV feature within `radius`.
fn neighbours(pts: &[FeaturePoint], radius: f64) -> Vec<Vec<usize>> {
    let key = |p: [f64; 3]| -> [i64; 3] { p.map(|c| (c / radius).floor() as i64) };
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, f) in pts.iter().enumerate() {
        grid.entry(key(f.position_mm)).or_default().push(i);
    }
    pts.iter()
        .enumerate()
        .map(|(i, f)| {
            let k = key(f.position_mm);
            let mut out = Vec::new();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        if let Some(l) = grid.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                            out.extend(l.iter().copied().filter(|&j| {
                                j != i && dist(pts[j].position_mm, f.position_mm) < radius
                            }));
                        }
                    }
                }
            }
            out.sort_unstable();
            out
        })
        .collect()
}

/// Relaxation over the candidates: the potential match set.
pub fn relax(
    pts_iv: &[FeaturePoint],
    pts_fv: &[FeaturePoint],
    initial_candidates: &[Vec<(usize, f64)>],
    params: &MatchParams,
) -> Result<Vec<Match>> {
    params.validate()?;
    let nb = neighbours(pts_iv, params.neighbourhood_mm);
    let mut cand: Vec<Vec<(usize, f64)>> = initial_candidates.to_vec();
    let mut fixed: Vec<Option<Match>> = vec![None; pts_iv.len()];
    let mut fv_taken = vec![false; pts_fv.len()];
    let eps = params.relative_distance_limit;
    for _round in 0..params.max_rounds {
        // Strength of every remaining candidate.
        let strength = |i: usize, j: usize, cs: f64| -> f64 {
            let p = pts_iv[i].position_mm;
            let q = pts_fv[j].position_mm;
            let state = direction_state(sub(q, p), params.min_motion_mm);
            let mut support = 0.0;
            for &k in &nb[i] {
                let pk = pts_iv[k].position_mm;
                let dp = dist(p, pk);
                let mut best: f64 = 0.0;
                for &(l, csl) in &cand[k] {
                    if l == j {
                        continue;
                    }
                    let ql = pts_fv[l].position_mm;
                    let dq = dist(q, ql);
                    if dq >= params.neighbourhood_mm {
                        continue;
                    }
                    let r = (dp - dq).abs() / (0.5 * (dp + dq)).max(1e-12);
                    if r >= eps {
                        continue;
                    }
                    let a = angle_class(state, direction_state(sub(ql, pk), params.min_motion_mm));
                    let w = (-params.consistency.j(r / eps, a)).exp();
                    best = best.max(csl * w);
                }
                support += best;
            }
            cs + support / nb[i].len().max(1) as f64
        };
        let sm: Vec<Vec<(usize, f64, f64)>> = cand
            .iter()
            .enumerate()
            .map(|(i, c)| {
                c.iter()
                    .map(|&(j, cs)| (j, cs, strength(i, j, cs)))
                    .collect()
            })
            .collect();
        // Each IV feature's best, and each FV feature's best IV feature.
        let mut best_of_fv: HashMap<usize, (usize, f64)> = HashMap::new();
        for (i, c) in sm.iter().enumerate() {
            for &(j, _, s) in c {
                let e = best_of_fv.entry(j).or_insert((i, s));
                if s > e.1 || (s == e.1 && i < e.0) {
                    *e = (i, s);
                }
            }
        }
        let mut mutual: Vec<Match> = Vec::new();
        for (i, c) in sm.iter().enumerate() {
            if fixed[i].is_some() {
                continue;
            }
            let best = c
                .iter()
                .copied()
                .max_by(|a, b| a.2.total_cmp(&b.2).then(b.0.cmp(&a.0)));
            if let Some((j, cs, s)) = best {
                if best_of_fv.get(&j).map(|e| e.0) == Some(i) {
                    mutual.push(Match {
                        initial: i,
                        deformed: j,
                        correlation: cs,
                        strength: s,
                    });
                }
            }
        }
        mutual.retain(|m| m.strength >= params.min_strength);
        if mutual.is_empty() {
            break;
        }
        mutual.sort_by(|a, b| {
            b.strength
                .total_cmp(&a.strength)
                .then(a.initial.cmp(&b.initial))
        });
        let take = ((params.fix_fraction * mutual.len() as f64).ceil() as usize).max(1);
        for m in mutual.into_iter().take(take) {
            fixed[m.initial] = Some(m);
            fv_taken[m.deformed] = true;
        }
        for (i, c) in cand.iter_mut().enumerate() {
            match fixed[i] {
                Some(m) => c.retain(|&(j, _)| j == m.deformed),
                None => c.retain(|&(j, _)| !fv_taken[j]),
            }
        }
    }
    Ok(fixed.into_iter().flatten().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_quantise_to_26_states_with_45_degree_sectors() {
        assert_eq!(direction_state([1.0, 0.0, 0.0], 0.1), [1, 0, 0]);
        assert_eq!(direction_state([1.0, 0.5, 0.0], 0.1), [1, 1, 0]);
        assert_eq!(direction_state([1.0, 0.3, 0.0], 0.1), [1, 0, 0]);
        assert_eq!(direction_state([-1.0, -1.0, 1.0], 0.1), [-1, -1, 1]);
        assert_eq!(direction_state([0.01, 0.0, 0.0], 0.1), [0, 0, 0]);
        let mut states = std::collections::HashSet::new();
        for k in 0..20000 {
            let t = k as f64 * 0.618;
            let d = [t.sin(), (1.7 * t).cos(), (0.3 * t).sin() * 1.3];
            states.insert(direction_state(d, 0.0));
        }
        states.remove(&[0, 0, 0]);
        assert_eq!(states.len(), 26);
    }

    #[test]
    fn angle_classes_follow_eq_7() {
        assert_eq!(angle_class([1, 0, 0], [1, 0, 0]), 0);
        assert_eq!(angle_class([1, 0, 0], [1, 1, 0]), 1);
        assert_eq!(angle_class([1, 0, 0], [0, 1, 0]), 2);
        assert_eq!(angle_class([1, 0, 0], [-1, 1, 0]), 3);
        assert_eq!(angle_class([0, 0, 0], [0, 1, 0]), 2);
    }

    #[test]
    fn the_printed_eq_5_rewards_acute_neighbours_over_parallel_ones() {
        // What the module docs say: as printed, J(acute) < J(parallel) and
        // J(opposite) = J(parallel); the penalty reading orders them.
        let diff = 0.5;
        let p = Consistency::DirectionAsPrinted;
        assert!(p.j(diff, 1) < p.j(diff, 0));
        assert_eq!(p.j(diff, 3), p.j(diff, 0));
        let d = Consistency::Direction;
        assert!(
            d.j(diff, 0) < d.j(diff, 1)
                && d.j(diff, 1) < d.j(diff, 2)
                && d.j(diff, 2) < d.j(diff, 3)
        );
        assert_eq!(Consistency::StrengthOnly.j(diff, 3), diff);
    }

    fn fp(p: [f64; 3]) -> FeaturePoint {
        FeaturePoint {
            position_mm: p,
            voxel: p.map(|c| c.round().max(0.0) as usize),
            response: 1.0,
        }
    }

    #[test]
    fn relaxation_prefers_the_candidate_consistent_with_its_neighbours() {
        // A grid of IV points all moving by (+2, 0, 0); point 0 has two
        // equally correlated candidates: the consistent one and a decoy
        // moved by (−2, +1, 0) whose distances to the neighbours' matches
        // are within ε_r but whose direction is opposite.
        let mut iv = Vec::new();
        for j in 0..4 {
            for i in 0..4 {
                iv.push(fp([10.0 + 3.0 * i as f64, 10.0 + 3.0 * j as f64, 5.0]));
            }
        }
        let mut fv: Vec<FeaturePoint> = iv
            .iter()
            .map(|f| fp([f.position_mm[0] + 2.0, f.position_mm[1], 5.0]))
            .collect();
        let target = 5; // an inner point
        let decoy = fv.len();
        let p = iv[target].position_mm;
        fv.push(fp([p[0] - 0.8, p[1] + 0.6, 5.0]));
        let mut cand: Vec<Vec<(usize, f64)>> = (0..iv.len()).map(|i| vec![(i, 0.9)]).collect();
        cand[target] = vec![(target, 0.9), (decoy, 0.9)];
        let params = MatchParams {
            neighbourhood_mm: 7.0,
            relative_distance_limit: 0.6,
            min_strength: 0.0,
            ..MatchParams::default()
        };
        let m = relax(&iv, &fv, &cand, &params).unwrap();
        let chosen = m.iter().find(|m| m.initial == target).unwrap().deformed;
        assert_eq!(chosen, target, "direction constraint chose the decoy");
        assert_eq!(m.len(), iv.len());
    }
}
