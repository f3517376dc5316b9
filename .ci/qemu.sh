#!/usr/bin/env bash
# Firmware proof in QEMU (called by .ci/run; runs on its own from a clean clone).
#
# 1. installs what is missing: the thumbv7em target, qemu-system-arm (apt),
#    flip-link and defmt-print (cargo install --locked);
# 2. builds the hardware firmware and reports its flash / static RAM;
# 3. records a fresh closed-loop sensor trace with the simulator
#    (`host-sim trace`: the firmware's own logic on the simulated prototype)
#    and builds the QEMU variant around it;
# 4. runs it on QEMU's netduinoplus2 under `-icount shift=0,sleep=off` with a
#    timeout, decodes the defmt stream, and fails on a timeout, a failure exit
#    (panic or HardFault), or an ERROR line;
# 5. replays the same trace through the core on the host and requires the
#    firmware's output to be identical tick by tick, bit for bit
#    (tests/qemu_replay.rs);
# 6. prints the instructions per control stage (TIM2 under -icount) and writes
#    the run as a CSV log (host-sim ingest).
#
# Host tools run in the dev profile, so the builds of .ci/run's `cargo test
# --workspace` are reused. Outputs land in $QEMU_OUT (default: <target dir>/qemu): firmware-hw.elf,
# firmware-qemu.elf, trace.bin, qemu.defmt (raw), qemu.txt (decoded),
# qemu.csv, sizes.txt, icount.txt.
set -euo pipefail
cd "$(dirname "$0")/.."

TARGET=thumbv7em-none-eabihf
TARGET_DIR="${CARGO_TARGET_DIR:-target}"
OUT="${QEMU_OUT:-$TARGET_DIR/qemu}"
TIMEOUT_S="${QEMU_TIMEOUT_S:-300}"
ELF="$TARGET_DIR/$TARGET/release/firmware"
LOCKED=(--locked)
[ "${QEMU_UNLOCKED:-0}" = 1 ] && LOCKED=()
mkdir -p "$OUT"
say() { printf -- '--- %s\n' "$*"; }

say "tools"
rustup target add "$TARGET" >/dev/null
if ! command -v qemu-system-arm >/dev/null || ! command -v arm-none-eabi-size >/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq qemu-system-arm binutils-arm-none-eabi
fi
command -v flip-link >/dev/null || cargo install flip-link --locked
command -v defmt-print >/dev/null || cargo install defmt-print --locked
qemu-system-arm --version | head -n 1

size_of() {
  if command -v arm-none-eabi-size >/dev/null; then
    arm-none-eabi-size "$1"
  else
    echo "(arm-none-eabi-size not installed: apt-get install binutils-arm-none-eabi)"
  fi
}

say "hardware firmware (cargo fw)"
cargo fw "${LOCKED[@]}"
cp "$ELF" "$OUT/firmware-hw.elf"
{
  echo "hardware build (text = flash code+rodata, data = initialised RAM also in flash, bss = zeroed RAM):"
  size_of "$OUT/firmware-hw.elf"
} | tee "$OUT/sizes.txt"

say "closed-loop sensor trace (host-sim trace)"
cargo run "${LOCKED[@]}" -p host-sim -- trace --out "$OUT/trace.bin"

say "QEMU firmware (cargo fw-qemu, trace $OUT/trace.bin)"
CABLE_JOINT_TRACE="$OUT/trace.bin" cargo fw-qemu "${LOCKED[@]}"
cp "$ELF" "$OUT/firmware-qemu.elf"
{
  echo "qemu build (includes the embedded trace):"
  size_of "$OUT/firmware-qemu.elf"
} | tee -a "$OUT/sizes.txt"

say "QEMU run (timeout ${TIMEOUT_S} s)"
set +e
timeout "$TIMEOUT_S" qemu-system-arm \
  -machine netduinoplus2 -nographic -monitor none -serial none \
  -semihosting-config enable=on,target=native \
  -icount shift=0,sleep=off \
  -kernel "$OUT/firmware-qemu.elf" >"$OUT/qemu.defmt" 2>"$OUT/qemu.stderr"
status=$?
set -e
defmt-print -e "$OUT/firmware-qemu.elf" <"$OUT/qemu.defmt" >"$OUT/qemu.txt" 2>&1 || true
grep -v '^INFO  tlm \[' "$OUT/qemu.txt" | tail -n 20 || true
if [ "$status" -eq 124 ]; then
  echo "FAIL: QEMU timed out after ${TIMEOUT_S} s" >&2
  exit 1
elif [ "$status" -ne 0 ]; then
  echo "FAIL: the firmware exited with failure ($status: panic or HardFault)" >&2
  cat "$OUT/qemu.stderr" >&2 || true
  exit 1
fi
if grep -q -E '^(ERROR|WARN)' "$OUT/qemu.txt"; then
  echo "FAIL: the firmware logged an error or a warning" >&2
  exit 1
fi
if ! grep -q 'trace played' "$OUT/qemu.txt"; then
  echo "FAIL: the firmware did not finish the trace" >&2
  exit 1
fi

say "bit-for-bit comparison with the host replay (tests/qemu_replay.rs)"
CABLE_JOINT_QEMU_LOG="$OUT/qemu.txt" CABLE_JOINT_TRACE="$OUT/trace.bin" \
  cargo test "${LOCKED[@]}" --test qemu_replay -- --include-ignored

say "instructions per control tick (TIM2 under -icount shift=0)"
cargo run "${LOCKED[@]}" -p host-sim -- ingest "$OUT/qemu.txt" \
  --out "$OUT/qemu.csv" --stats | tee "$OUT/icount.txt"
cat "$OUT/sizes.txt"
say "QEMU proof passed"
