"""ROS 2 actions and services (SPEC 5.3, docs/ros2.md "Services and actions"): every status
against a test server of the runtime, the request bytes against rosbags' serialization with
rmw_cyclonedds_cpp's request header, the simulator's navigate_to_pose, bad inputs."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hfsmc.emit.python import INTERFACE_FILES
from hfsmc.errors import Span
from hfsmc.ros2.definitions import message_set, rosbags_store
from tests.ros2_support import NAV, ROOM, build_component, generate, ros2_domain, run_against_sim
from tests.support import hfsmc

RUNTIME = Path(__file__).resolve().parent.parent / "templates" / "python"
SCRIPT = Path(__file__).resolve().parent / "ros2" / "action_statuses.py"
TYPES = ["nav2_msgs/action/NavigateToPose", "std_srvs/srv/Trigger"]


def scenario(tmp: Path, name: str) -> dict[str, Any]:
    ms = message_set("jazzy", [("rmw_dds_common/msg/ParticipantEntitiesInfo", Span("t", 1, 1))],
                     (), [(t, Span("t", 1, 1)) for t in TYPES])
    out = tmp / "gen"
    if not out.exists():
        generate(ms, out)
        for f in INTERFACE_FILES["ros2"]:  # what a component gets beside it
            (out / f).write_text((RUNTIME / f).read_text())
    with ros2_domain() as dom:
        run = subprocess.run([sys.executable, str(SCRIPT), str(dom), name], cwd=out,
                             capture_output=True, text=True, timeout=60,
                             env={"PYTHONPATH": str(out), "PATH": "/usr/bin:/bin",
                                  "CYCLONEDDS_URI": os.environ["CYCLONEDDS_URI"]})
    assert run.returncode == 0, run.stderr
    return dict(json.loads(run.stdout.strip().splitlines()[-1]))


def statuses(seen: list[list[str]], i: int) -> list[str]:
    out: list[str] = []
    for s in seen:
        if not out or out[-1] != s[i]:
            out.append(s[i])
    return out


def test_a_goal_is_accepted_gets_feedback_and_succeeds_and_a_call_is_done(tmp_path: Path) -> None:
    r = scenario(tmp_path, "succeed")
    goals = statuses(r["seen"], 0)
    assert goals[0] == "pending" and goals[-1] == "succeeded", goals
    assert set(goals) <= {"pending", "accepted", "executing", "succeeded"}
    assert r["feedback"] == 2.5 and r["result"] == [0, "done"]
    assert statuses(r["seen"], 1) == ["pending", "done"] and r["response"] == "ok"
    assert r["cancel_nothing"] is False  # a cancel with nothing running sends nothing
    # before any goal or call: the statuses say none, a result or response read is None,
    # and a cancel is False (nothing sent: the first request the server saw was the goal)
    assert r["before"] == {"status": "none", "result": None, "feedback": None, "call": "none",
                           "response": None, "cancel": False}


def test_the_requests_are_rosbags_bytes_after_rmw_cyclonedds_cpps_header(tmp_path: Path) -> None:
    r = scenario(tmp_path, "succeed")
    store = rosbags_store("jazzy")
    Goal = store.types["nav2_msgs/action/NavigateToPose_Goal"]
    raw = [bytes.fromhex(h) for h in r["raw"]]
    # the send_goal request: header (client id, sequence 1), then goal id and goal
    send = next(b for b in raw if len(b) > 40)
    client, seq = struct.unpack_from("<Qq", send, 4)
    assert client in r["client_ids"] and seq == 1
    body = send[:4] + send[20:]
    msg = store.deserialize_cdr(body, "nav2_msgs/action/NavigateToPose_SendGoal_Request")
    assert msg.goal.pose.pose.position.x == 1.25 and msg.goal.behavior_tree == "bt"
    again = store.serialize_cdr(msg, "nav2_msgs/action/NavigateToPose_SendGoal_Request")
    assert bytes(again) == body[:len(again)] and set(body[len(again):]) <= {0}
    assert isinstance(msg.goal, Goal)
    trigger = next(b for b in raw if len(b) <= 24)  # Trigger's request: one byte
    assert trigger[20:21] == bytes(store.serialize_cdr(
        store.types["std_srvs/srv/Trigger_Request"](structure_needs_at_least_one_member=0),
        "std_srvs/srv/Trigger_Request"))[4:5]


@pytest.mark.parametrize(("name", "last"), [("reject", "rejected"), ("abort", "aborted"),
                                             ("cancel", "canceled"), ("timeout", "timeout"),
                                             ("no_server", "timeout"), ("gone", "no_server")])
def test_every_end_of_a_goal(tmp_path: Path, name: str, last: str) -> None:
    r = scenario(tmp_path, name)
    goals = statuses(r["seen"], 0)
    assert goals[0] == "pending" and goals[-1] == last, goals
    if name == "cancel":  # canceled after the goal ran (canceling may fall between instants)
        assert "executing" in goals
    if name == "no_server":
        assert "no_server" in goals and statuses(r["seen"], 1)[-1] == "timeout"
    if name == "abort":
        assert r["result"] == [9000, ""]


def test_a_model_sends_a_navigate_to_pose_goal_and_the_robot_reaches_the_pose(
        tmp_path: Path) -> None:
    (tmp_path / "nav.yaml").write_text(NAV)
    component = build_component(tmp_path, tmp_path / "nav.yaml")
    with ros2_domain() as dom:
        run, truth = run_against_sim(tmp_path, ROOM + "robots: [{name: tb, x: 1, y: 2}]\n",
                                     dom, component, env={"ROS_DOMAIN_ID": str(dom)})
    assert run.returncode == 0, run.stderr
    assert "stopped (final)" in run.stderr, run.stderr
    tb = truth["tb"]
    assert isinstance(tb, dict)
    # odom (2, 1) from the start (1, 2) facing +x is (3, 3) in the world
    assert abs(tb["pose"]["x"] - 3.0) < 0.06 and abs(tb["pose"]["y"] - 3.0) < 0.06, tb["pose"]
    assert tb["collisions"] == []


def test_bad_actions_and_services_are_found_by_check(tmp_path: Path) -> None:
    bad = NAV.replace("nav2_msgs/action/NavigateToPose, timeout", "nav2_msgs/action/NavigateTo, timeout")
    bad = bad.replace('robot.call_status("reset")', 'robot.call_status("rest")')
    bad = bad.replace("std_srvs/srv/Trigger}", "std_msgs/msg/String}")
    (tmp_path / "bad.yaml").write_text(bad)
    run = hfsmc("check", str(tmp_path / "bad.yaml"))
    assert run.returncode == 1
    assert "bad.yaml:10:" in run.stderr and "E316" in run.stderr and "NavigateToPose" in run.stderr
    assert "bad.yaml:12:" in run.stderr  # a message type among the services
    assert "E148" in run.stderr and "rest" in run.stderr
