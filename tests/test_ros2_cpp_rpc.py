"""C++ action and service clients (SPEC 5.3, docs/ros2-cpp.md "Actions and services"): a C++
model resets odometry and drives `hfsmc sim --robot diffdrive` to a pose with a
NavigateToPose goal (truth), recorded as Python records it and replayed identical by its
C++ and its Python twin, and a Python recording replayed by the C++ twin; every status of a
goal and of a call against the runtime's Python test servers, the requests decoded with
rosbags after rmw_cyclonedds_cpp's header; a goal of the wrong type refused at its line."""

from __future__ import annotations

import base64
import json
import os
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import yaml

from hfsmc.emit.python import INTERFACE_FILES
from hfsmc.errors import Span
from hfsmc.ros2.definitions import message_set, rosbags_store
from tests.cppbuild import Superbuild
from tests.ros2_support import NAV, ROOM, build_component, generate, ros2_domain, run_against_sim
from tests.support import ROOT, hfsmc

MODELS = ROOT / "tests" / "ros2" / "models"
NAV_CPP = MODELS / "nav_cpp" / "nav_cpp.yaml"
CLIENT = MODELS / "rpc_client_cpp" / "rpc_client_cpp.yaml"
SERVERS = ROOT / "tests" / "ros2" / "rpc_servers.py"
RUNTIME = ROOT / "templates" / "python"
WORLD = ROOM + "robots: [{name: tb, x: 1, y: 2}]\n"


@pytest.fixture(scope="module")
def build(tmp_path_factory: pytest.TempPathFactory) -> Superbuild:
    sb = Superbuild(tmp_path_factory.mktemp("cpprpc") / "build", [NAV_CPP, CLIENT])
    sb.build()
    return sb


def snapshots(mcap: Path) -> list[dict[str, Any]]:
    from mcap.reader import make_reader

    with mcap.open("rb") as f:
        return [json.loads(m.data) for _, c, m in make_reader(f).iter_messages()
                if c.topic == "/hfsmc/interface/robot"]


def commands(mcap: Path) -> list[dict[str, Any]]:
    from mcap.reader import make_reader

    with mcap.open("rb") as f:
        return [json.loads(m.data) for _, c, m in make_reader(f).iter_messages()
                if c.topic == "/hfsmc/command/robot"]


def changes(values: list[str]) -> list[str]:
    out: list[str] = []
    for v in values:
        if not out or out[-1] != v:
            out.append(v)
    return out


