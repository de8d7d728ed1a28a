//! Where a run's time series goes while the run goes: streamed to a CSV
//! file in blocks of whole rows, and kept for the plot only as a bounded,
//! decimated copy. Memory therefore stays flat however long the run (the
//! summary is accumulated row by row, `sim::SummaryBuilder`), and a run
//! that ends early — a dead link, a QEMU that exited, an unstable plant, a
//! failed write, Ctrl-C — leaves its trace on disk up to its last step,
//! complete to the last row.
//!
//! The CSV is the one output that is not written atomically (it would have
//! to be kept whole until the end): rows reach the file in blocks of about
//! [`BLOCK_BYTES`] (and at least once a second), each block one `write`,
//! and a write that fails part-way is cut back to the last whole row. The
//! run's summary says how many rows the file holds and whether they are the
//! whole run.
//!
//! Not atomic, but checked like every result (`crate::output`): each value
//! of a row is checked finite before the row is formatted, and a row that
//! holds a non-finite value is refused (naming file, line and column) and
//! ends the run there; a missing angle estimate (NaN: the controller has
//! none yet) is an empty field.
use std::fmt::Write as _;
use std::fs::File;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::output::{check_number, estimate_field, AtomicFile, NonFinite};
use crate::plot::{line_charts, Chart, Series};
use crate::run::record::Row;

/// Where each row of a run goes.
pub trait RowSink {
    /// Takes one control period's row; an error ends the run early (the
    /// rows taken before stay).
    fn row(&mut self, row: &Row) -> anyhow::Result<()>;
}

/// Rows kept in memory (tests, library callers that want the series).
impl RowSink for Vec<Row> {
    fn row(&mut self, row: &Row) -> anyhow::Result<()> {
        self.push(*row);
        Ok(())
    }
}

/// Rows dropped (only the summary is wanted).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoRows;

impl RowSink for NoRows {
    fn row(&mut self, _row: &Row) -> anyhow::Result<()> {
        Ok(())
    }
}

/// Rows are written once this many bytes of text are waiting.
pub const BLOCK_BYTES: usize = 64 * 1024;
/// … or once this long has passed since the last write.
pub const BLOCK_INTERVAL: Duration = Duration::from_secs(1);

/// The CSV header for `angles` (2D: `theta`; 3D: `alpha`, `beta`).
pub fn csv_header(angles: &[String]) -> String {
    let mut s = String::from("t_s");
    for a in angles {
        let _ = write!(s, ",{a}_true_deg,{a}_estimate_deg,{a}_desired_deg");
    }
    for c in 1..=2 * angles.len() {
        let _ = write!(s, ",v{c}_V");
    }
    s.push_str(",faults\n");
    s
}

/// Appends one row as CSV text (the columns of [`csv_header`]), each value
/// checked first (`crate::output::check_number`): a non-finite value is
/// refused, naming `file`, the row's `line` and its column, and nothing of
/// the row is appended. A missing angle estimate (NaN: the controller has
/// none yet) is an empty field.
pub fn push_csv_row(
    s: &mut String,
    file: &Path,
    line: u64,
    angles: &[String],
    r: &Row,
) -> Result<(), NonFinite> {
    check_row(file, line, angles, r)?;
    let _ = write!(s, "{:.4}", r.t_s);
    for p in 0..angles.len() {
        let _ = write!(
            s,
            ",{:.4},{},{:.4}",
            r.true_deg[p],
            estimate_field(r.estimate_deg[p], 4),
            r.desired_deg[p]
        );
    }
    for v in r.coil_volts.iter().take(2 * angles.len()) {
        let _ = write!(s, ",{v:.3}");
    }
    let _ = writeln!(s, ",{}", r.faults);
    Ok(())
}

