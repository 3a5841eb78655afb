# mypy: ignore-errors
# (it imports the runtime and the messages generated beside it, which mypy cannot see)
"""The ros2 interface recorded and played back, as the engine drives it, for
tests/test_ros2_record.py: run from a folder that holds the generated message packages
and the runtime files (hfsmc_ros2*.py, hfsmc_record.py, hfsmc_playback.py).

usage: record_peer.py record DISTRO DOMAIN OUT.mcap
         a `robot` node (subscribes /tb2/scan, publishes /tb2/cmd_vel) and a `sim` node
         publishing /tb2/scan at 20 Hz (ranges [i, i, i]); 40 instants 50 ms apart, each
         snapshot recorded, and at each the "snippet" below; the recording closed.
       record_peer.py play DISTRO FOLDER
         the same snippet at the instants of FOLDER/inputs.jsonl, over the ros2 fake;
         its commands go to FOLDER/commands.jsonl.
The snippet: once a scan has come, publish a Twist whose linear.x is the scan's first
range and angular.z the number of scans seen."""

from __future__ import annotations

import hashlib
import json
import sys
import time

from geometry_msgs.msg import Twist, Vector3

SCAN = {"topic": "scan", "type": "sensor_msgs/msg/LaserScan", "qos": "sensor_data"}
CMD = {"topic": "/tb2/cmd_vel", "type": "geometry_msgs/msg/Twist"}
ROBOT = {"node": "bump_and_go", "namespace": "/tb2", "subscribe": {"scan": SCAN},
         "publish": {"cmd_vel": CMD}}


def snippet(robot) -> None:
    if robot.scan is not None:
        robot.publish("cmd_vel", Twist(linear=Vector3(x=float(robot.scan.ranges[0])),
                                       angular=Vector3(z=float(robot.count("scan")))))


def record(distro: str, domain: int, out: str) -> None:
    import hfsmc_record
    import hfsmc_ros2
    from sensor_msgs.msg import LaserScan

    robot = hfsmc_ros2.connect("robot", {**ROBOT, "domain": domain, "distro": distro})
    sim = hfsmc_ros2.connect("sim", {"node": "sim", "namespace": "/tb2", "domain": domain,
                                     "distro": distro, "publish": {"scan": SCAN}})
    end = time.monotonic() + 10
    while time.monotonic() < end and sim._writers["scan"].get_publication_matched_status(
            ).current_count == 0:
        time.sleep(0.02)
    sources = (("robot.yaml", "name: robot\n"),)
    digest = hashlib.sha256(b"".join(p.encode() + b"\0" + x.encode() + b"\0"
                                     for p, x in sources)).hexdigest()
    run = {"component": "robot", "language": "python", "hfsmc": "0", "clock": "real",
           "model_hash": "sha256:" + digest, "until_us": "", "time_limit_us": ""}
    rec = hfsmc_record.Recorder(out, run, {},
                                {"robot": {"type": "ros2", "url": None, "options": {}}},
                                sources)
    t = 0
    rec.attach("robot", robot, lambda: t)
    start = time.monotonic()
    for k in range(40):
        if k % 2 == 0:
            sim.publish("scan", LaserScan(ranges=[float(k)] * 3, range_max=10.0))
        time.sleep(max(0.0, start + k * 0.05 + 0.025 - time.monotonic()))
        t = k * 50_000
        rec.snapshot(t, "robot", "ros2", robot.snapshot())
        snippet(robot)
        rec.flush()
    rec.close()
    robot.close()
    sim.close()


def play(folder: str) -> None:
    import hfsmc_playback

    pb = hfsmc_playback.Playback(folder)
    robot = pb.fake("robot", "ros2", ROBOT)
    instants = sorted({t for t, _, _ in pb.snapshots["robot"]})
    for t in instants:
        robot.on_command = lambda call, args, t=t: pb.command(t, "robot", call, args)
        pb.advance(t)
        robot.snapshot()
        snippet(robot)
    pb.close()
    print(json.dumps({"unanswered": pb.unanswered}))


if __name__ == "__main__":
    if sys.argv[1] == "record":
        record(sys.argv[2], int(sys.argv[3]), sys.argv[4])
    else:
        play(sys.argv[3])
