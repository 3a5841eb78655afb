"""`hfsmc sim --robot diffdrive`: ground robots in a world of walls and boxes, on ROS 2.

The physics steps every 20 ms against the monotonic clock with absolute deadlines;
simulated time is steps * 20 ms, so readings depend only on the world, its seed and the
step at which each cmd_vel arrives. SIGINT and SIGTERM stop cleanly (truth written, nodes
gone, exit 0). docs/worlds.md, "Ground robots", says what it publishes.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import json
import math
import signal
import sys
import time
from collections.abc import Iterator
from types import FrameType
from typing import IO, Any

from hfsmc.fsutil import write_atomic
from hfsmc.sim.ground import lockstep as ground_lockstep
from hfsmc.sim.ground.sim import STEP_S, GroundSim
from hfsmc.sim.ground.world import load_ground_world
from hfsmc.sim.options import OutputError, open_outputs
from hfsmc.sim.options import fail as _fail
from hfsmc.sim.options import seconds as _seconds
from hfsmc.sim.options import speedup as _speedup
from hfsmc.sim.world import WorldError

ROBOTS = ("diffdrive",)
TRUTH_LOG_S = 0.5
DISTROS = ("jazzy", "humble")


class GroundRun:
    """The loop: commands in, one step, readings out, the truth now and then."""

    def __init__(self, sim: GroundSim, nodes: Any, truth: str | None,
                 truth_log: IO[str] | None) -> None:
        self.sim, self.nodes = sim, nodes
        self.truth_path, self.truth_log = truth, truth_log
        self.stopping = False
        self._truth_failed = False

    def log(self, text: str) -> None:
        print(f"sim: [{self.sim.t:7.2f} s] {text}", file=sys.stderr, flush=True)

    def advance(self, duration: float | None) -> bool:
        """Apply the commands that came, step, publish; True when ``duration`` is reached."""
        self.nodes.commands()
        readings = self.sim.step()
        self.nodes.publish(readings)
        steps = self.sim.steps
        if self.truth_path and steps % round(1.0 / STEP_S) == 0:
            self.write_truth()
        if self.truth_log is not None and steps % round(TRUTH_LOG_S / STEP_S) == 0:
            self.log_truth()
        return duration is not None and self.sim.t >= duration - 1e-9

    def run(self, duration: float | None) -> None:
        start = time.monotonic() - self.sim.t
        while not self.stopping:
            if self.advance(duration):
                break
            late = time.monotonic() - (start + self.sim.steps * STEP_S)
            if late < 0:
                time.sleep(-late)
            elif late > 0.5:  # stalled (suspended, overloaded): go on from now, no burst
                start += late

    def write_truth(self) -> None:
        if not self.truth_path:
            return
        try:
            write_atomic(self.truth_path, json.dumps(self.sim.truth(), indent=2) + "\n")
        except OSError as e:
            self._truth_failed_once(f"cannot write the truth file: {e}")

    def log_truth(self) -> None:
        if self.truth_log is None:
            return
        truth = self.sim.truth()
        for r in truth["robots"].values():
            del r["trail"]  # the log is the trail
        try:
            self.truth_log.write(json.dumps(truth, separators=(",", ":")) + "\n")
            self.truth_log.flush()
        except OSError as e:
            self._truth_failed_once(f"cannot write the truth log: {e}")

    def _truth_failed_once(self, text: str) -> None:
        if not self._truth_failed:
            self._truth_failed = True
            self.log(text)

    @contextlib.contextmanager
    def signals(self) -> Iterator[None]:
        def stop(signum: int, frame: FrameType | None) -> None:
            self.stopping = True

        old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            yield
        finally:
            for s, h in old.items():
                signal.signal(s, h)






def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="hfsmc sim --robot diffdrive",
        description="Simulated differential-drive robots (TurtleBot 2 size) in a world of "
                    "walls and boxes, on ROS 2 topics (cmd_vel in; odom, scan, events/bumper "
                    "and /clock out).")
    p.add_argument("--robot", choices=ROBOTS, required=True, help="the kind of robot")
    p.add_argument("--world", metavar="FILE", required=True, help="world file (YAML)")
    p.add_argument("--seed", type=int, metavar="N", help="override the world's seed")
    p.add_argument("--domain", metavar="ID",
                   help="ROS_DOMAIN_ID (default: $ROS_DOMAIN_ID, else 0)")
    p.add_argument("--distro", choices=DISTROS, default="jazzy",
                   help="the ROS 2 wire details to follow (default jazzy)")
    p.add_argument("--truth", metavar="FILE",
                   help="write the ground truth (JSON) every simulated second and at exit")
    p.add_argument("--truth-log", metavar="FILE",
                   help=f"append the truth as one JSON line every {TRUTH_LOG_S} simulated "
                        "seconds and at exit")
    p.add_argument("--duration", type=_seconds, metavar="S",
                   help="exit after S simulated seconds (default: until SIGINT/SIGTERM)")
    p.add_argument("--lockstep", metavar="[HOST:]PORT",
                   help="be the time master of one component started with --clock sim:PORT "
                        "(loopback unless a host is named): step only when it is done")
    p.add_argument("--speedup", type=_speedup, metavar="N",
                   help="with --lockstep: hold simulated time to N times real time")
    p.add_argument("--component-gone", choices=("stop", "realtime"), default="stop",
                   help="with --lockstep, when the component ends or dies: stop (the default) "
                        "or go on in real time")
    return p




def main(argv: list[str]) -> int:
    """`hfsmc sim --robot diffdrive ...`: 0 when stopped cleanly, 2 on a usage error."""
    args = parser().parse_args(argv)
    if args.speedup is not None and args.lockstep is None:
        return _fail("--speedup needs --lockstep (in real time the simulator runs at 1x)")
    try:
        world = load_ground_world(args.world)
    except WorldError as e:
        return _fail(str(e))
    if args.seed is not None:
        world = dataclasses.replace(world, seed=args.seed)
    from hfsmc.sim.ground.node import GroundNodes, NodeError

    sim = GroundSim(world)
    try:
        nodes = GroundNodes(sim, args.domain, args.distro)
    except NodeError as e:
        return _fail(str(e))
    try:
        server, truth_log = open_outputs(args, nodes.close)
    except OutputError as e:
        return _fail(str(e))
    run = GroundRun(sim, nodes, args.truth, truth_log)
    try:
        with run.signals():
            names = ", ".join(f"{r.name} in {r.namespace}" for r in sim.robots)
            more = f", {server.describe()}" if server is not None else ""
            print(f"sim: {len(sim.robots)} diffdrive robot(s) ({names}), ROS 2 domain "
                  f"{nodes.domain} ({args.distro}), world {world.name}{more}", file=sys.stderr,
                  flush=True)
            try:
                if server is None or ground_lockstep.drive(
                        run, server, args.duration, args.speedup or math.inf,
                        args.component_gone):
                    run.run(args.duration)
            finally:
                run.write_truth()
                run.log_truth()
    finally:
        nodes.close()
        if server is not None:
            server.close()
        if truth_log is not None:
            truth_log.close()
    return 0
