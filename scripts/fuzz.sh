#!/usr/bin/env bash
# Coverage-guided fuzzing of the file readers and the firmware's serial decoder
# (fuzz/, docs/FUZZING.md).
#
#   scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]
#
# SECONDS_PER_TARGET defaults to 20 (the CI smoke run); TARGETs default to all four
# (csv mat toml_files serial). For each target: runs every recorded crash in
# fuzz/regressions/<target>/ once, then fuzzes for SECONDS_PER_TARGET on a copy of the
# committed seed corpus fuzz/corpus/<target>/ (new inputs go to a scratch directory, so
# the committed corpus never grows) with the dictionary fuzz/dict/<target>.dict if there
# is one, and prints executions, exec/s and coverage.
# Exits non-zero if any target crashed, failed a check, timed out or ran out of memory,
# printing the input that did it (kept under fuzz/artifacts/<target>/).
#
# Environment:
#   FUZZ_WORK=DIR        keep the grown corpora and logs in DIR/<target>/ (default: a
#                        temporary directory, deleted at exit)
#   FUZZ_TARGET_DIR=DIR  cargo target directory of the fuzz build (default fuzz/target)
#   FUZZ_ARGS="..."      extra libFuzzer flags, e.g. "-jobs=2 -workers=2" or "-max_len=20000"
#   FUZZ_JOBS=N          targets fuzzed side by side (default: the number of cores;
#                        each libFuzzer process uses one)
#
# Stable Rust: built with `--sanitizer none` (the sanitizers need nightly's -Zsanitizer);
# libFuzzer's coverage instrumentation only needs stable -C flags. See docs/FUZZING.md.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD

