//! The real-time runtime of one tetmsd site (seed 000, Yamaguchi §5.2):
//! four threads and a UDP socket around the pure session logic of
//! `plant_tetmsd::session`.
//!
//! * **Network** (this thread first): the handshake ([`super::control`])
//!   over the socket until the session starts — a new one, or a running one
//!   joined by state transfer — then the link (acks, resends), the
//!   emulator in the sending path when one is set, state transfers to a
//!   restarted peer, the status line and the bye of both sides.
//! * **Haptic, 1 kHz** (the seed's haptic thread, L2667): reads the
//!   scripted stylus, decides the grip on the latest published shape
//!   (Eq. 3), computes the felt force from the latest published reaction
//!   (first-order local model) and hands the tick's manipulation to the
//!   other threads. It never waits: the shape is taken with `try_lock`
//!   (the previous one is kept if the lock is busy) and the manipulation
//!   goes out with `try_send` into bounded channels, with a bounded local
//!   backlog if they are full (a full backlog stops the session by name).
//!   Deadlines are absolute (the session clock the handshake agreed); a
//!   late tick is not skipped but run at once, and its lateness recorded.
//!   A tick whose work starts a whole period (1 ms) or more after its
//!   deadline is a *missed* tick. It also counts the committed replica's
//!   lag every tick. With `rt_priority` it runs on SCHED_FIFO at that
//!   priority, and the network thread one below it.
//! * **Deformation** (the seed's OpenGL thread's deformation, L2661–2664):
//!   feeds local and peer inputs to the replicas, advances them as far as
//!   it can, publishes the speculative shape and the held node's reaction,
//!   and computes the state a restarted peer starts from.
//! * **Display, 30 Hz** (L2665): takes the published shape as a renderer
//!   would, counts frames and how old the shape was, and keeps the frame
//!   where the user pushed hardest for the picture.
//!
//! **Ending.** A site stops making inputs when its duration is over, its
//! user asks (the `stop` flag: SIGINT, SIGTERM) or the peer says it stops;
//! it says so (bye "stopping", with its tick count). The session ends at
//! the smaller of the two counts: each site commits up to there, sends bye
//! "done" with the committed replica's hash, and leaves once it has the
//! peer's — so each site reports whether the two replicas ended
//! bit-identical, from the peer's own word.
//!
//! Timing is whatever the machine gives: on a shared machine the haptic
//! loop's lateness is measured and reported, never assumed.
//!
//! The parts: [`threads`] (haptic, deformation, display), [`network`]
//! (handshake and the network thread), [`relay`] (the path emulator as a
//! UDP relay process between two sites, for `tetmsd relay`); the report
//! they fill is [`super::report::SiteReport`]. The pure session logic they drive is
//! tested deterministically in [`super::pair`], [`super::link`] and
//! [`super::control`]; this module is tested over real sockets by
//! host-tools' `tetmsd_cli` (and across two network namespaces).
//!
//! Errors are the crate's [`TetError`]: a thread, socket or peer failure
//! is [`TetError::Site`] with the words that name it.
mod network;
mod relay;
mod threads;

use super::pair::{Haptic, PairConfig, SessionConfig};
use super::replica::{LagHistogram, Replicas};
use super::report::{arr, DisplayTiming, LinkSummary, NetemSummary, ReplicaSummary, SiteReport};
use super::scenario::Scenario;
use crate::error::{Result, TetError};
use crate::model::probe::{NodeReaction, Trajectory};
use crate::model::V3;
use crate::netem::NetemConfig;
use network::{NetOut, Started};
use serde::{Deserialize, Serialize};
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicU8, AtomicUsize, Ordering};
use std::sync::mpsc::{self, SyncSender};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};
use threads::{DeformOut, HapticOut};

pub use relay::{run_relay, RelayReport, RelaySetup};

/// Capacity of each inter-thread channel and of the haptic thread's
/// backlog (ticks): 4 s of input.
const CHANNEL_TICKS: usize = 4096;
/// How long the network thread sleeps after a pass that received nothing
/// (µs): the emulator's release resolution. The socket is non-blocking and
/// the thread sleeps (nanosleep, a high-resolution timer) rather than
/// waiting in a socket read timeout: Linux rounds `SO_RCVTIMEO` up to
/// whole scheduler ticks, and a 200 µs timeout measured 6–16 ms on the
/// benchmark machine, which added about 7 ms to every round trip and had
/// half the inputs resent spuriously.
const NET_POLL_US: u64 = 200;
/// How long a site lingers after its bye "done" for the peer's.
const LINGER: Duration = Duration::from_secs(2);
/// Time allowed without any packet from the peer once this site has
/// stopped making inputs.
const DRAIN_LIMIT: Duration = Duration::from_secs(30);

