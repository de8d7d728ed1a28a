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
        let (board, host, host_path) = pty_pair()?;
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

/// A pseudo-terminal pair in raw mode: `(master, slave, slave's path)`.
///
/// Both descriptors are opened close-on-exec, in the same system call that
/// creates them. `TTYPort::pair` opens them without it, so a process that
/// another thread starts before they could be marked inherits them, and with
/// them every lock later taken on them: a test's board then stays locked for
/// as long as that unrelated process lives, and `softjoint console --port`
/// fails with "Unable to acquire exclusive lock" (seen in CI). No lock is
/// taken here; a program opening the slave's path takes its own.
pub fn pty_pair() -> serialport::Result<(TTYPort, TTYPort, String)> {
    use std::os::fd::{FromRawFd as _, IntoRawFd as _, OwnedFd};
    let last = || serialport::Error::from(std::io::Error::last_os_error());
    // SAFETY: libc calls on descriptors owned here (each wrapped in an
    // OwnedFd as soon as it exists, so it is closed on every error path);
    // the only memory passed is `name` with its true length and a termios
    // value initialised by tcgetattr before it is read.
    #[allow(unsafe_code)]
    unsafe {
        let m = libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY | libc::O_CLOEXEC);
        if m < 0 {
            return Err(last());
        }
        let master = OwnedFd::from_raw_fd(m);
        if libc::grantpt(m) != 0 || libc::unlockpt(m) != 0 {
            return Err(last());
        }
        let mut name = [0 as libc::c_char; 128];
        if libc::ptsname_r(m, name.as_mut_ptr(), name.len()) != 0 {
            return Err(last());
        }
        let s = libc::open(
            name.as_ptr(),
            libc::O_RDWR | libc::O_NOCTTY | libc::O_CLOEXEC,
        );
        if s < 0 {
            return Err(last());
        }
        let slave = OwnedFd::from_raw_fd(s);
        let mut t = std::mem::MaybeUninit::<libc::termios>::uninit();
        if libc::tcgetattr(s, t.as_mut_ptr()) != 0 {
            return Err(last());
        }
        let mut t = t.assume_init();
        libc::cfmakeraw(&mut t);
        if libc::tcsetattr(s, libc::TCSANOW, &t) != 0 {
            return Err(last());
        }
        let path = std::ffi::CStr::from_ptr(name.as_ptr())
            .to_string_lossy()
            .into_owned();
        // from_raw_fd would take an exclusive flock and TIOCEXCL on each
        // end; neither is wanted (the slave's path is opened again by the
        // program under test), so both are released at once.
        let master = TTYPort::from_raw_fd(master.into_raw_fd());
        let slave = TTYPort::from_raw_fd(slave.into_raw_fd());
        unlock(&master);
        unlock(&slave);
        Ok((master, slave, path))
    }
}

/// Drops whatever exclusivity `TTYPort::from_raw_fd` took on `port`: the
/// terminal's TIOCEXCL and the descriptor's flock.
fn unlock(port: &TTYPort) {
    use std::os::fd::AsRawFd as _;
    let fd = port.as_raw_fd();
    // SAFETY: ioctl and flock on a descriptor `port` owns and keeps open,
    // with integer arguments only.
    #[allow(unsafe_code)]
    unsafe {
        libc::ioctl(fd, libc::TIOCNXCL);
        libc::flock(fd, libc::LOCK_UN);
    }
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
