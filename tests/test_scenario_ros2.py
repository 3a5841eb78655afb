"""`hfsmc test` scenarios that script a ros2 interface's topics (docs/testing.md, "`ros2`
interfaces"): messages by field values and from a recorded topic, turned into the CDR
rosbags writes; expectations on the messages published; every mistake at its position;
examples/stop_at_wall's and examples/bump_and_go's scenarios pass, and a wrong one fails
naming the publish that broke it."""

from __future__ import annotations

import base64
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from hfsmc.errors import Diagnostics, Span
from hfsmc.pipeline import compile_file
from hfsmc.ros2.definitions import rosbags_store
from hfsmc.scenario import check_against_model, read_scenario
from hfsmc.scenario_inputs import write_playback
from hfsmc.scenario_ros2 import Topics, Written
from tests.support import ROOT

WALL = ROOT / "examples/stop_at_wall/stop_at_wall.yaml"
BUMP = ROOT / "examples/bump_and_go/bump_and_go.yaml"
BUMP_CPP = ROOT / "examples/bump_and_go_cpp/bump_and_go_cpp.yaml"
SCAN = ("angle_min: -3.1416, angle_max: 3.1416, angle_increment: 0.017453, range_max: 12.0")


def hfsmc_test(*args: str, cache: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "XDG_CACHE_HOME": str(cache)}
    return subprocess.run([sys.executable, "-m", "hfsmc", "test", *args], cwd=ROOT, env=env,
                          capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)


def problems(folder: Path, text: str, model: Path = WALL) -> list[str]:
    """`line:col: code message` of every problem of a scenario against ``model``."""
    path = folder / "sc.yaml"
    path.write_text(text.format(model=model), encoding="utf-8")
    diags = Diagnostics()
    sc = read_scenario(str(path), diags)
    if sc is not None:
        result = compile_file(str(model))
        assert result.model is not None
        check_against_model(sc, result.model, diags)
    return [f"{d.span.line}:{d.span.col}: {d.code} {d.message}" for d in diags.sorted()]


def test_the_examples_pass_and_a_wrong_expectation_names_the_publish(tmp_path: Path) -> None:
    r = hfsmc_test(str(ROOT / "examples/stop_at_wall"), str(ROOT / "examples/bump_and_go"),
                   str(ROOT / "examples/bump_and_go_cpp"), cache=tmp_path / "cache")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "examples/stop_at_wall/tests/wall_ahead.yaml::python PASSED" in r.stdout
    assert "examples/bump_and_go/tests/obstacle_ahead.yaml::python PASSED" in r.stdout
    # The same scenario against the C++ twin: its ros2 interface's playback fake
    # (hfsmc_ros2_playback.cpp) delivers the scripted scans and odometry.
    assert "examples/bump_and_go_cpp/tests/obstacle_ahead.yaml::cpp PASSED" in r.stdout
    # The same wall, but a test that wants the robot to go on at 0.5 m/s and to stop by 2 s.
    wrong = (ROOT / "examples/stop_at_wall/tests/wall_ahead.yaml").read_text("utf-8")
    wrong = wrong.replace("model: ../stop_at_wall.yaml", f"model: {WALL}")
    wrong = wrong.replace("fields: {linear: {x: 0.4, y: 0, z: 0}, angular: {z: 0}}",
                          "fields: {linear: {x: 0.5}}")
    wrong = wrong.replace("between: [3s, 3.05s]\n    count: 1", "before: 2s\n    count: 1")
    bad = tmp_path / "wrong.yaml"
    bad.write_text(wrong, encoding="utf-8")
    r = hfsmc_test(str(bad), cache=tmp_path / "cache")
    assert r.returncode == 1, r.stdout + r.stderr
    out = r.stdout
    assert (f"{bad}:22:5: expected robot.cmd_vel published with linear.x=0.5 at least 40 "
            "time(s) between 0.5 s and 2.95 s\n  got: published only with other fields\n"
            "    commands.jsonl:1: at 500 ms: robot.publish(\"cmd_vel\", Twist(linear.x=0.4))"
            ) in out, out
    assert (f"{bad}:28:5: expected robot.cmd_vel published with linear.x=0, angular.z=0 1 "
            "time(s) by 2 s\n  got: published 0 time(s) in that window, not 1") in out, out
    assert "1 failed" in out
    # The C++ twin is held to its expectations as well: backing off forwards never happens.
    twin = (ROOT / "examples/bump_and_go_cpp/tests/obstacle_ahead.yaml").read_text("utf-8")
    twin = twin.replace("model: ../bump_and_go_cpp.yaml", f"model: {BUMP_CPP}")
    twin = twin.replace("fields: {linear: {x: {below: 0}}, angular: {z: 0}}",
                        "fields: {linear: {x: {above: 0}}, angular: {z: 0}}")
    bad = tmp_path / "wrong_cpp.yaml"
    bad.write_text(twin, encoding="utf-8")
    r = hfsmc_test(str(bad), cache=tmp_path / "cache")
    assert r.returncode == 1 and f"{bad}::cpp FAILED" in r.stdout, r.stdout + r.stderr
    assert (f"{bad}:36:5: expected robot.cmd_vel published with linear.x={{above: 0}}, "
            "angular.z=0 20 time(s) between 3 s and 3.95 s\n  got: published 0 time(s) in "
            "that window, not 20") in r.stdout, r.stdout


