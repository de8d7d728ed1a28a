//! The two copies of the object a site keeps: a **committed** replica that
//! both sites compute identically, and a **speculative** one that the
//! site's user sees and feels without waiting for the network.
//!
//! Consistency rule: the input of every site for every 1 kHz tick is a
//! packet (a [`Manipulation`], sequence number = tick). The committed
//! replica steps tick `k` only when it holds *both* sites' inputs for `k`,
//! and applies them in site order (site 0's held node, then site 1's; a
//! node held by both goes where site 1 puts it). The step is deterministic
//! f64 arithmetic in a fixed order, so two sites that received the same
//! packets hold bit-identical committed replicas, whatever order and
//! timing the packets arrived in. A lost or late packet stalls the
//! committed replica until the link recovers it ([`super::link`]); it never
//! lets the copies drift apart silently.
//!
//! The speculative replica starts from the committed one and runs ahead to
//! the present with the inputs known so far; a missing peer input is
//! predicted as the peer's latest known one (its grip held still). When a
//! peer input arrives that differs from what the speculation used, the
//! speculation is recomputed from the committed replica (a *rebase*), at
//! most once every [`ReplicaConfig::rebase_every_ticks`] ticks (this bounds
//! the recomputation on large meshes).
//!
//! Divergence is measured, not assumed away: every displayed frame (a
//! speculative state at a tick that is a multiple of
//! [`ReplicaConfig::frame_ticks`], 33 ≈ 30 Hz) is kept until the committed
//! replica reaches the same tick, and the largest node distance between
//! the two is recorded. As both sites' committed replicas are equal, the
//! distance between the two users' displays at a tick is at most the sum
//! of their two recorded divergences.
use super::link::WINDOW_TICKS;
use crate::error::{Result, TetError};
use crate::model::probe::{Manipulation, NodeReaction};
use crate::model::voigt::{Hold, State, VoigtModel};
use crate::model::V3;
use std::collections::VecDeque;
use std::sync::Arc;

/// Replica settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplicaConfig {
    /// Least ticks between two rebases of the speculation (1: rebase
    /// whenever a prediction turns out wrong).
    pub rebase_every_ticks: u32,
    /// Ticks between displayed frames (33 ≈ the seed's 30 Hz drawing, L2665).
    pub frame_ticks: u32,
    /// Displayed frames kept for the divergence check; older ones are
    /// dropped unchecked (and counted) when the committed replica lags.
    pub max_pending_frames: usize,
}

impl Default for ReplicaConfig {
    fn default() -> Self {
        ReplicaConfig {
            rebase_every_ticks: 4,
            frame_ticks: 33,
            max_pending_frames: 64,
        }
    }
}

/// Counters and measurements of one site's replicas.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ReplicaStats {
    /// Ticks computed by the speculative replica going forward.
    pub speculative_ticks: u64,
    /// Ticks computed again after a rebase.
    pub recomputed_ticks: u64,
    /// Rebases.
    pub rebases: u64,
    /// Speculative ticks that used a predicted peer input.
    pub predicted_ticks: u64,
    /// Peer inputs that differed from their prediction.
    pub mispredictions: u64,
    /// Largest jump of the speculative replica at a rebase (m).
    pub max_rebase_jump_m: f64,
    /// Displayed frames compared with the committed replica.
    pub frames_checked: u64,
    /// Displayed frames dropped before the committed replica got there.
    pub frames_unchecked: u64,
    /// (tick, divergence in m) of every checked frame, in order.
    pub divergence: Vec<(u64, f64)>,
    /// Largest gap between the speculative and committed tick.
    pub max_lag_ticks: u64,
    /// The committed replica's lag behind the present, once per tick
    /// ([`Replicas::record_lag`]).
    pub lag: LagHistogram,
    /// Times this site re-synchronised a restarted peer from its state.
    pub resyncs: u64,
}

/// How far the committed replica is behind the present, counted once per
/// tick in whole ticks (1 ms); lags of a window or more share the last
/// bucket. The buckets are allocated once, so the 1 kHz haptic thread can
/// record without allocating.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LagHistogram {
    counts: Vec<u64>,
    samples: u64,
    max_ticks: u64,
}

impl LagHistogram {
    /// An empty histogram with its buckets allocated.
    pub fn new() -> Self {
        LagHistogram {
            counts: vec![0; WINDOW_TICKS as usize + 1],
            samples: 0,
            max_ticks: 0,
        }
    }

