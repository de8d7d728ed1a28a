//! The session's control plane as pure logic (time passed in, no socket):
//! the handshake that agrees on the configuration and starts both sites'
//! clocks together, and the state transfer that brings a restarted peer
//! back into a running session.
//!
//! **Handshake.** A site that is not yet in a session sends a hello every
//! [`HELLO_EVERY_US`]: its configuration ([`SessionFields`], the hash of
//! it, a random nonce for this start of the process) and the echo of the
//! peer's last hello (its serial and how long it was held), from which
//! each side measures the round trip. A hello of another configuration is
//! refused, naming each field that differs, and a fresh site answers it
//! with its own hello (so a peer that started later learns why too). When both sites are fresh,
//! site 0 — once it has heard site 1 and has [`RTT_SAMPLES`] round trips —
//! starts a new session: it sends `go` with its session clock, negative by
//! half the smallest round trip, and starts tick 0 that much later; site 1
//! starts tick 0 when `go` arrives, half a round trip after it was sent.
//! So the two clocks agree to the path's asymmetry. Site 0 answers every
//! later hello of the same peer with `go` (a `go` can be lost).
//!
//! **A peer restarts.** A running site that hears a fresh hello with a
//! new nonce re-synchronises it: the caller picks the tick `R` (its next
//! input), takes the committed replica to `R` with the peer's missing
//! ticks as "no contact" ([`super::replica::Replicas::resync_at`]), and
//! hands the state to [`Control::offer`]. The state goes out as one packet
//! per node plus a summary (hash, session clock), whole rounds repeated
//! every [`Control::round_us`] until the peer says it has the state. The
//! joining site assembles it, checks the hash, and starts at the session
//! tick the peer's clock says it is at: its ticks from `R` up to then are
//! "no contact" inputs, sent at once.
//!
//! Left out: two running sites of different sessions meeting (the second
//! is refused and ignored), and a peer that stays away longer than the
//! link's window (the session then stops with a named error).
use super::packet::{Echo, Hello, Message, Packet, SessionFields, Stage, StateChunk};
use crate::model::voigt::State;
use crate::model::V3;
use std::collections::VecDeque;
use std::sync::Arc;

/// Hello period while looking for the peer (µs).
pub const HELLO_EVERY_US: u64 = 10_000;
/// Round trips site 0 measures before it starts a session.
pub const RTT_SAMPLES: usize = 3;

/// What the caller must do.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// Start the session clock: tick `first_tick` begins at local time
    /// `at_us`. `state`: the committed state to start from (a join), with
    /// the ticks from `state.tick` to `first_tick` filled by "no contact".
    Start {
        /// The first tick with live input.
        first_tick: u64,
        /// Local time (µs) at which it begins.
        at_us: u64,
        /// The state transferred from the peer, for a join.
        state: Option<State>,
    },
    /// A fresh peer with a new nonce: it restarted. Re-synchronise it
    /// ([`Control::offer`]).
    PeerRestarted,
    /// The peer has the state offered at this tick.
    PeerHasState(u32),
    /// The peer runs another configuration (or speaks it wrongly): the
    /// reason names every field. Fatal before a session; a running site
    /// ignores that peer.
    Refused(String),
    /// A hello of a site that runs some other session (ignored).
    Stranger(String),
}

/// Where this site is.
#[derive(Clone, Debug)]
enum Phase {
    /// Looking for the peer.
    Fresh,
    /// Receiving the state of `tick` from a running peer.
    Joining(Assembly),
    /// In the session.
    Running,
    /// In the session; a restarted peer waits for the state the caller is
    /// preparing.
    Preparing,
    /// In the session, giving a restarted peer the state of `tick`.
    Offering {
        tick: u32,
        state: Arc<State>,
        last_round_us: Option<u64>,
    },
}

/// A state being assembled from its packets.
#[derive(Clone, Debug)]
struct Assembly {
    tick: u32,
    nodes: Vec<Option<(V3, V3)>>,
    /// (hash, the peer's clock, when it arrived).
    summary: Option<(u64, i64, u64)>,
}

