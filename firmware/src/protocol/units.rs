//! Physical quantities in their wire units: driver inputs in signed
//! millivolts per pair, angles in centidegrees, faults in one byte.

use crate::control::{DriveVolts, DriverConfig, PairCommand};
use crate::supervisor::Faults;

/// Encodes a pair command as signed millivolts (+ agonist, − antagonist).
/// Uses the same rounding as a PWM channel whose full scale is the supply in
/// millivolts ([`volts_to_duty`](crate::control::volts_to_duty)), so a
/// simulator driving such a channel and a host receiving these frames see
/// identical values.
pub fn pair_to_mv(cmd: PairCommand, driver: &DriverConfig) -> i16 {
    let mv = |v| i16::try_from(coil_to_mv(v, driver)).unwrap_or(i16::MAX);
    match cmd {
        PairCommand::Off => 0,
        PairCommand::Agonist(v) => mv(v),
        PairCommand::Antagonist(v) => -mv(v),
    }
}

/// One coil's driver input as unsigned millivolts, with [`pair_to_mv`]'s
/// rounding (a millivolt PWM channel's duty).
pub fn coil_to_mv(v: DriveVolts, driver: &DriverConfig) -> u16 {
    crate::control::volts_to_duty(v, driver, millivolt_full_scale(driver))
}

/// A coil input from the wire (mV) as a bounded voltage; `None` above the
/// supply (the request is out of range, not silently clamped).
pub fn mv_to_coil(mv: u16, driver: &DriverConfig) -> Option<DriveVolts> {
    (mv <= millivolt_full_scale(driver)).then(|| driver.clamp(f32::from(mv) / 1000.0))
}

/// The supply in millivolts, as a duty-cycle full scale (saturating).
pub fn millivolt_full_scale(driver: &DriverConfig) -> u16 {
    let mv = num_traits::Float::round(driver.supply_v() * 1000.0);
    if mv >= f32::from(i16::MAX) {
        i16::MAX as u16
    } else if mv >= 1.0 {
        mv as u16
    } else {
        1
    }
}

/// Decodes signed millivolts into a pair command, clamped to the driver.
pub fn mv_to_pair(mv: i16, driver: &DriverConfig) -> PairCommand {
    let v = f32::from(mv) / 1000.0;
    match mv {
        0 => PairCommand::Off,
        m if m > 0 => PairCommand::Agonist(driver.clamp(v)),
        _ => PairCommand::Antagonist(driver.clamp(-v)),
    }
}

/// The driver input (V) of a channel set to `mv` millivolts: what a PWM
/// channel whose full scale is the supply in millivolts produces (host
/// side, in f64; the simulator's channels use exactly this).
pub fn millivolts_to_volts(mv: u16) -> f64 {
    f64::from(mv) / 1000.0
}

/// Signed pair millivolts from the wire to driver input volts per coil
/// `[agonist, antagonist]`: the same values a millivolt PWM channel set by
/// [`pair_to_mv`]'s rounding produces (at most the supply; the idle coil
/// at 0).
pub fn mv_to_coil_volts(mv: i16, driver: &DriverConfig) -> [f64; 2] {
    let full_scale = millivolt_full_scale(driver);
    let v = millivolts_to_volts(mv.unsigned_abs().min(full_scale));
    match mv {
        0 => [0.0, 0.0],
        m if m > 0 => [v, 0.0],
        _ => [0.0, v],
    }
}

/// Angle in centidegrees for the wire (`i16::MIN` for NaN; saturating).
pub fn deg_to_cdeg(deg: f32) -> i16 {
    if deg.is_nan() {
        return i16::MIN;
    }
    let c = num_traits::Float::round(deg * 100.0);
    if c >= f32::from(i16::MAX) {
        i16::MAX
    } else if c <= f32::from(i16::MIN + 1) {
        i16::MIN + 1
    } else {
        c as i16
    }
}

/// Centidegrees from the wire to degrees (NaN for `i16::MIN`).
pub fn cdeg_to_deg(c: i16) -> f32 {
    if c == i16::MIN {
        f32::NAN
    } else {
        f32::from(c) / 100.0
    }
}

/// Fault flags to their wire byte (all defined flags fit in 8 bits).
pub fn faults_to_u8(f: Faults) -> u8 {
    (f.bits() & 0xFF) as u8
}
