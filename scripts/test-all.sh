#!/usr/bin/env bash
# Runs every test of the project on a fresh machine, installing what is
# missing: the thumbv7em target, clippy and QEMU. This is the README's test
# command and what CI (.ci/run) calls.
#
# The host tests build once, in the `ci-opt` profile (Cargo.toml: the plant
# crates optimised, debug assertions and overflow checks on): the ordinary
# tests, then every #[ignore]d test — the checks that need an optimised
# build or QEMU — from the same build. An #[ignore]d test is a CI check by
# definition: long experiments that CI does not run are examples
# (docs/experiments.md), not ignored tests.
set -euo pipefail
cd "$(dirname "$0")/.."

started=$(date +%s)
stage_started=$started
stage_name=""
stages=""
step() {
    local now
    now=$(date +%s)
    if [ -n "$stage_name" ]; then
        stages+=$(printf '%5d s  %s\n' $((now - stage_started)) "$stage_name")$'\n'
    fi
    stage_name="$1"
    stage_started=$now
    printf '\n==> [%d s] %s\n' $((now - started)) "$*"
}
finish() {
    step "done"
    printf '\nstage times:\n%s%5d s  in all\n' "$stages" $(($(date +%s) - started))
}

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
        echo "need root to run: $*" >&2; return 1; fi
}

# The images' target, and the three the core library is held to (issue
# 32): Cortex-M0+ (no FPU), Cortex-M33, RISC-V.
core_targets=(thumbv6m-none-eabi thumbv8m.main-none-eabihf riscv32imac-unknown-none-elf)
step "install: thumbv7em-none-eabihf and the core's targets (${core_targets[*]}), clippy, qemu-system-arm"
for t in thumbv7em-none-eabihf "${core_targets[@]}"; do
    rustup target list --installed | grep -qx "$t" || rustup target add "$t"
done
rustup component list --installed | grep -q '^clippy' || rustup component add clippy
if ! command -v qemu-system-arm >/dev/null; then
    as_root apt-get update
    # Without recommends: QEMU's recommended packages (firmware blobs for
    # other machines, speech data) are hundreds of MB this suite never uses.
    as_root env DEBIAN_FRONTEND=noninteractive \
        apt-get install -y --no-install-recommends qemu-system-arm
fi
qemu-system-arm --version | head -1

step "firmware images: thumbv7em with and without defmt, the step probe, the STM32F4 board images"
cargo build -p firmware --release --target thumbv7em-none-eabihf --locked --bins
cargo build -p firmware --release --target thumbv7em-none-eabihf --features defmt --locked
# Built from its directory: its .cargo/config.toml sets the thumb target,
# the shared target/ directory and the probe-rs runner.
(cd firmware/stm32f4 && cargo build --release --locked)
llvm-size target/thumbv7em-none-eabihf/release/softjoint-fw \
    target/thumbv7em-none-eabihf/release/step-probe \
    target/thumbv7em-none-eabihf/release/softjoint-stm32f4 \
    target/thumbv7em-none-eabihf/release/softjoint-stm32f4-qemu 2>/dev/null || true

step "clippy -D warnings: host (every crate, every target) and thumb"
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo clippy -p firmware --target thumbv7em-none-eabihf --lib --bins --locked -- -D warnings
cargo clippy -p firmware --target thumbv7em-none-eabihf --features defmt --lib --bins --locked -- -D warnings
(cd firmware/stm32f4 && cargo clippy --release --lib --bins --locked -- -D warnings)

step "the core library on ${core_targets[*]}: build and clippy -D warnings (the library only; the per-target images and their figures: docs/benchmarks.md)"
for t in "${core_targets[@]}"; do
    cargo build -p firmware --lib --target "$t" --locked
    cargo clippy -p firmware --lib --target "$t" --locked -- -D warnings
done

step "the core's 3D control step in the Cortex-M4F image under QEMU"
timeout 60 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -icount shift=0 \
    -semihosting-config enable=on,target=native \
    -kernel target/thumbv7em-none-eabihf/release/step-probe
echo "step-probe exited 0 (every output bounded, no fault)"

# Libraries, binaries and integration tests: one build. (Examples are
# checked by clippy above; the crates have no doc tests.)
targets=(--workspace --lib --bins --tests --locked --profile ci-opt)

step "build the host tests (profile ci-opt)"
cargo test "${targets[@]}" --no-run

step "tests: unit, property, closed-loop, pty and CLI (host)"
cargo test "${targets[@]}"

step "the checks that need the optimised build or QEMU (every #[ignore]d test): the knot, the belt and the end-distance sequence; indentation at levels 7-9 and the 60 s replays; the 10-minute identification twins; Table I at the paper's size; the firmware images in lockstep with the joint under QEMU (mps2-an386 and the STM32F4 image on netduinoplus2), the tuned gains and the link's fault campaign through the image"
cargo test "${targets[@]}" -- --ignored --skip hil_qemu_cli:: --skip qemu_conform:: --skip qemu_hil::
step "the images in lockstep (qemu_hil, asserting not one retry) and softjoint conform on both QEMU images, one at a time: beside other QEMU work the STM32F4 lockstep run lost a frame to a retry"
cargo test "${targets[@]}" -- --ignored qemu_conform:: qemu_hil:: --test-threads 1
step "softjoint hil under QEMU as a user runs it: QEMU killed, hil stopped or killed, bad images (one at a time: they signal process groups)"
cargo test "${targets[@]}" -- --ignored hil_qemu_cli:: --test-threads 1

# The Python package (issue 33), in a virtual environment of its own
# under target/: the wheel built from the workspace crate python/ in the
# ci-opt profile into the workspace's target directory, its pytest suite
# compared with the program built above (SOFTJOINT_BIN), and a local Ray
# cluster of two raylets (separate `ray start` processes) that the tests
# start and stop: a tune and a rheology calibration equal to the
# program's, a worker killed mid-sweep, Ctrl-C.
step "the Python package: wheel (maturin, ci-opt), pytest against the program, two Ray raylets"
venv=target/python-venv
[ -x "$venv/bin/python" ] || python3 -m venv "$venv"
"$venv/bin/pip" install -q --disable-pip-version-check maturin numpy pytest ray
"$venv/bin/maturin" build -m python/Cargo.toml --profile ci-opt --locked \
    -i "$venv/bin/python" --out target/wheels
"$venv/bin/pip" install -q --disable-pip-version-check --force-reinstall --no-deps \
    target/wheels/softjoint-0.1.0-*.whl
SOFTJOINT_BIN=target/ci-opt/softjoint "$venv/bin/python" -m pytest -q python/tests

finish
