"""`hfsmc sim --robot diffdrive --lockstep`: the ground robots as the time master of one
component, over ROS 2 topics (schemas/lockstep.md, "Over ROS 2").

The protocol is the drone's (hfsmc/sim/lockstep.py) with the ROS 2 topics in place of
MAVLink datagrams and camera frames:

- the hellos name topics: the component lists the resolved topics it subscribes and
  publishes, the simulator those it publishes and subscribes; before the first step the
  simulator waits until its endpoints and the component's have matched (bounded), so that
  no sample of the run is lost to discovery;
- the component says ``{"next": T, "sent": 0, "topics": {"/cmd_vel": n}}``: n samples
  published on that topic since it connected; the simulator waits until it has received
  them, steps to the last step at or before T (applying the latest cmd_vel at the first
  step) and answers ``{"t": T, "now": S, "sent": 0, "frame": 0, "frame_t": 0,
  "topics": {"/odom": n, "/scan": m, ...}}``: samples published on each topic since the
  component connected; the component's ros2 interface waits until it holds them.
"""

from __future__ import annotations

import json
import math
import time
from typing import Any

from hfsmc.sim.lockstep import (
    ANSWER_WAIT_S,
    DATAGRAM_WAIT_S,
    PROTOCOL,
    VERSION,
    LockstepError,
    Server,
)

MATCH_WAIT_S = 10.0  # discovery between the simulator's nodes and the component's
POLL_S = 0.0005


def drive(run: Any, server: Server, duration: float | None, speedup: float,
          when_gone: str) -> bool:
    """Drive in lockstep until stopped, ``duration``, or the component's end; True when the
    simulator is to go on in real time (``when_gone`` == "realtime" and the component went)."""
    nodes, sim = run.nodes, run.sim
    step_us = round(sim.step_s * 1e6)
    run.log(f"lockstep: waiting for a component on {server.describe().partition(' on ')[2]}")
    got = server.accept(lambda: run.stopping)
    if got is None:
        return False
    channel, name = got
    hello = server.hello
    theirs_in = {t for t in hello.get("subscribe") or () if isinstance(t, str)}
    theirs_out = {t for t in hello.get("publish") or () if isinstance(t, str)}
    channel.send({"hello": PROTOCOL, "version": VERSION, "step_us": step_us,
                  "publish": sorted(nodes.published_topics()),
                  "subscribe": sorted(nodes.subscribed_topics())})
    if not _wait(lambda: nodes.matched(theirs_in, theirs_out), MATCH_WAIT_S, run):
        run.log(f"lockstep: the component's topics did not all match in {MATCH_WAIT_S:g} s "
                "(going on: samples sent before they match are lost)")
    nodes.count_from_now()
    rate = "as fast as it goes" if math.isinf(speedup) else f"{speedup:g}x real time"
    run.log(f"lockstep: component {name} connected; simulated time runs {rate}")
    wall0 = time.monotonic() - sim.t / speedup
    while not run.stopping:
        try:
            msg = channel.read(lambda: run.stopping, ANSWER_WAIT_S)
        except LockstepError as e:
            run.log(f"lockstep: the component broke the protocol ({e}); it is dropped")
            msg = None
        if msg is None or "bye" in msg:
            if run.stopping:
                return False
            why = f" ({msg['bye']})" if msg is not None else ""
            then = "goes on in real time" if when_gone == "realtime" else "stops"
            run.log(f"lockstep: the component has gone{why}; the simulator {then}")
            server.channel = None
            channel.close()
            return when_gone == "realtime"
        until, topics = msg.get("next"), msg.get("topics") or {}
        if not isinstance(until, int) or until < 0 or not isinstance(topics, dict) \
                or not all(isinstance(v, int) and v >= 0 for v in topics.values()):
            run.log(f"lockstep: not a request: {json.dumps(msg)[:80]}; the component is dropped")
            channel.close()
            server.channel = None
            return when_gone == "realtime"
        if not _wait(lambda want=topics: nodes.received_all(want), DATAGRAM_WAIT_S, run):
            run.log(f"lockstep: some of the component's samples ({json.dumps(topics)}) did not "
                    f"come in {DATAGRAM_WAIT_S:g} s; going on without them")
        while (sim.steps + 1) * step_us <= until and not run.stopping:
            if run.advance(duration):
                return False
        if not math.isinf(speedup):
            ahead = wall0 + sim.t / speedup - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
        channel.send({"t": until, "now": sim.steps * step_us, "sent": 0, "frame": 0,
                      "frame_t": 0, "topics": nodes.published_counts()})
    return False


def _wait(done: Any, seconds: float, run: Any) -> bool:
    end = time.monotonic() + seconds
    while not done():
        if run.stopping or time.monotonic() > end:
            return False
        time.sleep(POLL_S)
    return True
