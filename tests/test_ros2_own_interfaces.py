"""A model's own `.srv` and `.action` files (docs/ros2.md, "Services and actions": "The
model's own services and actions"): generated, called and served over real DDS by the
runtime's test servers, every sample on the wire checked against rosbags' serialization of
the same definitions; bad files reported at their line, bad uses at the model's."""

from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hfsmc.errors import CheckError, Span
from hfsmc.ros2.definitions import MsgFile, message_set
from tests.ros2_support import build_component, ros2_domain
from tests.support import hfsmc

SERVERS = Path(__file__).resolve().parent / "ros2" / "own_servers.py"
STATION = "# a charging station\nstring name\nfloat64 x\nfloat64 y\n"
BEEP = "# beep a number of times\nuint8 LOUD=2\nuint8 times 3\nstring<=8 tune \"do\"\n---\n" \
       "bool ok\nstring said\n"
DOCK = "# dock at a station\nStation station\nfloat32 speed 0.2\n---\nint32 CODE_BLOCKED=7\n" \
       "int32 code\nStation[] tried\n---\nfloat64 distance_remaining\n"
FILES = {"dock_msgs/msg/Station.msg": STATION, "dock_msgs/srv/Beep.srv": BEEP,
         "dock_msgs/action/Dock.action": DOCK}
MODEL = """\
hfsm: 1
name: dock
imports:
  - from dock_msgs.action import Dock
  - from dock_msgs.srv import Beep
  - from dock_msgs.msg import Station
interfaces:
  robot:
    type: ros2
    messages: [dock_msgs/msg/Station.msg, dock_msgs/srv/Beep.srv, dock_msgs/action/Dock.action]
    actions:
      dock: {name: dock, type: dock_msgs/action/Dock, timeout: 30s}
    services:
      beep: {name: beep, type: dock_msgs/srv/Beep, timeout: 30s}
initial: Beep
states:
  Beep:
    entry: robot.call("beep", Beep.Request(times=Beep.Request.LOUD))
    transitions:
      - {to: Go, when: robot.call_status("beep") == "done" and robot.response("beep").said == "beep beep"}
  Go:
    entry: robot.send_goal("dock", Dock.Goal(station=Station(name="home", x=1.5, y=-2.0)))
    transitions:
      - {to: Done, when: robot.goal_status("dock") == "succeeded" and robot.result("dock").code == Dock.Result.CODE_BLOCKED}
  Done:
    final: true
"""


def write_model(tmp: Path, files: dict[str, str] | None = None, model: str = MODEL) -> Path:
    for rel, text in (files or FILES).items():
        (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp / rel).write_text(text)
    (tmp / "dock.yaml").write_text(model)
    return tmp / "dock.yaml"


