//! A network emulator in the packets' path: the seed's measured round-trip
//! profiles (Yamaguchi Tables 2–5, seed 000 L2724–2803), loss, extra
//! reordering and a bounded queue.
//!
//! **Replaying a table.** The seed gives, per trial, only the minimum,
//! average and maximum round trip over 10,000–25,000 frames (and a plot of
//! the first trial, not in the text). A profile here is five trials of
//! [`TRIAL_FRAMES`] frames (12 s at one frame per millisecond, inside the
//! seed's frame counts), one round trip per frame, built so that each
//! trial's minimum, mean and maximum are the table's to the microsecond:
//! a body of exponential excess over the minimum (the seed: "the average
//! times are almost same as the minimum times", L2764) scaled to the
//! trial's mean, capped below the maximum, and one frame at the maximum
//! (the rare outlier: up to 1,126,960 µs in Table 5). A 60 s run replays
//! the five trials once; longer runs repeat them. The body's shape and the
//! outlier's position are drawn from the seeded stream of the sending site
//! (see [`plant_common::rng::TETMSD_DELAY_BASE`]); the seed does not say how its
//! outliers cluster, so each is a single frame.
//!
//! **One way.** A packet sent at time t takes half the round trip of its
//! frame (⌊t / 1 ms⌋): the seed measured round trips only, and its two
//! directions are taken as equal. Each direction has its own series, so a
//! round trip in the session is the sum of two independent halves.
//!
//! **Loss, bursts, reordering and jitter** (beyond the tables: the seed
//! gives none of them). Each packet is lost with probability `loss`,
//! independently, or — with `burst_len` ≥ 1 — by a two-state (Gilbert)
//! chain that loses every packet in its bad state, leaves it with
//! probability `1/burst_len` per packet and enters it with probability
//! `loss/(burst_len·(1 − loss))`, so that the long-run loss is still
//! `loss` and a run of losses is `burst_len` packets long on average. With
//! probability `reorder` a packet is held 1–3 ms extra, and every packet
//! is delayed by a further uniform draw in `[0, jitter]`; delays that vary
//! by more than the 1 ms between packets reorder them (the tables' spread
//! is milliseconds too). The queue holds at most `capacity` packets; a
//! packet that finds it full is dropped and counted. The seed used TCP and
//! counted "only correct frames" (L2712), so it reports no loss rate: the
//! loss here is a parameter (default 1 %, an estimate for a loaded WAN).
//!
//! The emulator also keeps the truth a site cannot see, for checking what
//! the sites measure: how many *input* packets it lost and the mean
//! one-way delay it gave the inputs it passed.
use super::packet::Packet;
use crate::error::{check_range, Result};
use plant_common::rng;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Exp1};
use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap};

/// Frames per replayed trial: 12 s at one frame per millisecond.
pub const TRIAL_FRAMES: usize = 12_000;

/// One trial of a round-trip table (µs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Trial {
    /// Minimum round trip.
    pub min_us: u64,
    /// Average round trip.
    pub avg_us: u64,
    /// Maximum round trip.
    pub max_us: u64,
}

const fn trial(max_us: u64, min_us: u64, avg_us: u64) -> Trial {
    Trial {
        min_us,
        avg_us,
        max_us,
    }
}

/// A round-trip table of the seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PaperTable {
    /// Short name (`table2` …).
    pub name: &'static str,
    /// What was measured and where the table is.
    pub label: &'static str,
    /// The five trials.
    pub trials: [Trial; 5],
}

/// Table 2 (L2724–2726): RU-BKC ↔ Shiga Medical University, 2 km.
pub const TABLE_2: PaperTable = PaperTable {
    name: "table2",
    label: "Table 2 (L2724): RU-BKC - SMU, 2 km WAN",
    trials: [
        trial(30_139, 9_044, 11_943),
        trial(19_148, 9_798, 11_178),
        trial(23_024, 9_008, 11_103),
        trial(24_152, 8_964, 11_685),
        trial(17_211, 9_025, 11_116),
    ],
};

