//! The safety supervisor: the last word on what reaches the SMA drivers.
//!
//! SMA coils burn out and drivers overheat (SPEC §6). Unpowered is the safe
//! state: an unpowered coil is just a bias spring. The supervisor
//!
//! - keeps a per-coil **thermal budget**: a first-order model of the coil's
//!   temperature rise above ambient, `C dT/dt = I² R − T/R_th`, driven by the
//!   current the ULN2003 would pass for the commanded input voltage. A coil
//!   whose modelled rise reaches the trip level is held off until it has
//!   cooled to the resume level (cool-down with hysteresis), and
//!   [`Faults::OVER_BUDGET`] is reported meanwhile;
//! - watches the link (hardware-in-the-loop or a remote host): no frame for
//!   longer than the timeout is [`Faults::LINK_LOSS`];
//! - **latches** the safe state on any fault other than the thermal cut-off
//!   (sensor range/rate/stale, link loss, invalid input): every output is
//!   zero until [`Supervisor::clear`] is called, and clearing only succeeds
//!   once the cause has gone;
//! - gates everything behind arm/disarm (disarmed: all off, not a fault).
//!
//! The pair rule (never both coils of a pair) is enforced by the type of
//! [`PairCommand`]; the supervisor can only remove drive, never add it.

use crate::control::{DriveVolts, DriverConfig, PairCommand};
use crate::time::{Duration, Instant};

/// A set of fault flags (a bit set; combine with `|`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Faults(u16);

impl Faults {
    /// No fault.
    pub const NONE: Faults = Faults(0);
    /// A sensor reading was out of range or not finite.
    pub const SENSOR_RANGE: Faults = Faults(1 << 0);
    /// A sensor reading changed implausibly fast.
    pub const SENSOR_RATE: Faults = Faults(1 << 1);
    /// A sensor has not delivered a good reading for too long.
    pub const SENSOR_STALE: Faults = Faults(1 << 2);
    /// No frame from the host within the link timeout.
    pub const LINK_LOSS: Faults = Faults(1 << 3);
    /// A coil's thermal budget is exhausted; it is held off to cool.
    pub const OVER_BUDGET: Faults = Faults(1 << 4);
    /// A non-finite or out-of-range input (time, target, step).
    pub const INVALID_INPUT: Faults = Faults(1 << 5);
    /// A driver channel reported an error.
    pub const DRIVER: Faults = Faults(1 << 6);
    /// The firmware panicked or reset unexpectedly (set by the image).
    pub const INTERNAL: Faults = Faults(1 << 7);