SECS=${1:-20}
shift $(($# > 0 ? 1 : 0))
if ! [[ $SECS =~ ^[0-9]+$ ]] || [ "$SECS" -lt 1 ]; then
  echo "usage: scripts/fuzz.sh [SECONDS_PER_TARGET] [TARGET...]" >&2
  exit 2
fi
JOBS=${FUZZ_JOBS:-$(nproc)}
if ! [[ $JOBS =~ ^[0-9]+$ ]] || [ "$JOBS" -lt 1 ]; then
  echo "FUZZ_JOBS must be a whole number >= 1, not '$JOBS'" >&2
  exit 2
fi
ALL_TARGETS=(csv mat toml_files serial)
TARGETS=("$@")
[ ${#TARGETS[@]} -gt 0 ] || TARGETS=("${ALL_TARGETS[@]}")

step() { printf '\n==> %s\n' "$*"; }
as_root() { if [ "$(id -u)" = 0 ]; then "$@"; else sudo "$@"; fi; }

step "set-up: cargo-fuzz and a C++ compiler (libFuzzer is C++)"
if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked
fi
if ! command -v c++ >/dev/null && ! command -v g++ >/dev/null && ! command -v clang++ >/dev/null; then
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq g++
fi

TARGET_DIR=${FUZZ_TARGET_DIR:-$ROOT/fuzz/target}
TRIPLE=$(rustc -vV | sed -n 's/^host: //p')
BIN=$TARGET_DIR/$TRIPLE/release
# Release build with debug assertions and overflow checks, no sanitizer (stable Rust).
BUILD=(--fuzz-dir "$ROOT/fuzz" --sanitizer none --release --debug-assertions --target-dir "$TARGET_DIR")

step "build the fuzz targets: ${TARGETS[*]}"
for t in "${TARGETS[@]}"; do
  cargo fuzz build "${BUILD[@]}" "$t"
done

if [ -n "${FUZZ_WORK:-}" ]; then
  WORK=$FUZZ_WORK
  mkdir -p "$WORK"
else
  WORK=$(mktemp -d "${TMPDIR:-/tmp}/simrod-fuzz.XXXXXX")
  trap 'rm -rf "$WORK"' EXIT
fi

# A failed libFuzzer run: the panic, and the input (the artifact libFuzzer wrote, or
# the file it was running).
report_failure() { # target log
  local art
  art=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$2" | tail -1)
  [ -n "$art" ] || art=$(sed -n 's/^Running: \(.*\)$/\1/p' "$2" | tail -1)
  echo "!!! $1: FAILED" >&2
  grep -A2 "panicked at" "$2" | head -3 >&2 || true
  grep -E "^==[0-9]+== ERROR|ERROR: libFuzzer|Timeout|out-of-memory" "$2" | head -3 >&2 || true
  if [ -n "$art" ]; then
    echo "!!! $1: input: $art" >&2
    echo "    reproduce: $BIN/$1 $art" >&2
  fi
  echo "    log: $2 (FUZZ_WORK=DIR keeps it)" >&2
}

# One target: its regressions, then SECS of fuzzing. Writes what it prints to
# $WORK/<target>/out, its summary line to .../summary and, if it failed, the reason
# to .../failed (targets run side by side, so nothing is shared but these files).
fuzz_one() {
  local t=$1 bad=0 r log status runs rate cov line
  mkdir -p "$WORK/$t/corpus" "$ROOT/fuzz/artifacts/$t"
  mapfile -t regs < <(find "$ROOT/fuzz/regressions/$t" -maxdepth 1 -type f ! -name '.*' ! -name '*.md' 2>/dev/null | sort)
  if [ ${#regs[@]} -gt 0 ]; then
    step "$t: ${#regs[@]} regression input(s) from fuzz/regressions/$t/"
    for r in "${regs[@]}"; do
      log=$WORK/$t/regression-$(basename "$r").log
      if ! "$BIN/$t" -timeout=10 "$r" >"$log" 2>&1; then
        report_failure "$t" "$log"
        bad=$((bad + 1))
      fi
    done
    if [ $bad -eq 0 ]; then
      echo "$t: regressions pass"
    else
      echo "$t ($bad regression(s))" >>"$WORK/$t/failed"
    fi
  fi

  step "$t: fuzzing ${SECS}s on a copy of fuzz/corpus/$t/"
  log=$WORK/$t/fuzz.log
  # The words the parser compares strings against (not traced without a sanitizer).
  local dict=()
  [ -f "$ROOT/fuzz/dict/$t.dict" ] && dict=(-dict="$ROOT/fuzz/dict/$t.dict")
  # First corpus dir: scratch (libFuzzer writes new inputs there); second: the seeds.
  # shellcheck disable=SC2086 # FUZZ_ARGS is a list of flags
  if "$BIN/$t" -max_total_time="$SECS" -print_final_stats=1 -timeout=10 "${dict[@]}" \
    -artifact_prefix="$ROOT/fuzz/artifacts/$t/" ${FUZZ_ARGS:-} \
    "$WORK/$t/corpus" "$ROOT/fuzz/corpus/$t" >"$log" 2>&1; then
    status=ok
  else
    status=FAILED
    report_failure "$t" "$log"
    echo "$t" >>"$WORK/$t/failed"
  fi
  # libFuzzer's final stats (-print_final_stats=1); older versions say `_runs`.
  runs=$(sed -n 's/^stat::number_of_executed_\(units\|runs\): *//p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+ corp: [0-9]+' "$log" | tail -1 || true)
  line=$(printf '%-11s %-6s %12s runs %8s exec/s  %s' "$t" "$status" "${runs:-?}" "${rate:-?}" "${cov:-}")
  echo "$line"
  echo "$line" >"$WORK/$t/summary"
}

# libFuzzer runs on one core: FUZZ_JOBS targets (default: the number of cores) fuzz
# side by side, each for the full SECS, and their output is printed in target order.
for t in "${TARGETS[@]}"; do
  mkdir -p "$WORK/$t"
  rm -f "$WORK/$t/failed" "$WORK/$t/summary"
  fuzz_one "$t" >"$WORK/$t/out" 2>&1 &
  while [ "$(jobs -rp | wc -l)" -ge "$JOBS" ]; do
    wait -n || true
  done
done
wait
FAILED=()
SUMMARY=()
for t in "${TARGETS[@]}"; do
  cat "$WORK/$t/out"
  [ -f "$WORK/$t/failed" ] && mapfile -t -O "${#FAILED[@]}" FAILED <"$WORK/$t/failed"
  if [ -f "$WORK/$t/summary" ]; then
    SUMMARY+=("$(cat "$WORK/$t/summary")")
  else
    SUMMARY+=("$t: no summary (the run stopped early; see its output above)")
    FAILED+=("$t")
  fi
done

step "summary (${SECS}s per target)"
printf '%s\n' "${SUMMARY[@]}"
if [ ${#FAILED[@]} -gt 0 ]; then
  echo "fuzzing FAILED: ${FAILED[*]} (inputs under fuzz/artifacts/; see docs/FUZZING.md)" >&2
  exit 1
fi
echo "no crashes"