/// Table 3 (L2751–2753): RU-BKC ↔ Osaka University, Toyonaka, 52 km.
pub const TABLE_3: PaperTable = PaperTable {
    name: "table3",
    label: "Table 3 (L2751): RU-BKC - OU-TC, 52 km WAN",
    trials: [
        trial(53_143, 10_893, 13_110),
        trial(57_166, 10_891, 13_186),
        trial(57_153, 10_889, 13_183),
        trial(268_743, 11_020, 13_574),
        trial(87_133, 10_893, 13_120),
    ],
};

/// Table 4 (L2790–2796): three sites, OU-TC location A.
pub const TABLE_4: PaperTable = PaperTable {
    name: "table4",
    label: "Table 4 (L2790): three sites, OU-TC location A",
    trials: [
        trial(77_266, 11_886, 13_448),
        trial(684_837, 11_234, 16_191),
        trial(998_508, 11_022, 14_667),
        trial(36_133, 10_999, 13_978),
        trial(164_391, 11_854, 14_398),
    ],
};

/// Table 5 (L2799–2803): three sites, OU-TC location B.
pub const TABLE_5: PaperTable = PaperTable {
    name: "table5",
    label: "Table 5 (L2799): three sites, OU-TC location B",
    trials: [
        trial(83_307, 10_987, 12_753),
        trial(1_126_960, 11_016, 14_699),
        trial(618_546, 10_988, 13_595),
        trial(65_058, 10_880, 13_221),
        trial(65_206, 10_857, 13_479),
    ],
};

/// Every table, for `--profile` lookup.
pub const TABLES: [&PaperTable; 4] = [&TABLE_2, &TABLE_3, &TABLE_4, &TABLE_5];

/// Where the round trips come from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Profile {
    /// No delay (packets arrive in the tick they are sent).
    Zero,
    /// A fixed round trip (µs).
    Constant(u64),
    /// A replayed table.
    Paper(&'static PaperTable),
    /// A fixed round trip with one slow millisecond: packets sent during
    /// millisecond `at_ms` take `spike_rtt_us` (a single outlier frame, as
    /// in the tables, at a known time; for tests and experiments).
    Spike {
        /// The usual round trip (µs).
        rtt_us: u64,
        /// The slow millisecond.
        at_ms: u64,
        /// Its round trip (µs).
        spike_rtt_us: u64,
    },
}

impl Profile {
    /// By name: `none`, `table2` … `table5`, or `rtt-MS` (a fixed round
    /// trip of MS milliseconds).
    pub fn by_name(name: &str) -> Option<Profile> {
        if name == "none" {
            return Some(Profile::Zero);
        }
        if let Some(ms) = name.strip_prefix("rtt-") {
            return ms
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0 && *v <= 10_000.0)
                .map(|v| Profile::Constant((v * 1000.0).round() as u64));
        }
        TABLES
            .iter()
            .find(|t| t.name == name)
            .map(|t| Profile::Paper(t))
    }

    /// The name [`Profile::by_name`] reads.
    pub fn name(&self) -> String {
        match self {
            Profile::Zero => "none".into(),
            Profile::Constant(us) => format!("rtt-{}", *us as f64 / 1000.0),
            Profile::Paper(t) => t.name.into(),
            Profile::Spike {
                rtt_us,
                at_ms,
                spike_rtt_us,
            } => format!(
                "rtt-{} with {} at {at_ms} ms",
                *rtt_us as f64 / 1000.0,
                *spike_rtt_us as f64 / 1000.0
            ),
        }
    }
}

