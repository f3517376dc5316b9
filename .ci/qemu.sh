#!/usr/bin/env bash
# Firmware proof in QEMU (called by .ci/run; runs on its own from a clean clone).
#
# 1. installs what is missing: the thumbv7em target, qemu-system-arm (apt),
#    flip-link and defmt-print (cargo install --locked);
# 2. builds the hardware firmware, reports its flash / static RAM, and fails
#    if a panic location from the tick's code (src/control/, src/board/) is
#    left in it;
# 3. records a fresh closed-loop sensor trace with the simulator
#    (`host-sim trace`: the firmware's own logic on the simulated prototype)
#    and builds the QEMU variant around it;
# 4. runs it on QEMU's netduinoplus2 under `-icount shift=0,sleep=off` with a
#    timeout, decodes the defmt stream, and fails on a timeout, a failure exit
#    (panic or HardFault), or an ERROR line; the run injects a drive fault
#    (from the trace) and a watchdog reset (the control task hangs once the
#    trace is played), and the boot after the reset must report fault 32
#    with the drive off;
# 5. replays the same trace through the core on the host and requires the
#    firmware's output of both boots to be identical tick by tick, bit for
#    bit (tests/qemu_replay.rs);
# 6. prints the instructions per control stage (TIM2 under -icount) and writes
#    the run as a CSV log (host-sim ingest);
# 7. repeats 3-6 with probing on (`host-sim trace --probe`: the trace's header
#    tells the QEMU board to boot with the dither on), in $QEMU_OUT/probing,
#    so the dither's cost per tick is measured too.
# 8. runs the PIL firmware in closed loop with the simulated prototype
#    (host-sim pil; tests/pil.rs: bit for bit with the host-only run, a
#    request over the link included) and the rig workflow under QEMU
#    (scripts/rig-qemu.sh);
#
# Host tools run in the dev profile, so the builds of .ci/run's `cargo test
# --workspace` are reused. Outputs land in $QEMU_OUT (default: <target dir>/qemu): firmware-hw.elf,
# firmware-qemu.elf, trace.bin, qemu.defmt (raw), qemu-all.txt (decoded),
# qemu.txt (its first boot), qemu-reset.txt (the recovery boot), qemu.csv,
# sizes.txt, icount.txt.
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
if ! command -v qemu-system-arm >/dev/null || ! command -v arm-none-eabi-size >/dev/null \
  || ! command -v tmux >/dev/null; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  $SUDO apt-get install -y -qq qemu-system-arm binutils-arm-none-eabi tmux
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

# The tick never panics: no panic location (the file name rustc keeps for a
# bounds check, an unwrap, an overflow) from the control path (src/control/)
# or the board layer (src/board/) may be left in the hardware firmware's
# .rodata (where panic locations live; the debug info is not looked at).
OBJCOPY=arm-none-eabi-objcopy
command -v "$OBJCOPY" >/dev/null || OBJCOPY=objcopy
"$OBJCOPY" -O binary --only-section=.rodata "$OUT/firmware-hw.elf" "$OUT/firmware-hw.rodata"
if strings -n 6 "$OUT/firmware-hw.rodata" | grep -E '(^|/)src/(control|board)/[a-z_]+\.rs' >&2; then
  echo "FAIL: a panic location in the tick's code (above) is left in the firmware" >&2
  exit 1
fi
echo "no panic location from src/control/ or src/board/ in the hardware firmware"

