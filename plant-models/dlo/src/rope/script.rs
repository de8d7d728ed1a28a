//! Scripted hands and rope scenarios: instead of the paper's two PHANTOM
//! Omni devices (L1434, L1520), each hand follows key positions in time,
//! grasping and releasing at keys; the virtual coupling (Fig. 7) joins the
//! hand to the point it holds. A scenario also fixes the rope's layout,
//! pins, desk and when to record frames and check the topology.
//!
//! Between two keys a hand moves on a straight line with smoothstep timing
//! (3u² − 2u³), so it starts and stops at rest. At a key's time its
//! action runs: `grasp` takes the named node, or the node nearest the hand
//! within `reach_m` (the paper intersects the gripper with the tree,
//! L1336; a reach is the scripted stand-in); `release` lets go.
use serde::{Deserialize, Serialize};

use super::forces::V3;
use super::params::RopeParams;
use super::sim::{Desk, Rope, Tool};
use crate::error::{check_non_negative, check_positive, DloError, Result};
use crate::topology::{crossings, knot_determinant, View};

/// What a hand does when it reaches a key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Action {
    Grasp,
    Release,
}

/// One key of a hand: where it is at `t_s`, and what it does there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Key {
    /// Time, s.
    pub t_s: f64,
    /// Hand position, m; with `at_node`, an offset from that node.
    pub at_m: [f64; 3],
    /// Aim at a rope node: while the hand moves towards this key, the
    /// key's position follows the node (its position plus `at_m`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub at_node: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub action: Option<Action>,
    /// Node to grasp (default: the nearest within the hand's reach).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node: Option<usize>,
}

/// A scripted hand.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HandScript {
    pub name: String,
    /// How far from the hand a point may be to be grasped, m.
    #[serde(default = "default_reach")]
    pub reach_m: f64,
    pub keys: Vec<Key>,
}

fn v3(a: [f64; 3]) -> V3 {
    V3::new(a[0], a[1], a[2])
}

fn default_reach() -> f64 {
    0.3
}

impl HandScript {
    /// Hand position and velocity at `t_s`, with the keys' positions
    /// `resolved` (m; see [`Key::at_node`]).
    pub fn motion_resolved(&self, t_s: f64, resolved: &[V3]) -> (V3, V3) {
        let keys = &self.keys;
        let Some(first) = keys.first() else {
            return (V3::zeros(), V3::zeros());
        };
        if t_s <= first.t_s {
            return (resolved[0], V3::zeros());
        }
        for (k, w) in keys.windows(2).enumerate() {
            let (a, b) = (&w[0], &w[1]);
            if t_s < b.t_s {
                let span = b.t_s - a.t_s;
                let u = (t_s - a.t_s) / span;
                let s = u * u * (3.0 - 2.0 * u);
                let ds = 6.0 * u * (1.0 - u) / span;
                let (pa, pb) = (resolved[k], resolved[k + 1]);
                return (pa + (pb - pa) * s, (pb - pa) * ds);
            }
        }
        (resolved[keys.len() - 1], V3::zeros())
    }

    /// Hand position and velocity at `t_s` for keys given in space (an
    /// `at_node` key counts as its bare offset).
    pub fn motion(&self, t_s: f64) -> (V3, V3) {
        let fixed: Vec<V3> = self.keys.iter().map(|k| v3(k.at_m)).collect();
        self.motion_resolved(t_s, &fixed)
    }

    fn validate(&self, nodes: usize) -> Result<()> {
        let bad = |why: String| DloError::InvalidScenario(format!("hand `{}`: {why}", self.name));
        check_positive(&format!("hands.{}.reach_m", self.name), self.reach_m)?;
        if self.keys.is_empty() {
            return Err(bad("has no keys".into()));
        }
        let mut last = f64::NEG_INFINITY;
        for (k, key) in self.keys.iter().enumerate() {
            check_non_negative(&format!("hands.{}.keys[{k}].t_s", self.name), key.t_s)?;
            if key.t_s <= last {
                return Err(bad(format!(
                    "key {k}: t_s = {} is not after the previous key's {}",
                    key.t_s, last
                )));
            }
            last = key.t_s;
            if key.at_m.iter().any(|c| !c.is_finite()) {
                return Err(bad(format!("key {k}: at_m must be finite")));
            }
            if let Some(node) = key.at_node {
                if node >= nodes {
                    return Err(bad(format!(
                        "key {k}: at_node {node} does not exist (rope has {nodes})"
                    )));
                }
                if k == 0 {
                    return Err(bad("the first key cannot aim at a node".into()));
                }
            }
            if let Some(node) = key.node {
                if node >= nodes {
                    return Err(bad(format!(
                        "key {k}: node {node} does not exist (rope has {nodes})"
                    )));
                }
                if key.action != Some(Action::Grasp) {
                    return Err(bad(format!("key {k}: `node` needs action = \"grasp\"")));
                }
            }
        }
        Ok(())
    }
}

