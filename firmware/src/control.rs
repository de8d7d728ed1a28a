//! Antagonistic P(+I) control of SMA coil pairs (Shibata, Yoshimura, Hirai,
//! seed 000, last paper).
//!
//! The control input is the voltage at the ULN2003 driver's input, 0 V to
//! the supply, and `v_offset` (1.7 V for the paper's drivers) is the lowest
//! input at which the driver conducts. The paper's laws, with error
//! `e = θ − θd` and gain `Kp > 0`:
//!
//! - one actuator, visual feedback (Eq. 1): `v1 = −Kp e + v_offset`, `v2 = 0`
//!   ([`PairMode::SingleAgonist`]);
//! - antagonistic pair (2D, length feedback): `θ < θd` → `v1 = −Kp e +
//!   v_offset`, `v2 = 0`; `θ ≥ θd` → `v1 = 0`, `v2 = +Kp e + v_offset`
//!   ([`PairMode::Antagonistic`]). **Sign:** the paper prints `v2 = −Kp e +
//!   v_offset`, which would weaken coil 2 the further the link overshoots.
//!   Coil 2 must pull back harder the larger `e ≥ 0` is, so we use
//!   `+Kp e + v_offset` — the law the paper describes in words;
//! - 3D: two such pairs (α: coils 1/3, β: coils 2/4), independent SISO laws
//!   with a gain per actuator (see [`crate::joint`]).
//!
//! An SMA coil only contracts when heated, and heating both coils of a pair
//! fights itself and cooks them. [`PairCommand`] therefore has no value that
//! heats both: a pair is `Off`, heats its agonist, or heats its antagonist.
//! [`PairDriver`] turns a command into two `SetDutyCycle` outputs, always
//! switching the idle coil off before the other is driven.
//!
//! The integral term (the paper's "future work": it proposes I action but did
//! not try it because SMA is slow) is off by default (`ki = 0`). Its
//! anti-windup is conditional integration: the integrator does not grow
//! while the output is saturated in the direction of the error, and it is
//! clamped to a configurable magnitude.

use embedded_hal::pwm::SetDutyCycle;

/// Minimum driver input voltage that makes the ULN2003 conduct
/// (seed 000, last paper, Eq. 1: "1.7 V for our drivers").
pub const PAPER_V_OFFSET_V: f32 = 1.7;
/// The paper's driver input range is 0–5 V (seed 000, last paper, §II-C and
/// the 5 V open-loop and disturbance experiments).
pub const PAPER_SUPPLY_V: f32 = 5.0;

/// Why a controller parameter was rejected.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum ControlError {
    /// The supply voltage must be finite and > 0.
    SupplyNotPositive,
    /// `v_offset` must be finite and within [0, supply).
    OffsetOutOfRange,
    /// A proportional gain must be finite and > 0.
    ProportionalGainNotPositive,
    /// The integral gain must be finite and ≥ 0.
    IntegralGainNegative,
    /// The integral limit must be finite and ≥ 0.
    IntegralLimitNegative,
    /// A desired angle must be finite.
    TargetNotFinite,
}

impl core::fmt::Display for ControlError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            ControlError::SupplyNotPositive => "the supply voltage must be finite and > 0",
            ControlError::OffsetOutOfRange => "v_offset must be finite and within [0, supply)",
            ControlError::ProportionalGainNotPositive => {
                "a proportional gain must be finite and > 0"
            }
            ControlError::IntegralGainNegative => "the integral gain must be finite and >= 0",
            ControlError::IntegralLimitNegative => "the integral limit must be finite and >= 0",
            ControlError::TargetNotFinite => "a desired angle must be finite",
        })
    }
}

impl core::error::Error for ControlError {}

/// The driver's input range and conduction threshold.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriverConfig {
    offset_v: f32,
    supply_v: f32,
}

impl Default for DriverConfig {
    /// The paper's driver: 1.7 V offset, 5 V supply.
    fn default() -> Self {
        Self {
            offset_v: PAPER_V_OFFSET_V,
            supply_v: PAPER_SUPPLY_V,
        }
    }
}

impl DriverConfig {
    /// A driver with conduction threshold `offset_v` and maximum input
    /// `supply_v`.
    pub fn new(offset_v: f32, supply_v: f32) -> Result<Self, ControlError> {
        if !(supply_v.is_finite() && supply_v > 0.0) {
            return Err(ControlError::SupplyNotPositive);
        }
        if !(offset_v.is_finite() && (0.0..supply_v).contains(&offset_v)) {
            return Err(ControlError::OffsetOutOfRange);
        }
        Ok(Self { offset_v, supply_v })
    }

