//! A session scenario: the object, the network and the two users' scripted
//! stylus paths. `softjoint tetmsd` reads it from TOML (every table refuses
//! unknown fields); [`Scenario::default`] is the built-in one.
use super::link::LinkConfig;
use super::netem::{NetemConfig, Profile};
use super::pair::{PairConfig, SessionConfig};
use super::replica::ReplicaConfig;
use crate::error::{check_range, Result, TetError};
use crate::model::mesh::MAX_LEVEL;
use crate::model::probe::{Trajectory, Waypoint};
use crate::model::voigt::{VoigtMaterial, TICK_S};
use serde::{Deserialize, Serialize};

/// The network of a scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetworkSpec {
    /// `none`, `table2` … `table5` (the seed's round-trip tables) or
    /// `rtt-MS` (a fixed round trip of MS milliseconds).
    pub profile: String,
    /// Probability a packet is lost (0 … 0.5). Estimate: 1 %.
    pub loss: f64,
    /// Probability a packet is held 1–3 ms extra (0 … 1).
    pub reorder: f64,
    /// Packets the emulator queue holds.
    pub queue_packets: usize,
    /// Extra one-way delay per packet, uniform in `[0, jitter_ms]` (ms).
    #[serde(default)]
    pub jitter_ms: f64,
    /// Mean length of a run of lost packets (0: independent losses).
    #[serde(default)]
    pub burst_len: f64,
}

/// One user's stylus.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SiteSpec {
    /// The path restarts every `repeat_s` seconds (omit: play once, then hold).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub repeat_s: Option<f64>,
    /// Stylus waypoints (mm in the cube's frame; the cube spans
    /// `[0, side_mm]³` and rests on `z = 0`).
    pub waypoints: Vec<Waypoint>,
}

/// A whole scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Refinement level of the cube (3–9 are the seed's; 0–12 are built).
    pub level: u32,
    /// Cube edge (mm). Estimate: 60 mm, a hand-sized soft block (the
    /// seed gives no size).
    pub side_mm: f64,
    /// Simulated time (s).
    pub duration_s: f64,
    /// Seed of the network's random delays, loss and reordering.
    pub seed: u64,
    /// The Voigt network's constants.
    pub material: VoigtMaterial,
    /// The network between the sites.
    pub network: NetworkSpec,
    /// Least ticks between rebases of the speculative replica.
    pub rebase_every_ticks: u32,
    /// The two users: exactly two `[[site]]` tables.
    pub site: Vec<SiteSpec>,
}

fn wp(t_s: f64, x_mm: f64, y_mm: f64, z_mm: f64) -> Waypoint {
    Waypoint {
        t_s,
        x_mm,
        y_mm,
        z_mm,
    }
}

impl Default for Scenario {
    /// Level 6 (125 nodes), Table 2's network, 10 s. User 0 presses 8 mm
    /// into the top face 20 mm from one edge every 3 s; user 1 presses
    /// 7 mm deep 20 mm away and drags 15 mm sideways every 2.2 s, so the
    /// two deformations meet.
    fn default() -> Self {
        Scenario {
            level: 6,
            side_mm: 60.0,
            duration_s: 10.0,
            seed: 1,
            material: VoigtMaterial::default(),
            network: NetworkSpec {
                profile: "table2".into(),
                loss: 0.01,
                reorder: 0.01,
                queue_packets: 4096,
                jitter_ms: 0.0,
                burst_len: 0.0,
            },
            rebase_every_ticks: ReplicaConfig::default().rebase_every_ticks,
            site: vec![
                SiteSpec {
                    repeat_s: Some(3.0),
                    waypoints: vec![
                        wp(0.0, 20.0, 30.0, 65.0),
                        wp(1.0, 20.0, 30.0, 52.0),
                        wp(1.5, 20.0, 30.0, 52.0),
                        wp(2.5, 20.0, 30.0, 65.0),
                    ],
                },
                SiteSpec {
                    repeat_s: Some(2.2),
                    waypoints: vec![
                        wp(0.0, 40.0, 22.0, 64.0),
                        wp(0.7, 40.0, 22.0, 53.0),
                        wp(1.5, 40.0, 37.0, 53.0),
                        wp(2.0, 40.0, 37.0, 64.0),
                    ],
                },
            ],
        }
    }
}