/// When to look at the rope's topology, and under which name.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TopologyCheck {
    pub label: String,
    pub at_s: f64,
}

/// A rope scenario: rope, layout, pins, desk, hands, duration, outputs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RopeScenario {
    pub name: String,
    #[serde(default)]
    pub rope: RopeParams,
    /// First point of the straight initial rope, m.
    pub start_m: [f64; 3],
    /// Direction of the straight initial rope.
    pub direction: [f64; 3],
    /// Points fixed in space.
    #[serde(default)]
    pub pins: Vec<usize>,
    /// Height of the desk, m (none: no desk).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub desk_height_m: Option<f64>,
    #[serde(default)]
    pub hands: Vec<HandScript>,
    pub duration_s: f64,
    /// Record a frame every this many seconds.
    #[serde(default = "default_frame_interval")]
    pub frame_interval_s: f64,
    #[serde(default)]
    pub checks: Vec<TopologyCheck>,
    /// Relax to rest: after every step, all velocities are zeroed whenever
    /// the kinetic energy has passed a peak ([`Rope::relax`]'s kinetic
    /// damping). The answer is then the run's end state, and the run
    /// carries the `rest` check (see [`super::verify`]).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub kinetic_damping: bool,
}

fn default_frame_interval() -> f64 {
    0.05
}

/// A recorded state.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub time_s: f64,
    pub x: Vec<V3>,
    /// Hand positions, m.
    pub hands_m: Vec<V3>,
    /// Which node each hand holds.
    pub held: Vec<Option<usize>>,
}

/// The topology at a check.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TopologyResult {
    pub label: String,
    pub time_s: f64,
    /// Crossings of the open rope seen from above.
    pub crossings: usize,
    /// Knot determinant of the closed rope (1 unknot, 3 trefoil/overhand).
    pub determinant: Option<u128>,
    /// Node positions then, m (for the time-step check).
    #[serde(skip)]
    pub x: Vec<V3>,
}

/// Per-hand figures of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HandSummary {
    pub name: String,
    /// Largest device force −s·f, N (PHANTOM Omni: 3.3 N at most, L1399).
    pub max_output_force_n: f64,
    /// Largest coupling force on the rope, N.
    pub max_coupling_force_n: f64,
    /// Grasps that found no point within reach (key times).
    pub missed_grasps_s: Vec<f64>,
}

/// What a run produced.
#[derive(Debug, Clone, PartialEq)]
pub struct RunResult {
    pub frames: Vec<Frame>,
    /// The topology checks, in time order.
    pub topology: Vec<TopologyResult>,
    pub hands: Vec<HandSummary>,
    pub steps: usize,
    /// Largest overlap 2r − s of non-neighbouring segments after any
    /// step's collision handling, m.
    pub max_penetration_m: f64,
    /// When that overlap happened, s.
    pub max_penetration_time_s: f64,
    /// Steps with at least one self-contact.
    pub contact_steps: usize,
    /// Segments clamped by force propagation, summed over steps.
    pub clamped_segments: usize,
    /// Largest |Σ internal forces| over the run, N (0 up to rounding).
    pub max_internal_force_sum_n: f64,
    /// Largest Σ|f_i| of the internal forces at the same samples, N (the
    /// scale the rounding of the sum is relative to).
    pub internal_force_scale_n: f64,
    /// Longest segment after any step, in rest lengths.
    pub max_segment_ratio: f64,
    /// Which segment that was, and when, s.
    pub max_segment_index: usize,
    pub max_segment_ratio_time_s: f64,
    /// Why the step's own checks stopped the run (time and reason); the
    /// frames and the figures end at the last good step.
    pub unstable: Option<String>,
    /// Node positions at the end of the run (or at the last good step), m.
    pub final_x: Vec<V3>,
    /// Largest force left on a free point by the end positions at rest
    /// (gravity, internal forces, desk, couplings; not the collision
    /// impulses), N.
    pub rest_force_n: f64,
    /// Wall time of the stepping alone, s.
    pub wall_s: f64,
}

