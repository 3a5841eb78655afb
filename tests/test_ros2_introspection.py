"""The automaton on ROS 2 (SPEC 5.4, docs/ros2.md "The automaton on ROS 2"): a component
with `introspection: true` publishes yasmin_msgs/msg/StateMachine on /fsm_viewer and its
JSON status on ~/hfsm/status; decoded here with rosbags from yasmin_msgs' .msg files, for
a model with regions and a used file; the C++ twin's samples byte for byte the Python
component's; off unless asked; bad settings refused."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from hfsmc.ros2.services import SHIPPED
from tests.cppbuild import Superbuild
from tests.ros2_support import ros2_domain
from tests.support import hfsmc

HERE = Path(__file__).resolve().parent
MODEL = HERE / "ros2" / "models" / "introspect" / "watcher.yaml"
CPP_MODEL = HERE / "ros2" / "models" / "introspect_cpp" / "watcher.yaml"
LISTENER = HERE / "ros2" / "fsm_listener.py"
STATUS_TOPIC = "/tb7/watcher/hfsm/status"

# (name, parent id, is_fsm) of each state, depth first in model order: a state with
# regions is a machine of its regions, a region a machine of its states, a used file's
# states are those of the using state.
EXPECTED = [("tb7.watcher", -1, True), ("Idle", 0, False), ("Mission", 0, True),
            ("Drive", 2, True), ("Leg", 3, True), ("Turn", 4, False), ("Go", 4, False),
            ("Arrived", 4, False), ("Parked", 3, False), ("Watch", 2, True), ("Ok", 9, False),
            ("Alarm", 9, False), ("Done", 0, False)]


def rosbags_store() -> Any:
    """rosbags' jazzy store with yasmin_msgs registered from the shipped .msg files."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ("Transition", "State", "StateMachine"):
        text = (SHIPPED / "yasmin_msgs" / "msg" / f"{name}.msg").read_text()
        store.register(get_types_from_msg(text, f"yasmin_msgs/msg/{name}"))
    return store


def listen(folder: Path, component: list[str], domain: int, until_stop: bool = True
           ) -> list[tuple[str, bytes]]:
    """Run the listener from ``folder``, then the component (a Python component's file, or a
    command) on ``domain``: every sample
    (until the component's last status, or, ``until_stop`` False, a moment after it ends)."""
    env = {**os.environ, "PYTHONPATH": str(folder), "ROS_DOMAIN_ID": str(domain)}
    listener = subprocess.Popen([sys.executable, str(LISTENER), str(domain), STATUS_TOPIC,
                                 "30"], cwd=folder, env=env, stdout=subprocess.PIPE,
                                stderr=subprocess.PIPE, text=True)
    try:
        assert listener.stdout is not None
        assert json.loads(listener.stdout.readline()) == {"ready": True}
        run = subprocess.run([sys.executable, *component] if component[0].endswith(".py")
                             else component, capture_output=True, text=True, timeout=60, env=env)
        assert run.returncode == 0, run.stderr
        if not until_stop:
            time.sleep(0.5)
            listener.terminate()
        out, err = listener.communicate(timeout=40)
    finally:
        if listener.poll() is None:
            listener.kill()
            listener.communicate()
    assert listener.returncode == (0 if until_stop else -signal.SIGTERM), err
    lines = [json.loads(line) for line in out.splitlines()]
    return [(x["topic"], bytes.fromhex(x["cdr"])) for x in lines]