def test_messages_are_rosbags_cdr_at_their_rate_and_a_span_gives_way(tmp_path: Path) -> None:
    """Fields left out take ROS 2's defaults (Quaternion's w 1); the bytes are rosbags'; an
    entry with `rate` sends at that rate while it holds; a span's end brings back what held
    before (sent again at once), and without `rate` a message is sent once."""
    text = f"""
model: {{model}}
until: 2s
inputs:
  robot:
    - {{at: 0s, rate: 5, scan: {{{SCAN}, ranges: [{{repeat: 4.0, times: 3}}, 1.5]}}}}
    - {{from: 500ms, to: 1s, scan: {{range_max: 2.0}}}}
    - {{at: 100ms, odom: {{child_frame_id: base, pose: {{pose: {{position: {{x: 1.5}}}}}}}}}}
"""
    path = tmp_path / "sc.yaml"
    path.write_text(text.replace("{model}", str(WALL)), encoding="utf-8")
    diags = Diagnostics()
    sc = read_scenario(str(path), diags)
    model = compile_file(str(WALL)).model
    assert sc is not None and model is not None
    check_against_model(sc, model, diags)
    assert not diags.has_errors, diags.sorted()
    write_playback(sc, {"robot": "ros2"}, 50_000, tmp_path, Topics(model))
    rows = [json.loads(line) for line in (tmp_path / "inputs.jsonl").read_text().splitlines()]
    got = [(r["t"], name, v["count"]) for r in rows
           for name, v in r["values"]["subscriptions"].items()]
    assert got == [(0, "scan", 1), (100_000, "odom", 1), (200_000, "scan", 2),
                   (400_000, "scan", 3), (500_000, "scan", 4), (1_000_000, "scan", 5),
                   (1_200_000, "scan", 6), (1_400_000, "scan", 7), (1_600_000, "scan", 8),
                   (1_800_000, "scan", 9), (2_000_000, "scan", 10)]
    store = rosbags_store("jazzy")
    types = store.types
    scan = types["sensor_msgs/msg/LaserScan"](
        header=types["std_msgs/msg/Header"](stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                                            frame_id=""),
        angle_min=-3.1416, angle_max=3.1416, angle_increment=0.017453, time_increment=0.0,
        scan_time=0.0, range_min=0.0, range_max=12.0,
        ranges=np.array([4.0, 4.0, 4.0, 1.5], dtype=np.float32),
        intensities=np.array([], dtype=np.float32))
    cdr = {(r["t"], n): base64.b64decode(v["cdr"]) for r in rows
           for n, v in r["values"]["subscriptions"].items()}
    assert cdr[(0, "scan")] == bytes(store.serialize_cdr(scan, "sensor_msgs/msg/LaserScan"))
    assert cdr[(1_000_000, "scan")] == cdr[(0, "scan")]  # what held before, again
    short: Any = store.deserialize_cdr(cdr[(500_000, "scan")], "sensor_msgs/msg/LaserScan")
    assert short.range_max == 2.0 and short.angle_min == 0.0 and len(short.ranges) == 0
    odom: Any = store.deserialize_cdr(cdr[(100_000, "odom")], "nav_msgs/msg/Odometry")
    assert odom.child_frame_id == "base" and odom.pose.pose.position.x == 1.5
    assert odom.pose.pose.orientation.w == 1.0  # Quaternion.msg: `float64 w 1`
    assert odom.pose.covariance.shape == (36,)


