//! What a run records: one [`Row`] per control period, and a whole
//! [`Trace`].
use hal_sim::Sample;
use serde::Serialize;

/// One row of the time series. Fixed-size so recording a step does not
/// allocate: a 2D joint uses index 0 of the angle arrays and coils 0–1.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Row {
    /// Time (s).
    pub t_s: f64,
    /// True angles (deg).
    pub true_deg: [f64; 2],
    /// Estimated angles (deg).
    pub estimate_deg: [f64; 2],
    /// Desired angles (deg).
    pub desired_deg: [f64; 2],
    /// Driver input voltages, paper numbering (V).
    pub coil_volts: [f64; 4],
    /// Fault bits.
    pub faults: u16,
}

/// The time series of a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Trace {
    /// Angles per row that are used (1 or 2).
    pub planes: usize,
    /// One row per control period.
    pub rows: Vec<Row>,
}

impl Row {
    /// The row of one closed-loop period (a 2D joint fills index 0 of the
    /// angles and coils 0–1; the rest are NaN).
    pub fn of_sample<const P: usize, const S: usize, const C: usize>(
        sample: &Sample<P, S, C>,
    ) -> Self {
        Row {
            t_s: sample.t_s,
            true_deg: pad(sample.true_deg),
            estimate_deg: pad(sample.estimate_deg),
            desired_deg: pad(sample.desired_deg),
            coil_volts: pad(sample.coil_volts),
            faults: sample.faults,
        }
    }
}

fn pad<const N: usize, const M: usize>(v: [f64; N]) -> [f64; M] {
    core::array::from_fn(|i| v.get(i).copied().unwrap_or(f64::NAN))
}
