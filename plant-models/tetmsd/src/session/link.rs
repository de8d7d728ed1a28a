//! Sequence numbers, acknowledgements and retransmission over the 64-byte
//! packet: every input of the peer arrives exactly once, or the session
//! says why it cannot go on.
//!
//! A site sends one input packet per 1 kHz tick, numbered by the tick.
//! Every packet it sends carries, in the node-ID word, how many of the
//! peer's ticks it has received without a gap (low 16 bits, extended on
//! arrival against the receiver's own count) and a 16-bit map of the ticks
//! after that gap that did arrive. The sender keeps every unacknowledged
//! input in a bounded window ([`WINDOW_TICKS`]) and sends one again when
//! neither an acknowledgement nor a selective acknowledgement has come
//! within the retransmission timeout, estimated from the measured round
//! trips as TCP does (Jacobson/Karels: `srtt + 4·rttvar`, clamped; samples
//! only from packets sent once, Karn's rule), doubled for every resend of
//! the same packet. The receiver keeps a bounded window of ticks ahead of
//! its gap, counts duplicates (a late original after its retransmission, a
//! retransmission after a late original) and every gap it saw and later
//! saw filled ("recovered").
//!
//! Time is passed in as microseconds (`now_us`), so the same code runs in
//! virtual time (tests, `pair --virtual`) and in real time over UDP.
//!
//! Left out: congestion control (the stream is 64 kB/s), sequence-number
//! wrap (2³² ticks are 49.7 days: a longer session is refused).
use super::packet::{DecodeStats, Malformed, Message, Packet};
use crate::error::{Result, TetError};
use crate::model::probe::{ContactGeometry, Manipulation};
use std::collections::VecDeque;

/// Inputs a sender may have unacknowledged and a receiver may hold ahead
/// of its gap: 8.2 s at 1 kHz, seven times the worst round trip the seed
/// measured (1,126,960 µs, L2803).
pub const WINDOW_TICKS: u32 = 8192;

/// Retransmission timing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkConfig {
    /// Lower bound of the retransmission timeout (µs). 15 ms: above the
    /// seed's typical round trips (9–14 ms), so ordinary jitter does not
    /// cause resends, and short enough that a lost input costs little.
    pub min_rto_us: u64,
    /// Upper bound (µs).
    pub max_rto_us: u64,
    /// Timeout before the first round-trip sample (µs).
    pub initial_rto_us: u64,
    /// Most packets resent by one [`Link::poll`] (bounds a burst).
    pub max_resends_per_poll: usize,
}

impl Default for LinkConfig {
    fn default() -> Self {
        LinkConfig {
            min_rto_us: 15_000,
            max_rto_us: 1_000_000,
            initial_rto_us: 100_000,
            max_resends_per_poll: 32,
        }
    }
}

/// Counters of one site's link.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkStats {
    /// Input packets sent for the first time.
    pub inputs_sent: u64,
    /// Input packets sent again.
    pub retransmissions: u64,
    /// Acknowledgement-only packets sent.
    pub acks_sent: u64,
    /// Peer inputs received for the first time.
    pub inputs_received: u64,
    /// Peer inputs received again (late originals, spurious resends).
    pub duplicates: u64,
    /// Peer inputs that arrived further ahead than the window (dropped;
    /// the peer resends them).
    pub beyond_window: u64,
    /// Peer ticks seen missing (a later tick arrived first).
    pub gaps_seen: u64,
    /// Of those, ticks that arrived afterwards.
    pub gaps_filled: u64,
    /// Refused packets by reason.
    pub malformed: DecodeStats,
    /// Round-trip samples (µs): count, min, sum, max.
    pub rtt_samples: u64,
    /// Smallest round trip (µs).
    pub rtt_min_us: u64,
    /// Sum of round trips (µs).
    pub rtt_sum_us: u64,
    /// Largest round trip (µs).
    pub rtt_max_us: u64,
}

impl LinkStats {
    /// Mean round trip (µs), 0 without samples.
    pub fn rtt_mean_us(&self) -> f64 {
        if self.rtt_samples == 0 {
            0.0
        } else {
            self.rtt_sum_us as f64 / self.rtt_samples as f64
        }
    }
}