    /// Conduction threshold in volts.
    pub fn offset_v(&self) -> f32 {
        self.offset_v
    }

    /// Maximum driver input in volts.
    pub fn supply_v(&self) -> f32 {
        self.supply_v
    }

    /// Clamps a requested voltage into [0, supply]; NaN becomes 0 V (off).
    pub fn clamp(&self, volts: f32) -> DriveVolts {
        // `max`/`min` return the non-NaN operand, so NaN maps to 0.
        let v = if volts.is_nan() {
            0.0
        } else {
            volts.max(0.0).min(self.supply_v)
        };
        DriveVolts(v)
    }
}

/// A driver input voltage that is finite and within [0, supply]: only
/// [`DriverConfig::clamp`] makes one.
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveVolts(f32);

impl DriveVolts {
    /// 0 V.
    pub const ZERO: DriveVolts = DriveVolts(0.0);

    /// The voltage.
    pub fn volts(self) -> f32 {
        self.0
    }
}

/// What one antagonistic pair is told to do. There is no variant that heats
/// both coils: the pair rule holds by construction.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PairCommand {
    /// Both coils unpowered (the safe state).
    #[default]
    Off,
    /// Heat the agonist (coil 1 of the pair: raises the angle).
    Agonist(DriveVolts),
    /// Heat the antagonist (coil 2 of the pair: lowers the angle).
    Antagonist(DriveVolts),
}

impl PairCommand {
    /// Driver input voltages `[agonist, antagonist]`; at most one is non-zero.
    pub fn coil_volts(self) -> [f32; 2] {
        match self {
            PairCommand::Off => [0.0, 0.0],
            PairCommand::Agonist(v) => [v.volts(), 0.0],
            PairCommand::Antagonist(v) => [0.0, v.volts()],
        }
    }

    /// Driver inputs `[agonist, antagonist]` as bounded voltages; at most
    /// one is non-zero.
    pub fn coil_drive(self) -> [DriveVolts; 2] {
        match self {
            PairCommand::Off => [DriveVolts::ZERO; 2],
            PairCommand::Agonist(v) => [v, DriveVolts::ZERO],
            PairCommand::Antagonist(v) => [DriveVolts::ZERO, v],
        }
    }

    /// The command with every coil whose supervised input `got` differs
    /// from the command's own ([`Self::coil_drive`]) inhibited: how a
    /// supervisor's per-coil decision maps back onto a pair command.
    pub fn limited_to(self, got: [DriveVolts; 2]) -> PairCommand {
        let want = self.coil_drive();
        let mut c = self;
        for (k, (g, w)) in got.iter().zip(want.iter()).enumerate() {
            if g != w {
                c = c.inhibit(k);
            }
        }
        c
    }

    /// The same command with its voltage replaced by 0 V on `coil`
    /// (0 = agonist, 1 = antagonist), used by the supervisor to inhibit one
    /// coil without touching the other.
    pub fn inhibit(self, coil: usize) -> PairCommand {
        match (self, coil) {
            (PairCommand::Agonist(_), 0) | (PairCommand::Antagonist(_), 1) => PairCommand::Off,
            (other, _) => other,
        }
    }
}

/// How a pair uses its two coils.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PairMode {
    /// Eq. 1: only the agonist is driven; the antagonist is a bias spring.
    SingleAgonist,
    /// The antagonistic law: the side is chosen by the sign of the error.
    Antagonistic,
}

/// Gains of one pair.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PairGains {
    kp_agonist_v_per_deg: f32,
    kp_antagonist_v_per_deg: f32,
    ki_v_per_deg_s: f32,
    integral_limit_v: f32,
    v_offset_v: f32,
}

impl PairGains {
    /// Proportional gains per actuator (the paper's `K_P1..K_P4`), integral
    /// action off.
    pub fn proportional(
        kp_agonist_v_per_deg: f32,
        kp_antagonist_v_per_deg: f32,
    ) -> Result<Self, ControlError> {
        Self::new(kp_agonist_v_per_deg, kp_antagonist_v_per_deg, 0.0, 0.0)
    }

