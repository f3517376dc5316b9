#!/usr/bin/env bash
# The rig workflow under QEMU, step by step, each step one command (README,
# "Operating the prototype"): the PIL firmware on QEMU with the simulated
# prototype stands in for the rig, and `host-sim link` operates it through
# the firmware's link exactly as it would the prototype's USART2. Each
# `host-sim pil` run is one power-on of the "rig".
#
#   1. "flash": build the PIL firmware (cargo fw-pil);
#   2. power on with the rope wheel unhooked (the simulated plant's
#      motor_decoupled) and record the no-load motor run through the link
#      (bm-noload at a quarter of its length: a motor-only program, no
#      homing, slider 1 must not move);
#   3. power on with the wheel hooked and record the JAE's identification
#      run: the jae-ident scenario's commands (check, homing, motor-side
#      sines, joint free) at a quarter of their length, telemetry every
#      4th tick, the magnetic encoder fitted; `host-sim identify
#      --procedure jae` on it writes jae.toml;
#   4. power on again, load jae.toml and record the no-load tension run
#      (tension-ident, the JAE in the loop, a quarter of its length);
#      `host-sim identify --procedure all` on the three recordings (bm,
#      jae, tension, the seed's order: each uses the one before) writes
#      identified.toml;
#   5. power on again, connect, load identified.toml (validated here and on
#      the MCU), run the loading scenario's commands (check, homing, 30° and
#      hold; the simulated 50 g weight is hung at 4.5 s) and record 5.5 s, with
#      the live view on (in a tmux pane, read back into live-view.txt, and
#      closed with q as a person would);
#   6. read the recorded log back: host-sim estimate replays it from where
#      homing ended, with the fused force and its bound;
#   7. power on with a soft object at the tip (10° out, 1000 N/m), load
#      identified.toml and run the grip scenario's commands: the firmware
#      closes onto the object and regulates its force estimate to 2 N, then
#      opens; recorded.
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
cargo build -q "${LOCKED[@]}" -p host-sim
HOST_SIM="${CARGO_TARGET_DIR:-target}/debug/host-sim"

