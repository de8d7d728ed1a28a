//! Simulated devices: PWM channels, pulse coders, a clock.

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use embedded_hal::pwm::{ErrorKind, ErrorType, SetDutyCycle};
use firmware::control::DriverConfig;
use firmware::protocol::{millivolt_full_scale, millivolts_to_volts};
use firmware::sensor::{WireSensor, WireSensorError};
use firmware::time::{Duration, Instant};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

/// Simulated time, shared by the parts of one simulation (nanoseconds
/// internally, so `DelayNs` keeps its resolution).
#[derive(Clone, Debug, Default)]
pub struct SimClock(Rc<Cell<u64>>);

impl SimClock {
    /// A clock at the epoch.
    pub fn new() -> Self {
        Self::default()
    }
    /// Current time.
    pub fn now(&self) -> Instant {
        Instant::from_micros(self.0.get() / 1000)
    }
    /// Moves time forward by `d` (saturating).
    pub fn advance(&self, d: Duration) {
        self.advance_ns(d.as_micros().saturating_mul(1000));
    }
    fn advance_ns(&self, ns: u64) {
        self.0.set(self.0.get().saturating_add(ns));
    }
}

/// `DelayNs` that advances a [`SimClock`] instead of spinning.
#[derive(Clone, Debug)]
pub struct SimDelay(pub SimClock);

impl embedded_hal::delay::DelayNs for SimDelay {
    fn delay_ns(&mut self, ns: u32) {
        self.0.advance_ns(u64::from(ns));
    }
}

/// An injected coil or channel fault.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CoilFault {
    /// The coil is disconnected: duty is accepted, no current flows.
    Open,
    /// The PWM channel reports an error on every write.
    ChannelError,
}

/// Error of a failing simulated PWM channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PwmFailure;

impl embedded_hal::pwm::Error for PwmFailure {
    fn kind(&self) -> ErrorKind {
        ErrorKind::Other
    }
}

#[derive(Debug, Default)]
struct PwmState {
    duty: Cell<u16>,
    /// The driver input (V) for `duty`, computed when the duty is written:
    /// the plant reads it every period, the controller writes it less often.
    volts: Cell<f64>,
    fault: Cell<Option<CoilFault>>,
}

/// One simulated SMA driver channel. Clones share the channel, so a test can
/// keep a handle while the controller owns the writer.
#[derive(Clone, Debug)]
pub struct SimPwm {
    state: Rc<PwmState>,
    max_duty: u16,
}

impl SimPwm {
    /// A channel whose full scale is the driver supply in millivolts.
    pub fn for_driver(driver: &DriverConfig) -> Self {
        Self {
            state: Rc::default(),
            max_duty: millivolt_full_scale(driver),
        }
    }
    /// Duty as last written.
    pub fn duty(&self) -> u16 {
        self.state.duty.get()
    }
    /// The voltage the driver input sees (0 with an open coil).
    pub fn coil_input_volts(&self) -> f64 {
        match self.state.fault.get() {
            Some(CoilFault::Open) => 0.0,
            _ => self.state.volts.get(),
        }
    }
    /// Injects or clears a fault.
    pub fn set_fault(&self, fault: Option<CoilFault>) {
        self.state.fault.set(fault);
    }
}

impl ErrorType for SimPwm {
    type Error = PwmFailure;
}

impl SetDutyCycle for SimPwm {
    fn max_duty_cycle(&self) -> u16 {
        self.max_duty
    }
    fn set_duty_cycle(&mut self, duty: u16) -> Result<(), PwmFailure> {
        if self.state.fault.get() == Some(CoilFault::ChannelError) {
            return Err(PwmFailure);
        }
        let duty = duty.min(self.max_duty);
        if duty != self.state.duty.get() {
            self.state.duty.set(duty);
            // The full scale is the supply in millivolts: duty = mV.
            self.state.volts.set(millivolts_to_volts(duty));
        }
        Ok(())
    }
}

/// An injected wire-sensor fault.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensorFault {
    /// The count freezes at its value when the fault starts.
    Stuck,
    /// An extra lag of this many mm on top of the plant's own jamming.
    Jammed {
        /// Extra lag (mm).
        extra_mm: f64,
    },
    /// Each read fails (`NotReady`) with this probability (seeded).
    Dropout {
        /// Probability per read, 0..=1.
        probability: f64,
    },
    /// The coder is dead: every read is a `Fault`.
    Dead,
}