/// Why the haptic thread stopped (shared code, 0 = running).
const STOP_NONE: u8 = 0;
const STOP_DURATION: u8 = 1;
const STOP_USER: u8 = 2;
const STOP_PEER: u8 = 3;

/// Everything one site needs.
#[derive(Clone, Debug)]
pub struct SiteSetup {
    /// 0 or 1.
    pub site: u8,
    /// The shared session (both sites must agree: the hello checks it).
    pub session: SessionConfig,
    /// The emulator in this site's sending path (`None`: packets go
    /// straight to the socket, as on a real network).
    pub netem: Option<NetemConfig>,
    /// Seed of the emulator.
    pub seed: u64,
    /// The session tick at which this site stops making inputs.
    pub duration_ticks: u64,
    /// This user's stylus path.
    pub trajectory: Trajectory,
    /// Busy-wait this long (µs) before each haptic deadline instead of
    /// sleeping through it (0: sleep only).
    pub spin_us: u64,
    /// Ticks between rows of the force trace.
    pub trace_every_ticks: u64,
    /// Run the haptic thread at this SCHED_FIFO priority (1–99; 0: the
    /// normal scheduler).
    pub rt_priority: u8,
    /// This start of the process (random per start; a peer that sees a
    /// new one knows this site restarted).
    pub nonce: u32,
    /// How long to look for the peer.
    pub connect_timeout: Duration,
    /// Non-zero when the user asks the site to stop (SIGINT, SIGTERM).
    pub stop: Arc<AtomicUsize>,
    /// A status line every so often, to this channel.
    pub status: Option<(Duration, SyncSender<SiteStatus>)>,
}

impl SiteSetup {
    /// Site `site` (0 or 1) of `scenario`'s session, its packets through
    /// the scenario's emulator, busy-waiting `spin_us` before each haptic
    /// deadline, its haptic thread at SCHED_FIFO `rt_priority` (0: normal).
    pub fn from_scenario(
        scenario: &Scenario,
        site: u8,
        spin_us: u64,
        rt_priority: u8,
    ) -> Result<SiteSetup> {
        let cfg: PairConfig = scenario.pair_config("scenario")?;
        let [t0, t1] = cfg.trajectories;
        Ok(SiteSetup {
            site,
            session: cfg.session,
            netem: Some(cfg.netem),
            seed: cfg.seed,
            duration_ticks: cfg.duration_ticks,
            trajectory: if site == 0 { t0 } else { t1 },
            spin_us,
            trace_every_ticks: cfg.trace_every_ticks,
            rt_priority,
            nonce: fresh_nonce(site),
            connect_timeout: Duration::from_secs(20),
            stop: Arc::new(AtomicUsize::new(0)),
            status: None,
        })
    }
}

/// A nonce for this start of a site: the clock's nanoseconds mixed with
/// the process id and the site.
pub fn fresh_nonce(site: u8) -> u32 {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64);
    let mut h = t ^ (u64::from(std::process::id()) << 32) ^ u64::from(site);
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h as u32
}

/// The line a running site reports every so often.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct SiteStatus {
    /// 0 or 1.
    pub site: u8,
    /// Session time (s).
    pub clock_s: f64,
    /// What the site is doing.
    pub phase: String,
    /// The haptic tick.
    pub tick: u64,
    /// The committed replica's tick.
    pub committed_tick: u64,
    /// Mean of the round-trip samples so far (ms).
    pub rtt_mean_ms: f64,
    /// Smoothed round trip (ms).
    pub srtt_ms: f64,
    /// Inputs sent.
    pub inputs_sent: u64,
    /// Inputs resent.
    pub resent: u64,
    /// Peer ticks seen missing (the incoming loss, as far as it shows).
    pub gaps_seen: u64,
    /// Peer inputs received.
    pub inputs_received: u64,
    /// The committed replica's lag now (ms).
    pub lag_ms: u64,
    /// Its largest lag since the last line (ms).
    pub lag_max_ms: u64,
    /// Missed haptic ticks so far.
    pub missed_ticks: u64,
    /// Restarted peers given the state so far.
    pub resyncs: u64,
}

impl SiteStatus {
    /// One line for a terminal.
    pub fn line(&self) -> String {
        let pct = |n: u64, of: u64| 100.0 * n as f64 / of.max(1) as f64;
        format!(
            "site {} t {:.1} s {}: tick {} committed {} (lag {} ms, max {} ms); rtt {:.1} ms (srtt {:.1}); resent {} of {} ({:.2} %); incoming gaps {} of {} ({:.2} %); missed ticks {}; resyncs {}",
            self.site,
            self.clock_s,
            self.phase,
            self.tick,
            self.committed_tick,
            self.lag_ms,
            self.lag_max_ms,
            self.rtt_mean_ms,
            self.srtt_ms,
            self.resent,
            self.inputs_sent,
            pct(self.resent, self.inputs_sent),
            self.gaps_seen,
            self.inputs_received,
            pct(self.gaps_seen, self.inputs_received),
            self.missed_ticks,
            self.resyncs
        )
    }
}

