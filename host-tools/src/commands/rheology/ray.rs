//! `rheology calibrate --ray ADDRESS`: each batch the search asks for (a
//! GA generation, RA's probes, a uniform draw) is scored on a Ray cluster
//! by the Python package's driver ([`host_tools::ray`]), `python3 -m
//! softjoint.ray_sweep rheology-serve` ($SOFTJOINT_PYTHON names another
//! Python), which cuts it into the units `softjoint.ray_sweep.rheology_batches`
//! runs as tasks. Its `null` (a score that is not finite) reads as +∞,
//! which is how the search counts any non-finite S. A stop ends the
//! search at once: the batch in flight is lost, the batches before it
//! are kept in the search state (`--resume` goes on from it, with or
//! without `--ray`).
use std::path::Path;
use std::process::Command;

pub use host_tools::ray::Driver;
use host_tools::resume::Scores;
use plant_rheology::identify::search::BatchObjective;

/// What the calibration asks the driver for.
pub struct Problem<'a> {
    pub scenario: Option<&'a Path>,
    pub measured: Option<&'a Path>,
    pub params: usize,
    pub address: &'a str,
}

/// The driver's command line for `p`, and its name in errors.
pub fn driver_command(p: &Problem) -> (Command, String) {
    let (mut cmd, who) = host_tools::ray::serve_command("rheology-serve", p.address);
    if let Some(s) = p.scenario {
        cmd.arg(s);
    }
    if let Some(m) = p.measured {
        cmd.arg("--measured").arg(m);
    }
    cmd.args(["--params", &p.params.to_string()]);
    (cmd, who)
}

/// The search's objective on the driver, with its scores kept as the
/// local one keeps them ([`Scores::score_batch`]): a candidate scored
/// before (a resumed search, a repeat) is not sent again, and nothing is
/// sent once a stop is asked.
pub struct OnRay<'a> {
    pub driver: Driver,
    pub scores: &'a Scores,
}

impl BatchObjective for OnRay<'_> {
    fn scores(&mut self, batch: &[Vec<f64>]) -> Result<Vec<f64>, String> {
        let driver = &mut self.driver;
        self.scores
            .score_batch(batch, |todo| driver.scores(todo))?
            .ok_or_else(|| "stopped by a signal".into())
    }
}
