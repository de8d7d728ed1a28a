//! Evolutionary calibration, Algorithm 5 of the seed with Table III's
//! settings: N = α + β + γ + ζ candidates per generation (5 survivors, 5
//! mutants, 5 cross-overs, 5 new log-uniform samples), M = 30 generations,
//! mutation σ falling linearly from σ_max = 1000 to σ_min = 10, special
//! value 0 for the spring constants with probability P(s) = 0.05.
//!
//! Interpretation where the seed is silent (all estimates, stated here):
//! * σ is read in per-mille of each parameter's logarithmic range, i.e. a
//!   mutation multiplies a parameter by exp(N(0, σ/1000 · ln(max/min))):
//!   σ_max explores the whole range, σ_min refines by ~1 % of it. The seed
//!   gives σ without units, and absolute noise of 1000 on a parameter in
//!   [1e-5, 0.9] would not be usable.
//! * cross-over parents come from the population minus its ε = 5 worst.
//! * mutated values are reflected back into the range; a parameter at the
//!   special value 0 stays 0 under mutation.
//!
//! Candidates of a generation are scored in parallel (rayon); the random
//! numbers are drawn sequentially from one seeded ChaCha generator and the
//! scores are collected in candidate order, so results do not depend on the
//! number of threads.
use crate::error::{check_range, PushError, Result};
use crate::forces::MaterialParams;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// Search range of one parameter (Table III).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ParamRange {
    pub min: f64,
    pub max: f64,
    /// Whether the special value 0 may be drawn (spring constants).
    pub allows_zero: bool,
}

/// Table III ranges, in the order of [`MaterialParams::to_array`]:
/// k_d, k_L, k_A, k_φ, max(F), max α, yield, creep.
pub const TABLE_III_RANGES: [ParamRange; 8] = [
    ParamRange {
        min: 1e-5,
        max: 2.0,
        allows_zero: true,
    },
    ParamRange {
        min: 1e-5,
        max: 1e4,
        allows_zero: true,
    },
    ParamRange {
        min: 1e-5,
        max: 1e4,
        allows_zero: true,
    },
    ParamRange {
        min: 1e-5,
        max: 100.0,
        allows_zero: true,
    },
    ParamRange {
        min: 5.0,
        max: 1e5,
        allows_zero: false,
    },
    ParamRange {
        min: 1e-5,
        max: 0.9,
        allows_zero: false,
    },
    ParamRange {
        min: 1e-5,
        max: 1.0,
        allows_zero: false,
    },
    ParamRange {
        min: 1e-5,
        max: 1.0,
        allows_zero: false,
    },
];

/// Settings of Algorithm 5.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct EvolutionSettings {
    /// M, generations (Table III: 30).
    pub generations: usize,
    /// α, survivors (Table III: 5).
    pub survivors: usize,
    /// β, mutants (Table III: 5).
    pub mutants: usize,
    /// γ, cross-overs (Table III: 5).
    pub crossovers: usize,
    /// ζ, new samples (Table III: 5).
    pub newcomers: usize,
    /// σ_max (Table III: 1000).
    pub sigma_max: f64,
    /// σ_min (Table III: 10).
    pub sigma_min: f64,
    /// P(s), probability of the special value 0 (Table III: 0.05).
    pub p_special: f64,
    /// ε, worst candidates excluded from cross-over (estimate: 5).
    pub crossover_exclude_worst: usize,
    pub seed: u64,
}

impl EvolutionSettings {
    /// Table III.
    pub fn table_iii(seed: u64) -> Self {
        Self {
            generations: 30,
            survivors: 5,
            mutants: 5,
            crossovers: 5,
            newcomers: 5,
            sigma_max: 1000.0,
            sigma_min: 10.0,
            p_special: 0.05,
            crossover_exclude_worst: 5,
            seed,
        }
    }

    /// N = α + β + γ + ζ.
    pub fn population(&self) -> usize {
        self.survivors + self.mutants + self.crossovers + self.newcomers
    }

