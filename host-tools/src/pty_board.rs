//! A simulated board on a pseudo-terminal: the firmware's board
//! application ([`firmware::app::App`]) in a thread on one end of a real pty
//! pair, with injectable faults (dropped and delayed replies). The host
//! tools talk to it exactly as to a board or to QEMU; tests use it, and so
//! can anyone trying `softjoint console` without hardware.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use firmware::app::{App, NoSensors};
use firmware::control::PairCommand;
use serialport::{SerialPort, TTYPort};

/// Faults the simulated board can inject into its replies.
#[derive(Clone, Copy, Debug, Default)]
pub struct BoardFaults {
    /// Drop this many of the next replies (the host must retry).
    pub drop_replies: u32,
    /// Hold each reply this long before writing it.
    pub delay_replies: Duration,
    /// Restart the board application as a reset button would (a fresh
    /// application, as after power-up: free-running, disarmed, default
    /// configuration, counters at zero); cleared once done.
    pub reset: bool,
}

/// What the board thread reports.
#[derive(Debug, Default)]
pub struct BoardState {
    /// Outputs after the last loop iteration.
    pub outputs: [PairCommand; 2],
    /// Board time (ms since start) of the last received byte.
    pub last_rx_ms: Option<u32>,
    /// Board time when the outputs last went from driven to all off.
    pub outputs_off_at_ms: Option<u32>,
    /// Replies dropped by fault injection.
    pub dropped: u32,
    /// Resets done.
    pub resets: u32,
}

/// The board application on a pty, in a thread.
pub struct PtyBoard {
    /// Path of the host's end (for subprocesses).
    pub host_path: String,
    /// Fault injection, changeable while running.
    pub faults: Arc<Mutex<BoardFaults>>,
    /// Reported state.
    pub state: Arc<Mutex<BoardState>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl PtyBoard {
    /// Starts a board; returns it and the host end of the pty.
    pub fn start() -> serialport::Result<(Self, TTYPort)> {
        // pair() returns (master, slave); only the slave has a device path.
        let (board, mut host) = TTYPort::pair()?;
        host.set_exclusive(false)?;
        let host_path = host.name().unwrap_or_default();
        let faults = Arc::new(Mutex::new(BoardFaults::default()));
        let state = Arc::new(Mutex::new(BoardState::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (faults, state, stop) = (faults.clone(), state.clone(), stop.clone());
            std::thread::spawn(move || board_loop(board, faults, state, stop))
        };
        Ok((
            Self {
                host_path,
                faults,
                state,
                stop,
                thread: Some(thread),
            },
            host,
        ))
    }
}

impl Drop for PtyBoard {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

fn board_loop(
    mut port: TTYPort,
    faults: Arc<Mutex<BoardFaults>>,
    state: Arc<Mutex<BoardState>>,
    stop: Arc<AtomicBool>,
) {
    // The paper configuration is valid (a firmware unit test checks it); a
    // board that cannot start simply never answers, like a dead board.
    let Ok(mut app) = App::new() else { return };
    let start = Instant::now();
    // The board's clock: microseconds since the thread started.
    let now = || {
        firmware::time::Instant::from_micros(
            u64::try_from(start.elapsed().as_micros()).unwrap_or(u64::MAX),
        )
    };
    let now_ms = || now().wrapping_millis_u32();
    if port.set_timeout(Duration::from_millis(1)).is_err() {
        return;
    }
    let mut buf = [0u8; 256];
    let mut out: Vec<Vec<u8>> = Vec::new();
    let mut was_driving = false;
    while !stop.load(Ordering::SeqCst) {
        if std::mem::take(&mut faults.lock().unwrap().reset) {
            let Ok(fresh) = App::new() else { return };
            app = fresh;
            out.clear();
            state.lock().unwrap().resets += 1;
        }
        if let Ok(n) = port.read(&mut buf) {
            if n > 0 {
                state.lock().unwrap().last_rx_ms = Some(now_ms());
            }
            for &b in &buf[..n] {
                app.on_byte(b, now(), &mut |f: &[u8]| out.push(f.to_vec()));
            }
        }
        app.poll(now(), &mut NoSensors, &mut |f: &[u8]| out.push(f.to_vec()));
        for frame in out.drain(..) {
            let f = *faults.lock().unwrap();
            if f.drop_replies > 0 {
                let mut fl = faults.lock().unwrap();
                fl.drop_replies -= 1;
                state.lock().unwrap().dropped += 1;
                continue;
            }
            if !f.delay_replies.is_zero() {
                std::thread::sleep(f.delay_replies);
            }
            let _ = port.write_all(&frame);
        }
        let outputs = app.outputs();
        let driving = outputs.iter().any(|c| *c != PairCommand::Off);
        let mut st = state.lock().unwrap();
        if was_driving && !driving {
            st.outputs_off_at_ms = Some(now_ms());
        }
        was_driving = driving;
        st.outputs = outputs;
    }
}
