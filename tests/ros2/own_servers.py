"""Run by tests/test_ros2_own_interfaces.py in a built component's folder (its generated
`dock_msgs` package): the runtime's test servers of the model's own action
`dock_msgs/action/Dock` (on `/dock`) and service `dock_msgs/srv/Beep` (on `/beep`). Beep
answers `said="beep" * times`; a Dock goal is executed, gets one feedback and succeeds with
code 7 and the station it was sent to. Prints one JSON line: every sample the servers took
and wrote (hex, as on the wire), by endpoint; exits once the result has been asked for and
sent, or after 40 s."""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import hfsmc_ros2 as ros2  # type: ignore[import-not-found]
import hfsmc_ros2_rpc as rpc  # type: ignore[import-not-found]
from dock_msgs.action import Dock  # type: ignore[import-not-found]
from dock_msgs.srv import Beep  # type: ignore[import-not-found]

DOMAIN = int(sys.argv[1])


def spy(seen: dict[str, list[str]], key: str, ep: Any) -> None:
    """Keep the hex of every sample ``ep`` takes and writes under ``key``."""
    take, write = ep.reader.take, ep.writer.write

    def taking(n: int) -> Any:
        got = take(n)
        seen[f"{key}.in"] += [bytes(s.__dict__["raw"]).hex() for s in got
                              if s.__dict__.get("raw") is not None]
        return got

    def writing(sample: Any) -> Any:
        seen[f"{key}.out"].append(bytes(sample.__dict__["raw"]).hex())
        return write(sample)

    seen[f"{key}.in"], seen[f"{key}.out"] = [], []
    ep.reader.take, ep.writer.write = taking, writing


def main() -> None:
    node = ros2.Ros2Node("srv", {"node": "dock_server", "domain": DOMAIN})
    goals: dict[bytes, Any] = {}

    def on_goal(gid: bytes, goal: Any) -> bool:
        goals[gid] = goal
        return True

    dock = rpc.ActionServer(node._dp, "/dock", Dock, on_goal, lambda gid: True)
    beep = rpc.ServiceServer(node._dp, "/beep", Beep,
                             lambda r: Beep.Response(ok=True, said=" ".join(["beep"] * r.times)))
    seen: dict[str, list[str]] = {}
    for key, ep in (("beep", beep.ep), ("send_goal", dock.send_ep),
                    ("get_result", dock.result_ep)):
        spy(seen, key, ep)
    feedback_write = dock.feedback_writer.write
    seen["feedback.out"] = []

    def feedback(sample: Any) -> Any:
        seen["feedback.out"].append(bytes(sample.__dict__["raw"]).hex())
        return feedback_write(sample)

    dock.feedback_writer.write = feedback
    t0 = time.monotonic()
    done_at: float | None = None
    while time.monotonic() - t0 < 40:
        beep.poll()
        dock.poll()
        for gid, g in list(dock.goals.items()):
            if g[0] == 1:  # accepted: run it
                dock.execute(gid)
                dock.publish_feedback(gid, Dock.Feedback(distance_remaining=0.75))
            elif g[0] == 2:
                station = goals[gid].station
                dock.finish(gid, 4, Dock.Result(code=Dock.Result.CODE_BLOCKED,
                                                tried=[station]))
        if seen["get_result.out"] and done_at is None:
            done_at = time.monotonic()
        if done_at is not None and time.monotonic() - done_at > 0.5:
            break
        time.sleep(0.01)
    print(json.dumps(seen))
    node.close()


main()
