//! The fault campaign of the lockstep link: the closed loop of `softjoint
//! hil` (plant ⇄ `BoardController` over the protocol) against a board — the
//! pty board or the firmware image under QEMU — with faults injected on the
//! wire in both directions at a seeded rate ([`crate::fault_injector`]) and
//! a board reset in the middle, checked step by step against the same loop
//! with the firmware core in process and no faults. What must hold is
//! listed in tests/tests/it/fault_campaign.rs, which runs the short forms;
//! the long forms are the example `fault_campaign`
//! (`cargo run --release -p integration-tests --example fault_campaign`).
use std::time::{Duration, Instant};

use crate::fault_injector::{Direction, Fault, FaultRates, FaultyPort};
use crate::PtyBoard;
use firmware::joint::{JointConfig, JointController};
use firmware::protocol::Status;
use hal_sim::{
    Actuation, ClosedLoop, Controller, CoreController, FeedbackSource, Readings, Sample,
};
use host_tools::board::controller::{BoardController, LockstepSetup};
use host_tools::board::link::{HostLinkStats, Link, Port};
use host_tools::files::scenario::{EstimatorMethod, Scenario, TargetStep};
use host_tools::run::schedule::RunSchedule;
use host_tools::run::spec::RunSpec;

/// The campaign's scenario: the 3D joint on wires with the paper's laws, a
/// PI law (ki > 0, so a double or missed step changes the integrator), and
/// targets that move every 3 s through a cycle of (α, β) pairs.
fn scenario(steps: u64) -> RunSpec {
    let mut s = Scenario {
        name: "fault campaign".into(),
        duration_s: steps as f64 * 1e-3,
        ..Scenario::default()
    };
    s.estimator.method = EstimatorMethod::Paper;
    s.controller.ki_v_per_deg_s = 0.5;
    s.controller.integral_limit_v = 1.0;
    let cycle = [
        (0.0, 0.0),
        (5.0, 3.0),
        (10.0, 8.0),
        (4.0, -3.0),
        (-5.0, 2.0),
    ];
    s.targets = (0..)
        .map(|k: u64| k as f64 * 3.0)
        .take_while(|t| *t < s.duration_s)
        .enumerate()
        .map(|(k, t_s)| {
            let (a, b) = cycle[k % cycle.len()];
            TargetStep {
                t_s,
                deg: vec![a, b],
            }
        })
        .collect();
    RunSpec::resolve(&s).expect("the campaign scenario resolves")
}

/// A step's trajectory, as one number: true angles, coil voltages, faults.
fn fingerprint(x: &Sample<2, 4, 4>) -> u64 {
    use std::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    for v in x.true_deg.iter().chain(&x.coil_volts) {
        v.to_bits().hash(&mut h);
    }
    x.faults.hash(&mut h);
    h.finish()
}

/// The firmware core in process, made afresh at step `restart_at` (the
/// reference for a board reset there).
struct RestartingCore {
    scenario: RunSpec,
    core: CoreController<2, 4>,
    mm_per_count: [f64; 4],
    restart_at: u64,
    steps: u64,
}

impl RestartingCore {
    fn fresh(s: &RunSpec, mm_per_count: [f64; 4]) -> CoreController<2, 4> {
        let mut cfg = JointConfig::paper_3d();
        for p in 0..2 {
            cfg.gains[p] = s.controller.gains.as_ref().unwrap()[p];
        }
        let ctl = JointController::new(cfg).unwrap();
        CoreController::new(
            ctl,
            FeedbackSource::Wire,
            s.period_us(),
            mm_per_count,
            s.seed(),
        )
    }
}

impl Controller<2, 4> for RestartingCore {
    type Error = firmware::joint::ConfigError;
    fn set_target(&mut self, plane: usize, d: f32) -> Result<(), Self::Error> {
        self.core.set_target(plane, d)
    }
    fn targets_deg(&self) -> [f32; 2] {
        self.core.targets_deg()
    }
    fn step(&mut self, r: &Readings<2, 4>) -> Result<Actuation<2>, Self::Error> {
        if self.steps == self.restart_at {
            let targets = self.core.targets_deg();
            self.core = Self::fresh(&self.scenario, self.mm_per_count);
            for (p, t) in targets.into_iter().enumerate() {
                self.core.set_target(p, t)?;
            }
        }
        self.steps += 1;
        self.core.step(r)
    }
}

