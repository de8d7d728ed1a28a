//! The link's figures on one emulated path, checked against the path
//! itself (issue 30's criteria): the emulator knows what it did to every
//! input — its one-way delay, whether it was dropped — so each figure the
//! link measures has an independent reference.
//!
//! - **Round trip**: the link's mean sample against the path's mean round
//!   trip, the mean one-way delay the emulator gave the inputs one way
//!   plus the mean it gave them the other way (the timestamp echoes ride
//!   on the inputs, and a sample leaves out the receiver's hold, which
//!   the echo states). Within 10 %.
//! - **Resends** against the inputs the emulator really dropped: at most
//!   1.2 × as many (with nothing dropped, none).
//! - **Committed lag** (the committed replica's distance behind the
//!   present, once per tick) at p99, against one round trip + 50 ms.
//! - **Replicas** bit-identical at the end.
//!
//! Resends are counted against the inputs *really* lost (every packet
//! carrying the input, its own and the copies in later packets, dropped:
//! `NetemStats::input_ticks_lost`); the packets dropped are reported
//! beside them. Without copies a lost input holds the committed replica
//! about one round trip plus one one-way delay behind
//! ([`PathFigures::loss_floor_ms`]); with K copies only a run of K + 1
//! lost packets does. The bytes sent per second, and how many of them
//! were copies, give the redundancy's cost against version 2.
use super::link::DEFAULT_REDUNDANCY;
use super::netem::{NetemConfig, Profile, TABLES};
use super::pair::{run_virtual, PairConfig, PairReport};
use super::scenario::Scenario;
use crate::error::Result;

/// One path of the table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathCase {
    /// Round trips.
    pub profile: Profile,
    /// Probability an input is lost.
    pub loss: f64,
    /// Probability an input is held 1–3 ms extra.
    pub reorder: f64,
}

impl PathCase {
    /// A label: the profile, loss and reordering.
    pub fn label(&self) -> String {
        format!(
            "{} loss {:.0} % reorder {:.0} %",
            self.profile.name(),
            100.0 * self.loss,
            100.0 * self.reorder
        )
    }
}

/// The full table: every paper profile at 0, 5 and 10 % loss and
/// reordering together, and fixed round trips of 10, 50, 100 and 200 ms at
/// every combination of 0, 1, 5, 10 % loss and 0, 5, 10 % reordering.
pub fn full_table() -> Vec<PathCase> {
    let mut out = Vec::new();
    for t in TABLES {
        for p in [0.0, 0.05, 0.10] {
            out.push(PathCase {
                profile: Profile::Paper(t),
                loss: p,
                reorder: p,
            });
        }
    }
    for rtt_ms in [10u64, 50, 100, 200] {
        for loss in [0.0, 0.01, 0.05, 0.10] {
            for reorder in [0.0, 0.05, 0.10] {
                out.push(PathCase {
                    profile: Profile::Constant(rtt_ms * 1000),
                    loss,
                    reorder,
                });
            }
        }
    }
    out
}

/// What one site measured and what the path was.
#[derive(Clone, Debug, PartialEq)]
pub struct SiteFigures {
    /// The link's mean round-trip sample (ms).
    pub rtt_measured_ms: f64,
    /// The path's mean round trip as the emulators gave it (ms).
    pub rtt_path_ms: f64,
    /// Round-trip samples taken.
    pub rtt_samples: u64,
    /// Inputs this site resent.
    pub resends: u64,
    /// This site's inputs the emulator really dropped: every packet
    /// carrying the tick (its own and the copies) lost
    /// (`NetemStats::input_ticks_lost`).
    pub lost: u64,
    /// Input packets the emulator dropped (each of them a loss version 2
    /// would have had to resend).
    pub packets_lost: u64,
    /// Bytes per second of session this site sent (every datagram).
    pub bytes_per_s: f64,
    /// Of those, the copies of earlier inputs: without them a site sends
    /// `bytes_per_s − copy_bytes_per_s` (version 2 sent that less the
    /// 12-byte timestamp echo of every input packet).
    pub copy_bytes_per_s: f64,
    /// The committed replica's lag at p99 (ms).
    pub lag_p99_ms: f64,
    /// The longest one-way delay the peer's inputs had (ms).
    pub peer_one_way_ms: f64,
}

/// One run's figures, both sites.
#[derive(Clone, Debug, PartialEq)]
pub struct PathFigures {
    /// The path.
    pub case: PathCase,
    /// Ticks with user input.
    pub ticks: u64,
    /// Per site.
    pub sites: [SiteFigures; 2],
    /// The final committed replicas are bit-identical.
    pub identical: bool,
}

