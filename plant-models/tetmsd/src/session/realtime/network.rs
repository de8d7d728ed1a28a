//! The network side of a site: the handshake until the session starts,
//! then the network thread — the UDP socket, the link (acks, resends), the
//! emulator in the sending path, state transfers to a restarted peer, the
//! status line, and the bye of both sides.
use super::threads::schedule_fifo;
use super::{io_error, PeerEvent, Shared, SiteSetup, SiteStatus, CHANNEL_TICKS, NET_POLL_US};
use super::{DRAIN_LIMIT, LINGER, STOP_DURATION, STOP_NONE, STOP_PEER, STOP_USER};
use crate::error::{Result, TetError};
use crate::model::probe::{ContactGeometry, Manipulation};
use crate::model::voigt::State;
use crate::session::control::{Control, Event};
use crate::session::link::{Arrival, Link};
use crate::session::netem::Emulator;
use crate::session::packet::{Bye, ByeReason, Message, Packet, VERSION};
use crate::session::pair::Haptic;
use crate::session::report::EndReport;
use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError};
use std::thread;
use std::time::{Duration, Instant};

/// How often a stopping or done site repeats its bye (µs).
const BYE_EVERY_US: u64 = 20_000;

/// How a session started for this site.
#[derive(Clone, Debug)]
pub(super) struct Started {
    /// The instant local times (µs) count from.
    pub(super) epoch: Instant,
    /// The committed state's tick (0 for a new session): this site's
    /// ticks from here to `first_tick` are "no contact".
    pub(super) start_tick: u64,
    /// The first tick with live input.
    pub(super) first_tick: u64,
    /// Local time (µs) at which it begins.
    pub(super) at_us: u64,
    /// The state a joining site starts from.
    pub(super) state: Option<State>,
    /// The handshake's round trip (µs).
    pub(super) rtt_us: Option<u64>,
}

/// What the network thread hands back.
pub(super) struct NetOut {
    pub(super) link: Link,
    pub(super) emulator: Option<Emulator>,
    pub(super) send_errors: u64,
    pub(super) scheduling: String,
    pub(super) end: EndReport,
    pub(super) notes: Vec<String>,
}

/// The end of the session as this site sees it.
#[derive(Clone, Debug, Default)]
struct Ending {
    /// This site's tick count and why it stopped.
    own: Option<(u64, ByeReason)>,
    /// The peer's.
    peer: Option<(u64, ByeReason)>,
    /// (end tick, hash) this site said "done" with.
    own_done: Option<(u64, u64)>,
    /// The peer's.
    peer_done: Option<(u64, u64)>,
    last_bye_us: Option<u64>,
    done_at: Option<Instant>,
    peer_done_at: Option<Instant>,
}

/// The network side of a site.
pub(super) struct Net<'a> {
    setup: &'a SiteSetup,
    socket: UdpSocket,
    peer: SocketAddr,
    link: Link,
    control: Control,
    geometry: ContactGeometry,
    nodes: usize,
    emulator: Option<Emulator>,
    epoch: Instant,
    /// Peer inputs and re-synchronisations the deformation thread has not
    /// taken yet.
    backlog: VecDeque<PeerEvent>,
    send_errors: u64,
    notes: Vec<String>,
    ending: Ending,
    last_ack_us: u64,
    last_heard: Instant,
    waiting_state: bool,
    last_status: Instant,
}

impl<'a> Net<'a> {
    /// The network side of `setup` over `socket` to `peer`.
    pub(super) fn new(
        setup: &'a SiteSetup,
        socket: UdpSocket,
        peer: SocketAddr,
        haptic: &Haptic,
        nodes: usize,
        epoch: Instant,
    ) -> Result<Self> {
        socket
            .set_nonblocking(true)
            .map_err(io_error("cannot make the UDP socket non-blocking"))?;
        let emulator = match setup.netem {
            Some(cfg) => Some(Emulator::new(cfg, setup.seed, setup.site)?),
            None => None,
        };
        Ok(Net {
            setup,
            socket,
            peer,
            link: Link::new(setup.site, setup.session.link),
            control: Control::new(setup.site, setup.session.fields(), setup.nonce),
            geometry: haptic.geometry().clone(),
            nodes,
            emulator,
            epoch,
            backlog: VecDeque::new(),
            send_errors: 0,
            notes: Vec::new(),
            ending: Ending::default(),
            last_ack_us: 0,
            last_heard: Instant::now(),
            waiting_state: false,
            last_status: Instant::now(),
        })
    }