/// What the deformation thread publishes.
struct Snapshot {
    tick: u64,
    x_m: Vec<V3>,
    reaction: Option<NodeReaction>,
    /// The node the peer holds, as far as this site knows.
    peer_grip: Option<u16>,
}

/// State shared between the threads.
struct Shared {
    shape: Mutex<Arc<Snapshot>>,
    committed_tick: AtomicU64,
    committed_hash: AtomicU64,
    haptic_tick: AtomicU64,
    lag_ticks: AtomicU64,
    lag_max_ticks: AtomicU64,
    missed_ticks: AtomicU64,
    resyncs: AtomicU64,
    /// Why the haptic thread stops ([`STOP_NONE`] while it runs).
    stop: AtomicU8,
    /// The tick count a peer that ran out its duration reached (`u64::MAX`
    /// until one says so): this site runs up to it, then stops, so that a
    /// site running a few ticks behind its peer (late wake-ups, a later
    /// start) still ends where the session's duration does.
    peer_end: AtomicU64,
    /// The haptic thread made its last input.
    haptic_done: AtomicBool,
    abort: AtomicBool,
    done: AtomicBool,
}

impl Shared {
    /// The shape `x_m` published at `tick`, nothing held.
    fn at(tick: u64, x_m: Vec<V3>, hash: u64) -> Self {
        Shared {
            shape: Mutex::new(Arc::new(Snapshot {
                tick,
                x_m,
                reaction: None,
                peer_grip: None,
            })),
            committed_tick: AtomicU64::new(tick),
            committed_hash: AtomicU64::new(hash),
            haptic_tick: AtomicU64::new(tick),
            lag_ticks: AtomicU64::new(0),
            lag_max_ticks: AtomicU64::new(0),
            missed_ticks: AtomicU64::new(0),
            resyncs: AtomicU64::new(0),
            stop: AtomicU8::new(STOP_NONE),
            peer_end: AtomicU64::new(u64::MAX),
            haptic_done: AtomicBool::new(false),
            abort: AtomicBool::new(false),
            done: AtomicBool::new(false),
        }
    }
}

/// A site failure in the words of `what` (the io error appended).
fn io_error(what: &'static str) -> impl Fn(std::io::Error) -> TetError {
    move |e| TetError::Site(format!("{what}: {e}"))
}

/// A UDP socket on an ephemeral port of 127.0.0.1.
pub fn bind_loopback() -> Result<UdpSocket> {
    UdpSocket::bind("127.0.0.1:0").map_err(io_error("cannot bind a UDP socket on 127.0.0.1"))
}

/// What a peer input or a re-synchronisation is, for the deformation
/// thread (in the order the network thread saw them).
enum PeerEvent {
    /// The peer's input of a tick.
    Input(u64, crate::model::probe::Manipulation),
    /// A restarted peer: take the committed replica to this tick and send
    /// it back.
    Resync(u64),
}

/// Runs one site over `socket` against the peer at `peer` in real time:
/// the handshake, the session, the bye of both sides.
pub fn run_site(setup: SiteSetup, socket: UdpSocket, peer: SocketAddr) -> Result<SiteReport> {
    let model = Arc::new(setup.session.model()?);
    let haptic = Haptic::new(&model);
    let epoch = Instant::now();
    let mut net = network::Net::new(
        &setup,
        socket,
        peer,
        &haptic,
        model.mesh().node_count(),
        epoch,
    )?;
    let started: Started = net.connect()?;
    let replicas = match &started.state {
        Some(s) => {
            Replicas::from_state(model.clone(), setup.site, setup.session.replica, s.clone())
        }
        None => Replicas::new(model.clone(), setup.site, setup.session.replica),
    };
    let base = replicas.committed().tick;
    let shared = Shared::at(
        base,
        replicas.committed().x_m.clone(),
        replicas.committed().bit_hash(),
    );
    let out = run_threads(&setup, &shared, haptic, replicas, net, &started)?;
    Ok(site_report(&setup, out, &started))
}

/// What the four threads of a site hand back.
struct ThreadsOut {
    haptic: HapticOut,
    deform: DeformOut,
    net: NetOut,
    display: (DisplayTiming, Vec<[f64; 3]>),
}

