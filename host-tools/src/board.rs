//! A board as the closed loop's controller: the firmware image under QEMU,
//! a real board on a serial port, or the pty board, in lockstep over the
//! protocol link. Each control period is one `HilSensor` → `HilActuator`
//! round trip; everything else (plant, schedule, summary) is the same loop
//! `softjoint sim` runs with the core in process.

use std::time::Duration;

use firmware::control::DriverConfig;
use firmware::estimate::PlaneLaw;
use firmware::protocol::{
    cdeg_to_deg, kind, mv_to_coil_volts, Arm, ClearFaults, Disarm, GetStatus, Hello, HelloAck,
    HilSensor, HilStart, Message, SetCalibration, SetGains, SetLinkTimeout, SetTarget, Status,
    PROTOCOL_VERSION, SCHEMA_HASH,
};
use hal_sim::{Actuation, Controller, Readings};

use crate::link::{Link, LinkError, Port};

/// Per-attempt timeout of configuration requests.
pub const CMD_TIMEOUT: Duration = Duration::from_millis(200);
/// Attempts of configuration requests.
pub const CMD_ATTEMPTS: u32 = 10;

/// Handshake: `Hello` → `HelloAck` with our version and schema; checks the
/// board drives the 3D joint (2 pairs, 4 sensors).
pub fn handshake<P: Port>(link: &mut Link<P>) -> anyhow::Result<()> {
    // A lone delimiter first: ends any partial frame in the board's decoder.
    link.send_raw(&[0])?;
    let reply = link.request(
        &Hello {
            version: PROTOCOL_VERSION,
        }
        .into(),
        CMD_TIMEOUT,
        CMD_ATTEMPTS,
        |m| matches!(m, Message::HelloAck(_)),
    )?;
    if let Message::HelloAck(HelloAck {
        version,
        schema,
        pairs,
        sensors,
    }) = reply
    {
        if version != PROTOCOL_VERSION || schema != SCHEMA_HASH {
            anyhow::bail!(
                "board speaks protocol v{version} schema {schema:#010x}; this host v{PROTOCOL_VERSION} schema {SCHEMA_HASH:#010x}: rebuild one of them"
            );
        }
        if (pairs, sensors) != (2, 4) {
            anyhow::bail!("board controls {pairs} pairs with {sensors} sensors; the lockstep runner drives the 3D joint (2, 4)");
        }
    }
    Ok(())
}

/// Reads the board's status.
pub fn status<P: Port>(link: &mut Link<P>) -> Result<Status, LinkError> {
    match link.request(&GetStatus {}.into(), CMD_TIMEOUT, CMD_ATTEMPTS, |m| {
        matches!(m, Message::Status(_))
    })? {
        Message::Status(s) => Ok(s),
        other => Err(LinkError::Unexpected {
            request: kind::GET_STATUS,
            reply: other.kind(),
        }),
    }
}

/// How a board is set up for a lockstep run.
#[derive(Clone, Debug)]
pub struct LockstepSetup {
    /// Control period (µs).
    pub period_us: u32,
    /// Gains per plane: `(kp_agonist, kp_antagonist, ki, integral_limit_v)`.
    pub gains: [(f32, f32, f32, f32); 2],
    /// Estimation law per plane.
    pub laws: [PlaneLaw; 2],
    /// Link-loss timeout to set (ms of the board's clock); `None` keeps the
    /// board's own.
    pub link_timeout_ms: Option<u16>,
    /// Wait for each lockstep reply (per attempt).
    pub timeout: Duration,
    /// Attempts per step before giving up.
    pub attempts: u32,
    /// Fault injection: lose the first transmission of every Nth sensor
    /// frame (the retry must recover it).
    pub lose_every: Option<u32>,
}

/// A board in lockstep: the closed loop's controller.
pub struct BoardController<'a, P: Port> {
    link: &'a mut Link<P>,
    setup: LockstepSetup,
    driver: DriverConfig,
    targets_deg: [f32; 2],
    seq: u16,
    steps: u64,
}