/// The fingerprints of the fault-free run with the core in process.
fn reference(s: &RunSpec, restart_at: u64) -> Vec<u64> {
    let plant = s.joint.plant_3d().unwrap();
    let mm = hal_sim::Plant::mm_per_count(&plant);
    let core = RestartingCore {
        scenario: s.clone(),
        core: RestartingCore::fresh(s, mm),
        mm_per_count: mm,
        restart_at,
        steps: 0,
    };
    let mut cl = ClosedLoop::new(plant, core, s.period_us()).unwrap();
    let mut out = Vec::with_capacity(s.steps() as usize);
    cl.run(s.steps(), &mut RunSchedule::new(s), |x| {
        out.push(fingerprint(x));
        Ok::<(), hal_sim::LoopError<firmware::joint::ConfigError>>(())
    })
    .unwrap();
    out
}

/// A board to run the campaign against.
enum Board {
    Pty(PtyBoard),
    /// QEMU, and the directory of its control socket.
    Qemu(
        host_tools::board::qemu::Qemu,
        #[allow(dead_code)] tempfile::TempDir,
    ),
}

impl Board {
    /// What the board says after a failure: a status read without faults,
    /// whether QEMU still runs and what it printed.
    fn diagnose<P: Port>(&mut self, link: &mut Link<FaultyPort<P>>) -> String {
        link.port_mut().set_enabled(false);
        let _ = link.port_mut().flush_delayed();
        std::thread::sleep(Duration::from_millis(500));
        while let Ok(Some(_)) = link.recv_until(Instant::now() + Duration::from_millis(100)) {}
        let status = host_tools::board::hil::status(link);
        let recent: Vec<String> = link
            .port_mut()
            .ledger
            .recent
            .iter()
            .map(|(d, f, frame, item)| format!("{d:?} {} {frame:02x?} -> {item:02x?}", f.name()))
            .collect();
        let board = match self {
            Board::Pty(b) => format!("pty board state {:?}", b.state.lock().unwrap()),
            Board::Qemu(q, _dir) => {
                format!("qemu running {}, printed {:?}", q.is_running(), q.output())
            }
        };
        format!(
            "status without faults: {status:?}\nlink {:?}\n{board}\nlast faults:\n{}",
            link.stats(),
            recent.join("\n")
        )
    }

    fn reset(&mut self) {
        match self {
            Board::Pty(b) => {
                let before = b.state.lock().unwrap().resets;
                b.faults.lock().unwrap().reset = true;
                let until = Instant::now() + Duration::from_secs(5);
                while b.state.lock().unwrap().resets == before {
                    assert!(Instant::now() < until, "pty board did not reset");
                    std::thread::sleep(Duration::from_millis(1));
                }
            }
            Board::Qemu(q, _dir) => {
                q.reset().expect("QMP system_reset");
                // The guest starts from its reset vector; let it set up its
                // UART before the next frame.
                std::thread::sleep(Duration::from_millis(200));
            }
        }
    }
}

/// What a campaign found.
#[derive(Debug)]
struct Report {
    steps: u64,
    injected: [[u64; 7]; 2],
    detected_by_board: u64,
    detected_by_host: u64,
    corrupting: [u64; 2],
    redrawn: u64,
    restarts: u32,
    retries: u64,
    unexpected: u64,
    stale_seqs: u64,
    first_mismatch: Option<u64>,
    wall_s: f64,
}

impl Report {
    fn print(&self, what: &str) {
        println!(
            "fault campaign, {what}: {} lockstep steps in {:.1} s",
            self.steps, self.wall_s
        );
        println!("| fault | host → board | board → host |");
        println!("|---|---|---|");
        for (k, f) in Fault::ALL.iter().enumerate() {
            println!(
                "| {} | {} | {} |",
                f.name(),
                self.injected[0][k],
                self.injected[1][k]
            );
        }
        println!(
            "| board reset | 1 | — |\ncorrupting faults {} / {}; counted by the board's decoder {}, by the host's {}; redrawn (a decoder would have taken them) {}",
            self.corrupting[0], self.corrupting[1], self.detected_by_board, self.detected_by_host, self.redrawn
        );
        println!(
            "restarts detected {}; host retries {}, unexpected replies {}, board stale seqs {}; first step differing from the reference: {:?}",
            self.restarts, self.retries, self.unexpected, self.stale_seqs, self.first_mismatch
        );
    }
}

/// Reads the board's status with faults off, after every held frame was
/// delivered and every reply read: a clean cut between ledger segments.
fn quiesce<P: Port>(link: &mut Link<FaultyPort<P>>) -> Status {
    link.port_mut().set_enabled(false);
    link.port_mut().flush_delayed().unwrap();
    while link
        .recv_until(Instant::now() + Duration::from_millis(100))
        .unwrap()
        .is_some()
    {}
    host_tools::board::hil::status(link).expect("status")
}

