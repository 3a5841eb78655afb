"""A component-like ROS 2 peer of the ground robot in lockstep (tests/test_ground_ros2.py):
it speaks schemas/lockstep.md over TCP, sends cmd_vel at every instant and, before each
instant, waits until it holds every sample the simulator says it published. Prints the
odometry it held at each second of simulated time, as JSON lines.

    python ground_lockstep_peer.py DOMAIN PORT SECONDS LINEAR ANGULAR
"""

from __future__ import annotations

import json
import socket
import sys
import time
from typing import Any

from hfsmc.sim.ground.node import Messages

STEP_US = 50_000  # the peer's instants: every 50 ms of simulated time


def main() -> None:
    domain, port = int(sys.argv[1]), int(sys.argv[2])
    seconds, linear, angular = (float(a) for a in sys.argv[3:6])
    m = Messages("jazzy")
    node = m.ros2.Ros2Node("peer", {
        "node": "peer", "namespace": "/", "domain": domain, "distro": "jazzy",
        "subscribe": {"odom": {"topic": "odom", "type": "nav_msgs/msg/Odometry"},
                      "scan": {"topic": "scan", "type": "sensor_msgs/msg/LaserScan",
                               "qos": "sensor_data"}},
        "publish": {"cmd_vel": {"topic": "cmd_vel", "type": "geometry_msgs/msg/Twist"}}})
    end = time.monotonic() + 30  # the simulator may still be starting
    while True:
        try:
            sock = socket.create_connection(("127.0.0.1", port), timeout=30)
            break
        except OSError:
            assert time.monotonic() < end, "no simulator"
            time.sleep(0.1)
    f = sock.makefile("rwb")

    def say(msg: dict[str, object]) -> None:
        f.write(json.dumps(msg).encode() + b"\n")
        f.flush()

    def hear() -> dict[str, Any]:
        msg: dict[str, Any] = json.loads(f.readline())
        return msg

    say({"hello": "hfsmc-lockstep", "version": 1, "component": "peer",
         "subscribe": ["/odom", "/scan"], "publish": ["/cmd_vel"]})
    hello = hear()
    assert "/odom" in hello["publish"], hello
    end = time.monotonic() + 10
    while node.snapshot() and (node.subscribers("cmd_vel") == 0 or node.publishers("odom") == 0):
        assert time.monotonic() < end, "no match"
        time.sleep(0.01)
    base = {"odom": node.count("odom"), "scan": node.count("scan")}
    sent = 0
    t_us = 0
    while t_us <= seconds * 1e6:
        say({"next": t_us, "sent": 0, "topics": {"/cmd_vel": sent}})
        step = hear()
        want = step["topics"]
        deadline = time.monotonic() + 10
        while True:
            node.snapshot()
            held = {t: node.count(t) - base[t] for t in base}
            if all(held[t] >= want.get(f"/{t}", 0) for t in base):
                break
            assert time.monotonic() < deadline, (held, want)
            time.sleep(0.0005)
        if t_us % 1_000_000 == 0 and node.odom is not None:
            p = node.odom.pose.pose.position
            print(json.dumps({"t": t_us, "x": p.x, "y": p.y, "odom": held["odom"]}), flush=True)
        twist = m.cls["cmd_vel"]()
        twist.linear.x, twist.angular.z = linear, angular
        node.publish("cmd_vel", twist)
        sent += 1
        t_us += STEP_US
    say({"bye": "done"})
    sock.close()
    node.close()
    m.close()


if __name__ == "__main__":
    main()
