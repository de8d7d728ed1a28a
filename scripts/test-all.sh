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
# CPU seconds (user + system) of every finished child so far, from bash's
# `times`: a stage's CPU beside its wall time shows whether it waits (on
# QEMU, ptys, the network) or computes, which is what decides whether
# running it beside another stage can gain anything on 2 cores.
cpu_file=$(mktemp)
read_cpu() {
    # `times` in this shell, not in a command substitution's subshell
    # (whose children's times start at zero).
    times >"$cpu_file"
    cpu_now=$(awk 'NR == 2 { split($0, f, /[ ms]+/); print int(f[1] * 60 + f[2] + f[3] * 60 + f[4]) }' "$cpu_file")
}
read_cpu
cpu_started=$cpu_now
step() {
    local now
    now=$(date +%s)
    read_cpu
    if [ -n "$stage_name" ]; then
        stages+=$(printf '%5d s %6d CPU-s  %s\n' $((now - stage_started)) $((cpu_now - cpu_started)) "$stage_name")$'\n'
    fi
    stage_name="$1"
    stage_started=$now
    cpu_started=$cpu_now
    printf '\n==> [%d s] %s\n' $((now - started)) "$*"
}
finish() {
    step "done"
    printf '\nstage times (wall, and CPU of the stage'"'"'s processes):\n%s%5d s %6d CPU-s  in all\n' \
        "$stages" $(($(date +%s) - started)) "$cpu_now"
    rm -f "$cpu_file"
}