/// The round trips of one trial (µs, [`TRIAL_FRAMES`] of them) with the
/// trial's exact minimum and maximum and its mean to rounding.
pub fn trial_round_trips(t: &Trial, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let n = TRIAL_FRAMES;
    let (min, avg, max) = (t.min_us as f64, t.avg_us as f64, t.max_us as f64);
    let outlier = rng.gen_range(0..n);
    let draws: Vec<f64> = (0..n - 1).map(|_| Exp1.sample(rng)).collect();
    let lowest = draws.iter().copied().fold(f64::INFINITY, f64::min);
    let mut excess: Vec<f64> = draws.iter().map(|d| d - lowest).collect();
    // The body's excess over the minimum must sum to this.
    let target = n as f64 * avg - max - (n - 1) as f64 * min;
    // Cap the body at 90 % of the way to the maximum: scale, clamp the
    // frames above the cap, rescale the rest, until nothing is above it.
    let cap = 0.9 * (max - min);
    let mut fixed = vec![false; excess.len()];
    for _ in 0..50 {
        let fixed_sum: f64 = excess
            .iter()
            .zip(&fixed)
            .filter(|(_, f)| **f)
            .map(|(e, _)| *e)
            .sum();
        let free_sum: f64 = excess
            .iter()
            .zip(&fixed)
            .filter(|(_, f)| !**f)
            .map(|(e, _)| *e)
            .sum();
        let scale = if free_sum > 0.0 {
            (target - fixed_sum) / free_sum
        } else {
            1.0
        };
        let mut clamped = false;
        for (e, f) in excess.iter_mut().zip(fixed.iter_mut()) {
            if !*f {
                *e *= scale;
                if *e > cap {
                    *e = cap;
                    *f = true;
                    clamped = true;
                }
            }
        }
        if !clamped {
            break;
        }
    }
    let mut out: Vec<f64> = excess.iter().map(|e| min + e).collect();
    out.insert(outlier, max);
    out
}

/// The round trips of a whole table: its five trials one after another
/// (µs, one per millisecond of session time).
pub fn table_round_trips(table: &PaperTable, seed: u64, site: u8) -> Vec<f64> {
    let mut r = rng::stream(seed, rng::TETMSD_DELAY_BASE + u64::from(site & 1));
    table
        .trials
        .iter()
        .flat_map(|t| trial_round_trips(t, &mut r))
        .collect()
}

/// Emulator settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NetemConfig {
    /// Round trips.
    pub profile: Profile,
    /// Probability a packet is lost.
    pub loss: f64,
    /// Probability a packet is held 1–3 ms extra.
    pub reorder: f64,
    /// Packets the queue holds.
    pub capacity: usize,
    /// Extra one-way delay, uniform in `[0, jitter_us]` per packet (µs).
    pub jitter_us: u64,
    /// Mean length of a run of lost packets (Gilbert chain); 0: losses
    /// are independent.
    pub burst_len: f64,
}

impl Default for NetemConfig {
    fn default() -> Self {
        NetemConfig {
            profile: Profile::Zero,
            loss: 0.01,
            reorder: 0.01,
            capacity: 4096,
            jitter_us: 0,
            burst_len: 0.0,
        }
    }
}

impl NetemConfig {
    /// Checks the probabilities and the capacity.
    pub fn validate(&self) -> Result<()> {
        check_range("loss", self.loss, 0.0, 0.5, "must be in [0, 0.5]")?;
        check_range("reorder", self.reorder, 0.0, 1.0, "must be in [0, 1]")?;
        check_range(
            "capacity",
            self.capacity as f64,
            1.0,
            1e6,
            "must be 1 to 1,000,000 packets",
        )?;
        check_range(
            "jitter_ms",
            self.jitter_us as f64 / 1000.0,
            0.0,
            1000.0,
            "must be 0 to 1000 ms",
        )?;
        if self.burst_len != 0.0 {
            check_range(
                "burst_len",
                self.burst_len,
                1.0,
                1000.0,
                "must be 0 (independent losses) or 1 to 1000 packets",
            )?;
        }
        Ok(())
    }
}

