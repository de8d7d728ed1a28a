//! The host end of the serial protocol (`firmware::protocol`): framing,
//! bounded waits and retries, and the counters a user needs to judge a link.
//!
//! The host always speaks first (QEMU's pty drops what the guest writes
//! before the host opens it; a board never speaks unasked except for
//! telemetry). Every wait has a deadline; a request that times out is sent
//! again unchanged — board requests are idempotent (a repeated lockstep
//! `seq` is answered from the board's cache) — up to a retry limit.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use firmware::protocol::{encode_frame, ErrorCode, FrameDecoder, LinkStats, Message, MAX_FRAME};
use serde::Serialize;

/// Why a request failed.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// No matching reply after every retry.
    #[error("no reply to {} after {attempts} attempts of {timeout_ms} ms", name(*.request))]
    Timeout {
        /// Type byte of the request.
        request: u8,
        /// Attempts made.
        attempts: u32,
        /// Per-attempt timeout (ms).
        timeout_ms: u64,
    },
    /// The board answered with an error.
    #[error("board refused {}: {} ({code})", name(*.request), .code.name())]
    Refused {
        /// Type byte of the request.
        request: u8,
        /// The board's reason.
        code: ErrorCode,
    },
    /// A reply was accepted that does not fit the request (a bug on one
    /// side).
    #[error("reply {} does not answer request {}", name(*.reply), name(*.request))]
    Unexpected {
        /// Type byte of the request.
        request: u8,
        /// Type byte of the reply.
        reply: u8,
    },
    /// The port failed.
    #[error("serial port: {0}")]
    Io(#[from] io::Error),
}

/// A message type by name and type byte, e.g. `SetTarget (0x10)`.
fn name(kind: u8) -> String {
    match firmware::protocol::message_name(kind) {
        Some(n) => format!("{n} ({kind:#04x})"),
        None => format!("type {kind:#04x}"),
    }
}

/// Host-side link counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct HostLinkStats {
    /// Frames written.
    pub frames_sent: u64,
    /// Frames received and decoded.
    pub frames_received: u64,
    /// Requests sent again after a timeout.
    pub retries: u64,
    /// Received frames with a CRC mismatch.
    pub crc_errors: u64,
    /// Received frames with bad COBS or too short.
    pub cobs_errors: u64,
    /// Received frames longer than the maximum.
    pub overfull: u64,
    /// Received CRC-valid frames of unknown type or wrong length.
    pub malformed: u64,
    /// Decoded frames that were not the awaited reply (stale replies to
    /// retried requests, telemetry while waiting).
    pub unexpected: u64,
    /// Times the port was closed and opened again after
    /// [`REOPEN_AFTER_SILENT_ATTEMPTS`] silent attempts.
    pub reopens: u64,
}

/// A byte port with a read timeout.
pub trait Port: Read + Write + Send {
    /// Sets how long a read may block.
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;

    /// Closes the device and opens it again; `Ok(false)` if this port
    /// cannot (a pty pair end, a test double).
    fn reopen(&mut self) -> io::Result<bool> {
        Ok(false)
    }
}

impl Port for Box<dyn serialport::SerialPort> {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.set_timeout(timeout).map_err(io::Error::from)
    }
}

#[cfg(unix)]
impl Port for serialport::TTYPort {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        serialport::SerialPort::set_timeout(self, timeout).map_err(io::Error::from)
    }
}

/// A serial device opened by path (a board, or QEMU's pty), which can be
/// closed and opened again.
///
/// QEMU 7.2's pty backend can stop reading its end of the pty while the
/// host holds the other end open: seen under heavy host load with both
/// the mps2-an386 and the netduinoplus2 images, after thousands of
/// lockstep steps, QEMU's main loop no longer polls the pty, the guest's
/// UART stays empty and every retry goes unanswered. Opening the device
/// again makes QEMU poll it again. [`Link::request`] does that after
/// [`REOPEN_AFTER_SILENT_ATTEMPTS`] attempts without a byte received, and
/// counts it in [`HostLinkStats::reopens`].
pub struct SerialDevice {
    path: String,
    baud: u32,
    port: Option<Box<dyn serialport::SerialPort>>,
}

impl SerialDevice {
    fn open(path: &str, baud: u32) -> io::Result<Box<dyn serialport::SerialPort>> {
        serialport::new(path, baud)
            .timeout(Duration::from_millis(10))
            .open()
            .map_err(io::Error::from)
    }

    fn port(&mut self) -> io::Result<&mut Box<dyn serialport::SerialPort>> {
        self.port.as_mut().ok_or_else(|| {
            io::Error::new(
                io::ErrorKind::NotConnected,
                format!("serial port {} could not be opened again", self.path),
            )
        })
    }
}

impl Read for SerialDevice {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.port()?.read(buf)
    }
}