# -- the simulator: navigate_to_pose and reset_odometry --------------------------------------
@pytest.fixture(scope="module")
def nav_runs(build: Superbuild, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The C++ and the Python twin each driven to the pose with --record."""
    tmp = tmp_path_factory.mktemp("cppnav")
    out: dict[str, Any] = {}
    (tmp / "nav.yaml").write_text(NAV)
    py = build_component(tmp, tmp / "nav.yaml")
    for lang, exe in (("cpp", build.executable(NAV_CPP)), ("python", py)):
        folder = tmp / lang
        folder.mkdir()
        with ros2_domain() as dom:
            run, truth = _against_sim(folder, dom, exe, "--record", str(folder / "run.mcap"))
        out[lang] = {"run": run, "truth": truth, "mcap": folder / "run.mcap"}
    out["py_model"] = tmp / "nav.yaml"
    return out


def _against_sim(folder: Path, dom: int, exe: Path, *args: str
                 ) -> tuple[subprocess.CompletedProcess[str], dict[str, object]]:
    return run_against_sim(folder, WORLD, dom, exe, *args, env={"ROS_DOMAIN_ID": str(dom)})


def test_a_cpp_model_resets_odometry_and_drives_to_the_pose(nav_runs: dict[str, Any]) -> None:
    run, truth = nav_runs["cpp"]["run"], nav_runs["cpp"]["truth"]
    assert run.returncode == 0 and "stopped (final)" in run.stderr, run.stderr
    tb = truth["tb"]
    # odom (2, 1) from the start (1, 2) facing +x is (3, 3) in the world
    assert abs(tb["pose"]["x"] - 3.0) < 0.06 and abs(tb["pose"]["y"] - 3.0) < 0.06, tb["pose"]
    assert tb["collisions"] == []


def test_the_cpp_recording_is_pythons(nav_runs: dict[str, Any]) -> None:
    """The same keys in /hfsmc/interface/robot, the same command payloads."""
    cpp, py = snapshots(nav_runs["cpp"]["mcap"]), snapshots(nav_runs["python"]["mcap"])
    assert {k for s in cpp for k in s} == {k for s in py for k in s}
    for snaps in (cpp, py):
        goals = changes([s["goals"]["navigate"]["status"] for s in snaps])
        assert goals[0] == "none" and goals[-1] == "succeeded", goals
        assert set(goals) <= {"none", "pending", "accepted", "executing", "succeeded"}
        calls = changes([s["calls"]["reset"]["status"] for s in snaps])
        assert calls[0] == "none" and calls[-1] == "done", calls
    store = rosbags_store("jazzy")
    navs = [s["goals"]["navigate"] for s in cpp]
    feedback = [store.deserialize_cdr(base64.b64decode(g["feedback"]),
                                      "nav2_msgs/action/NavigateToPose_Feedback")
                for g in navs if g.get("feedback")]
    assert len(feedback) >= 3 and feedback[-1].distance_remaining < feedback[0].distance_remaining
    results = [g["result"] for g in navs if "result" in g]
    assert len(results) == 1
    assert store.deserialize_cdr(base64.b64decode(results[0]),
                                 "nav2_msgs/action/NavigateToPose_Result").error_code == 0
    responses = [s["calls"]["reset"]["response"] for s in cpp if "response" in s["calls"]["reset"]]
    assert len(responses) == 1
    assert store.deserialize_cdr(base64.b64decode(responses[0]), "std_srvs/srv/Trigger_Response").success
    cpp_cmds, py_cmds = commands(nav_runs["cpp"]["mcap"]), commands(nav_runs["python"]["mcap"])
    assert [(c["call"], c["args"]) for c in cpp_cmds] == [(c["call"], c["args"]) for c in py_cmds]
    assert [c["call"] for c in cpp_cmds] == ["call", "send_goal"]


@pytest.mark.parametrize(("recorded", "model", "said"), [
    ("cpp", "cpp", "(cpp -> cpp)"), ("cpp", "python", "(cpp -> python)"),
    ("python", "cpp", "(python -> cpp)")])
def test_replays_are_identical_across_languages(nav_runs: dict[str, Any], recorded: str,
                                                model: str, said: str) -> None:
    path = NAV_CPP if model == "cpp" else nav_runs["py_model"]
    done = hfsmc("replay", str(nav_runs[recorded]["mcap"]), "--model", str(path))
    assert done.returncode == 0, done.stdout + done.stderr
    assert f"{said}: identical:" in done.stdout and " 2 commands" in done.stdout, done.stdout


def test_a_replay_finds_another_goal_at_its_send_goal(nav_runs: dict[str, Any], tmp_path: Path) -> None:
    (tmp_path / "nav_cpp.yaml").write_text(
        NAV_CPP.read_text().replace("position.x = 2.0", "position.x = 2.5"))
    done = hfsmc("replay", str(nav_runs["cpp"]["mcap"]), "--model", str(tmp_path / "nav_cpp.yaml"))
    assert done.returncode == 1, done.stdout + done.stderr
    assert "different" in done.stdout and "(command 2):" in done.stdout, done.stdout
    assert "pose.pose.position.x=2.5" in done.stdout, done.stdout


# -- every status, against the runtime's Python test servers -------------------------------
@pytest.fixture(scope="module")
def messages(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Python runtime and messages the test servers run on."""
    out = tmp_path_factory.mktemp("servers")
    ms = message_set("jazzy", [("rmw_dds_common/msg/ParticipantEntitiesInfo", Span("t", 1, 1))], (),
                     [(t, Span("t", 1, 1)) for t in ("nav2_msgs/action/NavigateToPose",
                                                     "std_srvs/srv/Trigger")])
    generate(ms, out)
    for f in INTERFACE_FILES["ros2"]:
        (out / f).write_text((RUNTIME / f).read_text())
    return out


def scenario(build: Superbuild, messages: Path, tmp: Path, name: str) -> dict[str, Any]:
    """The C++ client against the servers of scenario ``name``: its recorded snapshots and
    commands, and the requests the servers received."""
    config = yaml.safe_load((build.folder(CLIENT) / "rpc_client_cpp.yaml").read_text())
    robot = config["interfaces"]["robot"]
    if name in ("timeout", "no_server"):
        robot["actions"]["nav"]["timeout"] = 1.5
        robot["services"]["reset"]["timeout"] = 1.5
    args = ["--param", "cancel_when_executing=true"] if name == "cancel" else []
    with ros2_domain() as dom:
        robot["domain"] = dom
        (tmp / "config.yaml").write_text(json.dumps(config))
        servers = None if name == "no_server" else subprocess.Popen(
            [sys.executable, str(SERVERS), str(dom), name, "12"], cwd=messages, text=True,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
            env={"PYTHONPATH": str(messages), "PATH": "/usr/bin:/bin",
                 "CYCLONEDDS_URI": os.environ["CYCLONEDDS_URI"]})
        try:
            if servers is not None:
                assert servers.stdout is not None and servers.stdout.readline().strip() == "ready"
            run = subprocess.run([str(build.executable(CLIENT)), "--config", str(tmp / "config.yaml"),
                                  "--until", "8s", "--record", str(tmp / "run.mcap"), *args],
                                 capture_output=True, text=True, timeout=60)
            raw: list[str] = []
            if servers is not None:
                out, err = servers.communicate(timeout=30)
                assert servers.returncode == 0, err
                raw = json.loads(out.strip().splitlines()[-1])["raw"]
        finally:
            if servers is not None and servers.poll() is None:
                servers.kill()
                servers.communicate()
    assert run.returncode == 0, run.stderr
    snaps = snapshots(tmp / "run.mcap")
    return {"goals": changes([s["goals"]["nav"]["status"] for s in snaps]),
            "calls": changes([s["calls"]["reset"]["status"] for s in snaps]),
            "snaps": snaps, "commands": commands(tmp / "run.mcap"), "raw": raw,
            "stderr": run.stderr}


def test_a_goal_gets_feedback_and_succeeds_and_the_requests_are_rosbags_bytes(
        build: Superbuild, messages: Path, tmp_path: Path) -> None:
    r = scenario(build, messages, tmp_path, "succeed")
    assert r["goals"][0] == "none" and r["goals"][-1] == "succeeded", r["goals"]
    assert set(r["goals"]) <= {"none", "pending", "accepted", "executing", "succeeded"}
    assert r["calls"][-1] == "done" and "stopped (final)" in r["stderr"]
    store = rosbags_store("jazzy")
    goals = [s["goals"]["nav"] for s in r["snaps"]]
    fb = [g["feedback"] for g in goals if g.get("feedback")]
    assert fb and store.deserialize_cdr(base64.b64decode(fb[-1]),
                                        "nav2_msgs/action/NavigateToPose_Feedback").distance_remaining == 2.5
    result = store.deserialize_cdr(base64.b64decode(next(g["result"] for g in goals if g.get("result"))),
                                   "nav2_msgs/action/NavigateToPose_Result")
    assert result.error_msg == "done"
    response = next(s["calls"]["reset"]["response"] for s in r["snaps"] if s["calls"]["reset"].get("response"))
    assert store.deserialize_cdr(base64.b64decode(response), "std_srvs/srv/Trigger_Response").message == "ok"
    raw = [bytes.fromhex(h) for h in r["raw"]]
    send = next(b for b in raw if len(b) > 40)  # the send_goal request
    _, seq = struct.unpack_from("<Qq", send, 4)
    assert seq == 1
    body = send[:4] + send[20:]
    msg = store.deserialize_cdr(body, "nav2_msgs/action/NavigateToPose_SendGoal_Request")
    assert msg.goal.pose.pose.position.x == 1.25 and msg.goal.behavior_tree == "bt"
    assert (msg.goal_id.uuid[6] >> 4) == 4  # a random (version 4) UUID
    again = bytes(store.serialize_cdr(msg, "nav2_msgs/action/NavigateToPose_SendGoal_Request"))
    # rosbags' bytes, padded to 4 with the padding announced in the options, as Cyclone does
    assert again[:3] + again[4:] == body[:3] + body[4:len(again)]
    assert body[3] == len(body) - len(again) and set(body[len(again):]) <= {0}
    # the goal command's bytes are the goal's, as rosbags writes it
    goal_cmd = next(c for c in r["commands"] if c["call"] == "send_goal")
    assert base64.b64decode(goal_cmd["args"][1]) == bytes(
        store.serialize_cdr(msg.goal, "nav2_msgs/action/NavigateToPose_Goal"))
    trigger = next(b for b in raw if len(b) <= 24)
    assert trigger[20:21] == bytes(store.serialize_cdr(
        store.types["std_srvs/srv/Trigger_Request"](structure_needs_at_least_one_member=0),
        "std_srvs/srv/Trigger_Request"))[4:5]


@pytest.mark.parametrize(("name", "last"), [("reject", "rejected"), ("abort", "aborted"),
                                             ("cancel", "canceled"), ("timeout", "timeout"),
                                             ("no_server", "timeout"), ("gone", "no_server")])
def test_every_end_of_a_goal(build: Superbuild, messages: Path, tmp_path: Path, name: str,
                             last: str) -> None:
    r = scenario(build, messages, tmp_path, name)
    assert r["goals"][-1] == last, r["goals"]
    if name == "cancel":
        assert "executing" in r["goals"]
        assert ["cancel", ["nav"]] in [[c["call"], c["args"]] for c in r["commands"]]
    if name == "no_server":
        assert "no_server" in r["goals"] and r["calls"][-2:] == ["no_server", "timeout"], r["calls"]
    elif name != "gone":
        assert r["calls"][-1] == "done", r["calls"]
    if name == "abort":
        goals = [s["goals"]["nav"] for s in r["snaps"]]
        result = next(g["result"] for g in goals if g.get("result"))
        assert rosbags_store("jazzy").deserialize_cdr(
            base64.b64decode(result), "nav2_msgs/action/NavigateToPose_Result").error_code == 9000
    if name == "gone":  # still running at --until: cancelled at stop, recorded
        assert [c["args"] for c in r["commands"] if c["call"] == "cancel"] == [["nav", "stop"]]


def test_a_goal_of_the_wrong_type_is_refused_at_its_line(tmp_path: Path) -> None:
    bad = NAV_CPP.read_text().replace('robot.send_goal("navigate", goal);',
                                      'robot.send_goal("navigate", goal.pose);')
    (tmp_path / "nav_cpp.yaml").write_text(bad)
    line = next(i for i, t in enumerate(bad.splitlines(), 1) if "goal.pose);" in t)
    run = hfsmc("check", str(tmp_path / "nav_cpp.yaml"))
    assert run.returncode == 1
    assert f"nav_cpp.yaml:{line}:" in run.stderr and "cannot convert 'geometry_msgs::msg::PoseStamped'" \
        in run.stderr and "NavigateToPose::Goal" in run.stderr, run.stderr