    fn now_us(&self) -> u64 {
        self.epoch.elapsed().as_micros() as u64
    }

    /// Sends `bytes` through the emulator (if any) or straight out.
    fn send(&mut self, now_us: u64, bytes: Vec<u8>) {
        match &mut self.emulator {
            Some(e) => e.push(now_us, bytes),
            None => {
                if self.socket.send_to(&bytes, self.peer).is_err() {
                    self.send_errors += 1;
                }
            }
        }
    }

    fn send_all(&mut self, now_us: u64, packets: Vec<Vec<u8>>) {
        for p in packets {
            self.send(now_us, p);
        }
    }

    /// Sends the packets the emulator releases now.
    fn release_due(&mut self, now_us: u64) {
        if let Some(e) = &mut self.emulator {
            while let Some(bytes) = e.pop_due(now_us) {
                if self.socket.send_to(&bytes, self.peer).is_err() {
                    self.send_errors += 1;
                }
            }
        }
    }

    /// The next datagram, if one is waiting: refuses another protocol
    /// version by name.
    fn recv(&mut self, buf: &mut [u8; 2048]) -> Result<Option<usize>> {
        // Empty (WouldBlock) or a transient error: nothing this pass.
        let Ok((len, from)) = self.socket.recv_from(buf) else {
            return Ok(None);
        };
        self.last_heard = Instant::now();
        if len >= 64 && buf[26] != VERSION && !self.control.running() {
            return Err(TetError::Site(format!(
                "refused the peer at {from}: it speaks protocol version {}, this site version {VERSION}",
                buf[26]
            )));
        }
        Ok(Some(len))
    }

    /// Looks for the peer until the session starts (a new one, or a
    /// running one joined by state transfer).
    pub(super) fn connect(&mut self) -> Result<Started> {
        let timeout = self.setup.connect_timeout;
        let mut buf = [0u8; 2048];
        loop {
            if self.setup.stop.load(Ordering::Relaxed) != 0 {
                return Err(TetError::Site(format!(
                    "stopped while looking for the peer at {}",
                    self.peer
                )));
            }
            let now = self.now_us();
            let hellos = self.control.poll(now);
            self.send_all(now, hellos);
            self.release_due(now);
            let mut got = false;
            while let Some(len) = self.recv(&mut buf)? {
                got = true;
                let now = self.now_us();
                match self
                    .link
                    .on_datagram(now, &buf[..len], &self.geometry, self.nodes)
                {
                    Arrival::Inputs(inputs) => {
                        for (tick, input) in inputs {
                            self.backlog
                                .push_back(PeerEvent::Input(u64::from(tick), input));
                        }
                    }
                    Arrival::Control(p) => {
                        if let Some(s) = self.on_connect_packet(now, &p)? {
                            return Ok(s);
                        }
                    }
                    Arrival::Nothing => {}
                }
            }
            if self.epoch.elapsed() > timeout {
                return Err(TetError::Site(format!(
                    "no session with the peer at {} in {} s (its hello {})",
                    self.peer,
                    timeout.as_secs(),
                    if self.control.rtt_us().is_some() {
                        "came, but no start followed"
                    } else {
                        "never came"
                    }
                )));
            }
            if !got {
                thread::sleep(Duration::from_micros(NET_POLL_US));
            }
        }
    }

    /// One handshake packet before the session: the start, a refusal, or
    /// nothing yet.
    fn on_connect_packet(&mut self, now: u64, p: &Packet) -> Result<Option<Started>> {
        let (events, replies) = self.control.on_packet(now, p);
        self.send_all(now, replies);
        for e in events {
            match e {
                Event::Start {
                    first_tick,
                    at_us,
                    state,
                } => {
                    let start_tick = state.as_ref().map_or(0, |s| s.tick);
                    if state.is_some() {
                        self.link.rebase(start_tick as u32);
                        self.backlog.clear();
                    }
                    if let Some(r) = self.control.rtt_us() {
                        self.link.seed_rtt(r);
                    }
                    return Ok(Some(Started {
                        epoch: self.epoch,
                        start_tick,
                        first_tick,
                        at_us,
                        state,
                        rtt_us: self.control.rtt_us(),
                    }));
                }
                Event::Refused(why) => {
                    self.link
                        .refuse(crate::session::packet::Malformed::WrongPeer);
                    return Err(TetError::Site(format!(
                        "refused the peer at {}: {why}",
                        self.peer
                    )));
                }
                Event::Stranger(who) => self.notes.push(who),
                Event::PeerRestarted | Event::PeerHasState(_) => {}
            }
        }
        Ok(None)
    }

