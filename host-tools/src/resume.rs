//! A calibration search stopped by a signal, and the same search resumed.
//!
//! The searches of `rheology calibrate` (GA, RA, uniform) and `push
//! calibrate` (Algorithm 5) are seeded: which candidate they simulate next
//! depends only on their settings, their seed and the scores of the
//! candidates before it. And a candidate's score depends only on its
//! genes (the simulation and the objective are deterministic). So a
//! stopped search keeps what it has as the list of candidates it scored
//! ([`Scored`]: genes and score), and a resumed search starts again from
//! its seed, takes each score it already has from that list instead of
//! simulating the candidate again ([`Scores::score`]), and so retraces the
//! stopped search's path at no cost, then simulates on from where it
//! stopped: its answer is the one the search gives when never stopped.
//!
//! What is left out: a score that is not finite (an unstable lattice, a
//! failed run) is kept as absent and handed back as NaN, which both
//! searches rank as they rank any non-finite score (the rheology search
//! as +∞, Algorithm 5 as −∞; neither scores +∞ as best). A wall-time
//! budget is the caller's to carry over.
use std::collections::HashMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use serde::{Deserialize, Serialize};

use crate::stop::{Stop, Stopped};

/// One candidate a search scored.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scored {
    /// The candidate's genes, in the search's own units (as `params.toml`
    /// or `params.json` names them).
    pub genes: Vec<f64>,
    /// Its score; absent when not finite (the run was unstable or failed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub score: Option<f64>,
}

/// The candidates scored, in the order they came in, and where each one's
/// genes (as bits) are in that list.
type Kept = (HashMap<Vec<u64>, usize>, Vec<Scored>);

/// The scores of a search so far: those of the search it resumes, then
/// each one simulated here, in the order they came in.
pub struct Scores {
    stop: Stop,
    /// Genes (as bits) → index in `scored`.
    index: Mutex<Kept>,
    /// How many of `scored` came from the resumed search.
    resumed: usize,
    /// Candidates answered (a search may ask for one twice), taken from
    /// the resumed search, simulated here.
    answered: AtomicUsize,
    replayed: AtomicUsize,
    simulated: AtomicUsize,
}

/// The genes as exact bits (a map key).
fn key(genes: &[f64]) -> Vec<u64> {
    genes.iter().map(|g| g.to_bits()).collect()
}

impl Scores {
    /// The scores of a search that resumes `resumed` (empty for a fresh
    /// one); `stop` is read before each candidate is simulated.
    pub fn new(stop: Stop, resumed: Vec<Scored>) -> Self {
        let map = resumed
            .iter()
            .enumerate()
            .map(|(k, s)| (key(&s.genes), k))
            .collect();
        Self {
            stop,
            resumed: resumed.len(),
            index: Mutex::new((map, resumed)),
            answered: AtomicUsize::new(0),
            replayed: AtomicUsize::new(0),
            simulated: AtomicUsize::new(0),
        }
    }

    /// The score of `genes`: the one kept if this candidate was scored
    /// before, else `run(genes)` (kept); `None` when a stop is asked (then
    /// nothing is run: the search is to end here).
    pub fn score(&self, genes: &[f64], run: impl FnOnce(&[f64]) -> f64) -> Option<f64> {
        if self.stop.requested().is_some() {
            return None;
        }
        let k = key(genes);
        let kept = {
            let guard = self.index.lock().unwrap_or_else(|e| e.into_inner());
            guard.0.get(&k).map(|&i| (i, guard.1[i].score))
        };
        self.answered.fetch_add(1, Ordering::Relaxed);
        if let Some((i, s)) = kept {
            if i < self.resumed {
                self.replayed.fetch_add(1, Ordering::Relaxed);
            }
            return Some(s.unwrap_or(f64::NAN));
        }
        let s = run(genes);
        self.simulated.fetch_add(1, Ordering::Relaxed);
        let mut guard = self.index.lock().unwrap_or_else(|e| e.into_inner());
        let (map, scored) = &mut *guard;
        map.entry(k).or_insert_with(|| {
            scored.push(Scored {
                genes: genes.to_vec(),
                score: s.is_finite().then_some(s),
            });
            scored.len() - 1
        });
        Some(s)
    }

