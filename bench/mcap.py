#!/usr/bin/env python3
"""Speed of the C++ component's MCAP writer (templates/cpp/hfsmc/mcap.hpp).

tests/cpp/mcap_main.cpp, compiled with -O2, writes 1 kB messages to a file under
bench/_work/ (one flush_tick() per 1024 messages) and then times 2000 flush_tick()
calls each after one 64-byte message: MB/s of the writer (records built, data CRC,
fwrite), and what one flush costs (an fflush that hands the bytes to the kernel).
Figures are the median of the rounds. Issue 18's budget for a recording is 30 MB per
minute; the target here is that writing it costs at most 1 % of a core.

Usage::

    python bench/mcap.py                           # 5 rounds of 256 MB
    python bench/mcap.py --quick                   # 3 rounds of 64 MB
    python bench/mcap.py --json bench/results.json
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

from report import finish_targets, hfsmc_revision, loadavg, machine

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
WORK = HERE / "_work" / "mcap"
KEY = "cpp_mcap"
BUDGET_MB_PER_MIN = 30.0  # issue 18: a recording's size budget
TARGET_CORE_PERCENT = 1.0  # writing that budget costs at most this share of one core


def build() -> Path:
    gxx = shutil.which("g++")
    if gxx is None:
        sys.exit("g++ missing: `make deps` installs the C++ tool chain")
    WORK.mkdir(parents=True, exist_ok=True)
    exe = WORK / "mcap_main"
    cmd = [gxx, "-std=c++17", "-O2", "-DNDEBUG", "-I", str(ROOT / "templates" / "cpp"),
           str(ROOT / "tests" / "cpp" / "mcap_main.cpp"), "-o", str(exe)]
    subprocess.run(cmd, check=True, timeout=300)
    return exe


def one_round(exe: Path, mb: int) -> dict[str, float]:
    out = WORK / "bench.mcap"
    try:
        done = subprocess.run([str(exe), "bench", str(out), str(mb)], capture_output=True,
                              text=True, check=True, timeout=600)
    finally:
        out.unlink(missing_ok=True)
    figures: dict[str, float] = json.loads(done.stdout)
    return figures


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="Time the C++ MCAP writer: MB/s of 1 kB messages, "
                                             "cost of one flush_tick().")
    ap.add_argument("--quick", action="store_true", help="3 rounds of 64 MB")
    ap.add_argument("--json", type=Path, metavar="OUT",
                    help=f'merge the figures into OUT under the key "{KEY}"')
    ns = ap.parse_args(argv)
    rounds, mb = (3, 64) if ns.quick else (5, 256)

    def log(s: str = "") -> None:
        print(s, flush=True)

    load_before = loadavg()
    exe = build()
    runs = [one_round(exe, mb) for _ in range(rounds)]
    mb_s = statistics.median(r["mb_per_s"] for r in runs)
    flush_us = statistics.median(r["flush_us"] for r in runs)
    core_percent = BUDGET_MB_PER_MIN / 60.0 / mb_s * 100.0
    log(f"C++ MCAP writer, {rounds} rounds of {mb} MB of 1 kB messages (median):")
    log(f"  {mb_s:.0f} MB/s; one flush_tick() {flush_us:.2f} us; "
        f"{BUDGET_MB_PER_MIN:g} MB/min costs {core_percent:.3f} % of a core")
    figures: dict[str, Any] = {
        "description": "C++ MCAP writer (templates/cpp/hfsmc/mcap.hpp, g++ -O2): MB/s writing 1 kB "
                       "messages to a file (a flush_tick() per 1024 messages; records, data CRC, "
                       "fwrite), and the cost of one flush_tick() after one 64-byte message; "
                       "median of the rounds",
        "mode": "quick" if ns.quick else "full", "machine": machine(), "hfsmc": hfsmc_revision(),
        "rounds": runs, "mb_per_s": round(mb_s, 1), "flush_us": round(flush_us, 2),
        "core_percent_at_budget": round(core_percent, 4)}
    targets = [{"target": f"writing {BUDGET_MB_PER_MIN:g} MB/min costs <= {TARGET_CORE_PERCENT:g} % "
                          "of a core", "value": round(core_percent, 4),
                "met": core_percent <= TARGET_CORE_PERCENT}]
    finish_targets(figures, targets, load_before, ns.json, KEY, log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
