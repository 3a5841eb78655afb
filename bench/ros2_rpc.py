#!/usr/bin/env python3
"""ROS 2 services and actions on loopback: call -> response and goal -> accepted (issue 30).

In one run, in a ROS 2 domain no test holds meanwhile, on loopback (bench/ros2.py's
``CYCLONEDDS_URI``: 127.0.0.1, no multicast), one after the other on the same topics:

1. **a Python component** (bench/models/ros2_rpc.yaml, period 1 ms) calls a
   std_srvs/srv/Trigger service and sends a goal of its own action
   (bench/models/bench_msgs/action/Count.action) against the runtime's test servers
   (hfsmc_ros2_rpc.ServiceServer and ActionServer, answering at once, woken by a WaitSet);
   for each exchange it notes the delay from its call or send_goal to the first instant whose
   snapshot says `done` or `accepted` (the wait for the next 1 ms instant included, as
   bench/ros2.py's "publish -> snapshot");
2. **the floor**: a bare cyclonedds-python client and server (IDL dataclasses, the binding's
   own serializer, no hfsmc) exchanging the same requests and replies (rmw_cyclonedds_cpp's
   request header and the same message) on the same topics and types, the client timing
   each round trip from its write to the reply's take on a WaitSet.

It reports p50, p99 and max of each, and the component's p50 and p99 over the floor's.
The C++ row is the twin model bench/models/ros2_rpc.cpp.yaml (built Release by
bench/cpp.py's build_cpp), against the same servers.

Usage::

    python bench/ros2_rpc.py                 # about half a minute
    python bench/ros2_rpc.py --quick         # a few seconds
    python bench/ros2_rpc.py --json bench/results.json

The servers and the bare pair are bench/ros2_rpc_peers.py.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from component import busy_percent, cpu_counters  # bench/, beside this script
from cpp import build_cpp, build_python
from report import finish_targets, hfsmc_revision, loadavg, machine, table
from ros2 import LOOPBACK, Procs, must_succeed, percentiles, ros2_domain

HERE = Path(__file__).resolve().parent
MODEL = HERE / "models" / "ros2_rpc.yaml"
MODEL_CPP = HERE / "models" / "ros2_rpc.cpp.yaml"
PEERS = HERE / "ros2_rpc_peers.py"
WORK = HERE / "_work" / "ros2_rpc"
KEY = "ros2_rpc"
KINDS = ("call", "goal")  # call -> response; send_goal -> accepted
PERIOD_MS = 1  # the client model's period: an answer is seen at an instant, never between
LANGS = ("Python", "C++")


@dataclass(frozen=True)
class Mode:
    exchanges: int  # of each kind
    warmup: int  # exchanges of each kind dropped at the start (discovery, first handshakes)


FULL = Mode(exchanges=1000, warmup=20)
QUICK = Mode(exchanges=80, warmup=10)


# -- the measurement -----------------------------------------------------------------
def latencies(path: Path, warmup: int) -> dict[str, list[list[int]]]:
    """The file's "KIND NS [INSTANTS]" lines, by kind, the first ``warmup`` of each dropped."""
    out: dict[str, list[list[int]]] = {k: [] for k in KINDS}
    for line in path.read_text(encoding="ascii").splitlines():
        kind, *values = line.split()
        out[kind].append([int(v) for v in values])
    return {k: v[warmup:] for k, v in out.items()}


def figures_of(rows: list[list[int]]) -> dict[str, Any]:
    """p50/p99/max of the delays; for a component, the share of answers its first instant
    after the call saw (within one period)."""
    fig: dict[str, Any] = percentiles([r[0] for r in rows])
    if rows and len(rows[0]) > 1:
        fig["next_instant_percent"] = round(100 * sum(r[1] <= 1 for r in rows) / len(rows), 1)
    return fig


