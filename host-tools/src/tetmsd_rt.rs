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
use anyhow::{anyhow, bail, Context, Result};
use plant_tetmsd::link::{Arrival, Link, LinkStats};
use plant_tetmsd::model::probe::{Manipulation, NodeReaction, Trajectory};
use plant_tetmsd::model::voigt::TICK_S;
use plant_tetmsd::model::V3;
use plant_tetmsd::netem::{Emulator, NetemConfig, NetemStats};
use plant_tetmsd::packet::{Message, Packet};
use plant_tetmsd::pair::{Haptic, SessionConfig};
use plant_tetmsd::replica::{ReplicaStats, Replicas};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TryRecvError, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread;
use std::time::{Duration, Instant};

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
    /// Datagrams the socket refused to send.
    pub send_errors: u64,
    /// The network thread's scheduling (`normal` or `SCHED_FIFO N`).
    pub scheduling: String,
}

impl From<&LinkStats> for LinkSummary {
    fn from(s: &LinkStats) -> Self {
        LinkSummary {
            inputs_sent: s.inputs_sent,
            retransmissions: s.retransmissions,
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
            send_errors: 0,
            scheduling: "virtual".into(),
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
            divergence_series: s.divergence.iter().map(|(t, d)| (*t, d * 1e3)).collect(),
        }
    }
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

fn arr(v: V3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// The `q` quantile of sorted `v`.
fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Puts the calling thread on SCHED_FIFO at `priority` (0: leave it) and
/// says what it got.
fn realtime(priority: u8) -> String {
    use thread_priority::{
        set_thread_priority_and_policy, thread_native_id, RealtimeThreadSchedulePolicy,
        ThreadPriority, ThreadPriorityValue, ThreadSchedulePolicy,
    };
    if priority == 0 {
        return "normal".into();
    }
    let value = match ThreadPriorityValue::try_from(priority) {
        Ok(v) => v,
        Err(e) => return format!("normal (priority {priority} refused: {e})"),
    };
    match set_thread_priority_and_policy(
        thread_native_id(),
        ThreadPriority::Crossplatform(value),
        ThreadSchedulePolicy::Realtime(RealtimeThreadSchedulePolicy::Fifo),
    ) {
        Ok(()) => format!("SCHED_FIFO {priority}"),
        Err(e) => format!("normal (SCHED_FIFO refused: {e:?})"),
    }
}

/// Sleeps (and spins for the last `spin`) until `deadline`.
fn wait_until(deadline: Instant, spin: Duration) {
    loop {
        let now = Instant::now();
        if now >= deadline {
            return;
        }
        let left = deadline - now;
        if left > spin {
            thread::sleep(left - spin);
        } else {
            std::hint::spin_loop();
        }
    }
}

/// Hands `item` to `tx` without waiting; what does not fit waits in the
/// bounded `backlog`. Returns false when the backlog is full too.
fn offer<T>(tx: &SyncSender<T>, backlog: &mut VecDeque<T>, item: T, counted: &mut u64) -> bool {
    backlog.push_back(item);
    while let Some(x) = backlog.pop_front() {
        match tx.try_send(x) {
            Ok(()) => {}
            Err(TrySendError::Full(x)) => {
                backlog.push_front(x);
                *counted += 1;
                break;
            }
            Err(TrySendError::Disconnected(_)) => return true,
        }
    }
    backlog.len() < CHANNEL_TICKS
}

struct HapticOut {
    timing: HapticTiming,
    trace: Vec<ForceRow>,
    contact_ticks: u64,
    max_force_n: f64,
}

#[allow(clippy::too_many_arguments)]
fn haptic_thread(
    setup: &SiteSetup,
    mut haptic: Haptic,
    shared: &Shared,
    t0: Instant,
    to_net: SyncSender<(u32, Manipulation)>,
    to_deform: SyncSender<(u64, Manipulation)>,
) -> Result<HapticOut> {
    let n = setup.duration_ticks as usize;
    let every = setup.trace_every_ticks.max(1);
    let mut late_us: Vec<f64> = Vec::with_capacity(n);
    let mut work_us: Vec<f64> = Vec::with_capacity(n);
    let mut trace = Vec::with_capacity(n / every as usize + 1);
    let (mut net_backlog, mut def_backlog) = (
        VecDeque::with_capacity(CHANNEL_TICKS + 1),
        VecDeque::with_capacity(CHANNEL_TICKS + 1),
    );
    let mut timing = HapticTiming {
        spin_us: setup.spin_us,
        scheduling: realtime(setup.rt_priority),
        ..HapticTiming::default()
    };
    let mut shape = shared
        .shape
        .lock()
        .map_err(|_| anyhow!("shape lock poisoned"))?
        .clone();
    let spin = Duration::from_micros(setup.spin_us);
    let (mut contact_ticks, mut max_force) = (0u64, 0.0f64);
    for k in 0..setup.duration_ticks {
        if shared.abort.load(Ordering::Relaxed) {
            break;
        }
        let deadline = t0 + Duration::from_micros(k * 1000);
        wait_until(deadline, spin);
        let start = Instant::now();
        late_us.push((start - deadline).as_secs_f64() * 1e6);
        match shared.shape.try_lock() {
            Ok(s) => shape = s.clone(),
            Err(_) => timing.lock_busy += 1,
        }
        let tip = setup.trajectory.at(k as f64 * TICK_S);
        let m = haptic.manipulate(tip, &shape.x_m, shape.peer_grip);
        let force = match (m.grip, shape.reaction) {
            (Some(g), Some(r)) if r.node == g.node => r.force_at(g.node_m),
            _ => V3::zeros(),
        };
        contact_ticks += u64::from(m.grip.is_some());
        max_force = max_force.max(force.norm());
        let ok_net = offer(
            &to_net,
            &mut net_backlog,
            (k as u32, m),
            &mut timing.backlogged,
        );
        let ok_def = offer(&to_deform, &mut def_backlog, (k, m), &mut timing.backlogged);
        shared.haptic_tick.store(k, Ordering::Relaxed);
        if k % every == 0 {
            trace.push(ForceRow {
                tick: k,
                tip_m: arr(tip),
                force_n: arr(force),
                contact: m.grip.is_some(),
            });
        }
        work_us.push(start.elapsed().as_secs_f64() * 1e6);
        if !(ok_net && ok_def) {
            shared.abort.store(true, Ordering::Relaxed);
            bail!(
                "tick {k}: the network or deformation thread took no input for {CHANNEL_TICKS} ticks"
            );
        }
    }
    // Hand over what is left, waiting now that the real-time part is over.
    for item in net_backlog {
        to_net.send(item).ok();
    }
    for item in def_backlog {
        to_deform.send(item).ok();
    }
    timing.ticks = late_us.len() as u64;
    timing.missed_ticks = late_us.iter().filter(|l| **l >= 1000.0).count() as u64;
    timing.work_mean_us = work_us.iter().sum::<f64>() / work_us.len().max(1) as f64;
    timing.work_max_us = work_us.iter().copied().fold(0.0, f64::max);
    late_us.sort_by(f64::total_cmp);
    timing.late_p50_us = quantile(&late_us, 0.5);
    timing.late_p99_us = quantile(&late_us, 0.99);
    timing.late_p999_us = quantile(&late_us, 0.999);
    timing.late_max_us = late_us.last().copied().unwrap_or(0.0);
    Ok(HapticOut {
        timing,
        trace,
        contact_ticks,
        max_force_n: max_force,
    })
}

struct DeformOut {
    timing: DeformationTiming,
    replicas: Replicas,
}

fn deformation_thread(
    mut replicas: Replicas,
    shared: &Shared,
    t0: Instant,
    duration_ticks: u64,
    local: Receiver<(u64, Manipulation)>,
    remote: Receiver<(u64, Manipulation)>,
) -> Result<DeformOut> {
    let mut timing = DeformationTiming::default();
    let mut busy = Duration::ZERO;
    let mut grip_node = None;
    let mut local_open = true;
    // Published snapshots the haptic or display thread may still hold.
    let mut retired: Vec<Arc<Snapshot>> = Vec::new();
    loop {
        if shared.abort.load(Ordering::Relaxed) {
            bail!("stopped: another thread failed");
        }
        let mut work = false;
        loop {
            match local.try_recv() {
                Ok((t, m)) => {
                    replicas.push_local(t, m)?;
                    grip_node = m.grip.map(|g| g.node);
                    work = true;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    local_open = false;
                    break;
                }
            }
        }
        while let Ok((t, m)) = remote.try_recv() {
            replicas.push_remote(t, m)?;
            work = true;
        }
        if work {
            let started = Instant::now();
            let before = replicas.committed().tick
                + replicas.stats().speculative_ticks
                + replicas.stats().recomputed_ticks;
            replicas.advance(replicas.local_end())?;
            let after = replicas.committed().tick
                + replicas.stats().speculative_ticks
                + replicas.stats().recomputed_ticks;
            timing.ticks_computed += after - before;
            let spec = replicas.speculative();
            let snap = Arc::new(Snapshot {
                tick: spec.tick,
                x_m: spec.x_m.clone(),
                reaction: grip_node.map(|n| replicas.reaction(n)),
                peer_grip: replicas.peer_grip(),
            });
            if let Ok(mut s) = shared.shape.lock() {
                retired.push(std::mem::replace(&mut *s, snap));
            }
            // The haptic thread must never free a snapshot: free() of
            // memory this thread allocated takes this thread's malloc
            // arena lock, which a preempted deformation thread may hold.
            // With the frees here the haptic loop's worst lateness in 10 s
            // runs fell from 26–36 ms to about 6 ms. Snapshots are freed
            // once only this list holds them.
            retired.retain(|a| Arc::strong_count(a) > 1);
            shared
                .committed_tick
                .store(replicas.committed().tick, Ordering::Relaxed);
            timing.updates += 1;
            busy += started.elapsed();
        } else {
            if !local_open && replicas.committed().tick >= duration_ticks {
                break;
            }
            if shared.done.load(Ordering::Relaxed) {
                break;
            }
            thread::sleep(Duration::from_micros(NET_POLL_US));
        }
    }
    let run = t0.elapsed().as_secs_f64();
    timing.updates_per_s = timing.updates as f64 / run;
    timing.ticks_per_busy_s = timing.ticks_computed as f64 / busy.as_secs_f64().max(1e-9);
    timing.busy_fraction = busy.as_secs_f64() / run;
    Ok(DeformOut { timing, replicas })
}

fn display_thread(shared: &Shared, t0: Instant) -> (DisplayTiming, Vec<[f64; 3]>) {
    let period = Duration::from_secs_f64(1.0 / 30.0);
    let mut timing = DisplayTiming::default();
    let mut ages = 0.0;
    let mut peak = (-1.0, Vec::new());
    let mut k = 1u32;
    while !shared.done.load(Ordering::Relaxed) && !shared.abort.load(Ordering::Relaxed) {
        wait_until(t0 + period * k, Duration::ZERO);
        k += 1;
        let Ok(s) = shared.shape.lock().map(|s| s.clone()) else {
            break;
        };
        let age_ms = shared
            .haptic_tick
            .load(Ordering::Relaxed)
            .saturating_sub(s.tick) as f64;
        timing.frames += 1;
        ages += age_ms;
        timing.age_max_ms = timing.age_max_ms.max(age_ms);
        let push = s.reaction.map(|r| r.force_n.norm()).unwrap_or(0.0);
        if push > peak.0 {
            peak = (push, s.x_m.iter().map(|p| arr(*p)).collect());
        }
    }
    timing.age_mean_ms = ages / timing.frames.max(1) as f64;
    (timing, peak.1)
}

/// Waits for the peer's hello and answers it (a three-way handshake: a
/// hello with `seq = 1` says "I have heard yours"). Returns when both
/// sides know of each other.
fn handshake(socket: &UdpSocket, peer: SocketAddr, link: &mut Link, hash: u64) -> Result<()> {
    let started = Instant::now();
    let mut heard = false;
    let mut last = None::<Instant>;
    let mut buf = [0u8; 128];
    loop {
        if started.elapsed() > HELLO_TIMEOUT {
            bail!(
                "no hello from the peer at {peer} in {} s",
                HELLO_TIMEOUT.as_secs()
            );
        }
        if last.is_none_or(|t| t.elapsed() > Duration::from_millis(10)) {
            let mut p = Packet::decode(&link.hello_packet(hash)).map_err(|e| anyhow!("{e}"))?;
            p.seq = u32::from(heard);
            socket.send_to(&p.encode(), peer).ok();
            last = Some(Instant::now());
        }
        let Ok((len, _)) = socket.recv_from(&mut buf) else {
            continue;
        };
        match Packet::decode(&buf[..len]) {
            Ok(Packet {
                message: Message::Hello { config_hash },
                seq,
                site,
                ..
            }) if site != link.site() => {
                if config_hash != hash {
                    link.refuse_peer();
                    bail!(
                        "the peer at {peer} runs another configuration (hash {config_hash:016x}, ours {hash:016x}): level, cube and material must match"
                    );
                }
                heard = true;
                if seq == 1 {
                    let mut p =
                        Packet::decode(&link.hello_packet(hash)).map_err(|e| anyhow!("{e}"))?;
                    p.seq = 1;
                    socket.send_to(&p.encode(), peer).ok();
                    return Ok(());
                }
            }
            // The peer already runs: it heard us.
            Ok(Packet {
                message: Message::Input(_),
                ..
            }) if heard => return Ok(()),
            _ => {}
        }
    }
}

struct NetOut {
    link: Link,
    emulator: Emulator,
    send_errors: u64,
    scheduling: String,
}

#[allow(clippy::too_many_arguments)]
fn network_thread(
    setup: &SiteSetup,
    socket: UdpSocket,
    peer: SocketAddr,
    mut link: Link,
    shared: &Shared,
    t0: Instant,
    from_haptic: Receiver<(u32, Manipulation)>,
    to_deform: SyncSender<(u64, Manipulation)>,
    geometry: &plant_tetmsd::model::probe::ContactGeometry,
    nodes: usize,
) -> Result<NetOut> {
    let mut emulator = Emulator::new(setup.netem, setup.seed, setup.site)?;
    // The network thread times the emulator's releases and the acks: one
    // step below the haptic thread when that one is real-time.
    let scheduling = realtime(setup.rt_priority.saturating_sub(1));
    socket
        .set_nonblocking(true)
        .context("cannot make the UDP socket non-blocking")?;
    let mut buf = [0u8; 128];
    let mut backlog: VecDeque<(u64, Manipulation)> = VecDeque::new();
    let mut send_errors = 0u64;
    let mut local_done = false;
    let mut last_ack_us = 0u64;
    let mut bye_at: Option<Instant> = None;
    let mut peer_bye = false;
    let mut last_input_at = t0;
    loop {
        if shared.abort.load(Ordering::Relaxed) {
            bail!("stopped: another thread failed");
        }
        let now_us = t0.elapsed().as_micros() as u64;
        loop {
            match from_haptic.try_recv() {
                Ok((tick, m)) => {
                    let bytes = link.send_input(now_us, tick, m)?;
                    emulator.push(now_us, bytes);
                    last_ack_us = now_us;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    local_done = true;
                    break;
                }
            }
        }
        for bytes in link.poll(now_us) {
            emulator.push(now_us, bytes);
        }
        if local_done && (link.owes_ack() || now_us >= last_ack_us + 10_000) {
            let bytes = link.ack_packet();
            emulator.push(now_us, bytes);
            last_ack_us = now_us;
        }
        while let Some(bytes) = emulator.pop_due(now_us) {
            if socket.send_to(&bytes, peer).is_err() {
                send_errors += 1;
            }
        }
        let mut got = 0;
        while got < 64 {
            // Empty (WouldBlock) or a transient error: try again next pass.
            let Ok((len, _)) = socket.recv_from(&mut buf) else {
                break;
            };
            got += 1;
            let now_us = t0.elapsed().as_micros() as u64;
            match link.on_datagram(now_us, &buf[..len], geometry, nodes) {
                Arrival::Input { tick, input } => {
                    last_input_at = Instant::now();
                    backlog.push_back((u64::from(tick), input));
                }
                Arrival::Hello(_) => {
                    // The peer missed our last hello: tell it again,
                    // through the emulated network like everything else.
                    let mut p = Packet::decode(&link.hello_packet(setup.session.hash()))
                        .map_err(|e| anyhow!("{e}"))?;
                    p.seq = 1;
                    emulator.push(now_us, p.encode());
                }
                Arrival::Bye => peer_bye = true,
                Arrival::Nothing => {}
            }
        }
        while let Some(item) = backlog.pop_front() {
            match to_deform.try_send(item) {
                Ok(()) => {}
                Err(TrySendError::Full(x)) => {
                    backlog.push_front(x);
                    break;
                }
                Err(TrySendError::Disconnected(_)) => break,
            }
        }
        if backlog.len() > 2 * CHANNEL_TICKS {
            bail!(
                "the deformation thread took no peer input for {} ticks",
                backlog.len()
            );
        }
        let complete = local_done
            && link.all_acknowledged()
            && backlog.is_empty()
            && shared.committed_tick.load(Ordering::Relaxed) >= setup.duration_ticks;
        if complete && bye_at.is_none() {
            for _ in 0..3 {
                let bytes = link.bye_packet();
                emulator.push(now_us, bytes);
            }
            bye_at = Some(Instant::now());
        }
        if let Some(t) = bye_at {
            if peer_bye || t.elapsed() > LINGER {
                break;
            }
        }
        if got == 0 {
            thread::sleep(Duration::from_micros(NET_POLL_US));
        }
        if local_done && last_input_at.elapsed() > DRAIN_LIMIT {
            bail!(
                "the session did not complete: no peer input for {} s (committed tick {} of {})",
                DRAIN_LIMIT.as_secs(),
                shared.committed_tick.load(Ordering::Relaxed),
                setup.duration_ticks
            );
        }
    }
    Ok(NetOut {
        link,
        emulator,
        send_errors,
        scheduling,
    })
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
        .context("socket timeout")?;
    handshake(&socket, peer, &mut link, setup.session.hash())?;
    let replicas = Replicas::new(model.clone(), setup.site, setup.session.replica);
    let shared = Shared {
        shape: Mutex::new(Arc::new(Snapshot {
            tick: 0,
            x_m: model.rest_state().x_m,
            reaction: None,
            peer_grip: None,
        })),
        committed_tick: AtomicU64::new(0),
        haptic_tick: AtomicU64::new(0),
        abort: AtomicBool::new(false),
        done: AtomicBool::new(false),
    };
    let (net_tx, net_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (def_tx, def_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let (remote_tx, remote_rx) = mpsc::sync_channel(CHANNEL_TICKS);
    let t0 = Instant::now();
    let setup_ref = &setup;
    let shared_ref = &shared;
    let geometry_ref = &geometry;
    let (haptic_out, deform_out, net_out, display) = thread::scope(|s| {
        let net = s.spawn(move || {
            let r = network_thread(
                setup_ref,
                socket,
                peer,
                link,
                shared_ref,
                t0,
                net_rx,
                remote_tx,
                geometry_ref,
                nodes,
            );
            if r.is_err() {
                shared_ref.abort.store(true, Ordering::Relaxed);
            }
            shared_ref.done.store(true, Ordering::Relaxed);
            r
        });
        let deform = s.spawn(move || {
            let r = deformation_thread(
                replicas,
                shared_ref,
                t0,
                setup_ref.duration_ticks,
                def_rx,
                remote_rx,
            );
            if r.is_err() {
                shared_ref.abort.store(true, Ordering::Relaxed);
            }
            r
        });
        let display = s.spawn(move || display_thread(shared_ref, t0));
        let h = haptic_thread(setup_ref, haptic, shared_ref, t0, net_tx, def_tx);
        if h.is_err() {
            shared_ref.abort.store(true, Ordering::Relaxed);
        }
        let join = |name: &str| anyhow!("the {name} thread panicked");
        let n = net.join().map_err(|_| join("network"));
        let d = deform.join().map_err(|_| join("deformation"));
        shared_ref.done.store(true, Ordering::Relaxed);
        let v = display.join().map_err(|_| join("display"));
        (h, d, n, v)
    });
    // Report the first real failure (the others stop because of it).
    let haptic_out = haptic_out?;
    let net_out = net_out??;
    let deform_out = deform_out??;
    let display = display?;
    let stats = deform_out.replicas.stats();
    let committed = deform_out.replicas.committed();
    let mut link_summary = LinkSummary::from(net_out.link.stats());
    link_summary.send_errors = net_out.send_errors;
    link_summary.scheduling = net_out.scheduling;
    Ok(SiteReport {
        site: setup.site,
        haptic: Some(haptic_out.timing),
        deformation: Some(deform_out.timing),
        display: Some(display.0),
        link: link_summary,
        netem: NetemSummary::from(net_out.emulator.stats()),
        replica: ReplicaSummary::from(stats),
        committed_tick: committed.tick,
        final_hash: committed.bit_hash(),
        final_x_m: committed.x_m.iter().map(|p| arr(*p)).collect(),
        peak_x_m: display.1,
        trace: haptic_out.trace,
        contact_ticks: haptic_out.contact_ticks,
        max_force_n: haptic_out.max_force_n,
    })
}
