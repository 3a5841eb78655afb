# mypy: ignore-errors
# (it imports the runtime and the messages generated beside it, which mypy cannot see)
"""A ROS 2 node made with hfsmc's Python runtime, for tests/test_ros2_wire.py: run from a
folder that holds the generated message packages and the runtime files.

usage: peer.py ROLE DISTRO DOMAIN SECONDS
  robot: subscribes /tb2/scan (sensor_data), publishes /tb2/cmd_vel (a Twist whose linear.x
         is the number of scans seen); prints one JSON line per instant with a new scan
  sim:   publishes /tb2/scan at 50 Hz (ranges = [i, i, i]), subscribes /tb2/cmd_vel;
         prints one JSON line per new cmd_vel
  garbage: as sim, but every other scan's frame_id is not UTF-8 (a malformed sample)
  discovery: prints the hex of each ros_discovery_info sample it reads
Stops after SECONDS, or on stdin's end."""

from __future__ import annotations

import json
import sys
import time

import hfsmc_ros2
from geometry_msgs.msg import Twist, Vector3
from sensor_msgs.msg import LaserScan

role, distro, domain, seconds = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
if role == "discovery":
    import hfsmc_ros2_wire as wire
    from cyclonedds.domain import DomainParticipant
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic

    kind = wire.dds_type(wire.message_class("rmw_dds_common/msg/ParticipantEntitiesInfo"))
    dp = DomainParticipant(domain)
    reader = DataReader(dp, Topic(dp, "ros_discovery_info", kind),
                        qos=wire.dds_qos(("reliable", "transient_local", 10)))
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for sample in reader.take(10):
            if "raw" in sample.__dict__:
                print(json.dumps({"info": sample.__dict__["raw"].hex()}), flush=True)
        time.sleep(0.05)
    sys.exit(0)
scan = {"topic": "scan", "type": "sensor_msgs/msg/LaserScan", "qos": "sensor_data"}
cmd = {"topic": "/tb2/cmd_vel", "type": "geometry_msgs/msg/Twist"}
if role == "robot":
    settings = {"node": "bump_and_go", "subscribe": {"scan": scan}, "publish": {"cmd_vel": cmd}}
else:
    settings = {"node": "sim", "publish": {"scan": scan}, "subscribe": {"cmd_vel": cmd}}
node = hfsmc_ros2.connect(role, {**settings, "namespace": "/tb2", "domain": domain,
                                 "distro": distro})
print(json.dumps({"ready": repr(node)}), flush=True)
end = time.monotonic() + seconds
seen = 0
i = 0
while time.monotonic() < end:
    node.snapshot()
    if role == "robot":
        if node.count("scan") != seen:
            seen = node.count("scan")
            print(json.dumps({"count": seen, "ranges": list(node.scan.ranges),
                              "frame": node.scan.header.frame_id,
                              "publishers": node.publishers("scan"),
                              "dropped": node.dropped("scan")}), flush=True)
            node.publish("cmd_vel", Twist(linear=Vector3(x=float(seen))))
    else:
        i += 1
        msg = LaserScan(ranges=[float(i)] * 3, range_max=8.0)
        msg.header.frame_id = "ab"
        good = hfsmc_ros2.cdr.serialize(msg)
        if role == "garbage" and i % 2:
            # frame_id's bytes made invalid UTF-8: well-formed CDR that Cyclone DDS delivers
            # (it refuses to write a buffer cut short), but no LaserScan ROS 2 can read
            assert good[16:18] == b"ab"
            node._send("scan", good[:16] + b"\xff\xfe" + good[18:])
        else:
            node._send("scan", good)
        if node.count("cmd_vel") != seen:
            seen = node.count("cmd_vel")
            print(json.dumps({"count": seen, "x": node.cmd_vel.linear.x,
                              "subscribers": node.subscribers("scan")}), flush=True)
    time.sleep(0.02)
node.close()
