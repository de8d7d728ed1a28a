//! Link setup for the Cortex-M images: puts the workspace's `memory.x` (the
//! mps2-an386 board's) on the linker search path when that board is
//! selected, and passes cortex-m-rt's `link.x` (plus defmt's `defmt.x` when
//! the `defmt` feature is on) to this package's binaries. Host builds are
//! untouched.
use std::{env, fs, path::PathBuf};

fn main() {
    // The step probe's machine when firmware/probes builds it for another
    // core (src/bin/step_probe.rs reads it for the machine's clock).
    println!("cargo::rustc-check-cfg=cfg(probe_machine, values(\"an505\", \"microbit\"))");
    let target_os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if target_os != "none" {
        return;
    }
    // The root memory.x is the mps2-an386 board's. A link-search path set
    // here also reaches the link of every crate that depends on this one,
    // so a board crate that uses the core (default-features = false, e.g.
    // firmware/stm32f4 with its own memory.x) must not see it.
    let manifest =
        PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let memory = manifest.join("..").join("memory.x");
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rerun-if-changed=build.rs");
    if env::var_os("CARGO_FEATURE_BOARD_MPS2_AN386").is_some() {
        let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
        fs::copy(&memory, out.join("memory.x")).expect("memory.x at the workspace root");
        println!("cargo:rustc-link-search={}", out.display());
    }
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
