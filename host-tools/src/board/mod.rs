//! A board as the controller: the serial link (real port, QEMU socket,
//! pty), the lockstep controller, hardware-in-the-loop runs, QEMU's life
//! and death, and the pty board of the tests.
pub mod conform;
pub mod controller;
pub mod hil;
pub mod link;
pub mod pty;
pub mod qemu;
pub mod seeded;
