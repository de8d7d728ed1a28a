//! A lockstep run whose board goes away mid-run ends there with the
//! failure named — the board restarted, stopped answering, or its line
//! closed — at the step and time it happened, and with every row up to
//! that step kept (`hil::run_into` with the pty board).
use std::time::Duration;

use host_tools::board::hil::{self, HilOptions};
use host_tools::board::link::Link;
use host_tools::files::scenario::{EstimatorMethod, Scenario};
use host_tools::run::record::Row;
use host_tools::run::sim::RunContext;
use host_tools::run::spec::RunSpec;
use host_tools::run::summary::CutCause;
use host_tools::stop::Stop;
use integration_tests::PtyBoard;

/// What happens to the board a moment into the run.
enum Mishap {
    Reset,
    Silence,
    Unplugged,
}

fn run_until(mishap: Mishap) -> (String, u64, Vec<Row>) {
    let (board, port) = PtyBoard::start().expect("pty pair");
    let (faults, state) = (board.faults.clone(), board.state.clone());
    let mut link = Link::new(port);
    let mut s = Scenario {
        duration_s: 60.0,
        ..Scenario::default()
    };
    s.estimator.method = EstimatorMethod::Paper;
    let opts = HilOptions {
        timeout: Duration::from_millis(30),
        attempts: 5,
        link_timeout_ms: Some(5000),
        ..HilOptions::default()
    };
    // A moment into the lockstep (the board has received frames for a
    // while), the mishap.
    let trigger = std::thread::spawn(move || {
        let mut board = Some(board);
        loop {
            std::thread::sleep(Duration::from_millis(20));
            if state.lock().unwrap().last_rx_ms.is_some_and(|t| t > 400) {
                break;
            }
        }
        match mishap {
            Mishap::Reset => faults.lock().unwrap().reset = true,
            Mishap::Silence => faults.lock().unwrap().drop_replies = u32::MAX,
            Mishap::Unplugged => drop(board.take()),
        }
        board
    });
    let mut rows = Vec::new();
    let report = hil::run_into(
        &RunSpec::resolve(&s).unwrap(),
        &mut link,
        opts,
        &mut rows,
        &RunContext {
            stop: &Stop::never(),
            progress: &host_tools::progress::hidden(),
        },
    )
    .expect("the run starts");
    let _board = trigger.join().unwrap();
    let cut = report.summary.cut_short.expect("the run was cut short");
    assert_eq!(cut.cause, CutCause::Controller);
    assert_eq!(report.summary.steps, cut.at_step);
    assert!((cut.at_t_s - cut.at_step as f64 * 1e-3).abs() < 1e-9);
    assert!(cut.at_step > 10 && cut.at_step < 60_000, "{cut:?}");
    (cut.to_string(), cut.at_step, rows)
}

#[test]
fn a_board_reset_mid_run_is_named_as_a_restart() {
    let (msg, step, rows) = run_until(Mishap::Reset);
    assert!(msg.contains("the board restarted"), "{msg}");
    assert!(msg.contains(&format!("at step {step}")), "{msg}");
    assert_eq!(rows.len() as u64, step);
}

#[test]
fn a_board_that_stops_answering_is_named_with_its_retries() {
    let (msg, step, rows) = run_until(Mishap::Silence);
    assert!(
        msg.contains("the board stopped answering") && msg.contains("after 5 attempts of 30 ms"),
        "{msg}"
    );
    assert_eq!(rows.len() as u64, step);
}

#[test]
fn a_line_that_closes_is_named_not_a_broken_pipe() {
    let (msg, step, rows) = run_until(Mishap::Unplugged);
    assert!(msg.contains("the serial line closed"), "{msg}");
    assert!(!msg.contains("Broken pipe"), "{msg}");
    assert_eq!(rows.len() as u64, step);
}
