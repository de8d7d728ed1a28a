//! A sweep's driver on a Ray cluster, as the program talks to it: a
//! Python process (`python3 -m softjoint.ray_sweep KIND-serve …`, from
//! the Python package) that scores the batches of candidates a search
//! sends it on the cluster. `rheology calibrate --ray` and `push
//! calibrate --ray` use it; the search, its draws and selection, its
//! progress bar, the scores kept for a stop and every file stay in the
//! program, so a calibration on Ray writes the files of the same
//! calibration without `--ray`.
//!
//! The protocol, one line each way over the driver's standard input and
//! output: the program writes a batch as a JSON array of gene arrays;
//! the driver answers with a JSON array of as many scores, in order,
//! `null` for one that is not finite. What `null` reads back as is the
//! caller's: the score its search gives any non-finite one, +∞ for a
//! search that minimises (rheology's S), NaN for one that maximises and
//! ranks NaN last (push's μ(F)); see [`Driver::start`]. The end of its
//! input ends the driver. The scores are parsed here number by number
//! with Rust's correctly rounded `f64` parser (serde_json's default float
//! parsing may be one unit in the last place off, which would change the
//! search).
//!
//! A driver that exits or answers anything else ends the search with an
//! error naming it and quoting what it said on standard error (the last
//! [`SAID_KEPT`] bytes). A stop (Ctrl-C, SIGTERM, SIGHUP) is sent on to
//! the driver as SIGINT (it stops submitting the batch's tasks and exits
//! 130) and ends the search at once: the batch in flight is lost.
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::Context;
use plant_joint::identify::{IdentifyError, StartFit, StartFits, StartUnit};

use crate::stop::Stop;

/// What the driver said on standard error that an error quotes: its last
/// this many bytes.
pub const SAID_KEPT: usize = 4000;

/// The longest answer line read (a batch's scores are a few kB).
const LINE_LIMIT: u64 = 16 << 20;

/// What [`Driver::answer`] says when a stop ended the wait.
pub const STOPPED: &str = "stopped by a signal";

/// How long a driver that closed its output or input is given to exit
/// (its exit status and last words are in its error).
const DYING: Duration = Duration::from_secs(2);

/// How long a driver whose input was closed, or that was sent SIGINT, is
/// given to exit before it is killed.
const EXIT_GRACE: Duration = Duration::from_secs(10);

/// The driver `python3 -m softjoint.ray_sweep SERVE --address ADDRESS`
/// ($SOFTJOINT_PYTHON names another Python), the problem's arguments
/// still to add, and its name in errors.
pub fn serve_command(serve: &str, address: &str) -> (Command, String) {
    let python = std::env::var_os("SOFTJOINT_PYTHON").unwrap_or_else(|| "python3".into());
    let mut cmd = Command::new(&python);
    cmd.args(["-m", "softjoint.ray_sweep", serve, "--address", address]);
    let who = format!(
        "the Ray driver ({} -m softjoint.ray_sweep {serve}, cluster at {address})",
        python.to_string_lossy(),
    );
    (cmd, who)
}

/// A running driver: its input, its answer lines (read by a thread, so
/// that a stop is seen while an answer is awaited) and what it said on
/// standard error.
pub struct Driver {
    who: String,
    child: Child,
    input: Option<ChildStdin>,
    lines: Receiver<std::io::Result<String>>,
    said: Arc<Mutex<Vec<u8>>>,
    /// Disconnected when the driver's standard error is closed (all it
    /// said is in `said`).
    said_all: Receiver<()>,
    stop: Stop,
    /// What an answer's `null` reads as.
    null_as: f64,
}