    /// Counts one tick's lag.
    pub fn record(&mut self, lag_ticks: u64) {
        if self.counts.is_empty() {
            self.counts = vec![0; WINDOW_TICKS as usize + 1];
        }
        let last = self.counts.len() - 1;
        self.counts[(lag_ticks as usize).min(last)] += 1;
        self.samples += 1;
        self.max_ticks = self.max_ticks.max(lag_ticks);
    }

    /// Ticks counted.
    pub fn samples(&self) -> u64 {
        self.samples
    }

    /// The largest lag (ticks).
    pub fn max_ticks(&self) -> u64 {
        self.max_ticks
    }

    /// The mean lag (ticks).
    pub fn mean_ticks(&self) -> f64 {
        let sum: f64 = self
            .counts
            .iter()
            .enumerate()
            .map(|(k, n)| k as f64 * *n as f64)
            .sum();
        sum / self.samples.max(1) as f64
    }

    /// The smallest lag that at least a fraction `q` of the ticks did not
    /// exceed (ticks; 0 without samples).
    pub fn quantile_ticks(&self, q: f64) -> u64 {
        let need = (q.clamp(0.0, 1.0) * self.samples as f64).ceil() as u64;
        let mut seen = 0;
        for (k, n) in self.counts.iter().enumerate() {
            seen += n;
            if seen >= need.max(1) {
                return k as u64;
            }
        }
        0
    }
}

impl ReplicaStats {
    /// Largest recorded divergence (m).
    pub fn max_divergence_m(&self) -> f64 {
        self.divergence.iter().map(|d| d.1).fold(0.0, f64::max)
    }

    /// Mean recorded divergence (m).
    pub fn mean_divergence_m(&self) -> f64 {
        if self.divergence.is_empty() {
            0.0
        } else {
            self.divergence.iter().map(|d| d.1).sum::<f64>() / self.divergence.len() as f64
        }
    }

    /// The `q` quantile (0..=1) of the recorded divergence (m).
    pub fn divergence_quantile_m(&self, q: f64) -> f64 {
        let mut v: Vec<f64> = self.divergence.iter().map(|d| d.1).collect();
        if v.is_empty() {
            return 0.0;
        }
        v.sort_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize]
    }
}

/// The holds of one tick, in site order.
fn holds_of(inputs: [&Manipulation; 2]) -> Vec<Hold> {
    inputs
        .iter()
        .filter_map(|m| m.grip)
        .map(|g| Hold {
            node: u32::from(g.node),
            target_m: g.node_m,
        })
        .collect()
}

/// One site's committed and speculative replicas.
#[derive(Clone, Debug)]
pub struct Replicas {
    model: Arc<VoigtModel>,
    site: usize,
    config: ReplicaConfig,
    committed: State,
    /// `inputs[s][k]`: site s's input for tick `committed.tick + k`.
    inputs: [VecDeque<Option<Manipulation>>; 2],
    /// The peer's latest input the committed replica applied.
    last_committed_peer: Manipulation,
    speculative: State,
    /// The peer input the speculation used at ticks `committed.tick..`.
    used: VecDeque<Manipulation>,
    /// The furthest tick the speculation has shown.
    shown: u64,
    dirty: bool,
    since_rebase: u32,
    frames: VecDeque<(u64, Vec<V3>)>,
    scratch: Vec<V3>,
    stats: ReplicaStats,
}

impl Replicas {
    /// Both replicas of site `site` (0 or 1) at rest.
    pub fn new(model: Arc<VoigtModel>, site: u8, config: ReplicaConfig) -> Self {
        let rest = model.rest_state();
        Replicas::from_state(model, site, config, rest)
    }

    /// Both replicas of a site that joins a session at `state` (a state
    /// transfer from the peer): committed and speculative start there, and
    /// the first inputs expected are those of `state.tick`.
    pub fn from_state(
        model: Arc<VoigtModel>,
        site: u8,
        config: ReplicaConfig,
        state: State,
    ) -> Self {
        let rest = state;
        Replicas {
            model,
            site: usize::from(site & 1),
            config,
            committed: rest.clone(),
            inputs: [VecDeque::new(), VecDeque::new()],
            last_committed_peer: Manipulation::free(V3::zeros()),
            shown: rest.tick,
            speculative: rest,
            used: VecDeque::new(),
            dirty: false,
            since_rebase: 0,
            frames: VecDeque::new(),
            scratch: Vec::new(),
            stats: ReplicaStats {
                lag: LagHistogram::new(),
                ..ReplicaStats::default()
            },
        }
    }

    /// Counts the committed replica's lag behind `present` (the tick the
    /// site is at) once.
    pub fn record_lag(&mut self, present: u64) {
        let lag = present.saturating_sub(self.committed.tick);
        self.stats.lag.record(lag);
    }

