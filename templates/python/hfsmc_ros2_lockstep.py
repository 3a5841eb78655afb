# hfsmc_ros2_lockstep.py: a ros2 interface in lockstep with hfsmc sim (schemas/lockstep.md).
# Copied beside a Python component with a ros2 interface; imports nothing of hfsmc.
"""``--clock sim:PORT`` with the ground robot: the ros2 interface's side of the lockstep
protocol over ROS 2 (schemas/lockstep.md, "Over ROS 2").

The component's hello names the interface's resolved topics; once the simulator has
answered with its own, the interface waits until the endpoints of the topics they share
have matched (no sample of the run is lost to discovery) and counts from then on: each
step says how many samples it published per topic, and the simulator answers how many it
published; before the instant runs, the interface waits until it holds them all. The
ages of its samples are then simulated time: a sample's age counts from the instant
that first held it, so a run is the same on every machine.
"""

from __future__ import annotations

import math
import time
from typing import Any

MATCH_WAIT_S = 10.0
SAMPLES_WAIT_S = 10.0
POLL_S = 0.0005


class Ros2Lockstep:
    """Mixed into hfsmc_ros2.Ros2Node: the Synced driver of hfsmc_simclock."""

    _subs: dict[str, Any]
    _pubs: dict[str, Any]
    _pending: dict[str, Any]
    _lock: Any
    _subscribers: dict[str, int]
    name: str

    def _lockstep_init(self) -> None:
        self._published: dict[str, int] = {}  # resolved topic -> samples written
        self._base_in: dict[str, int] = {}
        self._base_out: dict[str, int] = {}
        self.sim_t: float | None = None  # simulated seconds of this instant, in lockstep
        self._held: dict[str, tuple[int, float]] = {}  # name -> (count, sim time it came)

    def _count_published(self, name: str) -> None:
        topic = self._pubs[name]["topic"]
        self._published[topic] = self._published.get(topic, 0) + 1

    def lockstep_sent(self) -> int:
        return 0  # no MAVLink datagrams

    def lockstep_topics(self) -> dict[str, list[str]]:
        return {"subscribe": sorted({s["topic"] for s in self._subs.values()}),
                "publish": sorted({s["topic"] for s in self._pubs.values()})}

    def _received(self) -> dict[str, int]:
        out: dict[str, int] = {}
        with self._lock:
            for n, s in self._subs.items():
                out[s["topic"]] = out.get(s["topic"], 0) + self._pending[n].count
        return out

    def lockstep_match(self, hello: dict[str, Any]) -> str | None:
        """After the simulator's hello: wait until the shared topics' endpoints match, then
        count from now. Why not, or None."""
        theirs_out = set(hello.get("publish") or ())
        theirs_in = set(hello.get("subscribe") or ())
        end = time.monotonic() + MATCH_WAIT_S
        why = None
        while True:
            with self._lock:
                missing = [s["topic"] for n, s in self._subs.items()
                           if s["topic"] in theirs_out and self._pending[n].publishers == 0]
                missing += [s["topic"] for n, s in self._pubs.items()
                            if s["topic"] in theirs_in and self._subscribers.get(n, 0) == 0]
            if not missing:
                break
            if time.monotonic() > end:
                why = (f"{self.name}: {', '.join(sorted(set(missing)))} did not match the "
                       f"simulator's in {MATCH_WAIT_S:g} s (samples sent before are lost)")
                break
            time.sleep(0.005)
        self._base_in = self._received()
        self._base_out = dict(self._published)
        return why

    def lockstep_counts(self) -> dict[str, int]:
        return {t: n - self._base_out.get(t, 0) for t, n in sorted(self._published.items())}

    def lockstep_sync(self, t_us: int, step: dict[str, Any]) -> str | None:
        """Before the instant at ``t_us``: hold every sample the simulator says it sent."""
        want = step.get("topics") or {}
        mine = {s["topic"] for s in self._subs.values()}
        end = time.monotonic() + SAMPLES_WAIT_S
        while True:
            got = self._received()
            short = {t: n for t, n in want.items() if t in mine and isinstance(n, int)
                     and got.get(t, 0) - self._base_in.get(t, 0) < n}
            if not short:
                break
            if time.monotonic() > end:
                return (f"{self.name}: samples of {', '.join(sorted(short))} did not come in "
                        f"{SAMPLES_WAIT_S:g} s")
            time.sleep(POLL_S)
        self.sim_t = t_us / 1e6
        return None

    def _age(self, name: str, count: int, arrived: float, now: float) -> float:
        """A sample's age: wall time, or in lockstep simulated time since the instant that
        first held it."""
        if not count:
            return math.inf
        if self.sim_t is None:
            return now - arrived
        seen = self._held.get(name)
        if seen is None or seen[0] != count:
            seen = self._held[name] = (count, self.sim_t)
        return self.sim_t - seen[1]
