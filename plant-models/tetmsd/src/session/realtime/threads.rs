//! The three threads of a site besides the network: the 1 kHz haptic
//! loop, the deformation thread that advances the replicas, and the 30 Hz
//! display, with what they share (SCHED_FIFO, absolute deadlines, a
//! bounded hand-over that never waits).
use super::network::{stop_code, Started};
use super::{lag_histogram, PeerEvent, Shared, SiteSetup, Snapshot, CHANNEL_TICKS, NET_POLL_US};
use super::{STOP_NONE, STOP_PEER, STOP_USER};
use crate::error::{Result, TetError};
use crate::model::probe::Manipulation;
use crate::model::voigt::State;
use crate::model::voigt::TICK_S;
use crate::model::V3;
use crate::session::pair::Haptic;
use crate::session::replica::LagHistogram;
use crate::session::replica::Replicas;
use crate::session::report::{arr, DeformationTiming, DisplayTiming, ForceRow, HapticTiming};
use std::collections::VecDeque;
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread;
use std::time::{Duration, Instant};

/// The `q` quantile of sorted `v`.
fn quantile(v: &[f64], q: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v[((v.len() - 1) as f64 * q).round() as usize]
}

/// Puts the calling thread on SCHED_FIFO at `priority` (0: leave it) and
/// says what it got.
pub(super) fn schedule_fifo(priority: u8) -> String {
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

pub(super) struct HapticOut {
    pub(super) timing: HapticTiming,
    pub(super) trace: Vec<ForceRow>,
    pub(super) contact_ticks: u64,
    pub(super) max_force_n: f64,
    /// The committed replica's lag, once per live tick.
    pub(super) lag: LagHistogram,
}

/// The haptic loop's measurements as it goes (allocated before it runs).
struct HapticRun {
    late_us: Vec<f64>,
    work_us: Vec<f64>,
    trace: Vec<ForceRow>,
    lag: LagHistogram,
    contact_ticks: u64,
    max_force: f64,
}

/// Whether the haptic loop stops before tick `k`, and records why.
fn stopping(setup: &SiteSetup, shared: &Shared, k: u64) -> bool {
    if shared.abort.load(Ordering::Relaxed) {
        return true;
    }
    if setup.stop.load(Ordering::Relaxed) != 0 {
        let _ = shared.stop.compare_exchange(
            STOP_NONE,
            STOP_USER,
            Ordering::Relaxed,
            Ordering::Relaxed,
        );
    }
    if k >= shared.peer_end.load(Ordering::Relaxed) {
        let _ = shared.stop.compare_exchange(
            STOP_NONE,
            STOP_PEER,
            Ordering::Relaxed,
            Ordering::Relaxed,
        );
    }
    if k >= setup.duration_ticks {
        let _ = shared.stop.compare_exchange(
            STOP_NONE,
            stop_code(true),
            Ordering::Relaxed,
            Ordering::Relaxed,
        );
    }
    shared.stop.load(Ordering::Relaxed) != STOP_NONE
}

pub(super) fn haptic_thread(
    setup: &SiteSetup,
    mut haptic: Haptic,
    shared: &Shared,
    started: &Started,
    to_net: SyncSender<(u32, Manipulation)>,
    to_deform: SyncSender<(u64, Manipulation)>,
) -> Result<HapticOut> {
    let n = setup.duration_ticks.saturating_sub(started.first_tick) as usize;
    let every = setup.trace_every_ticks.max(1);
    let mut run = HapticRun {
        late_us: Vec::with_capacity(n),
        work_us: Vec::with_capacity(n),
        trace: Vec::with_capacity(n / every as usize + 1),
        lag: lag_histogram(),
        contact_ticks: 0,
        max_force: 0.0,
    };
    let (mut net_backlog, mut def_backlog) = (
        VecDeque::with_capacity(CHANNEL_TICKS + 1),
        VecDeque::with_capacity(CHANNEL_TICKS + 1),
    );
    let mut timing = HapticTiming {
        spin_us: setup.spin_us,
        scheduling: schedule_fifo(setup.rt_priority),
        ..HapticTiming::default()
    };
    let mut shape = shared
        .shape
        .lock()
        .map_err(|_| TetError::Site("shape lock poisoned".into()))?
        .clone();
    let spin = Duration::from_micros(setup.spin_us);
    let live_start = started.epoch + Duration::from_micros(started.at_us);
    let mut k = started.start_tick;
    while !stopping(setup, shared, k) {
        let tip = setup.trajectory.at(k as f64 * TICK_S);
        // Ticks before the first live one (a join) are "no contact",
        // sent at once.
        let live = k >= started.first_tick;
        let start = if live {
            let deadline = live_start + Duration::from_micros((k - started.first_tick) * 1000);
            wait_until(deadline, spin);
            let start = Instant::now();
            run.late_us
                .push(start.saturating_duration_since(deadline).as_secs_f64() * 1e6);
            start
        } else {
            Instant::now()
        };
        let (m, force) = if live {
            match shared.shape.try_lock() {
                Ok(s) => shape = s.clone(),
                Err(_) => timing.lock_busy += 1,
            }
            let m = haptic.manipulate(tip, &shape.x_m, shape.peer_grip);
            let force = match (m.grip, shape.reaction) {
                (Some(g), Some(r)) if r.node == g.node => r.force_at(g.node_m),
                _ => V3::zeros(),
            };
            (m, force)
        } else {
            (Manipulation::free(tip), V3::zeros())
        };
        run.contact_ticks += u64::from(m.grip.is_some());
        run.max_force = run.max_force.max(force.norm());
        let ok_net = offer(
            &to_net,
            &mut net_backlog,
            (k as u32, m),
            &mut timing.backlogged,
        );
        let ok_def = offer(&to_deform, &mut def_backlog, (k, m), &mut timing.backlogged);
        shared.haptic_tick.store(k, Ordering::Relaxed);
        if live {
            let lag = (k + 1).saturating_sub(shared.committed_tick.load(Ordering::Relaxed));
            run.lag.record(lag);
            shared.lag_ticks.store(lag, Ordering::Relaxed);
            shared.lag_max_ticks.fetch_max(lag, Ordering::Relaxed);
            if k % every == 0 {
                run.trace.push(ForceRow {
                    tick: k,
                    tip_m: arr(tip),
                    force_n: arr(force),
                    contact: m.grip.is_some(),
                });
            }
            let late = run.late_us.last().copied().unwrap_or(0.0);
            if late >= 1000.0 {
                shared.missed_ticks.fetch_add(1, Ordering::Relaxed);
            }
            run.work_us.push(start.elapsed().as_secs_f64() * 1e6);
        }
        if !(ok_net && ok_def) {
            shared.abort.store(true, Ordering::Relaxed);
            return Err(TetError::Site(format!(
                "tick {k}: the network or deformation thread took no input for {CHANNEL_TICKS} ticks"
            )));
        }
        k += 1;
    }
    // Hand over what is left, waiting now that the real-time part is over.
    for item in net_backlog {
        to_net.send(item).ok();
    }
    for item in def_backlog {
        to_deform.send(item).ok();
    }
    shared.haptic_done.store(true, Ordering::Relaxed);
    finish_timing(&mut timing, &mut run);
    Ok(HapticOut {
        timing,
        trace: run.trace,
        contact_ticks: run.contact_ticks,
        max_force_n: run.max_force,
        lag: run.lag,
    })
}

/// The haptic timing from the lateness and work of every live tick.
fn finish_timing(timing: &mut HapticTiming, run: &mut HapticRun) {
    let late_us = &mut run.late_us;
    timing.ticks = late_us.len() as u64;
    timing.missed_ticks = late_us.iter().filter(|l| **l >= 1000.0).count() as u64;
    timing.work_mean_us = run.work_us.iter().sum::<f64>() / run.work_us.len().max(1) as f64;
    timing.work_max_us = run.work_us.iter().copied().fold(0.0, f64::max);
    late_us.sort_by(f64::total_cmp);
    timing.late_p50_us = quantile(late_us, 0.5);
    timing.late_p99_us = quantile(late_us, 0.99);
    timing.late_p999_us = quantile(late_us, 0.999);
    timing.late_max_us = late_us.last().copied().unwrap_or(0.0);
}

pub(super) struct DeformOut {
    pub(super) timing: DeformationTiming,
    pub(super) replicas: Replicas,
}

/// Publishes the speculative shape and the committed tick and hash.
fn publish(
    replicas: &Replicas,
    shared: &Shared,
    grip_node: Option<u16>,
    retired: &mut Vec<Arc<Snapshot>>,
) {
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
    // The haptic thread must never free a snapshot: free() of memory this
    // thread allocated takes this thread's malloc arena lock, which a
    // preempted deformation thread may hold. With the frees here the
    // haptic loop's worst lateness in 10 s runs fell from 26–36 ms to
    // about 6 ms. Snapshots are freed once only this list holds them.
    retired.retain(|a| Arc::strong_count(a) > 1);
    let c = replicas.committed();
    shared.committed_hash.store(c.bit_hash(), Ordering::Release);
    shared.committed_tick.store(c.tick, Ordering::Release);
}

pub(super) fn deformation_thread(
    mut replicas: Replicas,
    shared: &Shared,
    local: Receiver<(u64, Manipulation)>,
    remote: Receiver<PeerEvent>,
    state_tx: SyncSender<State>,
) -> Result<DeformOut> {
    let t0 = Instant::now();
    let mut timing = DeformationTiming::default();
    let mut busy = Duration::ZERO;
    let mut grip_node = None;
    // A restarted peer waits for the committed state at this tick.
    let mut resync: Option<u64> = None;
    // Published snapshots the haptic or display thread may still hold.
    let mut retired: Vec<Arc<Snapshot>> = Vec::new();
    loop {
        if shared.abort.load(Ordering::Relaxed) {
            return Err(TetError::Site("stopped: another thread failed".into()));
        }
        let mut work = false;
        while let Ok((t, m)) = local.try_recv() {
            replicas.push_local(t, m)?;
            grip_node = m.grip.map(|g| g.node);
            work = true;
        }
        if let Some(tick) = resync {
            if replicas.local_end() >= tick {
                let state = replicas.resync_at(tick)?;
                state_tx.send(state).ok();
                resync = None;
                work = true;
            }
        }
        while resync.is_none() {
            match remote.try_recv() {
                Ok(PeerEvent::Input(t, m)) => replicas.push_remote(t, m)?,
                Ok(PeerEvent::Resync(tick)) => resync = Some(tick),
                Err(_) => break,
            }
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
            timing.ticks_computed += after.saturating_sub(before);
            publish(&replicas, shared, grip_node, &mut retired);
            timing.updates += 1;
            busy += started.elapsed();
        } else {
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

pub(super) fn display_thread(shared: &Shared, t0: Instant) -> (DisplayTiming, Vec<[f64; 3]>) {
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