impl PathFigures {
    /// The figures of a finished run on `case`.
    pub fn of(case: PathCase, ticks: u64, r: &PairReport) -> Self {
        let seconds = ticks as f64 / 1000.0;
        let site = |s: usize| {
            let (me, peer) = (&r.sites[s], &r.sites[1 - s]);
            SiteFigures {
                rtt_measured_ms: me.link.rtt_mean_us() / 1000.0,
                rtt_path_ms: (me.netem.input_delay_mean_us() + peer.netem.input_delay_mean_us())
                    / 1000.0,
                rtt_samples: me.link.rtt_samples,
                resends: me.link.retransmissions,
                lost: me.netem.input_ticks_lost,
                packets_lost: me.netem.inputs_lost,
                bytes_per_s: me.link.bytes_sent as f64 / seconds,
                copy_bytes_per_s: me.link.copy_bytes() as f64 / seconds,
                lag_p99_ms: me.replica.lag.quantile_ticks(0.99) as f64,
                peer_one_way_ms: peer.netem.input_delay_mean_us() / 1000.0,
            }
        };
        PathFigures {
            case,
            ticks,
            sites: [site(0), site(1)],
            identical: r.identical,
        }
    }

    /// The lag's bound: one round trip + 50 ms (ms).
    pub fn lag_bound_ms(&self, s: usize) -> f64 {
        self.sites[s].rtt_path_ms + 50.0
    }

    /// The lag an input lost with all its copies causes at least (ms): a
    /// round trip to learn of it, a one-way trip for the resend, the 5 ms
    /// reordering window and a tick.
    pub fn loss_floor_ms(&self, s: usize) -> f64 {
        let f = &self.sites[s];
        f.rtt_path_ms + f.peer_one_way_ms + 6.0
    }

    /// Every criterion this run misses, named with its figures (empty:
    /// all met).
    pub fn failures(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (s, f) in self.sites.iter().enumerate() {
            let err = (f.rtt_measured_ms - f.rtt_path_ms).abs() / f.rtt_path_ms;
            if f.rtt_samples == 0 || err > 0.10 {
                out.push(format!(
                    "site {s}: mean round trip {:.2} ms from {} samples, path {:.2} ms ({:.1} % off, limit 10 %)",
                    f.rtt_measured_ms,
                    f.rtt_samples,
                    f.rtt_path_ms,
                    100.0 * err
                ));
            }
            if f.resends as f64 > 1.2 * f.lost as f64 {
                out.push(format!(
                    "site {s}: {} resends for {} inputs really lost (limit 1.2 ×)",
                    f.resends, f.lost
                ));
            }
            if f.lag_p99_ms > self.lag_bound_ms(s) {
                out.push(format!(
                    "site {s}: committed lag p99 {:.0} ms over one round trip + 50 ms = {:.1} ms (a loss's floor is {:.1} ms)",
                    f.lag_p99_ms,
                    self.lag_bound_ms(s),
                    self.loss_floor_ms(s)
                ));
            }
        }
        if !self.identical {
            out.push("the final committed replicas differ".into());
        }
        out
    }

    /// One row of the table (Markdown).
    pub fn row(&self) -> String {
        let f = &self.sites;
        let ok = if self.failures().is_empty() {
            "yes".to_string()
        } else {
            "**no**".to_string()
        };
        format!(
            "| {} | {:.0} | {:.0} | {:.2} / {:.2} | {:.2} / {:.2} | {} / {} ({}) | {} / {} ({}) | {:.0} / {:.0} | {:.0} | {:.0} / {:.0} | {} | {} |",
            self.case.profile.name(),
            100.0 * self.case.loss,
            100.0 * self.case.reorder,
            f[0].rtt_measured_ms,
            f[0].rtt_path_ms,
            f[1].rtt_measured_ms,
            f[1].rtt_path_ms,
            f[0].resends,
            f[0].lost,
            f[0].packets_lost,
            f[1].resends,
            f[1].lost,
            f[1].packets_lost,
            f[0].lag_p99_ms,
            f[1].lag_p99_ms,
            self.lag_bound_ms(0),
            f[0].bytes_per_s / 1000.0,
            (f[0].bytes_per_s - f[0].copy_bytes_per_s) / 1000.0,
            if self.identical { "yes" } else { "**no**" },
            ok
        )
    }

    /// The table's header (Markdown).
    pub fn header() -> &'static str {
        "| path | loss % | reorder % | RTT site 0 measured / path (ms) | RTT site 1 | resends / inputs lost (packets lost) site 0 | site 1 | lag p99 site 0 / 1 (ms) | RTT + 50 ms | kB/s sent site 0 / without the copies | identical | all met |\n|---|---|---|---|---|---|---|---|---|---|---|---|"
    }
}

/// Runs `case` for `duration_s` of virtual time at `level` with `seed`
/// (the default scenario's users otherwise).
pub fn run_case(case: PathCase, level: u32, duration_s: f64, seed: u64) -> Result<PathFigures> {
    run_case_with(case, level, duration_s, seed, DEFAULT_REDUNDANCY)
}

/// [`run_case`] with `redundancy` copies per input packet (the link's K).
pub fn run_case_with(
    case: PathCase,
    level: u32,
    duration_s: f64,
    seed: u64,
    redundancy: usize,
) -> Result<PathFigures> {
    let s = Scenario {
        level,
        duration_s,
        seed,
        ..Scenario::default()
    };
    let mut cfg: PairConfig = s.pair_config("path table")?;
    cfg.netem = NetemConfig {
        profile: case.profile,
        loss: case.loss,
        reorder: case.reorder,
        ..cfg.netem
    };
    cfg.session.link.redundancy = redundancy;
    let r = run_virtual(&cfg)?;
    Ok(PathFigures::of(case, cfg.duration_ticks, &r))
}
