//! `softjoint tetmsd`: Yamaguchi's haptic communication (seed 000 L2523–
//! 2846) — a tetrahedral Voigt cube that two users deform at two sites.
//!
//! * `simulate` — both users' scripted styluses on one local model (no
//!   network): force traces, the deformed mesh, the deformation rate;
//! * `pair` — two sites against each other through the network emulator:
//!   two processes over UDP on loopback (default), two threads in one
//!   process (`--in-process`), or virtual time (`--virtual`, deterministic);
//!   reports missed haptic ticks, packet statistics, replica divergence
//!   and whether the final replicas are bit-identical;
//! * `site` — one site of a session between two machines: `--bind` and
//!   `--peer` (without them, the child process `pair` starts, which reads
//!   its peer's port on standard input); a status line every
//!   `--status-every-s`; the site's report as JSON at the end;
//! * `relay` — the path emulator as a UDP relay between two sites (delay,
//!   jitter, loss, reordering, bursts), for networks without `tc netem`.
//!
//! The physics, the session logic and the real-time sites live in
//! `plant_tetmsd` (`session::local`, `session::pair`, `session::realtime`);
//! this is argument handling, the child processes of a pair, file I/O,
//! reports and pictures.
use std::fmt::Write as _;
use std::io::{BufRead, BufReader, Write as _};
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdout, Command, Stdio};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use host_tools::output::{self, JsonObject};
use host_tools::plot::{self, Anchor, Chart, Series, Stroke, Svg};
use host_tools::{out, outln};
use plant_tetmsd::local::{self, LocalRun};
use plant_tetmsd::mesh::CubeMesh;
use plant_tetmsd::model::voigt::{VoigtModel, TICK_S};
use plant_tetmsd::model::V3;
use plant_tetmsd::netem::{NetemConfig, Profile};
use plant_tetmsd::pair::run_virtual;
use plant_tetmsd::realtime::{self, SiteSetup};
use plant_tetmsd::report::{ForceRow, PairOutcome, SiteReport};
use plant_tetmsd::scenario::Scenario;
use serde::Serialize;
use serde_json::Value;

/// Arguments of `softjoint tetmsd`.
#[derive(Args)]
pub struct TetArgs {
    #[command(subcommand)]
    command: TetCommand,
}

#[derive(Subcommand)]
enum TetCommand {
    /// Both users' styluses on one local model, no network: force traces,
    /// the deformed cube and the deformation update rate.
    Simulate(SimulateArgs),
    /// Two sites against each other through the network emulator.
    Pair(PairArgs),
    /// One site of a session: `--bind ADDR:PORT --peer HOST:PORT` between
    /// two machines (the handshake agrees on the configuration and refuses
    /// a mismatch by name; a restarted peer is re-synchronised). Without
    /// `--peer` it is the child process `pair` starts.
    Site(SiteArgs),
    /// The path emulator as a UDP relay process between two sites: each
    /// site's peer address is the relay, and each direction gets the
    /// emulated delay, jitter, loss, reordering and bursts.
    Relay(RelayArgs),
}

/// The scenario and what the command line changes in it.
#[derive(Args, Clone)]
struct ScenarioArgs {
    /// Scenario file (TOML); without it the built-in default
    /// (`--print-default` shows it).
    scenario: Option<PathBuf>,
    /// Print the built-in default scenario as TOML and exit.
    #[arg(long)]
    print_default: bool,
    /// Refinement level of the cube (the seed's are 3–9).
    #[arg(long, allow_negative_numbers = true)]
    level: Option<i64>,
    /// Simulated time (s).
    #[arg(long, allow_negative_numbers = true)]
    duration_s: Option<f64>,
    /// Seed of the network's delays, loss and reordering.
    #[arg(long, allow_negative_numbers = true)]
    seed: Option<u64>,
    /// Round-trip profile: none, table2, table3, table4, table5 (the seed's
    /// Tables 2–5) or rtt-MS (a fixed round trip of MS ms).
    #[arg(long)]
    profile: Option<String>,
    /// Probability a packet is lost (0–0.5).
    #[arg(long, allow_negative_numbers = true)]
    loss: Option<f64>,
    /// Probability a packet is held 1–3 ms extra (0–1).
    #[arg(long, allow_negative_numbers = true)]
    reorder: Option<f64>,
    /// Least ticks between rebases of the speculative replica.
    #[arg(long, allow_negative_numbers = true)]
    rebase_every_ticks: Option<i64>,
}

/// Output flags.
#[derive(Args, Clone)]
struct OutArgs {
    /// Write CSV traces and SVG pictures into this directory (created).
    #[arg(long, value_name = "DIR")]
    out_dir: Option<PathBuf>,
    /// Print a machine-readable summary instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct SimulateArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    #[command(flatten)]
    out: OutArgs,
}

#[derive(Args)]
struct PairArgs {
    #[command(flatten)]
    scenario: ScenarioArgs,
    #[command(flatten)]
    out: OutArgs,
    /// Run in virtual time (deterministic, no sockets, no threads).
    #[arg(long, conflicts_with = "in_process")]
    r#virtual: bool,
    /// Run both sites as threads of this process (UDP on loopback still).
    #[arg(long)]
    in_process: bool,
    /// Busy-wait this long before each haptic deadline instead of sleeping
    /// (µs; 0 sleeps only). Spinning steadies the 1 kHz loop but burns a
    /// core per site.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    spin_us: i64,
    /// Run each site's haptic thread at this real-time (SCHED_FIFO)
    /// priority, 1–99, and its network thread one below (0: the normal
    /// scheduler). Needs CAP_SYS_NICE; a refusal is reported, not fatal.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    rt_priority: i64,
}

