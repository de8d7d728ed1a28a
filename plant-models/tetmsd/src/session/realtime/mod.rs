//! The real-time runtime of one tetmsd site (seed 000, Yamaguchi §5.2):
//! four threads and a UDP socket around the pure session logic of
//! `plant_tetmsd::session`.
//!
//! * **Haptic, 1 kHz** (the seed's haptic thread, L2667): reads the
//!   scripted stylus, decides the grip on the latest published shape
//!   (Eq. 3), computes the felt force from the latest published reaction
//!   (first-order local model) and hands the tick's manipulation to the
//!   other threads. It never waits: the shape is taken with `try_lock`
//!   (the previous one is kept if the lock is busy) and the manipulation
//!   goes out with `try_send` into bounded channels, with a bounded local
//!   backlog if they are full (a full backlog stops the session by name).
//!   Deadlines are absolute (`t0 + k ms`); a late tick is not skipped but
//!   run at once, and its lateness recorded. A tick whose work starts a
//!   whole period (1 ms) or more after its deadline is a *missed* tick.
//!   With `rt_priority` it runs on SCHED_FIFO at that priority, and the
//!   network thread one below it (both sleep most of the time).
//! * **Deformation** (the seed's OpenGL thread's deformation, L2661–2664):
//!   feeds local and peer inputs to the replicas, advances them as far as
//!   it can, and publishes the speculative shape and the held node's
//!   reaction. Its rate follows the mesh size and the machine.
//! * **Network**: the UDP socket, the link (acks, resends), the emulator
//!   in the sending path, the hello/bye handshake.
//! * **Display, 30 Hz** (L2665): takes the published shape as a renderer
//!   would, counts frames and how old the shape was, and keeps the frame
//!   where the user pushed hardest for the picture.
//!
//! Timing is whatever the machine gives: on a shared machine the haptic
//! loop's lateness is measured and reported, never assumed.
//!
//! The parts: [`threads`] (haptic, deformation, display), [`network`]
//! (handshake and the network thread); the report they fill is
//! [`super::report::SiteReport`]. The pure session logic they drive is
//! tested deterministically in [`super::pair`]; this module is tested by
//! `softjoint tetmsd pair` over real sockets (host-tools' `tetmsd_cli`).
//!
//! Errors are the crate's [`TetError`]: a thread, socket or peer failure
//! is [`TetError::Site`] with the words that name it.
mod network;
mod threads;

use super::pair::{Haptic, PairConfig, SessionConfig};
use super::replica::Replicas;
use super::report::DisplayTiming;
use super::report::{arr, LinkSummary, NetemSummary, ReplicaSummary, SiteReport};
use super::scenario::Scenario;
use crate::error::{Result, TetError};
use crate::link::Link;
use crate::model::probe::{ContactGeometry, NodeReaction, Trajectory};
use crate::model::V3;
use crate::netem::NetemConfig;
use network::NetOut;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc;
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};
use threads::{DeformOut, HapticOut};

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
/// How long a site waits for its peer's hello.
const HELLO_TIMEOUT: Duration = Duration::from_secs(20);
/// How long a site lingers after its bye for the peer's.
const LINGER: Duration = Duration::from_secs(2);
/// Time allowed after the last tick for the replicas to complete.
const DRAIN_LIMIT: Duration = Duration::from_secs(60);

/// Everything one site needs.
#[derive(Clone, Debug)]
pub struct SiteSetup {
    /// 0 or 1.
    pub site: u8,
    /// The shared session (both sites must agree: the hello checks it).
    pub session: SessionConfig,
    /// The emulator of this site's outgoing packets.
    pub netem: NetemConfig,
    /// Seed of the emulator.
    pub seed: u64,
    /// Ticks with user input.
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
}

impl SiteSetup {
    /// Site `site` (0 or 1) of `scenario`'s session, busy-waiting
    /// `spin_us` before each haptic deadline, its haptic thread at
    /// SCHED_FIFO `rt_priority` (0: normal).
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
            netem: cfg.netem,
            seed: cfg.seed,
            duration_ticks: cfg.duration_ticks,
            trajectory: if site == 0 { t0 } else { t1 },
            spin_us,
            trace_every_ticks: cfg.trace_every_ticks,
            rt_priority,
        })
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
    haptic_tick: AtomicU64,
    abort: AtomicBool,
    done: AtomicBool,
}