impl RopeScenario {
    /// Checks every field; the error names the bad one.
    pub fn validate(&self) -> Result<()> {
        self.rope.validate()?;
        check_positive("duration_s", self.duration_s)?;
        if self.duration_s > 600.0 {
            return Err(DloError::InvalidParameter {
                name: "duration_s".into(),
                value: self.duration_s,
                reason: "at most 600 s",
            });
        }
        check_positive("frame_interval_s", self.frame_interval_s)?;
        if self
            .start_m
            .iter()
            .chain(&self.direction)
            .any(|c| !c.is_finite())
            || self.direction.iter().all(|&c| c == 0.0)
        {
            return Err(DloError::InvalidScenario(
                "start_m must be finite and direction finite and non-zero".into(),
            ));
        }
        for &p in &self.pins {
            if p >= self.rope.nodes {
                return Err(DloError::InvalidScenario(format!(
                    "pins: node {p} does not exist (rope has {})",
                    self.rope.nodes
                )));
            }
        }
        if let Some(h) = self.desk_height_m {
            if !h.is_finite() {
                return Err(DloError::InvalidParameter {
                    name: "desk_height_m".into(),
                    value: h,
                    reason: "must be finite",
                });
            }
        }
        for h in &self.hands {
            h.validate(self.rope.nodes)?;
        }
        for c in &self.checks {
            check_non_negative(&format!("checks.{}.at_s", c.label), c.at_s)?;
        }
        Ok(())
    }

    /// The rope at t = 0.
    pub fn initial_rope(&self) -> Result<Rope> {
        self.validate()?;
        let mut rope = Rope::straight(self.rope.clone(), v3(self.start_m), v3(self.direction))?;
        for &p in &self.pins {
            rope.pin(p)?;
        }
        rope.desk = self.desk_height_m.map(|height_m| Desk { height_m });
        for h in &self.hands {
            rope.tools.push(Tool::at(h.motion(0.0).0));
        }
        Ok(rope)
    }

    /// Runs the scenario; `on_frame` sees every recorded frame as it comes
    /// (a progress bar, a streaming writer).
    pub fn run(&self, mut on_frame: impl FnMut(&Frame)) -> Result<RunResult> {
        let mut run = ScenarioRun::start(self)?;
        let steps = run.out.steps;
        let frame_every = ((self.frame_interval_s / run.dt).round() as usize).max(1);
        let started = std::time::Instant::now();
        // Kinetic damping: the kinetic energy after the last step.
        let mut last_ke = 0.0;
        for k in 0..=steps {
            run.move_hands(k)?;
            run.check_topology(k);
            if k % frame_every == 0 {
                let f = run.frame();
                on_frame(&f);
                run.out.frames.push(f);
            }
            if k == steps {
                break;
            }
            match run.rope.step() {
                Ok(()) => {}
                Err(e @ DloError::Unstable { .. }) => {
                    // Reported as the failed stability check, with the
                    // frames and figures up to the last good step.
                    run.out.unstable = Some(e.to_string());
                    break;
                }
                Err(e) => return Err(e),
            }
            run.record_step(k);
            if self.kinetic_damping {
                let ke = run.rope.kinetic_energy();
                if ke < last_ke {
                    // Past a peak: the potential energy is near a minimum
                    // along the motion; stop it there.
                    for v in run.rope.v.iter_mut() {
                        *v = V3::zeros();
                    }
                    last_ke = 0.0;
                } else {
                    last_ke = ke;
                }
            }
        }
        run.out.wall_s = started.elapsed().as_secs_f64();
        run.out.hands = run.hands;
        run.out.final_x = run.rope.x.clone();
        if run.out.unstable.is_none() {
            // The static residual: the forces at the end positions with
            // every point at rest (the dampers then exert nothing).
            let mut still = run.rope.clone();
            still.v.iter_mut().for_each(|v| *v = V3::zeros());
            run.out.rest_force_n = still
                .net_forces_n()
                .iter()
                .map(|f| f.norm())
                .fold(0.0, f64::max);
        }
        Ok(run.out)
    }