#[derive(Args)]
struct SiteArgs {
    /// Which site (0 or 1). Site 0 starts a new session.
    #[arg(long, allow_negative_numbers = true)]
    site: u8,
    /// The scenario (TOML); without it the built-in default.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Busy-wait before each haptic deadline (µs).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    spin_us: u64,
    /// SCHED_FIFO priority of the haptic thread (0: normal).
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    rt_priority: u8,
    /// Local address and port to bind, e.g. `0.0.0.0:7400` or `[::]:7400`
    /// (with `--peer`; default: the unspecified address of the peer's
    /// family, port 7400 + site).
    #[arg(long, requires = "peer")]
    bind: Option<String>,
    /// The peer site's address: `HOST:PORT`, an IPv4 or IPv6 address
    /// (`[::1]:7401`) or a DNS name. Without it, reads `peer PORT` on
    /// standard input (the child process `pair` starts).
    #[arg(long)]
    peer: Option<String>,
    /// Pass this site's packets through the scenario's network emulator
    /// too (with `--peer`; by default a site with a peer sends straight to
    /// the socket, as on a real network).
    #[arg(long, requires = "peer")]
    emulate: bool,
    /// Refinement level (overrides the scenario's; both sites must agree).
    #[arg(long, allow_negative_numbers = true)]
    level: Option<i64>,
    /// Session time this site makes inputs for (s; overrides the
    /// scenario's).
    #[arg(long, allow_negative_numbers = true)]
    duration_s: Option<f64>,
    /// A status line (round trip, resends, incoming gaps, replica lag) on
    /// standard error every this many seconds (0: none).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    status_every_s: f64,
    /// How long to look for the peer (s).
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    connect_timeout_s: f64,
}

#[derive(Args)]
struct RelayArgs {
    /// The relay's socket facing site A (`ADDR:PORT`).
    #[arg(long)]
    a: String,
    /// The relay's socket facing site B.
    #[arg(long)]
    b: String,
    /// Site A's address (default: learnt from its first datagram).
    #[arg(long)]
    a_site: Option<String>,
    /// Site B's address (default: learnt).
    #[arg(long)]
    b_site: Option<String>,
    /// Round-trip profile: none, table2 … table5 (the seed's Tables 2–5)
    /// or rtt-MS (a fixed round trip of MS ms).
    #[arg(long, default_value = "rtt-20")]
    profile: String,
    /// Probability a packet is lost (0–0.5).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    loss: f64,
    /// Probability a packet is held 1–3 ms extra (0–1).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    reorder: f64,
    /// Extra one-way delay per packet, uniform in [0, JITTER] ms.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    jitter_ms: f64,
    /// Mean length of a run of lost packets (0: independent losses).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    burst_len: f64,
    /// Packets each direction's queue holds.
    #[arg(long, default_value_t = 4096, allow_negative_numbers = true)]
    queue_packets: i64,
    /// Seed of the delays, losses and reordering.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    seed: u64,
    /// Stop once nothing has come for this long after the first datagram
    /// (s).
    #[arg(long, default_value_t = 5.0, allow_negative_numbers = true)]
    idle_exit_s: f64,
    /// Stop after this long in any case (s).
    #[arg(long, default_value_t = 3600.0, allow_negative_numbers = true)]
    max_run_s: f64,
}

/// Runs a `softjoint tetmsd` subcommand.
pub fn run(args: TetArgs) -> Result<()> {
    match args.command {
        TetCommand::Simulate(a) => simulate(&a),
        TetCommand::Pair(a) => pair(&a),
        TetCommand::Site(a) => site(&a),
        TetCommand::Relay(a) => relay(&a),
    }
}

/// The scenario with the command line's changes, and its label.
fn load(args: &ScenarioArgs) -> Result<(Scenario, String)> {
    let (mut s, name) = match &args.scenario {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let name = p.display().to_string();
            let s: Scenario = host_tools::input::from_toml(&text, &name)?;
            (s, name)
        }
        None => (Scenario::default(), "the default scenario".to_string()),
    };
    if let Some(l) = args.level {
        s.level = u32::try_from(l).map_err(|_| {
            anyhow!("--level must be 0 to 12 (the seed's levels are 3 to 9), got {l}")
        })?;
    }
    if let Some(d) = args.duration_s {
        s.duration_s = d;
    }
    if let Some(seed) = args.seed {
        s.seed = seed;
    }
    if let Some(p) = &args.profile {
        s.network.profile = p.clone();
    }
    if let Some(l) = args.loss {
        s.network.loss = l;
    }
    if let Some(r) = args.reorder {
        s.network.reorder = r;
    }
    if let Some(r) = args.rebase_every_ticks {
        s.rebase_every_ticks = u32::try_from(r)
            .map_err(|_| anyhow!("--rebase-every-ticks must be 1 to 10000, got {r}"))?;
    }
    // Check everything once, naming the source and the flag or field.
    let label = if args.scenario.is_some() {
        name.clone()
    } else {
        "command line".to_string()
    };
    s.pair_config(&label).map_err(|e| anyhow!("{e}"))?;
    Ok((s, name))
}

fn print_default() -> Result<()> {
    output::print_toml(
        "# softjoint tetmsd scenario (all tables refuse unknown fields)\n",
        &Scenario::default(),
    )
}

/// Refuses an unwritable `--out-dir` before the run rather than after it.
fn check_out_dir(out: &OutArgs) -> Result<()> {
    match &out.out_dir {
        Some(d) => output::check_dir(d),
        None => Ok(()),
    }
}

/// Creates `--out-dir` when the results are written.
fn out_dir(out: &OutArgs) -> Result<Option<PathBuf>> {
    if let Some(d) = &out.out_dir {
        output::create_dir(d)?;
    }
    Ok(out.out_dir.clone())
}

// ---------------------------------------------------------------- simulate

