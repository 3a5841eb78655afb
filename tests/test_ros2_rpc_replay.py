"""Actions and services recorded and replayed (docs/ros2.md "Recordings, replay and
rosbags", issue 30 item 2): a Python component that resets odometry and sends a
NavigateToPose goal to `hfsmc sim --robot diffdrive`, recorded; the goal's and the call's
statuses, feedback, result and response in each instant's snapshot (decoded with
rosbags); `hfsmc replay` identical; a model that sends another goal found at its
send_goal; a script's bad goal refused in one line."""

from __future__ import annotations

import base64
import json
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hfsmc.ros2.definitions import rosbags_store
from tests.ros2_support import ros2_domain
from tests.test_ros2_actions import NAV, ROOM
from tests.test_ros2_model import build, run_against_sim


def _hfsmc(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "hfsmc", *args], capture_output=True,
                          text=True, timeout=300, check=False)


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(the model, run.mcap): nav driven to its pose in the simulator, recorded."""
    tmp = tmp_path_factory.mktemp("rpcreplay")
    (tmp / "nav.yaml").write_text(NAV)
    component = build(tmp, tmp / "nav.yaml")
    with ros2_domain() as dom:
        run, truth = run_against_sim(tmp, ROOM + "robots: [{name: tb, x: 1, y: 2}]\n", dom,
                                     component, "--record", str(tmp / "run.mcap"),
                                     env={"ROS_DOMAIN_ID": str(dom)})
    assert run.returncode == 0, run.stderr
    assert "stopped (final)" in run.stderr, run.stderr
    assert isinstance(truth["tb"], dict) and truth["tb"]["collisions"] == []
    return tmp / "nav.yaml", tmp / "run.mcap"


def snapshots(mcap: Path) -> list[dict[str, Any]]:
    from mcap.reader import make_reader

    with mcap.open("rb") as f:
        return [json.loads(m.data) for _, c, m in make_reader(f).iter_messages()
                if c.topic == "/hfsmc/interface/robot"]


def test_statuses_feedback_results_and_responses_are_in_the_snapshots(
        recording: tuple[Path, Path]) -> None:
    _, mcap = recording
    snaps = snapshots(mcap)
    goals = [s["goals"]["navigate"] for s in snaps]
    calls = [s["calls"]["reset"] for s in snaps]
    seen: list[str] = []
    for g in goals:
        if not seen or seen[-1] != g["status"]:
            seen.append(g["status"])
    assert seen[0] == "none" and seen[-1] == "succeeded", seen
    assert set(seen) <= {"none", "pending", "accepted", "executing", "succeeded"}
    assert calls[0]["status"] == "none" and calls[-1]["status"] == "done"
    store = rosbags_store("jazzy")

    def decoded(text: str, kind: str) -> Any:
        return store.deserialize_cdr(base64.b64decode(text), kind)

    # each message once, in the instant it changed: the feedback's distance goes down
    feedback = [decoded(g["feedback"], "nav2_msgs/action/NavigateToPose_Feedback")
                for g in goals if g.get("feedback")]
    assert len(feedback) >= 3
    assert feedback[-1].distance_remaining < feedback[0].distance_remaining
    results = [g["result"] for g in goals if "result" in g]
    assert len(results) == 1
    assert decoded(results[0], "nav2_msgs/action/NavigateToPose_Result").error_code == 0
    responses = [c["response"] for c in calls if "response" in c]
    assert len(responses) == 1
    assert decoded(responses[0], "std_srvs/srv/Trigger_Response").success


def test_replay_is_identical(recording: tuple[Path, Path]) -> None:
    model, mcap = recording
    done = _hfsmc("replay", str(mcap), "--model", str(model))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "(python -> python): identical:" in done.stdout
    assert " 2 commands" in done.stdout  # the call and the goal, each compared by its bytes


def test_replay_of_a_model_that_sends_another_goal(recording: tuple[Path, Path],
                                                   tmp_path: Path) -> None:
    model, mcap = recording
    shutil.copy(model, tmp_path / "nav.yaml")
    text = (tmp_path / "nav.yaml").read_text()
    (tmp_path / "nav.yaml").write_text(text.replace("position.x = 2.0", "position.x = 2.5"))
    done = _hfsmc("replay", str(mcap), "--model", str(tmp_path / "nav.yaml"))
    assert done.returncode == 1, done.stdout + done.stderr
    assert "different" in done.stdout and "(command 2):" in done.stdout, done.stdout
    assert 'recorded: robot.send_goal("navigate", NavigateToPose.Goal(pose.header.frame_id=' \
        "'odom', pose.pose.position.x=2.0, pose.pose.position.y=1.0, " \
        "pose.pose.orientation.w=1.0)) at " in done.stdout, done.stdout
    assert "pose.pose.position.x=2.5" in done.stdout


def test_a_replay_that_waits_on_a_status_the_recording_lacks_is_no_evidence(
        recording: tuple[Path, Path], tmp_path: Path) -> None:
    """A model with an action the recorded one did not have: its status is not evidence."""
    model, mcap = recording
    text = model.read_text().replace(
        "    services:\n",
        "      dock: {name: dock, type: nav2_msgs/action/NavigateToPose}\n    services:\n")
    text = text.replace('robot.goal_status("navigate") == "succeeded"',
                        'robot.goal_status("navigate") == "succeeded" '
                        'and robot.goal_status("dock") == "none"')
    (tmp_path / "nav.yaml").write_text(text)
    done = _hfsmc("replay", str(mcap), "--model", str(tmp_path / "nav.yaml"))
    assert "goal_status" in done.stdout + done.stderr, done.stdout + done.stderr
    assert "dock" in done.stdout + done.stderr


def _playback(component: Path, folder: Path, rows: list[dict[str, Any]]
              ) -> subprocess.CompletedProcess[str]:
    folder.mkdir()
    (folder / "inputs.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return subprocess.run([sys.executable, str(component), "--playback", str(folder),
                           "--trace", str(folder / "trace.jsonl"), "--until", "3s"],
                          capture_output=True, text=True, timeout=60)


def test_a_script_answers_goals_and_calls_at_its_instants_and_bad_ones_are_refused(
        tmp_path: Path) -> None:
    (tmp_path / "nav.yaml").write_text(NAV)
    component = build(tmp_path, tmp_path / "nav.yaml")
    store = rosbags_store("jazzy")
    result = base64.b64encode(store.serialize_cdr(
        store.types["nav2_msgs/action/NavigateToPose_Result"](error_code=0, error_msg=""),
        "nav2_msgs/action/NavigateToPose_Result")).decode()

    def row(t: int, **values: Any) -> dict[str, Any]:
        return {"t": t, "kind": "snapshot", "interface": "robot", "values": values}

    good = [row(0, calls={"reset": {"status": "none"}}, goals={"navigate": {"status": "none"}}),
            row(500_000, calls={"reset": {"status": "done"}}),
            row(1_000_000, goals={"navigate": {"status": "executing"}}),
            row(2_000_000, goals={"navigate": {"status": "succeeded", "result": result}})]
    run = _playback(component, tmp_path / "good", good)
    assert run.returncode == 0, run.stderr
    trace = [json.loads(line)
             for line in (tmp_path / "good" / "trace.jsonl").read_text().splitlines()]
    fired = [(r["t"], r["to"]) for r in trace if r["ev"] == "fire"]
    assert fired == [(500, "Go"), (2000, "Done")]  # at the instants the script says
    commands = [json.loads(line)
                for line in (tmp_path / "good" / "commands.jsonl").read_text().splitlines()]
    assert [(c["t"], c["call"], c["args"][0]) for c in commands] == [
        (0, "call", "reset"), (500_000, "send_goal", "navigate")]
    cases: list[tuple[str, dict[str, Any], str]] = [
            ("status", {"goals": {"navigate": {"status": "flying"}}},
             "`goals.navigate`: {status, feedback, result} with a status among none, "),
            ("bytes", {"goals": {"navigate": {"status": "executing", "feedback": "AAEA"}}},
             "`navigate`'s feedback is no nav2_msgs/action/NavigateToPose_Feedback: "),
            ("name", {"calls": {"rest": {"status": "done"}}}, "no service `rest` (reset)"),
            ("field", {"calls": {"reset": {"status": "done", "answer": None}}},
             "`calls.reset` has no field `answer`")]
    for name, bad, said in cases:
        run = _playback(component, tmp_path / name, [row(0, **bad)])
        assert run.returncode == 2, (name, run.stderr)
        lines = run.stderr.strip().splitlines()
        assert len(lines) == 1 and "inputs.jsonl: t=0: interface `robot`: " in lines[0] \
            and said in lines[0], (name, lines)