    /// The stated bound on segment overlap: 0.3 r (centre lines never
    /// closer than 1.7 r; passing through would need 2r).
    pub fn penetration_tolerance_m(&self) -> f64 {
        0.3 * self.rope.radius_m
    }
}

impl RunResult {
    /// Wall time per step, µs (of the stepping alone).
    pub fn step_time_us(&self) -> f64 {
        1e6 * self.wall_s / self.steps.max(1) as f64
    }
}

/// A scenario being run: the rope, where each hand is in its script, the
/// checks still to come, and what has been recorded so far.
struct ScenarioRun<'a> {
    scenario: &'a RopeScenario,
    rope: Rope,
    dt: f64,
    /// Next key of each hand (key actions run in time order).
    next_key: Vec<usize>,
    /// Key positions, resolved for `at_node` keys when the hand sets off.
    resolved: Vec<Vec<V3>>,
    /// Topology checks as step indices, in time order.
    checks: Vec<(usize, &'a TopologyCheck)>,
    next_check: usize,
    /// Scratch for the internal-force sum.
    internal: Vec<V3>,
    hands: Vec<HandSummary>,
    out: RunResult,
}

impl<'a> ScenarioRun<'a> {
    fn start(scenario: &'a RopeScenario) -> Result<Self> {
        let rope = scenario.initial_rope()?;
        let dt = rope.params.dt_s;
        let steps = (scenario.duration_s / dt).round() as usize;
        let hands = scenario
            .hands
            .iter()
            .map(|h| HandSummary {
                name: h.name.clone(),
                max_output_force_n: 0.0,
                max_coupling_force_n: 0.0,
                missed_grasps_s: Vec::new(),
            })
            .collect();
        let mut checks: Vec<(usize, &TopologyCheck)> = scenario
            .checks
            .iter()
            .map(|c| (((c.at_s / dt).round() as usize).min(steps), c))
            .collect();
        checks.sort_by_key(|c| c.0);
        let resolved = scenario
            .hands
            .iter()
            .map(|h| h.keys.iter().map(|k| v3(k.at_m)).collect())
            .collect();
        Ok(ScenarioRun {
            scenario,
            next_key: vec![0usize; scenario.hands.len()],
            resolved,
            checks,
            next_check: 0,
            internal: vec![V3::zeros(); rope.len()],
            hands,
            out: RunResult {
                frames: Vec::new(),
                topology: Vec::new(),
                hands: Vec::new(),
                steps,
                max_penetration_m: 0.0,
                max_penetration_time_s: 0.0,
                contact_steps: 0,
                clamped_segments: 0,
                max_internal_force_sum_n: 0.0,
                internal_force_scale_n: 0.0,
                max_segment_ratio: 1.0,
                max_segment_index: 0,
                max_segment_ratio_time_s: 0.0,
                unstable: None,
                final_x: Vec::new(),
                rest_force_n: 0.0,
                wall_s: 0.0,
            },
            rope,
            dt,
        })
    }

    /// Moves every hand to where its script has it at step `k`, and runs
    /// the actions of the keys it has reached.
    fn move_hands(&mut self, k: usize) -> Result<()> {
        let t = k as f64 * self.dt;
        for (h, script) in self.scenario.hands.iter().enumerate() {
            // A key aimed at a node follows it until the hand gets there.
            if let Some(next) = script.keys.get(self.next_key[h]) {
                if let Some(node) = next.at_node {
                    self.resolved[h][self.next_key[h]] = self.rope.x[node] + v3(next.at_m);
                }
            }
            let (pos, vel) = script.motion_resolved(t, &self.resolved[h]);
            self.rope.tools[h].position_m = pos;
            self.rope.tools[h].velocity_m_s = vel;
            while let Some(key) = script.keys.get(self.next_key[h]) {
                if ((key.t_s / self.dt).round() as usize) > k {
                    break;
                }
                self.next_key[h] += 1;
                self.run_action(h, script, key, pos)?;
            }
        }
        Ok(())
    }