fn simulate(args: &SimulateArgs) -> Result<()> {
    if args.scenario.print_default {
        return print_default();
    }
    let (scenario, name) = load(&args.scenario)?;
    check_out_dir(&args.out)?;
    let cfg = scenario.pair_config(&name).map_err(|e| anyhow!("{e}"))?;
    let model = cfg.session.model()?;
    let run = local::simulate(&model, &cfg).map_err(|e| anyhow!("{name}: {e}"))?;
    let summary = simulate_summary(&name, &scenario, &model, &run)?;
    if let Some(dir) = out_dir(&args.out)? {
        write_simulate_files(&dir, &name, &scenario, model.mesh(), &run)?;
    }
    if args.out.json {
        summary.print()?;
    } else {
        print_simulate_table(&name, &scenario, &model, &run)?;
    }
    Ok(())
}

fn simulate_summary(
    name: &str,
    scenario: &Scenario,
    model: &VoigtModel,
    run: &LocalRun,
) -> Result<JsonObject> {
    let mesh = model.mesh();
    let energy = model.energy(&run.final_state);
    JsonObject::new()
        .field("scenario", name)?
        .field("level", &scenario.level)?
        .field("nodes", &mesh.node_count())?
        .field("tetrahedra", &mesh.tets.len())?
        .field("elements", &mesh.edges.len())?
        .field("substeps_per_tick", &model.substeps())?
        .field("ticks", &run.ticks)?
        .field("compute_s", &run.compute_s)?
        .field("deformation_rate_hz", &run.deformation_rate_hz())?
        .field("max_force_n", &run.max_force_n)?
        .field("contact_ticks", &run.contact_ticks)?
        .field("final_kinetic_j", &energy.kinetic_j)?
        .field("final_elastic_j", &energy.elastic_j)
}

fn write_simulate_files(
    dir: &Path,
    name: &str,
    scenario: &Scenario,
    mesh: &CubeMesh,
    run: &LocalRun,
) -> Result<()> {
    write_forces_csv(&dir.join("forces.csv"), &run.traces)?;
    output::write_svg(
        &dir.join("forces.svg"),
        &forces_svg(
            &format!(
                "{name}: level {} ({} nodes), no network",
                scenario.level,
                mesh.node_count()
            ),
            &run.traces,
            &[None, None],
        ),
    )?;
    output::write_svg(
        &dir.join("mesh.svg"),
        &mesh_svg(
            mesh,
            &run.peak_x_m,
            &format!("level {} cube where the users push hardest", scenario.level),
        ),
    )
}

fn print_simulate_table(
    name: &str,
    scenario: &Scenario,
    model: &VoigtModel,
    run: &LocalRun,
) -> Result<()> {
    let mesh = model.mesh();
    outln!("scenario   {name}");
    outln!(
        "mesh       level {}: {} nodes, {} tetrahedra, {} Voigt elements, {} substeps per 1 ms tick",
        scenario.level,
        mesh.node_count(),
        mesh.tets.len(),
        mesh.edges.len(),
        model.substeps()
    );
    outln!(
        "run        {} ticks in {:.3} s of computation: {:.0} deformation updates/s (the seed: 1000 Hz at level 3 to 50 Hz at 729 nodes)",
        run.ticks, run.compute_s, run.deformation_rate_hz()
    );
    for s in 0..2 {
        outln!(
            "user {s}     in contact {:.2} s, largest force {:.3} N",
            run.contact_ticks[s] as f64 * TICK_S,
            run.max_force_n[s]
        );
    }
    Ok(())
}

// ---------------------------------------------------------------- pair

fn pair(args: &PairArgs) -> Result<()> {
    if args.scenario.print_default {
        return print_default();
    }
    if args.spin_us < 0 || args.spin_us > 1000 {
        bail!("--spin-us must be 0 to 1000 µs, got {}", args.spin_us);
    }
    let spin = args.spin_us as u64;
    if args.rt_priority < 0 || args.rt_priority > 99 {
        bail!("--rt-priority must be 0 to 99, got {}", args.rt_priority);
    }
    let rt = args.rt_priority as u8;
    let (scenario, name) = load(&args.scenario)?;
    check_out_dir(&args.out)?;
    let started = Instant::now();
    let outcome = if args.r#virtual {
        virtual_pair(&scenario, &name)?
    } else if args.in_process {
        let setups = [
            SiteSetup::from_scenario(&scenario, 0, spin, rt)?,
            SiteSetup::from_scenario(&scenario, 1, spin, rt)?,
        ];
        PairOutcome {
            mode: "in-process",
            sites: realtime::run_pair_in_process(setups)?,
            display_gap_max_mm: None,
            wall_s: 0.0,
        }
    } else {
        processes(&scenario, spin, rt)?
    };
    let outcome = PairOutcome {
        wall_s: started.elapsed().as_secs_f64(),
        ..outcome
    };
    report_pair(&scenario, &name, &outcome, &args.out)
}

fn virtual_pair(scenario: &Scenario, name: &str) -> Result<PairOutcome> {
    let cfg = scenario.pair_config(name).map_err(|e| anyhow!("{e}"))?;
    let r = run_virtual(&cfg).map_err(|e| anyhow!("{name}: {e}"))?;
    if !r.identical {
        bail!(
            "the final replicas differ (largest node distance {} m): this is a defect",
            r.final_distance_m
        );
    }
    Ok(PairOutcome::from_virtual(&r, cfg.duration_ticks))
}