@pytest.fixture(scope="module")
def component(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("introspect") / "watcher"
    result = hfsmc("build", str(MODEL), "-o", str(out))
    assert result.returncode == 0, result.stderr
    return out


def test_yasmins_message_shows_the_structure_and_the_active_states(component: Path) -> None:
    with ros2_domain() as dom:
        samples = listen(component, [str(component / "watcher.py")], dom)
    store = rosbags_store()
    machines = [store.deserialize_cdr(b, "yasmin_msgs/msg/StateMachine")
                for t, b in samples if t == "/fsm_viewer"]
    statuses = [json.loads(store.deserialize_cdr(b, "std_msgs/msg/String").data)
                for t, b in samples if t == STATUS_TOPIC]
    assert machines and statuses
    for m in machines:  # the structure is the same in every message
        assert [(s.name, s.parent, s.is_fsm) for s in m.states] == EXPECTED
        assert [s.id for s in m.states] == list(range(len(EXPECTED)))
        by_name = {s.name: s for s in m.states}
        assert [(t.outcome, t.state) for t in by_name["Idle"].transitions] == [("go", "Mission")]
        assert [(t.outcome, t.state) for t in by_name["Mission"].transitions] == \
            [("finish", "Done")]
        assert [(t.outcome, t.state) for t in by_name["Leg"].transitions] == [("t0", "Parked")]
        assert [(t.outcome, t.state) for t in by_name["Turn"].transitions] == [("t0", "Go")]
        assert list(by_name["Turn"].outcomes) == ["t0"] and list(by_name["Done"].outcomes) == []
        for s in m.states:
            if not s.is_fsm:
                assert s.current_state == -1
    names = [s[0] for s in EXPECTED]

    def active(m: Any) -> tuple[str, ...]:
        """The active states, by following each machine's current_state from the top."""
        out: list[int] = []
        todo = [0]
        while todo:
            s = m.states[todo.pop()]
            if s.name == "Mission" and s.id == m.states[0].current_state:
                assert s.current_state == -1  # regions: each says its own
                todo += [3, 9]
            elif s.current_state >= 0:
                out.append(s.current_state)
                todo.append(s.current_state)
        return tuple(names[i] for i in sorted(out))

    seen: list[tuple[str, ...]] = []
    for m in machines:
        a = active(m)
        if not seen or seen[-1] != a:
            seen.append(a)
    # each configuration is published at the transition into it, however short it lasts
    assert seen[0] == ("Idle",), seen
    assert seen[-1] == (), seen  # the last word: stopped, nothing active
    for want in [("Mission", "Leg", "Turn", "Ok"), ("Mission", "Leg", "Go", "Alarm"),
                 ("Mission", "Leg", "Arrived", "Alarm"), ("Mission", "Parked", "Alarm"),
                 ("Done",)]:
        assert want in seen, (want, seen)
    order = [seen.index(w) for w in [("Idle",), ("Mission", "Leg", "Go", "Alarm"),
                                     ("Mission", "Parked", "Alarm"), ("Done",)]]
    assert order == sorted(order)
    # 4 Hz while nothing happens: Idle lasts 1.5 s
    assert sum(1 for m in machines if active(m) == ("Idle",)) >= 2
    # the JSON status: the monitor's snapshot, named as the machine
    assert {s["type"] for s in statuses} == {"snapshot"}
    assert {s["name"] for s in statuses} == {"tb7.watcher"}
    both = [s for s in statuses if {"Mission/Drive/Leg/Go", "Mission/Watch/Alarm"}
            <= {a["state"] for a in s["active"]}]
    assert both, statuses
    assert statuses[-1]["stop"]["reason"] == "final"
    assert [a["state"] for a in statuses[-1]["stop"]["states"]] == ["Done"]
    assert statuses[-1]["transitions"][0]["name"] == "go"


def test_introspection_is_off_unless_asked(component: Path, tmp_path: Path) -> None:
    config = json.loads((component / "watcher.yaml").read_text().split("\n", 5)[-1])
    config["interfaces"]["robot"]["introspection"] = False
    (tmp_path / "off.yaml").write_text(json.dumps(config))
    with ros2_domain() as dom:
        samples = listen(component, [str(component / "watcher.py"), "--config",
                                     str(tmp_path / "off.yaml"), "--until", "2s"], dom,
                         until_stop=False)
    assert samples == []


def test_a_model_without_it_cannot_turn_it_on_in_its_configuration(tmp_path: Path) -> None:
    text = MODEL.read_text().replace("    introspection: true\n", "")
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "leg.yaml").write_text((MODEL.parent / "lib" / "leg.yaml").read_text())
    (tmp_path / "watcher.yaml").write_text(text)
    out = tmp_path / "out"
    assert hfsmc("build", str(tmp_path / "watcher.yaml"), "-o", str(out)).returncode == 0
    assert not (out / "yasmin_msgs").exists()  # its messages are generated only when asked
    (tmp_path / "on.yaml").write_text(json.dumps(
        {"interfaces": {"robot": {"introspection": True}}}))
    run = subprocess.run([sys.executable, str(out / "watcher.py"), "--config",
                          str(tmp_path / "on.yaml"), "--until", "1s"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "watcher: the configuration of interface `robot`: `introspection: true`: the model "
        "does not ask for it (its messages are not generated): change the model and rebuild"]
    (tmp_path / "bad.yaml").write_text(json.dumps(
        {"interfaces": {"robot": {"introspection": "yes"}}}))
    run = subprocess.run([sys.executable, str(out / "watcher.py"), "--config",
                          str(tmp_path / "bad.yaml"), "--until", "1s"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "`introspection: yes`: true or false" in run.stderr


def test_the_key_in_yaml_and_xml_and_its_errors(tmp_path: Path) -> None:
    (tmp_path / "lib").mkdir()
    (tmp_path / "lib" / "leg.yaml").write_text((MODEL.parent / "lib" / "leg.yaml").read_text())
    (tmp_path / "watcher.yaml").write_text(MODEL.read_text())
    xml = tmp_path / "watcher.xml"
    assert hfsmc("convert", str(tmp_path / "watcher.yaml"), "-o", str(xml)).returncode == 0
    assert 'introspection="true"' in xml.read_text()
    back = tmp_path / "back.yaml"
    assert hfsmc("convert", str(xml), "-o", str(back)).returncode == 0
    assert "introspection: true" in back.read_text()
    dumped = hfsmc("build", str(xml), "--dump-ir")
    assert dumped.returncode == 0 and " introspection " in dumped.stdout
    (tmp_path / "bad.yaml").write_text(MODEL.read_text().replace(
        "introspection: true", "introspection: yes please"))
    bad = hfsmc("check", str(tmp_path / "bad.yaml"))
    assert bad.returncode == 1 and "bad.yaml:9:" in bad.stderr
    cpp = MODEL.read_text().replace("name: watcher\n", "name: watcher\nlanguage: cpp\n")
    (tmp_path / "cpp.yaml").write_text(cpp)
    (tmp_path / "lib" / "leg.yaml").write_text(
        (MODEL.parent / "lib" / "leg.yaml").read_text().replace(
            "name: leg\n", "name: leg\nlanguage: cpp\n"))
    good = hfsmc("check", str(tmp_path / "cpp.yaml"))  # C++ components have it too
    assert good.returncode == 0, good.stderr


def test_the_cpp_twin_publishes_the_python_components_bytes(component: Path,
                                                           tmp_path: Path) -> None:
    """The same model and instant give the same samples in both languages: every
    configuration's StateMachine, and the JSON status of every instant both published (those
    of the transitions and the last word, at least); each decoded with rosbags and written
    again byte for byte (the encapsulation's options, which say how much padding DDS added,
    and the padding aside)."""
    sb = Superbuild(tmp_path / "build", [CPP_MODEL], build_type="Release")
    exe = sb.executable(CPP_MODEL)
    runs = {}
    for lang, cmd in (("python", [str(component / "watcher.py")]),
                      ("cpp", [str(exe), "--config", str(sb.folder(CPP_MODEL) / "watcher.yaml")])):
        with ros2_domain() as dom:
            runs[lang] = listen(component, cmd, dom)
    store = rosbags_store()

    def body(raw: bytes, type_name: str) -> bytes:
        msg = store.deserialize_cdr(raw, type_name)
        again = bytes(store.serialize_cdr(msg, type_name))
        assert raw[:2] == again[:2] and raw[4:len(again)] == again[4:], type_name
        assert set(raw[len(again):]) <= {0}
        return again

    machines: dict[str, list[bytes]] = {}
    statuses: dict[str, dict[int, set[bytes]]] = {}
    for lang, samples in runs.items():
        machines[lang], statuses[lang] = [], {}
        for topic, raw in samples:
            if topic == "/fsm_viewer":
                b = body(raw, "yasmin_msgs/msg/StateMachine")
                if not machines[lang] or machines[lang][-1] != b:
                    machines[lang].append(b)
            else:
                b = body(raw, "std_msgs/msg/String")
                t = json.loads(store.deserialize_cdr(raw, "std_msgs/msg/String").data)["t"]
                statuses[lang].setdefault(t, set()).add(b)
    assert machines["cpp"] == machines["python"] and len(machines["cpp"]) == 7
    common = statuses["cpp"].keys() & statuses["python"].keys()
    assert {1500, 1800, 2100, 2200, 3000} <= common, sorted(common)
    for t in sorted(common):
        assert statuses["cpp"][t] == statuses["python"][t], t
    last = store.deserialize_cdr(runs["cpp"][-1][1], "std_msgs/msg/String").data
    assert json.loads(last)["stop"]["reason"] == "final"
    # NAME.yaml turns it off (nothing on the wire), and a value that is no bool is refused
    config = json.loads((sb.folder(CPP_MODEL) / "watcher.yaml").read_text().split("\n", 5)[-1])
    config["interfaces"]["robot"]["introspection"] = False
    (tmp_path / "off.yaml").write_text(json.dumps(config))
    with ros2_domain() as dom:
        assert listen(component, [str(exe), "--config", str(tmp_path / "off.yaml"),
                                  "--until", "2s"], dom, until_stop=False) == []
    config["interfaces"]["robot"]["introspection"] = "yes"
    (tmp_path / "bad.yaml").write_text(json.dumps(config))
    run = subprocess.run([str(exe), "--config", str(tmp_path / "bad.yaml"), "--until", "1s"],
                         capture_output=True, text=True, timeout=60)
    assert run.returncode == 2 and "`introspection: yes`: true or false" in run.stderr, run.stderr


CLASH = """\
hfsm: 1
name: clash
interfaces:
  robot:
    type: ros2
    introspection: true
    publish:
      v: {topic: TOPIC, type: std_msgs/msg/String}
initial: A
states:
  A: {transitions: [{to: B, after: 1s}]}
  B: {final: true}
"""


def test_the_introspections_topics_are_its_own(tmp_path: Path) -> None:
    for topic, col in (("/fsm_viewer", 18), ("~/hfsm/status", 18)):
        (tmp_path / "clash.yaml").write_text(CLASH.replace("TOPIC", topic))
        bad = hfsmc("check", str(tmp_path / "clash.yaml"))
        assert bad.returncode == 1
        assert f"clash.yaml:8:{col}: error[E314]: topic " in bad.stderr, bad.stderr
    # a configuration file that renames a topic onto one of them: refused at start
    (tmp_path / "clash.yaml").write_text(CLASH.replace("TOPIC", "/other"))
    out = tmp_path / "out"
    assert hfsmc("build", str(tmp_path / "clash.yaml"), "-o", str(out)).returncode == 0
    (tmp_path / "rename.yaml").write_text(json.dumps(
        {"interfaces": {"robot": {"publish": {"v": {"topic": "/fsm_viewer"}}}}}))
    with ros2_domain() as dom:
        run = subprocess.run([sys.executable, str(out / "clash.py"), "--config",
                              str(tmp_path / "rename.yaml"), "--until", "1s"],
                             capture_output=True, text=True, timeout=60,
                             env={**os.environ, "ROS_DOMAIN_ID": str(dom)})
    assert run.returncode == 2
    assert run.stderr.strip().splitlines() == [
        "robot: ros2: topic /fsm_viewer is the introspection's (yasmin_msgs/msg/StateMachine): "
        "the model may not subscribe or publish it"]
