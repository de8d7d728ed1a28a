//! What a site reports at the end of a pair run, in one shape for every
//! mode: a real-time site ([`super::realtime`]) fills every part, a site
//! of a virtual run ([`super::pair`]) the link, emulator and replica parts
//! only. The records are serialisable: `softjoint tetmsd pair` prints them
//! as JSON, and a site started as a child process hands its report to the
//! parent as JSON on standard output.
use super::link::LinkStats;
use super::netem::NetemStats;
use super::pair::PairReport;
use super::replica::{LagHistogram, ReplicaStats};
use crate::model::V3;
use serde::{Deserialize, Serialize};

/// A vector as the three numbers the reports carry.
pub(crate) fn arr(v: V3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// One row of a site's force trace.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
pub struct ForceRow {
    /// Tick.
    pub tick: u64,
    /// Stylus (m).
    pub tip_m: [f64; 3],
    /// Felt force (N).
    pub force_n: [f64; 3],
    /// In contact.
    pub contact: bool,
}

/// The haptic loop's timing.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct HapticTiming {
    /// Ticks run.
    pub ticks: u64,
    /// Ticks whose work started ≥ 1 ms after their deadline.
    pub missed_ticks: u64,
    /// Lateness of the tick start after its deadline (µs): median.
    pub late_p50_us: f64,
    /// 99th percentile.
    pub late_p99_us: f64,
    /// 99.9th percentile.
    pub late_p999_us: f64,
    /// Largest.
    pub late_max_us: f64,
    /// Mean work per tick (µs).
    pub work_mean_us: f64,
    /// Largest work of one tick (µs).
    pub work_max_us: f64,
    /// Ticks that found the shape locked and used the previous one.
    pub lock_busy: u64,
    /// Inputs that waited in the backlog because a channel was full.
    pub backlogged: u64,
    /// Busy-wait before each deadline (µs).
    pub spin_us: u64,
    /// The haptic thread's scheduling: `normal`, `SCHED_FIFO N`, or why
    /// the real-time priority was refused.
    pub scheduling: String,
}

/// The deformation thread's work.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct DeformationTiming {
    /// Shapes published.
    pub updates: u64,
    /// Published shapes per second of run time.
    pub updates_per_s: f64,
    /// Replica ticks computed (committed + speculative + recomputed).
    pub ticks_computed: u64,
    /// Replica ticks per second of busy time.
    pub ticks_per_busy_s: f64,
    /// Fraction of the run time the thread was busy.
    pub busy_fraction: f64,
}

/// The display thread's frames.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct DisplayTiming {
    /// Frames taken.
    pub frames: u64,
    /// Mean age of the shape shown (ms behind the haptic tick).
    pub age_mean_ms: f64,
    /// Largest age (ms).
    pub age_max_ms: f64,
}

/// Serializable link counters.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct LinkSummary {
    /// Inputs sent once.
    pub inputs_sent: u64,
    /// Inputs sent again.
    pub retransmissions: u64,
    /// Of those, resent because a later tick arrived first.
    pub fast_retransmissions: u64,
    /// Of those, resent when the timeout ran out.
    pub timeout_retransmissions: u64,
    /// Resends found needless afterwards.
    pub needless_resends: u64,
    /// Ack-only packets.
    pub acks_sent: u64,
    /// Peer inputs received.
    pub inputs_received: u64,
    /// Duplicates (late originals, spurious resends).
    pub duplicates: u64,
    /// Dropped for being beyond the window.
    pub beyond_window: u64,
    /// Peer ticks seen missing.
    pub gaps_seen: u64,
    /// Of those, filled later.
    pub gaps_filled: u64,
    /// Refused packets.
    pub malformed: u64,
    /// Refused packets by reason (only non-zero ones).
    pub malformed_by_reason: Vec<(String, u64)>,
    /// Round trip min / mean / max (µs) from acknowledgements.
    pub rtt_min_us: u64,
    /// Mean round trip (µs).
    pub rtt_mean_us: f64,
    /// Largest round trip (µs).
    pub rtt_max_us: u64,
    /// Round-trip samples.
    pub rtt_samples: u64,
    /// Smoothed round trip at the end (µs).
    pub srtt_us: f64,
    /// Reordering window at the end (µs).
    pub reorder_window_us: u64,
    /// Datagrams the socket refused to send.
    pub send_errors: u64,
    /// The network thread's scheduling (`normal` or `SCHED_FIFO N`).
    pub scheduling: String,
    /// Copies of earlier inputs sent in new input packets.
    #[serde(default)]
    pub copies_sent: u64,
    /// Bytes of those copies (56 each).
    #[serde(default)]
    pub copy_bytes: u64,
    /// Bytes of every datagram sent (version 2 would have sent this less
    /// `copy_bytes`).
    #[serde(default)]
    pub bytes_sent: u64,
    /// Peer inputs that came first in a copy.
    #[serde(default)]
    pub inputs_from_copies: u64,
    /// Copies of peer inputs already there.
    #[serde(default)]
    pub copies_redundant: u64,
}