/// One site's control plane.
#[derive(Clone, Debug)]
pub struct Control {
    site: u8,
    fields: SessionFields,
    hash: u64,
    nonce: u32,
    serial: u16,
    /// (serial, sent µs) of this site's recent hellos.
    sent: VecDeque<(u16, u64)>,
    /// The peer's last hello serial and when it arrived.
    heard: Option<(u16, u64)>,
    peer_nonce: Option<u32>,
    rtt_samples: Vec<u64>,
    last_hello_us: Option<u64>,
    /// This site's session clock: tick k begins at local `origin + k·1000`
    /// (µs, may be negative).
    origin_us: Option<i64>,
    phase: Phase,
}

impl Control {
    /// The control plane of site `site` running `fields`, with `nonce`
    /// for this start of the process.
    pub fn new(site: u8, fields: SessionFields, nonce: u32) -> Self {
        Control {
            site: site & 1,
            fields,
            hash: fields.hash(),
            nonce,
            serial: 0,
            sent: VecDeque::new(),
            heard: None,
            peer_nonce: None,
            rtt_samples: Vec::new(),
            last_hello_us: None,
            origin_us: None,
            phase: Phase::Fresh,
        }
    }

    /// Whether the session runs (started, or joined).
    pub fn running(&self) -> bool {
        matches!(
            self.phase,
            Phase::Running | Phase::Preparing | Phase::Offering { .. }
        )
    }

    /// Whether a restarted peer is waiting for, or being given, a state.
    pub fn resyncing(&self) -> bool {
        matches!(self.phase, Phase::Preparing | Phase::Offering { .. })
    }

    /// The restarted peer sends inputs: it has the state (its word that
    /// it does was lost).
    pub fn peer_is_running(&mut self) {
        if matches!(self.phase, Phase::Offering { .. }) {
            self.phase = Phase::Running;
        }
    }

    /// The smallest round trip the hellos measured (µs).
    pub fn rtt_us(&self) -> Option<u64> {
        self.rtt_samples.iter().copied().min()
    }

    /// This site's session clock at local time `now_us` (µs: tick k
    /// begins at k·1000), once it runs.
    pub fn clock_us(&self, now_us: u64) -> Option<i64> {
        self.origin_us.map(|o| now_us as i64 - o)
    }

    /// What a stranger's or a mismatching hello is called.
    fn describe(&self, h: &Hello) -> Option<String> {
        let named = self.fields.mismatches(&h.fields);
        if !named.is_empty() {
            return Some(format!(
                "the peer runs another configuration: {}",
                named.join("; ")
            ));
        }
        if h.config_hash != self.hash {
            return Some(format!(
                "the peer's configuration hash {:016x} is not the hash of its fields ({:016x}): it computes the hash differently",
                h.config_hash, self.hash
            ));
        }
        None
    }

    fn hello(&mut self, now_us: u64, stage: Stage) -> Vec<u8> {
        self.serial = self.serial.wrapping_add(1);
        self.sent.push_back((self.serial, now_us));
        if self.sent.len() > 64 {
            self.sent.pop_front();
        }
        self.last_hello_us = Some(now_us);
        let echo = self.heard.map(|(serial, at)| Echo {
            serial,
            hold_us: now_us.saturating_sub(at).min(0xFFFE) as u16,
        });
        Packet {
            site: self.site,
            message: Message::Hello(Hello {
                stage,
                serial: self.serial,
                echo,
                fields: self.fields,
                config_hash: self.hash,
                nonce: self.nonce,
            }),
        }
        .encode()
    }

    fn take_echo(&mut self, now_us: u64, h: &Hello) {
        self.heard = Some((h.serial, now_us));
        if let Some(e) = h.echo {
            if let Some((_, sent)) = self.sent.iter().find(|(s, _)| *s == e.serial) {
                let rtt = now_us.saturating_sub(*sent + u64::from(e.hold_us));
                self.rtt_samples.push(rtt);
                if self.rtt_samples.len() > 16 {
                    self.rtt_samples.remove(0);
                }
            }
        }
    }

