#!/usr/bin/env bash
# The rig workflow under QEMU, step by step, each step one command (README,
# "Operating the prototype"): the PIL firmware on QEMU with the simulated
# prototype stands in for the rig, and `host-sim link` operates it through
# the firmware's link exactly as it would the prototype's USART2.
#
#   1. "flash": build the PIL firmware (cargo fw-pil);
#   2. identification data: a calibration run (simulated here: host-sim
#      simulate jae-ident) and `host-sim identify` on it, which writes
#      identified.toml;
#   3. start the "rig": host-sim pil with the link on a local TCP port;
#   4. connect, load identified.toml (validated here and on the MCU),
#      set the telemetry rate (every tick here; on the rig's 460 800 baud
#      link, every 10th: 200 Hz), run the loading scenario's command list
#      (check, homing, 30° and hold) and record the stream as a CSV log
#      with progress on the terminal;
#   5. read the recorded log back (host-sim estimate replays it).
#
# Outputs in $RIG_OUT (default target/rig). Usage: scripts/rig-qemu.sh
set -euo pipefail
cd "$(dirname "$0")/.."
OUT="${RIG_OUT:-target/rig}"
PORT="${RIG_PORT:-5555}"
LOCKED=(--locked)
[ "${QEMU_UNLOCKED:-0}" = 1 ] && LOCKED=()
mkdir -p "$OUT"
say() { printf -- '--- %s\n' "$*"; }
HOST_SIM=(cargo run -q "${LOCKED[@]}" -p host-sim --)

say "1. the PIL firmware (cargo fw-pil)"
cargo fw-pil "${LOCKED[@]}"
cp "${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/release/firmware" "$OUT/firmware-pil.elf"

say "2. identification: calibration run and host-sim identify"
"${HOST_SIM[@]}" simulate --scenario jae-ident --out "$OUT/calibration.csv"
"${HOST_SIM[@]}" identify --procedure jae --log "$OUT/calibration.csv" --config-out "$OUT/identified.toml" \
  --json "$OUT/identified.json" | tail -n 5

say "3. the rig: PIL firmware on QEMU, link on tcp:127.0.0.1:$PORT"
"${HOST_SIM[@]}" pil --elf "$OUT/firmware-pil.elf" --out "$OUT/pil" --link-port "$PORT" \
  --duration-s 6 --load-at-s 4.5 --drive-fault-at-s -1 >"$OUT/pil.stdout" 2>"$OUT/pil.stderr" &
RIG=$!
trap 'kill $RIG 2>/dev/null || true' EXIT
for _ in $(seq 1 100); do
  (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && break
  sleep 0.2
done

say "4. operate it: configuration, telemetry rate, the loading scenario, recording"
"${HOST_SIM[@]}" link --port "tcp:127.0.0.1:$PORT" --config "$OUT/identified.toml" \
  --decimation 1 --scenario loading --duration-s 3 --record "$OUT/loading.csv"
wait "$RIG"
trap - EXIT

say "5. the recorded log, replayed through the core"
"${HOST_SIM[@]}" estimate --log "$OUT/loading.csv" --config "$OUT/identified.toml" \
  --out "$OUT/loading-estimate.csv"
say "rig workflow under QEMU passed ($OUT)"