/// Two child processes `softjoint tetmsd site`, over UDP on loopback.
///
/// The sites die with this process however it ends (their own process
/// group and `PR_SET_PDEATHSIG`, `host_tools::stop::die_with_parent`, as
/// `hil` does for QEMU): a SIGTERM, Ctrl-C, SIGHUP or SIGKILL to `pair`
/// leaves no site running under PID 1. The scenario file they read is
/// removed as soon as both have reported their port (each reads it before
/// it binds), so it is not left in the temporary directory for the length
/// of the run either.
///
/// SIGINT, SIGTERM and SIGHUP end `pair` at once with 130, 143 or 129
/// (the sites with it, no report written), whatever their disposition was
/// when it started: a job a script starts in the background starts with
/// SIGINT ignored, and `kill -INT` then did nothing for the run's length.
fn processes(scenario: &Scenario, spin_us: u64, rt_priority: u8) -> Result<PairOutcome> {
    let exe = std::env::current_exe().context("cannot find the softjoint binary")?;
    let file = std::env::temp_dir().join(format!("softjoint-tetmsd-{}.toml", std::process::id()));
    end_on_signals(file.clone())?;
    output::write_toml(&file, "", scenario)?;
    let result = (|| {
        let spawned = spawn_sites(&exe, &file, spin_us, rt_priority);
        let mut children = spawned?;
        let introduced = introduce_sites(&mut children);
        // Both sites have read the scenario (or failed): the file goes.
        std::fs::remove_file(&file).ok();
        let readers = introduced?;
        let [r0, r1] = collect_reports(children, readers)?;
        Ok(PairOutcome {
            mode: "processes",
            sites: [r0, r1],
            display_gap_max_mm: None,
            wall_s: 0.0,
        })
    })();
    std::fs::remove_file(&file).ok();
    result
}

