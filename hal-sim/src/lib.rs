//! embedded-hal implementations backed by the plant models, and the one
//! closed loop every run of the joint goes through.
//!
//! - [`SimPwm`]: one SMA driver channel (`embedded_hal::pwm::SetDutyCycle`).
//!   Its full scale is the supply in millivolts, so one duty count is 1 mV
//!   at the driver input — the resolution the serial protocol carries, which
//!   makes the simulator and the hardware-in-the-loop link see identical
//!   voltages.
//! - [`SimWireSensor`]: one pulse coder (the core's `WireSensor` trait).
//! - [`SimClock`] and [`SimDelay`] (`embedded_hal::delay::DelayNs`): simulated
//!   time that only moves when the simulation says so.
//! - [`Plant`]: what the loop needs of a plant; implemented for the joints of
//!   `plant-models`.
//! - [`Controller`]: what the loop needs of a controller, wherever it runs.
//!   [`CoreController`] is the firmware core in process, driving [`SimPwm`]
//!   channels and reading [`SimWireSensor`]s; `host-tools` implements it for
//!   a board (QEMU, a serial port, the pty board) behind the lockstep link.
//! - [`ClosedLoop`]: plant ⇄ controller at a fixed control period, with a
//!   [`Schedule`] of targets and disturbances. As in PX4, where one
//!   simulator serves software- and hardware-in-the-loop and only the
//!   transport differs, `softjoint sim` and `softjoint hil` both run this
//!   loop; only the controller differs.
//!
//! Fault injection ([`SensorFault`], [`CoilFault`]): stuck and jammed
//! sensors, dropped samples (seeded), dead sensors, open coils, failing PWM
//! channels. Everything is deterministic.

mod closed_loop;
mod core_controller;
mod devices;
pub mod plants;

pub use closed_loop::{
    Actuation, ClosedLoop, Controller, Hold, LoopError, Readings, Sample, Schedule,
};
pub use core_controller::{CoreController, FeedbackSource};
pub use devices::{CoilFault, PwmFailure, SensorFault, SimClock, SimDelay, SimPwm, SimWireSensor};
pub use plants::{Loads, Plant};

/// The coil numbering is the firmware's (it defines the protocol's coil
/// order): the simulator's coil arrays follow it.
pub use firmware::joint::{coil_index, pairs_to_coils};
