//! embedded-hal implementations backed by the plant models (simulated PWM
//! channels, wire sensors, clock), so the firmware core runs closed loop on
//! the host.
#![deny(unsafe_code)]
