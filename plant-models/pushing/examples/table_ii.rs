//! Table II of the seed with its protocol (§VIII-B, `pushing::table_ii`):
//! for each integration scheme, 24 training sessions — 3 sets of
//! preservation terms × plasticity on/off × collision resolution on/off ×
//! geometric repair on/off — each an Algorithm 5 calibration (Table III
//! settings) under that scheme on the same training push, with the same
//! seed per session for every scheme. Reported like the seed: mean ±
//! standard deviation over the sessions of the best model, the worst and
//! the average of the final generation; plus, because an undeformed block
//! already scores μ(F) ≈ 0.96 on these videos, the best model's skill
//! (μ − μ_still)/(1 − μ_still) and its mean F over the push (frames 0–49)
//! and retrieval (50–99) phases.
//!
//! ```sh
//! cargo run --release -p plant-pushing --example table_ii -- \
//!     [--cell-px 2] [--generations 30] [--sessions 24] [--schemes customised,euler,verlet]
//! ```
//!
//! Tens of minutes of CPU with the defaults (the README's table).
//! `--cell-px` is the raster cell (px); `--sessions n` runs only the first
//! n of the 24; `--schemes` lists the integrators, the first compared with
//! the others (e.g. `customised-seq,euler,verlet` for the spring-by-spring
//! reading). `--sessions 1 --generations 2` is a short run of the protocol.
use plant_pushing::evaluate::{score_run, score_with_measured_forces, EvalSetup, PreparedVideo};
use plant_pushing::evolution::{calibrate, EvolutionSettings, TABLE_III_RANGES};
use plant_pushing::forces::MaterialParams;
use plant_pushing::reference::{record_push, ReferenceConfig, ReferenceMaterial};
use plant_pushing::scenario::{PushScenario, PushSite};
use plant_pushing::sim::{DrivingMode, Integrator, SimConfig};
use plant_pushing::table_ii::{skill, Session};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn mean_sd(v: &[f64]) -> (f64, f64) {
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (
        m,
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt(),
    )
}

/// The command line: `--name value` pairs.
struct Options {
    cell_px: f64,
    generations: usize,
    sessions: usize,
    schemes: Vec<Integrator>,
}

impl Options {
    fn parse() -> Result<Options> {
        let mut o = Options {
            cell_px: 2.0,
            generations: 30,
            sessions: 24,
            schemes: Integrator::ALL.to_vec(),
        };
        let args: Vec<String> = std::env::args().skip(1).collect();
        for pair in args.chunks(2) {
            let (flag, value) = match pair {
                [f, v] => (f.as_str(), v.as_str()),
                [f] => return Err(format!("{f} needs a value").into()),
                _ => unreachable!("chunks of two"),
            };
            let bad = |what: &str| format!("{flag} must be {what}, got `{value}`");
            match flag {
                "--cell-px" => o.cell_px = value.parse().map_err(|_| bad("a number of px"))?,
                "--generations" => {
                    o.generations = value.parse().map_err(|_| bad("a whole number"))?
                }
                "--sessions" => o.sessions = value.parse().map_err(|_| bad("a whole number"))?,
                "--schemes" => {
                    o.schemes = value
                        .split(',')
                        .map(|n| {
                            Integrator::from_name(n.trim())
                                .ok_or_else(|| format!("--schemes: unknown scheme `{n}`"))
                        })
                        .collect::<std::result::Result<_, _>>()?
                }
                other => {
                    return Err(
                        format!("unknown flag {other} (see the example's doc comment)").into(),
                    )
                }
            }
        }
        Ok(o)
    }
}

#[derive(Default)]
struct Column {
    best: Vec<f64>,
    worst: Vec<f64>,
    average: Vec<f64>,
    skill: Vec<f64>,
    push: Vec<f64>,
    retrieval: Vec<f64>,
}

/// The undeformed block's μ(F), and the seed's Fig. 14 and 15 parameters
/// scored under each scheme.
fn print_baselines(label: &str, pv: &PreparedVideo, schemes: &[Integrator]) -> Result<f64> {
    let still_cfg = SimConfig {
        mode: DrivingMode::ForcesOnVertices,
        ..SimConfig::default()
    };
    let still = score_run(
        pv,
        &vec![0.0; pv.frame_count()],
        &MaterialParams::SEED_FIG14_SPONGE,
        &still_cfg,
    )?
    .mean_f;
    println!("{label}: undeformed block μ(F) = {still:.4}");
    // The parameters the seed prints under Fig. 14 and 15 (found with
    // its customised scheme on its own videos), on this video.
    for (fig, p) in [
        ("Fig. 14", MaterialParams::SEED_FIG14_SPONGE),
        ("Fig. 15", MaterialParams::SEED_FIG15_PLASTICINE),
    ] {
        let mut line = format!("{label}: seed {fig} parameters μ(F)");
        for &integ in schemes {
            let cfg = SimConfig {
                integrator: integ,
                ..SimConfig::default()
            };
            let r = score_with_measured_forces(pv, &p, &cfg)?;
            line += &format!("  {} {:.4}", integ.name(), r.mean_f);
        }
        println!("{line}");
    }
    Ok(still)
}