    /// Every flag, in bit order, with a short name (for reports).
    pub const NAMED: [(Faults, &'static str); 8] = [
        (Faults::SENSOR_RANGE, "sensor-range"),
        (Faults::SENSOR_RATE, "sensor-rate"),
        (Faults::SENSOR_STALE, "sensor-stale"),
        (Faults::LINK_LOSS, "link-loss"),
        (Faults::OVER_BUDGET, "over-budget"),
        (Faults::INVALID_INPUT, "invalid-input"),
        (Faults::DRIVER, "driver"),
        (Faults::INTERNAL, "internal"),
    ];

    /// Faults that latch the safe state (all but the thermal cut-off, which
    /// clears itself after cool-down).
    pub const LATCHING: Faults = Faults(
        Faults::SENSOR_RANGE.0
            | Faults::SENSOR_RATE.0
            | Faults::SENSOR_STALE.0
            | Faults::LINK_LOSS.0
            | Faults::INVALID_INPUT.0
            | Faults::DRIVER.0
            | Faults::INTERNAL.0,
    );

    /// The raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }

    /// From raw bits (unknown bits kept, so nothing reported is lost).
    pub const fn from_bits(bits: u16) -> Faults {
        Faults(bits)
    }

    /// True when no flag is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// True when every flag of `other` is set here.
    pub const fn contains(self, other: Faults) -> bool {
        self.0 & other.0 == other.0
    }

    /// True when any flag of `other` is set here.
    pub const fn intersects(self, other: Faults) -> bool {
        self.0 & other.0 != 0
    }

    /// The flags of `self` that are also in `other`.
    pub const fn intersection(self, other: Faults) -> Faults {
        Faults(self.0 & other.0)
    }
}

impl core::ops::BitOr for Faults {
    type Output = Faults;
    fn bitor(self, o: Faults) -> Faults {
        Faults(self.0 | o.0)
    }
}

impl core::ops::BitOrAssign for Faults {
    fn bitor_assign(&mut self, o: Faults) {
        self.0 |= o.0;
    }
}

/// Parameters of the per-coil thermal model and budget.
///
/// Defaults are estimates for a BMX200-class coil (SPEC §2): 0.2 mm NiTi
/// wire, ~5 Ω per 20 mm coil, thermal time constant 3–7 s. The heat
/// capacity: ~100 turns × π × 0.6 mm ≈ 190 mm of wire, π(0.1 mm)² × 190 mm
/// ≈ 6.0 mm³, × 6450 kg/m³ (NiTi density) ≈ 39 mg, × 837 J/(kg·K) ≈
/// 0.032 J/K. With τ = 5 s, R_th = τ/C ≈ 155 K/W.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ThermalConfig {
    /// Coil resistance (Ω). Estimate: ~5 Ω per 20 mm BMX200 coil (SPEC §2).
    pub coil_resistance_ohm: f32,
    /// ULN2003 transconductance above the threshold (A/V). Estimate within
    /// SPEC §2's 0.3–1.5 A/V; the upper end is the conservative choice.
    pub driver_gain_a_per_v: f32,
    /// Driver current limit (A): ULN2003 rating of 0.5 A per channel.
    pub max_current_a: f32,
    /// Heat capacity of one coil (J/K). Estimate, see above.
    pub heat_capacity_j_per_k: f32,
    /// Cooling time constant (s). Estimate: middle of SPEC §2's 3–7 s.
    pub time_constant_s: f32,
    /// Modelled rise above ambient that trips the coil off (K). Estimate:
    /// 95 K ≈ 120 °C at 25 °C ambient, 42 K above A_f = 78 °C (SPEC §2),
    /// enough to finish the transformation with margin below the ~150 °C
    /// where NiTi begins to lose its trained memory.
    pub trip_rise_k: f32,
    /// Rise below which a tripped coil may be driven again (K). Estimate:
    /// 45 K ≈ 70 °C, below A_s = 68 °C + margin, so a tripped coil has
    /// really cooled before it is reheated.
    pub resume_rise_k: f32,
}

impl Default for ThermalConfig {
    fn default() -> Self {
        Self {
            coil_resistance_ohm: 5.0,
            driver_gain_a_per_v: 1.5,
            max_current_a: 0.5,
            heat_capacity_j_per_k: 0.032,
            time_constant_s: 5.0,
            trip_rise_k: 95.0,
            resume_rise_k: 45.0,
        }
    }
}

impl ThermalConfig {
    /// True when every parameter is finite, positive and resume < trip.
    pub fn is_valid(&self) -> bool {
        let pos = |v: f32| v.is_finite() && v > 0.0;
        pos(self.coil_resistance_ohm)
            && pos(self.driver_gain_a_per_v)
            && pos(self.max_current_a)
            && pos(self.heat_capacity_j_per_k)
            && pos(self.time_constant_s)
            && pos(self.trip_rise_k)
            && self.resume_rise_k.is_finite()
            && self.resume_rise_k >= 0.0
            && self.resume_rise_k < self.trip_rise_k
    }

    /// Current the driver passes at input `volts` (A), the SPEC §2 model
    /// `clamp(g (V − V_offset), 0, I_max)`.
    pub fn current_a(&self, volts: DriveVolts, driver: &DriverConfig) -> f32 {
        let i = self.driver_gain_a_per_v * (volts.volts() - driver.offset_v());
        i.max(0.0).min(self.max_current_a)
    }

    /// Steady-state rise (K) at a constant input — what the budget converges
    /// to if the coil is driven forever: `I² R · R_th`.
    pub fn steady_rise_k(&self, volts: DriveVolts, driver: &DriverConfig) -> f32 {
        let i = self.current_a(volts, driver);
        i * i * self.coil_resistance_ohm * self.time_constant_s / self.heat_capacity_j_per_k
    }
}

/// One coil's thermal state.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
struct CoilThermal {
    rise_k: f32,
    tripped: bool,
}