    pub fn validate(&self) -> Result<()> {
        let bad = |name: &'static str, v: usize, reason: &'static str| {
            Err(PushError::InvalidParameter {
                name,
                value: v as f64,
                reason,
            })
        };
        if self.generations == 0 {
            return bad("generations", 0, "needs at least one generation");
        }
        if self.survivors == 0 {
            return bad("survivors", 0, "needs at least one survivor");
        }
        if self.population() < 2 {
            return bad(
                "population",
                self.population(),
                "needs at least two candidates",
            );
        }
        if self.crossovers > 0
            && self
                .population()
                .saturating_sub(self.crossover_exclude_worst)
                < 2
        {
            return bad(
                "crossover_exclude_worst",
                self.crossover_exclude_worst,
                "leaves fewer than two parents",
            );
        }
        check_range("sigma_max", self.sigma_max, 0.0, 1e6)?;
        check_range("sigma_min", self.sigma_min, 0.0, self.sigma_max)?;
        check_range("p_special", self.p_special, 0.0, 1.0)?;
        Ok(())
    }
}

/// Statistics of one evaluated generation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GenerationReport {
    /// 1-based generation number.
    pub generation: usize,
    pub best: f64,
    pub mean: f64,
    pub worst: f64,
    /// σ used to breed the next generation.
    pub sigma: f64,
    pub best_params: MaterialParams,
}

/// Outcome of a calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationResult {
    pub best_params: MaterialParams,
    pub best_score: f64,
    pub history: Vec<GenerationReport>,
    /// Fitness evaluations run (survivors are not re-run).
    pub evaluations: usize,
}

fn check_ranges(ranges: &[ParamRange; 8]) -> Result<()> {
    for r in ranges {
        if !(r.min.is_finite() && r.max.is_finite() && r.min > 0.0 && r.max > r.min) {
            return Err(PushError::InvalidParameter {
                name: "parameter range",
                value: r.min,
                reason: "needs 0 < min < max, finite",
            });
        }
    }
    Ok(())
}

/// A completely new candidate (Algorithm 5 lines 12–18): every parameter
/// log-uniform in its range, spring constants 0 with probability `p_special`.
pub fn new_candidate(rng: &mut ChaCha8Rng, ranges: &[ParamRange; 8], p_special: f64) -> [f64; 8] {
    core::array::from_fn(|k| log_uniform(rng, &ranges[k], p_special))
}

fn log_uniform(rng: &mut ChaCha8Rng, r: &ParamRange, p_special: f64) -> f64 {
    if r.allows_zero && rng.gen::<f64>() < p_special {
        return 0.0;
    }
    let n: f64 = rng.gen(); // Algorithm 5 lines 13-17
    let (lo, hi) = (r.min.ln(), r.max.ln());
    (n * (hi - lo) + lo).exp()
}

fn mutate(rng: &mut ChaCha8Rng, value: f64, r: &ParamRange, sigma: f64, p_special: f64) -> f64 {
    if value == 0.0 {
        return 0.0;
    }
    if r.allows_zero && rng.gen::<f64>() < p_special {
        return 0.0;
    }
    let (lo, hi) = (r.min.ln(), r.max.ln());
    let z: f64 = StandardNormal.sample(rng);
    let mut x = value.ln() + z * sigma / 1000.0 * (hi - lo);
    // Reflect into [lo, hi] (a few bounces, then clamp).
    for _ in 0..4 {
        if x < lo {
            x = 2.0 * lo - x;
        } else if x > hi {
            x = 2.0 * hi - x;
        }
    }
    x.clamp(lo, hi).exp()
}

/// Runs Algorithm 5, maximising `fitness` (μ(F) in the seed). Candidates
/// whose fitness is NaN are ranked last. `on_generation` is called after
/// each generation (progress bars, logs).
pub fn calibrate<F>(
    settings: &EvolutionSettings,
    ranges: &[ParamRange; 8],
    fitness: F,
    on_generation: impl FnMut(&GenerationReport),
) -> Result<CalibrationResult>
where
    F: Fn(&MaterialParams) -> f64 + Sync,
{
    calibrate_until(settings, ranges, |p| Some(fitness(p)), on_generation)?.ok_or(
        PushError::InvalidParameter {
            name: "generations",
            value: 0.0,
            reason: "the search stopped without being asked to",
        },
    )
}