    /// Proportional gains plus an integral gain (V per deg·s) whose
    /// contribution is limited to ±`integral_limit_v`.
    pub fn new(
        kp_agonist_v_per_deg: f32,
        kp_antagonist_v_per_deg: f32,
        ki_v_per_deg_s: f32,
        integral_limit_v: f32,
    ) -> Result<Self, ControlError> {
        let kp_ok = |k: f32| k.is_finite() && k > 0.0;
        if !kp_ok(kp_agonist_v_per_deg) || !kp_ok(kp_antagonist_v_per_deg) {
            return Err(ControlError::ProportionalGainNotPositive);
        }
        if !(ki_v_per_deg_s.is_finite() && ki_v_per_deg_s >= 0.0) {
            return Err(ControlError::IntegralGainNegative);
        }
        if !(integral_limit_v.is_finite() && integral_limit_v >= 0.0) {
            return Err(ControlError::IntegralLimitNegative);
        }
        Ok(Self {
            kp_agonist_v_per_deg,
            kp_antagonist_v_per_deg,
            ki_v_per_deg_s,
            integral_limit_v,
            v_offset_v: PAPER_V_OFFSET_V,
        })
    }

    /// The same gains with the law's `v_offset` (V): the input at zero
    /// effort, the paper's 1.7 V (its drivers' conduction threshold) by
    /// default. Must be finite and ≥ 0; the joint also requires it below
    /// the driver's supply ([`crate::joint::JointController::set_gains`]).
    /// A tuned value need not equal the driver's threshold (the thermal
    /// budget keeps using the driver's, the physical one).
    pub fn with_v_offset(self, v_offset_v: f32) -> Result<Self, ControlError> {
        if !(v_offset_v.is_finite() && v_offset_v >= 0.0) {
            return Err(ControlError::OffsetOutOfRange);
        }
        Ok(Self { v_offset_v, ..self })
    }

    /// Agonist proportional gain (V/deg).
    pub fn kp_agonist(&self) -> f32 {
        self.kp_agonist_v_per_deg
    }
    /// Antagonist proportional gain (V/deg).
    pub fn kp_antagonist(&self) -> f32 {
        self.kp_antagonist_v_per_deg
    }
    /// Integral gain (V/(deg·s)).
    pub fn ki(&self) -> f32 {
        self.ki_v_per_deg_s
    }
    /// Integral limit (V).
    pub fn integral_limit_v(&self) -> f32 {
        self.integral_limit_v
    }
    /// The law's `v_offset` (V).
    pub fn v_offset_v(&self) -> f32 {
        self.v_offset_v
    }
}

impl Default for PairGains {
    /// `Kp = 2.0` V/deg on both coils, the paper's higher gain (Fig. 7, 9).
    fn default() -> Self {
        Self {
            kp_agonist_v_per_deg: 2.0,
            kp_antagonist_v_per_deg: 2.0,
            ki_v_per_deg_s: 0.0,
            integral_limit_v: 0.0,
            v_offset_v: PAPER_V_OFFSET_V,
        }
    }
}

/// The P(+I) law for one pair, with its integrator state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PairController {
    gains: PairGains,
    mode: PairMode,
    integral_v: f32,
}

impl PairController {
    /// A controller with the given gains and mode, integrator empty.
    pub fn new(gains: PairGains, mode: PairMode) -> Self {
        Self {
            gains,
            mode,
            integral_v: 0.0,
        }
    }

    /// Current gains.
    pub fn gains(&self) -> PairGains {
        self.gains
    }

    /// Replaces the gains (the integrator is kept, clamped to the new limit).
    pub fn set_gains(&mut self, gains: PairGains) {
        self.gains = gains;
        let lim = gains.integral_limit_v;
        self.integral_v = self.integral_v.clamp(-lim, lim);
    }

    /// The pair's mode.
    pub fn mode(&self) -> PairMode {
        self.mode
    }

    /// The integrator's contribution in volts (signed: + drives the agonist).
    pub fn integral_v(&self) -> f32 {
        self.integral_v
    }

    /// Empties the integrator (on arming, or after a fault).
    pub fn reset(&mut self) {
        self.integral_v = 0.0;
    }