/// Counters of one direction.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NetemStats {
    /// Packets given to the emulator.
    pub offered: u64,
    /// Dropped at random.
    pub lost: u64,
    /// Dropped because the queue was full.
    pub overflowed: u64,
    /// Held extra.
    pub held_extra: u64,
    /// Handed on.
    pub delivered: u64,
    /// Largest queue length.
    pub max_queued: usize,
    /// Largest one-way delay given (µs).
    pub max_delay_us: u64,
    /// Input packets (kind 0) given to the emulator.
    pub inputs_offered: u64,
    /// Input packets lost (at random or by a full queue).
    pub inputs_lost: u64,
    /// Inputs really lost, what the sender has to resend: ticks whose own
    /// packet and every copy of them in later packets were lost, and
    /// resends lost before any packet carrying the tick passed. Without
    /// copies (version 2, K = 0) this is [`NetemStats::inputs_lost`].
    pub input_ticks_lost: u64,
    /// Bytes of the input packets offered (their copies included).
    pub input_bytes_offered: u64,
    /// Input packets passed on.
    pub inputs_passed: u64,
    /// Sum of the one-way delays given to those (µs).
    pub input_delay_sum_us: u64,
}

impl NetemStats {
    /// Mean one-way delay of the inputs passed (µs), 0 without any.
    pub fn input_delay_mean_us(&self) -> f64 {
        if self.inputs_passed == 0 {
            0.0
        } else {
            self.input_delay_sum_us as f64 / self.inputs_passed as f64
        }
    }
}

/// What became of one input tick's packets.
#[derive(Clone, Copy, Debug, Default)]
struct Fate {
    /// Its own first packet was lost.
    own_lost: bool,
    /// Its own first packet or a copy of it passed.
    first_round_passed: bool,
    /// Any packet carrying it passed.
    passed: bool,
}

/// Ticks whose fate an emulator remembers behind the highest it saw: the
/// link's window (`link::WINDOW_TICKS`), beyond which nothing is resent.
const FATE_TICKS: u32 = 8192;

/// One direction of the emulated network.
#[derive(Clone, Debug)]
pub struct Emulator {
    config: NetemConfig,
    /// One-way delay per millisecond of session time; a table repeats,
    /// the other profiles keep their last entry.
    one_way_us: Vec<u64>,
    repeats: bool,
    rng: ChaCha8Rng,
    queue: BinaryHeap<Reverse<(u64, u64, Vec<u8>)>>,
    order: u64,
    /// Input ticks seen, and what became of their packets.
    fates: BTreeMap<u32, Fate>,
    /// The Gilbert chain is in its losing state.
    in_burst: bool,
    stats: NetemStats,
}

impl Emulator {
    /// The emulator of the packets site `site` sends in a run with `seed`.
    pub fn new(config: NetemConfig, seed: u64, site: u8) -> Result<Self> {
        config.validate()?;
        let one_way_us = match config.profile {
            Profile::Paper(t) => table_round_trips(t, seed, site)
                .iter()
                .map(|rtt| (rtt / 2.0).round() as u64)
                .collect(),
            Profile::Constant(rtt) => vec![rtt / 2],
            Profile::Zero => vec![0],
            Profile::Spike {
                rtt_us,
                at_ms,
                spike_rtt_us,
            } => {
                let mut v = vec![rtt_us / 2; at_ms as usize + 2];
                v[at_ms as usize] = spike_rtt_us / 2;
                v
            }
        };
        let repeats = matches!(config.profile, Profile::Paper(_));
        Ok(Emulator {
            config,
            one_way_us,
            repeats,
            rng: rng::stream(seed, rng::TETMSD_LOSS_BASE + u64::from(site & 1)),
            queue: BinaryHeap::new(),
            order: 0,
            fates: BTreeMap::new(),
            in_burst: false,
            stats: NetemStats::default(),
        })
    }

