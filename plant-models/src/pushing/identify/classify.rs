//! Material classification by prediction quality (§VIII-E, Table IV): each
//! calibrated model predicts the video; per frame the model with the higher
//! F-score wins, and the global vote adds each model's F-score margin over
//! the frame's mean of all models, so frames where the models differ most
//! weigh most (for two models: the sum of F differences, §VIII-E 2).
use crate::pushing::error::{PushError, Result};
use crate::pushing::evaluate::{score_run, PreparedVideo};
use crate::pushing::forces::MaterialParams;
use crate::pushing::sim::SimConfig;
use serde::{Deserialize, Serialize};

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
    /// Index of the global winner.
    pub winner: usize,
}

impl Classification {
    pub fn winner_label(&self) -> &str {
        &self.labels[self.winner]
    }
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
    } = tally(&f_per_frame);
    Ok(Classification {
        labels: models.iter().map(|m| m.label.clone()).collect(),
        f_per_frame,
        frame_winner,
        frames_won,
        vote,
        winner,
    })
}

/// Per-frame winners and the weighted global vote over several models'
/// per-frame scores (outer index: model; higher is better).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Tally {
    /// Per-frame winner (index of the model); `None` on an exact tie.
    pub frame_winner: Vec<Option<usize>>,
    /// Frames won by each model.
    pub frames_won: Vec<usize>,
    /// Each model's summed margin over the frame's mean of all models.
    pub vote: Vec<f64>,
    /// Index of the global winner (highest vote; the first on a tie).
    pub winner: usize,
}

/// Counts per-frame wins and the weighted vote of §VIII-E for `scores`
/// (outer: model, inner: frame; higher is better — negate a distance).
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
        let best = col.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let winners: Vec<usize> = (0..col.len()).filter(|&k| col[k] == best).collect();
        if winners.len() == 1 {
            frames_won[winners[0]] += 1;
            frame_winner.push(Some(winners[0]));
        } else {
            frame_winner.push(None);
        }
    }
    let winner = (0..models)
        .max_by(|&a, &b| vote[a].total_cmp(&vote[b]).then(b.cmp(&a)))
        .unwrap_or(0);
    Tally {
        frame_winner,
        frames_won,
        vote,
        winner,
    }
}