/// Checks every value of a row that goes into the columns of
/// [`csv_header`] (`crate::output::check_number`): a non-finite value is
/// refused, naming `file` (or whatever the row goes to), the row's `line`
/// and its column. A missing angle estimate (NaN: the controller has none
/// yet) is allowed. The CSV trace and the Python package's arrays hold
/// their rows to this one check.
pub fn check_row(file: &Path, line: u64, angles: &[String], r: &Row) -> Result<(), NonFinite> {
    let check = |column: &dyn Fn() -> String, v: f64| check_number(file, line, column, v);
    check(&|| "t_s".into(), r.t_s)?;
    for (p, a) in angles.iter().enumerate() {
        check(&|| format!("{a}_true_deg"), r.true_deg[p])?;
        if !r.estimate_deg[p].is_nan() {
            check(&|| format!("{a}_estimate_deg"), r.estimate_deg[p])?;
        }
        check(&|| format!("{a}_desired_deg"), r.desired_deg[p])?;
    }
    for (c, v) in r.coil_volts.iter().take(2 * angles.len()).enumerate() {
        check(&|| format!("v{}_V", c + 1), *v)?;
    }
    Ok(())
}

/// A CSV file written as its rows arrive: the header at once (so a path
/// that cannot be written is refused before any work), then blocks of
/// whole rows of about [`BLOCK_BYTES`] (and at least once a second), each
/// block one `write`; a write that fails part-way is cut back to the last
/// whole row. The run trace ([`CsvStream`]) and an excitation session's
/// log (`crate::joint::excite`) stream through it.
///
/// Two ways to the target: straight into it ([`RowFile::create`]: the
/// rows are at the path as the run goes, the `sim`/`hil` traces and
/// logs), or into [`AtomicFile`]'s temporary file beside it, renamed over
/// it by [`RowFile::finish`] ([`RowFile::create_atomic`]: the console's
/// board sessions, whose previous log stays as it was until a session has
/// rows to replace it with; dropped unfinished, the temporary file goes
/// and the target is untouched).
pub struct RowFile {
    path: PathBuf,
    out: RowOut,
    pending: String,
    pending_rows: u64,
    /// Bytes in the file, all of them whole rows (and the header).
    committed_bytes: u64,
    /// Rows in the file.
    committed_rows: u64,
    last_write: Instant,
}

/// Where a [`RowFile`]'s blocks go.
enum RowOut {
    /// The target itself.
    Direct(File),
    /// An atomic file's stream, kept (renamed over the target) at the end.
    Atomic(AtomicFile),
}

impl RowOut {
    fn file(&mut self) -> std::io::Result<&mut File> {
        match self {
            RowOut::Direct(f) => Ok(f),
            RowOut::Atomic(a) => a.streamed(),
        }
    }
}

impl RowFile {
    /// Creates (or truncates) `path` and writes `header` (a line).
    pub fn create(path: &Path, header: &str) -> anyhow::Result<Self> {
        if path.is_dir() {
            anyhow::bail!("cannot write {}: it is a directory", path.display());
        }
        let file = File::create(path)
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", path.display()))?;
        let mut s = Self::over(path, RowOut::Direct(file), header);
        s.write_block()?;
        Ok(s)
    }

    /// Opens `path` as an [`AtomicFile`] (refused by name here if it
    /// cannot be written) and streams `header` and the rows into its
    /// temporary file; [`finish`](Self::finish) renames it over `path`. A
    /// device is written through; a FIFO is opened at the first block.
    pub fn create_atomic(path: &Path, header: &str) -> anyhow::Result<Self> {
        let file = AtomicFile::create(path)?;
        Ok(Self::over(path, RowOut::Atomic(file), header))
    }

