#!/usr/bin/env bash
# Every test of the project, from a clean checkout: installs what it needs first.
# Used by CI (.ci/run) and by developers alike.
set -euo pipefail
cd "$(dirname "$0")/.."

# Each crate is built once per clean checkout: incremental caches would only take disk
# (the machine's disk is shared; CI once stopped on "No space left on device").
export CARGO_INCREMENTAL=0

step() { printf '\n==> [%ds] %s\n' "$SECONDS" "$*"; }
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

step "set-up: Cortex-M4F and Cortex-M3 targets, QEMU, /usr/bin/time (peak memory), Chromium (check --html)"
rustup target list --installed | grep -qx thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf
rustup target list --installed | grep -qx thumbv7m-none-eabi || rustup target add thumbv7m-none-eabi
if ! command -v qemu-system-arm >/dev/null; then
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-system-arm
fi
if [ ! -x /usr/bin/time ]; then
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq time
fi
# `simrod check --html` is rendered in headless Chromium (workbench/tests/check_cli.rs).
if [ ! -x /usr/bin/chromium ]; then
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium
fi
rustup component list --installed | grep -q '^rustfmt' || rustup component add rustfmt
rustup component list --installed | grep -q '^clippy' || rustup component add clippy

step "format"
cargo fmt --all -- --check

step "lints (clippy, all targets, warnings are errors)"
cargo clippy --all-targets -- -D warnings
cargo clippy -p model-core --target thumbv7em-none-eabihf -- -D warnings
cargo clippy -p model-core --features fixed --target thumbv7m-none-eabi -- -D warnings

step "model-core and the xDT build for the target without std or alloc"
cargo build -p model-core --target thumbv7em-none-eabihf
cargo build -p model-core --target thumbv7em-none-eabihf --features defmt
cargo build -p model-core --target thumbv7em-none-eabihf --features profile-hooks
cargo build -p model-core --target thumbv7m-none-eabi --features fixed
cargo build -p simrod-xdt --target thumbv7em-none-eabihf
cargo clippy -p simrod-xdt --target thumbv7em-none-eabihf -- -D warnings

step "firmware builds (Cortex-M4F; Cortex-M3 fixed point and soft-float)"
cargo build -p firmware --release --target thumbv7em-none-eabihf
M3_BINS=(--bin firmware --bin simrod-trace --bin simrod-cost)
cargo build -p firmware --release --target thumbv7m-none-eabi --features fixed "${M3_BINS[@]}"
cargo clippy -p firmware --release --target thumbv7m-none-eabi --features fixed "${M3_BINS[@]}" -- -D warnings
cargo build -p firmware --release --target thumbv7m-none-eabi "${M3_BINS[@]}"

step "FMU validators: Python environment (FMPy, FMU Manipulation Toolbox; scripts/py-env.sh) and valgrind"
scripts/py-env.sh
if ! command -v valgrind >/dev/null; then
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq valgrind
fi

step "all host tests (model, workbench, physics plant, firmware under QEMU, reference accuracy)"
cargo test

step "physics plant speed (target 2 s per 60 s of bench time; CI guard 6 s)"
cargo bench -p simrod-plant --bench plant_speed -- --quick --guard 6

# The examples and the `simrod` binary they drive, as `cargo test` built them (the same
# default members, so the same features: nothing to compile). A `-p workbench` build
# resolves features for one package and compiles 20 crates again (about 100 s).
cargo build --bins --examples

step "peak memory of compare and diagnose on a 40 MB run (aims: 4x / 8x the file + 200 MB; the 300 MB run: --mb 300)"
"${CARGO_TARGET_DIR:-target}"/debug/examples/memory --mb 40 --guard

step "diagnose speed, once each in the test profile (aims 1.5 s one run, 5 s five runs; CI guard 5x the aims)"
"${CARGO_TARGET_DIR:-target}"/debug/examples/diagnose_timing --repeats 1 --guard 5

step "issue 12's blind loop, short: 2 cases on tuning seeds (the proof: --cases 200, seeds from 1,000,000)"
"${CARGO_TARGET_DIR:-target}"/debug/examples/blind_loop --cases 2 --first 500000

step "fuzz smoke run: CSV, MAT, TOML files, serial decoder, 20 s each on the committed corpus (docs/FUZZING.md)"
scripts/fuzz.sh 20
