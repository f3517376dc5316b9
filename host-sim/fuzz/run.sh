#!/usr/bin/env bash
# Bounded coverage-guided fuzzing of every parser (docs/fuzzing.md).
#
#   bash host-sim/fuzz/run.sh [TARGET ...]     (default: all six)
#
# Builds the targets with cargo-fuzz on stable Rust (no sanitizer: `-s none`,
# debug assertions and overflow checks on), then runs each for FUZZ_SECONDS
# (default 30) on a working corpus (host-sim/fuzz/corpus/TARGET, not
# committed) seeded from host-sim/fuzz/seeds/TARGET and the kept crashes in
# host-sim/tests/data/fuzz/TARGET. Prints the executions per target and
# exits non-zero at the first crash, leaving the input in
# host-sim/fuzz/artifacts/TARGET/. To keep it as a regression test:
#
#   cargo fuzz tmin -s none -a TARGET artifacts/TARGET/crash-...   (in host-sim/fuzz)
#   cp the minimised input to host-sim/tests/data/fuzz/TARGET/NAME
#
# `cargo test -p host-sim --test fuzz_parsers` replays every kept input.
#
# Environment: FUZZ_SECONDS (30 per target), FUZZ_TARGET_DIR (build
# directory; default target/fuzz at the repository root), FUZZ_MAX_LEN
# (8192 bytes), CARGO_BUILD_JOBS.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"
secs="${FUZZ_SECONDS:-30}"
max_len="${FUZZ_MAX_LEN:-8192}"
tdir="${FUZZ_TARGET_DIR:-$root/target/fuzz}"
all=(csv_log config_toml mrdlab kuka defmt_text trace)
if [ "$#" -gt 0 ]; then targets=("$@"); else targets=("${all[@]}"); fi

if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked
fi
cd "$here"
cargo fuzz build -s none -a --target-dir "$tdir"

# The targets write their path-only inputs (TOML, KUKA) to a scratch
# directory; keep those under one directory removed at the end.
# In memory where possible: rewriting a file on ext4 waits for the disk.
if [ -d /dev/shm ] && [ -w /dev/shm ]; then
  scratch="$(mktemp -d -p /dev/shm)"
else
  scratch="$(mktemp -d)"
fi
trap 'rm -rf "$scratch"' EXIT

summary=()
for t in "${targets[@]}"; do
  corpus="$here/corpus/$t"
  mkdir -p "$corpus" "$here/artifacts/$t"
  cp "$here/seeds/$t"/* "$corpus"/
  kept="$root/host-sim/tests/data/fuzz/$t"
  if [ -d "$kept" ]; then
    find "$kept" -maxdepth 1 -type f ! -name '*.md' -exec cp {} "$corpus"/ \;
  fi
  log="$scratch/$t.log"
  echo "=== fuzz $t for ${secs}s"
  start=$(date +%s)
  status=0
  TMPDIR="$scratch" cargo fuzz run -s none -a --target-dir "$tdir" "$t" "$corpus" -- \
    -max_total_time="$secs" -max_len="$max_len" -timeout=10 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$here/artifacts/$t/" >"$log" 2>&1 || status=$?
  took=$(($(date +%s) - start))
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  if [ "$status" -ne 0 ]; then
    tail -n 60 "$log"
    echo "fuzz $t: CRASH after ${took}s (exit $status); input in host-sim/fuzz/artifacts/$t/" >&2
    exit 1
  fi
  summary+=("$t: ${execs:-?} executions in ${took}s, no crash")
done
printf '%s\n' "${summary[@]}"