    /// Packets due at `now_us`: hellos while looking for the peer, state
    /// rounds while offering. `committed_tick` is what a running site
    /// reports in its hellos.
    pub fn poll(&mut self, now_us: u64) -> Vec<Vec<u8>> {
        let due = self
            .last_hello_us
            .is_none_or(|t| now_us >= t + HELLO_EVERY_US);
        match &self.phase {
            Phase::Fresh | Phase::Joining(_) if due => {
                vec![self.hello(
                    now_us,
                    Stage::Hello {
                        committed_tick: None,
                    },
                )]
            }
            Phase::Offering {
                tick,
                state,
                last_round_us,
            } => {
                let round = self.round_us();
                if last_round_us.is_some_and(|t| now_us < t + round) {
                    return Vec::new();
                }
                let (tick, state) = (*tick, state.clone());
                if let Phase::Offering { last_round_us, .. } = &mut self.phase {
                    *last_round_us = Some(now_us);
                }
                let mut out = vec![self.hello(now_us, Stage::StateFollows { state_tick: tick })];
                let clock = self.clock_us(now_us).unwrap_or(0);
                out.extend(state_packets(self.site, &state, clock));
                out
            }
            _ => Vec::new(),
        }
    }

    /// Time between two rounds of an offered state (µs): twice the round
    /// trip, at least 50 ms.
    pub fn round_us(&self) -> u64 {
        (2 * self.rtt_us().unwrap_or(0)).max(50_000)
    }

    /// Starts the session clock of a running site at `origin_us` (tick k
    /// begins at `origin + k·1000`); for a caller that started otherwise.
    pub fn set_origin(&mut self, origin_us: i64) {
        self.origin_us = Some(origin_us);
    }

    /// Starts offering `state` (the committed replica at its tick) to a
    /// restarted peer.
    pub fn offer(&mut self, state: State) {
        self.phase = Phase::Offering {
            tick: state.tick as u32,
            state: Arc::new(state),
            last_round_us: None,
        };
    }

    /// Takes in a hello or state packet at `now_us`; returns what to do
    /// and what to send at once.
    pub fn on_packet(&mut self, now_us: u64, packet: &Packet) -> (Vec<Event>, Vec<Vec<u8>>) {
        match &packet.message {
            Message::Hello(h) => self.on_hello(now_us, h),
            Message::State { tick, chunk } => self.on_state(now_us, *tick, chunk),
            _ => (Vec::new(), Vec::new()),
        }
    }

    fn on_hello(&mut self, now_us: u64, h: &Hello) -> (Vec<Event>, Vec<Vec<u8>>) {
        if let Some(why) = self.describe(h) {
            // Answer a fresh site's refusal with our own hello, so that a
            // peer which started later (and missed our earlier hellos)
            // hears our configuration and names the mismatch itself before
            // we go away.
            let answer = match self.phase {
                Phase::Fresh | Phase::Joining(_) => vec![self.hello(
                    now_us,
                    Stage::Hello {
                        committed_tick: None,
                    },
                )],
                _ => Vec::new(),
            };
            return (vec![Event::Refused(why)], answer);
        }
        let known = self.peer_nonce == Some(h.nonce);
        match (&self.phase, h.stage) {
            (
                Phase::Fresh,
                Stage::Hello {
                    committed_tick: None,
                },
            ) => {
                self.take_echo(now_us, h);
                if self.site == 0 && self.rtt_samples.len() >= RTT_SAMPLES {
                    return self.go(now_us, h.nonce);
                }
                (Vec::new(), Vec::new())
            }
            (Phase::Fresh | Phase::Joining(_), Stage::Go { clock_us }) if self.site == 1 => {
                self.take_echo(now_us, h);
                self.peer_nonce = Some(h.nonce);
                // Site 0's tick 0 begins `-clock_us` after it sent this,
                // which was half a round trip ago.
                let owd = self.rtt_us().map_or((-clock_us).max(0), |r| (r / 2) as i32);
                let origin = now_us as i64 - i64::from(owd) - i64::from(clock_us);
                self.origin_us = Some(origin);
                self.phase = Phase::Running;
                let at_us = origin.max(now_us as i64) as u64;
                let first_tick = ((at_us as i64 - origin) as u64).div_ceil(1000);
                let start = Event::Start {
                    first_tick,
                    at_us: (origin + 1000 * first_tick as i64) as u64,
                    state: None,
                };
                (vec![start], Vec::new())
            }
            (Phase::Fresh, Stage::StateFollows { state_tick })
            | (Phase::Joining(_), Stage::StateFollows { state_tick }) => {
                self.take_echo(now_us, h);
                self.peer_nonce = Some(h.nonce);
                let same = matches!(&self.phase, Phase::Joining(a) if a.tick == state_tick);
                if !same {
                    self.phase = Phase::Joining(Assembly {
                        tick: state_tick,
                        nodes: Vec::new(),
                        summary: None,
                    });
                }
                (Vec::new(), Vec::new())
            }
            (
                Phase::Running | Phase::Preparing | Phase::Offering { .. },
                Stage::Hello {
                    committed_tick: None,
                },
            ) if !known => {
                self.take_echo(now_us, h);
                self.peer_nonce = Some(h.nonce);
                self.phase = Phase::Preparing;
                (vec![Event::PeerRestarted], Vec::new())
            }
            (
                Phase::Running,
                Stage::Hello {
                    committed_tick: None,
                },
            ) if self.site == 0 => {
                // Our go was lost: say it again with the clock as it is now.
                self.take_echo(now_us, h);
                let clock = self.clock_us(now_us).unwrap_or(0);
                let go = Stage::Go {
                    clock_us: clock.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
                };
                (Vec::new(), vec![self.hello(now_us, go)])
            }
            (Phase::Running, Stage::StateFollows { state_tick }) if known => {
                // The peer did not hear that we have its state.
                self.take_echo(now_us, h);
                let ok = Stage::StateReceived { state_tick };
                (Vec::new(), vec![self.hello(now_us, ok)])
            }
            (Phase::Offering { tick, .. }, Stage::StateReceived { state_tick })
                if known && *tick == state_tick =>
            {
                self.take_echo(now_us, h);
                self.phase = Phase::Running;
                (vec![Event::PeerHasState(state_tick)], Vec::new())
            }
            (
                Phase::Running | Phase::Preparing | Phase::Offering { .. },
                Stage::Hello {
                    committed_tick: Some(t),
                },
            ) if !known => {
                let who = format!(
                    "a site of another session (nonce {:08x}, at tick {t}) was ignored",
                    h.nonce
                );
                (vec![Event::Stranger(who)], Vec::new())
            }
            _ => {
                self.take_echo(now_us, h);
                (Vec::new(), Vec::new())
            }
        }
    }

