//! A simulated board on a pseudo-terminal: the firmware's board
//! application ([`firmware::app::App`]) in a thread on one end of a real pty
//! pair, with injectable faults (dropped and delayed replies). The host
//! tools talk to it exactly as to a board or to QEMU; tests use it, and so
//! can anyone trying `softjoint console` without hardware.
//!
//! Without a plant ([`PtyBoard::start`]) the board has no sensors, as
//! under QEMU. With one ([`PtyBoard::start_with_plant`]) the board is
//! wired to a simulated 3D joint ([`plant_joint::Joint3d`]): the
//! application's per-coil outputs drive the plant's coils, advanced in
//! 1 ms steps to the board's clock (the host's), and the plant's wire
//! counts are what [`BoardSensors::read_counts`] reads — a board in
//! free-running mode, closed loop or in open-loop drive, with no
//! hardware. The plant runs in the board thread; if it cannot keep up with
//! the clock, the lag is reported ([`BoardState::plant_lag_ms`]) rather
//! than hidden.

use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use firmware::app::{App, BoardSensors, NoSensors};
use firmware::control::DriveVolts;

use crate::board::seeded::{SeededFault, Seeder};
use plant_joint::Joint3d;
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
    /// Outputs after the last loop iteration, per pair `[agonist,
    /// antagonist]`.
    pub outputs: [[DriveVolts; 2]; 2],
    /// The plant's true angles (α, β) after its last step (plant-backed
    /// boards only).
    pub true_angles_deg: Option<[f64; 2]>,
    /// Largest time the plant was behind the board's clock (ms).
    pub plant_lag_ms: f64,
    /// Why the plant stopped, if it did (its outputs stay applied to
    /// nothing and its counts frozen).
    pub plant_error: Option<String>,
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
    /// Starts a board without sensors; returns it and the host end of the
    /// pty.
    pub fn start() -> serialport::Result<(Self, TTYPort)> {
        Self::start_seeded(None, &[])
    }

    /// Starts a board wired to `plant` (see the module docs).
    pub fn start_with_plant(plant: Joint3d) -> serialport::Result<(Self, TTYPort)> {
        Self::start_seeded(Some(plant), &[])
    }

    /// Starts a board (wired to `plant`, if given) that breaks the
    /// protocol as `seeded` says: the broken board the conformance
    /// suite's own tests run against ([`crate::board::seeded`]).
    pub fn start_seeded(
        plant: Option<Joint3d>,
        seeded: &[SeededFault],
    ) -> serialport::Result<(Self, TTYPort)> {
        // pair() returns (master, slave); only the slave has a device path.
        let (board, mut host) = TTYPort::pair()?;
        // serialport opens both ends without close-on-exec: a process
        // another thread starts meanwhile would inherit them, and with
        // them the host end's lock, and a program opening the port later
        // (`softjoint console --port`) would find it locked.
        close_on_exec(&board)?;
        close_on_exec(&host)?;
        host.set_exclusive(false)?;
        let host_path = host.name().unwrap_or_default();
        let faults = Arc::new(Mutex::new(BoardFaults::default()));
        let state = Arc::new(Mutex::new(BoardState::default()));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (faults, state, stop) = (faults.clone(), state.clone(), stop.clone());
            let seeder = Seeder::new(seeded);
            std::thread::spawn(move || board_loop(board, plant, seeder, faults, state, stop))
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

/// Marks `port`'s descriptor close-on-exec.
pub fn close_on_exec(port: &TTYPort) -> serialport::Result<()> {
    use std::os::fd::AsRawFd as _;
    let fd = port.as_raw_fd();
    // SAFETY: fcntl on a descriptor `port` owns and keeps open, with
    // integer arguments only; no memory is passed.
    #[allow(unsafe_code)]
    let ok = unsafe {
        let flags = libc::fcntl(fd, libc::F_GETFD);
        flags >= 0 && libc::fcntl(fd, libc::F_SETFD, flags | libc::FD_CLOEXEC) >= 0
    };
    if !ok {
        return Err(std::io::Error::last_os_error().into());
    }
    Ok(())
}

/// The plant's wire counts as the board's sensors read them.
struct PlantSensors<'a>(&'a Joint3d);

impl BoardSensors for PlantSensors<'_> {
    fn read_counts(&mut self) -> [Option<i32>; 4] {
        self.0.wire_counts().map(|c| i32::try_from(c).ok())
    }
}

/// Plant step (s): the board's control period.
const PLANT_STEP_S: f64 = 1e-3;

fn board_loop(
    mut port: TTYPort,
    mut plant: Option<Joint3d>,
    mut seeder: Seeder,
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
    // Plant time (s of the board's clock) reached so far.
    let mut plant_t_s = 0.0f64;
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
                seeder.on_byte(b, &mut out);
            }
        }
        if let Some(pl) = plant.as_mut() {
            // The coils get what the drivers are set to, paper numbering.
            let volts = firmware::joint::pairs_to_coils::<_, 2, 4>(app.outputs())
                .map(|v: firmware::control::DriveVolts| f64::from(v.volts()));
            let t_s = now().as_micros() as f64 * 1e-6;
            let mut err = None;
            while plant_t_s + PLANT_STEP_S <= t_s {
                if let Err(e) = pl.step(PLANT_STEP_S, &volts) {
                    err = Some(e.to_string());
                    break;
                }
                plant_t_s += PLANT_STEP_S;
            }
            let lag_ms = (now().as_micros() as f64 * 1e-6 - plant_t_s) * 1e3;
            let mut st = state.lock().unwrap();
            st.plant_lag_ms = st.plant_lag_ms.max(lag_ms);
            st.true_angles_deg = Some(pl.angles_deg());
            if let Some(e) = err {
                st.plant_error = Some(e);
                drop(st);
                plant = None;
            }
        }
        seeder.before_poll(&mut app, now());
        match plant.as_ref() {
            Some(pl) => app.poll(now(), &mut PlantSensors(pl), &mut |f: &[u8]| {
                out.push(f.to_vec())
            }),
            None => app.poll(now(), &mut NoSensors, &mut |f: &[u8]| out.push(f.to_vec())),
        }
        out = seeder.rewrite(std::mem::take(&mut out));
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
        let driving = outputs.iter().flatten().any(|v| v.volts() > 0.0);
        let mut st = state.lock().unwrap();
        if was_driving && !driving {
            st.outputs_off_at_ms = Some(now_ms());
        }
        was_driving = driving;
        st.outputs = outputs;
    }
}