impl Driver {
    /// Starts `cmd` (named `who` in errors), which dies with this program
    /// and is out of the terminal's process group: a signal reaches it
    /// from here. An answer's `null` (a score that is not finite) reads
    /// as `null_as`: the search's worst value (+∞ when it minimises; NaN,
    /// ranked last, when it maximises).
    pub fn start(mut cmd: Command, who: String, stop: Stop, null_as: f64) -> anyhow::Result<Self> {
        cmd.stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        crate::stop::die_with_parent(&mut cmd);
        let mut child = cmd.spawn().with_context(|| {
            format!("cannot run {who} (the Python package, python/README.md, and ray installed?)")
        })?;
        let (Some(input), Some(out), Some(mut err)) =
            (child.stdin.take(), child.stdout.take(), child.stderr.take())
        else {
            anyhow::bail!("{who}: its pipes were not opened");
        };
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            let mut out = BufReader::new(out);
            loop {
                let mut line = String::new();
                match (&mut out).take(LINE_LIMIT).read_line(&mut line) {
                    Ok(0) => break,
                    Ok(_) if !line.ends_with('\n') && line.len() as u64 >= LINE_LIMIT => {
                        let _ = tx.send(Err(std::io::Error::other(format!(
                            "an answer line longer than {LINE_LIMIT} bytes"
                        ))));
                        break;
                    }
                    Ok(_) => {
                        if tx.send(Ok(line)).is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        let _ = tx.send(Err(e));
                        break;
                    }
                }
            }
        });
        let said = Arc::new(Mutex::new(Vec::new()));
        let kept = Arc::clone(&said);
        let (done, said_all) = mpsc::channel::<()>();
        std::thread::spawn(move || {
            let _done = done;
            let mut buf = [0u8; 4096];
            while let Ok(n) = err.read(&mut buf) {
                if n == 0 {
                    break;
                }
                let mut k = kept.lock().unwrap_or_else(|e| e.into_inner());
                k.extend_from_slice(&buf[..n]);
                let over = k.len().saturating_sub(SAID_KEPT);
                k.drain(..over);
            }
        });
        Ok(Self {
            who,
            child,
            input: Some(input),
            lines,
            said,
            said_all,
            stop,
            null_as,
        })
    }

    /// The scores of `batch`, or why there are none: a stop, or a
    /// driver that ended or answered garbage (then it is ended too).
    pub fn scores(&mut self, batch: &[Vec<f64>]) -> Result<Vec<f64>, String> {
        let line = batch_line(batch).map_err(|why| self.failed(&why, DYING))?;
        let n = batch.len();
        let answer = self.answer(&line, &format!("a batch of {n}"))?;
        parse_scores(&answer, n, self.null_as)
            .map_err(|why| self.refused(&format!("a batch of {n} candidates"), &answer, &why))
    }

    /// Sends `line` (one line, `\n` ended) and returns the driver's answer
    /// line, or why there is none: a stop (`"stopped by a signal"`; the
    /// driver is sent SIGINT), or a driver that ended (then it is ended
    /// too). `what` names the request in errors.
    pub fn answer(&mut self, line: &str, what: &str) -> Result<String, String> {
        self.send(line, what)?;
        loop {
            if let Some(line) = self.poll(what, Duration::from_millis(20))? {
                return Ok(line);
            }
        }
    }

    /// Sends `line` (one line, `\n` ended); why not (the driver is ended
    /// then). `what` names the request in errors.
    pub fn send(&mut self, line: &str, what: &str) -> Result<(), String> {
        let sent = self
            .input
            .as_mut()
            .ok_or_else(|| "its input is closed".to_string())
            .and_then(|input| {
                input
                    .write_all(line.as_bytes())
                    .and_then(|()| input.flush())
                    .map_err(|e| format!("sending it {what}: {e}"))
            });
        sent.map_err(|why| self.failed(&why, DYING))
    }

    /// The driver's next answer line if one comes within `wait`; `None`
    /// if none did; an error on a stop (`"stopped by a signal"`, the
    /// driver sent SIGINT) or a driver that ended without answering
    /// `what` (then it is ended too).
    pub fn poll(&mut self, what: &str, wait: Duration) -> Result<Option<String>, String> {
        if self.stop.requested().is_some() {
            crate::stop::interrupt(&self.child);
            return Err(STOPPED.into());
        }
        match self.lines.recv_timeout(wait) {
            Ok(Ok(line)) => Ok(Some(line)),
            Ok(Err(e)) => Err(self.failed(&format!("reading its answer: {e}"), Duration::ZERO)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => {
                let why = format!("it ended without answering {what}");
                Err(self.failed(&why, DYING))
            }
        }
    }

    /// The error of a driver whose answer to `what` was `answer` and is
    /// refused for `why` (the driver is ended).
    pub fn refused(&mut self, what: &str, answer: &str, why: &str) -> String {
        self.failed(
            &format!(
                "it answered {what} with {:?}: {why}",
                clip(answer.trim_end(), 200)
            ),
            Duration::ZERO,
        )
    }

    /// The error of a failed driver: `why`, how it ended (it is killed if
    /// still running after `grace`) and what it said.
    fn failed(&mut self, why: &str, grace: Duration) -> String {
        let ended = match self.end(grace) {
            Some(status) => format!("{status}"),
            None => "killed".into(),
        };
        // What it said last may still be on its way from the pipe.
        let _ = self.said_all.recv_timeout(Duration::from_secs(1));
        let said = self.said.lock().unwrap_or_else(|e| e.into_inner());
        let said = String::from_utf8_lossy(&said);
        let said = said.trim();
        format!(
            "{}: {why} ({ended}); it said: {}",
            self.who,
            if said.is_empty() { "nothing" } else { said }
        )
    }

    /// Closes the driver's input and waits up to `grace` for it to exit;
    /// kills it then. Its exit status, unless it had to be killed.
    pub fn end(&mut self, grace: Duration) -> Option<std::process::ExitStatus> {
        self.input = None;
        let until = Instant::now() + grace;
        while Instant::now() < until {
            match self.child.try_wait() {
                Ok(Some(status)) => return Some(status),
                Ok(None) => std::thread::sleep(Duration::from_millis(20)),
                Err(_) => break,
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
        None
    }
}

impl Drop for Driver {
    /// The driver's input is closed (it ends its Ray job and exits), or,
    /// after a stop, it was sent SIGINT; either way it is waited for, at
    /// most [`EXIT_GRACE`].
    fn drop(&mut self) {
        self.end(EXIT_GRACE);
    }
}

/// The mechanics stage's starts of `identify joint --ray` run on the
/// cluster by the driver `identify-serve`. A request is one line, `{"id":
/// N, "units": [...]}` (the units, [`StartUnit`]: every number as its
/// bit pattern); its answer, when the units are fitted, `{"id": N,
/// "answers": [...]}` with as many `{"fit": StartFit}` or `{"error":
/// "message"}` in order. Requests overlap: the 3D joint's planes each
/// send theirs when they reach the stage, and each takes the answer that
/// carries its id, whichever plane reads it.
pub struct RayStartFits {
    state: Mutex<FitsState>,
}

struct FitsState {
    driver: Driver,
    /// Why the driver failed, once it has: every later request gets that
    /// error (the other plane would otherwise report only that the
    /// driver's input is closed).
    failed: Option<String>,
    next_id: u64,
    /// Requests sent and not answered yet.
    waiting: std::collections::HashSet<u64>,
    /// Answers read for another request than the reader's.
    answered: std::collections::HashMap<u64, Vec<StartAnswer>>,
}

impl RayStartFits {
    /// Fits run by `driver`.
    pub fn new(driver: Driver) -> Self {
        Self {
            state: Mutex::new(FitsState {
                driver,
                failed: None,
                next_id: 0,
                waiting: Default::default(),
                answered: Default::default(),
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, FitsState> {
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// One answer of `identify-serve`.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields, rename_all = "snake_case")]
enum StartAnswer {
    Fit(StartFit),
    Error(String),
}

/// An answer line of `identify-serve`.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct StartReply {
    id: u64,
    answers: Vec<StartAnswer>,
}

/// A request line of `identify-serve`.
#[derive(serde::Serialize)]
struct StartRequest<'a> {
    id: u64,
    units: &'a [StartUnit],
}

impl FitsState {
    /// The error of a failed request: kept for every later one.
    fn fail(&mut self, why: String) -> IdentifyError {
        if why == STOPPED {
            return IdentifyError::Stopped;
        }
        self.failed = Some(why.clone());
        IdentifyError::Remote(why)
    }
}

impl StartFits for RayStartFits {
    fn fit(&self, units: &[StartUnit]) -> Result<Vec<Result<StartFit, String>>, IdentifyError> {
        let what = format!("{} mechanics fits", units.len());
        let id = {
            let mut st = self.lock();
            if let Some(why) = &st.failed {
                return Err(IdentifyError::Remote(why.clone()));
            }
            let id = st.next_id;
            st.next_id += 1;
            let line = crate::output::json_line(
                "the fits sent to the Ray driver",
                &StartRequest { id, units },
            )
            .map_err(|e| IdentifyError::Remote(format!("{e:#}")))?
                + "\n";
            if let Err(why) = st.driver.send(&line, &what) {
                return Err(st.fail(why));
            }
            st.waiting.insert(id);
            id
        };
        // Read answer lines a short while at a time, so that the other
        // plane can send its request meanwhile; an answer for it is kept
        // for it.
        let answers = loop {
            let mut st = self.lock();
            if let Some(a) = st.answered.remove(&id) {
                break a;
            }
            if let Some(why) = &st.failed {
                return Err(IdentifyError::Remote(why.clone()));
            }
            let line = match st.driver.poll(&what, Duration::from_millis(20)) {
                Ok(Some(line)) => line,
                Ok(None) => continue,
                Err(why) => return Err(st.fail(why)),
            };
            let reply = serde_json::from_str::<StartReply>(&line)
                .map_err(|e| e.to_string())
                .and_then(|r| {
                    if st.waiting.remove(&r.id) {
                        Ok(r)
                    } else {
                        Err(format!("no request {} is waiting for it", r.id))
                    }
                });
            match reply {
                Ok(r) if r.id == id => break r.answers,
                Ok(r) => {
                    st.answered.insert(r.id, r.answers);
                }
                Err(why) => {
                    let why = st
                        .driver
                        .refused(&format!("a request ({what})"), &line, &why);
                    return Err(st.fail(why));
                }
            }
        };
        if answers.len() != units.len() {
            let mut st = self.lock();
            let why = format!(
                "the Ray driver answered {} fits for {} units",
                answers.len(),
                units.len()
            );
            st.driver.end(Duration::ZERO);
            return Err(st.fail(why));
        }
        Ok(answers
            .into_iter()
            .map(|a| match a {
                StartAnswer::Fit(f) => Ok(f),
                StartAnswer::Error(e) => Err(e),
            })
            .collect())
    }
}

/// A batch as the line sent: a JSON array of gene arrays, each gene the
/// shortest decimal that reads back as the same `f64` (Rust's `{:?}`:
/// `0.1`, `1e-7`, `2.0`), after `output`'s check that every gene is
/// finite (JSON has no word for the others).
fn batch_line(batch: &[Vec<f64>]) -> Result<String, String> {
    crate::output::check_value("the batch sent to the Ray driver", &batch)
        .map_err(|e| format!("{e:#}"))?;
    let genes = |g: &Vec<f64>| {
        let each: Vec<String> = g.iter().map(|x| format!("{x:?}")).collect();
        format!("[{}]", each.join(","))
    };
    let rows: Vec<String> = batch.iter().map(genes).collect();
    Ok(format!("[{}]\n", rows.join(",")))
}

/// `s` cut to at most `n` characters.
fn clip(s: &str, n: usize) -> String {
    match s.char_indices().nth(n) {
        Some((at, _)) => format!("{}…", &s[..at]),
        None => s.to_string(),
    }
}

/// The scores of an answer line: a JSON array of `n` numbers or `null`s
/// (read as `null_as`).
pub fn parse_scores(line: &str, n: usize, null_as: f64) -> Result<Vec<f64>, String> {
    let inner = line
        .trim()
        .strip_prefix('[')
        .and_then(|s| s.strip_suffix(']'))
        .ok_or("not a JSON array")?
        .trim();
    let scores = if inner.is_empty() {
        Vec::new()
    } else {
        inner
            .split(',')
            .map(|tok| match tok.trim() {
                "null" => Ok(null_as),
                t => match t.parse::<f64>() {
                    Ok(v)
                        if v.is_finite()
                            && t.starts_with(|c: char| c == '-' || c.is_ascii_digit()) =>
                    {
                        Ok(v)
                    }
                    _ => Err(format!("{t:?} is neither a finite number nor null")),
                },
            })
            .collect::<Result<Vec<f64>, String>>()?
    };
    if scores.len() != n {
        return Err(format!("{} scores for {n} candidates", scores.len()));
    }
    Ok(scores)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_parse_exactly_and_garbage_is_named() {
        let got = parse_scores("[0.1, null, 2.5e-3, 17]\n", 4, f64::INFINITY).unwrap();
        assert_eq!(got, [0.1, f64::INFINITY, 0.0025, 17.0]);
        // The shortest decimal of a double comes back as that double.
        let x = 0.300_000_000_000_000_04_f64;
        assert_eq!(
            parse_scores(&format!("[{x:?}]"), 1, f64::INFINITY).unwrap()[0].to_bits(),
            x.to_bits()
        );
        assert_eq!(
            parse_scores("[]", 0, f64::INFINITY).unwrap(),
            Vec::<f64>::new()
        );
        for (line, why) in [
            ("[1.0, 2.0]", "2 scores for 3 candidates"),
            ("{\"s\": 1}", "not a JSON array"),
            (
                "[1.0, NaN, 2.0]",
                "\"NaN\" is neither a finite number nor null",
            ),
            ("[1.0, inf, 2.0]", "\"inf\" is neither"),
            ("[1.0, 1e999, 2.0]", "\"1e999\" is neither"),
            ("[1.0, \"x\", 2.0]", "\"\\\"x\\\"\" is neither"),
            ("Traceback (most recent call last):", "not a JSON array"),
        ] {
            let e = parse_scores(line, 3, f64::INFINITY).unwrap_err();
            assert!(e.contains(why), "{line}: {e}");
        }
    }

    #[test]
    fn null_reads_as_the_callers_worst_value() {
        // Push maximises and ranks NaN last; rheology minimises (+∞).
        let got = parse_scores("[0.5, null]", 2, f64::NAN).unwrap();
        assert_eq!(got[0], 0.5);
        assert!(got[1].is_nan());
        let mut d = stand_in("read b; echo '[null, -2.5]'; read b", Stop::never());
        d.null_as = f64::NEG_INFINITY;
        assert_eq!(
            d.scores(&[vec![1.0], vec![2.0]]).unwrap(),
            [f64::NEG_INFINITY, -2.5]
        );
    }

    #[test]
    fn a_batch_is_one_line_of_exact_decimals_and_only_finite_genes_go() {
        let x = 0.300_000_000_000_000_04_f64;
        let line = batch_line(&[vec![x, 1e-7, 2.0], vec![-1.5e300]]).unwrap();
        assert_eq!(line, "[[0.30000000000000004,1e-7,2.0],[-1.5e300]]\n");
        assert_eq!(
            "0.30000000000000004".parse::<f64>().unwrap().to_bits(),
            x.to_bits()
        );
        let e = batch_line(&[vec![1.0, f64::NAN]]).unwrap_err();
        assert!(e.contains("the batch sent to the Ray driver"), "{e}");
    }

    /// A stand-in driver: `sh -c SCRIPT`.
    fn stand_in(script: &str, stop: Stop) -> Driver {
        let mut cmd = Command::new("sh");
        cmd.args(["-c", script]);
        Driver::start(cmd, "the stand-in driver".into(), stop, f64::INFINITY).unwrap()
    }

    #[test]
    fn a_driver_that_answers_garbage_or_dies_is_an_error_naming_it() {
        // One that answers, then garbage.
        let mut d = stand_in(
            "read b; echo '[1.5, null]'; read b; echo 'oops' >&2; echo 'not json'; read b",
            Stop::never(),
        );
        let batch = [vec![1.0, 2.0], vec![3.0, 4.0]];
        assert_eq!(d.scores(&batch).unwrap(), [1.5, f64::INFINITY]);
        let e = d.scores(&batch).unwrap_err();
        assert!(
            e.starts_with("the stand-in driver: it answered a batch of 2 candidates with \"not json\": not a JSON array (killed)")
                && e.ends_with("it said: oops"),
            "{e}"
        );
        // One that exits at once, saying why.
        let mut d = stand_in(
            "echo 'ConnectionError: no cluster' >&2; exit 1",
            Stop::never(),
        );
        let e = d.scores(&batch).unwrap_err();
        assert!(
            e.contains("the stand-in driver: ")
                && e.contains("exit status: 1")
                && e.ends_with("it said: ConnectionError: no cluster"),
            "{e}"
        );
    }

    fn unit(start: usize) -> StartUnit {
        StartUnit {
            plane: 0,
            start,
            base: vec![("coil.convection_w_m2_k".into(), 80.0f64.to_bits())],
            active: vec!["coil.convection_w_m2_k".into()],
            x0: vec![0.5f64.to_bits()],
            fit_fraction: 0.75f64.to_bits(),
            substep_s: 1e-3f64.to_bits(),
            angle_sigma_deg: 0.1f64.to_bits(),
            resistance_sigma_ohm: 0.02f64.to_bits(),
            max_iterations: 3,
            ftol: 1e-4f64.to_bits(),
            step: 1e-3f64.to_bits(),
            secant_updates: 2,
            derivative_jacobians: false,
        }
    }

    /// A fit's answer whose minimiser is `x` (cost 2).
    fn fit_answer(x: f64) -> String {
        format!(
            r#"{{"fit":{{"x":[{}],"cost":{},"iterations":2,"evaluations":5,"stopped_by_budget":false,"jacobian_known":true}}}}"#,
            x.to_bits(),
            2.0f64.to_bits()
        )
    }

    fn bash_stand_in(script: &str) -> RayStartFits {
        let mut cmd = Command::new("bash");
        cmd.args(["-c", script]);
        let d = Driver::start(cmd, "the stand-in driver".into(), Stop::never(), f64::NAN).unwrap();
        RayStartFits::new(d)
    }

    #[test]
    fn start_fits_come_back_in_order_and_a_failed_driver_is_named_to_every_plane() {
        // One request of two units answered (a fit, then a worker's
        // error), then garbage.
        let script = format!(
            "read r; echo '{{\"id\":0,\"answers\":[{},{{\"error\":\"replay unstable: angle is not finite\"}}]}}'; read r; echo 'oops' >&2; echo '[1]'; read r",
            fit_answer(0.5)
        );
        let fits = bash_stand_in(&script);
        let got = fits.fit(&[unit(0), unit(1)]).unwrap();
        let f = got[0].as_ref().unwrap();
        assert_eq!((f.x(), f64::from_bits(f.cost)), (vec![0.5], 2.0));
        assert_eq!(
            (f.iterations, f.evaluations, f.jacobian_known),
            (2, 5, true)
        );
        assert_eq!(
            got[1].as_ref().unwrap_err(),
            "replay unstable: angle is not finite"
        );
        let e = fits.fit(&[unit(0)]).unwrap_err().to_string();
        assert!(
            e.starts_with(
                "the stand-in driver: it answered a request (1 mechanics fits) with \"[1]\""
            ) && e.ends_with("it said: oops"),
            "{e}"
        );
        // The other plane's request gets the same error, not "its input is
        // closed".
        assert_eq!(fits.fit(&[unit(0)]).unwrap_err().to_string(), e);
        // An answer for no request waiting is refused.
        let script = format!(
            "read r; echo '{{\"id\":7,\"answers\":[{}]}}'; read r",
            fit_answer(0.5)
        );
        let e = bash_stand_in(&script)
            .fit(&[unit(0)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("no request 7 is waiting for it"), "{e}");
    }

    #[test]
    fn two_planes_requests_are_out_at_once_and_each_takes_its_own_answer() {
        // The stand-in answers only once both requests have come (a
        // program that sent one at a time would find it gone, saying
        // so), the second first.
        let script = format!(
            "read a; read -t 10 b || {{ echo 'only one request came' >&2; exit 1; }}; \
             echo '{{\"id\":1,\"answers\":[{}]}}'; echo '{{\"id\":0,\"answers\":[{}]}}'; read r",
            fit_answer(1.5),
            fit_answer(0.5)
        );
        let fits = bash_stand_in(&script);
        let (a, b) = std::thread::scope(|s| {
            let a = s.spawn(|| fits.fit(&[unit(0)]));
            let b = s.spawn(|| fits.fit(&[unit(0)]));
            (a.join().unwrap(), b.join().unwrap())
        });
        let mut xs: Vec<f64> = [a, b]
            .into_iter()
            .map(|r| r.unwrap()[0].as_ref().unwrap().x()[0])
            .collect();
        xs.sort_by(f64::total_cmp);
        // Each request got one of the two answers, neither twice.
        assert_eq!(xs, [0.5, 1.5]);
    }

    #[test]
    fn a_stop_while_a_batch_is_out_interrupts_the_driver() {
        let stop = Stop::never();
        let mut d = stand_in(
            "trap 'echo stopped >&2; exit 130' INT; read b; while :; do sleep 0.02; done",
            stop.clone(),
        );
        let s2 = stop.clone();
        let t = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            s2.request(crate::stop::StopSignal::Interrupt);
        });
        let started = Instant::now();
        assert_eq!(d.scores(&[vec![1.0]]), Err("stopped by a signal".into()));
        t.join().unwrap();
        let status = d.end(Duration::from_secs(5)).expect("the driver exits");
        assert_eq!(status.code(), Some(130));
        assert!(started.elapsed() < Duration::from_secs(5));
    }
}
