//! Link setup for the step probe on another core: the memory map of the
//! QEMU machine that runs it, on the linker search path as `memory.x`, and
//! cortex-m-rt's `link.x`; `probe_machine` tells the probe the machine's
//! clock. Maps from QEMU's machine models: hw/arm/mps2.c (AN385: the
//! AN386's map, as the root memory.x), hw/arm/mps2-tz.c (AN505: code in
//! SSRAM1's secure alias at 0x1000_0000, where the secure vector table
//! starts, data in SSRAM2's at 0x3800_0000) and hw/arm/nrf51_soc.c
//! (micro:bit: 256 KiB flash at 0, 16 KiB RAM at 0x2000_0000). The same
//! small lengths as the root memory.x where a machine has more.
//!
//! RISC-V (riscv32imac on QEMU's `virt`, hw/riscv/virt.c): the machine has
//! RAM only, from 0x8000_0000, where `-bios none` jumps at reset. Its first
//! 256 KiB stand in for flash (text, rodata and .data's load image, as on a
//! flash part such as the GD32VF103) and the next 64 KiB for RAM, so the
//! sizes read as the Cortex-M ones do. riscv-rt's `link.x` places sections
//! by the REGION_* aliases.
use std::{env, fs, path::PathBuf};

fn main() {
    let target = env::var("TARGET").unwrap_or_default();
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    println!("cargo:rerun-if-changed=build.rs");
    if target == "riscv32imac-unknown-none-elf" {
        let map = "MEMORY\n{\n  FLASH : ORIGIN = 0x80000000, LENGTH = 256K\n  RAM   : ORIGIN = 0x80040000, LENGTH = 64K\n}\n\
            REGION_ALIAS(\"REGION_TEXT\", FLASH);\nREGION_ALIAS(\"REGION_RODATA\", FLASH);\n\
            REGION_ALIAS(\"REGION_DATA\", RAM);\nREGION_ALIAS(\"REGION_BSS\", RAM);\n\
            REGION_ALIAS(\"REGION_HEAP\", RAM);\nREGION_ALIAS(\"REGION_STACK\", RAM);\n";
        fs::write(out.join("memory.x"), map).expect("OUT_DIR is writable");
        println!("cargo:rustc-link-search={}", out.display());
        println!("cargo:rustc-link-arg-bins=-Tlink.x");
        return;
    }
    let (flash, ram, ram_len, machine) = match target.as_str() {
        "thumbv6m-none-eabi" => (0x0000_0000u32, 0x2000_0000u32, "16K", Some("microbit")),
        "thumbv7m-none-eabi" => (0x0000_0000, 0x2000_0000, "64K", None),
        "thumbv8m.main-none-eabihf" => (0x1000_0000, 0x3800_0000, "64K", Some("an505")),
        other => panic!(
            "firmware/probes builds the step probe for thumbv6m-none-eabi (microbit), thumbv7m-none-eabi (mps2-an385), thumbv8m.main-none-eabihf (mps2-an505) or riscv32imac-unknown-none-elf (virt), not {other}"
        ),
    };
    let map = format!(
        "MEMORY\n{{\n  FLASH : ORIGIN = {flash:#010x}, LENGTH = 256K\n  RAM   : ORIGIN = {ram:#010x}, LENGTH = {ram_len}\n}}\n"
    );
    fs::write(out.join("memory.x"), map).expect("OUT_DIR is writable");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if let Some(m) = machine {
        println!("cargo:rustc-cfg=probe_machine=\"{m}\"");
    }
}
