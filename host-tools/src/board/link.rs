//! The host end of the serial protocol (`firmware::protocol`): framing,
//! bounded waits and retries, and the counters a user needs to judge a link.
//!
//! The host always speaks first (QEMU drops what the guest writes before
//! the host connects; a board never speaks unasked except for
//! telemetry). Every wait has a deadline; a request that times out is sent
//! again unchanged — board requests are idempotent (a repeated lockstep
//! `seq` is answered from the board's cache) — up to a retry limit.
//!
//! Telemetry that arrives while a request waits for its reply is set aside
//! for [`Link::recv_until`] (at most [`TELEMETRY_QUEUE`] frames; older ones
//! are dropped and counted), never read again by the waiting request: a
//! board streaming at 1 kHz cannot keep a request from reaching its
//! deadline. A port that hangs up (QEMU exited, a board unplugged) is
//! [`LinkError::PortClosed`], not a wait until the deadline.

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
    /// The other end of the line went away: the pty's QEMU exited, the
    /// pty board stopped, a USB adapter was unplugged.
    #[error(
        "the serial line closed: the other end hung up (a QEMU that exited, an unplugged board)"
    )]
    PortClosed,
    /// The port failed otherwise. The I/O error is part of the message
    /// and deliberately not also `source()`, so a reporter that prints
    /// the chain does not print it twice.
    #[error("serial port: {0}")]
    Io(io::Error),
}

impl From<io::Error> for LinkError {
    fn from(e: io::Error) -> Self {
        if is_hang_up(&e) {
            LinkError::PortClosed
        } else {
            LinkError::Io(e)
        }
    }
}

/// Whether an I/O error means the other end of the line went away
/// (serialport reports a pty whose master closed as `BrokenPipe`; a read
/// of a hung-up tty gives `EIO` or end of file).
///
/// serialport's wait for a readable or writable port reports a poll that
/// came back with an error event but no hang-up event as a bare "I/O
/// error" of kind `Other` (its `EIO` text, without the OS code): on a
/// tty that is the line hung up too, seen a moment before the hang-up
/// event (once in a clean CI run, `link_failures::a_line_that_closes_…`).
pub fn is_hang_up(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::BrokenPipe | io::ErrorKind::UnexpectedEof | io::ErrorKind::ConnectionReset
    ) || e.raw_os_error() == Some(5) // EIO
        || (e.kind() == io::ErrorKind::Other
            && e.raw_os_error().is_none()
            && e.to_string() == SERIALPORT_POLL_ERROR)
}

/// The text of serialport's poll error without a hang-up event (nix's
/// description of `EIO`).
const SERIALPORT_POLL_ERROR: &str = "I/O error";

/// Most telemetry frames kept for [`Link::recv_until`] while requests wait
/// (2 s of a 500 Hz stream); older ones are dropped and counted.
pub const TELEMETRY_QUEUE: usize = 1024;

/// A message type by name and type byte, e.g. `SetTarget (0x10)`.
fn name(kind: u8) -> String {
    match firmware::protocol::message_name(kind) {
        Some(n) => format!("{n} ({kind:#04x})"),
        None => format!("type {kind:#04x}"),
    }
}

/// Longest single wait for a reply: an hour. A longer per-attempt timeout
/// (a user's `--timeout-ms`) is held to it rather than overflowing the
/// clock.
pub const MAX_REPLY_WAIT: Duration = Duration::from_secs(3600);

/// How long a write may wait for room in the port's buffer (the far end
/// not reading) before it fails.
pub const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// The instant `timeout` from now, `timeout` held to [`MAX_REPLY_WAIT`].
pub fn deadline_after(timeout: Duration) -> Instant {
    Instant::now() + timeout.min(MAX_REPLY_WAIT)
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
    /// retried requests); telemetry is counted apart.
    pub unexpected: u64,
    /// Telemetry frames that arrived while a request waited and were
    /// dropped because [`TELEMETRY_QUEUE`] frames were already waiting.
    pub telemetry_dropped: u64,
}

