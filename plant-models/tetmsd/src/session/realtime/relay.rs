//! The path emulator as a UDP relay process between two sites: the sites
//! see only sockets (each one's peer address is the relay), and the relay
//! gives each direction the emulator's delay, jitter, loss, reordering
//! and bursts ([`crate::session::netem::Emulator`], one per direction with
//! its own seeded stream). It stands in for `tc netem` where the kernel
//! lacks it — between two network namespaces in CI, or between two
//! machines.
//!
//! Side A's socket faces one site, side B's the other: a datagram from
//! A's site goes out of B's socket to B's site after its emulated delay,
//! and the reverse. A side's site address is given or learnt from the
//! first datagram that arrives on its socket (a restarted site that binds
//! a new port is learnt again). Datagrams shorter than 64 bytes or longer
//! than an input with 16 copies (972 bytes) are not packets of this
//! protocol: counted and dropped.
//!
//! Timing is the relay's own clock (µs since it started); it sleeps
//! [`super::NET_POLL_US`] when nothing is due, so a delay is given to
//! that resolution plus the scheduler's. What the relay reports is what
//! it did — the mean one-way delay it gave the inputs each way and the
//! inputs it dropped — the reference against which a site's measured
//! round trip and resends are checked.
use super::{io_error, NET_POLL_US};
use crate::error::{Result, TetError};
use crate::session::netem::{Emulator, NetemConfig};
use crate::session::packet::{MAX_DATAGRAM_BYTES, PACKET_BYTES};
use crate::session::report::NetemSummary;
use serde::{Deserialize, Serialize};
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// What a relay needs.
#[derive(Debug)]
pub struct RelaySetup {
    /// The socket facing site A.
    pub a: UdpSocket,
    /// The socket facing site B.
    pub b: UdpSocket,
    /// Site A's address (`None`: learnt from its first datagram).
    pub a_site: Option<SocketAddr>,
    /// Site B's address.
    pub b_site: Option<SocketAddr>,
    /// The emulated path (both directions).
    pub netem: NetemConfig,
    /// Seed of the two emulators (A→B is stream 0, B→A stream 1).
    pub seed: u64,
    /// Stop once traffic has started and then nothing came for this long.
    pub idle_exit: Duration,
    /// Stop after this long in any case.
    pub max_run: Duration,
    /// Non-zero when the user asks the relay to stop (SIGINT, SIGTERM).
    pub stop: Arc<AtomicUsize>,
}

/// What a relay did.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct RelayReport {
    /// The path's name (`rtt-40`, `table2`, …).
    pub profile: String,
    /// Loss probability per packet.
    pub loss: f64,
    /// Probability a packet is held 1–3 ms extra.
    pub reorder: f64,
    /// Jitter (ms).
    pub jitter_ms: f64,
    /// Mean loss burst length (0: independent).
    pub burst_len: f64,
    /// Packets from site A towards site B.
    pub a_to_b: NetemSummary,
    /// Packets from site B towards site A.
    pub b_to_a: NetemSummary,
    /// How late, on average, the relay sent the inputs from A after their
    /// emulated delay ran out (µs): its own scheduling, part of the path
    /// the sites saw.
    pub a_to_b_late_mean_us: f64,
    /// The same from B.
    pub b_to_a_late_mean_us: f64,
    /// The mean round trip the relay gave the inputs — one way plus the
    /// other, each the emulated delay plus the relay's lateness (ms). The
    /// sites' samples leave out the receiver's hold (the timestamp echo
    /// says it), so none is added.
    pub path_rtt_ms: f64,
    /// Datagrams shorter than 64 or longer than 972 bytes (dropped).
    pub not_packets: u64,
    /// Datagrams due to a side whose site was not known yet (dropped).
    pub no_destination: u64,
    /// Site addresses learnt (more than one per side: a site restarted
    /// on another port).
    pub sites_learnt: u64,
    /// How long the relay ran (s).
    pub run_s: f64,
}

