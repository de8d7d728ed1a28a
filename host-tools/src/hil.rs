//! Hardware-in-the-loop in lockstep: the host owns time and the plant; the
//! board (the firmware image under QEMU, or a real board) runs the control
//! step. Each period the host sends a sensor frame `{seq, counts}` and waits
//! (bounded, with retries of the same `seq`) for the actuator frame, then
//! advances the plant with the board's outputs. See ARCHITECTURE.md.

use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use firmware::control::DriverConfig;
use firmware::joint::JointConfig;
use firmware::protocol::{
    cdeg_to_deg, ActuatorFrame, Message, SensorFrame, Status, PROTOCOL_VERSION, SCHEMA_HASH,
};
use hal_sim::Plant;
use serde::Serialize;

use crate::link::{HostLinkStats, Link, LinkError, Port};
use crate::scenario::{FeedbackKind, JointKind, Scenario, TargetTracker};
use crate::sim::{self, Row, Summary, Trace};

/// Lockstep settings.
#[derive(Clone, Copy, Debug)]
pub struct HilOptions {
    /// Wait for each reply (per attempt).
    pub timeout: Duration,
    /// Attempts per step before giving up.
    pub attempts: u32,
    /// Fault injection: lose the first transmission of every Nth sensor
    /// frame (the retry must recover it).
    pub lose_every: Option<u32>,
    /// Link-loss timeout to configure on the board (ms); `None` keeps the
    /// board's own (50 ms by default).
    pub link_timeout_ms: Option<u16>,
}

impl Default for HilOptions {
    fn default() -> Self {
        Self {
            timeout: Duration::from_millis(100),
            attempts: 20,
            lose_every: None,
            link_timeout_ms: None,
        }
    }
}

/// What a HIL run reports beyond the simulation summary.
#[derive(Clone, Debug, Serialize)]
pub struct HilReport {
    /// The same summary as `softjoint sim`.
    #[serde(flatten)]
    pub summary: Summary,
    /// Host-side link counters.
    pub link: HostLinkStats,
    /// The board's own counters at the end.
    pub board_frames_ok: u32,
    /// Board: CRC errors.
    pub board_crc_errors: u16,
    /// Board: COBS errors.
    pub board_cobs_errors: u16,
    /// Board: oversized frames.
    pub board_overfull: u16,
    /// Board: malformed frames.
    pub board_malformed: u16,
    /// Lockstep steps per wall-clock second.
    pub lockstep_steps_per_s: f64,
}

/// A finished HIL run.
pub struct HilOutput {
    /// Report (summary + link statistics).
    pub report: HilReport,
    /// Time series, same columns as `sim`.
    pub trace: Trace,
}

const CMD_TIMEOUT: Duration = Duration::from_millis(200);
const CMD_ATTEMPTS: u32 = 10;

/// Handshake: `Hello` → `HelloAck` with our version and schema.
pub fn handshake<P: Port>(link: &mut Link<P>) -> anyhow::Result<()> {
    // A lone delimiter first: ends any partial frame in the board's decoder.
    link.send_raw(&[0])?;
    let reply = link.request(
        &Message::Hello {
            version: PROTOCOL_VERSION,
        },
        CMD_TIMEOUT,
        CMD_ATTEMPTS,
        |m| matches!(m, Message::HelloAck { .. }),
    )?;
    if let Message::HelloAck {
        version,
        schema,
        pairs,
        sensors,
    } = reply
    {
        if version != PROTOCOL_VERSION || schema != SCHEMA_HASH {
            bail!(
                "board speaks protocol v{version} schema {schema:#010x}; this host v{PROTOCOL_VERSION} schema {SCHEMA_HASH:#010x}: rebuild one of them"
            );
        }
        if (pairs, sensors) != (2, 4) {
            bail!("board controls {pairs} pairs with {sensors} sensors; the lockstep runner drives the 3D joint (2, 4)");
        }
    }
    Ok(())
}

/// Reads the board's status.
pub fn status<P: Port>(link: &mut Link<P>) -> Result<Status, LinkError> {
    match link.request(&Message::GetStatus, CMD_TIMEOUT, CMD_ATTEMPTS, |m| {
        matches!(m, Message::Status(_))
    })? {
        Message::Status(s) => Ok(s),
        other => Err(LinkError::Unexpected {
            request: firmware::protocol::kind::GET_STATUS,
            reply: other.kind(),
        }),
    }
}