as_root() {
    if [ "$(id -u)" -eq 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
        echo "need root to run: $*" >&2; return 1; fi
}

# The images' target, and the three the core library is held to (issue
# 32): Cortex-M0+ (no FPU), Cortex-M33, RISC-V.
core_targets=(thumbv6m-none-eabi thumbv8m.main-none-eabihf riscv32imac-unknown-none-elf)
step "install: thumbv7em-none-eabihf and the core's targets (${core_targets[*]}), clippy, qemu-system-arm, python3-venv"
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
# The Python stage's virtual environment needs venv and ensurepip, which
# Debian ships apart (python3-venv).
if ! python3 -c 'import ensurepip, venv' 2>/dev/null; then
    as_root apt-get update
    as_root env DEBIAN_FRONTEND=noninteractive \
        apt-get install -y --no-install-recommends python3-venv
fi
qemu-system-arm --version | head -1

# Background jobs (the lints and images, the pip install, the joint's
# twins) are killed if the script stops early.
bg_pids=()
# A failed run prints its stage table too (where the time went up to the
# failure).
kill_tree() {
    local c
    for c in $(cat /proc/"$1"/task/*/children 2>/dev/null); do kill_tree "$c"; done
    kill "$1" 2>/dev/null || true
}
on_exit() {
    local rc=$?
    # The jobs' processes too (a test binary outlives its subshell).
    for p in "${bg_pids[@]}"; do kill_tree "$p"; done
    [ "$rc" -eq 0 ] || { finish; echo "failed in the stage above \"done\" (exit $rc)" >&2; }
}
trap on_exit EXIT
# Waits for background job $1 whose output went to file $2, prints that
# output under the heading $3 and fails the script if the job failed.
wait_job() {
    local rc=0
    wait "$1" || rc=$?
    printf -- '--- %s ---\n' "$3"
    cat "$2"
    rm -f "$2"
    if [ "$rc" -eq 124 ]; then
        echo "$3: did not finish in its time limit (timeout, exit $rc)" >&2
        exit 1
    fi
    if [ "$rc" -ne 0 ]; then
        echo "$3: failed (exit $rc)" >&2
        exit 1
    fi
}

# Clippy runs as the compiler of the host build itself: cargo's
# RUSTC_WORKSPACE_WRAPPER is what `cargo clippy` sets, but on a build
# (not a check) every workspace crate is linted and compiled in one pass,
# and the dependencies are compiled once, not also checked apart (a separate
# `cargo clippy --workspace --all-targets` cost ≈ 150 CPU-s of 1,360, the
# lints themselves next to nothing). CLIPPY_ARGS carries `-D warnings` the
# way cargo-clippy hands it to clippy-driver. Exported for every host cargo
# and maturin below: the wrapper is part of cargo's fingerprints, so a host
# build without it would compile the workspace again. The firmware images
# are built without it (clippy-driver turns MIR optimisations off, and the
# images' sizes are figures).
clippy_driver="$(rustc --print sysroot)/bin/clippy-driver"
clippy_args="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__"
# The wrapper must deny a lint, or the suite would pass with clippy's
# warnings printed and ignored: a one-line crate it must refuse.
lint_probe=$(mktemp -d)
printf 'pub fn n(v: &Vec<u8>) -> usize { v.len() }\n' >"$lint_probe/probe.rs"
if CLIPPY_ARGS="$clippy_args" "$clippy_driver" rustc --crate-type lib --edition 2021 \
    --emit=metadata --out-dir "$lint_probe" "$lint_probe/probe.rs" >/dev/null 2>&1; then
    echo "clippy-driver with CLIPPY_ARGS=$clippy_args did not deny clippy::ptr_arg: the lint stage would check nothing" >&2
    exit 1
fi
rm -rf "$lint_probe"
with_clippy() { RUSTC_WORKSPACE_WRAPPER="$clippy_driver" CLIPPY_ARGS="$clippy_args" "$@"; }

# The images, clippy and the core's other targets build in cargo's
# `release` and `dev` build directories while the host tests build in
# `ci-opt`'s: cargo locks each apart, so the two run at once and fill each
# other's idle time (a build's serial tail, linking one binary at a time).
# The images are needed from the #[ignore]d stage on, the lints only for
# the verdict.
step "in parallel: the host tests', examples' and benches' build (profile ci-opt, clippy -D warnings as it builds), and at lower priority the firmware images, clippy -D warnings on thumb, the core on ${core_targets[*]}, the control step under QEMU"
lint_log=$(mktemp)
(
    set -euo pipefail
    # Below the host build (the longer path) and the host tests (some keep
    # time), above the joint's twins.
    renice -n 10 -p "$BASHPID" >/dev/null
    # Without debug info (the release profiles keep it for users' debuggers
    # and backtraces; nothing here reads it): the flashed bytes are the
    # same (`llvm-objcopy -O binary` of the STM32F4 image compared equal),
    # the STM32F4 build alone 44 → 33 CPU-s.
    export CARGO_PROFILE_RELEASE_DEBUG=false
    echo "== firmware images: thumbv7em with and without defmt, the step probe, the STM32F4 board images"
    cargo build -p firmware --release --target thumbv7em-none-eabihf --locked --bins
    cargo build -p firmware --release --target thumbv7em-none-eabihf --features defmt --locked
    # Built from its directory: its .cargo/config.toml sets the thumb
    # target, the shared target/ directory and the probe-rs runner.
    (cd firmware/stm32f4 && cargo build --release --locked)
    llvm-size target/thumbv7em-none-eabihf/release/softjoint-fw \
        target/thumbv7em-none-eabihf/release/step-probe \
        target/thumbv7em-none-eabihf/release/softjoint-stm32f4 \
        target/thumbv7em-none-eabihf/release/softjoint-stm32f4-qemu 2>/dev/null || true
    echo "== the core's 3D control step in the Cortex-M4F image under QEMU"
    timeout 60 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -icount shift=0 \
        -semihosting-config enable=on,target=native \
        -kernel target/thumbv7em-none-eabihf/release/step-probe
    echo "step-probe exited 0 (every output bounded, no fault)"
    echo "== clippy -D warnings on thumb (the host's is the host build's compiler)"
    cargo clippy -p firmware --target thumbv7em-none-eabihf --lib --bins --locked -- -D warnings
    cargo clippy -p firmware --target thumbv7em-none-eabihf --features defmt --lib --bins --locked -- -D warnings
    (cd firmware/stm32f4 && cargo clippy --release --lib --bins --locked -- -D warnings)
    echo "== the core library on ${core_targets[*]}: built with clippy -D warnings as its compiler (the library only; the per-target images and their figures: docs/benchmarks.md)"
    for t in "${core_targets[@]}"; do
        with_clippy cargo build -p firmware --lib --target "$t" --locked
    done
) >"$lint_log" 2>&1 &
lint_pid=$!
bg_pids+=("$lint_pid")

# Libraries, binaries and integration tests: one build. (The crates have
# no doc tests.)
targets=(--workspace --lib --bins --tests --locked --profile ci-opt)
export RUSTC_WORKSPACE_WRAPPER="$clippy_driver" CLIPPY_ARGS="$clippy_args"

# The Python stage's packages (issue 33) download and unpack meanwhile:
# the install is mostly waiting on the network and the disk.
venv=target/python-venv
pip_log=$(mktemp)
(
    [ -x "$venv/bin/python" ] || python3 -m venv "$venv"
    "$venv/bin/pip" install -q --disable-pip-version-check maturin numpy pytest ray
) >"$pip_log" 2>&1 &
pip_pid=$!
bg_pids+=("$pip_pid")

# The examples and benches too, so that clippy sees every target (they
# are not run here: the examples are the long experiments of
# docs/experiments.md, the benches docs/benchmarks.md's figures).
cargo test "${targets[@]}" --examples --benches --no-run

# The lints and images (if still running) before the host tests: the
# host tests include pty boards and sessions that keep time, and nothing
# but the twins at the lowest priority runs beside them.
wait_job "$lint_pid" "$lint_log" "firmware images, clippy, the core's targets"

# The joint's identification twins (#[ignore]d: ten-minute logs, minutes
# of CPU on both cores, waiting on nothing) start now, from their binaries
# (a second cargo would wait for the lock on the build directory while
# another cargo runs tests), at the lowest priority: they take the CPU
# time the next stages leave (the host tests wait on ptys and child
# programs for half their time, the QEMU checks on round trips, the
# Python tests on Ray). While the stages with pty boards run (the host
# tests, the console's excitation session) the twins are held to one CPU:
# on this VM a process that keeps *every* CPU busy, even at nice 19 or
# under SCHED_IDLE, can starve the kernel's workqueue threads that carry
# pty data (`flush_to_ldisc`), and a pty reader then sleeps in
# `__flush_work` for seconds. Measured with the pty conformance suite and
# the console tests (`conform_suite:: cli_console::`, 11 tests, 13.2 s
# alone): beside two nice-19 busy loops 2 of 5 runs failed ("no reply …
# after 5 attempts") and the others took up to 87 s; beside one, 5 of 5
# passed in 13.2 s. The twins get both CPUs once those stages are done.
# Their paths come from the workspace build (built alone, plant-joint
# would resolve other features and build again).
mapfile -t joint_tests < <(cargo test "${targets[@]}" --no-run --message-format=json 2>/dev/null |
    python3 -c '
import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if (m.get("reason") == "compiler-artifact" and m.get("executable") and m["profile"]["test"]
            and m["manifest_path"].endswith("plant-models/joint/Cargo.toml")):
        print(m["executable"])')
[ "${#joint_tests[@]}" -gt 0 ] || { echo "no plant-joint test binaries found" >&2; exit 1; }
joint_log=$(mktemp)
ncpu=$(nproc)
# The 3D and 2D ten-minute twins (≈ 60 and 33 CPU-s, the longest) go
# first, with the jamming check that reads both from the same process's
# cache, and the campaign's short form (two probed twins, ≈ 70 CPU-s):
# in name order the 3D twin started seventh of nine and ran on alone at
# the end. Should these names change, the first run matches
# nothing and the second runs every test: the order is lost, no test.
taskset -c "$((ncpu - 1))" bash -c '
    cd plant-models/joint
    first=(identify::ten_minute_twin_3d_recovers_both_planes
        identify::ten_minute_twin_2d_recovers_each_identifiable_parameter
        identify::ten_minute_twins_recover_the_jamming_gain_or_name_it_not_identifiable
        identify::the_campaign_in_short_form_calls_nothing_wrong_identifiable)
    skip=()
    for f in "${first[@]}"; do skip+=(--skip "$f"); done
    for t in "$@"; do
        nice -n 19 "$t" --ignored --exact "${first[@]}" || exit 1
        nice -n 19 "$t" --ignored "${skip[@]}" || exit 1
    done
' twins "${joint_tests[@]}" >"$joint_log" 2>&1 &
joint_pid=$!
bg_pids+=("$joint_pid")
# Gives the twins (the loop and the binary it runs, every thread) all CPUs.
twins_on_every_cpu() {
    local p
    for p in "$joint_pid" $(cat /proc/"$joint_pid"/task/*/children 2>/dev/null); do
        taskset -a -p -c "0-$((ncpu - 1))" "$p" >/dev/null 2>&1 || true
    done
}

step "tests: unit, property, closed-loop, pty and CLI (host; the joint's twins beside them at nice 19 on one CPU)"
cargo test "${targets[@]}"

step "softjoint hil under QEMU as a user runs it: QEMU killed, hil stopped or killed, bad images (one at a time: they signal process groups); the console's excitation session on a real-time pty board (the twins still on one CPU)"
cargo test "${targets[@]}" -- --ignored hil_qemu_cli:: console_excite:: --test-threads 1
twins_on_every_cpu

# The Python package (issue 33), in a virtual environment of its own
# under target/: the wheel built from the workspace crate python/ in the
# ci-opt profile into the workspace's target directory (python/Cargo.toml
# asks for the workspace build's features, so only pyo3's chain and the
# module compile), its pytest suite compared with the program built above
# (SOFTJOINT_BIN), and a local Ray cluster of two raylets (separate `ray
# start` processes) that the tests start and stop: a tune and a rheology
# calibration equal to the program's, a worker killed mid-sweep, Ctrl-C.
# The wheel is built first (a cargo running tests holds the build
# directory's lock); the tests then run beside the other ignored checks:
# they wait on Ray and on the program for most of their ≈ 100 s (≈ 0.8 of
# a CPU), as those wait on QEMU, so one after the other they left a CPU to
# the twins for ≈ 200 s that the suite's end then waited for.
step "the Python package's wheel (maturin, ci-opt)"
if ! wait "$pip_pid"; then
    cat "$pip_log" >&2
    echo "pip install of maturin, numpy, pytest and ray failed (log above)" >&2
    exit 1
fi
rm -f "$pip_log"
"$venv/bin/maturin" build -m python/Cargo.toml --profile ci-opt --locked \
    -i "$venv/bin/python" --out target/wheels
"$venv/bin/pip" install -q --disable-pip-version-check --force-reinstall --no-deps \
    target/wheels/softjoint-0.1.0-*.whl

step "beside each other: the checks that need the optimised build or QEMU (every #[ignore]d test but the joint's twins): the knot, the belt and the end-distance sequence; indentation at levels 7-9 and the 60 s replays; Table I at the paper's size; the firmware images in lockstep with the joint under QEMU (mps2-an386 and the STM32F4 image on netduinoplus2), the tuned gains and the link's fault campaign through the image — and the Python package's pytest against the program with two Ray raylets"
py_log=$(mktemp)
# A bound on the Python tests (≈ 100 s when well): a Ray head that dies
# while `ray.init` waits on it, or any other test that hangs, fails the
# suite after 15 minutes, naming it, instead of holding CI to its limit.
# SIGINT first, so that pytest runs its fixtures' teardown (the raylets
# are stopped); SIGKILL a minute later if that hangs too.
SOFTJOINT_BIN=target/ci-opt/softjoint timeout --signal=INT --kill-after=60 900 \
    "$venv/bin/python" -m pytest -q python/tests >"$py_log" 2>&1 &
py_pid=$!
bg_pids+=("$py_pid")
cargo test "${targets[@]}" --exclude plant-joint -- --ignored --skip hil_qemu_cli:: --skip console_excite::
wait_job "$py_pid" "$py_log" "the Python package's tests (pytest)"

step "the joint's identification twins: the 10-minute logs, the off-plan, true-prior and campaign twins (if still running)"
wait_job "$joint_pid" "$joint_log" "plant-joint's #[ignore]d checks"

trap - EXIT
finish