# Power the "rig" on: the PIL firmware with the link on $PORT, for $1
# seconds of firmware time, its files in $OUT/$2; returns when the link's
# port accepts a connection.
RIG=""
power_on() {
  # In a session of its own, so that a failed step stops QEMU with it (a
  # QEMU left behind would keep the port and answer the next run).
  setsid "$HOST_SIM" pil --elf "$OUT/firmware-pil.elf" --out "$OUT/$2" --link-port "$PORT" \
    --duration-s "$1" "${@:3}" >"$OUT/$2.stdout" 2>"$OUT/$2.stderr" &
  RIG=$!
  for _ in $(seq 1 300); do
    (exec 3<>"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && return 0
    kill -0 "$RIG" 2>/dev/null || { cat "$OUT/$2.stderr"; return 1; }
    sleep 0.2
  done
  echo "the rig's link never opened" >&2
  return 1
}
trap '[ -n "$RIG" ] && kill -- -"$RIG" 2>/dev/null || true' EXIT

say "1. the PIL firmware (cargo fw-pil)"
cargo fw-pil "${LOCKED[@]}"
cp "${CARGO_TARGET_DIR:-target}/thumbv7em-none-eabihf/release/firmware" "$OUT/firmware-pil.elf"

say "2. the no-load motor run through the link, the rope wheel unhooked (bm-noload, quarter length)"
printf '# the rope wheel unhooked, slider 1 clamped (seed Sect. 4.2)\nmotor_decoupled = true\n' \
  >"$OUT/unhooked.toml"
power_on 10 pil-bm --drive-fault-at-s -1 --load-n 0 --plant "$OUT/unhooked.toml"
"$HOST_SIM" link --port "tcp:127.0.0.1:$PORT" --decimation 4 --scenario bm-noload \
  --duration-scale 0.25 --record "$OUT/bm.csv"
wait "$RIG"

say "3. the JAE's identification run through the link (jae-ident, quarter length), identified"
power_on 15 pil-ident --drive-fault-at-s -1 --load-n 0
# A record every 4th tick, as on the board, whose link carries about 590
# records a second (78-byte frames at 460 800 baud): each record carries
# the mean current applied since the last one sent (telemetry format 3),
# which the identification's replay holds over the ticks between rows.
"$HOST_SIM" link --port "tcp:127.0.0.1:$PORT" --decimation 4 --scenario jae-ident \
  --duration-scale 0.25 --magnetic --record "$OUT/calibration.csv"
wait "$RIG"
"$HOST_SIM" identify --procedure jae --log "$OUT/calibration.csv" --config-out "$OUT/jae.toml" \
  | tail -n 8

say "4. the no-load tension run through the link with jae.toml (tension-ident, quarter length); all three identified"
power_on 17 pil-tension --drive-fault-at-s -1 --load-n 0
"$HOST_SIM" link --port "tcp:127.0.0.1:$PORT" --config "$OUT/jae.toml" --decimation 4 \
  --scenario tension-ident --duration-scale 0.25 --record "$OUT/tension.csv"
wait "$RIG"
"$HOST_SIM" identify --procedure all --log "bm=$OUT/bm.csv" "jae=$OUT/calibration.csv" \
  "tension=$OUT/tension.csv" --config-out "$OUT/identified.toml" --json "$OUT/identified.json" \
  | tail -n 12

say "5. the loading scenario with identified.toml, recorded, with the live view"
power_on 7 pil-loading --load-at-s 4.5 --drive-fault-at-s -1
LINK=("$HOST_SIM" link --port "tcp:127.0.0.1:$PORT" --config "$OUT/identified.toml"
  --decimation 1 --scenario loading --duration-s 5.5 --record "$OUT/loading.csv")
if command -v tmux >/dev/null; then
  # A person at a terminal: the view is read back from the pane at the end
  # of the run, then closed with q.
  TMUX_SOCKET="rig-qemu-$$"
  rm -f "$OUT/link.rc"
  tmux -L "$TMUX_SOCKET" new-session -d -s rig -x 140 -y 40 \
    "$(printf '%q ' "${LINK[@]}") --view 2>$(printf '%q' "$OUT/link.stderr"); echo \$? > $(printf '%q' "$OUT/link.rc"); sleep 600"
  for _ in $(seq 1 1500); do
    tmux -L "$TMUX_SOCKET" capture-pane -p -t rig >"$OUT/live-view.txt"
    grep -q "run finished: q quits" "$OUT/live-view.txt" && break
    [ -f "$OUT/link.rc" ] && break
    sleep 0.4
  done
  tmux -L "$TMUX_SOCKET" send-keys -t rig q
  for _ in $(seq 1 100); do [ -f "$OUT/link.rc" ] && break; sleep 0.2; done
  tmux -L "$TMUX_SOCKET" kill-server || true
  cat "$OUT/link.stderr"
  echo "the live view at the end of the run ($OUT/live-view.txt):"
  cat "$OUT/live-view.txt"
  [ "$(cat "$OUT/link.rc" 2>/dev/null)" = 0 ] || { echo "host-sim link failed" >&2; exit 1; }
  grep -q "run finished: q quits" "$OUT/live-view.txt"
  grep -q "phase running" "$OUT/live-view.txt"
else
  echo "(tmux not installed: recording without the live view)"
  "${LINK[@]}"
fi
wait "$RIG"
RIG=""

say "6. the recorded log, replayed through the core from where homing ended"
"$HOST_SIM" estimate --log "$OUT/loading.csv" --config "$OUT/identified.toml" \
  --out "$OUT/loading-estimate.csv"
say "7. a grip over the link: an object 10° out, 2 N, with identified.toml"
power_on 16 pil-grip --object-at-deg 10 --drive-fault-at-s -1 --load-n 0
"$HOST_SIM" link --port "tcp:127.0.0.1:$PORT" --config "$OUT/identified.toml" \
  --decimation 1 --scenario grip --record "$OUT/grip.csv"
wait "$RIG"
RIG=""
say "rig workflow under QEMU passed ($OUT)"