/// Ends the process on SIGINT, SIGTERM or SIGHUP with the signal's
/// status, removing the sites' scenario `file`; the sites die with it
/// (`PR_SET_PDEATHSIG`). A watcher thread polls the stop flag every 20 ms.
fn end_on_signals(file: PathBuf) -> Result<()> {
    let stop = host_tools::stop::Stop::on_signals()?;
    std::thread::spawn(move || loop {
        if let Some(s) = stop.requested() {
            std::fs::remove_file(&file).ok();
            eprintln!(
                "stopped by {}: the sites ended with it, no report written",
                s.name()
            );
            std::process::exit(i32::from(s.exit_code()));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    });
    Ok(())
}

/// Starts `softjoint tetmsd site` for sites 0 and 1 on the scenario `file`.
fn spawn_sites(exe: &Path, file: &Path, spin_us: u64, rt_priority: u8) -> Result<Vec<Child>> {
    let mut children = Vec::new();
    for s in 0..2 {
        let mut cmd = Command::new(exe);
        host_tools::stop::die_with_parent(&mut cmd);
        let child = cmd
            .args([
                "tetmsd",
                "site",
                "--site",
                &s.to_string(),
                "--spin-us",
                &spin_us.to_string(),
                "--rt-priority",
                &rt_priority.to_string(),
            ])
            .arg("--scenario")
            .arg(file)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .context("cannot start a site process")?;
        children.push(child);
    }
    Ok(children)
}

/// Reads each site's `port N` and tells each the other's (`peer N`);
/// returns the readers of their standard outputs.
fn introduce_sites(children: &mut [Child]) -> Result<Vec<BufReader<ChildStdout>>> {
    let mut readers = Vec::new();
    let mut ports = Vec::new();
    for c in children.iter_mut() {
        let out = c.stdout.take().ok_or_else(|| anyhow!("site stdout"))?;
        let mut r = BufReader::new(out);
        let mut line = String::new();
        r.read_line(&mut line)?;
        let port = line
            .trim()
            .strip_prefix("port ")
            .and_then(|p| p.parse::<u16>().ok())
            .ok_or_else(|| anyhow!("a site process did not report its port (said {line:?})"))?;
        ports.push(port);
        readers.push(r);
    }
    for (k, c) in children.iter_mut().enumerate() {
        let mut stdin = c.stdin.take().ok_or_else(|| anyhow!("site stdin"))?;
        writeln!(stdin, "peer {}", ports[1 - k])?;
    }
    Ok(readers)
}

/// Waits for both sites and reads their JSON reports.
fn collect_reports(
    children: Vec<Child>,
    readers: Vec<BufReader<ChildStdout>>,
) -> Result<[SiteReport; 2]> {
    let mut reports = Vec::new();
    for (k, (mut c, mut r)) in children.into_iter().zip(readers).enumerate() {
        let mut text = String::new();
        std::io::Read::read_to_string(&mut r, &mut text)?;
        let status = c.wait()?;
        let mut err = String::new();
        if let Some(mut e) = c.stderr.take() {
            std::io::Read::read_to_string(&mut e, &mut err).ok();
        }
        if !status.success() {
            bail!("site {k} failed: {}", err.trim());
        }
        let rep: SiteReport = serde_json::from_str(text.trim())
            .with_context(|| format!("site {k} wrote no report"))?;
        reports.push(rep);
    }
    let r1 = reports.pop().ok_or_else(|| anyhow!("no report"))?;
    let r0 = reports.pop().ok_or_else(|| anyhow!("no report"))?;
    Ok([r0, r1])
}

fn site(args: &SiteArgs) -> Result<()> {
    if args.site > 1 {
        bail!("--site must be 0 or 1, got {}", args.site);
    }
    let scenario = site_scenario(args)?;
    let mut setup = SiteSetup::from_scenario(&scenario, args.site, args.spin_us, args.rt_priority)?;
    setup.connect_timeout = seconds("--connect-timeout-s", args.connect_timeout_s)?;
    let stop = host_tools::stop::Stop::on_signals()?;
    setup.stop = stop.flag();
    let status_printer = if args.status_every_s > 0.0 {
        let every = seconds("--status-every-s", args.status_every_s)?;
        let (tx, rx) = std::sync::mpsc::sync_channel::<realtime::SiteStatus>(16);
        setup.status = Some((every, tx));
        Some(std::thread::spawn(move || {
            for s in rx {
                eprintln!("{}", s.line());
            }
        }))
    } else {
        None
    };
    let (socket, peer) = match &args.peer {
        Some(peer) => {
            if !args.emulate {
                setup.netem = None;
            }
            bind_to_peer(args.site, args.bind.as_deref(), peer)?
        }
        None => peer_from_stdin()?,
    };
    let report = realtime::run_site(setup, socket, peer);
    if let Some(t) = status_printer {
        t.join().ok();
    }
    output::print_json(&report?)?;
    Ok(())
}

/// The site's scenario: the file or the default, with `--level` and
/// `--duration-s`, checked.
fn site_scenario(args: &SiteArgs) -> Result<Scenario> {
    let (mut scenario, name) = match &args.scenario {
        Some(p) => {
            let text = std::fs::read_to_string(p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let name = p.display().to_string();
            (host_tools::input::from_toml(&text, &name)?, name)
        }
        None => (Scenario::default(), "the default scenario".to_string()),
    };
    if let Some(l) = args.level {
        scenario.level = u32::try_from(l).map_err(|_| {
            anyhow!("--level must be 0 to 12 (the seed's levels are 3 to 9), got {l}")
        })?;
    }
    if let Some(d) = args.duration_s {
        scenario.duration_s = d;
    }
    scenario.pair_config(&name).map_err(|e| anyhow!("{e}"))?;
    Ok(scenario)
}

/// A positive, finite number of seconds from `flag`.
fn seconds(flag: &str, s: f64) -> Result<std::time::Duration> {
    if !(s.is_finite() && s > 0.0 && s <= 1e6) {
        bail!("{flag} must be a positive number of seconds up to 1e6, got {s}");
    }
    Ok(std::time::Duration::from_secs_f64(s))
}

/// `HOST:PORT` resolved (DNS names, IPv4, IPv6 in brackets): the first
/// address, or an error naming `flag`.
fn resolve(flag: &str, text: &str) -> Result<SocketAddr> {
    use std::net::ToSocketAddrs;
    text.to_socket_addrs()
        .with_context(|| format!("{flag} {text:?}: not HOST:PORT, or the name does not resolve"))?
        .next()
        .ok_or_else(|| anyhow!("{flag} {text:?}: the name resolves to no address"))
}

/// The socket bound at `bind` (default: the unspecified address of the
/// peer's family, port 7400 + site) and the peer's address.
fn bind_to_peer(site: u8, bind: Option<&str>, peer: &str) -> Result<(UdpSocket, SocketAddr)> {
    let peer = resolve("--peer", peer)?;
    let local = match bind {
        Some(b) => resolve("--bind", b)?,
        None => {
            let any: std::net::IpAddr = if peer.is_ipv6() {
                std::net::Ipv6Addr::UNSPECIFIED.into()
            } else {
                std::net::Ipv4Addr::UNSPECIFIED.into()
            };
            SocketAddr::new(any, 7400 + u16::from(site))
        }
    };
    if local.is_ipv6() != peer.is_ipv6() {
        bail!("--bind {local} and --peer {peer} are of different address families");
    }
    let socket = UdpSocket::bind(local).with_context(|| format!("--bind {local}: cannot bind"))?;
    Ok((socket, peer))
}

/// The child process of `pair`: a loopback socket, its port on standard
/// output, the peer's port from standard input.
fn peer_from_stdin() -> Result<(UdpSocket, SocketAddr)> {
    let socket = realtime::bind_loopback()?;
    outln!("port {}", socket.local_addr()?.port());
    output::flush_stdout()?;
    let mut line = String::new();
    std::io::stdin().read_line(&mut line)?;
    let port: u16 = line
        .trim()
        .strip_prefix("peer ")
        .and_then(|p| p.parse().ok())
        .ok_or_else(|| anyhow!("expected `peer PORT` on standard input, got {line:?}"))?;
    Ok((socket, SocketAddr::from(([127, 0, 0, 1], port))))
}

/// `softjoint tetmsd relay`: the emulated path between two sites.
fn relay(args: &RelayArgs) -> Result<()> {
    let profile = Profile::by_name(&args.profile).ok_or_else(|| {
        anyhow!(
            "--profile {:?}: expected none, table2, table3, table4, table5 or rtt-MS",
            args.profile
        )
    })?;
    if !(args.jitter_ms.is_finite() && (0.0..=1000.0).contains(&args.jitter_ms)) {
        bail!("--jitter-ms must be 0 to 1000, got {}", args.jitter_ms);
    }
    let netem = NetemConfig {
        profile,
        loss: args.loss,
        reorder: args.reorder,
        capacity: usize::try_from(args.queue_packets).map_err(|_| {
            anyhow!(
                "--queue-packets must be positive, got {}",
                args.queue_packets
            )
        })?,
        jitter_us: (args.jitter_ms * 1000.0).round() as u64,
        burst_len: args.burst_len,
    };
    netem.validate().map_err(|e| anyhow!("relay: {e}"))?;
    let bind = |flag: &str, text: &str| -> Result<UdpSocket> {
        let addr = resolve(flag, text)?;
        UdpSocket::bind(addr).with_context(|| format!("{flag} {addr}: cannot bind"))
    };
    let site =
        |flag: &str, text: &Option<String>| text.as_deref().map(|t| resolve(flag, t)).transpose();
    let stop = host_tools::stop::Stop::on_signals()?;
    let report = realtime::run_relay(realtime::RelaySetup {
        a: bind("--a", &args.a)?,
        b: bind("--b", &args.b)?,
        a_site: site("--a-site", &args.a_site)?,
        b_site: site("--b-site", &args.b_site)?,
        netem,
        seed: args.seed,
        idle_exit: seconds("--idle-exit-s", args.idle_exit_s)?,
        max_run: seconds("--max-run-s", args.max_run_s)?,
        stop: stop.flag(),
    })?;
    output::print_json(&report)?;
    Ok(())
}

/// A site report without its long arrays, for `--json`.
fn site_json(r: &SiteReport) -> Result<Value> {
    let mut v = serde_json::to_value(r)?;
    if let Some(o) = v.as_object_mut() {
        for k in ["final_x_m", "peak_x_m", "trace"] {
            o.remove(k);
        }
        if let Some(rep) = o.get_mut("replica").and_then(Value::as_object_mut) {
            rep.remove("divergence_series");
        }
    }
    Ok(v)
}

#[derive(Serialize)]
struct PairSummary<'a> {
    scenario: &'a str,
    mode: &'a str,
    level: u32,
    nodes: usize,
    profile: &'a str,
    loss: f64,
    reorder: f64,
    duration_s: f64,
    seed: u64,
    wall_s: f64,
    replicas_identical: bool,
    final_max_distance_m: f64,
    /// Bound on the gap between the two users' displays: the sum of the
    /// two sites' largest divergences from the common committed replica.
    display_gap_bound_mm: f64,
    display_gap_max_mm: Option<f64>,
    sites: Vec<Value>,
}

fn report_pair(scenario: &Scenario, name: &str, o: &PairOutcome, out: &OutArgs) -> Result<()> {
    let (identical, dist) = o.compare_finals();
    let nodes = CubeMesh::new(scenario.level, scenario.side_mm * 1e-3)?.node_count();
    if let Some(dir) = out_dir(out)? {
        write_pair_files(&dir, scenario, name, nodes, o)?;
    }
    let summary = PairSummary {
        scenario: name,
        mode: o.mode,
        level: scenario.level,
        nodes,
        profile: &scenario.network.profile,
        loss: scenario.network.loss,
        reorder: scenario.network.reorder,
        duration_s: scenario.duration_s,
        seed: scenario.seed,
        wall_s: o.wall_s,
        replicas_identical: identical,
        final_max_distance_m: dist,
        display_gap_bound_mm: o.display_gap_bound_mm(),
        display_gap_max_mm: o.display_gap_max_mm,
        sites: vec![site_json(&o.sites[0])?, site_json(&o.sites[1])?],
    };
    if out.json {
        output::print_json(&summary)?;
    } else {
        out!("{}", pair_table(&summary, o));
    }
    if !identical {
        bail!("the final replicas differ (largest node distance {dist} m): this is a defect");
    }
    Ok(())
}

fn write_pair_files(
    dir: &Path,
    scenario: &Scenario,
    name: &str,
    nodes: usize,
    o: &PairOutcome,
) -> Result<()> {
    let traces = [o.sites[0].trace.clone(), o.sites[1].trace.clone()];
    write_forces_csv(&dir.join("forces.csv"), &traces)?;
    write_divergence_csv(&dir.join("divergence.csv"), &o.sites)?;
    let title = format!(
        "{name}: level {} ({nodes} nodes), profile {}, loss {}, {} run",
        scenario.level, scenario.network.profile, scenario.network.loss, o.mode
    );
    let series = [
        Some(&o.sites[0].replica.divergence_series),
        Some(&o.sites[1].replica.divergence_series),
    ];
    output::write_svg(
        &dir.join("forces.svg"),
        &forces_svg(&title, &traces, &series),
    )?;
    let mesh = CubeMesh::new(scenario.level, scenario.side_mm * 1e-3)?;
    output::write_svg(
        &dir.join("mesh.svg"),
        &mesh_svg(
            &mesh,
            &o.sites[0].peak_x_m,
            &format!(
                "site 0's display where its user pushed hardest (level {})",
                scenario.level
            ),
        ),
    )
}

fn pair_table(s: &PairSummary<'_>, o: &PairOutcome) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "scenario   {} ({} run, {:.1} s wall)",
        s.scenario, s.mode, s.wall_s
    );
    let _ = writeln!(
        t,
        "session    level {} ({} nodes), profile {}, loss {}, reorder {}, {} s",
        s.level, s.nodes, s.profile, s.loss, s.reorder, s.duration_s
    );
    let _ = writeln!(
        t,
        "replicas   {} at the end (largest node distance {} m)",
        if s.replicas_identical {
            "bit-identical"
        } else {
            "DIFFERENT"
        },
        s.final_max_distance_m
    );
    let gap = match s.display_gap_max_mm {
        Some(g) => format!("{g:.3} mm measured, "),
        None => String::new(),
    };
    let _ = writeln!(
        t,
        "displays   gap {gap}at most {:.3} mm (sum of the divergences)",
        s.display_gap_bound_mm
    );
    let _ = writeln!(t);
    for r in &o.sites {
        let _ = writeln!(t, "site {}", r.site);
        if let Some(h) = &r.haptic {
            let _ = writeln!(
                t,
                "  haptic 1 kHz   {} ticks, {} missed; lateness p50 {:.0} µs, p99 {:.0} µs, p99.9 {:.0} µs, max {:.0} µs; work {:.1} µs mean; {}",
                h.ticks, h.missed_ticks, h.late_p50_us, h.late_p99_us, h.late_p999_us, h.late_max_us, h.work_mean_us, h.scheduling
            );
        }
        if let Some(d) = &r.deformation {
            let _ = writeln!(
                t,
                "  deformation    {:.0} updates/s, {:.0} replica ticks per busy second, busy {:.0} %",
                d.updates_per_s,
                d.ticks_per_busy_s,
                100.0 * d.busy_fraction
            );
        }
        if let Some(d) = &r.display {
            let _ = writeln!(
                t,
                "  display 30 Hz  {} frames, shape {:.1} ms old on average ({:.0} ms at most)",
                d.frames, d.age_mean_ms, d.age_max_ms
            );
        }
        let l = &r.link;
        let _ = writeln!(
            t,
            "  packets        {} sent, {} resent, {} acks; {} received, {} duplicates, {} gaps seen / {} filled, {} refused; rtt {}/{:.0}/{} µs",
            l.inputs_sent, l.retransmissions, l.acks_sent, l.inputs_received, l.duplicates, l.gaps_seen, l.gaps_filled, l.malformed, l.rtt_min_us, l.rtt_mean_us, l.rtt_max_us
        );
        let _ = writeln!(
            t,
            "  copies         {} sent ({} of {} bytes sent), {} peer inputs came first in a copy, {} copies already had",
            l.copies_sent, l.copy_bytes, l.bytes_sent, l.inputs_from_copies, l.copies_redundant
        );
        let n = &r.netem;
        let _ = writeln!(
            t,
            "  emulator       {} offered, {} lost, {} held extra, {} overflowed, longest one-way {:.1} ms",
            n.offered, n.lost, n.held_extra, n.overflowed, n.max_delay_us as f64 / 1000.0
        );
        let p = &r.replica;
        let _ = writeln!(
            t,
            "  divergence     max {:.3} mm, p99 {:.3} mm, mean {:.3} mm over {} frames ({} unchecked); {} rebases, lag ≤ {} ticks",
            p.divergence_max_mm, p.divergence_p99_mm, p.divergence_mean_mm, p.frames_checked, p.frames_unchecked, p.rebases, p.lag_max_ticks
        );
        let _ = writeln!(
            t,
            "  user           in contact {:.2} s, largest force {:.3} N",
            r.contact_ticks as f64 * TICK_S,
            r.max_force_n
        );
    }
    t
}