impl Write for SerialDevice {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.port()?.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.port()?.flush()
    }
}

impl Port for SerialDevice {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.port()?.set_read_timeout(timeout)
    }

    fn reopen(&mut self) -> io::Result<bool> {
        // Close first: the device is opened exclusively.
        self.port = None;
        self.port = Some(Self::open(&self.path, self.baud)?);
        Ok(true)
    }
}

/// Opens a serial device (a board, or QEMU's pty) in raw mode.
pub fn open_port(path: &str, baud: u32) -> anyhow::Result<SerialDevice> {
    let port = SerialDevice::open(path, baud)
        .map_err(|e| anyhow::anyhow!("cannot open serial port {path}: {e}"))?;
    Ok(SerialDevice {
        path: path.to_string(),
        baud,
        port: Some(port),
    })
}

/// Attempts of one request without a single byte received after which
/// [`Link::request`] reopens a port that can be reopened (see
/// [`SerialDevice`]).
pub const REOPEN_AFTER_SILENT_ATTEMPTS: u32 = 3;

/// The host end of a link.
pub struct Link<P: Port> {
    port: P,
    decoder: FrameDecoder,
    stats: HostLinkStats,
    queued: VecDeque<Message>,
    buf: [u8; 256],
    buffered: (usize, usize),
    lose_next: bool,
    /// Bytes read from the port so far.
    bytes_read: u64,
}

impl<P: Port> Link<P> {
    /// Wraps a port.
    pub fn new(port: P) -> Self {
        Self {
            port,
            decoder: FrameDecoder::host(),
            stats: HostLinkStats::default(),
            queued: VecDeque::new(),
            buf: [0; 256],
            buffered: (0, 0),
            lose_next: false,
            bytes_read: 0,
        }
    }

    /// Counters so far.
    pub fn stats(&self) -> HostLinkStats {
        let d: LinkStats = self.decoder.stats();
        HostLinkStats {
            crc_errors: u64::from(d.crc_errors),
            cobs_errors: u64::from(d.cobs_errors),
            overfull: u64::from(d.overfull),
            malformed: u64::from(d.malformed),
            ..self.stats
        }
    }

    /// The port (tests use it to inject bytes).
    pub fn port_mut(&mut self) -> &mut P {
        &mut self.port
    }

    /// Fault injection: the next frame is counted as sent but not written
    /// (a frame lost on the wire), so the request's retry must recover it.
    pub fn lose_next_send(&mut self) {
        self.lose_next = true;
    }

    /// Sends one message as a frame.
    pub fn send(&mut self, msg: &Message) -> io::Result<()> {
        if std::mem::take(&mut self.lose_next) {
            self.stats.frames_sent += 1;
            return Ok(());
        }
        let mut frame = [0u8; MAX_FRAME];
        let n = encode_frame(msg, &mut frame);
        // No flush: on a tty it is tcdrain, which would block until the far
        // end (QEMU feeds its UART one byte at a time) has read everything.
        self.port.write_all(&frame[..n])?;
        self.stats.frames_sent += 1;
        Ok(())
    }

