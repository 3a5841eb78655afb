"""A ROS 2 peer of the simulated ground robot, for tests/test_ground_ros2.py: a node (the
components' own runtime) that sends cmd_vel for a while and prints, as one JSON line, what
it received of odom, scan, events/bumper and /clock.

    python ground_peer.py DOMAIN NAMESPACE SECONDS LINEAR ANGULAR
"""

from __future__ import annotations

import json
import math
import sys
import time

from hfsmc.sim.ground.node import Messages


def main() -> None:
    domain, namespace = int(sys.argv[1]), sys.argv[2]
    seconds, linear, angular = (float(a) for a in sys.argv[3:6])
    m = Messages("jazzy")
    node = m.ros2.Ros2Node("peer", {
        "node": "peer", "namespace": namespace, "domain": domain, "distro": "jazzy",
        "subscribe": {
            "odom": {"topic": "odom", "type": "nav_msgs/msg/Odometry"},
            "scan": {"topic": "scan", "type": "sensor_msgs/msg/LaserScan", "qos": "sensor_data"},
            "clock": {"topic": "/clock", "type": "rosgraph_msgs/msg/Clock"},
            "bumper": {"topic": "events/bumper",
                       "type": "kobuki_ros_interfaces/msg/BumperEvent"}},
        "publish": {"cmd_vel": {"topic": "cmd_vel", "type": "geometry_msgs/msg/Twist"}}})
    bumps: list[list[int]] = []
    seen = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        node.snapshot()
        if node.count("bumper") != seen:
            seen = node.count("bumper")
            bumps.append([node.bumper.bumper, node.bumper.state])
        twist = m.cls["cmd_vel"]()
        twist.linear.x, twist.angular.z = linear, angular
        node.publish("cmd_vel", twist)
        time.sleep(0.05)
    node.snapshot()
    odom, scan, clock = node.odom, node.scan, node.clock
    print(json.dumps({
        "odom": None if odom is None else {
            "x": odom.pose.pose.position.x, "y": odom.pose.pose.position.y,
            "yaw": 2 * math.atan2(odom.pose.pose.orientation.z, odom.pose.pose.orientation.w),
            "frame": odom.header.frame_id,
            "child": odom.child_frame_id, "v": odom.twist.twist.linear.x},
        "scan": None if scan is None else {
            "n": len(scan.ranges), "frame": scan.header.frame_id,
            "ahead": scan.ranges[len(scan.ranges) // 2], "angle_min": scan.angle_min},
        "clock": None if clock is None else clock.clock.sec + clock.clock.nanosec * 1e-9,
        "bumps": bumps,
        "counts": {k: node.count(k) for k in ("odom", "scan", "clock", "bumper")},
        "sim_subscribers": node.subscribers("cmd_vel"),
    }, allow_nan=True))
    node.close()
    m.close()


if __name__ == "__main__":
    main()