    /// Re-synchronises a restarted peer (this site runs the session on):
    /// the peer's inputs this site never got for ticks before `tick` are
    /// taken as "no contact", its inputs from `tick` on are dropped (its
    /// new incarnation sends them), the committed replica advances to
    /// `tick` and is returned — the state the peer starts from. Needs this
    /// site's own inputs up to `tick`.
    pub fn resync_at(&mut self, tick: u64) -> Result<State> {
        let base = self.committed.tick;
        if tick < base || tick > self.local_end() {
            return Err(TetError::Session(format!(
                "cannot re-synchronise at tick {tick}: committed tick {base}, own inputs up to {}",
                self.local_end()
            )));
        }
        let peer = 1 - self.site;
        let n = (tick - base) as usize;
        let q = &mut self.inputs[peer];
        q.truncate(n);
        q.resize(n, None);
        for m in q.iter_mut() {
            if m.is_none() {
                *m = Some(Manipulation::free(V3::zeros()));
            }
        }
        self.advance(self.local_end())?;
        if self.committed.tick != tick {
            return Err(TetError::Session(format!(
                "re-synchronisation stopped at tick {} of {tick}",
                self.committed.tick
            )));
        }
        // Speculate again from here with the peer free.
        self.last_committed_peer = Manipulation::free(V3::zeros());
        self.dirty = true;
        self.since_rebase = self.config.rebase_every_ticks;
        self.stats.resyncs += 1;
        Ok(self.committed.clone())
    }

    /// The model.
    pub fn model(&self) -> &VoigtModel {
        &self.model
    }

    /// The committed replica (identical on both sites).
    pub fn committed(&self) -> &State {
        &self.committed
    }

    /// The speculative replica (what this site's user sees).
    pub fn speculative(&self) -> &State {
        &self.speculative
    }

    /// Counters and divergence.
    pub fn stats(&self) -> &ReplicaStats {
        &self.stats
    }

    /// The first tick without this site's own input.
    pub fn local_end(&self) -> u64 {
        self.committed.tick + self.inputs[self.site].len() as u64
    }

    /// The network's reaction at `node` in the speculative replica.
    pub fn reaction(&self, node: u16) -> NodeReaction {
        NodeReaction::of(
            &self.model,
            &self.speculative.x_m,
            &self.speculative.v_m_s,
            node,
        )
    }

    /// The node the peer holds at the speculative tick, as far as this
    /// site knows (its input there, or the prediction of it).
    pub fn peer_grip(&self) -> Option<u16> {
        self.peer_input(self.speculative.tick)
            .0
            .grip
            .map(|g| g.node)
    }

    /// This site's input for its next tick ([`Self::local_end`]).
    pub fn push_local(&mut self, tick: u64, input: Manipulation) -> Result<()> {
        if tick != self.local_end() {
            return Err(TetError::Session(format!(
                "local input for tick {tick}, expected tick {}",
                self.local_end()
            )));
        }
        if self.inputs[self.site].len() >= WINDOW_TICKS as usize {
            return Err(TetError::Session(format!(
                "the peer's input for tick {} has not arrived in {WINDOW_TICKS} ticks: the replicas cannot advance",
                self.committed.tick
            )));
        }
        self.inputs[self.site].push_back(Some(input));
        Ok(())
    }

    /// The peer's input for `tick` (any order, each tick once).
    pub fn push_remote(&mut self, tick: u64, input: Manipulation) -> Result<()> {
        let peer = 1 - self.site;
        let base = self.committed.tick;
        if tick < base {
            return Err(TetError::Session(format!(
                "peer input for tick {tick}, which is already committed"
            )));
        }
        let k = (tick - base) as usize;
        if k >= WINDOW_TICKS as usize {
            return Err(TetError::Session(format!(
                "peer input for tick {tick} is more than {WINDOW_TICKS} ticks ahead of tick {base}"
            )));
        }
        let q = &mut self.inputs[peer];
        if q.len() <= k {
            q.resize(k + 1, None);
        }
        if q[k].is_some() {
            return Err(TetError::Session(format!(
                "peer input for tick {tick} arrived twice"
            )));
        }
        q[k] = Some(input);
        if let Some(used) = self.used.get(k) {
            if *used != input {
                self.stats.mispredictions += 1;
                self.dirty = true;
            }
        }
        Ok(())
    }