    /// The network thread: until both sides have the session's end and
    /// said so, passes of local inputs out, due packets released,
    /// datagrams in, peer inputs on to the deformation thread.
    pub(super) fn run(
        mut self,
        shared: &Shared,
        from_haptic: Receiver<(u32, Manipulation)>,
        to_deform: SyncSender<PeerEvent>,
        state_rx: Receiver<State>,
    ) -> Result<NetOut> {
        // The network thread times the emulator's releases and the acks:
        // one step below the haptic thread when that one is real-time.
        let scheduling = schedule_fifo(self.setup.rt_priority.saturating_sub(1));
        loop {
            if shared.abort.load(Ordering::Relaxed) {
                return Err(TetError::Site("stopped: another thread failed".into()));
            }
            let now = self.now_us();
            self.send_local(&from_haptic, shared, now)?;
            if self.waiting_state {
                if let Ok(state) = state_rx.try_recv() {
                    self.control.offer(state);
                    self.waiting_state = false;
                    shared.resyncs.fetch_add(1, Ordering::Relaxed);
                }
            }
            let mut out = self.link.report_packets(now);
            out.extend(self.link.poll(now));
            out.extend(self.control.poll(now));
            self.send_all(now, out);
            self.acks_when_quiet(now);
            self.bye(shared, now);
            self.release_due(now);
            let got = self.receive(shared)?;
            self.hand_on(&to_deform)?;
            self.status(shared);
            if self.finished() {
                break;
            }
            if got == 0 {
                thread::sleep(Duration::from_micros(NET_POLL_US));
            }
            self.check_drain(shared)?;
        }
        let end = self.end_report();
        Ok(NetOut {
            link: self.link,
            emulator: self.emulator,
            send_errors: self.send_errors,
            scheduling,
            end,
            notes: self.notes,
        })
    }

    /// The haptic thread's new inputs into the link; when it has made its
    /// last, this site's tick count and reason.
    fn send_local(
        &mut self,
        from_haptic: &Receiver<(u32, Manipulation)>,
        shared: &Shared,
        now: u64,
    ) -> Result<()> {
        loop {
            match from_haptic.try_recv() {
                Ok((tick, m)) => {
                    if let Some(bytes) = self.link.send_input(now, tick, m)? {
                        self.send(now, bytes);
                    }
                }
                Err(TryRecvError::Empty) => return Ok(()),
                Err(TryRecvError::Disconnected) => {
                    if self.ending.own.is_none() {
                        let reason = match shared.stop.load(Ordering::Relaxed) {
                            STOP_USER => ByeReason::User,
                            STOP_PEER => ByeReason::Peer,
                            _ => ByeReason::Duration,
                        };
                        self.ending.own = Some((u64::from(self.link.sent_ticks()), reason));
                    }
                    return Ok(());
                }
            }
        }
    }

    /// Acks when no inputs carry them: after this site's last input, and
    /// while its inputs are held for a restarted peer.
    fn acks_when_quiet(&mut self, now: u64) {
        let quiet = self.ending.own.is_some() || self.control.resyncing();
        if quiet && (self.link.owes_ack() || now >= self.last_ack_us + 10_000) {
            let bytes = self.link.ack_packet();
            self.send(now, bytes);
            self.last_ack_us = now;
        }
    }

