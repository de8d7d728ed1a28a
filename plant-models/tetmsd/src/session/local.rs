//! Both users on one local model, no network (`softjoint tetmsd
//! simulate`): each tick both styluses grip or let go on the one shared
//! state, feel the held node's reaction, and the model steps once with
//! both holds. What it measures is the model alone: the forces the users
//! feel, the shape where they push hardest, and how many deformation
//! updates per second of computation this machine manages (the seed's
//! 1000 Hz at level 3 to 50 Hz at 729 nodes).
use super::pair::{Haptic, PairConfig};
use super::report::{arr, ForceRow};
use crate::error::Result;
use crate::model::probe::NodeReaction;
use crate::model::voigt::{Hold, State, VoigtModel, TICK_S};
use crate::model::V3;
use std::time::Instant;

/// What a local run produces.
#[derive(Clone, Debug)]
pub struct LocalRun {
    /// Ticks run.
    pub ticks: u64,
    /// Each user's force trace (every `trace_every_ticks`).
    pub traces: [Vec<ForceRow>; 2],
    /// Each user's largest felt force (N).
    pub max_force_n: [f64; 2],
    /// Each user's ticks in contact.
    pub contact_ticks: [u64; 2],
    /// The shape (m) at the tick where the two users pushed hardest
    /// (largest sum of felt forces).
    pub peak_x_m: Vec<[f64; 3]>,
    /// The state after the last tick.
    pub final_state: State,
    /// Time spent in the model's steps (s of wall clock).
    pub compute_s: f64,
}

impl LocalRun {
    /// Deformation updates per second of computation.
    pub fn deformation_rate_hz(&self) -> f64 {
        self.ticks as f64 / self.compute_s.max(1e-12)
    }
}

/// Both users of `cfg` on `model` (built from `cfg.session`) for
/// `cfg.duration_ticks` ticks.
pub fn simulate(model: &VoigtModel, cfg: &PairConfig) -> Result<LocalRun> {
    let mut haptics = [Haptic::new(model), Haptic::new(model)];
    let mut state = model.rest_state();
    let mut scratch = Vec::new();
    let every = cfg.trace_every_ticks;
    let mut traces: [Vec<ForceRow>; 2] = [Vec::new(), Vec::new()];
    let mut max_force = [0.0f64; 2];
    let mut contact = [0u64; 2];
    let mut peak = (-1.0, state.x_m.clone());
    let mut compute_s = 0.0;
    let mut grips: [Option<u16>; 2] = [None; 2];
    for k in 0..cfg.duration_ticks {
        let mut holds = Vec::with_capacity(2);
        let mut push = 0.0;
        for s in 0..2 {
            let tip = cfg.trajectories[s].at(k as f64 * TICK_S);
            let m = haptics[s].manipulate(tip, &state.x_m, grips[1 - s]);
            grips[s] = m.grip.map(|g| g.node);
            let force = match m.grip {
                Some(g) => {
                    NodeReaction::of(model, &state.x_m, &state.v_m_s, g.node).force_at(g.node_m)
                }
                None => V3::zeros(),
            };
            if let Some(g) = m.grip {
                holds.push(Hold {
                    node: u32::from(g.node),
                    target_m: g.node_m,
                });
                contact[s] += 1;
            }
            max_force[s] = max_force[s].max(force.norm());
            push += force.norm();
            if k % every == 0 {
                traces[s].push(ForceRow {
                    tick: k,
                    tip_m: arr(tip),
                    force_n: arr(force),
                    contact: m.grip.is_some(),
                });
            }
        }
        if push > peak.0 {
            peak = (push, state.x_m.clone());
        }
        let t = Instant::now();
        model.step(&mut state, &holds, &mut scratch)?;
        compute_s += t.elapsed().as_secs_f64();
    }
    Ok(LocalRun {
        ticks: cfg.duration_ticks,
        traces,
        max_force_n: max_force,
        contact_ticks: contact,
        peak_x_m: peak.1.iter().map(|p| arr(*p)).collect(),
        final_state: state,
        compute_s,
    })
}