    /// Site 0 starts a new session with the peer `nonce`.
    fn go(&mut self, now_us: u64, nonce: u32) -> (Vec<Event>, Vec<Vec<u8>>) {
        let half = (self.rtt_us().unwrap_or(0) / 2) as i64;
        let origin = now_us as i64 + half;
        self.origin_us = Some(origin);
        self.peer_nonce = Some(nonce);
        self.phase = Phase::Running;
        let go = self.hello(
            now_us,
            Stage::Go {
                clock_us: -(half as i32),
            },
        );
        let start = Event::Start {
            first_tick: 0,
            at_us: origin as u64,
            state: None,
        };
        (vec![start], vec![go])
    }

    fn on_state(
        &mut self,
        now_us: u64,
        tick: u32,
        chunk: &StateChunk,
    ) -> (Vec<Event>, Vec<Vec<u8>>) {
        if self.running() {
            // A round after we started: the peer did not hear us.
            if matches!(self.phase, Phase::Running) && matches!(chunk, StateChunk::Summary { .. }) {
                let ok = Stage::StateReceived { state_tick: tick };
                return (Vec::new(), vec![self.hello(now_us, ok)]);
            }
            return (Vec::new(), Vec::new());
        }
        let Phase::Joining(a) = &mut self.phase else {
            return (Vec::new(), Vec::new());
        };
        if a.tick != tick {
            return (Vec::new(), Vec::new());
        }
        match *chunk {
            StateChunk::Node {
                index,
                count,
                x_m,
                v_m_s,
            } => {
                a.nodes.resize(usize::from(count), None);
                if let Some(slot) = a.nodes.get_mut(usize::from(index)) {
                    *slot = Some((x_m, v_m_s));
                }
            }
            StateChunk::Summary {
                count,
                state_hash,
                clock_us,
            } => {
                a.nodes.resize(usize::from(count), None);
                a.summary = Some((state_hash, clock_us, now_us));
            }
        }
        self.try_join(now_us)
    }

