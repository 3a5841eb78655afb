#!/usr/bin/env bash
# `make demo`: fly the paper's follow_colors mission in the simulator with the live view.
# Starts `hfsmc sim` (MAVLink on udp 127.0.0.1:14550, camera on http 127.0.0.1:8554),
# builds and runs the Python component, then prints the mission result.
set -u
BIN=${BIN:-.venv/bin}
OUT=build/demo
mkdir -p "$OUT"
rm -f "$OUT"/truth.json "$OUT"/report.json "$OUT"/trace.jsonl

"$BIN"/hfsmc build -t python examples/follow_colors/follow_colors.yaml -o "$OUT"/follow_colors || exit 1
"$BIN"/hfsmc sim --world examples/follow_colors/world.yaml --truth "$OUT"/truth.json \
  >"$OUT"/sim.log 2>&1 &
sim=$!
trap 'kill -INT $sim 2>/dev/null; wait $sim 2>/dev/null' EXIT
# Up when it says where it serves; a simulator that cannot take its ports exits instead.
for _ in $(seq 100); do
  grep -q '^sim: MAVLink to' "$OUT"/sim.log 2>/dev/null && break
  kill -0 $sim 2>/dev/null || break
  sleep 0.2
done
if ! kill -0 $sim 2>/dev/null || ! grep -q '^sim: MAVLink to' "$OUT"/sim.log; then
  echo "demo: the simulator did not start:"; cat "$OUT"/sim.log; exit 1
fi

# The web view (docs/web.md) next to the flight: the component's monitor on a free port.
port=$("$BIN"/python -c 'import socket; s = socket.create_server(("127.0.0.1", 0)); print(s.getsockname()[1])')
rm -f "$OUT"/web.out
"$BIN"/hfsmc view --web 0 "127.0.0.1:$port" --model examples/follow_colors/follow_colors.yaml \
  >"$OUT"/web.out 2>"$OUT"/web.log &
web=$!
trap 'kill -INT $sim 2>/dev/null; kill -TERM $web 2>/dev/null; wait $sim $web 2>/dev/null' EXIT
url=""
for _ in $(seq 50); do
  url=$(sed -n 's/^hfsmc view: web view on \(http[^ ]*\) .*/\1/p' "$OUT"/web.out 2>/dev/null)
  [ -n "$url" ] && break
  kill -0 $web 2>/dev/null || break
  sleep 0.2
done
if [ -n "$url" ]; then
  echo "== web view of the flight: $url (open it in a browser) =="
else
  echo "demo: the web view did not start (see $OUT/web.log); flying without it"
fi

echo "== flying follow_colors (about 2.5 min; Ctrl+C lands the drone and stops) =="
# --time-limit: past 4 min the mission stops as on Ctrl+C, landing the drone (exit 124).
"$BIN"/python "$OUT"/follow_colors/follow_colors.py --display --time-limit 240s \
  --monitor "$port" --trace "$OUT"/trace.jsonl --param report="$OUT"/report.json
status=$?
kill -INT $sim 2>/dev/null; kill -TERM $web 2>/dev/null; wait $sim $web 2>/dev/null; trap - EXIT

"$BIN"/python - "$OUT" "$status" <<'PY'
import json, math, sys
out, status = sys.argv[1], int(sys.argv[2])
try:
    report = json.load(open(f"{out}/report.json"))
    truth = json.load(open(f"{out}/truth.json"))
except (OSError, ValueError) as e:
    sys.exit(f"demo: no mission result ({e}); component exit status {status}")
red = next(o for o in truth["objects"] if o["name"] == "red")
land = truth["landing"] or truth["position"]
miss = math.dist((land["north"], land["east"]), (red["north"], red["east"]))
ok = report["stages"] == ["green", "blue", "green", "red"] and miss < 1.0 and not truth["armed"]
print()
print(f"== mission {'SUCCEEDED' if ok else 'FAILED'} (component exit {status}) ==")
print(f"   stages reached: {' -> '.join(report['stages'])}")
print(f"   landed at north {land['north']:.2f} m, east {land['east']:.2f} m: "
      f"{miss:.2f} m from the red object; armed: {truth['armed']}")
print(f"   flight {truth['track']['flight_time']:.0f} s, {truth['track']['distance']:.0f} m flown")
if status == 124:
    print("   the mission's time limit (240 s) ran out: the drone landed where it was")
print(f"   files: {out}/trace.jsonl (trace), {out}/report.json, {out}/truth.json (simulator's truth)")
print(f"   replay it in the browser: hfsmc view --web 8080 --replay {out}/trace.jsonl "
      "--model examples/follow_colors/follow_colors.yaml")
print("   draw it: hfsmc diagram examples/follow_colors/follow_colors.yaml -o build/follow_colors.svg")
print("   edit it in the browser: hfsmc edit examples/follow_colors/follow_colors.yaml "
      "(open the URL it prints; docs/editor.md)")
sys.exit(0 if ok else 1)
PY