    /// The one-way delay of a packet sent at `now_us`.
    pub fn delay_at_us(&self, now_us: u64) -> u64 {
        let n = self.one_way_us.len();
        let frame = (now_us / 1000) as usize;
        let frame = if self.repeats {
            frame % n
        } else {
            frame.min(n - 1)
        };
        self.one_way_us[frame]
    }

    /// Counters.
    pub fn stats(&self) -> &NetemStats {
        &self.stats
    }

    /// Packets in flight.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    /// Whether the next packet is lost: an independent draw `u`, or a step
    /// of the Gilbert chain driven by `u`.
    fn loses(&mut self, u: f64) -> bool {
        let c = &self.config;
        if c.burst_len < 1.0 {
            return u < c.loss;
        }
        let leave = 1.0 / c.burst_len;
        let enter = c.loss * leave / (1.0 - c.loss);
        self.in_burst = if self.in_burst { u >= leave } else { u < enter };
        self.in_burst
    }

    /// Sends `packet` at `now_us`.
    pub fn push(&mut self, now_us: u64, packet: Vec<u8>) {
        self.stats.offered += 1;
        let input = packet.len() >= 28 && packet[27] & 0b111 == 0;
        self.stats.inputs_offered += u64::from(input);
        if input {
            self.stats.input_bytes_offered += packet.len() as u64;
        }
        // Draw every number for every packet so that one setting does
        // not shift the others' streams.
        let (lose, hold, extra, jitter) = (
            self.rng.gen::<f64>(),
            self.rng.gen::<f64>(),
            self.rng.gen_range(1_000..=3_000u64),
            self.rng.gen::<f64>(),
        );
        if self.loses(lose) {
            self.stats.lost += 1;
            self.stats.inputs_lost += u64::from(input);
            self.count_fate(&packet, false);
            return;
        }
        if self.queue.len() >= self.config.capacity {
            self.stats.overflowed += 1;
            self.stats.inputs_lost += u64::from(input);
            self.count_fate(&packet, false);
            return;
        }
        self.count_fate(&packet, true);
        let mut delay = self.delay_at_us(now_us);
        if hold < self.config.reorder {
            delay += extra;
            self.stats.held_extra += 1;
        }
        delay += (jitter * (self.config.jitter_us as f64 + 1.0)).floor() as u64;
        if input {
            self.stats.inputs_passed += 1;
            self.stats.input_delay_sum_us += delay;
        }
        self.stats.max_delay_us = self.stats.max_delay_us.max(delay);
        self.order += 1;
        self.queue
            .push(Reverse((now_us + delay, self.order, packet)));
        self.stats.max_queued = self.stats.max_queued.max(self.queue.len());
    }

    /// Counts what became of the input ticks `packet` carries (nothing
    /// if it is not an input packet): see [`NetemStats::input_ticks_lost`].
    fn count_fate(&mut self, packet: &[u8], passed: bool) {
        let Some((tick, copies)) = Packet::input_ticks(packet) else {
            return;
        };
        let lost = &mut self.stats.input_ticks_lost;
        for t in copies {
            // A copy rides behind its tick's own packet.
            if let Some(f) = self.fates.get_mut(&t) {
                if passed && !f.first_round_passed {
                    f.first_round_passed = true;
                    *lost -= u64::from(f.own_lost);
                }
                f.passed |= passed;
            }
        }
        match self.fates.get_mut(&tick) {
            Some(f) => {
                // A resend.
                if !passed && !f.passed {
                    *lost += 1;
                }
                f.passed |= passed;
            }
            None => {
                *lost += u64::from(!passed);
                self.fates.insert(
                    tick,
                    Fate {
                        own_lost: !passed,
                        first_round_passed: passed,
                        passed,
                    },
                );
                if self.fates.len() > 2 * FATE_TICKS as usize {
                    let keep = self.fates.split_off(&tick.saturating_sub(FATE_TICKS));
                    self.fates = keep;
                }
            }
        }
    }

