"""Run by tests/test_ros2_cpp_rpc.py in a folder of generated messages: the runtime's test
action server (navigate_to_pose) and service server (reset) on domain ARGV[1], behaving as
scenario ARGV[2] says, until the client (a C++ component) has ended or ARGV[3] seconds have
passed; prints one JSON line: the request samples received (hex, header included)."""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import hfsmc_ros2 as ros2  # type: ignore[import-not-found]
import hfsmc_ros2_rpc as rpc  # type: ignore[import-not-found]
from nav2_msgs.action import NavigateToPose  # type: ignore[import-not-found]
from std_srvs.srv import Trigger  # type: ignore[import-not-found]

DOMAIN, SCENARIO, LIMIT = int(sys.argv[1]), sys.argv[2], float(sys.argv[3])


def main() -> None:
    node: Any = ros2.Ros2Node("srv", {"node": "s", "domain": DOMAIN})
    raw: list[str] = []
    server = rpc.ActionServer(node._dp, "/navigate_to_pose", NavigateToPose,
                              lambda g, goal: SCENARIO != "reject", lambda g: True)
    trigger = rpc.ServiceServer(node._dp, "/reset", Trigger,
                                lambda r: Trigger.Response(success=True, message="ok"))
    for ep in (server.send_ep, trigger.ep):
        take = ep.reader.take

        def taking(n: int, take: Any = take) -> Any:
            got = take(n)
            raw.extend(bytes(s.__dict__["raw"]).hex() for s in got
                       if s.__dict__.get("raw") is not None)
            return got
        ep.reader.take = taking
    print("ready", flush=True)
    t0 = time.monotonic()
    started = 0.0
    while time.monotonic() - t0 < LIMIT:
        server.poll()
        trigger.poll()
        for gid, g in list(server.goals.items()):
            started = started or time.monotonic()
            late = time.monotonic() - started > 0.8
            if g[0] == 1 and SCENARIO != "timeout":
                server.execute(gid)
                server.publish_feedback(gid, NavigateToPose.Feedback(distance_remaining=2.5))
            elif g[0] == 2 and late and SCENARIO == "succeed":
                server.finish(gid, 4, NavigateToPose.Result(error_msg="done"))
            elif g[0] == 2 and late and SCENARIO == "abort":
                server.finish(gid, 6, NavigateToPose.Result(error_code=9000))
            elif g[0] == 2 and late and SCENARIO == "gone":
                print(json.dumps({"raw": raw}), flush=True)
                node.close()  # the server goes away while its goal runs
                return
            elif g[0] == 3:
                server.finish(gid, 5, NavigateToPose.Result())
        time.sleep(0.01)
    print(json.dumps({"raw": raw}), flush=True)
    node.close()


main()
