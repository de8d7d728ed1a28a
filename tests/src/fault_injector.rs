//! A fault injector for the lockstep link: a [`Port`] between the host's
//! [`Link`](host_tools::board::link::Link) and the real port (a pty to QEMU or to
//! the pty board) that mangles whole frames in both directions at a seeded
//! rate — dropped, duplicated, delayed (and so reordered), bit-flipped,
//! truncated, garbage frames inserted, bursts of noise merged into a frame.
//!
//! It keeps a ledger: the faults it injected by direction and kind, and a
//! reference decoder per direction fed with exactly the bytes it delivered,
//! whose counters are what the receiving end must count.
//!
//! Every corrupting fault is drawn so that a fresh decoder *rejects* it
//! (CRC, COBS, length or overfull): a 16-bit CRC passes a random frame of
//! the right length with probability 2⁻¹⁶, and a corruption that the
//! framing cannot see is not a fault of the link's handling but of the CRC
//! width. Draws that a decoder would accept are drawn again, and counted
//! ([`Ledger::redrawn`]).
use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use firmware::protocol::{FrameDecoder, FrameError, LinkStats};
use host_tools::board::link::Port;
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// What can happen to a frame on the wire.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// Never arrives.
    Drop,
    /// Arrives twice.
    Duplicate,
    /// Arrives late (after frames sent after it).
    Delay,
    /// One bit flipped.
    BitFlip,
    /// Cut short (its end lost).
    Truncate,
    /// A garbage frame arrives before it.
    Garbage,
    /// Line noise merged into it (it is lost).
    Noise,
}

impl Fault {
    /// Every kind, in the ledger's order.
    pub const ALL: [Fault; 7] = [
        Fault::Drop,
        Fault::Duplicate,
        Fault::Delay,
        Fault::BitFlip,
        Fault::Truncate,
        Fault::Garbage,
        Fault::Noise,
    ];

    /// Name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Fault::Drop => "dropped",
            Fault::Duplicate => "duplicated",
            Fault::Delay => "delayed",
            Fault::BitFlip => "bit-flipped",
            Fault::Truncate => "truncated",
            Fault::Garbage => "garbage frame",
            Fault::Noise => "noise burst",
        }
    }

    /// Whether the receiver's decoder must count it as an error.
    pub fn corrupts(self) -> bool {
        matches!(
            self,
            Fault::BitFlip | Fault::Truncate | Fault::Garbage | Fault::Noise
        )
    }
}

/// A direction of the link.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Host → board (requests, sensor frames).
    ToBoard = 0,
    /// Board → host (replies, actuator frames).
    ToHost = 1,
}

/// What the injector did, and what the receivers must have counted.
pub struct Ledger {
    /// Faults injected, `[direction][kind]` (kinds as in [`Fault::ALL`]).
    pub injected: [[u64; 7]; 2],
    /// Frames (whole, unmangled) passed on, per direction.
    pub frames_passed: [u64; 2],
    /// Corruptions drawn again because a decoder would have accepted them.
    pub redrawn: u64,
    /// Decoders fed with every byte delivered, per direction.
    reference: [FrameDecoder; 2],
    /// Corrupting items whose fresh decode gave no error (must stay 0).
    pub undetectable: u64,
    /// The last faults injected (direction, kind, the frame, what was
    /// delivered instead), for the report of a failed campaign.
    pub recent: VecDeque<(Direction, Fault, Vec<u8>, Vec<u8>)>,
}

impl Ledger {
    fn new() -> Self {
        Self {
            injected: [[0; 7]; 2],
            frames_passed: [0; 2],
            redrawn: 0,
            reference: [FrameDecoder::board(), FrameDecoder::host()],
            undetectable: 0,
            recent: VecDeque::new(),
        }
    }

    /// What the receiver in `dir` must have counted since the ledger was
    /// last reset.
    pub fn expected(&self, dir: Direction) -> LinkStats {
        self.reference[dir as usize].stats()
    }

    /// Faults of `kind` injected in `dir`.
    pub fn count(&self, dir: Direction, kind: Fault) -> u64 {
        let k = Fault::ALL.iter().position(|f| *f == kind).unwrap_or(0);
        self.injected[dir as usize][k]
    }

    /// All faults injected.
    pub fn total(&self) -> u64 {
        self.injected.iter().flatten().sum()
    }

    fn deliver(&mut self, dir: Direction, bytes: &[u8]) {
        for b in bytes {
            let _ = self.reference[dir as usize].push(*b);
        }
    }
}