/// Starts the network, deformation and display threads, runs the haptic
/// loop on this one, and joins them; the first real failure wins (the
/// others stop because of it).
fn run_threads(
    setup: &SiteSetup,
    shared: &Shared,
    haptic: Haptic,
    replicas: Replicas,
    net: network::Net<'_>,
    started: &Started,
) -> Result<ThreadsOut> {
    let (net_tx, net_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (def_tx, def_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (remote_tx, remote_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (state_tx, state_rx) = mpsc::sync_channel(1);
    let (haptic_out, deform_out, net_out, display) = thread::scope(|s| {
        let net = s.spawn(move || {
            let r = net.run(shared, net_rx, remote_tx, state_rx);
            if r.is_err() {
                shared.abort.store(true, Ordering::Relaxed);
            }
            shared.done.store(true, Ordering::Relaxed);
            r
        });
        let deform = s.spawn(move || {
            let r = threads::deformation_thread(replicas, shared, def_rx, remote_rx, state_tx);
            if r.is_err() {
                shared.abort.store(true, Ordering::Relaxed);
            }
            r
        });
        let display = s.spawn(move || threads::display_thread(shared, started.epoch));
        let h = threads::haptic_thread(setup, haptic, shared, started, net_tx, def_tx);
        if h.is_err() {
            shared.abort.store(true, Ordering::Relaxed);
        }
        let join = |name: &str| TetError::Site(format!("the {name} thread panicked"));
        let n = net.join().map_err(|_| join("network"));
        let d = deform.join().map_err(|_| join("deformation"));
        shared.done.store(true, Ordering::Relaxed);
        let v = display.join().map_err(|_| join("display"));
        (h, d, n, v)
    });
    // Report the first real failure (the others stop because of it).
    let net = net_out??;
    let haptic = haptic_out?;
    let deform = deform_out??;
    let display = display?;
    Ok(ThreadsOut {
        haptic,
        deform,
        net,
        display,
    })
}

/// The site's report from what its threads handed back.
fn site_report(setup: &SiteSetup, out: ThreadsOut, started: &Started) -> SiteReport {
    let stats = out.deform.replicas.stats();
    let committed = out.deform.replicas.committed();
    let mut link_summary = LinkSummary::from(out.net.link.stats());
    link_summary.send_errors = out.net.send_errors;
    link_summary.scheduling = out.net.scheduling;
    let mut replica = ReplicaSummary::from(stats);
    replica.set_lag(&out.haptic.lag);
    SiteReport {
        site: setup.site,
        haptic: Some(out.haptic.timing),
        deformation: Some(out.deform.timing),
        display: Some(out.display.0),
        link: link_summary,
        netem: out
            .net
            .emulator
            .as_ref()
            .map(|e| NetemSummary::from(e.stats()))
            .unwrap_or_default(),
        replica,
        committed_tick: committed.tick,
        final_hash: committed.bit_hash(),
        final_x_m: committed.x_m.iter().map(|p| arr(*p)).collect(),
        peak_x_m: out.display.1,
        trace: out.haptic.trace,
        contact_ticks: out.haptic.contact_ticks,
        max_force_n: out.haptic.max_force_n,
        end: Some(out.net.end),
        joined_at_tick: started.state.as_ref().map(|s| s.tick),
        handshake_rtt_us: started.rtt_us,
        notes: out.net.notes,
    }
}

/// Both sites of `setups` as two threads of this process, over UDP on
/// loopback; their reports in site order.
pub fn run_pair_in_process(setups: [SiteSetup; 2]) -> Result<[SiteReport; 2]> {
    let sockets = [bind_loopback()?, bind_loopback()?];
    let local = |s: &UdpSocket| s.local_addr().map_err(|e| TetError::Site(e.to_string()));
    let addrs = [local(&sockets[0])?, local(&sockets[1])?];
    let [s0, s1] = sockets;
    let [u0, u1] = setups;
    let (r0, r1) = thread::scope(|s| {
        let a = s.spawn(move || run_site(u0, s0, addrs[1]));
        let b = s.spawn(move || run_site(u1, s1, addrs[0]));
        (a.join(), b.join())
    });
    let finish = |k: u8, r: thread::Result<Result<SiteReport>>| match r {
        Err(_) => Err(TetError::Site(format!("site {k} panicked"))),
        Ok(Err(e)) => Err(TetError::Site(format!("site {k}: {e}"))),
        Ok(Ok(report)) => Ok(report),
    };
    Ok([finish(0, r0)?, finish(1, r1)?])
}

/// The lag histogram the haptic thread fills, allocated before it runs.
fn lag_histogram() -> LagHistogram {
    LagHistogram::new()
}