impl Scenario {
    /// The session the scenario describes (checked; errors name the
    /// field, `file` labels them).
    pub fn session(&self, file: &str) -> Result<SessionConfig> {
        if self.level > MAX_LEVEL {
            return Err(TetError::Malformed {
                location: format!("{file}: level"),
                reason: format!(
                    "must be 0 to {MAX_LEVEL} (the seed's levels are 3 to 9), got {}",
                    self.level
                ),
            });
        }
        let named = |e: TetError| TetError::Malformed {
            location: file.into(),
            reason: e.to_string(),
        };
        check_range(
            "side_mm",
            self.side_mm,
            1.0,
            10_000.0,
            "must be 1 to 10,000 mm",
        )
        .map_err(named)?;
        self.material.validate().map_err(named)?;
        if self.rebase_every_ticks == 0 || self.rebase_every_ticks > 10_000 {
            return Err(TetError::Malformed {
                location: format!("{file}: rebase_every_ticks"),
                reason: format!("must be 1 to 10000, got {}", self.rebase_every_ticks),
            });
        }
        Ok(SessionConfig {
            level: self.level,
            side_m: self.side_mm * 1e-3,
            material: self.material,
            replica: ReplicaConfig {
                rebase_every_ticks: self.rebase_every_ticks,
                ..ReplicaConfig::default()
            },
            link: LinkConfig::default(),
        })
    }

    /// The network emulator's settings.
    pub fn netem(&self, file: &str) -> Result<NetemConfig> {
        let profile =
            Profile::by_name(&self.network.profile).ok_or_else(|| TetError::Malformed {
                location: format!("{file}: network.profile"),
                reason: format!(
                    "unknown profile `{}`: use none, table2, table3, table4, table5 or rtt-MS",
                    self.network.profile
                ),
            })?;
        let n = &self.network;
        check_range(
            "jitter_ms",
            n.jitter_ms,
            0.0,
            1000.0,
            "must be 0 to 1000 ms",
        )
        .map_err(|e| TetError::Malformed {
            location: format!("{file}: network"),
            reason: e.to_string(),
        })?;
        let cfg = NetemConfig {
            profile,
            loss: n.loss,
            reorder: n.reorder,
            capacity: n.queue_packets,
            jitter_us: (n.jitter_ms * 1000.0).round() as u64,
            burst_len: n.burst_len,
        };
        cfg.validate().map_err(|e| TetError::Malformed {
            location: format!("{file}: network"),
            reason: e.to_string(),
        })?;
        Ok(cfg)
    }

    /// The two stylus paths.
    pub fn trajectories(&self, file: &str) -> Result<[Trajectory; 2]> {
        if self.site.len() != 2 {
            return Err(TetError::Malformed {
                location: format!("{file}: site"),
                reason: format!("needs exactly two [[site]] tables, got {}", self.site.len()),
            });
        }
        let one = |k: usize| {
            let s = &self.site[k];
            Trajectory::new(&s.waypoints, s.repeat_s, &format!("{file}: site {}", k + 1))
        };
        Ok([one(0)?, one(1)?])
    }

    /// Ticks in `duration_s`.
    pub fn ticks(&self, file: &str) -> Result<u64> {
        check_range(
            "duration_s",
            self.duration_s,
            TICK_S,
            86_400.0,
            "must be 0.001 to 86400 s",
        )
        .map_err(|e| TetError::Malformed {
            location: file.into(),
            reason: e.to_string(),
        })?;
        Ok((self.duration_s / TICK_S).round() as u64)
    }

    /// The whole virtual pair run.
    pub fn pair_config(&self, file: &str) -> Result<PairConfig> {
        Ok(PairConfig {
            session: self.session(file)?,
            netem: self.netem(file)?,
            seed: self.seed,
            duration_ticks: self.ticks(file)?,
            trajectories: self.trajectories(file)?,
            trace_every_ticks: 10,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_scenario_is_valid_and_bad_fields_are_named() {
        let s = Scenario::default();
        let cfg = s.pair_config("default").unwrap();
        assert_eq!(cfg.duration_ticks, 10_000);
        let mut bad = s.clone();
        bad.network.profile = "table7".into();
        let e = bad.pair_config("x.toml").unwrap_err().to_string();
        assert!(
            e.contains("x.toml: network.profile") && e.contains("table7"),
            "{e}"
        );
        let mut bad = s.clone();
        bad.level = 20;
        assert!(bad
            .pair_config("x.toml")
            .unwrap_err()
            .to_string()
            .contains("level"));
        let mut bad = s.clone();
        bad.site.pop();
        assert!(bad
            .pair_config("x.toml")
            .unwrap_err()
            .to_string()
            .contains("exactly two"));
        let mut bad = s.clone();
        bad.network.loss = 0.7;
        assert!(bad
            .pair_config("x.toml")
            .unwrap_err()
            .to_string()
            .contains("loss"));
        let mut bad = s.clone();
        bad.material.stiffness_modulus_pa = -1.0;
        assert!(bad
            .pair_config("x.toml")
            .unwrap_err()
            .to_string()
            .contains("stiffness_modulus_pa"));
        let mut bad = s;
        bad.duration_s = f64::INFINITY;
        assert!(bad
            .pair_config("x.toml")
            .unwrap_err()
            .to_string()
            .contains("duration_s"));
    }
}