/// Whether a fresh decoder rejects every frame in `bytes` by the framing
/// (CRC, COBS, too short, overfull) — none accepted, none CRC-valid.
fn rejected_by_framing(dir: Direction, bytes: &[u8]) -> bool {
    let mut d = match dir {
        Direction::ToBoard => FrameDecoder::board(),
        Direction::ToHost => FrameDecoder::host(),
    };
    let mut errors = 0;
    for b in bytes {
        match d.push(*b) {
            Some(Ok(_)) | Some(Err(FrameError::Malformed { .. })) => return false,
            Some(Err(_)) => errors += 1,
            None => {}
        }
    }
    errors > 0
}

/// One direction's fault state.
struct Lane {
    rng: ChaCha8Rng,
    /// Bytes of a frame not yet complete.
    partial: Vec<u8>,
    /// Frames held back, with the time they are due.
    delayed: VecDeque<(Instant, Vec<u8>)>,
    /// Faults injected so far (their kinds take turns).
    faults: usize,
}

/// Fault settings.
#[derive(Clone, Copy, Debug)]
pub struct FaultRates {
    /// Probability that a frame gets a fault. Which frames are hit is
    /// drawn; the kinds take turns (every kind is exercised once seven
    /// faults have been injected in a direction).
    pub per_frame: f64,
    /// How long a delayed frame is held (drawn uniformly in this range).
    pub delay: (Duration, Duration),
}

/// The injecting port.
pub struct FaultyPort<P: Port> {
    inner: P,
    rates: FaultRates,
    enabled: bool,
    lanes: [Lane; 2],
    /// Bytes ready for the host.
    to_host: VecDeque<u8>,
    read_timeout: Duration,
    /// The ledger.
    pub ledger: Ledger,
}

impl<P: Port> FaultyPort<P> {
    /// Wraps `inner`; faults drawn from `seed`'s streams
    /// (`plant_common::rng::LINK_FAULTS_BASE` + direction). Starts disabled.
    pub fn new(inner: P, rates: FaultRates, seed: u64) -> Self {
        let lane = |dir: Direction| Lane {
            rng: plant_common::rng::stream(seed, plant_common::rng::LINK_FAULTS_BASE + dir as u64),
            partial: Vec::new(),
            delayed: VecDeque::new(),
            faults: 0,
        };
        Self {
            inner,
            rates,
            enabled: false,
            lanes: [lane(Direction::ToBoard), lane(Direction::ToHost)],
            to_host: VecDeque::new(),
            read_timeout: Duration::from_millis(10),
            ledger: Ledger::new(),
        }
    }

    /// Faults on or off (off: every frame passes, still counted).
    pub fn set_enabled(&mut self, on: bool) {
        self.enabled = on;
    }

    /// Delivers every held frame now.
    pub fn flush_delayed(&mut self) -> io::Result<()> {
        for d in [Direction::ToBoard, Direction::ToHost] {
            while let Some((_, f)) = self.lanes[d as usize].delayed.pop_front() {
                self.emit(d, &f)?;
            }
        }
        Ok(())
    }

    /// Starts a new ledger (counts and reference decoders from zero).
    pub fn reset_ledger(&mut self) {
        self.ledger = Ledger::new();
    }

    /// Bytes to the receiver in `dir`, now.
    fn emit(&mut self, dir: Direction, bytes: &[u8]) -> io::Result<()> {
        self.ledger.deliver(dir, bytes);
        match dir {
            Direction::ToBoard => {
                // Reads leave the port's one timeout short; a write gets
                // the link's.
                self.inner
                    .set_read_timeout(host_tools::board::link::WRITE_TIMEOUT)?;
                self.inner.write_all(bytes)
            }
            Direction::ToHost => {
                self.to_host.extend(bytes);
                Ok(())
            }
        }
    }

    /// Delivers the held frames that are due.
    fn release_due(&mut self) -> io::Result<()> {
        let now = Instant::now();
        for d in [Direction::ToBoard, Direction::ToHost] {
            while self.lanes[d as usize]
                .delayed
                .front()
                .is_some_and(|(due, _)| *due <= now)
            {
                if let Some((_, f)) = self.lanes[d as usize].delayed.pop_front() {
                    self.emit(d, &f)?;
                }
            }
        }
        Ok(())
    }

    /// Takes bytes travelling in `dir`; each completed frame (ending in
    /// its 0x00 delimiter) meets its fate.
    fn take(&mut self, dir: Direction, bytes: &[u8]) -> io::Result<()> {
        for &b in bytes {
            let lane = &mut self.lanes[dir as usize];
            lane.partial.push(b);
            if b == 0 {
                let frame = std::mem::take(&mut lane.partial);
                self.frame(dir, frame)?;
            }
        }
        Ok(())
    }

    /// Random non-zero bytes, 1..=`max` of them.
    fn nonzero_bytes(rng: &mut ChaCha8Rng, max: usize) -> Vec<u8> {
        let n = rng.gen_range(1..=max);
        (0..n).map(|_| rng.gen_range(1..=255u8)).collect()
    }