    /// The action of `key`, reached by hand `h` at `pos`.
    fn run_action(&mut self, h: usize, script: &HandScript, key: &Key, pos: V3) -> Result<()> {
        match key.action {
            Some(Action::Grasp) => {
                // A named node must be within reach too: a hand does not
                // pull a point from afar.
                let node = match key.node {
                    Some(n) => ((self.rope.x[n] - pos).norm() <= script.reach_m).then_some(n),
                    None => self.rope.nearest_node(pos, script.reach_m),
                };
                match node {
                    Some(n) => self.rope.grasp(h, n)?,
                    None => self.hands[h].missed_grasps_s.push(key.t_s),
                }
            }
            Some(Action::Release) => self.rope.tools[h].grasped = None,
            None => {}
        }
        Ok(())
    }

    /// Records the topology checks due at step `k`.
    fn check_topology(&mut self, k: usize) {
        while let Some(&(at, c)) = self.checks.get(self.next_check) {
            if at != k {
                break;
            }
            self.next_check += 1;
            self.out.topology.push(TopologyResult {
                label: c.label.clone(),
                time_s: self.rope.time_s,
                crossings: crossings(&self.rope.x, View::default()).len(),
                determinant: knot_determinant(&self.rope.x, View::default()),
                x: self.rope.x.clone(),
            });
        }
    }

    /// The rope and hands now.
    fn frame(&self) -> Frame {
        Frame {
            time_s: self.rope.time_s,
            x: self.rope.x.clone(),
            hands_m: self.rope.tools.iter().map(|t| t.position_m).collect(),
            held: self.rope.tools.iter().map(|t| t.grasped).collect(),
        }
    }