def reference() -> Any:
    """rosbags' jazzy store with the same definitions registered, split by hand and with
    the messages rosidl derives of an action written out here (not through hfsmc)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    req, resp = BEEP.split("---\n")
    goal, result, feedback = DOCK.split("---\n")
    texts = {
        "dock_msgs/msg/Station": STATION,
        "dock_msgs/srv/Beep_Request": req, "dock_msgs/srv/Beep_Response": resp,
        "dock_msgs/action/Dock_Goal": goal.replace("Station ", "dock_msgs/Station "),
        "dock_msgs/action/Dock_Result": result.replace("Station[]", "dock_msgs/Station[]"),
        "dock_msgs/action/Dock_Feedback": feedback,
        "dock_msgs/action/Dock_SendGoal_Request":
            "unique_identifier_msgs/UUID goal_id\ndock_msgs/action/Dock_Goal goal\n",
        "dock_msgs/action/Dock_GetResult_Response":
            "int8 status\ndock_msgs/action/Dock_Result result\n",
        "dock_msgs/action/Dock_FeedbackMessage":
            "unique_identifier_msgs/UUID goal_id\ndock_msgs/action/Dock_Feedback feedback\n",
    }
    for name, text in texts.items():
        # rosbags' parser takes `pkg/msg/Name` (it turns `pkg/srv/Name` into another name)
        as_msg = f"dock_msgs/msg/{name.rsplit('/', 1)[1]}"
        store.register({name: get_types_from_msg(text, as_msg)[as_msg]})
    return store


def decode(store: Any, sample_hex: str, type_name: str, header: bool = True) -> Any:
    """A sample as rosbags reads it (after rmw_cyclonedds_cpp's request header), checked
    to be byte for byte rosbags' serialization of what it holds (DDS's padding aside)."""
    raw = bytes.fromhex(sample_hex)
    body = raw[:4] + raw[20:] if header else raw
    msg = store.deserialize_cdr(body, type_name)
    again = bytes(store.serialize_cdr(msg, type_name))
    assert again == body[:len(again)] and set(body[len(again):]) <= {0}, type_name
    return msg


def test_an_own_action_and_service_on_the_wire_are_rosbags_bytes(tmp_path: Path) -> None:
    component = build_component(tmp_path, write_model(tmp_path))
    out = component.parent
    assert (out / "dock_msgs" / "action" / "__init__.py").is_file()
    with ros2_domain() as dom:
        env = {"PYTHONPATH": str(out), "PATH": "/usr/bin:/bin",
               "CYCLONEDDS_URI": os.environ["CYCLONEDDS_URI"]}
        server = subprocess.Popen([sys.executable, str(SERVERS), str(dom)], cwd=out, env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            run = subprocess.run([sys.executable, str(component), "--until", "30s"],
                                 capture_output=True, text=True, timeout=60,
                                 env={**os.environ, "ROS_DOMAIN_ID": str(dom)})
            sout, serr = server.communicate(timeout=60)
        finally:
            server.kill()
            server.wait()
    assert run.returncode == 0 and "stopped (final)" in run.stderr, run.stderr
    assert server.returncode == 0, serr
    seen = json.loads(sout.strip().splitlines()[-1])
    store = reference()
    request = decode(store, seen["beep.in"][0], "dock_msgs/srv/Beep_Request")
    assert (request.times, request.tune) == (2, "do")
    assert struct.unpack_from("<q", bytes.fromhex(seen["beep.in"][0]), 12)[0] == 1
    response = decode(store, seen["beep.out"][0], "dock_msgs/srv/Beep_Response")
    assert (response.ok, response.said) == (True, "beep beep")
    send = decode(store, seen["send_goal.in"][0], "dock_msgs/action/Dock_SendGoal_Request")
    assert (send.goal.station.name, send.goal.station.x, send.goal.station.y) == \
        ("home", 1.5, -2.0)
    assert abs(send.goal.speed - 0.2) < 1e-6  # the .action's default, float32
    fb = decode(store, seen["feedback.out"][0], "dock_msgs/action/Dock_FeedbackMessage",
                header=False)
    assert bytes(fb.goal_id.uuid) == bytes(send.goal_id.uuid)
    assert fb.feedback.distance_remaining == 0.75
    result = decode(store, seen["get_result.out"][-1], "dock_msgs/action/Dock_GetResult_Response")
    assert result.status == 4 and result.result.code == 7
    assert [s.name for s in result.result.tried] == ["home"]


def own(tmp: Path, rel: str, text: str) -> MsgFile:
    (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
    (tmp / rel).write_text(text)
    return MsgFile(tmp / rel, rel)


@pytest.mark.parametrize(("rel", "text", "line", "what"), [
    ("my_msgs/srv/Beep.srv", "int32 a\n---\nbool ok\n---\nint32 b\n", 4,
     "a service file has 2 parts (request, response) separated by 1 `---` line: this one is "
     "too many"),
    ("my_msgs/srv/Beep.srv", "int32 a\nbool ok\n", 2,
     "a service file has 2 parts (request, response) separated by `---` lines: this one has 1"),
    ("my_msgs/action/Dock.action", "int32 a\n---\nbool ok\n", 3,
     "an action file has 3 parts (goal, result, feedback) separated by `---` lines: this one "
     "has 2"),
    ("my_msgs/srv/Beep.srv", "int32 a\n---\nbool ok\n  %%\n", 4, "not a ROS 2 .msg line"),
    ("my_msgs/action/Dock.action", "int32 a\n---\nbool ok\n---\nuint8 v 300\n", 5,
     "`300` is not a value of type uint8"),
    ("my_msgs/action/Dock.action", "int32 a\n---\n\nStaton s\n---\n", 4,
     "unknown message type `my_msgs/msg/Staton`"),
    ("my_msgs/srv/Beep.srv", "int32 a\nint32 a\n---\n", 2, "`a` is defined twice"),
    ("my_msgs/msg/Beep.srv", "int32 a\n---\n", 1, "a service `PACKAGE/srv/Name.srv`"),
    ("my_msgs/msg/Station.msg", "int32 a\n---\nint32 b\n", 2, "a message file has no `---`"),
    ("std_srvs/srv/Trigger.srv", "---\nbool ok\n", 1,
     "`std_srvs/srv/Trigger` is a standard service of jazzy"),
    ("my_msgs/action/dock.action", "---\n---\n", 1, "action name `dock` is not CamelCase"),
])
def test_a_bad_own_file_is_reported_at_its_line(tmp_path: Path, rel: str, text: str, line: int,
                                                 what: str) -> None:
    station = own(tmp_path, "my_msgs/msg/Station.msg", STATION)
    files = [station] if rel != "my_msgs/msg/Station.msg" else []
    with pytest.raises(CheckError) as err:
        message_set("jazzy", [], [*files, own(tmp_path, rel, text)])
    d = err.value.diagnostics[0]
    assert d.code == "E311" and what in d.message, d.message
    assert (d.span.file, d.span.line) == (rel, line)


def test_a_nested_type_did_you_mean_and_two_files_of_one_type(tmp_path: Path) -> None:
    station = own(tmp_path, "my_msgs/msg/Station.msg", STATION)
    bad = own(tmp_path, "my_msgs/action/Dock.action", "Staton s\n---\n---\n")
    with pytest.raises(CheckError) as err:
        message_set("jazzy", [], [station, bad])
    assert "did you mean `my_msgs/msg/Station`?" in err.value.diagnostics[0].notes
    one = own(tmp_path, "a/my_msgs/srv/Beep.srv", "---\n")
    two = own(tmp_path, "b/my_msgs/srv/Beep.srv", "---\n")
    with pytest.raises(CheckError, match=r"`my_msgs/srv/Beep` is also defined by "
                       r"a/my_msgs/srv/Beep\.srv"):
        message_set("jazzy", [], [one, two])


def test_empty_parts_and_the_message_set(tmp_path: Path) -> None:
    """An empty part is ROS 2's one-byte message; the set has what the runtime needs."""
    files = [own(tmp_path, "my_msgs/srv/Ping.srv", "---\n"),
             own(tmp_path, "my_msgs/action/Wait.action", "---\n---\n")]
    at = Span("m.yaml", 1, 1)
    ms = message_set("humble", [], files, [("my_msgs/srv/Ping", at), ("my_msgs/action/Wait", at)])
    assert ms.services == ("action_msgs/srv/CancelGoal", "my_msgs/srv/Ping")
    assert ms.actions == ("my_msgs/action/Wait",)
    req = ms.get("my_msgs/srv/Ping_Request")
    assert [f.name for f in req.fields] == ["structure_needs_at_least_one_member"]
    assert req.origin == "my_msgs/srv/Ping.srv" and req.dds_type_name == \
        "my_msgs::srv::dds_::Ping_Request_"
    assert ms.get("my_msgs/action/Wait_SendGoal_Request").origin == "my_msgs/action/Wait.action"


def test_check_finds_a_bad_use_of_own_types_at_the_model(tmp_path: Path) -> None:
    bad = MODEL.replace("type: dock_msgs/action/Dock,", "type: dock_msgs/action/Dok,")
    bad = bad.replace("type: dock_msgs/srv/Beep,", "type: dock_msgs/action/Dock,")
    run = hfsmc("check", str(write_model(tmp_path, model=bad)))
    assert run.returncode == 1
    lines = run.stderr.splitlines()
    dok = next(x for x in lines if "dock.yaml:12:" in x)
    assert "E316" in dok and "unknown ROS 2 action type `dock_msgs/action/Dok`" in dok
    assert "did you mean `dock_msgs/action/Dock`?" in run.stderr
    assert any("dock.yaml:14:" in x and "E316" in x and "is not a service type" in x
               for x in lines), run.stderr
    # a bad line of the model's file is found by `check` at the file's line
    files = {**FILES, "dock_msgs/srv/Beep.srv": BEEP.replace("bool ok", "bool ok 2")}
    run = hfsmc("check", str(write_model(tmp_path, files=files)))
    assert run.returncode == 1 and "Beep.srv:6:" in run.stderr and "E311" in run.stderr