    /// The bye of this site: "stopping" until the end tick is known and
    /// committed and this site's inputs up to it are acknowledged, then
    /// "done" with the hash, both repeated.
    fn bye(&mut self, shared: &Shared, now: u64) {
        let Some((own_ticks, reason)) = self.ending.own else {
            return;
        };
        let e = &mut self.ending;
        if e.own_done.is_none() {
            if let Some((peer_ticks, _)) = e.peer {
                let end = own_ticks.min(peer_ticks);
                let committed = shared.committed_tick.load(Ordering::Acquire);
                if committed >= end && self.link.acknowledged_below(end as u32) {
                    let hash = shared.committed_hash.load(Ordering::Acquire);
                    e.own_done = Some((end, hash));
                    e.done_at = Some(Instant::now());
                    e.last_bye_us = None;
                }
            }
        }
        if e.last_bye_us.is_some_and(|t| now < t + BYE_EVERY_US) {
            return;
        }
        e.last_bye_us = Some(now);
        let bye = match e.own_done {
            Some((end_tick, state_hash)) => Bye::Done {
                reason,
                end_tick,
                state_hash,
            },
            None => Bye::Stopping(reason),
        };
        let bytes = self.link.with_acks(|next_tick, acks| Message::Bye {
            next_tick,
            acks,
            bye,
        });
        self.send(now, bytes);
    }

    /// Takes up to 64 datagrams from the socket; returns how many came.
    fn receive(&mut self, shared: &Shared) -> Result<usize> {
        let mut buf = [0u8; 2048];
        let mut got = 0;
        while got < 64 {
            let Some(len) = self.recv(&mut buf)? else {
                break;
            };
            got += 1;
            let now = self.now_us();
            match self
                .link
                .on_datagram(now, &buf[..len], &self.geometry, self.nodes)
            {
                Arrival::Inputs(inputs) => {
                    if self.control.resyncing() && !self.waiting_state {
                        // The restarted peer runs: it has the state.
                        self.control.peer_is_running();
                        self.link.set_paused(false);
                    }
                    for (tick, input) in inputs {
                        self.backlog
                            .push_back(PeerEvent::Input(u64::from(tick), input));
                    }
                }
                Arrival::Control(p) => self.on_control(shared, now, &p),
                Arrival::Nothing => {}
            }
            for p in self.link.poll(now) {
                self.send(now, p);
            }
        }
        Ok(got)
    }

    /// A handshake, state or bye packet during the session.
    fn on_control(&mut self, shared: &Shared, now: u64, p: &Packet) {
        if let Message::Bye { next_tick, bye, .. } = p.message {
            self.on_bye(shared, u64::from(next_tick), bye);
            return;
        }
        let (events, replies) = self.control.on_packet(now, p);
        self.send_all(now, replies);
        for e in events {
            match e {
                Event::PeerRestarted => self.begin_resync(),
                Event::PeerHasState(_) => self.link.set_paused(false),
                Event::Refused(why) => self.notes.push(format!("refused a peer: {why}")),
                Event::Stranger(who) => self.notes.push(who),
                Event::Start { .. } => {}
            }
        }
    }

    /// A restarted peer: the session goes on from this site's next tick,
    /// with this site's inputs held until the peer has the state.
    fn begin_resync(&mut self) {
        let tick = self.link.sent_ticks();
        self.link.rebase(tick);
        self.link.set_paused(true);
        self.backlog.retain(|e| !matches!(e, PeerEvent::Input(..)));
        self.backlog.push_back(PeerEvent::Resync(u64::from(tick)));
        self.waiting_state = true;
        self.notes.push(format!(
            "the peer restarted; re-synchronised at tick {tick}"
        ));
    }

    fn on_bye(&mut self, shared: &Shared, next_tick: u64, bye: Bye) {
        let e = &mut self.ending;
        let reason = match bye {
            Bye::Stopping(r) | Bye::Done { reason: r, .. } => r,
        };
        if e.peer.is_none() {
            e.peer = Some((next_tick, reason));
        }
        if let Bye::Done {
            end_tick,
            state_hash,
            ..
        } = bye
        {
            if e.peer_done.is_none() {
                e.peer_done = Some((end_tick, state_hash));
                e.peer_done_at = Some(Instant::now());
            }
            // Answer at once: the peer waits for our word.
            e.last_bye_us = None;
        }
        // A peer that ran out its duration: this site runs up to the
        // peer's tick count (it may be a few ticks behind), then stops.
        if reason == ByeReason::Duration {
            shared.peer_end.fetch_min(next_tick, Ordering::Relaxed);
            return;
        }
        // The peer stops for another reason: so does this site, now.
        let _ = shared.stop.compare_exchange(
            STOP_NONE,
            STOP_PEER,
            Ordering::Relaxed,
            Ordering::Relaxed,
        );
    }