fn errors(s: &firmware::protocol::LinkStats) -> u64 {
    u64::from(s.crc_errors + s.cobs_errors + s.overfull + s.malformed)
}

/// Checks one ledger segment: the board's counters (`before` → `after`)
/// and the host's (`host_before` → now) against the reference decoders,
/// and one decoder error per corrupting fault. Returns the errors counted
/// by board and host.
fn check_segment<P: Port>(
    link: &mut Link<FaultyPort<P>>,
    before: &Status,
    after: &Status,
    host_before: &HostLinkStats,
) -> (u64, u64) {
    let ledger = &link.port_mut().ledger;
    let (to_board, to_host) = (
        ledger.expected(Direction::ToBoard),
        ledger.expected(Direction::ToHost),
    );
    let corrupting = |d: Direction| -> u64 {
        Fault::ALL
            .iter()
            .filter(|f| f.corrupts())
            .map(|f| ledger.count(d, *f))
            .sum()
    };
    let (c_board, c_host) = (
        corrupting(Direction::ToBoard),
        corrupting(Direction::ToHost),
    );
    assert_eq!(ledger.undetectable, 0, "a corruption the framing accepts");
    let board = (
        after.frames_ok - before.frames_ok,
        u32::from(after.crc_errors - before.crc_errors),
        u32::from(after.cobs_errors - before.cobs_errors),
        u32::from(after.overfull - before.overfull),
        u32::from(after.malformed - before.malformed),
    );
    assert_eq!(
        board,
        (
            to_board.frames_ok,
            to_board.crc_errors,
            to_board.cobs_errors,
            to_board.overfull,
            to_board.malformed
        ),
        "board counters (frames, crc, cobs, overfull, malformed) vs the bytes delivered to it"
    );
    assert_eq!(
        errors(&to_board),
        c_board,
        "one board error per corrupting fault"
    );
    let h = link.stats();
    let host = (
        h.frames_received - host_before.frames_received,
        h.crc_errors - host_before.crc_errors,
        h.cobs_errors - host_before.cobs_errors,
        h.overfull - host_before.overfull,
        h.malformed - host_before.malformed,
    );
    assert_eq!(
        host,
        (
            u64::from(to_host.frames_ok),
            u64::from(to_host.crc_errors),
            u64::from(to_host.cobs_errors),
            u64::from(to_host.overfull),
            u64::from(to_host.malformed)
        ),
        "host counters (frames, crc, cobs, overfull, malformed) vs the bytes delivered to it"
    );
    assert_eq!(
        errors(&to_host),
        c_host,
        "one host error per corrupting fault"
    );
    (c_board, c_host)
}