impl CoilThermal {
    /// Semi-implicit Euler for `C dT/dt = P − C T/τ`:
    /// `T' = (T + dt P/C)/(1 + dt/τ)`, stable for any dt ≥ 0.
    fn advance(&mut self, power_w: f32, dt_s: f32, cfg: &ThermalConfig) {
        let next = (self.rise_k + dt_s * power_w / cfg.heat_capacity_j_per_k)
            / (1.0 + dt_s / cfg.time_constant_s);
        // A non-finite update (cannot happen with validated inputs) is
        // treated as the hottest state: trip.
        self.rise_k = if next.is_finite() { next } else { f32::MAX };
        if self.rise_k >= cfg.trip_rise_k {
            self.tripped = true;
        } else if self.rise_k <= cfg.resume_rise_k {
            self.tripped = false;
        }
    }
}

/// Supervisor configuration.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SupervisorConfig {
    /// Thermal model and budget.
    pub thermal: ThermalConfig,
    /// Link-loss timeout; `None` when there is no link to watch.
    pub link_timeout: Option<Duration>,
}

impl Default for SupervisorConfig {
    /// Default thermal budget, no link watchdog.
    fn default() -> Self {
        Self {
            thermal: ThermalConfig::default(),
            link_timeout: None,
        }
    }
}

/// The HIL default link timeout: 50 ms of the firmware's own time.
pub const DEFAULT_LINK_TIMEOUT: Duration = Duration::from_millis(50);

/// What the supervisor let through, and why anything was removed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Supervised<const P: usize> {
    /// Commands to apply to the drivers.
    pub commands: [PairCommand; P],
    /// Every fault active or latched after this step.
    pub faults: Faults,
}

/// The supervisor for `P` antagonistic pairs.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Supervisor<const P: usize> {
    config: SupervisorConfig,
    coils: [[CoilThermal; 2]; P],
    latched: Faults,
    /// Faults seen on the most recent step (to decide whether clear() may
    /// succeed).
    present: Faults,
    last_link: Option<Instant>,
    armed: bool,
}

/// Why `clear` refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StillFaulted(pub Faults);

impl core::fmt::Display for Faults {
    /// The names of the set flags, comma-separated (`none` when empty).
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let mut first = true;
        for (flag, name) in Faults::NAMED {
            if self.contains(flag) {
                if !first {
                    f.write_str(",")?;
                }
                f.write_str(name)?;
                first = false;
            }
        }
        if first {
            f.write_str("none")?;
        }
        Ok(())
    }
}

impl core::fmt::Display for StillFaulted {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "cannot clear: the cause of {} is still present", self.0)
    }
}

impl core::error::Error for StillFaulted {}

impl<const P: usize> Supervisor<P> {
    /// A disarmed supervisor. An invalid thermal configuration is replaced
    /// by the default and reported as `INVALID_INPUT` (latched), so a bad
    /// parameter cannot silently disable the budget.
    pub fn new(config: SupervisorConfig) -> Self {
        let valid_link = config.link_timeout.is_none_or(|t| !t.is_zero());
        let valid = config.thermal.is_valid() && valid_link;
        let config = if valid {
            config
        } else {
            SupervisorConfig::default()
        };
        Self {
            config,
            coils: [[CoilThermal::default(); 2]; P],
            latched: if valid {
                Faults::NONE
            } else {
                Faults::INVALID_INPUT
            },
            present: Faults::NONE,
            last_link: None,
            armed: false,
        }
    }

    /// The configuration in force.
    pub fn config(&self) -> SupervisorConfig {
        self.config
    }

    /// Allows outputs (if no fault is latched).
    pub fn arm(&mut self) {
        self.armed = true;
    }

    /// Forces every output off (not a fault).
    pub fn disarm(&mut self) {
        self.armed = false;
    }

    /// True when armed.
    pub fn is_armed(&self) -> bool {
        self.armed
    }

    /// Faults latched so far.
    pub fn latched(&self) -> Faults {
        self.latched
    }

    /// Modelled temperature rise of coil `coil` (0/1) of pair `pair` (K).
    pub fn coil_rise_k(&self, pair: usize, coil: usize) -> Option<f32> {
        self.coils
            .get(pair)
            .and_then(|c| c.get(coil))
            .map(|c| c.rise_k)
    }

    /// Records that a valid frame arrived from the host at `now`.
    pub fn note_link_frame(&mut self, now: Instant) {
        self.last_link = Some(now);
    }