// ---------------------------------------------------------------- files

fn write_forces_csv(path: &Path, traces: &[Vec<ForceRow>; 2]) -> Result<()> {
    let mut s = String::from(
        "t_s,tip0_x_mm,tip0_y_mm,tip0_z_mm,force0_x_n,force0_y_n,force0_z_n,contact0,tip1_x_mm,tip1_y_mm,tip1_z_mm,force1_x_n,force1_y_n,force1_z_n,contact1\n",
    );
    for (a, b) in traces[0].iter().zip(&traces[1]) {
        let _ = write!(s, "{}", a.tick as f64 * TICK_S);
        for r in [a, b] {
            let _ = write!(
                s,
                ",{},{},{},{},{},{},{}",
                r.tip_m[0] * 1e3,
                r.tip_m[1] * 1e3,
                r.tip_m[2] * 1e3,
                r.force_n[0],
                r.force_n[1],
                r.force_n[2],
                u8::from(r.contact)
            );
        }
        s.push('\n');
    }
    output::write_csv(path, &s)
}

fn write_divergence_csv(path: &Path, sites: &[SiteReport; 2]) -> Result<()> {
    let mut s = String::from("site,t_s,divergence_mm\n");
    for r in sites {
        for (tick, d) in &r.replica.divergence_series {
            let _ = writeln!(s, "{},{},{}", r.site, *tick as f64 * TICK_S, d);
        }
    }
    output::write_csv(path, &s)
}