impl From<&LinkStats> for LinkSummary {
    fn from(s: &LinkStats) -> Self {
        LinkSummary {
            inputs_sent: s.inputs_sent,
            retransmissions: s.retransmissions,
            fast_retransmissions: s.fast_retransmissions,
            timeout_retransmissions: s.timeout_retransmissions,
            needless_resends: s.needless_resends,
            acks_sent: s.acks_sent,
            inputs_received: s.inputs_received,
            duplicates: s.duplicates,
            beyond_window: s.beyond_window,
            gaps_seen: s.gaps_seen,
            gaps_filled: s.gaps_filled,
            malformed: s.malformed.total(),
            malformed_by_reason: s
                .malformed
                .by_reason()
                .filter(|(_, n)| *n > 0)
                .map(|(k, n)| (k.to_string(), n))
                .collect(),
            rtt_min_us: s.rtt_min_us,
            rtt_mean_us: s.rtt_mean_us(),
            rtt_max_us: s.rtt_max_us,
            rtt_samples: s.rtt_samples,
            srtt_us: s.srtt_us,
            reorder_window_us: s.reorder_window_us,
            send_errors: 0,
            scheduling: "virtual".into(),
            copies_sent: s.copies_sent,
            copy_bytes: s.copy_bytes(),
            bytes_sent: s.bytes_sent,
            inputs_from_copies: s.inputs_from_copies,
            copies_redundant: s.copies_redundant,
        }
    }
}

/// Serializable emulator counters.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct NetemSummary {
    /// Offered packets.
    pub offered: u64,
    /// Lost at random.
    pub lost: u64,
    /// Dropped by a full queue.
    pub overflowed: u64,
    /// Held 1–3 ms extra.
    pub held_extra: u64,
    /// Delivered.
    pub delivered: u64,
    /// Largest queue.
    pub max_queued: usize,
    /// Largest one-way delay (µs).
    pub max_delay_us: u64,
    /// Input packets offered.
    pub inputs_offered: u64,
    /// Input packets lost.
    pub inputs_lost: u64,
    /// Inputs really lost: every packet carrying the tick lost (see
    /// `NetemStats::input_ticks_lost`), what the sender had to resend.
    #[serde(default)]
    pub input_ticks_lost: u64,
    /// Mean one-way delay of the inputs passed (µs).
    pub input_delay_mean_us: f64,
}

impl From<&NetemStats> for NetemSummary {
    fn from(s: &NetemStats) -> Self {
        NetemSummary {
            offered: s.offered,
            lost: s.lost,
            overflowed: s.overflowed,
            held_extra: s.held_extra,
            delivered: s.delivered,
            max_queued: s.max_queued,
            max_delay_us: s.max_delay_us,
            inputs_offered: s.inputs_offered,
            inputs_lost: s.inputs_lost,
            input_ticks_lost: s.input_ticks_lost,
            input_delay_mean_us: s.input_delay_mean_us(),
        }
    }
}