    fn over(path: &Path, out: RowOut, header: &str) -> Self {
        Self {
            path: path.to_path_buf(),
            out,
            pending: header.to_string(),
            pending_rows: 0,
            committed_bytes: 0,
            committed_rows: 0,
            last_write: Instant::now(),
        }
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The line number the next row gets (the header is line 1).
    pub fn next_line(&self) -> u64 {
        self.committed_rows + self.pending_rows + 2
    }

    /// Rows in the file so far (not counting those still waiting).
    pub fn rows_written(&self) -> u64 {
        self.committed_rows
    }

    /// Appends one row: `push` is given the waiting text, the file's path
    /// and the row's line number (for its messages), and appends the
    /// row's text (a line) or refuses it, appending nothing, with an error
    /// that ends the stream's run.
    #[inline]
    pub fn row<E: Into<anyhow::Error>>(
        &mut self,
        push: impl FnOnce(&mut String, &Path, u64) -> Result<(), E>,
    ) -> anyhow::Result<()> {
        let line = self.next_line();
        push(&mut self.pending, &self.path, line).map_err(Into::into)?;
        self.pending_rows += 1;
        if self.pending.len() >= BLOCK_BYTES
            || (self.pending_rows % 256 == 0 && self.last_write.elapsed() >= BLOCK_INTERVAL)
        {
            self.write_block()?;
        }
        Ok(())
    }

    /// Writes the waiting rows if the last write was at least
    /// [`BLOCK_INTERVAL`] ago (a slow stream reaches the file at least
    /// once a second however few rows it has).
    pub fn write_if_due(&mut self) -> anyhow::Result<()> {
        if self.last_write.elapsed() >= BLOCK_INTERVAL {
            self.write_block()?;
        }
        Ok(())
    }

    /// Writes the waiting rows as one block; a write that fails part-way
    /// is cut back to the last whole row.
    fn write_block(&mut self) -> anyhow::Result<()> {
        self.last_write = Instant::now();
        if self.pending.is_empty() {
            return Ok(());
        }
        let file = self
            .out
            .file()
            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", self.path.display()))?;
        if let Err(e) = file.write_all(self.pending.as_bytes()) {
            let _ = file.set_len(self.committed_bytes);
            anyhow::bail!(
                "cannot write {}: {e} (it holds the first {} rows)",
                self.path.display(),
                self.committed_rows
            );
        }
        self.committed_bytes += self.pending.len() as u64;
        self.committed_rows += self.pending_rows;
        self.pending.clear();
        self.pending_rows = 0;
        Ok(())
    }

    /// Writes what is waiting (an atomic file: and renames it over its
    /// target) and returns the rows in the file.
    pub fn finish(mut self) -> anyhow::Result<u64> {
        self.write_block()?;
        if let RowOut::Atomic(file) = self.out {
            file.keep_streamed()?;
        }
        Ok(self.committed_rows)
    }
}

/// A CSV trace written as the run goes.
pub struct CsvStream {
    rows: RowFile,
    angles: Vec<String>,
}

impl CsvStream {
    /// Creates (or truncates) `path` and writes the header for `angles`.
    pub fn create(path: &Path, angles: &[String]) -> anyhow::Result<Self> {
        Ok(Self {
            rows: RowFile::create(path, &csv_header(angles))?,
            angles: angles.to_vec(),
        })
    }

    /// Rows in the file so far (not counting those still waiting).
    pub fn rows_written(&self) -> u64 {
        self.rows.rows_written()
    }

    /// Writes what is waiting and returns the rows in the file.
    pub fn finish(self) -> anyhow::Result<u64> {
        self.rows.finish()
    }
}

impl RowSink for CsvStream {
    #[inline]
    fn row(&mut self, row: &Row) -> anyhow::Result<()> {
        let angles = &self.angles;
        self.rows
            .row(|s, path, line| push_csv_row(s, path, line, angles, row))
    }
}

/// A bounded copy of a series for a plot: every `stride`-th row, the
/// stride doubling (and every other kept row dropped) whenever more than
/// `2 × target` rows are kept. Memory is at most `2 × target` rows however
/// long the run; a plot needs no more.
#[derive(Clone, Debug)]
pub struct Decimated {
    target: usize,
    stride: u64,
    seen: u64,
    rows: Vec<Row>,
}

impl Decimated {
    /// Points per line a plot gets at most (about; between `target` and
    /// `2 × target`).
    pub const PLOT_POINTS: usize = 4000;

