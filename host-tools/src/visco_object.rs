//! What `softjoint viscoelastic object` does (seed 002 §4–5): the DGFM
//! object of a mesh (default: the shipped blob), its parameters estimated
//! from a simulated probe campaign, and a scripted probe run at 1 kHz by
//! the firmware's real-time update beside the plant's exact reference —
//! with the command's bounds on its arguments and its figures. The
//! program and the Python package both take them from here.
use anyhow::{bail, Context, Result};
use plant_viscoelastic::error::VeError;
use plant_viscoelastic::experiment::pipeline::{
    default_probe_script, object_dgfm, probe_beside_reference, Campaign, IdentifiedObject, ProbeRun,
};
use plant_viscoelastic::io::read_probe_script;
use plant_viscoelastic::object::{ProbeEvent, HAPTIC_PERIOD_S};
use plant_viscoelastic::{Dgfm, SurfaceMesh};
use serde::Serialize;

use crate::visco_core::CoreObject;

/// Longest `object` run: every haptic step and every 30 Hz frame of every
/// vertex is kept in memory before it is written. Estimate for the default
/// ~200-vertex mesh at this length: 0.2 GB of frames, 0.5 GB of CSV text.
pub const MAX_OBJECT_DURATION_S: f64 = 600.0;

/// Most surface vertices `object` takes: its time grows about as n³
/// (1,982 vertices took 30 s, a 19,462-vertex sphere ran past 60 s with no
/// end in sight); 3,000 vertices is about two minutes.
pub const MAX_OBJECT_VERTICES: usize = 3000;

/// The run's settings: simulated `duration_s`, every `probe_every`-th
/// traction vertex probed in the campaign, the noise's `seed`, general
/// damping tensors (`tensor`) instead of Rayleigh damping.
#[derive(Clone, Copy, Debug)]
pub struct ObjectJob {
    pub duration_s: f64,
    pub probe_every: usize,
    pub seed: u64,
    pub tensor: bool,
}

impl ObjectJob {
    /// The bounds, each setting called `prefix` + its name with `-` for
    /// `_` on the command line (`prefix` `--`) and as it is in Python
    /// (`prefix` empty).
    pub fn check(&self, prefix: &str) -> Result<()> {
        let name = |n: &str| {
            if prefix.is_empty() {
                n.to_string()
            } else {
                format!("{prefix}{}", n.replace('_', "-"))
            }
        };
        let d = self.duration_s;
        if !(d.is_finite() && (HAPTIC_PERIOD_S..=MAX_OBJECT_DURATION_S).contains(&d)) {
            bail!(
                "{} must be between one haptic period ({HAPTIC_PERIOD_S} s) and {MAX_OBJECT_DURATION_S} s, got {d:e}",
                name("duration_s")
            );
        }
        if self.probe_every == 0 {
            bail!(
                "{} must be at least 1 (probe every N-th traction vertex)",
                name("probe_every")
            );
        }
        Ok(())
    }
}

/// The mesh of an OBJ's `(text, name)` (default: the shipped object),
/// refused when its DGFM would take too long.
pub fn load_mesh(obj: Option<(&str, &str)>) -> Result<SurfaceMesh> {
    let mesh = match obj {
        Some((text, name)) => SurfaceMesh::from_obj_str(text, name)?,
        None => SurfaceMesh::default_object(),
    };
    let n = mesh.vertices_m.len();
    if n > MAX_OBJECT_VERTICES {
        // Measured: 872 vertices 4 s, 1,982 vertices 30 s (release build):
        // about n³, so the estimate scales the latter.
        let minutes = 0.5 * (n as f64 / 1982.0).powi(3);
        bail!(
            "{}: {n} vertices is more than {MAX_OBJECT_VERTICES}: the DGFM and its fits take time growing as the cube of the vertex count (about {} minutes for this mesh; 1,982 vertices took 30 s); simplify the mesh (the seed's object has 193 vertices)",
            obj.map_or("the mesh", |(_, name)| name),
            plant_common::short_number(minutes.round())
        );
    }
    Ok(mesh)
}

/// The probe script: a CSV's `(text, name)` (its events and their lines)
/// or the default push.
struct Script<'a> {
    name: Option<&'a str>,
    events: Vec<ProbeEvent>,
    /// The file line of each event (empty for the default).
    lines: Vec<usize>,
}