/// Serializable replica measurements.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct ReplicaSummary {
    /// Displayed frames compared with the committed replica.
    pub frames_checked: u64,
    /// Frames dropped before the committed replica got there.
    pub frames_unchecked: u64,
    /// Largest divergence of a displayed frame from the committed one (mm).
    pub divergence_max_mm: f64,
    /// 99th percentile (mm).
    pub divergence_p99_mm: f64,
    /// Mean (mm).
    pub divergence_mean_mm: f64,
    /// Rebases of the speculation.
    pub rebases: u64,
    /// Ticks recomputed.
    pub recomputed_ticks: u64,
    /// Peer inputs that differed from their prediction.
    pub mispredictions: u64,
    /// Largest jump at a rebase (mm).
    pub rebase_jump_max_mm: f64,
    /// Largest gap speculative − committed (ticks).
    pub lag_max_ticks: u64,
    /// The committed replica's lag behind the present, per tick: median
    /// (ms).
    pub lag_p50_ms: u64,
    /// 99th percentile (ms).
    pub lag_p99_ms: u64,
    /// Mean (ms).
    pub lag_mean_ms: f64,
    /// Restarted peers this site re-synchronised.
    pub resyncs: u64,
    /// (tick, divergence mm) of every checked frame.
    pub divergence_series: Vec<(u64, f64)>,
}

impl From<&ReplicaStats> for ReplicaSummary {
    fn from(s: &ReplicaStats) -> Self {
        ReplicaSummary {
            frames_checked: s.frames_checked,
            frames_unchecked: s.frames_unchecked,
            divergence_max_mm: s.max_divergence_m() * 1e3,
            divergence_p99_mm: s.divergence_quantile_m(0.99) * 1e3,
            divergence_mean_mm: s.mean_divergence_m() * 1e3,
            rebases: s.rebases,
            recomputed_ticks: s.recomputed_ticks,
            mispredictions: s.mispredictions,
            rebase_jump_max_mm: s.max_rebase_jump_m * 1e3,
            lag_max_ticks: s.max_lag_ticks,
            lag_p50_ms: s.lag.quantile_ticks(0.5),
            lag_p99_ms: s.lag.quantile_ticks(0.99),
            lag_mean_ms: s.lag.mean_ticks(),
            resyncs: s.resyncs,
            divergence_series: s.divergence.iter().map(|(t, d)| (*t, d * 1e3)).collect(),
        }
    }
}

impl ReplicaSummary {
    /// The lag figures from a histogram filled elsewhere (the haptic
    /// thread of a real-time site).
    pub fn set_lag(&mut self, lag: &LagHistogram) {
        self.lag_p50_ms = lag.quantile_ticks(0.5);
        self.lag_p99_ms = lag.quantile_ticks(0.99);
        self.lag_mean_ms = lag.mean_ticks();
        self.lag_max_ticks = self.lag_max_ticks.max(lag.max_ticks());
    }
}

/// How the session ended for a real-time site: both sites' tick counts,
/// the end tick, and the hashes of both committed replicas there.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct EndReport {
    /// Why this site stopped.
    pub reason: String,
    /// Ticks this site made.
    pub own_ticks: u64,
    /// Ticks the peer made (from its bye).
    pub peer_ticks: Option<u64>,
    /// Why the peer stopped.
    pub peer_reason: Option<String>,
    /// The session's end tick (the smaller count).
    pub end_tick: Option<u64>,
    /// This site's committed hash there (hex).
    pub own_hash: Option<String>,
    /// The peer's, from its bye (hex).
    pub peer_hash: Option<String>,
    /// Whether the two agree (`None`: the peer's never came).
    pub peer_confirmed: Option<bool>,
}