    /// Starts the session from an assembled state once it is whole and
    /// its hash checks.
    fn try_join(&mut self, now_us: u64) -> (Vec<Event>, Vec<Vec<u8>>) {
        let Phase::Joining(a) = &self.phase else {
            return (Vec::new(), Vec::new());
        };
        let Some((hash, peer_clock_us, arrived_us)) = a.summary else {
            return (Vec::new(), Vec::new());
        };
        if a.nodes.iter().any(Option::is_none) {
            return (Vec::new(), Vec::new());
        }
        let state = State {
            tick: u64::from(a.tick),
            x_m: a.nodes.iter().flatten().map(|n| n.0).collect(),
            v_m_s: a.nodes.iter().flatten().map(|n| n.1).collect(),
        };
        let tick = a.tick;
        if state.bit_hash() != hash {
            // Corrupted beyond the CRC, or a mix of two rounds: start over.
            self.phase = Phase::Joining(Assembly {
                tick,
                nodes: Vec::new(),
                summary: None,
            });
            return (Vec::new(), Vec::new());
        }
        // The peer's clock now: at the summary's sending, plus the way
        // here, plus the time since.
        let owd = (self.rtt_us().unwrap_or(0) / 2) as i64;
        let clock_now = peer_clock_us + owd + (now_us - arrived_us) as i64;
        let origin = now_us as i64 - clock_now;
        let first_tick = (clock_now.max(0) as u64)
            .div_ceil(1000)
            .max(u64::from(tick));
        self.origin_us = Some(origin);
        self.phase = Phase::Running;
        let ok = Stage::StateReceived { state_tick: tick };
        let reply = vec![self.hello(now_us, ok), self.hello(now_us, ok)];
        let start = Event::Start {
            first_tick,
            at_us: (origin + 1000 * first_tick as i64).max(now_us as i64) as u64,
            state: Some(state),
        };
        (vec![start], reply)
    }
}

/// The packets of `state`: one per node, then the summary with the
/// sender's session clock `clock_us`.
pub fn state_packets(site: u8, state: &State, clock_us: i64) -> Vec<Vec<u8>> {
    let count = state.x_m.len() as u16;
    let tick = state.tick as u32;
    let mut out: Vec<Vec<u8>> = state
        .x_m
        .iter()
        .zip(&state.v_m_s)
        .enumerate()
        .map(|(i, (x, v))| {
            Packet {
                site,
                message: Message::State {
                    tick,
                    chunk: StateChunk::Node {
                        index: i as u16,
                        count,
                        x_m: *x,
                        v_m_s: *v,
                    },
                },
            }
            .encode()
        })
        .collect();
    out.push(
        Packet {
            site,
            message: Message::State {
                tick,
                chunk: StateChunk::Summary {
                    count,
                    state_hash: state.bit_hash(),
                    clock_us,
                },
            },
        }
        .encode(),
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::session::packet::TICK_US;

    fn fields(level: u16) -> SessionFields {
        SessionFields {
            level,
            tick_us: TICK_US,
            side_m: 0.05,
            stiffness_modulus_pa: 1.0e4,
            damping_modulus_pa_s: 10.0,
            density_kg_m3: 1000.0,
        }
    }

    /// Site 1 starts after site 0's hellos went unheard: its first hello
    /// reaches site 0, which refuses it and answers with its own, so site 1
    /// names the mismatch too instead of waiting for a hello that never
    /// comes.
    #[test]
    fn a_refused_hello_is_answered_so_both_sides_name_the_mismatch() {
        let mut site0 = Control::new(0, fields(3), 11);
        let mut site1 = Control::new(1, fields(4), 22);
        let hello1 = site1.poll(0);
        assert_eq!(hello1.len(), 1);
        let (events, answer) = site0.on_packet(50, &Packet::decode(&hello1[0]).unwrap());
        match events.as_slice() {
            [Event::Refused(why)] => assert!(why.contains("level: ours 3, the peer's 4"), "{why}"),
            other => panic!("site 0 did not refuse: {other:?}"),
        }
        assert_eq!(answer.len(), 1, "site 0 must answer the refused hello");
        let (events, _) = site1.on_packet(100, &Packet::decode(&answer[0]).unwrap());
        match events.as_slice() {
            [Event::Refused(why)] => assert!(why.contains("level: ours 4, the peer's 3"), "{why}"),
            other => panic!("site 1 did not refuse: {other:?}"),
        }
    }
}