/// Runs a 3D wire-feedback scenario in lockstep with the board on `link`.
pub fn run<P: Port>(
    s: &Scenario,
    link: &mut Link<P>,
    opts: HilOptions,
) -> anyhow::Result<HilOutput> {
    s.validate()?;
    if s.joint != JointKind::ThreeD || s.feedback != FeedbackKind::Wire {
        bail!("hardware-in-the-loop runs the 3D joint with wire-sensor feedback (the board's sensor frame carries wire counts)");
    }
    let (laws, estimator) = sim::laws_for(s)?;
    let mut plant = sim::plant_3d(s)?;
    handshake(link)?;
    link.command(&Message::Disarm, CMD_TIMEOUT, CMD_ATTEMPTS)?;
    let laws = laws.unwrap_or_else(|| JointConfig::paper_3d().laws.to_vec());
    for p in 0..2u8 {
        let g = sim::pair_gains(s, usize::from(p))?;
        link.command(
            &Message::SetGains {
                plane: p,
                kp_agonist: g.kp_agonist(),
                kp_antagonist: g.kp_antagonist(),
                ki: g.ki(),
                integral_limit_v: g.integral_limit_v(),
            },
            CMD_TIMEOUT,
            CMD_ATTEMPTS,
        )?;
        link.command(
            &Message::SetCalibration {
                plane: p,
                law: laws[usize::from(p)],
            },
            CMD_TIMEOUT,
            CMD_ATTEMPTS,
        )?;
    }
    if let Some(ms) = opts.link_timeout_ms {
        link.command(
            &Message::SetLinkTimeout { timeout_ms: ms },
            CMD_TIMEOUT,
            CMD_ATTEMPTS,
        )?;
    }
    link.command(
        &Message::HilStart {
            period_us: s.control_period_us,
        },
        CMD_TIMEOUT,
        CMD_ATTEMPTS,
    )?;
    // Faults latched by an earlier run (e.g. link loss) must be cleared.
    match link.command(&Message::ClearFaults, CMD_TIMEOUT, CMD_ATTEMPTS) {
        Ok(()) | Err(LinkError::Refused { .. }) => {}
        Err(e) => return Err(e.into()),
    }
    link.command(&Message::Arm, CMD_TIMEOUT, CMD_ATTEMPTS)?;

    let driver = DriverConfig::default();
    let (period, steps) = (s.period_s(), s.steps());
    let mut rows = Vec::with_capacity(steps as usize);
    let mut disturber = sim::Disturber::new(s);
    let mut targets = TargetTracker::default();
    let mut faults_seen = 0u16;
    let mut peak = [f64::NEG_INFINITY; 4];
    let started = Instant::now();
    for k in 0..steps {
        let t = k as f64 * period;
        if let Some(target) = targets.changed(s, t) {
            for (p, d) in target.iter().enumerate() {
                link.command(
                    &Message::SetTarget {
                        plane: p as u8,
                        target_deg: *d as f32,
                    },
                    CMD_TIMEOUT,
                    CMD_ATTEMPTS,
                )
                .with_context(|| format!("setting the target at t = {t:.3} s"))?;
            }
        }
        let mut overrides = [None; 4];
        disturber.apply(s, t, &mut overrides, |a, id| {
            sim::load_3d(&mut plant, a, id)
        })?;
        let counts = Plant::<4, 4, 2>::counts(&plant)
            .map(|c| c.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16);
        let seq = k as u16;
        let msg = Message::HilSensor(SensorFrame { seq, counts });
        if opts
            .lose_every
            .is_some_and(|n| n > 0 && k % u64::from(n) == u64::from(n) - 1)
        {
            link.lose_next_send();
        }
        let reply = link
            .request(
                &msg,
                opts.timeout,
                opts.attempts,
                |m| matches!(m, Message::HilActuator(a) if a.seq == seq),
            )
            .with_context(|| format!("lockstep step {k} (t = {t:.3} s)"))?;
        let Message::HilActuator(ActuatorFrame {
            pair_mv,
            estimate_cdeg,
            faults,
            ..
        }) = reply
        else {
            bail!("unexpected reply");
        };
        // The board's millivolts, exactly as a simulated PWM channel with a
        // millivolt full scale would apply them (+: agonist, −: antagonist).
        let mut volts = [0.0f64; 4];
        for (p, mv) in pair_mv.iter().enumerate() {
            let v = (f64::from(mv.unsigned_abs()) / 1000.0).min(f64::from(driver.supply_v()));
            if *mv > 0 {
                volts[p] = v;
            } else if *mv < 0 {
                volts[p + 2] = v;
            }
        }
        for (v, o) in volts.iter_mut().zip(overrides) {
            if let Some(o) = o {
                *v = o;
            }
        }
        let true_deg = plant.angles_deg();
        Plant::<4, 4, 2>::advance(&mut plant, period, &volts)
            .with_context(|| format!("plant at t = {t:.3} s"))?;
        for (pk, c) in peak.iter_mut().zip(plant.coil_temperatures_c()) {
            *pk = pk.max(c);
        }
        faults_seen |= u16::from(faults);
        rows.push(Row {
            t_s: t,
            true_deg,
            estimate_deg: estimate_cdeg.map(|c| f64::from(cdeg_to_deg(c))),
            desired_deg: [targets.current()[0], targets.current()[1]],
            coil_volts: volts,
            faults: u16::from(faults),
        });
    }
    let wall = started.elapsed().as_secs_f64();
    let _ = link.command(&Message::Disarm, CMD_TIMEOUT, CMD_ATTEMPTS);
    let board = status(link)?;
    let trace = Trace { planes: 2, rows };
    let summary = sim::summarize(
        s,
        &trace,
        &["alpha", "beta"],
        wall,
        estimator,
        faults_seen,
        peak.to_vec(),
    );
    let report = HilReport {
        summary,
        link: link.stats(),
        board_frames_ok: board.frames_ok,
        board_crc_errors: board.crc_errors,
        board_cobs_errors: board.cobs_errors,
        board_overfull: board.overfull,
        board_malformed: board.malformed,
        lockstep_steps_per_s: if wall > 0.0 {
            steps as f64 / wall
        } else {
            f64::INFINITY
        },
    };
    Ok(HilOutput { report, trace })
}