/// Force, stylus depth and (for pairs) divergence against time.
fn forces_svg(
    title: &str,
    traces: &[Vec<ForceRow>; 2],
    divergence: &[Option<&Vec<(u64, f64)>>; 2],
) -> String {
    const COLOURS: [&str; 2] = ["#1f5fbf", "#d2462d"];
    let t: Vec<Vec<f64>> = traces
        .iter()
        .map(|tr| tr.iter().map(|r| r.tick as f64 * TICK_S).collect())
        .collect();
    let mut force = Vec::new();
    let mut depth = Vec::new();
    for s in 0..2 {
        let fz: Vec<f64> = traces[s].iter().map(|r| r.force_n[2]).collect();
        let fm: Vec<f64> = traces[s]
            .iter()
            .map(|r| (r.force_n[0].powi(2) + r.force_n[1].powi(2) + r.force_n[2].powi(2)).sqrt())
            .collect();
        let z: Vec<f64> = traces[s].iter().map(|r| r.tip_m[2] * 1e3).collect();
        force.push(Series::over(
            format!("user {s} |F|"),
            COLOURS[s],
            false,
            &t[s],
            &fm,
        ));
        force.push(Series::over(
            format!("user {s} Fz"),
            COLOURS[s],
            true,
            &t[s],
            &fz,
        ));
        depth.push(Series::over(
            format!("user {s} stylus z"),
            COLOURS[s],
            false,
            &t[s],
            &z,
        ));
    }
    let mut charts = vec![
        Chart {
            title: format!("{title}: felt force"),
            x_label: "time (s)".into(),
            y_label: "force (N)".into(),
            series: force,
        },
        Chart {
            title: "stylus height (the cube's top face is at the side length)".into(),
            x_label: "time (s)".into(),
            y_label: "stylus z (mm)".into(),
            series: depth,
        },
    ];
    if divergence.iter().any(|d| d.is_some_and(|v| !v.is_empty())) {
        let series = (0..2)
            .filter_map(|s| {
                divergence[s].map(|v| {
                    let x: Vec<f64> = v.iter().map(|(k, _)| *k as f64 * TICK_S).collect();
                    let y: Vec<f64> = v.iter().map(|(_, d)| *d).collect();
                    Series::over(format!("site {s}"), COLOURS[s], false, &x, &y)
                })
            })
            .collect();
        charts.push(Chart {
            title: "displayed shape vs committed replica (largest node distance per 30 Hz frame)"
                .into(),
            x_label: "time (s)".into(),
            y_label: "divergence (mm)".into(),
            series,
        });
    }
    plot::line_charts(&charts).finish()
}