/// One unacknowledged input.
#[derive(Clone, Copy, Debug)]
struct Slot {
    input: Manipulation,
    first_sent_us: u64,
    last_sent_us: u64,
    sends: u32,
    /// Selectively acknowledged: known to have arrived.
    arrived: bool,
}

/// What a datagram brought.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Arrival {
    /// A new input of the peer for `tick`.
    Input {
        /// The peer's tick.
        tick: u32,
        /// Its manipulation.
        input: Manipulation,
    },
    /// The peer's hello with its configuration hash.
    Hello(u64),
    /// The peer is leaving.
    Bye,
    /// Nothing new (acks only, a duplicate, or a refused packet).
    Nothing,
}

/// One site's end of the link.
#[derive(Clone, Debug)]
pub struct Link {
    site: u8,
    config: LinkConfig,
    /// Ticks sent so far (the next input's tick).
    next_seq: u32,
    /// Inputs `acked..next_seq` are in `window`.
    acked: u32,
    window: VecDeque<Slot>,
    srtt_us: f64,
    rttvar_us: f64,
    rto_us: u64,
    /// Every peer tick below this has arrived.
    recv_base: u32,
    /// Arrival flags of peer ticks `recv_base..` (front = recv_base).
    ahead: VecDeque<bool>,
    /// Highest peer tick seen + 1.
    recv_high: u32,
    /// Something arrived that the peer has not yet seen acknowledged.
    owe_ack: bool,
    stats: LinkStats,
}

impl Link {
    /// The link of site `site` (0 or 1).
    pub fn new(site: u8, config: LinkConfig) -> Self {
        Link {
            site: site & 1,
            config,
            next_seq: 0,
            acked: 0,
            window: VecDeque::new(),
            srtt_us: 0.0,
            rttvar_us: 0.0,
            rto_us: config.initial_rto_us,
            recv_base: 0,
            ahead: VecDeque::new(),
            recv_high: 0,
            owe_ack: false,
            stats: LinkStats::default(),
        }
    }

    /// This site.
    pub fn site(&self) -> u8 {
        self.site
    }

    /// Counters.
    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// Ticks sent so far.
    pub fn sent_ticks(&self) -> u32 {
        self.next_seq
    }

    /// Peer ticks received without a gap.
    pub fn received_through(&self) -> u32 {
        self.recv_base
    }

    /// Whether every input sent has been acknowledged.
    pub fn all_acknowledged(&self) -> bool {
        self.acked == self.next_seq
    }

    /// Whether an acknowledgement is owed (something new arrived since the
    /// last packet this site sent).
    pub fn owes_ack(&self) -> bool {
        self.owe_ack
    }

    /// The current retransmission timeout (µs).
    pub fn rto_us(&self) -> u64 {
        self.rto_us
    }

    fn header(&mut self, seq: u32, message: Message) -> [u8; 64] {
        let mut sack = 0u16;
        for b in 0..16 {
            if self.ahead.get(b + 1).copied().unwrap_or(false) {
                sack |= 1 << b;
            }
        }
        self.owe_ack = false;
        Packet {
            site: self.site,
            seq,
            ack: self.recv_base as u16,
            sack,
            message,
        }
        .encode()
    }

    /// The packet of this site's input for `tick`, which must be the next
    /// tick; refused when the peer has not acknowledged a window's worth.
    pub fn send_input(&mut self, now_us: u64, tick: u32, input: Manipulation) -> Result<[u8; 64]> {
        if tick != self.next_seq {
            return Err(TetError::Session(format!(
                "input for tick {tick} sent out of order (next is {})",
                self.next_seq
            )));
        }
        if self.next_seq == u32::MAX {
            return Err(TetError::Session(
                "the session reached 2^32 ticks (49.7 days), the sequence-number limit".into(),
            ));
        }
        if self.next_seq - self.acked >= WINDOW_TICKS {
            return Err(TetError::Session(format!(
                "the peer has acknowledged nothing after tick {} for {WINDOW_TICKS} ticks: it is gone or the link is down",
                self.acked
            )));
        }
        self.window.push_back(Slot {
            input,
            first_sent_us: now_us,
            last_sent_us: now_us,
            sends: 1,
            arrived: false,
        });
        self.next_seq += 1;
        self.stats.inputs_sent += 1;
        Ok(self.header(tick, Message::Input(input)))
    }

