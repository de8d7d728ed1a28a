//! The paper's randomized algorithm, RA (L1746–1755): from random
//! parameters, descend to a local minimum by steepest descent; then add a
//! random amount to one parameter, T_ran = 100 times, and descend again;
//! until the time T_cal is spent. It is Barraquand and Latombe's
//! randomized path planner applied to S: descent, then a random walk out
//! of the basin.
//!
//! Readings where the slide is loose (stated here and in the README), in
//! the unit cube of the intervals:
//! * the "(=10)" added is read as 10 steps of a 1000-step scale, 1 % of
//!   the parameter's interval, with a random sign; the T_ran = 100 kicks
//!   are one random walk (each on a random parameter), not evaluated one
//!   by one;
//! * steepest descent by forward differences (1 % of each interval, the
//!   p evaluations in parallel) and a line search along the negative
//!   gradient over steps of 32, 16, 8, 4, 2 and 1 % of the cube's diagonal
//!   scale (evaluated in parallel); the descent ends when no step lowers S.
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::error::{check_range, Result};
use crate::identify::search::{
    BatchObjective, Budget, Local, Method, Progress, SearchResult, Tracker, UNIT_CANDIDATES,
};
use crate::params::ParamRange;

/// Settings of RA.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RaSettings {
    /// T_ran, kicks per random walk (L1754: 100).
    pub kicks: usize,
    /// Size of one kick as a fraction of the interval (L1754's "10" read
    /// as 1 %).
    pub kick: f64,
    /// Finite-difference step, fraction of the interval.
    pub gradient_step: f64,
}

impl Default for RaSettings {
    fn default() -> Self {
        Self {
            kicks: 100,
            kick: 0.01,
            gradient_step: 0.01,
        }
    }
}

impl RaSettings {
    /// Checks the settings (names the field).
    pub fn validate(&self) -> Result<()> {
        check_range("ra.kicks", self.kicks as f64, 0.0, 1e6)?;
        check_range("ra.kick", self.kick, 0.0, 1.0)?;
        check_range("ra.gradient_step", self.gradient_step, 1e-9, 0.5)?;
        Ok(())
    }
}

const LINE_STEPS: [f64; 6] = [0.32, 0.16, 0.08, 0.04, 0.02, 0.01];

/// Runs RA minimising `f` over `ranges`.
pub fn run<F: Fn(&[f64]) -> f64 + Sync>(
    f: &F,
    ranges: &[ParamRange],
    settings: &RaSettings,
    budget: Budget,
    seed: u64,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<SearchResult> {
    let mut local = Local {
        f,
        unit: UNIT_CANDIDATES,
    };
    run_with(&mut local, ranges, settings, budget, seed, on_progress)
}

/// RA with its probes scored by `objective`.
pub fn run_with(
    objective: &mut dyn BatchObjective,
    ranges: &[ParamRange],
    settings: &RaSettings,
    budget: Budget,
    seed: u64,
    on_progress: &mut dyn FnMut(&Progress),
) -> Result<SearchResult> {
    settings.validate()?;
    let mut tr = Tracker::new(objective, ranges, budget, on_progress)?;
    let mut rng = plant_common::rng::stream(seed, plant_common::rng::RHEOLOGY_SEARCH);
    let dim = tr.dim();
    let mut u: Vec<f64> = (0..dim).map(|_| rng.gen::<f64>()).collect();
    let mut cycle = 0;
    'outer: while let Some(&s0) = tr.evaluate(std::slice::from_ref(&u)).first() {
        let mut s = s0;
        let mut batch_scores = vec![s0];
        // Steepest descent.
        loop {
            let h = settings.gradient_step;
            let probes: Vec<Vec<f64>> = (0..dim)
                .map(|i| {
                    let mut p = u.clone();
                    p[i] = if u[i] + h <= 1.0 { u[i] + h } else { u[i] - h };
                    p
                })
                .collect();
            let fs = tr.evaluate(&probes);
            batch_scores.extend(&fs);
            if fs.len() < dim {
                break 'outer;
            }
            let penalty = s.abs() + 1.0;
            let g: Vec<f64> = (0..dim)
                .map(|i| {
                    let fi = if fs[i].is_finite() {
                        fs[i]
                    } else {
                        s + penalty
                    };
                    (fi - s) / (probes[i][i] - u[i])
                })
                .collect();
            let norm = g.iter().map(|x| x * x).sum::<f64>().sqrt();
            let descending = norm.is_finite() && norm > 0.0 && s.is_finite();
            if !descending {
                break;
            }
            let trials: Vec<Vec<f64>> = LINE_STEPS
                .iter()
                .map(|eta| {
                    u.iter()
                        .zip(&g)
                        .map(|(x, gi)| (x - eta * gi / norm).clamp(0.0, 1.0))
                        .collect()
                })
                .collect();
            let ft = tr.evaluate(&trials);
            batch_scores.extend(&ft);
            let best = ft
                .iter()
                .enumerate()
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map(|(k, &v)| (k, v));
            match best {
                Some((k, v)) if v < s => {
                    u = trials[k].clone();
                    s = v;
                }
                _ => break,
            }
            if ft.len() < LINE_STEPS.len() {
                break 'outer;
            }
        }
        cycle += 1;
        tr.record(cycle, &batch_scores);
        if tr.allowed(1) == 0 {
            break;
        }
        // The random walk out of the basin.
        for _ in 0..settings.kicks {
            let i = rng.gen_range(0..dim);
            let sign = if rng.gen::<bool>() { 1.0 } else { -1.0 };
            u[i] = (u[i] + sign * settings.kick).clamp(0.0, 1.0);
        }
    }
    if tr_history_empty(&tr) {
        tr.record(cycle + 1, &[]);
    }
    tr.finish(Method::Ra)
}

fn tr_history_empty(tr: &Tracker<'_>) -> bool {
    tr.history_len() == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ra_descends_a_bowl_escapes_by_walks_and_is_seeded() {
        let ranges: Vec<ParamRange> = (0..3)
            .map(|i| ParamRange {
                name: format!("p{i}"),
                min: 0.0,
                max: 10.0,
            })
            .collect();
        let f = |g: &[f64]| (g[0] - 3.0).powi(2) + (g[1] - 7.0).powi(2) + (g[2] - 5.0).abs();
        let a = run(
            &f,
            &ranges,
            &RaSettings::default(),
            Budget::evaluations(600),
            3,
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(a.evaluations, 600);
        assert!(a.best_s < 0.05, "best {}", a.best_s);
        let b = run(
            &f,
            &ranges,
            &RaSettings::default(),
            Budget::evaluations(600),
            3,
            &mut |_| {},
        )
        .unwrap();
        assert_eq!(a.best_genes, b.best_genes);
        assert!(a.history.len() > 1, "several descent cycles");
    }
}