/// One direction: the socket datagrams arrive on, the emulator, the
/// socket they leave from and where to.
struct Side {
    socket: UdpSocket,
    site: Option<SocketAddr>,
}

fn nonblocking(s: &UdpSocket) -> Result<()> {
    s.set_nonblocking(true)
        .map_err(io_error("cannot make the relay's socket non-blocking"))
}

/// Runs the relay until it is idle, stopped or out of time.
pub fn run_relay(setup: RelaySetup) -> Result<RelayReport> {
    nonblocking(&setup.a)?;
    nonblocking(&setup.b)?;
    let mut sides = [
        Side {
            socket: setup.a,
            site: setup.a_site,
        },
        Side {
            socket: setup.b,
            site: setup.b_site,
        },
    ];
    // emulators[s]: what arrived on side s, towards the other side.
    let mut emulators = [
        Emulator::new(setup.netem, setup.seed, 0)?,
        Emulator::new(setup.netem, setup.seed, 1)?,
    ];
    let mut report = RelayReport::default();
    let start = Instant::now();
    let mut last_heard: Option<Instant> = None;
    let mut buf = [0u8; 2048];
    // Summed lateness of the inputs released, per direction (µs).
    let mut late = [0.0f64; 2];
    loop {
        if setup.stop.load(Ordering::Relaxed) != 0
            || start.elapsed() >= setup.max_run
            || last_heard.is_some_and(|t| t.elapsed() >= setup.idle_exit)
        {
            break;
        }
        let mut busy = false;
        for s in 0..2 {
            while let Ok((len, from)) = sides[s].socket.recv_from(&mut buf) {
                busy = true;
                last_heard = Some(Instant::now());
                if sides[s].site != Some(from) {
                    sides[s].site = Some(from);
                    report.sites_learnt += 1;
                }
                if !(PACKET_BYTES..=MAX_DATAGRAM_BYTES).contains(&len) {
                    report.not_packets += 1;
                    continue;
                }
                let packet = buf[..len].to_vec();
                let now_us = start.elapsed().as_micros() as u64;
                emulators[s].push(now_us, packet);
            }
        }
        let now_us = start.elapsed().as_micros() as u64;
        for s in 0..2 {
            let to = 1 - s;
            while let Some(due_us) = emulators[s].next_due_us().filter(|t| *t <= now_us) {
                let Some(p) = emulators[s].pop_due(now_us) else {
                    break;
                };
                busy = true;
                if p[27] & 0b111 == 0 {
                    late[s] += (now_us - due_us) as f64;
                }
                match sides[to].site {
                    Some(addr) => {
                        sides[to].socket.send_to(&p, addr).map_err(|e| {
                            TetError::Site(format!("the relay cannot send to {addr}: {e}"))
                        })?;
                    }
                    None => report.no_destination += 1,
                }
            }
        }
        if !busy {
            std::thread::sleep(Duration::from_micros(NET_POLL_US));
        }
    }
    let n = &setup.netem;
    report.profile = n.profile.name();
    report.loss = n.loss;
    report.reorder = n.reorder;
    report.jitter_ms = n.jitter_us as f64 / 1000.0;
    report.burst_len = n.burst_len;
    report.a_to_b = NetemSummary::from(emulators[0].stats());
    report.b_to_a = NetemSummary::from(emulators[1].stats());
    let passed = |e: &Emulator| e.stats().inputs_passed.max(1) as f64;
    report.a_to_b_late_mean_us = late[0] / passed(&emulators[0]);
    report.b_to_a_late_mean_us = late[1] / passed(&emulators[1]);
    report.path_rtt_ms = (report.a_to_b.input_delay_mean_us
        + report.a_to_b_late_mean_us
        + report.b_to_a.input_delay_mean_us
        + report.b_to_a_late_mean_us)
        / 1000.0;
    report.run_s = start.elapsed().as_secs_f64();
    Ok(report)
}
