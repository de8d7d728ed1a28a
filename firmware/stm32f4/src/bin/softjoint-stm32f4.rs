//! The board image for a Nucleo-F446RE: `cargo run --release --bin
//! softjoint-stm32f4` (in firmware/stm32f4) flashes it with probe-rs.
#![no_std]
#![no_main]

softjoint_stm32f4::image!(softjoint_stm32f4::Nucleo);