    /// The peer input to use at `tick` (≥ committed tick): known, or the
    /// latest known before it, or the last committed one. The flag says
    /// whether it was predicted.
    fn peer_input(&self, tick: u64) -> (Manipulation, bool) {
        let q = &self.inputs[1 - self.site];
        let k = (tick - self.committed.tick) as usize;
        if let Some(Some(m)) = q.get(k) {
            return (*m, false);
        }
        let earlier = q.iter().take(k.min(q.len())).rev().flatten().next();
        (*earlier.unwrap_or(&self.last_committed_peer), true)
    }

    /// One speculative tick (forward or recomputed).
    fn speculate(&mut self) -> Result<()> {
        let tick = self.speculative.tick;
        let k = (tick - self.committed.tick) as usize;
        let own = self.inputs[self.site]
            .get(k)
            .copied()
            .flatten()
            .ok_or_else(|| TetError::Session(format!("no local input for tick {tick}")))?;
        let (peer, predicted) = self.peer_input(tick);
        if predicted {
            self.stats.predicted_ticks += 1;
        }
        let pair = if self.site == 0 {
            [&own, &peer]
        } else {
            [&peer, &own]
        };
        self.model
            .step(&mut self.speculative, &holds_of(pair), &mut self.scratch)?;
        self.used.push_back(peer);
        Ok(())
    }

    /// Steps the committed replica over every tick whose two inputs are
    /// here, then brings the speculation to `target` (at most the local
    /// end), rebasing it if a prediction was wrong.
    pub fn advance(&mut self, target: u64) -> Result<()> {
        let peer = 1 - self.site;
        while let (Some(Some(a)), Some(Some(b))) = (self.inputs[0].front(), self.inputs[1].front())
        {
            let holds = holds_of([a, b]);
            self.last_committed_peer = if peer == 0 { *a } else { *b };
            self.model
                .step(&mut self.committed, &holds, &mut self.scratch)?;
            self.inputs[0].pop_front();
            self.inputs[1].pop_front();
            if self.speculative.tick >= self.committed.tick {
                self.used.pop_front();
            }
            self.check_frames();
        }
        let behind = self.speculative.tick < self.committed.tick;
        if behind || (self.dirty && self.since_rebase >= self.config.rebase_every_ticks) {
            self.rebase()?;
        }
        // Ticks the committed replica reached first are shown as committed:
        // their frames diverge by nothing.
        let frame = u64::from(self.config.frame_ticks);
        while self.shown < self.speculative.tick {
            self.shown += 1;
            self.stats.speculative_ticks += 1;
            if self.shown % frame == 0 {
                self.stats.divergence.push((self.shown, 0.0));
                self.stats.frames_checked += 1;
            }
        }
        let target = target.min(self.local_end());
        while self.speculative.tick < target {
            self.speculate()?;
            self.since_rebase = self.since_rebase.saturating_add(1);
            if self.speculative.tick > self.shown {
                self.shown = self.speculative.tick;
                self.stats.speculative_ticks += 1;
                if self.shown % frame == 0 {
                    self.record_frame();
                }
            }
        }
        let lag = self.speculative.tick.saturating_sub(self.committed.tick);
        self.stats.max_lag_ticks = self.stats.max_lag_ticks.max(lag);
        Ok(())
    }

    /// Recomputes the speculation from the committed replica up to where
    /// it was.
    fn rebase(&mut self) -> Result<()> {
        let old = std::mem::replace(&mut self.speculative, self.committed.clone());
        self.used.clear();
        let to = old.tick.min(self.local_end());
        while self.speculative.tick < to {
            self.speculate()?;
            self.stats.recomputed_ticks += 1;
        }
        if old.tick == self.speculative.tick {
            let jump = old.max_distance_m(&self.speculative);
            self.stats.max_rebase_jump_m = self.stats.max_rebase_jump_m.max(jump);
        }
        self.stats.rebases += 1;
        self.dirty = false;
        self.since_rebase = 0;
        Ok(())
    }

    fn record_frame(&mut self) {
        if self.frames.len() >= self.config.max_pending_frames {
            self.frames.pop_front();
            self.stats.frames_unchecked += 1;
        }
        self.frames
            .push_back((self.speculative.tick, self.speculative.x_m.clone()));
        self.check_frames();
    }