impl Shared {
    /// The rest shape `x_m` published at tick 0, nothing held.
    fn at_rest(x_m: Vec<V3>) -> Self {
        Shared {
            shape: Mutex::new(Arc::new(Snapshot {
                tick: 0,
                x_m,
                reaction: None,
                peer_grip: None,
            })),
            committed_tick: AtomicU64::new(0),
            haptic_tick: AtomicU64::new(0),
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

/// The network thread's part of a site: the socket, the peer, the link
/// after the handshake and what it needs to check peer packets.
struct NetParts<'a> {
    socket: UdpSocket,
    peer: SocketAddr,
    link: Link,
    geometry: &'a ContactGeometry,
    nodes: usize,
}

/// Runs one site over `socket` against the peer at `peer` in real time.
pub fn run_site(setup: SiteSetup, socket: UdpSocket, peer: SocketAddr) -> Result<SiteReport> {
    let model = Arc::new(setup.session.model()?);
    let nodes = model.mesh().node_count();
    let haptic = Haptic::new(&model);
    let geometry = haptic.geometry().clone();
    let mut link = Link::new(setup.site, setup.session.link);
    socket
        .set_read_timeout(Some(Duration::from_millis(5)))
        .map_err(io_error("socket timeout"))?;
    network::handshake(&socket, peer, &mut link, setup.session.hash())?;
    let replicas = Replicas::new(model.clone(), setup.site, setup.session.replica);
    let shared = Shared::at_rest(model.rest_state().x_m);
    let net = NetParts {
        socket,
        peer,
        link,
        geometry: &geometry,
        nodes,
    };
    let out = run_threads(&setup, &shared, haptic, replicas, net)?;
    Ok(site_report(&setup, out))
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
    net: NetParts<'_>,
) -> Result<ThreadsOut> {
    let (net_tx, net_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (def_tx, def_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (remote_tx, remote_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let t0 = Instant::now();
    let (haptic_out, deform_out, net_out, display) = thread::scope(|s| {
        let net = s.spawn(move || {
            let r = network::network_thread(setup, net, shared, t0, net_rx, remote_tx);
            if r.is_err() {
                shared.abort.store(true, Ordering::Relaxed);
            }
            shared.done.store(true, Ordering::Relaxed);
            r
        });
        let deform = s.spawn(move || {
            let r = threads::deformation_thread(
                replicas,
                shared,
                t0,
                setup.duration_ticks,
                def_rx,
                remote_rx,
            );
            if r.is_err() {
                shared.abort.store(true, Ordering::Relaxed);
            }
            r
        });
        let display = s.spawn(move || threads::display_thread(shared, t0));
        let h = threads::haptic_thread(setup, haptic, shared, t0, net_tx, def_tx);
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
    let haptic = haptic_out?;
    let net = net_out??;
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
fn site_report(setup: &SiteSetup, out: ThreadsOut) -> SiteReport {
    let stats = out.deform.replicas.stats();
    let committed = out.deform.replicas.committed();
    let mut link_summary = LinkSummary::from(out.net.link.stats());
    link_summary.send_errors = out.net.send_errors;
    link_summary.scheduling = out.net.scheduling;
    SiteReport {
        site: setup.site,
        haptic: Some(out.haptic.timing),
        deformation: Some(out.deform.timing),
        display: Some(out.display.0),
        link: link_summary,
        netem: NetemSummary::from(out.net.emulator.stats()),
        replica: ReplicaSummary::from(stats),
        committed_tick: committed.tick,
        final_hash: committed.bit_hash(),
        final_x_m: committed.x_m.iter().map(|p| arr(*p)).collect(),
        peak_x_m: out.display.1,
        trace: out.haptic.trace,
        contact_ticks: out.haptic.contact_ticks,
        max_force_n: out.haptic.max_force_n,
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
