//! `softjoint tune`: controller gains searched on an identified plant,
//! robust over its uncertainty.
use std::path::PathBuf;

use anyhow::{bail, Context};
use clap::Args;
use host_tools::files::gains::GainsFile;
use host_tools::files::plant::{PlantFile, PlantParams};
use host_tools::files::JointKind;
use host_tools::joint::tune;
use host_tools::output;
use host_tools::stop::{Stop, StopSignal, Stopped};

/// The arguments of `tune`.
#[derive(Args)]
pub struct TuneArgs {
    /// The plant file (`softjoint identify joint` writes one).
    plant: PathBuf,
    /// Candidate gain sets (the first is the paper's).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    candidates: u64,
    /// Plants per candidate: the identified one and draws from its
    /// uncertainty.
    #[arg(long, allow_negative_numbers = true, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    plants: u64,
    /// Seed of the candidates and the plant draws.
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u64).range(1..=1024))]
    threads: Option<u64>,
    /// Run the search's units as tasks on the Ray cluster at this address
    /// (through the Python package's driver, `python3 -m
    /// softjoint.ray_sweep`; $SOFTJOINT_PYTHON names another Python). The
    /// reduction, the held-out check and the files are this program's:
    /// the result is the one without --ray.
    #[arg(long, value_name = "ADDRESS", conflicts_with_all = ["resume", "threads"])]
    ray: Option<String>,
    /// Write the gains file here.
    #[arg(short, long, default_value = "gains.toml")]
    output: PathBuf,
    /// Search v_offset too (uniform in 1.2–2.2 V, the paper's 1.7 V ±
    /// 0.5 V); without it every candidate keeps 1.7 V.
    #[arg(long)]
    search_v_offset: bool,
    /// Print a machine-readable result.
    #[arg(long)]
    json: bool,
    /// Write the gains and exit 0 even when they lose to the paper's on
    /// the held-out steps (the file and the output say so).
    #[arg(long)]
    allow_unproven: bool,
    /// Go on with a search stopped by a signal (Ctrl-C, SIGTERM, SIGHUP),
    /// from the search state it wrote: its scored candidates are not run
    /// again. Same plant file, --plants, --seed and --search-v-offset;
    /// --candidates may be more (the candidates are one seeded sequence).
    /// A search stopped again writes its state back to this file.
    #[arg(long, value_name = "STATE")]
    resume: Option<PathBuf>,
    /// A gains file in use now (`tune -o` or hand-written): scored on the
    /// held-out manoeuvres and plants beside the tuned and the paper's
    /// gains, so the output says whether the tuned gains beat them too.
    /// Reported only: the recommendation is against the paper's gains.
    #[arg(long, value_name = "GAINS_FILE")]
    current: Option<PathBuf>,
}

impl TuneArgs {
    fn request(&self) -> tune::TuneRequest {
        tune::TuneRequest {
            candidates: self.candidates as usize,
            plants: self.plants as usize,
            seed: self.seed,
            search_v_offset: self.search_v_offset,
        }
    }

    /// Where a stopped search writes its state: the file it resumed from,
    /// or beside the gains file (`gains.toml` → `gains.search.toml`).
    fn state_path(&self) -> PathBuf {
        match &self.resume {
            Some(p) => p.clone(),
            None => self.output.with_extension("search.toml"),
        }
    }

    /// The scored candidates of the search resumed, checked against this
    /// one.
    fn resumed(&self, plant_bytes: &[u8]) -> anyhow::Result<Vec<tune::Scored>> {
        let Some(path) = &self.resume else {
            return Ok(Vec::new());
        };
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read --resume {}", path.display()))?;
        let state: tune::SearchState =
            host_tools::input::from_toml(&text, &path.display().to_string())?;
        state
            .check_resumes(plant_bytes, self.request())
            .map_err(|e| anyhow::anyhow!("--resume {}: {e}", path.display()))?;
        Ok(state.scored)
    }
}

