#!/usr/bin/env python3
"""follow_colors flown in lockstep (``hfsmc sim --lockstep``, ``--clock sim``), in Python
and in C++: wall time as a ratio to the flight's simulated time.

Each flight is the whole mission (take-off to the final state, about 146 s of simulated
time) of examples/follow_colors (Python) or its C++ twin examples/follow_colors_cpp, in
examples/follow_colors/world.yaml, the simulator and the component as two processes on
loopback. Wall time runs from starting the simulator to both processes' exit; the C++
build is kept out of it. Every flight must reach the four stages; the traces of one
language must be byte for byte the same in every round.

Targets (issue 33): about 140 s of flight in <= 15 s of wall time in Python, <= 8 s in C++.

Usage::

    python bench/lockstep.py                      # 3 rounds of each language
    python bench/lockstep.py --only python --rounds 1
    python bench/lockstep.py --json bench/results.json
"""

from __future__ import annotations

import argparse
import json
import resource
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from report import finish_targets, hfsmc_revision, loadavg, machine, table  # bench/report.py

ROOT = Path(__file__).resolve().parent.parent
FOLLOW = ROOT / "examples/follow_colors"
TWIN = ROOT / "examples/follow_colors_cpp/follow_colors_cpp.yaml"
WORK = ROOT / "bench/_work"
KEY = "lockstep"
HFSMC = [sys.executable, "-m", "hfsmc"]
TARGET_S = {"python": 15.0, "cpp": 8.0}


def free_port(kind: int) -> int:
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def build(lang: str, tmp: Path) -> list[str]:
    if lang == "python":
        out = tmp / "python"
        subprocess.run([*HFSMC, "build", str(FOLLOW / "follow_colors.yaml"), "-o", str(out)],
                       check=True, capture_output=True)
        return [sys.executable, str(out / "follow_colors.py")]
    out = WORK / "lockstep_cpp"
    r = subprocess.run([*HFSMC, "build", "-t", "cpp", str(TWIN), "-o", str(out), "--compile"],
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise SystemExit(f"the C++ twin did not build:\n{r.stderr[-3000:]}")
    return [str(out / "build" / "follow_colors_cpp")]


def fly(command: list[str], folder: Path) -> dict[str, Any]:
    """One lockstep flight: wall time, simulated time, CPU of both processes, the trace."""
    folder.mkdir(parents=True)
    udp, http, port = (free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_STREAM),
                       free_port(socket.SOCK_STREAM))
    config = folder / "config.yaml"
    config.write_text(json.dumps({
        "parameters": {"report": str(folder / "report.json")},
        "interfaces": {"drone": {"type": "mavlink", "url": f"udpin:127.0.0.1:{udp}"},
                       "camera": {"type": "camera",
                                  "url": f"http://127.0.0.1:{http}/bottom.mjpg"}}}))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    with (folder / "sim.log").open("wb") as slog, (folder / "component.log").open("wb") as clog:
        sim = subprocess.Popen([*HFSMC, "sim", "--world", str(FOLLOW / "world.yaml"),
                                "--mavlink", f"udpout:127.0.0.1:{udp}", "--camera-port",
                                str(http), "--lockstep", str(port)],
                               stdout=slog, stderr=subprocess.STDOUT)
        comp = subprocess.run([*command, "--config", str(config), "--clock", f"sim:{port}",
                               "--trace", str(folder / "trace.jsonl"), "--until", "240s"],
                              stdout=clog, stderr=subprocess.STDOUT, timeout=600)
        sim.wait(timeout=60)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    trace = (folder / "trace.jsonl").read_bytes()
    last = json.loads(trace.splitlines()[-1])
    report = json.loads((folder / "report.json").read_text())
    if comp.returncode != 0 or report["stages"] != ["green", "blue", "green", "red"]:
        raise SystemExit(f"{folder}: the mission failed: "
                         f"{(folder / 'component.log').read_text()[-2000:]}")
    return {"wall_s": wall, "sim_s": last["t"] / 1000,
            "cpu_s": (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime),
            "trace": trace}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", choices=("python", "cpp"), help="one language only")
    ap.add_argument("--rounds", type=int, default=3, help="flights of each language")
    ap.add_argument("--json", type=Path, help=f'merge the figures into this file under "{KEY}"')
    ns = ap.parse_args(argv)
    languages = [ns.only] if ns.only else ["python", "cpp"]
    if "cpp" in languages and shutil.which("cmake") is None:
        print("bench/lockstep.py: cmake is not installed (`make deps`)", file=sys.stderr)
        return 1
    load_before = loadavg()
    figures: dict[str, Any] = {"machine": machine(), "hfsmc": hfsmc_revision(),
                               "rounds": ns.rounds}
    WORK.mkdir(parents=True, exist_ok=True)
    rows, targets = [], []
    with tempfile.TemporaryDirectory(dir=WORK) as d:
        tmp = Path(d)
        commands = {lang: build(lang, tmp) for lang in languages}
        for lang in languages:
            flights = [fly(commands[lang], tmp / f"{lang}-{i}") for i in range(ns.rounds)]
            same = all(f["trace"] == flights[0]["trace"] for f in flights)
            wall = statistics.median(f["wall_s"] for f in flights)
            sim = flights[0]["sim_s"]
            cpu = statistics.median(f["cpu_s"] for f in flights)
            figures[lang] = {"wall_s": round(wall, 2), "sim_s": sim,
                             "ratio": round(wall / sim, 4), "speed": round(sim / wall, 1),
                             "cpu_s": round(cpu, 2), "identical_traces": same,
                             "walls_s": [round(f["wall_s"], 2) for f in flights]}
            rows.append([lang, f"{sim:.1f}", f"{wall:.2f}", f"{wall / sim:.3f}",
                         f"{sim / wall:.0f}x", f"{cpu:.2f}", "yes" if same else "NO"])
            targets.append({"target": f"{lang}: follow_colors in lockstep, wall <= "
                                      f"{TARGET_S[lang]:g} s (median of {ns.rounds})",
                            "value": f"{wall:.2f} s", "met": wall <= TARGET_S[lang] and same})
    for line in table(rows, ["language", "simulated s", "wall s", "wall/sim", "speed",
                             "CPU s", "same traces"]):
        print(line)
    finish_targets(figures, targets, load_before, ns.json, KEY, print)
    return 0 if all(t["met"] for t in targets) else 1


if __name__ == "__main__":
    sys.exit(main())