def _mcap(path: Path, topics: dict[str, tuple[str, list[tuple[int, Any]]]]) -> None:
    """An MCAP file as rosbag2 writes one: per topic its ros2msg schema and CDR messages
    at the given times (ns)."""
    from mcap.writer import Writer

    store = rosbags_store("jazzy")
    with open(path, "wb") as f:
        w = Writer(f)
        w.start("ros2", "test")
        for topic, (kind, messages) in topics.items():
            schema = w.register_schema(kind, "ros2msg",
                                       store.generate_msgdef(kind, ros_version=2)[0].encode())
            channel = w.register_channel(topic, "cdr", schema)
            for t, msg in messages:
                w.add_message(channel, log_time=t, publish_time=t,
                              data=msg if isinstance(msg, bytes)
                              else bytes(store.serialize_cdr(msg, kind)))
        w.finish()  # type: ignore[no-untyped-call]


def _scan(store: Any, ahead: float) -> Any:
    t = store.types
    ranges = np.full(360, np.inf, dtype=np.float32)
    ranges[170:191] = ahead
    return t["sensor_msgs/msg/LaserScan"](
        header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=0, nanosec=0),
                                        frame_id="laser"),
        angle_min=-3.1416, angle_max=3.1416, angle_increment=0.017453, time_increment=0.0,
        scan_time=0.1, range_min=0.1, range_max=12.0, ranges=ranges,
        intensities=np.array([], dtype=np.float32))


def test_a_recorded_topic_is_replayed_from_a_time(tmp_path: Path) -> None:
    """A rosbag's /scan (a wall coming nearer by 0.5 m a second from 4 m), from 2 s of the
    bag on, delivered from the entry's 1 s: the wall is under 0.8 m at the bag's 6.5 s,
    so the robot stops at 1 + 4.5 = 5.5 s."""
    store = rosbags_store("jazzy")
    start = 1_700_000_000_000_000_000
    scans = [(start + k * 100_000_000, _scan(store, 4.0 - 0.05 * k)) for k in range(80)]
    _mcap(tmp_path / "drive.mcap", {"/scan": ("sensor_msgs/msg/LaserScan", scans)})
    (tmp_path / "sc.yaml").write_text(f"""
model: {WALL}
until: 8s
inputs:
  robot:
    - {{at: 1s, scan: {{recorded: drive.mcap, from: 2s}}}}
expect:
  - entered: Forward
    between: [1s, 1.05s]
  - entered: Stop
    between: [5.5s, 5.55s]
  - published: robot.cmd_vel
    fields: {{linear: {{x: 0.4}}}}
    after: 5.55s
    count: 0
""", encoding="utf-8")
    r = hfsmc_test(str(tmp_path / "sc.yaml"), "--keep", str(tmp_path / "runs"),
                   cache=tmp_path / "cache")
    assert r.returncode == 0, r.stdout + r.stderr
    rows = [json.loads(line) for line in
            next((tmp_path / "runs").iterdir()).joinpath("inputs.jsonl").read_text().splitlines()]
    assert [r["t"] for r in rows][:3] == [1_000_000, 1_100_000, 1_200_000]
    assert len(rows) == 60  # the bag's 2 s to 7.9 s
    first = base64.b64decode(rows[0]["values"]["subscriptions"]["scan"]["cdr"])
    assert first == bytes(store.serialize_cdr(scans[20][1], "sensor_msgs/msg/LaserScan"))


MISTAKES = """
model: {model}
until: 5s
inputs:
  robot:
    - {{at: 0s, scan: {{ranges: [1.0, true], angle_mim: 0.5}}}}
    - {{at: 1s, scna: {{range_max: 3}}}}
    - {{at: 1s, cmd_vel: {{linear: {{x: 1}}}}}}
    - {{at: 2s, odom: {{header: {{stamp: {{sec: 1.5, nanosec: -1}}}}, pose: 3}}}}
    - {{at: 2s, scan: {{recorded: other.mcap}}}}
    - {{at: 3s, scan: {{recorded: ../outside.mcap}}}}
    - {{at: 3s, odom: {{recorded: other.mcap, topic: /odom, form: 1s}}}}
    - {{at: 4s, scan: {{ranges: [{{repeat: 1.0, time: 3}}], intensities: 5}}}}
expect:
  - published: robot.cmd_vl
  - published: robot.scan
  - published: robot.cmd_vel
    type: geometry_msgs/msg/TwistStamped
  - published: robot.cmd_vel
    fields: {{linear: {{x: {{about: 1}}, w: 0}}, angular: {{z: "fast"}}}}
    count: 1
    at_least: 2
  - published: drone.cmd_vel
"""