    /// Starts a new time base (e.g. entering lockstep): forgets which fault
    /// causes were present and when the link last spoke, since both refer
    /// to the old clock. Latched faults stay latched until [`Self::clear`];
    /// the thermal state is physical and is kept.
    pub fn restart_time_base(&mut self) {
        self.present = Faults::NONE;
        self.last_link = None;
    }

    /// Latches `faults` (from the estimator, the image, a driver error...).
    pub fn report(&mut self, faults: Faults) {
        let new = faults.intersection(Faults::LATCHING);
        if !new.is_empty() && !self.latched.contains(new) {
            log_warn!("fault latched: {=u16:#x}", new.bits());
        }
        self.latched |= new;
        self.present |= new;
    }

    /// Clears the latch if the faults seen on the last step have gone.
    pub fn clear(&mut self) -> Result<(), StillFaulted> {
        let still = self.present.intersection(Faults::LATCHING);
        if still.is_empty() {
            self.latched = Faults::NONE;
            Ok(())
        } else {
            Err(StillFaulted(still))
        }
    }

    /// Filters one step's commands. `faults` are the faults detected this
    /// step by the caller (sensors, inputs); `dt` the time since the last
    /// step, used for the thermal model.
    pub fn supervise(
        &mut self,
        now: Instant,
        dt: Duration,
        commands: [PairCommand; P],
        faults: Faults,
        driver: &DriverConfig,
    ) -> Supervised<P> {
        let mut want = [[DriveVolts::ZERO; 2]; P];
        for (w, c) in want.iter_mut().zip(commands.iter()) {
            *w = c.coil_drive();
        }
        let s = self.supervise_coils(now, dt, want, faults, driver);
        Supervised {
            commands: s.limit(commands),
            faults: s.faults,
        }
    }

    /// Filters one step's per-coil inputs (`[agonist, antagonist]` per
    /// pair), the board's open-loop drive mode where both coils of a pair
    /// may be heated. The same rules as [`Self::supervise`]: off unless
    /// armed and nothing is latched, every coil counted by its own thermal
    /// budget and held off while tripped. The inputs are bounded already
    /// ([`DriveVolts`]); the supervisor only removes drive.
    pub fn supervise_coils(
        &mut self,
        now: Instant,
        dt: Duration,
        want: [[DriveVolts; 2]; P],
        faults: Faults,
        driver: &DriverConfig,
    ) -> SupervisedCoils<P> {
        let mut present = faults;
        if let Some(timeout) = self.config.link_timeout {
            let lost = match self.last_link {
                Some(t) => now - t > timeout,
                None => false, // not yet started: disarmed until a frame comes
            };
            if lost {
                present |= Faults::LINK_LOSS;
            }
        }
        self.present = present.intersection(Faults::LATCHING);
        let new = present.intersection(Faults::LATCHING);
        if !new.is_empty() && !self.latched.contains(new) {
            log_warn!("fault latched: {=u16:#x}", new.bits());
        }
        self.latched |= new;

        let allowed = self.armed && self.latched.is_empty();
        let mut out = [[DriveVolts::ZERO; 2]; P];
        let mut over_budget = false;
        let dt = dt.as_secs_f32();
        let cfg = self.config.thermal;
        for ((slot, w), coils) in out.iter_mut().zip(want.iter()).zip(self.coils.iter_mut()) {
            for ((o, v), coil) in slot.iter_mut().zip(w.iter()).zip(coils.iter_mut()) {
                let mut v = if allowed && !coil.tripped {
                    *v
                } else {
                    DriveVolts::ZERO
                };
                // Heat for this step is counted with the drive as decided
                // above; a coil that trips during the step is cut in this
                // step's output too (conservative: its last dt of heat is
                // still counted).
                let i = cfg.current_a(v, driver);
                coil.advance(i * i * cfg.coil_resistance_ohm, dt, &cfg);
                if coil.tripped {
                    v = DriveVolts::ZERO;
                    over_budget = true;
                }
                *o = v;
            }
        }
        let mut reported = self.latched;
        if over_budget {
            reported |= Faults::OVER_BUDGET;
        }
        SupervisedCoils {
            coils: out,
            faults: reported,
            allowed,
        }
    }