    /// The scores of `batch`, as [`Self::score`] gives each one, with the
    /// candidates not kept yet scored all at once by `run` (each once,
    /// in the order they first come in `batch`; it must give one score
    /// per gene vector): how a batch sent elsewhere (a Ray cluster) keeps
    /// its scores. `Ok(None)` when a stop is asked before the batch (then
    /// nothing is run); `run`'s error, and then nothing of this batch is
    /// kept.
    pub fn score_batch(
        &self,
        batch: &[Vec<f64>],
        run: impl FnOnce(&[Vec<f64>]) -> Result<Vec<f64>, String>,
    ) -> Result<Option<Vec<f64>>, String> {
        if self.stop.requested().is_some() {
            return Ok(None);
        }
        // Each candidate's score if kept, else the index of its genes
        // among those to run.
        let mut new: HashMap<Vec<u64>, usize> = HashMap::new();
        let mut to_run: Vec<Vec<f64>> = Vec::new();
        let mut replayed = 0;
        let slots: Vec<Result<f64, usize>> = {
            let guard = self.index.lock().unwrap_or_else(|e| e.into_inner());
            batch
                .iter()
                .map(|g| {
                    let k = key(g);
                    if let Some(&i) = guard.0.get(&k) {
                        replayed += usize::from(i < self.resumed);
                        return Ok(guard.1[i].score.unwrap_or(f64::NAN));
                    }
                    Err(*new.entry(k).or_insert_with(|| {
                        to_run.push(g.clone());
                        to_run.len() - 1
                    }))
                })
                .collect()
        };
        let fresh = if to_run.is_empty() {
            Vec::new()
        } else {
            run(&to_run)?
        };
        if fresh.len() != to_run.len() {
            return Err(format!(
                "{} scores came back for {} candidates",
                fresh.len(),
                to_run.len()
            ));
        }
        self.answered.fetch_add(batch.len(), Ordering::Relaxed);
        self.replayed.fetch_add(replayed, Ordering::Relaxed);
        self.simulated.fetch_add(to_run.len(), Ordering::Relaxed);
        let mut guard = self.index.lock().unwrap_or_else(|e| e.into_inner());
        let (map, scored) = &mut *guard;
        for (genes, &s) in to_run.iter().zip(&fresh) {
            map.entry(key(genes)).or_insert_with(|| {
                scored.push(Scored {
                    genes: genes.clone(),
                    score: s.is_finite().then_some(s),
                });
                scored.len() - 1
            });
        }
        Ok(Some(
            slots
                .into_iter()
                .map(|slot| slot.unwrap_or_else(|i| fresh[i]))
                .collect(),
        ))
    }

    /// Candidates answered so far (a candidate the search asks for twice
    /// counts twice; it is simulated once).
    pub fn answered(&self) -> usize {
        self.answered.load(Ordering::Relaxed)
    }

    /// Candidates whose scores were taken from the resumed search.
    pub fn replayed(&self) -> usize {
        self.replayed.load(Ordering::Relaxed)
    }

    /// Candidates simulated here.
    pub fn simulated(&self) -> usize {
        self.simulated.load(Ordering::Relaxed)
    }

    /// The line a resumed search prints: where from, and how many scores
    /// it took from there against how many it simulated now.
    pub fn resumed_line(&self, from: &std::path::Path) -> String {
        format!(
            "resumed from {}: {} candidates' scores taken from it, {} simulated now",
            from.display(),
            self.replayed(),
            self.simulated()
        )
    }

    /// Every candidate scored so far, in the order they came in (a copy).
    pub fn snapshot(&self) -> Vec<Scored> {
        self.index
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .1
            .clone()
    }

    /// Every candidate scored so far, in the order they came in.
    pub fn into_scored(self) -> Vec<Scored> {
        self.index.into_inner().unwrap_or_else(|e| e.into_inner()).1
    }
}

/// The best of `scored` by `better` (the first of equals), if any has a
/// score.
pub fn best_of(scored: &[Scored], better: impl Fn(f64, f64) -> bool) -> Option<&Scored> {
    let mut best: Option<&Scored> = None;
    for s in scored {
        let Some(v) = s.score else { continue };
        if best.and_then(|b| b.score).is_none_or(|b| better(v, b)) {
            best = Some(s);
        }
    }
    best
}