def test_every_mistake_is_said_at_its_place(tmp_path: Path) -> None:
    store = rosbags_store("jazzy")
    _mcap(tmp_path / "other.mcap", {
        "/scan": ("sensor_msgs/msg/Imu", [(10, _imu_zero(store))]),
        "/odom": ("nav_msgs/msg/Odometry", [(20, _odom_zero())])})
    (tmp_path.parent / "outside.mcap").write_bytes(b"")
    got = problems(tmp_path, MISTAKES)
    assert got == [
        "6:37: E191 `ranges` (float32[]) must be a number (.inf and .nan too), not a boolean",
        "6:44: E190 sensor_msgs/msg/LaserScan has no field `angle_mim`",
        "7:16: E195 the ros2 interface `robot` subscribes to no `scna`",
        "8:16: E195 `cmd_vel` is a publication of `robot`: the model publishes it (expect it: "
        "`published: robot.cmd_vel`)",
        "9:45: E191 `sec` (int32) must be an integer, not a number",
        "9:59: E191 `nanosec` (uint32): -1 is out of range (0..4294967295)",
        "9:71: E191 a geometry_msgs/msg/PoseWithCovariance is a mapping of its fields, not a number",
        "10:33: E195 the recorded topic /scan is a sensor_msgs/msg/Imu; `robot.scan` is a "
        "sensor_msgs/msg/LaserScan",
        "11:33: E198 the recording `../outside.mcap` is outside the scenario's folder (a "
        "scenario reads only files beside it or below)",
        "12:59: E190 unknown key `form` in a recorded topic",
        "13:46: E191 an item of `ranges` (float32[]) is a value, or `{repeat: VALUE, times: N}`",
        "13:70: E191 `intensities` (float32[]) must be a list, not a number",
        "15:16: E195 the ros2 interface `robot` publishes no `cmd_vl`",
        "16:16: E195 `scan` is a subscription of `robot`, not a publication",
        "17:16: E195 `robot.cmd_vel` is declared a geometry_msgs/msg/Twist, not "
        "geometry_msgs/msg/TwistStamped",
        "20:26: E191 `x`: a value, or one comparison: {above: X}, {below: X}, {not: X}",
        "20:38: E190 geometry_msgs/msg/Vector3 has no field `w`",
        "20:59: E191 `z` (float64) must be a number (.inf and .nan too), not a string",
        "22:5: E193 `count` (exactly) or `at_least`: write one or the other",
        "23:16: E195 the model has no ros2 interface `drone`",
    ], "\n".join(got)


def _odom_zero() -> bytes:
    """A default Odometry, as a scenario's `odom: {}` makes it."""
    model = compile_file(str(WALL)).model
    assert model is not None
    topics = Topics(model)
    msg = topics.build(Written({}, Span("x", 1, 1), Span("x", 1, 1)), "nav_msgs/msg/Odometry",
                       Diagnostics())
    return topics.cdr(msg, "nav_msgs/msg/Odometry")


def _imu_zero(store: Any) -> bytes:
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](sec=0, nanosec=0)
    q = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    v = t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    cov = np.zeros(9, dtype=np.float64)
    imu = t["sensor_msgs/msg/Imu"](header=t["std_msgs/msg/Header"](stamp=stamp, frame_id=""),
                                   orientation=q, orientation_covariance=cov,
                                   angular_velocity=v, angular_velocity_covariance=cov,
                                   linear_acceleration=v, linear_acceleration_covariance=cov)
    return bytes(store.serialize_cdr(imu, "sensor_msgs/msg/Imu"))


@pytest.mark.parametrize("where", ["python", "cpp"])
def test_a_cpp_model_takes_the_scripted_topics_of_the_python_one(tmp_path: Path, where: str) -> None:
    """The C++ interface's playback fake reads scripted messages (E195 no longer refuses
    them): the same inputs are checked the same way against either twin."""
    model = ROOT / ("examples/stop_at_wall_cpp/stop_at_wall_cpp.yaml" if where == "cpp" else
                    "examples/stop_at_wall/stop_at_wall.yaml")
    got = problems(tmp_path, "model: {model}\ninputs:\n  robot:\n    - {{at: 0s, scan: {{}}}}\n",
                   model)
    assert got == []
    bad = problems(tmp_path, "model: {model}\ninputs:\n  robot:\n"
                   "    - {{at: 0s, scan: {{angle_mn: 1}}}}\n    - {{at: 0s, cmd_vel: {{}}}}\n", model)
    assert [b.split(" ")[:2] for b in bad] == [["4:23:", "E190"], ["5:16:", "E195"]], bad
