//! The network side of a site: the hello handshake, then the network
//! thread — the UDP socket, the link (acks, resends), the emulator in the
//! sending path, and the bye that ends a session both sides completed.
use super::threads::schedule_fifo;
use super::{io_error, NET_POLL_US};
use super::{NetParts, Shared, SiteSetup, CHANNEL_TICKS, DRAIN_LIMIT, HELLO_TIMEOUT, LINGER};
use crate::error::{Result, TetError};
use crate::model::probe::{ContactGeometry, Manipulation};
use crate::session::link::{Arrival, Link};
use crate::session::netem::Emulator;
use crate::session::packet::{Message, Packet};
use std::collections::VecDeque;
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::Ordering;
use std::sync::mpsc::{Receiver, SyncSender, TryRecvError, TrySendError};
use std::thread;
use std::time::{Duration, Instant};

/// A hello packet of `link` for the configuration `hash`, with `seq = 1`
/// when it says "I have heard yours".
fn hello(link: &mut Link, hash: u64, seq: u32) -> Result<[u8; 64]> {
    let mut p =
        Packet::decode(&link.hello_packet(hash)).map_err(|e| TetError::Site(e.to_string()))?;
    p.seq = seq;
    Ok(p.encode())
}

/// Waits for the peer's hello and answers it (a three-way handshake: a
/// hello with `seq = 1` says "I have heard yours"). Returns when both
/// sides know of each other.
pub(super) fn handshake(
    socket: &UdpSocket,
    peer: SocketAddr,
    link: &mut Link,
    hash: u64,
) -> Result<()> {
    let started = Instant::now();
    let mut heard = false;
    let mut last = None::<Instant>;
    let mut buf = [0u8; 128];
    loop {
        if started.elapsed() > HELLO_TIMEOUT {
            return Err(TetError::Site(format!(
                "no hello from the peer at {peer} in {} s",
                HELLO_TIMEOUT.as_secs()
            )));
        }
        if last.is_none_or(|t| t.elapsed() > Duration::from_millis(10)) {
            socket
                .send_to(&hello(link, hash, u32::from(heard))?, peer)
                .ok();
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
                    return Err(TetError::Site(format!(
                        "the peer at {peer} runs another configuration (hash {config_hash:016x}, ours {hash:016x}): level, cube and material must match"
                    )));
                }
                heard = true;
                if seq == 1 {
                    socket.send_to(&hello(link, hash, 1)?, peer).ok();
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

/// What the network thread hands back.
pub(super) struct NetOut {
    pub(super) link: Link,
    pub(super) emulator: Emulator,
    pub(super) send_errors: u64,
    pub(super) scheduling: String,
}

/// The network thread's state between passes.
struct Network<'a> {
    setup: &'a SiteSetup,
    shared: &'a Shared,
    t0: Instant,
    socket: UdpSocket,
    peer: SocketAddr,
    link: Link,
    geometry: &'a ContactGeometry,
    nodes: usize,
    emulator: Emulator,
    /// Peer inputs the deformation thread has not taken yet.
    backlog: VecDeque<(u64, Manipulation)>,
    send_errors: u64,
    /// The haptic thread has sent its last input.
    local_done: bool,
    last_ack_us: u64,
    bye_at: Option<Instant>,
    peer_bye: bool,
    last_input_at: Instant,
}

/// The network thread: until both sides have every tick and said bye,
/// passes of local inputs out, due packets released, datagrams in, peer
/// inputs on to the deformation thread.
pub(super) fn network_thread(
    setup: &SiteSetup,
    parts: NetParts<'_>,
    shared: &Shared,
    t0: Instant,
    from_haptic: Receiver<(u32, Manipulation)>,
    to_deform: SyncSender<(u64, Manipulation)>,
) -> Result<NetOut> {
    let emulator = Emulator::new(setup.netem, setup.seed, setup.site)?;
    // The network thread times the emulator's releases and the acks: one
    // step below the haptic thread when that one is real-time.
    let scheduling = schedule_fifo(setup.rt_priority.saturating_sub(1));
    parts
        .socket
        .set_nonblocking(true)
        .map_err(io_error("cannot make the UDP socket non-blocking"))?;
    let mut net = Network {
        setup,
        shared,
        t0,
        socket: parts.socket,
        peer: parts.peer,
        link: parts.link,
        geometry: parts.geometry,
        nodes: parts.nodes,
        emulator,
        backlog: VecDeque::new(),
        send_errors: 0,
        local_done: false,
        last_ack_us: 0,
        bye_at: None,
        peer_bye: false,
        last_input_at: t0,
    };
    loop {
        if shared.abort.load(Ordering::Relaxed) {
            return Err(TetError::Site("stopped: another thread failed".into()));
        }
        let now_us = t0.elapsed().as_micros() as u64;
        net.send_local(&from_haptic, now_us)?;
        net.release_due(now_us);
        let got = net.receive()?;
        net.hand_on(&to_deform)?;
        if net.finished(now_us) {
            break;
        }
        if got == 0 {
            thread::sleep(Duration::from_micros(NET_POLL_US));
        }
        net.check_drain()?;
    }
    Ok(NetOut {
        link: net.link,
        emulator: net.emulator,
        send_errors: net.send_errors,
        scheduling,
    })
}

impl Network<'_> {
    /// The haptic thread's new inputs, the link's due resends and, once
    /// the local inputs are over, the acks the peer is owed, into the
    /// emulator.
    fn send_local(
        &mut self,
        from_haptic: &Receiver<(u32, Manipulation)>,
        now_us: u64,
    ) -> Result<()> {
        loop {
            match from_haptic.try_recv() {
                Ok((tick, m)) => {
                    let bytes = self.link.send_input(now_us, tick, m)?;
                    self.emulator.push(now_us, bytes);
                    self.last_ack_us = now_us;
                }
                Err(TryRecvError::Empty) => break,
                Err(TryRecvError::Disconnected) => {
                    self.local_done = true;
                    break;
                }
            }
        }
        for bytes in self.link.poll(now_us) {
            self.emulator.push(now_us, bytes);
        }
        if self.local_done && (self.link.owes_ack() || now_us >= self.last_ack_us + 10_000) {
            let bytes = self.link.ack_packet();
            self.emulator.push(now_us, bytes);
            self.last_ack_us = now_us;
        }
        Ok(())
    }

    /// Sends the packets the emulator releases now.
    fn release_due(&mut self, now_us: u64) {
        while let Some(bytes) = self.emulator.pop_due(now_us) {
            if self.socket.send_to(&bytes, self.peer).is_err() {
                self.send_errors += 1;
            }
        }
    }

    /// Takes up to 64 datagrams from the socket; returns how many came.
    fn receive(&mut self) -> Result<usize> {
        let mut buf = [0u8; 128];
        let mut got = 0;
        while got < 64 {
            // Empty (WouldBlock) or a transient error: try again next pass.
            let Ok((len, _)) = self.socket.recv_from(&mut buf) else {
                break;
            };
            got += 1;
            let now_us = self.t0.elapsed().as_micros() as u64;
            match self
                .link
                .on_datagram(now_us, &buf[..len], self.geometry, self.nodes)
            {
                Arrival::Input { tick, input } => {
                    self.last_input_at = Instant::now();
                    self.backlog.push_back((u64::from(tick), input));
                }
                Arrival::Hello(_) => {
                    // The peer missed our last hello: tell it again,
                    // through the emulated network like everything else.
                    let bytes = hello(&mut self.link, self.setup.session.hash(), 1)?;
                    self.emulator.push(now_us, bytes);
                }
                Arrival::Bye => self.peer_bye = true,
                Arrival::Nothing => {}
            }
        }
        Ok(got)
    }

    /// Hands the peer inputs on to the deformation thread without waiting;
    /// fails when it has taken none for too long.
    fn hand_on(&mut self, to_deform: &SyncSender<(u64, Manipulation)>) -> Result<()> {
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

    /// Says bye (three times) once this site is complete, and tells when
    /// to stop: the peer's bye came, or the linger after ours is over.
    fn finished(&mut self, now_us: u64) -> bool {
        let complete = self.local_done
            && self.link.all_acknowledged()
            && self.backlog.is_empty()
            && self.shared.committed_tick.load(Ordering::Relaxed) >= self.setup.duration_ticks;
        if complete && self.bye_at.is_none() {
            for _ in 0..3 {
                let bytes = self.link.bye_packet();
                self.emulator.push(now_us, bytes);
            }
            self.bye_at = Some(Instant::now());
        }
        self.bye_at
            .is_some_and(|t| self.peer_bye || t.elapsed() > LINGER)
    }

    /// Fails when the local inputs are over and no peer input came for
    /// [`DRAIN_LIMIT`].
    fn check_drain(&self) -> Result<()> {
        if self.local_done && self.last_input_at.elapsed() > DRAIN_LIMIT {
            return Err(TetError::Site(format!(
                "the session did not complete: no peer input for {} s (committed tick {} of {})",
                DRAIN_LIMIT.as_secs(),
                self.shared.committed_tick.load(Ordering::Relaxed),
                self.setup.duration_ticks
            )));
        }
        Ok(())
    }
}