    /// One control update. `angle_deg` is the measured or estimated angle,
    /// `desired_deg` the target, `dt_s` the time since the previous update.
    /// Non-finite inputs give `PairCommand::Off` and leave the integrator
    /// unchanged.
    pub fn update(
        &mut self,
        driver: &DriverConfig,
        angle_deg: f32,
        desired_deg: f32,
        dt_s: f32,
    ) -> PairCommand {
        let err_deg = desired_deg - angle_deg; // = −(θ − θd)
        if !err_deg.is_finite() || !dt_s.is_finite() || dt_s < 0.0 {
            return PairCommand::Off;
        }
        let g = &self.gains;
        let offset = g.v_offset_v;
        // Signed effort in volts above the offset: > 0 heats the agonist.
        let proportional = match self.mode {
            PairMode::SingleAgonist => g.kp_agonist_v_per_deg * err_deg,
            PairMode::Antagonistic if err_deg > 0.0 => g.kp_agonist_v_per_deg * err_deg,
            PairMode::Antagonistic => g.kp_antagonist_v_per_deg * err_deg,
        };
        if g.ki_v_per_deg_s > 0.0 {
            let headroom = driver.supply_v() - offset;
            let effort = proportional + self.integral_v;
            // Conditional integration: do not wind further into saturation.
            let saturated_high = effort >= headroom && err_deg > 0.0;
            let saturated_low = match self.mode {
                PairMode::Antagonistic => effort <= -headroom && err_deg < 0.0,
                // A single actuator cannot push back: its low saturation is
                // the point where the input stops conducting.
                PairMode::SingleAgonist => effort <= -offset && err_deg < 0.0,
            };
            if !saturated_high && !saturated_low {
                let lim = g.integral_limit_v;
                let next = self.integral_v + g.ki_v_per_deg_s * err_deg * dt_s;
                if next.is_finite() {
                    self.integral_v = next.clamp(-lim, lim);
                }
            }
        }
        let effort = proportional + self.integral_v;
        match self.mode {
            PairMode::SingleAgonist => PairCommand::Agonist(driver.clamp(effort + offset)),
            // Paper: θ < θd heats coil 1; θ ≥ θd heats coil 2 (with the
            // corrected sign: the antagonist's voltage grows with θ − θd).
            PairMode::Antagonistic if effort > 0.0 => {
                PairCommand::Agonist(driver.clamp(effort + offset))
            }
            PairMode::Antagonistic => PairCommand::Antagonist(driver.clamp(-effort + offset)),
        }
    }
}

/// Converts a driver input voltage to a duty cycle of `max_duty`, assuming
/// the channel produces `supply_v · duty/max_duty` at the driver input
/// (filtered PWM or a DAC scaled to the supply). Rounds to nearest and never
/// exceeds `max_duty`.
pub fn volts_to_duty(volts: DriveVolts, driver: &DriverConfig, max_duty: u16) -> u16 {
    let fraction = volts.volts() / driver.supply_v();
    let duty = fraction * f32::from(max_duty) + 0.5;
    if duty.is_nan() || duty <= 0.0 {
        0
    } else if duty >= f32::from(max_duty) {
        max_duty
    } else {
        duty as u16
    }
}

/// The two PWM channels of one antagonistic pair. Applying a command always
/// sets the coil that must be idle to 0 first, so even between the two
/// writes both coils are never on together; if that write fails the other
/// coil is not driven.
pub struct PairDriver<A, B> {
    agonist: A,
    antagonist: B,
}

/// Which channel of a pair failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PairDriverError<EA, EB> {
    /// The agonist channel's error.
    Agonist(EA),
    /// The antagonist channel's error.
    Antagonist(EB),
}

impl<EA: embedded_hal::pwm::Error, EB: embedded_hal::pwm::Error> core::fmt::Display
    for PairDriverError<EA, EB>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PairDriverError::Agonist(e) => write!(f, "agonist channel: {}", e.kind()),
            PairDriverError::Antagonist(e) => write!(f, "antagonist channel: {}", e.kind()),
        }
    }
}

impl<EA: embedded_hal::pwm::Error, EB: embedded_hal::pwm::Error> core::error::Error
    for PairDriverError<EA, EB>
{
}

impl<A: SetDutyCycle, B: SetDutyCycle> PairDriver<A, B> {
    /// Wraps the two channels.
    pub fn new(agonist: A, antagonist: B) -> Self {
        Self {
            agonist,
            antagonist,
        }
    }

    /// Gives the channels back.
    pub fn release(self) -> (A, B) {
        (self.agonist, self.antagonist)
    }

    /// Drives the pair. Duties scale with each channel's own maximum.
    pub fn apply(
        &mut self,
        command: PairCommand,
        driver: &DriverConfig,
    ) -> Result<(), PairDriverError<A::Error, B::Error>> {
        self.apply_coils(command.coil_drive(), driver)
    }

