//! A run's schedule: the targets and disturbances the closed loop asks
//! for every period.
use hal_sim::{Loads, Schedule};
use plant_joint::{LoadId, PlantError};

use crate::files::scenario::{target_at, Disturbance, PlaneName, TargetStep};
use crate::run::spec::RunSpec;

/// Follows a scenario's targets over time and tells when they change. One
/// tracker follows one scenario.
#[derive(Clone, Debug)]
pub struct TargetTracker {
    current: Vec<f64>,
    /// Times `[from, to)` over which `target_at` gives the same targets as
    /// at the last call: no target time lies inside, so the answer there is
    /// known without a search (the closed loop asks every period).
    unchanged_s: [f64; 2],
}

impl Default for TargetTracker {
    fn default() -> Self {
        Self {
            current: Vec::new(),
            // Empty: the first call searches.
            unchanged_s: [f64::INFINITY, f64::NEG_INFINITY],
        }
    }
}

impl TargetTracker {
    /// The targets at `t_s` if they differ from the last ones returned.
    pub fn changed<'a>(&mut self, targets: &'a [TargetStep], t_s: f64) -> Option<&'a [f64]> {
        if t_s >= self.unchanged_s[0] && t_s < self.unchanged_s[1] {
            return None;
        }
        // `target_at` takes the last target with t_s ≤ t: its answer only
        // changes at target times, so it holds from the latest of them
        // ≤ t_s to the earliest after.
        self.unchanged_s =
            targets
                .iter()
                .fold([f64::NEG_INFINITY, f64::INFINITY], |[lo, hi], g| {
                    if g.t_s <= t_s {
                        [lo.max(g.t_s), hi]
                    } else {
                        [lo, hi.min(g.t_s)]
                    }
                });
        let target = target_at(targets, t_s);
        if target == self.current.as_slice() {
            return None;
        }
        self.current = target.to_vec();
        Some(target)
    }

    /// The targets last returned by [`Self::changed`].
    pub fn current(&self) -> &[f64] {
        &self.current
    }
}

/// A run's targets and disturbances, as the closed loop asks for them
/// every period (the same for `sim` and `hil`).
pub struct RunSchedule<'a> {
    targets_deg: &'a [TargetStep],
    disturbances: &'a [Disturbance],
    targets: TargetTracker,
    /// The load hung by each disturbance, while it hangs.
    loads: Vec<Option<LoadId>>,
}

impl<'a> RunSchedule<'a> {
    /// Nothing applied yet.
    pub fn new(spec: &'a RunSpec) -> Self {
        Self::of(&spec.targets, &spec.disturbances)
    }

    /// The schedule of these targets and disturbances, nothing applied
    /// yet.
    pub fn of(targets: &'a [TargetStep], disturbances: &'a [Disturbance]) -> Self {
        Self {
            targets_deg: targets,
            disturbances,
            targets: TargetTracker::default(),
            loads: vec![None; disturbances.len()],
        }
    }
}

impl<Pl: Loads, const P: usize, const C: usize> Schedule<Pl, P, C> for RunSchedule<'_> {
    fn targets(&mut self, t_s: f64) -> Option<[f32; P]> {
        self.targets
            .changed(self.targets_deg, t_s)
            .map(|deg| core::array::from_fn(|p| deg.get(p).copied().unwrap_or(0.0) as f32))
    }

    /// Coil-voltage overrides active at `t_s` (coil index = paper number −
    /// 1), and weights hung and cut.
    fn disturb(
        &mut self,
        t_s: f64,
        plant: &mut Pl,
        overrides: &mut [Option<f64>; C],
    ) -> Result<(), PlantError> {
        for (d, hung) in self.disturbances.iter().zip(self.loads.iter_mut()) {
            match d {
                Disturbance::CoilVoltage {
                    coil,
                    volts,
                    from_s,
                    to_s,
                } => {
                    if t_s >= *from_s && t_s < *to_s {
                        if let Some(o) = overrides.get_mut(coil.saturating_sub(1)) {
                            *o = Some(*volts);
                        }
                    }
                }
                Disturbance::Weight {
                    mass_g,
                    plane,
                    direction,
                    from_s,
                    to_s,
                } => {
                    let active = t_s >= *from_s && t_s < *to_s;
                    let plane = plane.map_or(0, PlaneName::index);
                    match (active, *hung) {
                        (true, None) => {
                            let dir = direction.unwrap_or(DEFAULT_THREAD_DIRECTION);
                            *hung = Some(plant.hang_weight(plane, mass_g * 1e-3, dir)?);
                        }
                        (false, Some(id)) => {
                            plant.remove_load(plane, id);
                            *hung = None;
                        }
                        _ => {}
                    }
                }
            }
        }
        Ok(())
    }
}

/// Where a weight's thread is led when the scenario does not say:
/// horizontal, towards −θ (socket frame).
pub const DEFAULT_THREAD_DIRECTION: [f64; 2] = [-1.0, 0.0];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::files::scenario::Scenario;

    #[test]
    fn target_tracker_reports_each_change_once() {
        let s = Scenario {
            targets: [(0.0, 0.0), (1.0, 5.0), (1.0, 6.0), (2.5, 6.0), (3.0, -2.0)]
                .map(|(t_s, d)| TargetStep {
                    t_s,
                    deg: vec![d, d],
                })
                .to_vec(),
            ..Scenario::default()
        };
        let mut tr = TargetTracker::default();
        let mut seen = Vec::new();
        for k in 0..4000 {
            let t = k as f64 * 1e-3;
            if let Some(d) = tr.changed(&s.targets, t) {
                seen.push((k, d[0]));
            }
            assert_eq!(tr.current(), s.target_at(t), "t = {t}");
        }
        assert_eq!(seen, vec![(0, 0.0), (1000, 6.0), (3000, -2.0)]);
    }
}