/// The cube's surface in an oblique view, coloured by displacement, over
/// the outline of the rest shape.
fn mesh_svg(mesh: &CubeMesh, x_m: &[[f64; 3]], title: &str) -> String {
    let (w, h) = (760.0, 640.0);
    let mut svg = Svg::new(w, h);
    svg.text_styled(
        20.0,
        28.0,
        15.0,
        Anchor::Start,
        r#"font-weight="bold""#,
        title,
    );
    let x: Vec<V3> = if x_m.len() == mesh.node_count() {
        x_m.iter().map(|p| V3::new(p[0], p[1], p[2])).collect()
    } else {
        mesh.nodes_m.clone()
    };
    let view = Oblique::of(mesh, w, h);
    let disp: Vec<f64> = x
        .iter()
        .zip(&mesh.nodes_m)
        .map(|(a, b)| (a - b).norm())
        .collect();
    let max_disp = disp.iter().copied().fold(0.0, f64::max).max(1e-12);
    draw_rest_cube(&mut svg, mesh, &view);
    draw_surface(&mut svg, mesh, &x, &disp, max_disp, &view);
    draw_colour_bar(&mut svg, w, max_disp);
    svg.text(
        20.0,
        h - 16.0,
        12.0,
        Anchor::Start,
        &format!(
            "{} nodes, {} tetrahedra; dashed: the rest cube ({} mm); z up, viewed from the front right",
            mesh.node_count(),
            mesh.tets.len(),
            mesh.side_m * 1e3
        ),
    );
    svg.finish()
}

/// The oblique view of the cube: from the front right, above (turned by
/// −35° about z, tilted 28°), scaled onto a `w` × `h` picture.
struct Oblique {
    az: f64,
    el: f64,
    half_side_m: f64,
    scale: f64,
    cx: f64,
    cy: f64,
}

impl Oblique {
    fn of(mesh: &CubeMesh, w: f64, h: f64) -> Self {
        Oblique {
            az: (-35f64).to_radians(),
            el: 28f64.to_radians(),
            half_side_m: mesh.side_m / 2.0,
            scale: 0.46 * w / mesh.side_m,
            cx: w / 2.0 - 50.0,
            cy: h / 2.0 + 30.0,
        }
    }

    /// Across, up and depth (far = large) of `p` in the camera frame.
    fn view(&self, p: V3) -> (f64, f64, f64) {
        let (az, el) = (self.az, self.el);
        let c = p - V3::repeat(self.half_side_m);
        let (xr, yr) = (
            c.x * az.cos() - c.y * az.sin(),
            c.x * az.sin() + c.y * az.cos(),
        );
        // Camera looking along +yr, tilted down by el: screen up is
        // (yr sin el + z cos el), depth (yr cos el − z sin el), far = large.
        (
            xr,
            yr * el.sin() + c.z * el.cos(),
            yr * el.cos() - c.z * el.sin(),
        )
    }

    /// Picture coordinates (px) of `p`.
    fn screen(&self, p: V3) -> (f64, f64) {
        let (sx, sy, _) = self.view(p);
        (self.cx + sx * self.scale, self.cy - sy * self.scale)
    }

    /// The viewing direction in the model frame (a face is seen when its
    /// outward normal points against it).
    fn forward(&self) -> V3 {
        let (az, el) = (self.az, self.el);
        V3::new(az.sin() * el.cos(), az.cos() * el.cos(), -el.sin())
    }
}

/// The rest cube's twelve edges, dashed (drawn first, under the surface).
fn draw_rest_cube(svg: &mut Svg, mesh: &CubeMesh, view: &Oblique) {
    let corner = |i: usize| {
        V3::new(
            (i & 1) as f64 * mesh.side_m,
            ((i >> 1) & 1) as f64 * mesh.side_m,
            ((i >> 2) & 1) as f64 * mesh.side_m,
        )
    };
    let edges = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    for (a, b) in edges {
        svg.line(
            view.screen(corner(a)),
            view.screen(corner(b)),
            Stroke::dashed("#999", 1.0),
        );
    }
}

/// The boundary faces of the shape `x` that face the camera, far to
/// near, coloured by their mean displacement `disp` over `max_disp`.
fn draw_surface(
    svg: &mut Svg,
    mesh: &CubeMesh,
    x: &[V3],
    disp: &[f64],
    max_disp: f64,
    view: &Oblique,
) {
    let forward = view.forward();
    let mut faces: Vec<(f64, [usize; 3])> = mesh
        .boundary_faces
        .iter()
        .map(|f| {
            let idx = f.map(|i| i as usize);
            let c = (x[idx[0]] + x[idx[1]] + x[idx[2]]) / 3.0;
            (view.view(c).2, idx)
        })
        .collect();
    faces.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (_, f) in &faces {
        let n = (x[f[1]] - x[f[0]]).cross(&(x[f[2]] - x[f[0]]));
        if n.dot(&forward) >= 0.0 {
            continue;
        }
        let t = (disp[f[0]] + disp[f[1]] + disp[f[2]]) / 3.0 / max_disp;
        let (r, g, b) = plot::false_colour(t);
        let pts: Vec<(f64, f64)> = f.iter().map(|&i| view.screen(x[i])).collect();
        svg.polygon(
            &pts,
            &format!("rgb({r},{g},{b})"),
            Stroke::solid("#333", 0.6),
        );
    }
}

/// The displacement colour bar at the right of a picture `w` wide.
fn draw_colour_bar(svg: &mut Svg, w: f64, max_disp: f64) {
    let (bx, by, bh) = (w - 70.0, 80.0, 300.0);
    for k in 0..60 {
        let t = 1.0 - k as f64 / 59.0;
        let (r, g, b) = plot::false_colour(t);
        svg.rect(
            bx,
            by + k as f64 * bh / 60.0,
            18.0,
            bh / 60.0 + 0.5,
            &format!("rgb({r},{g},{b})"),
            None,
        );
    }
    svg.text(bx + 9.0, by - 10.0, 12.0, Anchor::Middle, "displacement");
    svg.text(
        bx - 4.0,
        by + 8.0,
        12.0,
        Anchor::End,
        &format!("{:.2} mm", max_disp * 1e3),
    );
    svg.text(bx - 4.0, by + bh, 12.0, Anchor::End, "0 mm");
}