def measure(mode: Mode, log: Callable[[str], None]) -> dict[str, Any]:
    WORK.mkdir(parents=True, exist_ok=True)
    script = build_python(MODEL, WORK / "py")
    exe = build_cpp(MODEL_CPP, WORK / "cpp").exe
    command = {"Python": [sys.executable, str(script)], "C++": [str(exe)]}
    me = [sys.executable, str(PEERS)]
    runs: dict[str, dict[str, Any]] = {}
    with ros2_domain() as dom:
        env = {**os.environ, "CYCLONEDDS_URI": LOOPBACK, "ROS_DOMAIN_ID": str(dom)}
        budget = 30 + mode.exchanges * 0.05
        for label in ("bare cyclonedds", *LANGS):
            f = WORK / "latency.txt"
            f.unlink(missing_ok=True)
            before = cpu_counters()
            with Procs(env) as ps:
                if label == "bare cyclonedds":
                    ps.start("bare server", [*me, "bare-server", "--seconds", f"{budget:g}"])
                    client = ps.start("bare client", [*me, "bare-client", "--n",
                                                      str(mode.exchanges), "--seconds",
                                                      f"{budget:g}", "--out", str(f)])
                else:
                    ps.start("test servers", [*me, "servers", "--folder", str(script.parent),
                                              "--seconds", f"{budget:g}"])
                    client = ps.start(f"{label} component", [
                        *command[label], "--until", f"{budget:g}s",
                        "--param", f"out={f}", "--param", f"n={mode.exchanges}"])
                client.wait(timeout=budget + 30)
                for _what, p in ps.procs:  # the servers are done once the client is
                    if p.poll() is None:
                        p.terminate()
                results = ps.wait_all(30)
            status, _so, se = next(r for w, r in results.items() if "client" in w
                                   or "component" in w)
            if status != 0 or not f.exists():
                raise SystemExit(f"{label}: exit status {status}\n{se[-3000:]}")
            must_succeed({w: r for w, r in results.items() if r[0] not in (0, -15)})
            got = latencies(f, mode.warmup)
            runs[label] = {k: figures_of(v) for k, v in got.items()}
            runs[label]["machine_busy_percent"] = busy_percent(before, cpu_counters())
            log(f"  {label}: {json.dumps(runs[label])}")
    floor = runs["bare cyclonedds"]
    ratios: dict[str, Any] = {}
    for kind in KINDS:
        ratios[kind] = {lang: {q: round(runs[lang][kind][f"{q}_us"] / floor[kind][f"{q}_us"], 2)
                               for q in ("p50", "p99")} for lang in LANGS}
    return {"latency": {kind: {label: runs[label][kind] for label in ("bare cyclonedds", *LANGS)}
                        for kind in KINDS},
            "machine_busy_percent": {label: r["machine_busy_percent"] for label, r in runs.items()},
            "ratio_to_floor": ratios, "exchanges": mode.exchanges, "warmup_dropped": mode.warmup,
            "period_ms": PERIOD_MS}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="ROS 2 services and actions on loopback: call -> "
                                 "response and goal -> accepted of Python and C++ components against "
                                 "a bare Cyclone DDS request/reply pair.")
    ap.add_argument("--quick", action="store_true", help="fewer exchanges")
    ap.add_argument("--json", type=Path, metavar="OUT",
                    help=f'merge the figures into OUT under the key "{KEY}"')
    ns = ap.parse_args(argv)

    def log(s: str = "") -> None:
        print(s, flush=True)

    mode = QUICK if ns.quick else FULL
    info, revision = machine(), hfsmc_revision()
    load_before = loadavg()
    log(f"machine: {info['cpu']}, {info['cores']} cores; Python {info['python']}; hfsmc "
        f"{revision['version']} at {revision['commit']}{' (modified)' if revision['dirty'] else ''}"
        f"; load average {load_before}")
    log(f"\n== call -> response, send_goal -> accepted: {mode.exchanges} of each ==")
    figs = measure(mode, log)
    for kind in KINDS:
        log(f"\n{'call -> response' if kind == 'call' else 'send_goal -> accepted'}, "
            "microseconds (p50 / p99 / max), over the floor (p50, p99), and the answers "
            f"seen at the first instant after the call ({PERIOD_MS} ms period)")
        rows = []
        for label, f in figs["latency"][kind].items():
            ratio = figs["ratio_to_floor"][kind].get(label)
            rows.append([label, f"{f['p50_us']:g} / {f['p99_us']:g} / {f['max_us']:g}",
                         "-" if ratio is None else f"x{ratio['p50']:g}, x{ratio['p99']:g}",
                         f"{f['next_instant_percent']:g} %" if "next_instant_percent" in f
                         else "-"])
        for line in table(rows, ["client", "latency", "over the floor", "next instant"]):
            log(line)
    figures: dict[str, Any] = {
        "description": "ROS 2 services and actions on loopback (Cyclone DDS): call -> "
                       "response and send_goal -> accepted of a Python and a C++ component (1 ms "
                       "period: to the snapshot that holds the answer) against the "
                       "runtime's test servers, beside a bare cyclonedds-python "
                       "request/reply pair on the same topics (the floor)",
        "quick": ns.quick, "machine": info, "hfsmc": revision, **figs}
    finish_targets(figures, [], load_before, ns.json, KEY, log)
    return 0


if __name__ == "__main__":
    sys.exit(main())