/// Scores the candidates of `pop` without a score yet with one call of
/// `batch` (their genes in population order; it must answer one score
/// each, in that order), NaN ranking as −∞; how many, or `None` if
/// `batch` refused the batch (then no score is set).
fn score_new<B>(
    pop: &[[f64; 8]],
    scores: &mut [Option<f64>],
    batch: &mut B,
) -> Result<Option<usize>>
where
    B: FnMut(&[Vec<f64>]) -> Option<Vec<f64>>,
{
    let todo: Vec<usize> = (0..pop.len()).filter(|&i| scores[i].is_none()).collect();
    let genes: Vec<Vec<f64>> = todo.iter().map(|&i| pop[i].to_vec()).collect();
    let Some(fresh) = batch(&genes) else {
        return Ok(None);
    };
    if fresh.len() != todo.len() {
        return Err(PushError::InvalidParameter {
            name: "batch scores",
            value: fresh.len() as f64,
            reason: "a batch scorer must answer one score per candidate",
        });
    }
    for (&i, s) in todo.iter().zip(fresh) {
        scores[i] = Some(if s.is_nan() { f64::NEG_INFINITY } else { s });
    }
    Ok(Some(todo.len()))
}

/// [`calibrate`] with a fitness that may refuse to score (`None`: the
/// caller asks the search to stop, e.g. on a signal). The search then
/// ends after the generation it was scoring, with `Ok(None)`; what was
/// scored is the caller's to keep (the draws depend only on the seed and
/// the scores, so a search given the same scores retraces this one).
/// Each generation's new candidates are scored in parallel (rayon), as
/// [`calibrate_batches`]' batch.
pub fn calibrate_until<F>(
    settings: &EvolutionSettings,
    ranges: &[ParamRange; 8],
    fitness: F,
    on_generation: impl FnMut(&GenerationReport),
) -> Result<Option<CalibrationResult>>
where
    F: Fn(&MaterialParams) -> Option<f64> + Sync,
{
    let local = |genes: &[Vec<f64>]| -> Option<Vec<f64>> {
        let fresh: Vec<Option<f64>> = genes
            .par_iter()
            .map(|g| {
                let a: [f64; 8] = core::array::from_fn(|k| g[k]);
                fitness(&MaterialParams::from_array(a))
            })
            .collect();
        fresh.into_iter().collect()
    };
    calibrate_batches(settings, ranges, local, on_generation)
}

