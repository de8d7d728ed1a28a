//! The calibration sweep of a simulated joint: what `sim
//! --calibration-sweep` writes and what fitted estimation laws are fitted
//! to (a simulated stand-in for the paper's camera-referenced calibration).
use hal_sim::{ClosedLoop, CoreController, Plant, Schedule};

use crate::files::sweep::SweepRow;
use crate::run::joint::{ControllerSpec, CoreLoopTask, JointSpec, SimJoint};

/// A calibration sweep of `joint`: the link follows a slow
/// triangle 0 → +20° → −20° → 0 at 1°/s, and every camera frame gives one
/// row of wire insertions and the camera's angles (with its noise and its
/// one-frame latency, ≈ 0.03° at this rate). The camera is the reference
/// only: the joint is moved by the firmware's P law on the wires with the
/// paper's published Eq. 2 / Eq. 3, because P control on 30 frames/s camera
/// feedback limit-cycles between the coils and overheats them (the thermal
/// budget then cuts them for much of the sweep). Frames taken while any
/// fault is active are skipped.
///
/// Why moving rather than held: a staircase with 8 s dwells (the paper's
/// static images) was tried. Laws fitted to it read held angles to 0.2–0.4°
/// but moving ones to 1.0–1.2°, because a moving wire lags in its tube; the
/// slow sweep covers both and its laws stay below 1° on independent runs.
pub fn calibration_sweep(joint: &JointSpec) -> anyhow::Result<Vec<SweepRow>> {
    let period_us = 1000u32;
    let steps = (SweepTriangle::DURATION_S / (f64::from(period_us) * 1e-6)).round() as u64;
    // The sweep's own plant streams; the cartilage joint even for a
    // rigid-bearing scenario (as the laws were always fitted).
    let plant = JointSpec {
        rigid_bearing: false,
        ..joint.with_seed(joint.seed ^ 0xCA1B)
    };
    let controller = ControllerSpec::paper(period_us, joint.seed);
    plant.core_loop(&controller, SweepRows { steps })
}

/// The sweep's targets: every plane follows 0 → +20° → −20° → 0 at 1°/s.
struct SweepTriangle;

impl SweepTriangle {
    const AMPLITUDE_DEG: f64 = 20.0;
    const RATE_DEG_S: f64 = 1.0;
    const QUARTER_S: f64 = Self::AMPLITUDE_DEG / Self::RATE_DEG_S;
    const DURATION_S: f64 = 4.0 * Self::QUARTER_S;

    fn at(t: f64) -> f64 {
        let (a, r, q) = (Self::AMPLITUDE_DEG, Self::RATE_DEG_S, Self::QUARTER_S);
        if t < q {
            t * r
        } else if t < 3.0 * q {
            a - (t - q) * r
        } else {
            -a + (t - 3.0 * q) * r
        }
    }
}

impl<Pl, const P: usize, const C: usize> Schedule<Pl, P, C> for SweepTriangle {
    fn targets(&mut self, t_s: f64) -> Option<[f32; P]> {
        Some([Self::at(t_s) as f32; P])
    }
    fn disturb(
        &mut self,
        _t_s: f64,
        _plant: &mut Pl,
        _overrides: &mut [Option<f64>; C],
    ) -> Result<(), plant_joint::PlantError> {
        Ok(())
    }
}

/// Runs a calibration sweep: each camera frame the controller is given
/// while its step reports no fault yields one row, with the wire
/// insertions read at the same instant. With wire feedback nothing else
/// consumes camera frames, so each is seen once. The camera's one-frame
/// latency makes each angle ~33 ms older than the insertions beside it: at
/// 1°/s that is 0.03°, well under the estimation errors being calibrated.
struct SweepRows {
    steps: u64,
}

impl CoreLoopTask for SweepRows {
    type Output = Vec<SweepRow>;

    fn run<Pl, const P: usize, const S: usize, const C: usize>(
        self,
        cl: &mut ClosedLoop<Pl, CoreController<P, S>, P, S, C>,
    ) -> anyhow::Result<Vec<SweepRow>>
    where
        Pl: Plant<P, S, C> + SimJoint,
    {
        let steps = self.steps;
        let mut rows = Vec::new();
        let res = cl.plant.mm_per_count();
        cl.run(steps, &mut SweepTriangle, |sample| -> anyhow::Result<()> {
            if let Some(angles) = sample.readings.camera {
                if sample.faults == 0 {
                    rows.push(SweepRow {
                        d_mm: sample
                            .readings
                            .counts
                            .iter()
                            .zip(res)
                            .map(|(c, r)| *c as f64 * r)
                            .collect(),
                        angle_deg: angles.to_vec(),
                    });
                }
            }
            Ok(())
        })?;
        Ok(rows)
    }
}