    /// Drives each coil of the pair with its own input `[agonist,
    /// antagonist]` — the board's output in every mode. Both may be
    /// non-zero only where the caller allows co-contraction (the board's
    /// open-loop drive mode, see [`crate::app`]); a [`PairCommand`]'s
    /// [`coil_drive`](PairCommand::coil_drive) never has both. Coils going
    /// to 0 V are written first, so a coil that must be idle is off before
    /// the other is driven; if such a write fails nothing is driven.
    pub fn apply_coils(
        &mut self,
        volts: [DriveVolts; 2],
        driver: &DriverConfig,
    ) -> Result<(), PairDriverError<A::Error, B::Error>> {
        let [ag, ant] = volts;
        if ag.volts() <= 0.0 {
            self.agonist
                .set_duty_cycle_fully_off()
                .map_err(PairDriverError::Agonist)?;
        }
        if ant.volts() <= 0.0 {
            self.antagonist
                .set_duty_cycle_fully_off()
                .map_err(PairDriverError::Antagonist)?;
        }
        if ag.volts() > 0.0 {
            let duty = volts_to_duty(ag, driver, self.agonist.max_duty_cycle());
            self.agonist
                .set_duty_cycle(duty)
                .map_err(PairDriverError::Agonist)?;
        }
        if ant.volts() > 0.0 {
            let duty = volts_to_duty(ant, driver, self.antagonist.max_duty_cycle());
            self.antagonist
                .set_duty_cycle(duty)
                .map_err(PairDriverError::Antagonist)?;
        }
        Ok(())
    }