    fn frame(&mut self, dir: Direction, frame: Vec<u8>) -> io::Result<()> {
        let i = dir as usize;
        // A lone delimiter (the host's decoder flush) or faults off: pass.
        let fault = if self.enabled && frame.len() > 1 {
            let lane = &mut self.lanes[i];
            lane.rng.gen_bool(self.rates.per_frame).then(|| {
                lane.faults += 1;
                Fault::ALL[(lane.faults - 1) % Fault::ALL.len()]
            })
        } else {
            None
        };
        let Some(fault) = fault else {
            self.ledger.frames_passed[i] += 1;
            return self.emit(dir, &frame);
        };
        let k = Fault::ALL.iter().position(|f| *f == fault).unwrap_or(0);
        self.ledger.injected[i][k] += 1;
        if self.ledger.recent.len() == 12 {
            self.ledger.recent.pop_front();
        }
        self.ledger
            .recent
            .push_back((dir, fault, frame.clone(), Vec::new()));
        let body = &frame[..frame.len() - 1]; // without its delimiter
        match fault {
            Fault::Drop => Ok(()),
            Fault::Duplicate => {
                self.emit(dir, &frame)?;
                self.emit(dir, &frame)
            }
            Fault::Delay => {
                let (lo, hi) = self.rates.delay;
                let lane = &mut self.lanes[i];
                let d = lo + (hi.saturating_sub(lo)).mul_f64(lane.rng.gen::<f64>());
                lane.delayed.push_back((Instant::now() + d, frame));
                Ok(())
            }
            Fault::BitFlip | Fault::Truncate | Fault::Garbage | Fault::Noise => {
                let item = self.corrupt(dir, fault, body);
                if let Some(r) = self.ledger.recent.back_mut() {
                    r.3 = item.clone();
                }
                if !rejected_by_framing(dir, &item) {
                    self.ledger.undetectable += 1;
                }
                self.emit(dir, &item)?;
                if fault == Fault::Garbage {
                    // The frame itself follows the garbage intact.
                    self.ledger.frames_passed[i] += 1;
                    self.emit(dir, &frame)?;
                }
                Ok(())
            }
        }
    }

    /// The bytes of a corrupting fault of `body` (a frame without its
    /// delimiter), delimited, drawn until the framing rejects them.
    fn corrupt(&mut self, dir: Direction, fault: Fault, body: &[u8]) -> Vec<u8> {
        for _ in 0..1000 {
            let rng = &mut self.lanes[dir as usize].rng;
            let mut item = match fault {
                Fault::BitFlip => {
                    let mut f = body.to_vec();
                    // A flip that made a 0x00 would split the frame in two.
                    loop {
                        let at = rng.gen_range(0..f.len());
                        let flipped = f[at] ^ (1 << rng.gen_range(0..8));
                        if flipped != 0 {
                            f[at] = flipped;
                            break;
                        }
                    }
                    f
                }
                Fault::Truncate => body[..rng.gen_range(1..body.len().max(2))].to_vec(),
                Fault::Garbage => Self::nonzero_bytes(rng, 40),
                _ => {
                    // Noise: a burst merged with the frame's start.
                    let mut f = Self::nonzero_bytes(rng, 24);
                    f.extend_from_slice(body);
                    f
                }
            };
            item.push(0);
            if rejected_by_framing(dir, &item) {
                return item;
            }
            self.ledger.redrawn += 1;
        }
        // Not reached in practice (each draw is rejected with probability
        // ≈ 1 − 2⁻¹⁶); a frame of pure noise then stands in.
        vec![0x5A; 3000]
    }
}

impl<P: Port> Write for FaultyPort<P> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.release_due()?;
        self.take(Direction::ToBoard, buf)?;
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

impl<P: Port> Read for FaultyPort<P> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let deadline = Instant::now() + self.read_timeout;
        loop {
            self.release_due()?;
            if !self.to_host.is_empty() {
                let n = buf.len().min(self.to_host.len());
                for (slot, b) in buf.iter_mut().zip(self.to_host.drain(..n)) {
                    *slot = b;
                }
                return Ok(n);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(io::ErrorKind::TimedOut.into());
            }
            // Wake up for held frames that fall due.
            let held = self.lanes.iter().any(|l| !l.delayed.is_empty());
            let wait = if held {
                (deadline - now).min(Duration::from_millis(2))
            } else {
                deadline - now
            };
            self.inner.set_read_timeout(wait)?;
            let mut chunk = [0u8; 256];
            match self.inner.read(&mut chunk) {
                Ok(0) => return Ok(0),
                Ok(n) => self.take(Direction::ToHost, &chunk[..n])?,
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
                    ) => {}
                Err(e) => return Err(e),
            }
        }
    }
}

impl<P: Port> Port for FaultyPort<P> {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.read_timeout = timeout;
        Ok(())
    }
}