    /// Sends raw bytes (a leading delimiter to flush the board's decoder,
    /// or deliberate garbage in tests).
    pub fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)
    }

    /// Next message received before `deadline` (queued ones first).
    pub fn recv_until(&mut self, deadline: Instant) -> io::Result<Option<Message>> {
        if let Some(m) = self.queued.pop_front() {
            return Ok(Some(m));
        }
        loop {
            while self.buffered.0 < self.buffered.1 {
                let b = self.buf[self.buffered.0];
                self.buffered.0 += 1;
                if let Some(Ok(m)) = self.decoder.push(b) {
                    self.stats.frames_received += 1;
                    return Ok(Some(m));
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            self.port
                .set_read_timeout((deadline - now).min(Duration::from_millis(100)))?;
            match self.port.read(&mut self.buf) {
                Ok(0) => {}
                Ok(n) => {
                    self.buffered = (0, n);
                    self.bytes_read += n as u64;
                }
                Err(e)
                    if e.kind() == io::ErrorKind::TimedOut
                        || e.kind() == io::ErrorKind::WouldBlock => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }

    /// Sends `msg` and waits up to `timeout` for a reply that `accept`
    /// takes; on a timeout sends it again, up to `attempts` times in all.
    /// An `Error` reply to this request type ends the wait. Other messages
    /// that arrive meanwhile are counted as unexpected (telemetry is kept
    /// for [`Link::recv_until`]).
    pub fn request(
        &mut self,
        msg: &Message,
        timeout: Duration,
        attempts: u32,
        accept: impl Fn(&Message) -> bool,
    ) -> Result<Message, LinkError> {
        let request = msg.kind();
        let mut silent = 0;
        for attempt in 0..attempts.max(1) {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            if silent >= REOPEN_AFTER_SILENT_ATTEMPTS && self.port.reopen()? {
                self.stats.reopens += 1;
                silent = 0;
                // A lone delimiter ends any partial frame on the far side.
                self.send_raw(&[0])?;
            }
            let read_before = self.bytes_read;
            self.send(msg)?;
            let deadline = Instant::now() + timeout;
            while let Some(reply) = self.recv_until(deadline)? {
                if accept(&reply) {
                    return Ok(reply);
                }
                match reply {
                    Message::Nak(firmware::protocol::Nak { request: r, code }) if r == request => {
                        return Err(LinkError::Refused { request, code });
                    }
                    Message::Telemetry(_) => self.queued.push_back(reply),
                    _ => self.stats.unexpected += 1,
                }
                if self.queued.len() > 1024 {
                    self.queued.pop_front();
                }
            }
            silent = if self.bytes_read == read_before {
                silent + 1
            } else {
                0
            };
        }
        Err(LinkError::Timeout {
            request,
            attempts: attempts.max(1),
            timeout_ms: timeout.as_millis() as u64,
        })
    }

    /// A request answered by `Ack` for its type.
    pub fn command(
        &mut self,
        msg: &Message,
        timeout: Duration,
        attempts: u32,
    ) -> Result<(), LinkError> {
        let kind = msg.kind();
        self.request(
            msg,
            timeout,
            attempts,
            |r| matches!(r, Message::Ack(a) if a.request == kind),
        )
        .map(|_| ())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use firmware::protocol::{kind, Ack, Arm};

    /// A board on a port that stops reading (as QEMU's pty backend can)
    /// until the port is reopened; it answers every complete frame with an
    /// `Ack` while it reads.
    struct StuckPort {
        stuck: bool,
        can_reopen: bool,
        reopened: u32,
        written: Vec<u8>,
        reply: VecDeque<u8>,
    }

    impl StuckPort {
        fn new(can_reopen: bool) -> Self {
            Self {
                stuck: true,
                can_reopen,
                reopened: 0,
                written: Vec::new(),
                reply: VecDeque::new(),
            }
        }
    }

    impl Read for StuckPort {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.reply.is_empty() {
                // As a serial port with a read timeout: nothing arrived.
                std::thread::sleep(Duration::from_millis(1));
                return Err(io::ErrorKind::TimedOut.into());
            }
            let n = buf.len().min(self.reply.len());
            for b in buf.iter_mut().take(n) {
                *b = self.reply.pop_front().unwrap();
            }
            Ok(n)
        }
    }

    impl Write for StuckPort {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.stuck {
                return Ok(buf.len()); // written, never read
            }
            for &b in buf {
                self.written.push(b);
                if b == 0 && self.written.len() > 1 {
                    let mut frame = [0u8; MAX_FRAME];
                    let n = encode_frame(&Ack { request: kind::ARM }.into(), &mut frame);
                    self.reply.extend(&frame[..n]);
                }
                if b == 0 {
                    self.written.clear();
                }
            }
            Ok(buf.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    impl Port for StuckPort {
        fn set_read_timeout(&mut self, _timeout: Duration) -> io::Result<()> {
            Ok(())
        }
        fn reopen(&mut self) -> io::Result<bool> {
            if self.can_reopen {
                self.stuck = false;
                self.reopened += 1;
            }
            Ok(self.can_reopen)
        }
    }

    #[test]
    fn a_port_silent_for_three_attempts_is_reopened_and_the_request_answered() {
        let mut link = Link::new(StuckPort::new(true));
        link.command(&Arm {}.into(), Duration::from_millis(5), 10)
            .expect("answered after the reopen");
        let s = link.stats();
        assert_eq!(
            (s.reopens, s.retries),
            (1, REOPEN_AFTER_SILENT_ATTEMPTS as u64)
        );
        assert_eq!(link.port_mut().reopened, 1);
    }

    #[test]
    fn a_port_that_cannot_reopen_times_out_after_every_attempt() {
        let mut link = Link::new(StuckPort::new(false));
        let err = link
            .command(&Arm {}.into(), Duration::from_millis(5), 6)
            .unwrap_err();
        assert!(
            matches!(err, LinkError::Timeout { attempts: 6, .. }),
            "{err}"
        );
        assert_eq!((link.stats().reopens, link.stats().retries), (0, 5));
    }

    #[test]
    fn a_port_that_answers_is_never_reopened() {
        let mut port = StuckPort::new(true);
        port.stuck = false;
        let mut link = Link::new(port);
        for _ in 0..10 {
            link.command(&Arm {}.into(), Duration::from_millis(5), 3)
                .unwrap();
        }
        assert_eq!(link.stats().reopens, 0);
    }
}