    /// The run's figures after step `k`: internal-force sum and its scale
    /// (every 100 steps), deepest overlap, longest segment, contacts,
    /// clamping, hand forces.
    fn record_step(&mut self, k: usize) {
        let (rope, out) = (&self.rope, &mut self.out);
        if k % 100 == 0 {
            for f in self.internal.iter_mut() {
                *f = V3::zeros();
            }
            super::forces::add_internal_forces(&rope.params, &rope.x, &rope.v, &mut self.internal);
            let sum: V3 = self.internal.iter().sum();
            out.max_internal_force_sum_n = out.max_internal_force_sum_n.max(sum.norm());
            let scale: f64 = self.internal.iter().map(|f| f.norm()).sum();
            out.internal_force_scale_n = out.internal_force_scale_n.max(scale);
        }
        // The longest segment so far, without a square root per segment
        // and step: squared lengths are screened against the record (with
        // a margin far above rounding), and only a candidate's ratio is
        // computed and compared as before, so the record is the same.
        let l_r = rope.params.rest_length_m();
        let screen = (out.max_segment_ratio * l_r).powi(2) * (1.0 - 1e-9);
        for (i, w) in rope.x.windows(2).enumerate() {
            let d2 = (w[1] - w[0]).norm_squared();
            if d2 < screen {
                continue;
            }
            let ratio = d2.sqrt() / l_r;
            if ratio > out.max_segment_ratio {
                out.max_segment_ratio = ratio;
                out.max_segment_index = i;
                out.max_segment_ratio_time_s = rope.time_s;
            }
        }
        if rope.stats.max_penetration_m > out.max_penetration_m {
            out.max_penetration_m = rope.stats.max_penetration_m;
            out.max_penetration_time_s = rope.time_s;
        }
        out.contact_steps += usize::from(rope.stats.contacts > 0);
        out.clamped_segments += rope.stats.clamped_segments;
        for (h, tool) in rope.tools.iter().enumerate() {
            let f = tool.coupling_force_n.norm();
            let hand = &mut self.hands[h];
            hand.max_coupling_force_n = hand.max_coupling_force_n.max(f);
            hand.max_output_force_n = hand
                .max_output_force_n
                .max(tool.output_force_n(&rope.params).norm());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shipped scenario (`softjoint dlo rope` runs it by default).
    const OVERHAND: &str = include_str!("../../../../scenarios/dlo/overhand.toml");

    /// 42 s of simulated time: about 1 s in a release build, minutes in a
    /// debug one, so CI runs `dropped_coil_keeps_its_topology` instead.
    /// `cargo test --release -p plant-models --lib scripted_hands -- --ignored`
    #[test]
    #[ignore = "long: run with --release (README)"]
    fn scripted_hands_tie_an_overhand_knot_and_untie_it() {
        let s: RopeScenario = toml::from_str(OVERHAND).unwrap();
        let r = s.run(|_| {}).unwrap();
        let check = |label: &str| {
            r.topology
                .iter()
                .find(|c| c.label == label)
                .unwrap_or_else(|| panic!("no check {label}"))
                .clone()
        };
        // Before the tuck: a loop, one crossing, no knot.
        assert_eq!(check("loop").determinant, Some(1));
        assert_eq!(check("loop").crossings, 1);
        // The tuck made a trefoil (knot determinant 3), still there when
        // pulled tight and when loosened.
        for label in ["knotted", "tight", "loosened"] {
            assert_eq!(check(label).determinant, Some(3), "{label}");
        }
        // Pulling the loop away draws the tail out: unknotted, and laid
        // straight, no crossing at all seen from above.
        assert_eq!(check("pulled out").determinant, Some(1));
        assert_eq!(check("untied").determinant, Some(1));
        assert_eq!(check("untied").crossings, 0);
        // Segments never overlap by more than 0.3 r (measured 12.6 mm at
        // the sudden release at 36 s; passing through would need 2r).
        assert!(
            r.max_penetration_m <= 0.3 * s.rope.radius_m,
            "overlap {} m at {} s",
            r.max_penetration_m,
            r.max_penetration_time_s
        );
        assert!(r.hands.iter().all(|h| h.missed_grasps_s.is_empty()));
        // Internal forces sum to zero along the whole run.
        assert!(
            r.max_internal_force_sum_n < 1e-9,
            "{}",
            r.max_internal_force_sum_n
        );
        // The device force stays within a PHANTOM Omni's 3.3 N (L1399).
        for h in &r.hands {
            assert!(h.max_output_force_n < super::super::params::OMNI_MAX_FORCE_N);
        }
        // The run passes its own checks (issue 29; the time-step check,
        // `--check-step`, is not made: README, "Rope self-checks").
        let c = super::super::verify::RopeChecks::of(&s, &r, None);
        assert!(c.verified(), "{c:?}");
        assert_eq!(c.status(), "verified");
    }
}

#[cfg(test)]
mod short_tests {
    use super::*;
    use crate::rope::sim::{Desk, Rope};

    #[test]
    fn dropped_coil_keeps_its_topology() {
        // A flat spiral of rope (three turns, 0.12 m apart: closer than
        // the 2r = 0.1 m contact distance plus its sag) dropped onto a desk
        // from 0.3 m with a twist: many self-contacts. The rope must never
        // pass through itself: the overlap stays under 0.3 r and the knot
        // determinant and the crossings seen from above do not change.
        let p = RopeParams {
            nodes: 40,
            length_m: 4.0,
            ..RopeParams::default()
        };
        let l_r = p.rest_length_m();
        let mut x = Vec::new();
        let (mut a, mut rad) = (0.0f64, 0.25f64);
        for i in 0..40 {
            x.push(V3::new(
                rad * a.cos(),
                rad * a.sin(),
                0.3 + 0.04 * (i % 2) as f64,
            ));
            a += l_r / rad;
            rad += 0.12 * l_r / (2.0 * std::f64::consts::PI * rad);
        }
        // Respace to rest length along the spiral.
        let mut rope = Rope::from_points(p.clone(), x).unwrap();
        rope.desk = Some(Desk { height_m: 0.0 });
        for (i, v) in rope.v.iter_mut().enumerate() {
            *v = V3::new(0.0, 0.0, -1.0) + V3::new(0.0, 0.3, 0.0) * (i as f64 / 40.0);
        }
        let view = View::default();
        let det0 = knot_determinant(&rope.x, view);
        let cross0 = crossings(&rope.x, view).len();
        let mut worst: f64 = 0.0;
        let mut contacts = 0;
        for _ in 0..1500 {
            rope.step().unwrap();
            worst = worst.max(rope.stats.max_penetration_m);
            contacts += rope.stats.contacts;
        }
        assert!(contacts > 100, "only {contacts} contacts");
        assert!(worst <= 0.3 * p.radius_m, "overlap {worst} m");
        assert_eq!(knot_determinant(&rope.x, view), det0);
        assert_eq!(crossings(&rope.x, view).len(), cross0);
    }
}