/// FNV-1a, 64 bits, as 16 hex digits: a fingerprint of a file's bytes (or
/// of a search's settings written out).
pub fn fnv1a_hex(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    format!("{h:016x}")
}

/// The end of a search whose result files are all written: `Ok`, or, if a
/// signal came after the search had finished, the stop (exit 130/143/129)
/// saying that every file in `out` is whole.
pub fn finished_or_stopped(stop: &Stop, out: &std::path::Path) -> anyhow::Result<()> {
    match stop.requested() {
        Some(signal) => Err(Stopped {
            signal,
            what: format!(
                "after the search had finished; every result file written to {}",
                out.display()
            ),
        }
        .into()),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stop::StopSignal;

    #[test]
    fn kept_scores_are_not_run_again_and_a_stop_runs_nothing() {
        let stop = Stop::never();
        let kept = vec![
            Scored {
                genes: vec![1.0, 2.0],
                score: Some(3.0),
            },
            Scored {
                genes: vec![0.1, 0.2],
                score: None,
            },
        ];
        let s = Scores::new(stop.clone(), kept);
        assert_eq!(s.score(&[1.0, 2.0], |_| panic!("run again")), Some(3.0));
        assert!(s
            .score(&[0.1, 0.2], |_| panic!("run again"))
            .unwrap()
            .is_nan());
        assert_eq!(s.score(&[5.0, 6.0], |g| g[0] + g[1]), Some(11.0));
        assert_eq!(s.score(&[5.0, 6.0], |_| panic!("run again")), Some(11.0));
        stop.request(StopSignal::Terminate);
        assert_eq!(s.score(&[7.0, 8.0], |_| panic!("run after a stop")), None);
        assert_eq!((s.answered(), s.replayed(), s.simulated()), (4, 2, 1));
        let all = s.into_scored();
        assert_eq!(all.len(), 3);
        assert_eq!(all[2].genes, [5.0, 6.0]);
        let best = best_of(&all, |a, b| a < b).unwrap();
        assert_eq!(best.score, Some(3.0));
        let best = best_of(&all, |a, b| a > b).unwrap();
        assert_eq!(best.score, Some(11.0));
    }

    #[test]
    fn a_batch_runs_only_the_candidates_not_kept_each_once() {
        let stop = Stop::never();
        let kept = vec![Scored {
            genes: vec![1.0],
            score: Some(3.0),
        }];
        let s = Scores::new(stop.clone(), kept);
        let batch = [vec![2.0], vec![1.0], vec![2.0], vec![4.0]];
        let mut ran = Vec::new();
        let got = s
            .score_batch(&batch, |b| {
                ran = b.to_vec();
                Ok(vec![f64::INFINITY, 16.0])
            })
            .unwrap()
            .unwrap();
        assert_eq!(ran, [vec![2.0], vec![4.0]]);
        assert_eq!(got, [f64::INFINITY, 3.0, f64::INFINITY, 16.0]);
        assert_eq!((s.answered(), s.replayed(), s.simulated()), (4, 1, 2));
        // Kept now: an unstable one comes back as NaN, as from `score`.
        let again = s
            .score_batch(&[vec![2.0], vec![4.0]], |_| Err("run again".into()))
            .unwrap()
            .unwrap();
        assert!(again[0].is_nan() && again[1] == 16.0);
        // A run that fails or miscounts keeps nothing of its batch.
        let e = s.score_batch(&[vec![5.0]], |_| Err("lost".into()));
        assert_eq!(e, Err("lost".into()));
        let e = s.score_batch(&[vec![5.0], vec![6.0]], |_| Ok(vec![1.0]));
        assert_eq!(e, Err("1 scores came back for 2 candidates".into()));
        stop.request(StopSignal::Interrupt);
        assert_eq!(
            s.score_batch(&[vec![7.0]], |_| panic!("run after a stop")),
            Ok(None)
        );
        let all = s.into_scored();
        let genes: Vec<_> = all.iter().map(|k| k.genes.clone()).collect();
        assert_eq!(genes, [vec![1.0], vec![2.0], vec![4.0]]);
        assert_eq!(all[1].score, None);
    }
}
