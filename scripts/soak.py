#!/usr/bin/env python3
"""`make soak`: fly follow_colors again and again for a while, and record what drifts.

Each round starts `hfsmc sim` on free ports, runs the built component against
it (real processes, MAVLink over UDP and MJPEG over HTTP on 127.0.0.1), and
records the mission's result (stages, landing distance to the red object),
the component's ticks and overruns (its stop summary) and the peak memory of
the component and of the simulator (from wait4). At the end it prints a table
and the verdicts the reliability issue asks for: every mission succeeds,
memory grows less than 5 % from the first round to the last, overruns do not
grow; and writes them as JSON.

Usage::

    python scripts/soak.py --minutes 30 --json build/soak.json
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
MODEL = ROOT / "examples/follow_colors/follow_colors.yaml"
WORLD = ROOT / "examples/follow_colors/world.yaml"
SUMMARY = re.compile(r"(\d+) ticks, (\d+) overruns")


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def wait_rss(proc: subprocess.Popen[bytes], timeout: float) -> tuple[int, int]:
    """Wait for a child; its exit status and peak RSS in KiB (wait4)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
        if pid:
            proc.returncode = os.waitstatus_to_exitcode(status)
            return proc.returncode, usage.ru_maxrss
        time.sleep(0.2)
    proc.kill()
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return proc.returncode, usage.ru_maxrss


def fly(folder: Path, main: Path) -> dict[str, Any]:
    folder.mkdir(parents=True, exist_ok=True)
    udp, http = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM)
    config = {"parameters": {"report": str(folder / "report.json")},
              "interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
                             "camera": {"type": "camera",
                                        "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}
    (folder / "config.yaml").write_text(json.dumps(config))
    with (folder / "sim.log").open("wb") as slog, (folder / "component.log").open("wb") as clog:
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--world", str(WORLD),
                                "--mavlink", f"udpout:127.0.0.1:{udp}", "--camera-port",
                                str(http), "--truth", str(folder / "truth.json")],
                               stdout=slog, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        comp = subprocess.Popen([sys.executable, str(main), "--config",
                                 str(folder / "config.yaml"), "--until", "240s"],
                                stdout=clog, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        status, comp_rss = wait_rss(comp, 300)
        sim.send_signal(signal.SIGINT)
        _, sim_rss = wait_rss(sim, 30)
    log = (folder / "component.log").read_text(errors="replace")
    m = SUMMARY.search(log)
    ticks, overruns = (int(m[1]), int(m[2])) if m else (0, -1)
    try:
        report = json.loads((folder / "report.json").read_text())
        truth = json.loads((folder / "truth.json").read_text())
        red = next(o for o in truth["objects"] if o["name"] == "red")
        land = truth["landing"] or truth["position"]
        miss = math.dist((land["north"], land["east"]), (red["north"], red["east"]))
        stages = report["stages"]
        disarmed = not truth["armed"]
    except (OSError, ValueError, KeyError, StopIteration, TypeError):
        miss, stages, disarmed = float("inf"), [], False
    ok = (status == 0 and stages == ["green", "blue", "green", "red"] and miss < 1.0
          and disarmed)
    return {"ok": ok, "status": status, "stages": stages, "miss_m": round(miss, 3),
            "ticks": ticks, "overruns": overruns, "component_rss_kib": comp_rss,
            "sim_rss_kib": sim_rss}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--minutes", type=float, default=30.0, help="how long to keep flying")
    ap.add_argument("--json", type=Path, help="write the rounds and verdicts here")
    ap.add_argument("--work", type=Path, default=ROOT / "build" / "soak")
    ns = ap.parse_args(argv)
    built = subprocess.run([sys.executable, "-m", "hfsmc", "build", str(MODEL), "-o",
                            str(ns.work / "component")], capture_output=True, text=True)
    if built.returncode != 0:
        print(built.stderr, file=sys.stderr)
        return 1
    main_py = ns.work / "component" / "follow_colors.py"
    end = time.monotonic() + ns.minutes * 60
    rounds: list[dict[str, Any]] = []
    while time.monotonic() < end or not rounds:
        r = fly(ns.work / f"round{len(rounds) + 1:03d}", main_py)
        rounds.append(r)
        print(f"round {len(rounds):3d}: {'ok  ' if r['ok'] else 'FAIL'} miss {r['miss_m']} m, "
              f"{r['ticks']} ticks, {r['overruns']} overruns, component "
              f"{r['component_rss_kib'] / 1024:.1f} MiB, sim {r['sim_rss_kib'] / 1024:.1f} MiB",
              flush=True)
    first, last = rounds[0], rounds[-1]
    growth = {k: round(100 * (last[k] - first[k]) / max(first[k], 1), 2)
              for k in ("component_rss_kib", "sim_rss_kib")}
    over = [r["overruns"] for r in rounds]
    verdicts = {
        "every mission succeeds": all(r["ok"] for r in rounds),
        "memory growth < 5 %": all(g < 5.0 for g in growth.values()),
        "no overrun growth": over[-1] <= max(over[0], 0) + 2 and min(over) >= 0,
    }
    print(f"\n{len(rounds)} rounds in {ns.minutes:g} min; memory growth first -> last round: "
          f"component {growth['component_rss_kib']} %, simulator {growth['sim_rss_kib']} %; "
          f"overruns per round {over}")
    for name, ok in verdicts.items():
        print(f"  {'met   ' if ok else 'MISSED'} {name}")
    if ns.json:
        ns.json.parent.mkdir(parents=True, exist_ok=True)
        ns.json.write_text(json.dumps({"rounds": rounds, "growth_percent": growth,
                                       "verdicts": verdicts}, indent=2) + "\n")
    return 0 if all(verdicts.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