/// What a site reports at the end.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct SiteReport {
    /// 0 or 1.
    pub site: u8,
    /// Haptic loop timing (absent in virtual runs).
    pub haptic: Option<HapticTiming>,
    /// Deformation thread (absent in virtual runs).
    pub deformation: Option<DeformationTiming>,
    /// Display thread (absent in virtual runs).
    pub display: Option<DisplayTiming>,
    /// Link counters.
    pub link: LinkSummary,
    /// Outgoing emulator counters.
    pub netem: NetemSummary,
    /// Replica measurements.
    pub replica: ReplicaSummary,
    /// Committed tick at the end.
    pub committed_tick: u64,
    /// Hash of the final committed replica.
    pub final_hash: u64,
    /// Final committed positions (m), for comparing the sites.
    pub final_x_m: Vec<[f64; 3]>,
    /// Displayed shape where this user pushed hardest (m).
    pub peak_x_m: Vec<[f64; 3]>,
    /// Force trace.
    pub trace: Vec<ForceRow>,
    /// Ticks in contact.
    pub contact_ticks: u64,
    /// Largest felt force (N).
    pub max_force_n: f64,
    /// How the session ended (real-time sites).
    pub end: Option<EndReport>,
    /// The tick this site joined a running session at (after a restart).
    pub joined_at_tick: Option<u64>,
    /// The handshake's round trip (µs).
    pub handshake_rtt_us: Option<u64>,
    /// What happened on the way (peers restarted, strangers refused).
    pub notes: Vec<String>,
}

/// A pair run's outcome in one shape for every mode.
#[derive(Clone, Debug, PartialEq)]
pub struct PairOutcome {
    /// `virtual`, `in-process` or `processes`.
    pub mode: &'static str,
    /// Site 0's and site 1's reports.
    pub sites: [SiteReport; 2],
    /// Largest gap between the two displays (virtual runs only).
    pub display_gap_max_mm: Option<f64>,
    /// Wall-clock time of the run (s).
    pub wall_s: f64,
}

impl PairOutcome {
    /// The two sites of a virtual run (`duration_ticks` of input) in the
    /// shape of real-time reports, without the timing parts.
    pub fn from_virtual(r: &PairReport, duration_ticks: u64) -> Self {
        let final_x: Vec<[f64; 3]> = r.final_state.x_m.iter().map(|p| arr(*p)).collect();
        let peak_x: Vec<[f64; 3]> = r.peak_state.x_m.iter().map(|p| arr(*p)).collect();
        let site = |s: usize| {
            let sm = &r.sites[s];
            SiteReport {
                site: s as u8,
                haptic: None,
                deformation: None,
                display: None,
                link: LinkSummary::from(&sm.link),
                netem: NetemSummary::from(&sm.netem),
                replica: ReplicaSummary::from(&sm.replica),
                committed_tick: duration_ticks,
                final_hash: sm.final_hash,
                // The virtual run compares the two replicas itself: both final
                // states are site 0's when they are identical.
                final_x_m: final_x.clone(),
                peak_x_m: peak_x.clone(),
                trace: r
                    .trace
                    .iter()
                    .map(|row| ForceRow {
                        tick: row.tick,
                        tip_m: arr(row.tip_m[s]),
                        force_n: arr(row.force_n[s]),
                        contact: row.contact[s],
                    })
                    .collect(),
                contact_ticks: sm.contact_ticks,
                max_force_n: sm.max_force_n,
                end: None,
                joined_at_tick: None,
                handshake_rtt_us: None,
                notes: Vec::new(),
            }
        };
        PairOutcome {
            mode: "virtual",
            sites: [site(0), site(1)],
            display_gap_max_mm: Some(r.max_display_gap_m * 1e3),
            wall_s: 0.0,
        }
    }

    /// Whether the two sites' final committed replicas agree bit for bit,
    /// and their largest node distance (m).
    pub fn compare_finals(&self) -> (bool, f64) {
        let [a, b] = &self.sites;
        let same = a.final_hash == b.final_hash
            && a.final_x_m.len() == b.final_x_m.len()
            && a.final_x_m
                .iter()
                .zip(&b.final_x_m)
                .all(|(p, q)| (0..3).all(|i| p[i].to_bits() == q[i].to_bits()));
        let dist = a
            .final_x_m
            .iter()
            .zip(&b.final_x_m)
            .map(|(p, q)| {
                ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
            })
            .fold(0.0, f64::max);
        (same, dist)
    }

    /// Bound on the gap between the two users' displays (mm): the sum of
    /// the two sites' largest divergences from the common committed
    /// replica.
    pub fn display_gap_bound_mm(&self) -> f64 {
        self.sites[0].replica.divergence_max_mm + self.sites[1].replica.divergence_max_mm
    }
}
