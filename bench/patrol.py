#!/usr/bin/env python3
"""The patrol pair's CPU per component (issue 30): examples/patrol_pair with r1 in Python
and r2 in C++ (Release), against ``hfsmc sim --robot diffdrive`` on loopback, as
tests/test_patrol_pair.py runs them, until both stop in Done.

Each process's CPU is its user + system time over its whole life, from ``wait4``'s
rusage (every thread, as ``time`` reports it), divided by its wall time: % of one core.
The simulator's is given beside (it drives both robots and answers their goals).

Usage::

    python bench/patrol.py                # one run, about 30 s (+ the C++ build the first time)
    python bench/patrol.py --runs 3 --json bench/results.json
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from cpp import build_cpp, build_python  # bench/cpp.py, beside this script
from report import hfsmc_revision, loadavg, machine, merge_json, table
from ros2 import LOOPBACK, ros2_domain

HERE = Path(__file__).resolve().parent
EXAMPLE = HERE.parent / "examples" / "patrol_pair"
WORK = HERE / "_work" / "patrol"
KEY = "patrol_pair"
LIMIT_S = 120


def reap(procs: dict[str, subprocess.Popen[bytes]], started: dict[str, float],
         got: dict[str, dict[str, float]], deadline: float) -> None:
    """Wait (bounded) for each of ``procs`` with wait4: its exit status, wall and CPU time."""
    while any(n not in got for n in procs) and time.monotonic() < deadline:
        for name, p in procs.items():
            if name in got:
                continue
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid == 0:
                continue
            p.returncode = os.waitstatus_to_exitcode(status)
            wall = time.monotonic() - started[name]
            cpu = usage.ru_utime + usage.ru_stime
            got[name] = {"status": p.returncode, "wall_s": wall, "cpu_s": cpu,
                         "percent": 100.0 * cpu / wall}
        time.sleep(0.05)


def one_run(py: Path, cpp: Path) -> dict[str, dict[str, float]]:
    with ros2_domain() as dom:
        env = {"ROS_DOMAIN_ID": str(dom), "PATH": "/usr/bin:/bin", "CYCLONEDDS_URI": LOOPBACK}
        started: dict[str, float] = {}
        procs: dict[str, subprocess.Popen[bytes]] = {}
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                                "--world", str(EXAMPLE / "world.yaml"), "--domain", str(dom)],
                               env={**os.environ, **env}, stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
        started["sim"] = time.monotonic()
        try:
            for name, cmd in (("r1 (Python)", [sys.executable, str(py)]), ("r2 (C++)", [str(cpp)])):
                robot = name.split()[0]
                procs[name] = subprocess.Popen(
                    [*cmd, "--config", str(EXAMPLE / f"{robot}.yaml"), "--until", f"{LIMIT_S}s"],
                    env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                started[name] = time.monotonic()
            got: dict[str, dict[str, float]] = {}
            reap(procs, started, got, time.monotonic() + LIMIT_S + 30)
            sim.send_signal(2)
            reap({"sim": sim}, started, got, time.monotonic() + 30)
        finally:
            for p in [*procs.values(), sim]:
                if p.returncode is None:
                    p.kill()
                    p.wait(10)
    bad = {n: g["status"] for n, g in got.items() if g["status"] != 0}
    if bad or len(got) != 3:
        raise SystemExit(f"a process did not end well: {bad or got}")
    return got


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)
    WORK.mkdir(parents=True, exist_ok=True)
    py = build_python(EXAMPLE / "robot.yaml", WORK / "python")
    cpp = build_cpp(EXAMPLE / "robot_cpp.yaml", WORK / "cpp").exe
    load0 = loadavg()
    runs = [one_run(py, cpp) for _ in range(args.runs)]
    names = list(runs[0])
    figures: dict[str, Any] = {
        n: {"percent_median": round(statistics.median(r[n]["percent"] for r in runs), 2),
            "percent_runs": [round(r[n]["percent"], 2) for r in runs],
            "wall_s_median": round(statistics.median(r[n]["wall_s"] for r in runs), 1)}
        for n in names}
    figures["loadavg"] = [load0, loadavg()]
    figures["revision"] = hfsmc_revision()
    figures["machine"] = machine()
    for line in table([[n, f"{figures[n]['percent_median']:.2f}",
                        " / ".join(f"{x:.2f}" for x in figures[n]["percent_runs"]),
                        f"{figures[n]['wall_s_median']:.1f}"] for n in names],
                      ["process", "CPU % of a core", "runs", "wall s"]):
        print(line)
    print(f"load average {load0} -> {loadavg()}")
    if args.json is not None:
        merge_json(args.json, KEY, figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