impl<'a> Script<'a> {
    fn load(csv: Option<(&str, &'a str)>, dgfm: &Dgfm) -> Result<Self> {
        let (events, lines) = match csv {
            Some((text, name)) => {
                let s = read_probe_script(text, name, dgfm.mesh().len())?;
                (s.events, s.lines)
            }
            None => (
                default_probe_script(dgfm).context("no traction vertex")?,
                Vec::new(),
            ),
        };
        Ok(Script {
            name: csv.map(|(_, n)| n),
            events,
            lines,
        })
    }

    /// An error of the run, with an event of the user's script named by
    /// its file and line.
    fn name_error(&self, e: VeError) -> anyhow::Error {
        match (&e, self.name) {
            (VeError::ProbeEvent { index, error, .. }, Some(name)) => {
                match self.lines.get(*index) {
                    Some(line) => anyhow::anyhow!("{name}:{line}: {error}"),
                    None => anyhow::Error::new(e),
                }
            }
            _ => anyhow::Error::new(e),
        }
    }
}

/// An object run: the DGFM, the simulated campaign, what was identified
/// from it, and the probe run beside the exact reference.
pub struct ObjectRun {
    pub dgfm: Dgfm,
    pub campaign: Campaign,
    pub identified: IdentifiedObject,
    pub run: ProbeRun,
}

/// What an object run printed: sizes, and how far the firmware's update
/// strays from the exact reference (the contact's largest |Δu| and that
/// of all vertices over the display frames, m and relative to max |u|).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ObjectFigures {
    pub vertices: usize,
    pub traction_vertices: usize,
    pub trials: usize,
    pub estimated_vertices: usize,
    pub haptic_steps: usize,
    pub display_frames: usize,
    pub contact_difference_m: f64,
    pub contact_difference_rel: f64,
    pub frames_difference_m: f64,
    pub frames_difference_rel: f64,
}

impl ObjectRun {
    pub fn figures(&self) -> ObjectFigures {
        let d = &self.run.difference;
        ObjectFigures {
            vertices: self.dgfm.mesh().len(),
            traction_vertices: self.dgfm.fixed().iter().filter(|f| !**f).count(),
            trials: self.campaign.trials.len(),
            estimated_vertices: self.identified.estimates.len(),
            haptic_steps: self.run.samples.len(),
            display_frames: self.run.frames.len(),
            contact_difference_m: d.contact_m,
            contact_difference_rel: d.contact_rel,
            frames_difference_m: d.frames_m,
            frames_difference_rel: d.frames_rel,
        }
    }
}

/// Runs `object`: the mesh (`obj`: an OBJ's text and name, else the
/// shipped one) and its DGFM, the script (`script`: a CSV's text and
/// name, else the default push) read and checked before the campaign,
/// the campaign simulated and identified (seed §4), and the script run by
/// the firmware's real-time update beside the exact reference (seed §5).
/// `phase` hears what is being done. The job is checked first.
pub fn run_object(
    obj: Option<(&str, &str)>,
    script: Option<(&str, &str)>,
    job: &ObjectJob,
    phase: &mut dyn FnMut(&str),
) -> Result<ObjectRun> {
    job.check("")?;
    let mesh = load_mesh(obj)?;
    phase(&format!(
        "building the DGFM of {} vertices (FEM)",
        mesh.vertices_m.len()
    ));
    let dgfm = object_dgfm(mesh)?;
    let script = Script::load(script, &dgfm)?;
    phase("simulating and fitting the probe campaign");
    let campaign = Campaign::simulate(&dgfm, job.probe_every, job.seed)?;
    let identified = campaign.identify(&dgfm, job.tensor)?;
    phase("running the probe script at 1 kHz");
    let run = probe_beside_reference(
        &dgfm,
        &identified.params,
        &script.events,
        job.duration_s,
        |dgfm, params| CoreObject::new(dgfm, params, HAPTIC_PERIOD_S),
    )
    .map_err(|e| script.name_error(e))?;
    Ok(ObjectRun {
        dgfm,
        campaign,
        identified,
        run,
    })
}
