//! The same board image for QEMU's netduinoplus2 (no clock setup, no timer
//! I/O): what `softjoint hil --board stm32f4` runs.
#![no_std]
#![no_main]

softjoint_stm32f4::image!(softjoint_stm32f4::Qemu);