    /// The next packet due by `now_us`, earliest first.
    pub fn pop_due(&mut self, now_us: u64) -> Option<Vec<u8>> {
        match self.queue.peek() {
            Some(Reverse((t, _, _))) if *t <= now_us => {
                self.stats.delivered += 1;
                self.queue.pop().map(|Reverse((_, _, p))| p)
            }
            _ => None,
        }
    }

    /// When the next packet is due (µs), if any is in flight.
    pub fn next_due_us(&self) -> Option<u64> {
        self.queue.peek().map(|Reverse((t, _, _))| *t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_replayed_trial_has_the_tables_minimum_mean_and_maximum() {
        for table in TABLES {
            for site in 0..2 {
                let rtt = table_round_trips(table, 7, site);
                assert_eq!(rtt.len(), 5 * TRIAL_FRAMES);
                for (k, t) in table.trials.iter().enumerate() {
                    let s = &rtt[k * TRIAL_FRAMES..(k + 1) * TRIAL_FRAMES];
                    let min = s.iter().copied().fold(f64::INFINITY, f64::min);
                    let max = s.iter().copied().fold(0.0, f64::max);
                    let mean = s.iter().sum::<f64>() / s.len() as f64;
                    let tag = format!("{} trial {} site {site}", table.name, k + 1);
                    assert_eq!(min, t.min_us as f64, "{tag}");
                    assert_eq!(max, t.max_us as f64, "{tag}");
                    assert!((mean - t.avg_us as f64).abs() < 1e-6, "{tag}: mean {mean}");
                    // One outlier; the body stays below 90 % of the way up.
                    let high = s
                        .iter()
                        .filter(|v| {
                            **v > t.min_us as f64 + 0.9 * (t.max_us - t.min_us) as f64 + 1e-6
                        })
                        .count();
                    assert_eq!(high, 1, "{tag}");
                }
            }
        }
        // The one-way delays of the emulator are the halves, to a µs.
        let cfg = NetemConfig {
            profile: Profile::Paper(&TABLE_4),
            ..NetemConfig::default()
        };
        let e = Emulator::new(cfg, 7, 1).unwrap();
        let rtt = table_round_trips(&TABLE_4, 7, 1);
        let worst = (0..60_000u64)
            .map(|k| e.delay_at_us(k * 1000))
            .max()
            .unwrap();
        assert_eq!(worst, 499_254, "Table 4's worst round trip, halved");
        for k in [0, 1234, 59_999] {
            assert!((e.delay_at_us(k * 1000) as f64 - rtt[k as usize] / 2.0).abs() <= 0.5);
        }
    }

    #[test]
    fn loss_reordering_and_the_bounded_queue() {
        let cfg = NetemConfig {
            profile: Profile::Constant(10_000),
            loss: 0.1,
            reorder: 0.2,
            capacity: 100,
            ..NetemConfig::default()
        };
        let mut e = Emulator::new(cfg, 3, 0).unwrap();
        let mut got = Vec::new();
        for k in 0..20_000u64 {
            let mut p = [0u8; 64];
            p[..8].copy_from_slice(&k.to_le_bytes());
            e.push(k * 1000, p.to_vec());
            while let Some(q) = e.pop_due(k * 1000) {
                got.push(u64::from_le_bytes(q[..8].try_into().unwrap()));
            }
        }
        let s = *e.stats();
        assert!((s.lost as f64 / 20_000.0 - 0.1).abs() < 0.01, "{s:?}");
        assert!(
            (s.held_extra as f64 / s.offered as f64 - 0.18).abs() < 0.02,
            "{s:?}"
        );
        let out_of_order = got.windows(2).filter(|w| w[1] < w[0]).count();
        assert!(out_of_order > 1000, "{out_of_order}");
        assert!(s.max_queued <= 100 && s.overflowed == 0);
        // A tiny queue overflows, and says so.
        let mut tiny = Emulator::new(
            NetemConfig {
                capacity: 2,
                loss: 0.0,
                ..cfg
            },
            3,
            0,
        )
        .unwrap();
        for k in 0..10 {
            tiny.push(k, vec![0; 64]);
        }
        assert_eq!(tiny.stats().overflowed, 8);
        assert!(Emulator::new(NetemConfig { loss: 0.9, ..cfg }, 3, 0).is_err());
        assert_eq!(Profile::by_name("table4"), Some(Profile::Paper(&TABLE_4)));
        assert_eq!(
            Profile::by_name("rtt-12.5"),
            Some(Profile::Constant(12_500))
        );
        assert_eq!(Profile::by_name("table9"), None);
        assert_eq!(Profile::by_name("rtt-x"), None);
    }

    /// Inputs (kind byte 0) numbered by their first eight bytes.
    fn numbered(k: u64) -> Vec<u8> {
        let mut p = vec![0u8; 64];
        p[..8].copy_from_slice(&k.to_le_bytes());
        p
    }

    #[test]
    fn bursts_keep_the_loss_rate_and_have_their_mean_length() {
        // The Gilbert chain: long-run loss `loss`, runs of mean `burst_len`
        // (a geometric law with that mean), against 200,000 packets.
        for (loss, burst) in [(0.05, 4.0), (0.1, 10.0), (0.02, 1.0)] {
            let cfg = NetemConfig {
                profile: Profile::Constant(2_000),
                loss,
                reorder: 0.0,
                capacity: 1_000_000,
                burst_len: burst,
                ..NetemConfig::default()
            };
            let mut e = Emulator::new(cfg, 11, 1).unwrap();
            let n = 200_000u64;
            let mut passed = vec![false; n as usize];
            for k in 0..n {
                e.push(k * 1000, numbered(k));
                while let Some(q) = e.pop_due(k * 1000) {
                    passed[u64::from_le_bytes(q[..8].try_into().unwrap()) as usize] = true;
                }
            }
            while let Some(q) = e.pop_due(u64::MAX) {
                passed[u64::from_le_bytes(q[..8].try_into().unwrap()) as usize] = true;
            }
            let s = *e.stats();
            let rate = s.lost as f64 / n as f64;
            assert!((rate - loss).abs() < 0.15 * loss, "{loss} {burst}: {rate}");
            assert_eq!(s.inputs_lost, s.lost);
            assert_eq!(s.inputs_passed + s.inputs_lost, n);
            let runs = passed.windows(2).filter(|w| w[0] && !w[1]).count();
            let mean_run = s.lost as f64 / runs as f64;
            assert!(
                (mean_run - burst).abs() < 0.1 * burst,
                "{loss} {burst}: runs of {mean_run}"
            );
        }
        let bad = NetemConfig {
            burst_len: 0.5,
            ..NetemConfig::default()
        };
        assert!(bad
            .validate()
            .unwrap_err()
            .to_string()
            .contains("burst_len"));
    }

    #[test]
    fn jitter_is_uniform_and_the_input_delays_are_counted() {
        let cfg = NetemConfig {
            profile: Profile::Constant(20_000),
            loss: 0.0,
            reorder: 0.0,
            capacity: 1_000_000,
            jitter_us: 8_000,
            ..NetemConfig::default()
        };
        let mut e = Emulator::new(cfg, 5, 0).unwrap();
        for k in 0..100_000u64 {
            e.push(k * 1000, numbered(k));
        }
        // An ack (kind 2) is not an input.
        let mut ack = [0u8; 64];
        ack[27] = 2;
        e.push(0, ack.to_vec());
        let s = *e.stats();
        assert_eq!((s.inputs_offered, s.inputs_passed), (100_000, 100_000));
        // 10 ms one way plus uniform [0, 8] ms: mean 14 ms, at most 18 ms.
        assert!((s.input_delay_mean_us() - 14_000.0).abs() < 30.0, "{s:?}");
        assert!(s.max_delay_us <= 18_000 && s.max_delay_us > 17_990, "{s:?}");
    }
}