    /// Empty, aiming at `target` rows.
    pub fn new(target: usize) -> Self {
        Self {
            target: target.max(1),
            stride: 1,
            seen: 0,
            rows: Vec::new(),
        }
    }

    /// The rows kept, in time order.
    pub fn rows(&self) -> &[Row] {
        &self.rows
    }
}

impl RowSink for Decimated {
    #[inline]
    fn row(&mut self, row: &Row) -> anyhow::Result<()> {
        if self.seen % self.stride == 0 {
            self.rows.push(*row);
            if self.rows.len() >= 2 * self.target {
                let mut k = 0;
                self.rows.retain(|_| {
                    k += 1;
                    k % 2 == 1
                });
                self.stride *= 2;
            }
        }
        self.seen += 1;
        Ok(())
    }
}

/// What the trace files of a run hold, for its summary.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TraceFileReport {
    /// The CSV written.
    pub csv: PathBuf,
    /// Data rows in it.
    pub rows: u64,
    /// Whether they are every step of the planned run.
    pub complete: bool,
}

/// The `--csv` and `--plot` outputs of a run, opened before it starts (so
/// an unwritable path is refused before any work) and fed row by row.
pub struct TraceFiles {
    csv: Option<CsvStream>,
    plot: Option<(AtomicFile, Decimated)>,
}

impl TraceFiles {
    /// Opens the CSV (header written) and the plot's temporary file.
    pub fn open(
        csv: Option<&Path>,
        plot: Option<&Path>,
        angles: &[String],
    ) -> anyhow::Result<Self> {
        let plot = plot
            .map(|p| -> anyhow::Result<_> {
                Ok((
                    AtomicFile::create(p)?,
                    Decimated::new(Decimated::PLOT_POINTS),
                ))
            })
            .transpose()?;
        let csv = csv.map(|p| CsvStream::create(p, angles)).transpose()?;
        Ok(Self { csv, plot })
    }

    /// Writes what is waiting and the plot (titled `title`, of the rows up
    /// to the end, early or not); `planned_steps` says whether the CSV is
    /// the whole run.
    pub fn finish(
        self,
        title: &str,
        angles: &[String],
        planned_steps: u64,
    ) -> anyhow::Result<Option<TraceFileReport>> {
        let mut report = None;
        if let Some(csv) = self.csv {
            let path = csv.rows.path().to_path_buf();
            let rows = csv.finish()?;
            report = Some(TraceFileReport {
                csv: path,
                rows,
                complete: rows == planned_steps,
            });
        }
        if let Some((file, rows)) = self.plot {
            let svg = plot_svg(title, angles, rows.rows());
            file.commit_svg(&svg)?;
        }
        Ok(report)
    }
}

impl RowSink for TraceFiles {
    #[inline]
    fn row(&mut self, row: &Row) -> anyhow::Result<()> {
        if let Some(c) = &mut self.csv {
            c.row(row)?;
        }
        if let Some((_, d)) = &mut self.plot {
            d.row(row)?;
        }
        Ok(())
    }
}