/// A byte port with a read timeout.
pub trait Port: Read + Write + Send {
    /// Sets how long a read may block.
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()>;
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

/// A serial device opened by path: a board's serial port, or `unix:PATH`,
/// a Unix socket such as the one QEMU serves the guest's UART on
/// ([`crate::board::qemu`]).
pub struct SerialDevice {
    port: Box<dyn ByteStream>,
}

/// What a [`SerialDevice`] reads and writes: a serial port, or (a path
/// `unix:PATH`) a Unix socket such as QEMU's `-serial unix:PATH,server=on`.
trait ByteStream: Read + Write + Send {
    fn set_stream_timeout(&mut self, timeout: Duration) -> io::Result<()>;
}

impl ByteStream for Box<dyn serialport::SerialPort> {
    fn set_stream_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        serialport::SerialPort::set_timeout(self.as_mut(), timeout).map_err(io::Error::from)
    }
}

#[cfg(unix)]
impl ByteStream for std::os::unix::net::UnixStream {
    fn set_stream_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        // One timeout for reads and writes, as a serial port has ([`Link`]
        // sets it before each); a zero timeout means "block for ever" to a
        // socket.
        let timeout = Some(timeout.max(Duration::from_micros(1)));
        self.set_read_timeout(timeout)?;
        self.set_write_timeout(timeout)
    }
}

impl SerialDevice {
    fn open(path: &str, baud: u32) -> io::Result<Box<dyn ByteStream>> {
        #[cfg(unix)]
        if let Some(socket) = path.strip_prefix("unix:") {
            return Ok(Box::new(std::os::unix::net::UnixStream::connect(socket)?));
        }
        Ok(Box::new(
            serialport::new(path, baud)
                .timeout(Duration::from_millis(10))
                .open()
                .map_err(io::Error::from)?,
        ))
    }
}

impl Read for SerialDevice {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.port.read(buf)
    }
}

impl Write for SerialDevice {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.port.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.port.flush()
    }
}

impl Port for SerialDevice {
    fn set_read_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.port.set_stream_timeout(timeout)
    }
}

/// Opens a serial device (a board's port in raw mode, or `unix:PATH`).
pub fn open_port(path: &str, baud: u32) -> anyhow::Result<SerialDevice> {
    let port = SerialDevice::open(path, baud)
        .map_err(|e| anyhow::anyhow!("cannot open serial port {path}: {e}"))?;
    Ok(SerialDevice { port })
}

