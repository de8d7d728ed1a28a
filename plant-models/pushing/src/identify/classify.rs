//! Material classification by prediction quality (§VIII-E, Table IV): each
//! calibrated model predicts the video; per frame the model with the higher
//! F-score wins, and the global vote adds each model's F-score margin over
//! the frame's mean of all models, so frames where the models differ most
//! weigh most (for two models: the sum of F differences, §VIII-E 2).
//!
//! Ties are results, not winners: a frame whose best F-scores agree within
//! [`TIE_TOLERANCE`] is won by nobody, and when the best global votes agree
//! within it there is no global winner (two identical models used to give
//! 0/0 frames won and the first label as the "winner").
use crate::error::{PushError, Result};
use crate::evaluate::{score_run, PreparedVideo};
use crate::forces::MaterialParams;
use crate::sim::SimConfig;
use serde::{Deserialize, Serialize};

/// F-scores and votes closer than this are a tie. F lies in [0, 1] and a
/// vote sums at most a few hundred frame margins, so differences this small
/// are rounding, not a difference between models (estimate: f64 sums of
/// 100 terms in [−1, 1] carry errors of order 1e-14).
pub const TIE_TOLERANCE: f64 = 1e-9;

/// A calibrated model of one material.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaterialModel {
    pub label: String,
    pub params: MaterialParams,
}

/// Outcome for one video.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Classification {
    pub labels: Vec<String>,
    /// F per frame for each model (outer: model).
    pub f_per_frame: Vec<Vec<f64>>,
    /// Per-frame winner (index into `labels`); `None` on an exact tie.
    pub frame_winner: Vec<Option<usize>>,
    /// Frames won by each model.
    pub frames_won: Vec<usize>,
    /// Weighted global vote of each model.
    pub vote: Vec<f64>,
    /// Index of the global winner; `None` when the best votes tie.
    pub winner: Option<usize>,
    /// The models whose votes tie for first place (one entry when there is
    /// a winner).
    pub leaders: Vec<usize>,
}

impl Classification {
    /// The global winner's label, if there is one.
    pub fn winner_label(&self) -> Option<&str> {
        self.winner.map(|k| self.labels[k].as_str())
    }

    /// The verdict in words: the winner's label, or `tie between a and b`.
    pub fn verdict(&self) -> String {
        match self.winner_label() {
            Some(l) => l.to_string(),
            None => {
                let names: Vec<&str> = self
                    .leaders
                    .iter()
                    .map(|&k| self.labels[k].as_str())
                    .collect();
                format!("tie between {}", names.join(" and "))
            }
        }
    }
}

/// The indices whose values lie within [`TIE_TOLERANCE`] of the largest.
fn leaders(values: &[f64]) -> Vec<usize> {
    let best = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (0..values.len())
        .filter(|&k| values[k] >= best - TIE_TOLERANCE)
        .collect()
}

/// Classifies one video among `models`, driving each with `forces_n`.
pub fn classify(
    prepared: &PreparedVideo,
    forces_n: &[f64],
    models: &[MaterialModel],
    sim: &SimConfig,
) -> Result<Classification> {
    if models.len() < 2 {
        return Err(PushError::InvalidParameter {
            name: "models",
            value: models.len() as f64,
            reason: "classification needs at least two material models",
        });
    }
    let mut f_per_frame = Vec::with_capacity(models.len());
    for m in models {
        f_per_frame.push(score_run(prepared, forces_n, &m.params, sim)?.f_per_frame);
    }
    let Tally {
        frame_winner,
        frames_won,
        vote,
        winner,
        leaders,
    } = tally(&f_per_frame);
    Ok(Classification {
        labels: models.iter().map(|m| m.label.clone()).collect(),
        f_per_frame,
        frame_winner,
        frames_won,
        vote,
        winner,
        leaders,
    })
}