    /// An acknowledgement-only packet.
    pub fn ack_packet(&mut self) -> [u8; 64] {
        self.stats.acks_sent += 1;
        self.header(self.next_seq, Message::Ack)
    }

    /// A hello carrying this site's configuration hash.
    pub fn hello_packet(&mut self, config_hash: u64) -> [u8; 64] {
        self.header(self.next_seq, Message::Hello { config_hash })
    }

    /// A bye.
    pub fn bye_packet(&mut self) -> [u8; 64] {
        self.header(self.next_seq, Message::Bye)
    }

    /// Packets to resend at `now_us`: unacknowledged inputs whose timeout
    /// (doubled per resend) has run out, oldest first, at most
    /// [`LinkConfig::max_resends_per_poll`].
    pub fn poll(&mut self, now_us: u64) -> Vec<[u8; 64]> {
        let mut due = Vec::new();
        for (k, slot) in self.window.iter().enumerate() {
            if due.len() >= self.config.max_resends_per_poll {
                break;
            }
            let backoff = self.rto_us.saturating_mul(1 << (slot.sends - 1).min(6));
            let timeout = backoff.min(self.config.max_rto_us);
            if !slot.arrived && now_us.saturating_sub(slot.last_sent_us) >= timeout {
                due.push(k);
            }
        }
        let mut out = Vec::with_capacity(due.len());
        for k in due {
            let tick = self.acked + k as u32;
            let slot = &mut self.window[k];
            slot.sends += 1;
            slot.last_sent_us = now_us;
            let input = slot.input;
            self.stats.retransmissions += 1;
            out.push(self.header(tick, Message::Input(input)));
        }
        out
    }

    fn rtt_sample(&mut self, rtt_us: u64) {
        let s = &mut self.stats;
        s.rtt_min_us = if s.rtt_samples == 0 {
            rtt_us
        } else {
            s.rtt_min_us.min(rtt_us)
        };
        s.rtt_max_us = s.rtt_max_us.max(rtt_us);
        s.rtt_sum_us += rtt_us;
        s.rtt_samples += 1;
        let r = rtt_us as f64;
        if s.rtt_samples == 1 {
            self.srtt_us = r;
            self.rttvar_us = r / 2.0;
        } else {
            self.rttvar_us = 0.75 * self.rttvar_us + 0.25 * (self.srtt_us - r).abs();
            self.srtt_us = 0.875 * self.srtt_us + 0.125 * r;
        }
        let rto = (self.srtt_us + 4.0 * self.rttvar_us) as u64;
        self.rto_us = rto.clamp(self.config.min_rto_us, self.config.max_rto_us);
    }

    /// Takes in the peer's acknowledgements.
    fn on_ack(&mut self, now_us: u64, ack: u16, sack: u16) {
        // Extend the 16-bit count against what this site has sent: the
        // true count lies within the window below `next_seq`.
        let behind = (self.next_seq as u16).wrapping_sub(ack) as u32;
        if behind > self.next_seq - self.acked {
            return; // older than what is already acknowledged
        }
        let through = self.next_seq - behind;
        while self.acked < through {
            if let Some(slot) = self.window.pop_front() {
                if slot.sends == 1 && !slot.arrived {
                    self.rtt_sample(now_us.saturating_sub(slot.first_sent_us));
                }
            }
            self.acked += 1;
        }
        for b in 0..16u32 {
            if sack & (1 << b) != 0 {
                let k = (b + 1) as usize;
                if let Some(slot) = self.window.get_mut(k) {
                    if !slot.arrived {
                        slot.arrived = true;
                        if slot.sends == 1 {
                            let rtt = now_us.saturating_sub(slot.first_sent_us);
                            self.rtt_sample(rtt);
                        }
                    }
                }
            }
        }
    }