/// Runs `steps` lockstep steps against `board` (reached through `port`)
/// with a fault on `rate` of the frames and a board reset half-way;
/// `timeout` is the wait per attempt.
fn campaign(
    mut board: Board,
    port: impl Port,
    steps: u64,
    seed: u64,
    timeout: Duration,
    rate: f64,
) -> Report {
    let s = scenario(steps);
    let reset_at = steps / 2 + 17; // not on a target change
    let want = reference(&s, reset_at);
    let rates = FaultRates {
        per_frame: rate,
        delay: (timeout / 2, timeout * 3),
    };
    let mut link = Link::new(FaultyPort::new(port, rates, seed));
    let setup = LockstepSetup {
        period_us: s.period_us(),
        gains: [0, 1].map(|p| s.controller.gains.as_ref().unwrap()[p]),
        laws: JointConfig::paper_3d().laws,
        // Retries and delays must never look like a dead link.
        link_timeout_ms: Some(10_000),
        timeout,
        // 200 attempts: a loaded CI machine can stall QEMU for seconds; a
        // board that is really gone still fails the step, after 200 waits.
        attempts: 200,
        lose_every: None,
        resume_after_restart: true,
    };
    let mut got = Vec::with_capacity(steps as usize);
    let started = Instant::now();
    let mut detected = (0, 0);
    let (restarts, retries, unexpected, stale_seqs, injected, redrawn, corrupting);
    {
        let plant = s.joint.plant_3d().unwrap();
        let ctl = BoardController::start(&mut link, setup).expect("board setup");
        let mut cl = ClosedLoop::new(plant, ctl, s.period_us()).unwrap();
        let mut schedule = RunSchedule::new(&s);
        let mut ledgers = Vec::new();
        let mut stale = 0u64;
        for (from, to) in [(0, reset_at), (reset_at, steps)] {
            let link = cl.controller.link();
            let before = quiesce(link);
            let host_before = link.stats();
            link.port_mut().reset_ledger();
            link.port_mut().set_enabled(true);
            let run = cl.run(to - from, &mut schedule, |x| {
                got.push(fingerprint(x));
                Ok::<(), hal_sim::LoopError<host_tools::board::controller::BoardError>>(())
            });
            if let Err(e) = run {
                let why = board.diagnose(cl.controller.link());
                panic!("lockstep failed after {} steps: {e}\n{why}", got.len());
            }
            let link = cl.controller.link();
            let after = quiesce(link);
            let (b, h) = check_segment(link, &before, &after, &host_before);
            detected.0 += b;
            detected.1 += h;
            stale += u64::from(after.stale_seqs - before.stale_seqs);
            ledgers.push((
                link.port_mut().ledger.injected,
                link.port_mut().ledger.redrawn,
            ));
            if to == reset_at {
                board.reset();
            }
        }
        restarts = cl.controller.restarts();
        let l = cl.controller.link().stats();
        retries = l.retries;
        unexpected = l.unexpected;
        stale_seqs = stale;
        let mut inj = [[0u64; 7]; 2];
        for (seg, _) in &ledgers {
            for d in 0..2 {
                for k in 0..7 {
                    inj[d][k] += seg[d][k];
                }
            }
        }
        injected = inj;
        redrawn = ledgers.iter().map(|(_, r)| r).sum();
        corrupting = [0, 1].map(|d| {
            Fault::ALL
                .iter()
                .enumerate()
                .filter(|(_, f)| f.corrupts())
                .map(|(k, _)| inj[d][k])
                .sum()
        });
    }
    drop(board);
    Report {
        steps: got.len() as u64,
        injected,
        detected_by_board: detected.0,
        detected_by_host: detected.1,
        corrupting,
        redrawn,
        restarts,
        retries,
        unexpected,
        stale_seqs,
        first_mismatch: got
            .iter()
            .zip(&want)
            .position(|(g, w)| g != w)
            .map(|k| k as u64)
            .or((got.len() != want.len()).then_some(got.len().min(want.len()) as u64)),
        wall_s: started.elapsed().as_secs_f64(),
    }
}

fn assert_campaign(r: &Report, steps: u64) {
    assert_eq!(r.steps, steps, "steps lost");
    assert_eq!(
        r.first_mismatch, None,
        "a step that did not get the board's answer for it"
    );
    assert_eq!(
        r.restarts, 1,
        "the board reset was not detected (or seen twice)"
    );
    assert_eq!(r.detected_by_board, r.corrupting[0]);
    assert_eq!(r.detected_by_host, r.corrupting[1]);
    // Every kind was exercised in both directions.
    for d in 0..2 {
        for (k, f) in Fault::ALL.iter().enumerate() {
            assert!(
                r.injected[d][k] > 0,
                "no {} fault in direction {d}",
                f.name()
            );
        }
    }
}

/// Runs the campaign for `steps` lockstep steps against the pty board (the
/// firmware's board application in a thread), faults on `rate` of the
/// frames drawn from `seed`, a board reset half-way; prints the report and
/// panics naming the first property that does not hold.
pub fn pty_campaign(steps: u64, seed: u64, rate: f64) {
    let (board, port) = PtyBoard::start().expect("pty pair");
    let r = campaign(
        Board::Pty(board),
        port,
        steps,
        seed,
        Duration::from_millis(20),
        rate,
    );
    r.print("pty board");
    assert_campaign(&r, steps);
}

/// As [`pty_campaign`], against the firmware image under QEMU (mps2-an386;
/// the image must be built: see scripts/test-all.sh).
pub fn qemu_campaign(steps: u64, seed: u64, rate: f64) {
    let image = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(host_tools::board::qemu::DEFAULT_IMAGE);
    let dir = tempfile::tempdir().unwrap();
    let qmp = dir.path().join("qmp.sock");
    let board = host_tools::board::qemu::QemuBoard::Mps2An386;
    let mut q = host_tools::board::qemu::Qemu::launch_with_control(board, &image, true, &qmp)
        .expect("qemu");
    let port = q.connect().expect("QEMU's serial socket");
    let wait = Duration::from_millis(60);
    let r = campaign(Board::Qemu(q, dir), port, steps, seed, wait, rate);
    r.print("QEMU image");
    assert_campaign(&r, steps);
}