/// Runs `tune`.
pub fn run(a: TuneArgs) -> anyhow::Result<()> {
    let file = PlantFile::load(&a.plant)?;
    let plant_bytes =
        std::fs::read(&a.plant).with_context(|| format!("cannot read {}", a.plant.display()))?;
    let (joint, coils) = match file.params()? {
        PlantParams::TwoD(_) => (JointKind::TwoD, 2),
        PlantParams::ThreeD(_) => (JointKind::ThreeD, 4),
    };
    let done = a.resumed(&plant_bytes)?;
    let current = a
        .current
        .as_ref()
        .map(|path| current_gains(path, joint))
        .transpose()?;
    // The gains file and the state file can be written: checked before
    // the search, not after it.
    output::check_file(&a.output)?;
    output::check_file(&a.state_path())?;
    let stop = Stop::on_signals()?;
    let go = || tune::tune(&file, a.request(), !a.json, &stop, &done);
    let started = std::time::Instant::now();
    let outcome = match (&a.ray, a.threads) {
        (Some(address), _) => on_ray(&a, &file, address, &stop),
        (None, Some(n)) => rayon::ThreadPoolBuilder::new()
            .num_threads(n as usize)
            .build()
            .context("worker threads")?
            .install(go),
        (None, None) => go(),
    }
    .map_err(|e| e.context(format!("tuning on {}", a.plant.display())))?;
    let r = match outcome {
        tune::TuneOutcome::Done(r) => r,
        tune::TuneOutcome::Stopped(signal, scored) => {
            let state = tune::SearchState::new(
                &a.plant.display().to_string(),
                &plant_bytes,
                a.request(),
                coils,
                scored,
            );
            return Err(stopped(&a, signal, &state));
        }
    };
    let wall = started.elapsed().as_secs_f64();
    let g = r.gains_file(&a.plant.display().to_string(), joint, a.request());
    let proven = r.heldout.beats_or_ties_paper;
    let verdict = heldout_verdict(&r.heldout, a.plants);
    let current = match &current {
        Some(g) => Some(
            tune::heldout_scores(&file, &[&g.controller], a.plants as usize, a.seed)
                .context("the current gains on the held-out manoeuvres")?
                .into_iter()
                .map(|(m, mut s)| (m, s.remove(0)))
                .collect::<Vec<_>>(),
        ),
        None => None,
    };
    let against_current = current.as_ref().map(|c| against_current(&r.heldout, c));
    if !proven && !a.allow_unproven {
        anyhow::bail!("{verdict}; no gains written (--allow-unproven writes them all the same)");
    }
    output::write_toml(&a.output, host_tools::files::gains::GAINS_HEADER, &g)?;
    if a.json {
        output::JsonObject::new()
            .field("gains", &g)?
            .field("failed_candidates", &r.failed)?
            .field("rejected_early", &r.rejected)?
            .field("wall_seconds", &wall)?
            .field("heldout_beats_or_ties_paper", &proven)?
            .field(
                "heldout_current",
                &against_current.as_ref().map(|(rows, _)| rows),
            )?
            .print()?;
    } else {
        let c = &r.best;
        host_tools::outln!(
            "best of {} candidates × {} plants ({:.1} s): K_P {:?} V/°, K_I {:.3} V/(°·s), limit {:.2} V, v_offset {:.3} V",
            a.candidates,
            a.plants,
            wall,
            c.kp_v_per_deg.iter().map(|k| (k * 1000.0).round() / 1000.0).collect::<Vec<_>>(),
            c.ki_v_per_deg_s,
            c.integral_limit_v,
            c.v_offset_v
        );
        for (name, s) in [("tuned", &r.score), ("paper", &r.paper)] {
            let n = &s.nominal;
            host_tools::outln!(
                "{name:>6}: robust cost {:.3} (mean {:.3} + sd {:.3}); identified plant: settling {:.2} s, overshoot {:.2}°, ss error {:.3}°, peak coil {:.1} °C, budget margin {:.1} K, fault {}",
                s.robust, s.mean, s.std, n.settling_s, n.overshoot_deg, n.steady_state_error_deg, n.peak_coil_c, n.budget_margin_k, n.fault
            );
        }
        if r.rejected > 0 {
            host_tools::outln!(
                "{} candidate(s) rejected early: their first plants' runs already cost more than the paper's gains' robust cost",
                r.rejected
            );
        }
        if r.failed > 0 {
            host_tools::outln!(
                "{} candidate(s) made a plant unstable and were dropped",
                r.failed
            );
        }
        host_tools::outln!("{verdict}");
        if let (Some(path), Some((_, line))) = (&a.current, &against_current) {
            host_tools::outln!("current gains ({}) {line}", path.display());
        }
        host_tools::outln!("gains written to {}", a.output.display());
    }
    Ok(())
}