    /// Takes in a datagram from the peer. Refused packets are counted
    /// (and reported as [`Arrival::Nothing`]); `geometry` and `nodes` check
    /// grips against the session's mesh.
    pub fn on_datagram(
        &mut self,
        now_us: u64,
        bytes: &[u8],
        geometry: &ContactGeometry,
        nodes: usize,
    ) -> Arrival {
        let packet = match Packet::decode(bytes).and_then(|p| {
            if p.site == self.site {
                Err(Malformed::WrongPeer)
            } else {
                p.check_against(geometry, nodes).map(|_| p)
            }
        }) {
            Ok(p) => p,
            Err(why) => {
                self.stats.malformed.record(why);
                return Arrival::Nothing;
            }
        };
        // A hello goes out when the handshake needs it, outside the
        // emulated path; its acknowledgements would arrive early and spoil
        // the round-trip estimate, so they are not read.
        if !matches!(packet.message, Message::Hello { .. }) {
            self.on_ack(now_us, packet.ack, packet.sack);
        }
        match packet.message {
            Message::Input(input) => self.on_input(packet.seq, input),
            Message::Hello { config_hash } => Arrival::Hello(config_hash),
            Message::Bye => Arrival::Bye,
            Message::Ack => Arrival::Nothing,
        }
    }

    /// Records that a hello was refused (another configuration).
    pub fn refuse_peer(&mut self) {
        self.stats.malformed.record(Malformed::WrongPeer);
    }