# One proof: record a trace (extra arguments go to `host-sim trace`), build
# the QEMU firmware around it, run it, check both boots, compare them bit for
# bit with the host replay, and count instructions per tick. Outputs in $dir.
proof() {
  local name="$1" dir="$2"
  shift 2
  mkdir -p "$dir"
  say "$name: closed-loop sensor trace (host-sim trace $*)"
  cargo run "${LOCKED[@]}" -p host-sim -- trace --out "$dir/trace.bin" "$@"

  say "$name: QEMU firmware (cargo fw-qemu, trace $dir/trace.bin)"
  CABLE_JOINT_TRACE="$dir/trace.bin" cargo fw-qemu "${LOCKED[@]}"
  cp "$ELF" "$dir/firmware-qemu.elf"
  {
    echo "qemu build, $name (includes the embedded trace):"
    size_of "$dir/firmware-qemu.elf"
  } | tee -a "$OUT/sizes.txt"

  say "$name: QEMU run (timeout ${TIMEOUT_S} s)"
  set +e
  timeout "$TIMEOUT_S" qemu-system-arm \
    -machine netduinoplus2 -nographic -monitor none -serial none \
    -semihosting-config enable=on,target=native \
    -icount shift=0,sleep=off \
    -kernel "$dir/firmware-qemu.elf" >"$dir/qemu.defmt" 2>"$dir/qemu.stderr"
  status=$?
  set -e
  defmt-print -e "$dir/firmware-qemu.elf" <"$dir/qemu.defmt" >"$dir/qemu-all.txt" 2>&1 || true
  # The run is two boots: the trace, then (after the injected watchdog reset)
  # the recovery boot. Split at the line that arms the watchdog test.
  awk -v first="$dir/qemu.txt" -v reset="$dir/qemu-reset.txt" '
    BEGIN { printf "" > first; printf "" > reset }
    { if (armed) print > reset; else print > first }
    /watchdog test: the control task hangs/ { armed = 1 }' "$dir/qemu-all.txt"
  grep -v '^INFO  tlm \[' "$dir/qemu-all.txt" | tail -n 20 || true
  if [ "$status" -eq 124 ]; then
    echo "FAIL: QEMU timed out after ${TIMEOUT_S} s" >&2
    exit 1
  elif [ "$status" -ne 0 ]; then
    echo "FAIL: the firmware exited with failure ($status: panic or HardFault)" >&2
    cat "$dir/qemu.stderr" >&2 || true
    exit 1
  fi
  if grep -q -E '^(ERROR|WARN)' "$dir/qemu.txt"; then
    echo "FAIL: the firmware logged an error or a warning" >&2
    exit 1
  fi
  if ! grep -q 'trace played' "$dir/qemu.txt"; then
    echo "FAIL: the firmware did not finish the trace" >&2
    exit 1
  fi
  if ! grep -q 'watchdog test: the control task hangs' "$dir/qemu.txt"; then
    echo "FAIL: the firmware did not arm the watchdog test" >&2
    exit 1
  fi
  # The recovery boot reports the reset as its one error, then ends cleanly.
  if ! grep -q -E '^ERROR +last reset: fault 32 ' "$dir/qemu-reset.txt"; then
    echo "FAIL: no watchdog reset reported at the next boot ($dir/qemu-reset.txt)" >&2
    exit 1
  fi
  if grep -E '^(ERROR|WARN)' "$dir/qemu-reset.txt" | grep -q -v -E '^ERROR +last reset: fault 32 '; then
    echo "FAIL: the recovery boot logged another error or a warning" >&2
    exit 1
  fi
  if ! grep -q 'recovery boot done' "$dir/qemu-reset.txt"; then
    echo "FAIL: the recovery boot did not finish" >&2
    exit 1
  fi

  say "$name: bit-for-bit comparison with the host replay, both boots (tests/qemu_replay.rs)"
  CABLE_JOINT_QEMU_LOG="$dir/qemu.txt" CABLE_JOINT_QEMU_RESET_LOG="$dir/qemu-reset.txt" \
    CABLE_JOINT_TRACE="$dir/trace.bin" \
    cargo test "${LOCKED[@]}" --test qemu_replay -- --include-ignored

  say "$name: instructions per control tick (TIM2 under -icount shift=0)"
  cargo run "${LOCKED[@]}" -p host-sim -- ingest "$dir/qemu.txt" \
    --out "$dir/qemu.csv" --stats | tee "$dir/icount.txt"
}

# The firmware as built (probing off), then the same with the dither on
# during the hold: its cost per tick is measured, not only argued. The
# probing trace runs long enough for the move to 30° to end (about 2.7 s)
# and for seven dither periods of hold, with the weight hung during it.
proof "default" "$OUT"
proof "probing" "$OUT/probing" --probe --duration-s 4.5 --load-at-s 3.5 --drive-fault-at-s 4.4

# Processor in the loop: the firmware binary closes the loop on the
# simulated prototype over QEMU's serial ports, and must match the
# host-only run of its logic tick by tick, bit for bit (tests/pil.rs), with
# its instructions per tick counted on the way.
say "PIL: the firmware binary in closed loop (cargo fw-pil, host-sim pil)"
cargo fw-pil "${LOCKED[@]}"
cp "$ELF" "$OUT/firmware-pil.elf"
{
  echo "PIL build:"
  size_of "$OUT/firmware-pil.elf"
} | tee -a "$OUT/sizes.txt"
cargo run "${LOCKED[@]}" -p host-sim -- pil --elf "$OUT/firmware-pil.elf" --out "$OUT/pil" \
  --duration-s 4 --load-at-s 3 --drive-fault-at-s 3.9
CABLE_JOINT_PIL_ELF="$OUT/firmware-pil.elf" cargo test "${LOCKED[@]}" --test pil -- --include-ignored

say "rig workflow under QEMU (scripts/rig-qemu.sh)"
RIG_OUT="$OUT/rig" bash scripts/rig-qemu.sh
cat "$OUT/sizes.txt"
say "QEMU proof passed"
