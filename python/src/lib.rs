//! `softjoint._native`: the Python package's door into the workspace's
//! own code. Every function here hands its inputs to host-tools or
//! plant-rheology — the code the `softjoint` program runs — and hands
//! their results back: the joint's closed loop with its trace as NumPy
//! arrays, the tuning cost of one candidate on one plant, the rheology
//! objective, and the sweeps (`tune`, rheology calibration) as work units
//! and a reduction. Nothing is modelled here.
//!
//! Errors: every Rust error becomes a Python exception of the hierarchy
//! in [`errors`], carrying the error's whole message (its context chain,
//! as the program prints it). Results pass the program's own output
//! checks: a summary or objective with a non-finite value raises
//! `NonFiniteError` instead of handing back a NaN or an infinity. A
//! trace row that fails its check cuts the run short there
//! (`RunCutShortError`, with the check's words, as `softjoint sim` exits
//! 1 with "run cut short"); the joint's plant stops a run whose state
//! goes non-finite before any row holds it.
//!
//! Contour fits are `softjoint contour fit`'s, with the fit's own checks,
//! and its test cases `contour synth`'s; the viscoelastic trace and fit
//! are `softjoint viscoelastic simulate`'s and `fit`'s, the object run
//! `object`'s; the rope's run is
//! `softjoint dlo rope`'s and the static solve `dlo solve`'s with its
//! checks; the pushed block is `push simulate`'s, and its objective the
//! fitness `push calibrate` maximises.
//!
//! Identification: `identify joint` as a call (`identify_joint`, the
//! report and plant file of `host_tools::joint::identify_run`), its
//! mechanics stage's fits from their starting points as work units
//! (`IdentifyProblem`) for Ray. Plant files and gains files written out
//! as the program writes them (`PlantFile.save`, `write_gains`).
//!
//! Left out: push calibration and classification as calls (push
//! calibration on Ray goes through the program, `push calibrate --ray`).

use pyo3::prelude::*;

mod arrays;
mod contour;
mod dlo_solve;
mod errors;
mod identify;
mod joint;
mod push;
mod rheology;
mod rope;
mod viscoelastic;

/// The module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    joint::register(m)?;
    rheology::register(m)?;
    contour::register(m)?;
    viscoelastic::register(m)?;
    rope::register(m)?;
    dlo_solve::register(m)?;
    push::register(m)?;
    identify::register(m)?;
    Ok(())
}
