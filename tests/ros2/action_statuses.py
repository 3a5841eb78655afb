"""Run by tests/test_ros2_actions.py in a folder of generated messages: a component's
ros2 interface (client) against a test action server and service server of the runtime,
one scenario per argument; prints one JSON line per scenario: the statuses the client's
snapshots saw, and the request bytes the server received."""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import hfsmc_ros2 as ros2  # type: ignore[import-not-found]
import hfsmc_ros2_rpc as rpc  # type: ignore[import-not-found]
from nav2_msgs.action import NavigateToPose  # type: ignore[import-not-found]
from std_srvs.srv import Trigger  # type: ignore[import-not-found]

DOMAIN = int(sys.argv[1])
SCENARIO = sys.argv[2]


def client(timeout: float | None) -> Any:
    return ros2.Ros2Node("cli", {"node": "c", "domain": DOMAIN, "actions": {
        "nav": {"name": "navigate_to_pose", "type": "nav2_msgs/action/NavigateToPose",
                "timeout": timeout}}, "services": {
        "reset": {"name": "reset", "type": "std_srvs/srv/Trigger", "timeout": timeout}}})


def main() -> None:
    server_node: Any = None if SCENARIO == "no_server" else ros2.Ros2Node(
        "srv", {"node": "s", "domain": DOMAIN})
    raw: list[str] = []
    server = trigger = None
    if server_node is not None:
        server = rpc.ActionServer(server_node._dp, "/navigate_to_pose", NavigateToPose,
                                  lambda g, goal: SCENARIO != "reject", lambda g: True)
        trigger = rpc.ServiceServer(server_node._dp, "/reset", Trigger,
                                    lambda r: Trigger.Response(success=True, message="ok"))
        for ep in (server.send_ep, trigger.ep):
            take = ep.reader.take

            def taking(n: int, take: Any = take) -> Any:
                got = take(n)
                raw.extend(bytes(s.__dict__["raw"]).hex() for s in got
                           if s.__dict__.get("raw") is not None)
                return got
            ep.reader.take = taking
    cli = client(1.5 if SCENARIO in ("no_server", "timeout") else None)
    cli.snapshot()
    before = {"status": cli.goal_status("nav"), "result": cli.result("nav"),  # nothing sent yet
              "feedback": cli.feedback("nav"), "call": cli.call_status("reset"),
              "response": cli.response("reset"), "cancel": cli.cancel("nav")}
    goal = NavigateToPose.Goal(behavior_tree="bt")
    goal.pose.pose.position.x = 1.25
    cli.send_goal("nav", goal)
    cli.call("reset", Trigger.Request())
    seen = [[cli.goal_status("nav"), cli.call_status("reset")]]
    t0 = time.monotonic()
    while time.monotonic() - t0 < 8:
        now = time.monotonic() - t0
        if server is not None and trigger is not None:
            server.poll()
            trigger.poll()
            for gid, g in list(server.goals.items()):
                if g[0] == 1 and SCENARIO != "timeout":
                    server.execute(gid)
                    server.publish_feedback(gid, NavigateToPose.Feedback(distance_remaining=2.5))
                elif g[0] == 2 and now > 0.8:
                    if SCENARIO == "succeed":
                        server.finish(gid, 4, NavigateToPose.Result(error_msg="done"))
                    elif SCENARIO == "abort":
                        server.finish(gid, 6, NavigateToPose.Result(error_code=9000))
                    elif SCENARIO == "cancel" and cli.goal_status("nav") == "executing":
                        cli.cancel("nav")
                    elif SCENARIO == "gone":
                        server_node.close()
                        server = trigger = None
                        break
                elif g[0] == 3:
                    server.finish(gid, 5, NavigateToPose.Result())
        cli.snapshot()
        st = [cli.goal_status("nav"), cli.call_status("reset")]
        if st != seen[-1]:
            seen.append(st)
        if st[0] not in rpc.RUNNING and st[1] not in ("pending", "no_server"):
            break
        time.sleep(0.01)
    fb = cli.feedback("nav")
    res = cli.result("nav")
    out = {"seen": seen, "feedback": None if fb is None else fb.distance_remaining,
           "result": None if res is None else [res.error_code, res.error_msg],
           "response": None if cli.response("reset") is None else cli.response("reset").message,
           "raw": raw, "client_ids": [cli._actions["nav"].send_ep.ident,
                                      cli._services["reset"].ep.ident],
           "before": before,
           "cancel_nothing": cli.cancel("nav") if cli.goal_status("nav") not in rpc.RUNNING
           else None}
    print(json.dumps(out))
    cli.close()
    if server_node is not None and server is not None:
        server_node.close()


main()