    fn check_frames(&mut self) {
        while let Some((tick, x)) = self.frames.front() {
            if *tick > self.committed.tick {
                break;
            }
            if *tick == self.committed.tick {
                let d = x
                    .iter()
                    .zip(&self.committed.x_m)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                self.stats.divergence.push((*tick, d));
                self.stats.frames_checked += 1;
            } else {
                self.stats.frames_unchecked += 1;
            }
            self.frames.pop_front();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::mesh::CubeMesh;
    use crate::model::probe::Grip;
    use crate::model::voigt::VoigtMaterial;

    fn model() -> Arc<VoigtModel> {
        Arc::new(
            VoigtModel::new(CubeMesh::new(3, 0.06).unwrap(), VoigtMaterial::default()).unwrap(),
        )
    }

    /// Site s presses its top node down and up, 2 mm, period 200 ticks.
    fn press(m: &VoigtModel, s: usize, tick: u64) -> Manipulation {
        let node = m.mesh().nearest_node(V3::new(0.03 * s as f64, 0.03, 0.06));
        let depth = 0.001 * (1.0 - (tick as f64 * std::f64::consts::TAU / 200.0).cos());
        let p = m.mesh().nodes_m[node] - V3::z() * depth;
        let tet = m
            .mesh()
            .tets
            .iter()
            .position(|t| t.contains(&(node as u32)))
            .unwrap();
        Manipulation {
            tip_m: p,
            grip: Some(Grip {
                tet: tet as u16,
                node: node as u16,
                node_m: p,
            }),
        }
    }

    #[test]
    fn any_arrival_order_gives_bit_identical_committed_replicas() {
        let m = model();
        let ticks = 300u64;
        let inputs: Vec<[Manipulation; 2]> = (0..ticks)
            .map(|k| [press(&m, 0, k), press(&m, 1, k)])
            .collect();
        // Site 0 gets site 1's inputs in order; site 1 gets site 0's
        // reversed in blocks of 17 and late by 40 ticks.
        let mut a = Replicas::new(m.clone(), 0, ReplicaConfig::default());
        let mut b = Replicas::new(m.clone(), 1, ReplicaConfig::default());
        let mut held: Vec<u64> = Vec::new();
        for k in 0..ticks {
            a.push_local(k, inputs[k as usize][0]).unwrap();
            b.push_local(k, inputs[k as usize][1]).unwrap();
            a.push_remote(k, inputs[k as usize][1]).unwrap();
            held.push(k);
            if (held.len() >= 17 && k >= 40) || k + 1 == ticks {
                for t in held.drain(..).rev() {
                    b.push_remote(t, inputs[t as usize][0]).unwrap();
                }
            }
            a.advance(k + 1).unwrap();
            b.advance(k + 1).unwrap();
        }
        a.advance(ticks).unwrap();
        b.advance(ticks).unwrap();
        assert_eq!(a.committed().tick, ticks);
        assert_eq!(b.committed().tick, ticks);
        assert_eq!(a.committed().bit_hash(), b.committed().bit_hash());
        for (p, q) in a.committed().x_m.iter().zip(&b.committed().x_m) {
            for c in 0..3 {
                assert_eq!(p[c].to_bits(), q[c].to_bits());
            }
        }
        // Site 1 had to predict and recompute; site 0 never did.
        assert!(b.stats().mispredictions > 0 && b.stats().rebases > 0);
        assert_eq!(a.stats().mispredictions, 0);
        // With every input known in time, the speculation is the truth.
        assert_eq!(a.stats().max_divergence_m(), 0.0);
        assert_eq!(a.stats().frames_checked, ticks / 33, "{:?}", a.stats());
        // Site 1's display was off while it predicted, and that is measured.
        assert!(b.stats().max_divergence_m() > 0.0);
        assert!(
            b.stats().max_divergence_m() < 0.003,
            "{}",
            b.stats().max_divergence_m()
        );
    }

    #[test]
    fn a_missing_input_stalls_the_committed_replica_only() {
        let m = model();
        let mut a = Replicas::new(m.clone(), 0, ReplicaConfig::default());
        for k in 0..100 {
            a.push_local(k, press(&m, 0, k)).unwrap();
            if k != 10 {
                a.push_remote(k, press(&m, 1, k)).unwrap();
            }
            a.advance(k + 1).unwrap();
        }
        assert_eq!(a.committed().tick, 10, "waits for tick 10");
        assert_eq!(a.speculative().tick, 100, "the user's view goes on");
        a.push_remote(10, press(&m, 1, 10)).unwrap();
        a.advance(100).unwrap();
        assert_eq!(a.committed().tick, 100);
        let e = a.push_remote(5, press(&m, 1, 5)).unwrap_err();
        assert!(e.to_string().contains("already committed"), "{e}");
        let e = a.push_local(7, press(&m, 0, 7)).unwrap_err();
        assert!(e.to_string().contains("expected tick 100"), "{e}");
        a.push_remote(150, press(&m, 1, 150)).unwrap();
        let e = a.push_remote(150, press(&m, 1, 150)).unwrap_err();
        assert!(e.to_string().contains("twice"), "{e}");
    }
}