    /// True when coil `coil` (0 = agonist, 1 = antagonist) of `pair` is
    /// held off to cool (its budget tripped and it has not cooled to the
    /// resume level).
    pub fn coil_tripped(&self, pair: usize, coil: usize) -> bool {
        self.coils
            .get(pair)
            .and_then(|c| c.get(coil))
            .is_some_and(|c| c.tripped)
    }
}

/// What [`Supervisor::supervise_coils`] let through.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SupervisedCoils<const P: usize> {
    /// Per pair, `[agonist, antagonist]` inputs to apply.
    pub coils: [[DriveVolts; 2]; P],
    /// Every fault active or latched after this step.
    pub faults: Faults,
    /// False when outputs were forced off (disarmed or a fault latched).
    pub allowed: bool,
}

impl<const P: usize> SupervisedCoils<P> {
    /// `commands` with whatever the supervisor removed removed: all `Off`
    /// when outputs were forced off, otherwise each coil the supervisor cut
    /// inhibited ([`PairCommand::limited_to`]). A plane whose command is
    /// `Off` (an open-loop driven one) stays `Off`.
    pub fn limit(&self, commands: [PairCommand; P]) -> [PairCommand; P] {
        let mut out = [PairCommand::Off; P];
        if self.allowed {
            for ((slot, cmd), got) in out.iter_mut().zip(commands.iter()).zip(self.coils.iter()) {
                *slot = cmd.limited_to(*got);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    /// The start times every time-dependent check is repeated at: boot, one
    /// second before a u32 millisecond counter wraps, 5 h, 30 days, 1 year.
    const UPTIMES: [Instant; 5] = [
        Instant::ZERO,
        Instant::from_millis(u32::MAX as u64 - 1000),
        Instant::from_secs(5 * 3600),
        Instant::from_secs(30 * 86_400),
        Instant::from_secs(365 * 86_400),
    ];

    fn armed() -> Supervisor<1> {
        let mut s = Supervisor::new(SupervisorConfig::default());
        s.arm();
        s
    }

    #[test]
    fn full_drive_trips_the_budget_and_cools_down() {
        let d = DriverConfig::default();
        let cfg = ThermalConfig::default();
        // Full drive: 0.5 A (clamped), 1.25 W, steady rise 195 K > trip.
        assert!(cfg.steady_rise_k(d.clamp(5.0), &d) > cfg.trip_rise_k);
        let full = [PairCommand::Agonist(d.clamp(5.0))];
        for t0 in UPTIMES {
            let mut s = armed();
            let mut k = 0u64;
            let at = |k: u64| t0 + MS.saturating_mul(k);
            let mut tripped_at = None;
            while k < 20_000 {
                let out = s.supervise(at(k), MS, full, Faults::NONE, &d);
                if out.faults.contains(Faults::OVER_BUDGET) {
                    tripped_at = Some(k);
                    assert_eq!(out.commands, [PairCommand::Off]);
                    break;
                }
                k += 1;
            }
            // Closed form of the first-order rise: T(t) = T∞(1 − e^(−t/τ))
            // hits 95 K at t = −τ ln(1 − 95/195.3) ≈ 3.34 s.
            let t_trip = tripped_at.expect("never tripped") as f32 * 1e-3;
            let expect = -cfg.time_constant_s
                * (1.0 - cfg.trip_rise_k / cfg.steady_rise_k(d.clamp(5.0), &d)).ln();
            assert!(
                (t_trip - expect).abs() < 0.02,
                "from {t0}: tripped at {t_trip}, expected {expect}"
            );
            // While cooling, still held off even though the command asks for
            // 5 V; the other coil of the pair is unaffected.
            let out = s.supervise(at(k + 100), MS, full, Faults::NONE, &d);
            assert_eq!(out.commands, [PairCommand::Off]);
            let other = s.supervise(
                at(k + 200),
                MS,
                [PairCommand::Antagonist(d.clamp(3.0))],
                Faults::NONE,
                &d,
            );
            assert_eq!(other.commands, [PairCommand::Antagonist(d.clamp(3.0))]);
            // Cool-down from 95 K to 45 K takes τ ln(95/45) ≈ 3.7 s.
            let mut resumed = None;
            let mut k2 = k + 200;
            while k2 < k + 20_000 {
                let out = s.supervise(at(k2), MS.saturating_mul(10), full, Faults::NONE, &d);
                if out.commands == full {
                    resumed = Some((k2 - k) as f32 * 1e-3);
                    break;
                }
                k2 += 10;
            }
            let resumed = resumed.expect("never resumed");
            assert!(
                resumed > 3.5 && resumed < 4.2,
                "from {t0}: resumed after {resumed} s"
            );
        }
    }

    #[test]
    fn every_latching_fault_zeroes_all_outputs_until_cleared() {
        let d = DriverConfig::default();
        for t0 in UPTIMES {
            for (fault, name) in Faults::NAMED {
                if !Faults::LATCHING.contains(fault) {
                    continue;
                }
                let at = |k: u64| t0 + MS.saturating_mul(k);
                let mut s: Supervisor<2> = Supervisor::new(SupervisorConfig::default());
                s.arm();
                let cmd = [
                    PairCommand::Agonist(d.clamp(3.0)),
                    PairCommand::Antagonist(d.clamp(2.0)),
                ];
                assert_eq!(s.supervise(at(0), MS, cmd, Faults::NONE, &d).commands, cmd);
                let out = s.supervise(at(1), MS, cmd, fault, &d);
                assert_eq!(
                    out.commands,
                    [PairCommand::Off; 2],
                    "{name} did not zero outputs"
                );
                assert!(out.faults.contains(fault), "{name} not reported");
                // The cause has gone, but the latch holds until cleared...
                let out = s.supervise(at(2), MS, cmd, Faults::NONE, &d);
                assert_eq!(out.commands, [PairCommand::Off; 2], "{name} did not latch");
                // ...and clearing succeeds now that the last step was clean.
                s.clear().unwrap();
                assert_eq!(s.supervise(at(3), MS, cmd, Faults::NONE, &d).commands, cmd);
            }
        }
    }

    #[test]
    fn clear_is_refused_while_the_cause_persists() {
        let d = DriverConfig::default();
        let mut s = armed();
        s.supervise(
            Instant::ZERO,
            MS,
            [PairCommand::Off],
            Faults::SENSOR_STALE,
            &d,
        );
        assert_eq!(s.clear(), Err(StillFaulted(Faults::SENSOR_STALE)));
    }

    #[test]
    fn link_loss_after_the_timeout_at_any_uptime() {
        let d = DriverConfig::default();
        for t0 in UPTIMES {
            let at = |k: u64| t0 + MS.saturating_mul(k);
            let mut s: Supervisor<1> = Supervisor::new(SupervisorConfig {
                link_timeout: Some(Duration::from_millis(50)),
                ..Default::default()
            });
            s.arm();
            let cmd = [PairCommand::Agonist(d.clamp(3.0))];
            s.note_link_frame(at(0));
            assert_eq!(s.supervise(at(50), MS, cmd, Faults::NONE, &d).commands, cmd);
            let out = s.supervise(at(51), MS, cmd, Faults::NONE, &d);
            assert_eq!(out.commands, [PairCommand::Off], "from {t0}");
            assert!(out.faults.contains(Faults::LINK_LOSS));
        }
    }

    #[test]
    fn disarmed_and_bad_config_mean_off() {
        let d = DriverConfig::default();
        let cmd = [PairCommand::Agonist(d.clamp(3.0))];
        let mut s: Supervisor<1> = Supervisor::new(SupervisorConfig::default());
        assert_eq!(
            s.supervise(Instant::ZERO, MS, cmd, Faults::NONE, &d)
                .commands,
            [PairCommand::Off]
        );
        let bad = SupervisorConfig {
            thermal: ThermalConfig {
                time_constant_s: f32::NAN,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut s: Supervisor<1> = Supervisor::new(bad);
        s.arm();
        let out = s.supervise(Instant::ZERO, MS, cmd, Faults::NONE, &d);
        assert_eq!(out.commands, [PairCommand::Off]);
        assert!(out.faults.contains(Faults::INVALID_INPUT));
        // A zero link timeout is not a usable watchdog either.
        let mut s: Supervisor<1> = Supervisor::new(SupervisorConfig {
            link_timeout: Some(Duration::ZERO),
            ..Default::default()
        });
        s.arm();
        assert!(s
            .supervise(Instant::ZERO, MS, cmd, Faults::NONE, &d)
            .faults
            .contains(Faults::INVALID_INPUT));
    }
}