/// Runs every session under every scheme; one column per scheme.
fn run_sessions(
    label: &str,
    pv: &PreparedVideo,
    n_push: usize,
    still: f64,
    sessions: &[Session],
    o: &Options,
) -> Result<Vec<Column>> {
    let mut cols: Vec<Column> = o.schemes.iter().map(|_| Column::default()).collect();
    for (s_idx, session) in sessions.iter().enumerate() {
        let mut line = format!("{label:>10} {:<28}", session.label());
        for (c, &integ) in o.schemes.iter().enumerate() {
            let cfg = session.sim_config(integ);
            let mut st = EvolutionSettings::table_iii(1 + s_idx as u64);
            st.generations = o.generations;
            let r = calibrate(
                &st,
                &TABLE_III_RANGES,
                |p| {
                    score_with_measured_forces(pv, &session.mask(p), &cfg)
                        .map(|s| s.mean_f)
                        .unwrap_or(f64::NAN)
                },
                |_| {},
            )?;
            let last = r.history.last().ok_or("a calibration with no generation")?;
            let best = score_with_measured_forces(pv, &session.mask(&r.best_params), &cfg)?;
            if best.mean_f != r.best_score {
                return Err(format!(
                    "{label} {}: the calibration's best μ(F) {} does not reproduce ({})",
                    session.label(),
                    r.best_score,
                    best.mean_f
                )
                .into());
            }
            let col = &mut cols[c];
            col.best.push(r.best_score);
            col.worst.push(last.worst.max(0.0));
            col.average.push(last.mean);
            col.skill.push(skill(r.best_score, still));
            col.push.push(mean_sd(&best.f_per_frame[..n_push]).0);
            col.retrieval.push(mean_sd(&best.f_per_frame[n_push..]).0);
            line += &format!(
                "  {} {:.4} ({:.4}/{:.4})",
                integ.name(),
                r.best_score,
                mean_sd(&best.f_per_frame[..n_push]).0,
                mean_sd(&best.f_per_frame[n_push..]).0
            );
        }
        println!("{line}");
    }
    Ok(cols)
}

/// The table: mean ± sd per scheme, then the first scheme's wins, overall
/// and split by the collision switch.
fn print_table(label: &str, cols: &[Column], sessions: &[Session], schemes: &[Integrator]) {
    println!("{label:>10} {:>10}  best             worst          average          skill of best    F push   F retrieval", "scheme");
    for (c, &integ) in schemes.iter().enumerate() {
        let col = &cols[c];
        let (b, w, a, k) = (
            mean_sd(&col.best),
            mean_sd(&col.worst),
            mean_sd(&col.average),
            mean_sd(&col.skill),
        );
        println!(
            "{label:>10} {:>10}  {:.4} ± {:.4}  {:.3} ± {:.3}  {:.4} ± {:.4}  {:.3} ± {:.3}  {:.4}   {:.4}",
            integ.name(),
            b.0,
            b.1,
            w.0,
            w.1,
            a.0,
            a.1,
            k.0,
            k.1,
            mean_sd(&col.push).0,
            mean_sd(&col.retrieval).0
        );
    }
    // Per other scheme: sessions among those selected by `keep` where
    // the first scheme's best beats that scheme's.
    let wins = |keep: &dyn Fn(&Session) -> bool| {
        let n = (0..sessions.len()).filter(|&k| keep(&sessions[k])).count();
        (1..schemes.len())
            .map(|j| {
                let w = (0..sessions.len())
                    .filter(|&k| keep(&sessions[k]) && cols[0].best[k] > cols[j].best[k])
                    .count();
                format!("vs {} {w}/{n}", schemes[j].name())
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    if schemes.len() > 1 {
        println!(
            "{label:>10} sessions where {}'s best is higher: {}",
            schemes[0].name(),
            wins(&|_| true)
        );
    }
    // The same split by the collision switch (forces-only sessions
    // drive the mesh through the sensed force alone, §VI-F mode 2).
    for collisions in [true, false] {
        let keep = |s: &Session| s.collisions == collisions;
        let idx: Vec<usize> = (0..sessions.len())
            .filter(|&k| keep(&sessions[k]))
            .collect();
        if idx.is_empty() {
            continue;
        }
        let mut line = format!(
            "{label:>10} {:<16}",
            if collisions {
                "with collisions"
            } else {
                "forces only"
            }
        );
        for (c, &integ) in schemes.iter().enumerate() {
            let pick = |v: &[f64]| idx.iter().map(|&k| v[k]).collect::<Vec<f64>>();
            let b = mean_sd(&pick(&cols[c].best));
            line += &format!(
                "  {} {:.4} ± {:.4} ({:.4}/{:.4})",
                integ.name(),
                b.0,
                b.1,
                mean_sd(&pick(&cols[c].push)).0,
                mean_sd(&pick(&cols[c].retrieval)).0
            );
        }
        if schemes.len() > 1 {
            line += &format!("  {} wins {}", schemes[0].name(), wins(&keep));
        }
        println!("{line}");
    }
}

fn run() -> Result<()> {
    let o = Options::parse()?;
    let sessions: Vec<Session> = Session::all().into_iter().take(o.sessions).collect();
    // Per session: best μ(F) of each scheme and, in brackets, its mean F
    // over the push / retrieval frames.
    let setup = EvalSetup {
        nx: 20,
        ny: 10,
        cell_px: o.cell_px,
    };
    println!(
        "Table II protocol: {} sessions per scheme, 20×10 mesh, {} px cells, Table III search ({} generations)",
        sessions.len(),
        o.cell_px,
        o.generations
    );
    for (label, mat) in [
        ("sponge", ReferenceMaterial::SPONGE),
        ("plasticine", ReferenceMaterial::PLASTICINE),
    ] {
        let sc = PushScenario::seed(PushSite::MiddleLongSide, mat.scale_px_per_m)?;
        let pv = PreparedVideo::new(
            record_push(label, mat, &sc, &ReferenceConfig::default())?,
            &setup,
        )?;
        let still = print_baselines(label, &pv, &o.schemes)?;
        let cols = run_sessions(label, &pv, sc.frames_push, still, &sessions, &o)?;
        print_table(label, &cols, &sessions, &o.schemes);
    }
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("table_ii: {e}");
            std::process::ExitCode::from(2)
        }
    }
}