/// [`calibrate_until`] with each generation's candidates not scored yet
/// given to `batch` at once, as gene vectors in the order of
/// [`MaterialParams::to_array`] (the work units of a generation), which
/// answers their scores in the same order, or `None` to stop the search.
/// Every random draw and the selection stay here, in one sequence from
/// the seed, so where `batch` scores them (threads, a Ray cluster) cannot
/// change the result, only the scores it answers can.
pub fn calibrate_batches<B>(
    settings: &EvolutionSettings,
    ranges: &[ParamRange; 8],
    mut batch: B,
    mut on_generation: impl FnMut(&GenerationReport),
) -> Result<Option<CalibrationResult>>
where
    B: FnMut(&[Vec<f64>]) -> Option<Vec<f64>>,
{
    settings.validate()?;
    check_ranges(ranges)?;
    let mut rng = ChaCha8Rng::seed_from_u64(settings.seed);
    let n = settings.population();
    let mut pop: Vec<[f64; 8]> = (0..n)
        .map(|_| new_candidate(&mut rng, ranges, settings.p_special))
        .collect();
    let mut scores: Vec<Option<f64>> = vec![None; n];
    let d_sigma = (settings.sigma_max - settings.sigma_min) / settings.generations as f64;
    let mut sigma = settings.sigma_max;
    let mut history = Vec::with_capacity(settings.generations);
    let mut evaluations = 0;
    let mut best: Option<([f64; 8], f64)> = None;
    for g in 1..=settings.generations {
        // Line 6: run the simulations not run yet, in parallel.
        let Some(fresh) = score_new(&pop, &mut scores, &mut batch)? else {
            return Ok(None);
        };
        evaluations += fresh;
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| {
            scores[b]
                .unwrap_or(f64::NEG_INFINITY)
                .total_cmp(&scores[a].unwrap_or(f64::NEG_INFINITY))
                .then(a.cmp(&b))
        });
        let vals: Vec<f64> = order
            .iter()
            .map(|&i| scores[i].unwrap_or(f64::NEG_INFINITY))
            .collect();
        let gen_best = vals[0];
        if best.as_ref().is_none_or(|b| gen_best > b.1) {
            best = Some((pop[order[0]], gen_best));
        }
        sigma -= d_sigma; // line 7
        let finite: Vec<f64> = vals.iter().copied().filter(|v| v.is_finite()).collect();
        let report = GenerationReport {
            generation: g,
            best: gen_best,
            mean: if finite.is_empty() {
                f64::NAN
            } else {
                finite.iter().sum::<f64>() / finite.len() as f64
            },
            worst: *vals.last().unwrap_or(&f64::NAN),
            sigma,
            best_params: MaterialParams::from_array(pop[order[0]]),
        };
        on_generation(&report);
        history.push(report);
        if g == settings.generations {
            break;
        }
        // Breed the next generation.
        let elite: Vec<usize> = order[..settings.survivors.min(n)].to_vec();
        let mut next: Vec<[f64; 8]> = Vec::with_capacity(n);
        let mut next_scores: Vec<Option<f64>> = Vec::with_capacity(n);
        for &i in &elite {
            next.push(pop[i]);
            next_scores.push(scores[i]);
        }
        for m in 0..settings.mutants {
            let parent = pop[elite[m % elite.len()]];
            next.push(core::array::from_fn(|k| {
                mutate(&mut rng, parent[k], &ranges[k], sigma, settings.p_special)
            }));
            next_scores.push(None);
        }
        let pool: Vec<usize> = order[..n - settings.crossover_exclude_worst.min(n - 2)].to_vec();
        for _ in 0..settings.crossovers {
            let a = pool[rng.gen_range(0..pool.len())];
            let mut b = pool[rng.gen_range(0..pool.len() - 1)];
            if b == a {
                b = pool[pool.len() - 1];
            }
            let (pa, pb) = (pop[a], pop[b]);
            next.push(core::array::from_fn(|k| {
                if rng.gen::<bool>() {
                    pa[k]
                } else {
                    pb[k]
                }
            }));
            next_scores.push(None);
        }
        for _ in 0..settings.newcomers {
            next.push(new_candidate(&mut rng, ranges, settings.p_special));
            next_scores.push(None);
        }
        pop = next;
        scores = next_scores;
    }
    let (p, s) = best.ok_or(PushError::InvalidParameter {
        name: "generations",
        value: 0.0,
        reason: "nothing evaluated",
    })?;
    Ok(Some(CalibrationResult {
        best_params: MaterialParams::from_array(p),
        best_score: s,
        history,
        evaluations,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cheap fitness: closeness of the parameters' logarithms to a
    /// point inside the ranges.
    fn bowl(p: &MaterialParams) -> f64 {
        -p.to_array()
            .iter()
            .map(|x| {
                if *x == 0.0 {
                    4.0
                } else {
                    (x.ln() + 2.0).powi(2)
                }
            })
            .sum::<f64>()
    }

    fn small(seed: u64) -> EvolutionSettings {
        let mut s = EvolutionSettings::table_iii(seed);
        s.generations = 6;
        s
    }

    #[test]
    fn a_batch_scorer_retraces_the_threaded_search_and_sees_each_generations_new_candidates() {
        let s = small(3);
        let local = calibrate_until(&s, &TABLE_III_RANGES, |p| Some(bowl(p)), |_| {})
            .unwrap()
            .unwrap();
        let mut sizes = Vec::new();
        let batched = calibrate_batches(
            &s,
            &TABLE_III_RANGES,
            |genes: &[Vec<f64>]| {
                sizes.push(genes.len());
                // Scored in reverse, one by one: the order of the work
                // cannot matter, only the answers in batch order.
                let mut out: Vec<f64> = genes
                    .iter()
                    .rev()
                    .map(|g| bowl(&MaterialParams::from_array(core::array::from_fn(|k| g[k]))))
                    .collect();
                out.reverse();
                Some(out)
            },
            |_| {},
        )
        .unwrap()
        .unwrap();
        assert_eq!(batched, local);
        // All of the first generation, then every candidate but the survivors.
        let n = s.population();
        assert_eq!(sizes[0], n);
        assert!(
            sizes[1..].iter().all(|&k| k == n - s.survivors),
            "{sizes:?}"
        );
        assert_eq!(local.evaluations, sizes.iter().sum::<usize>());
    }

    #[test]
    fn a_batch_scorer_that_stops_or_answers_the_wrong_count_ends_the_search() {
        let s = small(3);
        let stopped = calibrate_batches(&s, &TABLE_III_RANGES, |_: &[Vec<f64>]| None, |_| {});
        assert_eq!(stopped.unwrap(), None);
        let e = calibrate_batches(
            &s,
            &TABLE_III_RANGES,
            |g: &[Vec<f64>]| Some(vec![0.0; g.len() - 1]),
            |_| {},
        )
        .unwrap_err();
        assert!(format!("{e}").contains("one score per candidate"), "{e}");
    }
}