#[derive(Debug)]
struct SensorState {
    counts: Cell<i64>,
    mm_per_count: f64,
    fault: Cell<Option<SensorFault>>,
    stuck_at: Cell<Option<i64>>,
    rng: RefCell<ChaCha8Rng>,
}

/// One simulated pulse coder; clones share it.
#[derive(Clone, Debug)]
pub struct SimWireSensor(Rc<SensorState>);

impl SimWireSensor {
    /// A coder with the plant's resolution; `rng` draws its dropouts.
    pub fn new(mm_per_count: f64, rng: ChaCha8Rng) -> Self {
        Self(Rc::new(SensorState {
            counts: Cell::new(0),
            mm_per_count,
            fault: Cell::new(None),
            stuck_at: Cell::new(None),
            rng: RefCell::new(rng),
        }))
    }
    /// Sets the plant's current count.
    pub fn set_plant_counts(&self, counts: i64) {
        self.0.counts.set(counts);
    }
    /// Injects or clears a fault.
    pub fn set_fault(&self, fault: Option<SensorFault>) {
        self.0.stuck_at.set(match fault {
            Some(SensorFault::Stuck) => Some(self.0.counts.get()),
            _ => None,
        });
        self.0.fault.set(fault);
    }
}

impl WireSensor for SimWireSensor {
    fn read_counts(&mut self) -> Result<i32, WireSensorError> {
        let s = &self.0;
        let counts = match s.fault.get() {
            None => s.counts.get(),
            Some(SensorFault::Stuck) => s.stuck_at.get().unwrap_or(s.counts.get()),
            Some(SensorFault::Jammed { extra_mm }) => {
                s.counts.get() - (extra_mm / s.mm_per_count).round() as i64
            }
            Some(SensorFault::Dropout { probability }) => {
                if s.rng.borrow_mut().gen_bool(probability.clamp(0.0, 1.0)) {
                    return Err(WireSensorError::NotReady);
                }
                s.counts.get()
            }
            Some(SensorFault::Dead) => return Err(WireSensorError::Fault),
        };
        i32::try_from(counts).map_err(|_| WireSensorError::Fault)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use embedded_hal::delay::DelayNs;
    use rand::SeedableRng;

    #[test]
    fn pwm_counts_millivolts_and_faults_bite() {
        let d = DriverConfig::default();
        let mut p = SimPwm::for_driver(&d);
        assert_eq!(p.max_duty_cycle(), 5000);
        p.set_duty_cycle(3200).unwrap();
        assert!((p.coil_input_volts() - 3.2).abs() < 1e-12);
        p.set_fault(Some(CoilFault::Open));
        assert_eq!(p.coil_input_volts(), 0.0);
        p.set_fault(Some(CoilFault::ChannelError));
        assert_eq!(p.set_duty_cycle(1), Err(PwmFailure));
    }

    #[test]
    fn sensor_faults_behave_as_named() {
        let mut s = SimWireSensor::new(0.01, ChaCha8Rng::seed_from_u64(7));
        s.set_plant_counts(120);
        assert_eq!(s.read_counts(), Ok(120));
        s.set_fault(Some(SensorFault::Stuck));
        s.set_plant_counts(300);
        assert_eq!(s.read_counts(), Ok(120));
        s.set_fault(Some(SensorFault::Jammed { extra_mm: 0.5 }));
        assert_eq!(s.read_counts(), Ok(250));
        s.set_fault(Some(SensorFault::Dead));
        assert_eq!(s.read_counts(), Err(WireSensorError::Fault));
        s.set_fault(Some(SensorFault::Dropout { probability: 0.5 }));
        let dropped = (0..1000).filter(|_| s.read_counts().is_err()).count();
        assert!(
            (400..600).contains(&dropped),
            "{dropped} of 1000 dropped at p = 0.5"
        );
    }

    #[test]
    fn delay_advances_simulated_time_only() {
        let clock = SimClock::new();
        let mut d = SimDelay(clock.clone());
        d.delay_ms(3);
        d.delay_us(500);
        for _ in 0..1000 {
            d.delay_ns(250); // sub-microsecond delays still add up
        }
        assert_eq!(clock.now(), Instant::from_micros(3750));
    }
}