    /// Whether this site may leave: both "done" words exchanged and a
    /// short linger for the peer to hear ours, or the linger after ours
    /// is over without the peer's.
    fn finished(&self) -> bool {
        let e = &self.ending;
        let Some(done_at) = e.done_at else {
            return false;
        };
        let linger = Duration::from_micros((3.0 * self.link.srtt_us()) as u64)
            .max(Duration::from_millis(100));
        match e.peer_done_at {
            Some(t) => t.max(done_at).elapsed() > linger,
            None => done_at.elapsed() > LINGER,
        }
    }

    /// Hands peer inputs and re-synchronisations on to the deformation
    /// thread without waiting; fails when it has taken none for too long.
    fn hand_on(&mut self, to_deform: &SyncSender<PeerEvent>) -> Result<()> {
        while let Some(item) = self.backlog.pop_front() {
            match to_deform.try_send(item) {
                Ok(()) => {}
                Err(TrySendError::Full(x)) => {
                    self.backlog.push_front(x);
                    break;
                }
                Err(TrySendError::Disconnected(_)) => break,
            }
        }
        if self.backlog.len() > 2 * CHANNEL_TICKS {
            return Err(TetError::Site(format!(
                "the deformation thread took no peer input for {} ticks",
                self.backlog.len()
            )));
        }
        Ok(())
    }

    /// Fails when this site has stopped and the peer has been silent for
    /// [`DRAIN_LIMIT`].
    fn check_drain(&self, shared: &Shared) -> Result<()> {
        if self.ending.own.is_some() && self.last_heard.elapsed() > DRAIN_LIMIT {
            return Err(TetError::Site(format!(
                "the session did not end cleanly: nothing from the peer at {} for {} s after this site stopped (committed tick {})",
                self.peer,
                DRAIN_LIMIT.as_secs(),
                shared.committed_tick.load(Ordering::Relaxed)
            )));
        }
        Ok(())
    }

    /// Sends the status line when one is due (never waits).
    fn status(&mut self, shared: &Shared) {
        let Some((every, tx)) = &self.setup.status else {
            return;
        };
        if self.last_status.elapsed() < *every {
            return;
        }
        self.last_status = Instant::now();
        let s = self.link.stats();
        let phase = if self.ending.own_done.is_some() {
            "done"
        } else if self.ending.own.is_some() {
            "stopping"
        } else if self.control.resyncing() {
            "giving a restarted peer the state"
        } else {
            "running"
        };
        let now = self.now_us();
        let status = SiteStatus {
            site: self.setup.site,
            clock_s: self.control.clock_us(now).unwrap_or(0) as f64 * 1e-6,
            phase: phase.into(),
            tick: shared.haptic_tick.load(Ordering::Relaxed),
            committed_tick: shared.committed_tick.load(Ordering::Relaxed),
            rtt_mean_ms: s.rtt_mean_us() / 1000.0,
            srtt_ms: self.link.srtt_us() / 1000.0,
            inputs_sent: s.inputs_sent,
            resent: s.retransmissions,
            gaps_seen: s.gaps_seen,
            inputs_received: s.inputs_received,
            lag_ms: shared.lag_ticks.load(Ordering::Relaxed),
            lag_max_ms: shared.lag_max_ticks.swap(0, Ordering::Relaxed),
            missed_ticks: shared.missed_ticks.load(Ordering::Relaxed),
            resyncs: shared.resyncs.load(Ordering::Relaxed),
        };
        let _ = tx.try_send(status);
    }

    /// The end as this site saw it.
    fn end_report(&self) -> EndReport {
        let e = &self.ending;
        EndReport {
            reason: e.own.map_or("", |(_, r)| r.describe()).to_string(),
            own_ticks: e.own.map_or(0, |(t, _)| t),
            peer_ticks: e.peer.map(|(t, _)| t),
            peer_reason: e.peer.map(|(_, r)| r.describe().to_string()),
            end_tick: e.own_done.map(|(t, _)| t),
            own_hash: e.own_done.map(|(_, h)| format!("{h:016x}")),
            peer_hash: e.peer_done.map(|(_, h)| format!("{h:016x}")),
            peer_confirmed: match (e.own_done, e.peer_done) {
                (Some(a), Some(b)) => Some(a == b),
                _ => None,
            },
        }
    }
}

/// Why the haptic thread stopped, as a bye reason (for the threads).
pub(super) fn stop_code(duration_over: bool) -> u8 {
    if duration_over {
        STOP_DURATION
    } else {
        STOP_USER
    }
}
