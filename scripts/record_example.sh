#!/usr/bin/env bash
# Make examples/follow_colors/flight.mcap, the recorded flight the README replays:
# follow_colors (Python) flown in the simulator with a 160x120 camera at 5 frames a second
# (the world's 320x240 at 15 would make it 10 times larger), stopped by its 60 s time limit (it lands).
# Usage: scripts/record_example.sh [OUT.mcap]   (about 80 s)
set -eu
BIN=$(cd "${BIN:-.venv/bin}" && pwd)
OUT=${1:-examples/follow_colors/flight.mcap}
work=$(mktemp -d)
trap 'kill -INT $sim 2>/dev/null; wait $sim 2>/dev/null; rm -rf "$work"' EXIT
sed 's/camera: {width: 320, height: 240, hfov_deg: 80, fps: 15}/camera: {width: 160, height: 120, hfov_deg: 80, fps: 5}/' examples/follow_colors/world.yaml > "$work/world.yaml"
grep -q 'height: 120, hfov_deg: 80, fps: 5}' "$work/world.yaml"
"$BIN"/hfsmc build -t python examples/follow_colors/follow_colors.yaml -o "$work/fc" >/dev/null
"$BIN"/hfsmc sim --world "$work/world.yaml" --mavlink udpout:127.0.0.1:14850 \
  --camera-port 8854 >"$work/sim.log" 2>&1 &
sim=$!
sleep 2
printf '{"interfaces": {"drone": {"url": "udpin:127.0.0.1:14850"}, "camera": {"url": "http://127.0.0.1:8854/bottom.mjpg"}}}\n' \
  >"$work/config.yaml"
status=0
(cd "$work" && "$BIN"/python fc/follow_colors.py --config config.yaml --time-limit 60s \
  --param report=report.json --record recording.mcap) || status=$?
[ "$status" = 124 ] || { echo "record_example: the flight ended with status $status, not 124"; exit 1; }
mv "$work/recording.mcap" "$OUT"
ls -l "$OUT"
