//! Link setup for the Cortex-M image: puts the workspace's `memory.x` on the
//! linker search path and passes cortex-m-rt's `link.x` (plus defmt's
//! `defmt.x` when the `defmt` feature is on) to this package's binaries.
//! Host builds are untouched.
use std::{env, fs, path::PathBuf};

fn main() {
    let target_os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if target_os != "none" {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest =
        PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR"));
    let memory = manifest.join("..").join("memory.x");
    fs::copy(&memory, out.join("memory.x")).expect("memory.x at the workspace root");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