/// Per-frame winners and the weighted global vote over several models'
/// per-frame scores (outer index: model; higher is better).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tally {
    /// Per-frame winner (index of the model); `None` on a tie.
    pub frame_winner: Vec<Option<usize>>,
    /// Frames won by each model.
    pub frames_won: Vec<usize>,
    /// Each model's summed margin over the frame's mean of all models.
    pub vote: Vec<f64>,
    /// Index of the global winner; `None` when the best votes tie.
    pub winner: Option<usize>,
    /// The models whose votes tie for first place (one entry when there is
    /// a winner).
    pub leaders: Vec<usize>,
}

impl Tally {
    /// The verdict in words for models called `labels`: the winner's
    /// label, or `tie between a and b`.
    pub fn verdict(&self, labels: &[String]) -> String {
        match self.winner {
            Some(k) => labels[k].clone(),
            None => {
                let names: Vec<&str> = self.leaders.iter().map(|&k| labels[k].as_str()).collect();
                format!("tie between {}", names.join(" and "))
            }
        }
    }
}

/// Counts per-frame wins and the weighted vote of §VIII-E for `scores`
/// (outer: model, inner: frame; higher is better — negate a distance).
/// Scores within [`TIE_TOLERANCE`] of the best are ties.
pub fn tally(scores: &[Vec<f64>]) -> Tally {
    let models = scores.len();
    let frames = scores.iter().map(Vec::len).min().unwrap_or(0);
    let mut frame_winner = Vec::with_capacity(frames);
    let mut frames_won = vec![0usize; models];
    let mut vote = vec![0.0; models];
    for f in 0..frames {
        let col: Vec<f64> = scores.iter().map(|v| v[f]).collect();
        let mean = col.iter().sum::<f64>() / col.len() as f64;
        for (k, v) in col.iter().enumerate() {
            vote[k] += v - mean;
        }
        let winners = leaders(&col);
        if winners.len() == 1 {
            frames_won[winners[0]] += 1;
            frame_winner.push(Some(winners[0]));
        } else {
            frame_winner.push(None);
        }
    }
    let top = leaders(&vote);
    let winner = (top.len() == 1).then(|| top[0]);
    Tally {
        frame_winner,
        frames_won,
        vote,
        winner,
        leaders: top,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::EvalSetup;
    use crate::reference::{record_push, ReferenceConfig, ReferenceMaterial};
    use crate::scenario::{PushScenario, PushSite};

    #[test]
    fn two_identical_models_tie_and_a_different_one_wins() {
        let mat = ReferenceMaterial::SPONGE;
        let scenario = PushScenario::seed(PushSite::MiddleLongSide, mat.scale_px_per_m).unwrap();
        let cfg = ReferenceConfig {
            element_size_px: 30.0,
            ..ReferenceConfig::default()
        };
        let video = record_push("sponge", mat, &scenario, &cfg).unwrap();
        let prep = PreparedVideo::new(
            video,
            &EvalSetup {
                nx: 3,
                ny: 2,
                cell_px: 8.0,
            },
        )
        .unwrap();
        let sponge = MaterialModel {
            label: "a".into(),
            params: MaterialParams::SEED_FIG14_SPONGE,
        };
        let twin = MaterialModel {
            label: "b".into(),
            ..sponge.clone()
        };
        let sim = SimConfig::default();
        let c = classify(&prep, &prep.video.forces_n, &[sponge.clone(), twin], &sim).unwrap();
        assert_eq!(c.winner, None);
        assert_eq!(c.leaders, vec![0, 1]);
        assert_eq!(c.verdict(), "tie between a and b");
        assert_eq!(c.frames_won, vec![0, 0]);
        assert!(c.frame_winner.iter().all(Option::is_none));
        // A model that differs is not a tie with either.
        let other = MaterialModel {
            label: "p".into(),
            params: MaterialParams::SEED_FIG15_PLASTICINE,
        };
        let c = classify(&prep, &prep.video.forces_n, &[sponge, other], &sim).unwrap();
        assert_eq!(c.leaders.len(), 1);
        assert_eq!(c.winner, Some(c.leaders[0]));
        assert_eq!(c.verdict(), c.labels[c.leaders[0]]);
    }
}