/// An SVG of angles (true, estimated, desired) and coil voltages against
/// time, from `rows` (a decimated copy of the run: `trace::Decimated`).
pub fn plot_svg(title: &str, angles: &[String], rows: &[Row]) -> String {
    let t: Vec<f64> = rows.iter().map(|r| r.t_s).collect();
    let colours = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
    // Each plane's targets in a colour of their own (α's and β's desired
    // angles were one grey dashed line style, told apart only by order).
    let desired = ["#555555", "#ff7f0e"];
    let column = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).collect::<Vec<_>>();
    let mut angle_series = Vec::new();
    for (p, a) in angles.iter().enumerate() {
        let c = colours[p % colours.len()];
        angle_series.push(Series::over(
            format!("{a} true"),
            c,
            false,
            &t,
            &column(&|r| r.true_deg[p]),
        ));
        angle_series.push(Series::over(
            format!("{a} estimate"),
            c,
            true,
            &t,
            &column(&|r| r.estimate_deg[p]),
        ));
        angle_series.push(Series::over(
            format!("{a} desired"),
            desired[p % desired.len()],
            true,
            &t,
            &column(&|r| r.desired_deg[p]),
        ));
    }
    let coils = 2 * angles.len();
    let volt_series = (0..coils)
        .map(|c| {
            Series::over(
                format!("v{}", c + 1),
                colours[c % colours.len()],
                false,
                &t,
                &column(&|r| r.coil_volts[c]),
            )
        })
        .collect();
    let charts = [
        Chart {
            title: format!("{title} — angles"),
            x_label: "time (s)".into(),
            y_label: "angle (deg)".into(),
            series: angle_series,
        },
        Chart {
            title: "driver input voltages".into(),
            x_label: "time (s)".into(),
            y_label: "voltage (V)".into(),
            series: volt_series,
        },
    ];
    line_charts(&charts).finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(k: u64) -> Row {
        Row {
            t_s: k as f64 * 1e-3,
            true_deg: [k as f64, 0.0],
            estimate_deg: [0.0; 2],
            desired_deg: [0.0; 2],
            coil_volts: [0.0; 4],
            faults: 0,
        }
    }

    /// Rows of `n` lines of `k,` text into `f`.
    fn fill(f: &mut RowFile, n: u64) {
        for k in 0..n {
            f.row(|s, _, _| {
                s.push_str(&format!("{k}\n"));
                Ok::<(), NonFinite>(())
            })
            .unwrap();
        }
    }

    /// An atomic row file streams into a temporary file beside a regular
    /// target and renames it over the target at the end (dropped before,
    /// it leaves the target); a symbolic link is followed and kept; a
    /// FIFO is written through, never replaced.
    #[test]
    fn an_atomic_row_file_replaces_a_file_follows_a_link_and_writes_through_a_fifo() {
        let dir = tempfile::tempdir().unwrap();
        let names = || {
            let mut n: Vec<String> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            n.sort();
            n
        };
        let real = dir.path().join("real.csv");
        std::fs::write(&real, "old\n").unwrap();
        let link = dir.path().join("link.csv");
        std::os::unix::fs::symlink("real.csv", &link).unwrap();
        let mut f = RowFile::create_atomic(&link, "k\n").unwrap();
        fill(&mut f, 3);
        drop(f);
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "old\n");
        assert_eq!(names(), ["link.csv", "real.csv"]);
        let mut f = RowFile::create_atomic(&link, "k\n").unwrap();
        // 20,000 rows: more than one block on disk before the end.
        fill(&mut f, 20_000);
        assert!(f.rows_written() > 0 && names().len() == 3, "{:?}", names());
        assert_eq!(std::fs::read_to_string(&real).unwrap(), "old\n");
        assert_eq!(f.finish().unwrap(), 20_000);
        let text = std::fs::read_to_string(&real).unwrap();
        assert!(text.starts_with("k\n0\n1\n") && text.ends_with("\n19999\n"));
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(names(), ["link.csv", "real.csv"]);

        let fifo = dir.path().join("pipe");
        let reader = crate::output::fifo_and_reader(&fifo);
        let mut f = RowFile::create_atomic(&fifo, "k\n").unwrap();
        fill(&mut f, 2);
        assert_eq!(f.finish().unwrap(), 2);
        assert_eq!(reader.join().unwrap(), "k\n0\n1\n");
        use std::os::unix::fs::FileTypeExt as _;
        assert!(std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo());
        assert_eq!(names(), ["link.csv", "pipe", "real.csv"]);
    }

    /// In a 3D plot each plane's desired angle has its own line style,
    /// and neither is the style of a true or estimated angle.
    #[test]
    fn each_planes_targets_have_a_line_style_of_their_own() {
        let angles = ["alpha".to_string(), "beta".to_string()];
        let rows: Vec<Row> = (0..50).map(row).collect();
        let svg = plot_svg("t", &angles, &rows);
        // The style of the line drawn just before a legend label.
        let style = |label: &str| -> String {
            let at = svg
                .find(&format!(">{label}<"))
                .unwrap_or_else(|| panic!("{label}"));
            let line = svg[..at].rfind("<line").unwrap();
            let stroke = svg[line..at].find("stroke=").unwrap() + line;
            svg[stroke..at].split("/>").next().unwrap().to_string()
        };
        let (a, b) = (style("alpha desired"), style("beta desired"));
        assert_ne!(a, b);
        for other in ["alpha true", "alpha estimate", "beta true", "beta estimate"] {
            assert_ne!(style(other), a, "{other}");
            assert_ne!(style(other), b, "{other}");
        }
    }

    #[test]
    fn decimation_keeps_memory_bounded_and_rows_evenly_spaced() {
        let mut d = Decimated::new(100);
        for k in 0..1_000_000 {
            d.row(&row(k)).unwrap();
        }
        let kept = d.rows();
        assert!((100..200).contains(&kept.len()), "{}", kept.len());
        let step = kept[1].true_deg[0] - kept[0].true_deg[0];
        assert!(kept
            .windows(2)
            .all(|w| w[1].true_deg[0] - w[0].true_deg[0] == step));
        assert_eq!(kept[0].true_deg[0], 0.0);
    }

    #[test]
    fn the_csv_holds_whole_rows_only_and_counts_them() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        let angles = ["alpha".to_string(), "beta".to_string()];
        let mut c = CsvStream::create(&p, &angles).unwrap();
        for k in 0..5000 {
            c.row(&row(k)).unwrap();
        }
        // Some blocks are on disk before the end, as whole rows.
        assert!(c.rows_written() > 0 && c.rows_written() < 5000);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.ends_with('\n'));
        assert_eq!(text.lines().count() as u64, c.rows_written() + 1);
        assert_eq!(c.finish().unwrap(), 5000);
        let text = std::fs::read_to_string(&p).unwrap();
        assert_eq!(text.lines().count(), 5001);
        assert!(text.lines().all(|l| l.split(',').count() == 12));
    }

    #[test]
    fn a_missing_estimate_is_an_empty_field_and_a_non_finite_value_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("t.csv");
        let angles = ["alpha".to_string(), "beta".to_string()];
        let mut c = CsvStream::create(&p, &angles).unwrap();
        let mut first = row(0);
        first.estimate_deg = [f64::NAN, 1.0];
        c.row(&first).unwrap();
        c.row(&row(1)).unwrap();
        let mut bad = row(2);
        bad.coil_volts[3] = f64::INFINITY;
        let e = c.row(&bad).unwrap_err().to_string();
        assert!(
            e.contains("t.csv") && e.contains("line 4, column `v4_V`") && e.contains("inf"),
            "{e}"
        );
        let mut bad = row(2);
        bad.estimate_deg[1] = f64::NEG_INFINITY;
        let e = c.row(&bad).unwrap_err().to_string();
        assert!(e.contains("line 4, column `beta_estimate_deg`"), "{e}");
        // The refused rows left nothing behind; the rows before are whole.
        assert_eq!(c.finish().unwrap(), 2);
        let text = std::fs::read_to_string(&p).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        let fields: Vec<&str> = lines[1].split(',').collect();
        assert_eq!((fields[2], fields[5]), ("", "1.0000"), "{}", lines[1]);
        assert!(!text.to_lowercase().contains("nan") && !text.contains("inf"));
    }
}