    fn on_input(&mut self, tick: u32, input: Manipulation) -> Arrival {
        self.owe_ack = true;
        if tick < self.recv_base {
            self.stats.duplicates += 1;
            return Arrival::Nothing;
        }
        let k = (tick - self.recv_base) as usize;
        if k >= WINDOW_TICKS as usize {
            self.stats.beyond_window += 1;
            return Arrival::Nothing;
        }
        if self.ahead.len() <= k {
            self.ahead.resize(k + 1, false);
        }
        if self.ahead[k] {
            self.stats.duplicates += 1;
            return Arrival::Nothing;
        }
        self.ahead[k] = true;
        self.stats.inputs_received += 1;
        if tick >= self.recv_high {
            self.stats.gaps_seen += u64::from(tick - self.recv_high);
            self.recv_high = tick + 1;
        } else {
            self.stats.gaps_filled += 1;
        }
        while self.ahead.front() == Some(&true) {
            self.ahead.pop_front();
            self.recv_base += 1;
        }
        Arrival::Input { tick, input }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::mesh::CubeMesh;
    use crate::model::voigt::{VoigtMaterial, VoigtModel};
    use crate::model::V3;

    fn geometry() -> (ContactGeometry, usize) {
        let m = VoigtModel::new(CubeMesh::new(3, 0.06).unwrap(), VoigtMaterial::default()).unwrap();
        (ContactGeometry::of(&m), m.mesh().node_count())
    }

    fn input(k: u32) -> Manipulation {
        Manipulation::free(V3::new(f64::from(k), 0.0, 0.0))
    }

    #[test]
    fn in_order_delivery_acknowledges_and_measures_round_trips() {
        let (g, n) = geometry();
        let (mut a, mut b) = (
            Link::new(0, LinkConfig::default()),
            Link::new(1, LinkConfig::default()),
        );
        for k in 0..100u32 {
            let t = u64::from(k) * 1000;
            let p = a.send_input(t, k, input(k)).unwrap();
            // 5 ms one way each direction.
            assert_eq!(
                b.on_datagram(t + 5000, &p, &g, n),
                Arrival::Input {
                    tick: k,
                    input: input(k)
                }
            );
            let q = b.send_input(t + 5000, k, input(k)).unwrap();
            a.on_datagram(t + 10_000, &q, &g, n);
        }
        assert_eq!(b.received_through(), 100);
        // The last ack covers tick 98 (b's packet k acknowledges a's 0..=k).
        assert_eq!(a.acked, 100);
        assert!(a.all_acknowledged());
        let s = a.stats();
        assert_eq!((s.rtt_min_us, s.rtt_max_us), (10_000, 10_000));
        assert_eq!(a.rto_us(), 15_000, "clamped to the minimum");
        assert!(a.poll(1_000_000).is_empty());
    }

    #[test]
    fn a_lost_input_is_seen_missing_resent_and_filled() {
        let (g, n) = geometry();
        let (mut a, mut b) = (
            Link::new(0, LinkConfig::default()),
            Link::new(1, LinkConfig::default()),
        );
        let mut lost = None;
        for k in 0..40u32 {
            let t = u64::from(k) * 1000;
            let p = a.send_input(t, k, input(k)).unwrap();
            if k == 10 {
                lost = Some(p);
                continue;
            }
            b.on_datagram(t + 1000, &p, &g, n);
            let q = b.ack_packet();
            a.on_datagram(t + 2000, &q, &g, n);
        }
        assert_eq!(b.received_through(), 10);
        assert_eq!(b.stats().gaps_seen, 1);
        // Ticks 11..=26 were selectively acknowledged and are not resent.
        let resent = a.poll(40_000 + 100_000);
        assert_eq!(resent.len(), 1 + (40 - 27), "tick 10 and the unsacked tail");
        let first = Packet::decode(&resent[0]).unwrap();
        assert_eq!(first.seq, 10);
        assert_eq!(
            b.on_datagram(150_000, &resent[0], &g, n),
            Arrival::Input {
                tick: 10,
                input: input(10)
            }
        );
        assert_eq!(b.received_through(), 40);
        assert_eq!(b.stats().gaps_filled, 1);
        // The late original is a counted duplicate.
        assert_eq!(
            b.on_datagram(160_000, &lost.unwrap(), &g, n),
            Arrival::Nothing
        );
        assert_eq!(b.stats().duplicates, 1);
        let q = b.ack_packet();
        a.on_datagram(161_000, &q, &g, n);
        assert!(a.all_acknowledged());
    }

    #[test]
    fn refusals_are_counted_and_the_window_is_bounded() {
        let (g, n) = geometry();
        let mut a = Link::new(0, LinkConfig::default());
        let mut b = Link::new(1, LinkConfig::default());
        // Own site's packet, garbage, a bad length.
        let mine = a.send_input(0, 0, input(0)).unwrap();
        let mut other = Link::new(0, LinkConfig::default());
        assert_eq!(other.on_datagram(0, &mine, &g, n), Arrival::Nothing);
        assert_eq!(other.stats().malformed.count(Malformed::WrongPeer), 1);
        assert_eq!(b.on_datagram(0, &[0u8; 64], &g, n), Arrival::Nothing);
        assert_eq!(b.on_datagram(0, &[1, 2, 3], &g, n), Arrival::Nothing);
        assert_eq!(b.stats().malformed.total(), 2);
        // A tick far ahead is dropped and counted.
        let mut far = Link::new(0, LinkConfig::default());
        far.next_seq = WINDOW_TICKS + 5;
        far.acked = far.next_seq;
        let p = far.send_input(0, WINDOW_TICKS + 5, input(1)).unwrap();
        assert_eq!(b.on_datagram(0, &p, &g, n), Arrival::Nothing);
        assert_eq!(b.stats().beyond_window, 1);
        // A sender with a full window of unacknowledged inputs stops.
        let mut c = Link::new(0, LinkConfig::default());
        for k in 0..WINDOW_TICKS {
            c.send_input(0, k, input(k)).unwrap();
        }
        let e = c.send_input(0, WINDOW_TICKS, input(0)).unwrap_err();
        assert!(e.to_string().contains("acknowledged nothing"), "{e}");
        let e = c.send_input(0, 3, input(0)).unwrap_err();
        assert!(e.to_string().contains("out of order"), "{e}");
    }

    #[test]
    fn acknowledgements_survive_the_16_bit_wrap() {
        let (g, n) = geometry();
        let (mut a, mut b) = (
            Link::new(0, LinkConfig::default()),
            Link::new(1, LinkConfig::default()),
        );
        for k in 0..70_000u32 {
            let p = a.send_input(u64::from(k), k, input(0)).unwrap();
            b.on_datagram(u64::from(k), &p, &g, n);
            if k % 64 == 0 {
                let q = b.ack_packet();
                a.on_datagram(u64::from(k), &q, &g, n);
            }
        }
        let q = b.ack_packet();
        a.on_datagram(70_000, &q, &g, n);
        assert!(a.all_acknowledged());
        assert_eq!(b.received_through(), 70_000);
    }
}