    /// Both coils off (the safe state). Tries both channels even if the
    /// first fails, and reports the first error.
    pub fn all_off(&mut self) -> Result<(), PairDriverError<A::Error, B::Error>> {
        let a = self
            .agonist
            .set_duty_cycle_fully_off()
            .map_err(PairDriverError::Agonist);
        let b = self
            .antagonist
            .set_duty_cycle_fully_off()
            .map_err(PairDriverError::Antagonist);
        a.and(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn paper() -> DriverConfig {
        DriverConfig::default()
    }

    #[test]
    fn single_actuator_follows_eq1() {
        let mut c = PairController::new(
            PairGains::proportional(0.05, 0.05).unwrap(),
            PairMode::SingleAgonist,
        );
        // θ = 10°, θd = 20°: v1 = −0.05(10 − 20) + 1.7 = 2.2 V, v2 = 0.
        let cmd = c.update(&paper(), 10.0, 20.0, 0.001);
        let [v1, v2] = cmd.coil_volts();
        assert!((v1 - 2.2).abs() < 1e-6, "v1 = {v1}");
        assert_eq!(v2, 0.0);
        // Above the target the drive falls below the conduction threshold
        // and is clamped at 0 V far above it.
        let [v1, _] = c.update(&paper(), 25.0, 20.0, 0.001).coil_volts();
        assert!((v1 - 1.45).abs() < 1e-6, "v1 = {v1}");
        let [v1, _] = c.update(&paper(), 80.0, 20.0, 0.001).coil_volts();
        assert_eq!(v1, 0.0);
    }

    #[test]
    fn antagonist_pulls_back_harder_the_further_it_overshoots() {
        let mut c = PairController::new(
            PairGains::proportional(2.0, 1.0).unwrap(),
            PairMode::Antagonistic,
        );
        let below = c.update(&paper(), 4.0, 5.0, 0.001);
        assert_eq!(below, PairCommand::Agonist(paper().clamp(2.0 * 1.0 + 1.7)));
        let at = c.update(&paper(), 5.0, 5.0, 0.001);
        assert_eq!(
            at,
            PairCommand::Antagonist(paper().clamp(1.7)),
            "θ ≥ θd selects coil 2"
        );
        let small = c.update(&paper(), 5.5, 5.0, 0.001).coil_volts()[1];
        let large = c.update(&paper(), 6.5, 5.0, 0.001).coil_volts()[1];
        assert!(
            (small - 2.2).abs() < 1e-6 && (large - 3.2).abs() < 1e-6,
            "{small} {large}"
        );
        // Saturates at the supply.
        assert_eq!(c.update(&paper(), 60.0, 5.0, 0.001).coil_volts()[1], 5.0);
    }

    #[test]
    fn non_finite_inputs_switch_the_pair_off() {
        let mut c = PairController::new(PairGains::default(), PairMode::Antagonistic);
        assert_eq!(c.update(&paper(), f32::NAN, 5.0, 0.001), PairCommand::Off);
        assert_eq!(
            c.update(&paper(), 1.0, f32::INFINITY, 0.001),
            PairCommand::Off
        );
        assert_eq!(c.update(&paper(), 1.0, 5.0, f32::NAN), PairCommand::Off);
        assert_eq!(c.update(&paper(), 1.0, 5.0, -1.0), PairCommand::Off);
    }

    #[test]
    fn integrator_is_bounded_and_does_not_wind_up_in_saturation() {
        let gains = PairGains::new(2.0, 2.0, 1.0, 1.5).unwrap();
        let mut c = PairController::new(gains, PairMode::Antagonistic);
        // A small persistent error integrates up to the limit, not beyond.
        for _ in 0..10_000 {
            c.update(&paper(), 4.9, 5.0, 0.01);
        }
        assert!(
            (c.integral_v() - 1.5).abs() < 1e-6,
            "integral {}",
            c.integral_v()
        );
        // A huge error saturates the output: the integrator must not move.
        let mut c = PairController::new(gains, PairMode::Antagonistic);
        for _ in 0..1000 {
            c.update(&paper(), -30.0, 5.0, 0.01);
        }
        assert_eq!(c.integral_v(), 0.0, "integrated while saturated");
    }

    #[test]
    fn invalid_parameters_are_named() {
        assert_eq!(
            DriverConfig::new(1.7, f32::NAN),
            Err(ControlError::SupplyNotPositive)
        );
        assert_eq!(
            DriverConfig::new(6.0, 5.0),
            Err(ControlError::OffsetOutOfRange)
        );
        assert_eq!(
            PairGains::proportional(0.0, 1.0),
            Err(ControlError::ProportionalGainNotPositive)
        );
        assert_eq!(
            PairGains::new(1.0, 1.0, -1.0, 1.0),
            Err(ControlError::IntegralGainNegative)
        );
        assert_eq!(
            PairGains::new(1.0, 1.0, 1.0, f32::NAN),
            Err(ControlError::IntegralLimitNegative)
        );
    }

    #[test]
    fn duty_cycle_scales_and_saturates() {
        let d = paper();
        assert_eq!(volts_to_duty(d.clamp(2.5), &d, 1000), 500);
        assert_eq!(volts_to_duty(d.clamp(5.0), &d, 1000), 1000);
        assert_eq!(volts_to_duty(d.clamp(0.0), &d, 1000), 0);
        assert_eq!(volts_to_duty(d.clamp(9.0), &d, u16::MAX), u16::MAX);
        assert_eq!(volts_to_duty(d.clamp(f32::NAN), &d, 1000), 0);
    }

    /// A PWM channel that records every write into a shared log, so the
    /// order of writes across two channels can be checked.
    struct LoggingPwm<'a> {
        id: u8,
        log: &'a core::cell::RefCell<std::vec::Vec<(u8, u16)>>,
    }
    impl embedded_hal::pwm::ErrorType for LoggingPwm<'_> {
        type Error = core::convert::Infallible;
    }
    impl SetDutyCycle for LoggingPwm<'_> {
        fn max_duty_cycle(&self) -> u16 {
            1000
        }
        fn set_duty_cycle(&mut self, duty: u16) -> Result<(), Self::Error> {
            self.log.borrow_mut().push((self.id, duty));
            Ok(())
        }
    }

    #[test]
    fn driver_switches_the_idle_coil_off_before_driving_the_other() {
        let log = core::cell::RefCell::new(std::vec::Vec::new());
        let mut pair = PairDriver::new(
            LoggingPwm { id: 1, log: &log },
            LoggingPwm { id: 2, log: &log },
        );
        let d = paper();
        pair.apply(PairCommand::Agonist(d.clamp(5.0)), &d).unwrap();
        pair.apply(PairCommand::Antagonist(d.clamp(2.5)), &d)
            .unwrap();
        pair.apply(PairCommand::Off, &d).unwrap();
        assert_eq!(
            *log.borrow(),
            vec![(2, 0), (1, 1000), (1, 0), (2, 500), (1, 0), (2, 0)]
        );
        // Replaying the log, never both channels above zero at any instant.
        let mut state = [0u16; 2];
        for (id, duty) in log.borrow().iter() {
            state[usize::from(*id - 1)] = *duty;
            assert!(state[0] == 0 || state[1] == 0, "both coils on: {state:?}");
        }
    }
}