/// The host end of a link.
pub struct Link<P: Port> {
    port: P,
    decoder: FrameDecoder,
    stats: HostLinkStats,
    queued: VecDeque<Message>,
    buf: [u8; 256],
    buffered: (usize, usize),
    lose_next: bool,
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
        // The port has one timeout for reads and writes, and the last read
        // may have left it at a millisecond: a write gets its own.
        self.port.set_read_timeout(WRITE_TIMEOUT)?;
        self.port.write_all(&frame[..n])?;
        self.stats.frames_sent += 1;
        Ok(())
    }

    /// Sends raw bytes (a leading delimiter to flush the board's decoder,
    /// or deliberate garbage in tests).
    pub fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        // As in `send`: the last read may have left the timeout at a
        // millisecond, too short for a far end that reads slowly.
        self.port.set_read_timeout(WRITE_TIMEOUT)?;
        self.port.write_all(bytes)
    }

    /// Next message received before `deadline` (telemetry set aside by
    /// requests first).
    pub fn recv_until(&mut self, deadline: Instant) -> Result<Option<Message>, LinkError> {
        if let Some(m) = self.queued.pop_front() {
            return Ok(Some(m));
        }
        self.recv_wire_until(deadline)
    }

    /// Next message read from the line before `deadline`, ignoring what
    /// is set aside: every call either returns a newly decoded frame or
    /// waits on the port, so a caller looping on it reaches its deadline.
    fn recv_wire_until(&mut self, deadline: Instant) -> Result<Option<Message>, LinkError> {
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
                // A tty read that poll() found ready and that returns
                // nothing is end of file: the other end hung up.
                Ok(0) => return Err(LinkError::PortClosed),
                Ok(n) => self.buffered = (0, n),
                Err(e)
                    if e.kind() == io::ErrorKind::TimedOut
                        || e.kind() == io::ErrorKind::WouldBlock => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// Sends `msg` and waits up to `timeout` for a reply that `accept`
    /// takes; on a timeout sends it again, up to `attempts` times in all.
    /// An `Error` reply to this request type ends the wait. Other messages
    /// that arrive meanwhile are counted as unexpected; telemetry is set
    /// aside for [`Link::recv_until`] (bounded, see [`TELEMETRY_QUEUE`]).
    pub fn request(
        &mut self,
        msg: &Message,
        timeout: Duration,
        attempts: u32,
        accept: impl Fn(&Message) -> bool,
    ) -> Result<Message, LinkError> {
        let request = msg.kind();
        for attempt in 0..attempts.max(1) {
            if attempt > 0 {
                self.stats.retries += 1;
            }
            self.send(msg)?;
            let deadline = deadline_after(timeout);
            while let Some(reply) = self.recv_wire_until(deadline)? {
                if accept(&reply) {
                    return Ok(reply);
                }
                match reply {
                    Message::Nak(firmware::protocol::Nak { request: r, code }) if r == request => {
                        return Err(LinkError::Refused { request, code });
                    }
                    Message::Telemetry(_) => {
                        if self.queued.len() >= TELEMETRY_QUEUE {
                            self.queued.pop_front();
                            self.stats.telemetry_dropped += 1;
                        }
                        self.queued.push_back(reply);
                    }
                    _ => self.stats.unexpected += 1,
                }
            }
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

#[cfg(all(test, unix))]
mod tests {
    use super::*;
    use firmware::protocol::{kind, Ack, Arm};
    use std::os::unix::net::UnixListener;

    /// The hang-up errors, and serialport's poll error event among them;
    /// other I/O errors are not.
    #[test]
    fn a_poll_error_event_is_a_hang_up_and_other_errors_are_not() {
        let poll_error = io::Error::other("I/O error");
        assert!(is_hang_up(&poll_error));
        assert!(matches!(LinkError::from(poll_error), LinkError::PortClosed));
        assert!(is_hang_up(&io::Error::from_raw_os_error(5)));
        assert!(is_hang_up(&io::Error::from(io::ErrorKind::BrokenPipe)));
        for e in [
            io::Error::other("device busy"),
            io::Error::from_raw_os_error(13),
            io::Error::from(io::ErrorKind::TimedOut),
        ] {
            assert!(!is_hang_up(&e), "{e}");
        }
    }

    /// `open_port("unix:PATH")` talks to a Unix socket as QEMU serves its
    /// UART: a request is answered through it, and a far end that closes
    /// is [`LinkError::PortClosed`], not a wait for the deadline.
    #[test]
    fn a_unix_socket_port_carries_frames_and_reports_its_hang_up() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("uart.sock");
        let listener = UnixListener::bind(&path).unwrap();
        // A board that acknowledges one frame, then hangs up.
        let board = std::thread::spawn(move || {
            let (mut s, _) = listener.accept().unwrap();
            let mut got = Vec::new();
            let mut b = [0u8; 1];
            while got.iter().filter(|&&x| x == 0).count() < 1 {
                s.read_exact(&mut b).unwrap();
                got.push(b[0]);
            }
            let mut frame = [0u8; MAX_FRAME];
            let n = encode_frame(&Ack { request: kind::ARM }.into(), &mut frame);
            s.write_all(&frame[..n]).unwrap();
            got
        });
        let port = open_port(&format!("unix:{}", path.display()), 0).unwrap();
        let mut link = Link::new(port);
        link.command(&Arm {}.into(), Duration::from_secs(10), 1)
            .expect("acknowledged over the socket");
        let sent = board.join().unwrap();
        assert_eq!(sent.last(), Some(&0), "one whole frame reached the board");
        let err = link
            .command(&Arm {}.into(), Duration::from_secs(10), 3)
            .unwrap_err();
        assert!(matches!(err, LinkError::PortClosed), "{err}");
    }

    #[test]
    fn a_missing_socket_is_named() {
        let Err(err) = open_port("unix:/nonexistent/softjoint.sock", 0) else {
            panic!("a socket that is not there opened");
        };
        assert!(
            err.to_string().contains("/nonexistent/softjoint.sock"),
            "{err}"
        );
    }
}