/// The search's units run on the Ray cluster at `address` by the Python
/// package's driver, which writes the scored candidates to a file beside
/// the gains file; reduced here. A signal stops the driver too (it
/// cancels the cluster's tasks and writes the candidates of the units
/// that had finished): those are the stopped search's, kept in its state
/// file like a search on this machine's (`--resume` goes on from it
/// without `--ray`).
fn on_ray(
    a: &TuneArgs,
    file: &PlantFile,
    address: &str,
    stop: &Stop,
) -> anyhow::Result<tune::TuneOutcome> {
    let units = a.output.with_extension("ray-units.toml");
    output::check_file(&units)?;
    let python = std::env::var_os("SOFTJOINT_PYTHON").unwrap_or_else(|| "python3".into());
    let mut cmd = std::process::Command::new(&python);
    cmd.args(["-m", "softjoint.ray_sweep", "tune"])
        .arg(&a.plant)
        .args(["--candidates", &a.candidates.to_string()])
        .args(["--plants", &a.plants.to_string()])
        .args(["--seed", &a.seed.to_string()])
        .args(["--address", address, "--units-out"])
        .arg(&units)
        .stdout(std::process::Stdio::null());
    if a.search_v_offset {
        cmd.arg("--search-v-offset");
    }
    let who = format!("{} -m softjoint.ray_sweep", python.to_string_lossy());
    // The driver dies with this program and is out of the terminal's
    // process group: a signal to this program reaches it as SIGINT, sent
    // from here (`kill -TERM` on this program alone reached no driver,
    // which ran its whole sweep while this program waited).
    host_tools::stop::die_with_parent(&mut cmd);
    let mut child = cmd.spawn().with_context(|| {
        format!("cannot run {who} (the Python package, python/README.md, and ray installed?)")
    })?;
    let mut told = false;
    let status = loop {
        if let Some(status) = child
            .try_wait()
            .with_context(|| format!("waiting for {who}"))?
        {
            break status;
        }
        if !told && stop.requested().is_some() {
            told = true;
            host_tools::stop::interrupt(&child);
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let read = std::fs::read_to_string(&units);
    let _ = std::fs::remove_file(&units);
    let read_units = |text: &str| -> anyhow::Result<tune::ScoredFile> {
        host_tools::input::from_toml(text, &units.display().to_string())
    };
    let scored = |text: &str| -> anyhow::Result<Vec<tune::Scored>> { Ok(read_units(text)?.scored) };
    if let Some(signal) = stop.requested() {
        // The units finished before the stop, if the driver got to write
        // them.
        let kept = match &read {
            Ok(text) => scored(text)?,
            Err(_) => Vec::new(),
        };
        return Ok(tune::TuneOutcome::Stopped(signal, kept));
    }
    if !status.success() {
        bail!("the sweep on Ray at {address} failed: {who} exited with {status} (its message is above)");
    }
    let text = read.with_context(|| format!("{who} wrote no {}", units.display()))?;
    let sweep = tune::TuneSweep::new(file, a.request())?;
    // The held-out check's units too, where the driver ran them.
    let done = read_units(&text)?;
    let heldout = (!done.heldout.is_empty()).then_some(&done.heldout[..]);
    Ok(tune::TuneOutcome::Done(Box::new(
        sweep.reduce_with(&done.scored, heldout)?,
    )))
}

/// Writes a stopped search's state and says what it kept, as the error
/// the program exits with (130, 143, 129); no gains file is written (the
/// search did not finish).
fn stopped(a: &TuneArgs, signal: StopSignal, state: &tune::SearchState) -> anyhow::Error {
    let path = a.state_path();
    if let Err(e) = output::write_toml(&path, tune::STATE_HEADER, state) {
        return e.context(format!(
            "stopped by {}; the search state was lost",
            signal.name()
        ));
    }
    let best = match &state.best {
        Some(b) => format!(
            "best so far: candidate {} (robust cost {:.3}, K_P {:?} V/°, K_I {:.3} V/(°·s))",
            b.index,
            b.robust_cost,
            b.gains
                .kp_v_per_deg
                .iter()
                .map(|k| (k * 1000.0).round() / 1000.0)
                .collect::<Vec<_>>(),
            b.gains.ki_v_per_deg_s
        ),
        None => "none scored yet".into(),
    };
    Stopped {
        signal,
        what: format!(
            "{} of {} candidates scored, {best}; search state in {} (`softjoint tune {} --resume {}` goes on from there); {} not written",
            state.scored.len(),
            a.candidates,
            path.display(),
            a.plant.display(),
            path.display(),
            a.output.display()
        ),
    }
    .into()
}

/// What the held-out check found, manoeuvre by manoeuvre, and its verdict.
fn heldout_verdict(h: &host_tools::files::gains::HeldOut, plants: u64) -> String {
    let steps_ok = h.score.robust <= h.paper.robust * (1.0 + tune::HELDOUT_TIE);
    let mut parts = vec![format!(
        "steps {:?}: tuned {:.3}, paper {:.3}{}",
        tune::HELDOUT_STEPS.map(|s| s.1),
        h.score.robust,
        h.paper.robust,
        if steps_ok { "" } else { " (LOST)" }
    )];
    for m in &h.manoeuvres {
        parts.push(format!(
            "{}: tuned {:.3}, paper {:.3}{}",
            m.name,
            m.tuned.robust,
            m.paper.robust,
            if m.beats_or_ties_paper { "" } else { " (LOST)" }
        ));
    }
    format!(
        "held-out manoeuvres on {plants} plants drawn anew (robust cost) — {}: {}",
        parts.join("; "),
        if h.beats_or_ties_paper {
            "the tuned gains beat or tie the paper's on every one"
        } else {
            "the tuned gains LOSE to the paper's: NOT RECOMMENDED"
        }
    )
}

/// The gains file `--current` names, for a joint of kind `joint`.
fn current_gains(path: &std::path::Path, joint: JointKind) -> anyhow::Result<GainsFile> {
    let g = GainsFile::load(path).with_context(|| format!("--current {}", path.display()))?;
    if g.joint != joint {
        bail!(
            "--current {}: gains for a {} joint, but the plant file is a {} joint's",
            path.display(),
            kind(g.joint),
            kind(joint)
        );
    }
    Ok(g)
}

fn kind(j: JointKind) -> &'static str {
    match j {
        JointKind::TwoD => "2d",
        JointKind::ThreeD => "3d",
    }
}

/// One held-out manoeuvre's comparison of the tuned gains with the current
/// ones (`--json`'s `heldout_current`).
#[derive(serde::Serialize)]
struct AgainstCurrent {
    manoeuvre: &'static str,
    current_robust: f64,
    tuned_robust: f64,
    tuned_beats_or_ties_current: bool,
}

/// The current gains' held-out scores beside the tuned gains': the rows
/// and the line the text output prints.
fn against_current(
    h: &host_tools::files::gains::HeldOut,
    current: &[(tune::Manoeuvre, host_tools::files::gains::Score)],
) -> (Vec<AgainstCurrent>, String) {
    let rows: Vec<AgainstCurrent> = current
        .iter()
        .map(|(m, c)| {
            let tuned = if *m == tune::Manoeuvre::Steps {
                &h.score
            } else {
                h.manoeuvres
                    .iter()
                    .find(|s| s.name == m.name())
                    .map_or(&h.score, |s| &s.tuned)
            };
            AgainstCurrent {
                manoeuvre: m.name(),
                current_robust: c.robust,
                tuned_robust: tuned.robust,
                tuned_beats_or_ties_current: tuned.robust <= c.robust * (1.0 + tune::HELDOUT_TIE),
            }
        })
        .collect();
    let lost: Vec<&str> = rows
        .iter()
        .filter(|r| !r.tuned_beats_or_ties_current)
        .map(|r| r.manoeuvre)
        .collect();
    let line = format!(
        "on the held-out manoeuvres (robust cost) — {}: {}",
        rows.iter()
            .map(|r| format!(
                "{}: current {:.3}, tuned {:.3}",
                r.manoeuvre, r.current_robust, r.tuned_robust
            ))
            .collect::<Vec<_>>()
            .join("; "),
        if lost.is_empty() {
            "the tuned gains beat or tie them on every one".to_string()
        } else {
            format!("the tuned gains lose to them on {}", lost.join(", "))
        }
    );
    (rows, line)
}