impl<'a, P: Port> BoardController<'a, P> {
    /// Handshake, configuration, `HilStart`, clearing of faults latched
    /// before (stale sensors in free-running mode, an earlier link loss),
    /// `Arm`.
    pub fn start(link: &'a mut Link<P>, setup: LockstepSetup) -> anyhow::Result<Self> {
        handshake(link)?;
        link.command(&Disarm {}.into(), CMD_TIMEOUT, CMD_ATTEMPTS)?;
        for (plane, ((kp_agonist, kp_antagonist, ki, integral_limit_v), law)) in
            (0u8..).zip(setup.gains.iter().copied().zip(setup.laws))
        {
            link.command(
                &SetGains {
                    plane,
                    kp_agonist,
                    kp_antagonist,
                    ki,
                    integral_limit_v,
                }
                .into(),
                CMD_TIMEOUT,
                CMD_ATTEMPTS,
            )?;
            link.command(
                &SetCalibration { plane, law }.into(),
                CMD_TIMEOUT,
                CMD_ATTEMPTS,
            )?;
        }
        if let Some(timeout_ms) = setup.link_timeout_ms {
            link.command(
                &SetLinkTimeout { timeout_ms }.into(),
                CMD_TIMEOUT,
                CMD_ATTEMPTS,
            )?;
        }
        link.command(
            &HilStart {
                period_us: setup.period_us,
            }
            .into(),
            CMD_TIMEOUT,
            CMD_ATTEMPTS,
        )?;
        match link.command(&ClearFaults {}.into(), CMD_TIMEOUT, CMD_ATTEMPTS) {
            Ok(()) | Err(LinkError::Refused { .. }) => {}
            Err(e) => return Err(e.into()),
        }
        link.command(&Arm {}.into(), CMD_TIMEOUT, CMD_ATTEMPTS)?;
        Ok(Self {
            link,
            setup,
            driver: DriverConfig::default(),
            targets_deg: [0.0; 2],
            seq: 0,
            steps: 0,
        })
    }

    /// The link (statistics, further requests).
    pub fn link(&mut self) -> &mut Link<P> {
        self.link
    }

    /// Disarms the board and reads its counters.
    pub fn finish(self) -> Result<Status, LinkError> {
        let _ = self
            .link
            .command(&Disarm {}.into(), CMD_TIMEOUT, CMD_ATTEMPTS);
        status(self.link)
    }
}

impl<P: Port> Controller<2, 4> for BoardController<'_, P> {
    type Error = LinkError;

    fn set_target(&mut self, plane: usize, desired_deg: f32) -> Result<(), LinkError> {
        let msg = SetTarget {
            plane: u8::try_from(plane).unwrap_or(u8::MAX),
            target_deg: desired_deg,
        };
        self.link.command(&msg.into(), CMD_TIMEOUT, CMD_ATTEMPTS)?;
        if let Some(t) = self.targets_deg.get_mut(plane) {
            *t = desired_deg;
        }
        Ok(())
    }

    fn targets_deg(&self) -> [f32; 2] {
        self.targets_deg
    }

    fn step(&mut self, readings: &Readings<2, 4>) -> Result<Actuation<2>, LinkError> {
        let counts = readings
            .counts
            .map(|c| c.clamp(i64::from(i16::MIN), i64::from(i16::MAX)) as i16);
        let seq = self.seq;
        if self
            .setup
            .lose_every
            .is_some_and(|n| n > 0 && self.steps % u64::from(n) == u64::from(n) - 1)
        {
            self.link.lose_next_send();
        }
        let reply = self.link.request(
            &HilSensor { seq, counts }.into(),
            self.setup.timeout,
            self.setup.attempts,
            |m| matches!(m, Message::HilActuator(a) if a.seq == seq),
        )?;
        let Message::HilActuator(a) = reply else {
            return Err(LinkError::Unexpected {
                request: kind::HIL_SENSOR,
                reply: reply.kind(),
            });
        };
        self.seq = self.seq.wrapping_add(1);
        self.steps += 1;
        Ok(Actuation {
            // The board's millivolts, exactly as a simulated PWM channel with
            // a millivolt full scale applies them.
            pair_volts: a.pair_mv.map(|mv| mv_to_coil_volts(mv, &self.driver)),
            estimate_deg: a.estimate_cdeg.map(|c| f64::from(cdeg_to_deg(c))),
            faults: u16::from(a.faults),
        })
    }
}
