"""The ``ros2`` interface in models (docs/ros2.md, SPEC 5.2): the keys in YAML and XML, the
model's own ``.msg`` files, `check`'s name rules against the runtime's, and built Python
components on real DDS (loopback) driving `hfsmc sim --robot diffdrive`, with the
configuration file changing domain, namespace and topic names without a rebuild.

The bad inputs that are one model each live under tests/invalid/ (ros2_*.yaml)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from hfsmc.pipeline import compile_file
from hfsmc.ros2 import names
from tests.ros2_support import build_component, ros2_domain, run_against_sim
from tests.support import ROOT, hfsmc

EXAMPLE = ROOT / "examples" / "stop_at_wall" / "stop_at_wall.yaml"
ROOM = "walls: [[[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]]]\nlaser: {range_max: 8}\n"
DETECTION = "# a detection\nstring label\nfloat32 score 0.5\ngeometry_msgs/Point where\n"


def model_with_messages(tmp: Path, msg: str) -> Path:
    (tmp / "my_msgs" / "msg").mkdir(parents=True)
    (tmp / "my_msgs" / "msg" / "Detection.msg").write_text(msg)
    model = tmp / "seer.yaml"
    model.write_text(
        "hfsm: 1\nname: seer\nimports:\n  - from my_msgs.msg import Detection\n"
        "interfaces:\n  robot:\n    type: ros2\n    messages: [my_msgs/msg/Detection.msg]\n"
        "    publish:\n      seen: {topic: seen, type: my_msgs/msg/Detection, "
        "qos: {reliability: best_effort, depth: 3}}\n"
        "initial: A\nstates:\n  A: {final: true}\n")
    return model


def test_yaml_and_xml_give_one_model(tmp_path: Path) -> None:
    model = model_with_messages(tmp_path, DETECTION)
    xml = tmp_path / "seer.xml"
    assert hfsmc("convert", str(model), "-o", str(xml)).returncode == 0
    text = xml.read_text()
    assert '<message file="my_msgs/msg/Detection.msg"/>' in text
    assert 'reliability="best_effort" depth="3"' in text
    back = tmp_path / "back.yaml"
    assert hfsmc("convert", str(xml), "-o", str(back)).returncode == 0
    a, b, c = (compile_file(str(p)).model for p in (model, xml, back))
    assert a is not None and a == b == c
    r = a.interfaces[0].ros2
    assert r is not None and r.publish[0].qos == (("reliability", "best_effort"), ("depth", 3))
    dump = hfsmc("check", "--dump-ir", str(model)).stdout
    assert "publish seen: topic='seen' type=my_msgs/msg/Detection" in dump
    assert "message 'my_msgs/msg/Detection.msg'" in dump


def test_the_models_own_message_is_generated_and_imported(tmp_path: Path) -> None:
    model = model_with_messages(tmp_path, DETECTION)
    out = tmp_path / "out"
    assert hfsmc("build", str(model), "-o", str(out)).returncode == 0
    assert (out / "my_msgs" / "msg" / "__init__.py").is_file()
    assert (out / "rmw_dds_common" / "msg" / "__init__.py").is_file()  # the runtime's
    assert not (out / "sensor_msgs").exists()  # only what the model uses
    got = subprocess.run([sys.executable, "-c", "from my_msgs.msg import Detection\n"
                          "d = Detection(label='box')\nprint(d.score, d.where.x, d._TYPE)"],
                         cwd=out, capture_output=True, text=True, timeout=60, check=True)
    assert got.stdout.split() == ["0.5", "0.0", "my_msgs/msg/Detection"]


def test_a_msg_line_that_does_not_parse_is_reported_at_its_line(tmp_path: Path) -> None:
    model = model_with_messages(tmp_path, "string label\nfloat32 score = oops ]\n")
    result = compile_file(str(model))
    found = [(d.code, d.span.file.rsplit("/", 1)[-1], d.span.line) for d in result.diagnostics]
    assert ("E311", "Detection.msg", 2) in found, found


def test_a_msg_file_that_leads_out_of_the_models_folder_is_refused(tmp_path: Path) -> None:
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "Detection.msg").write_text(DETECTION)
    home = tmp_path / "model"
    home.mkdir()
    model = model_with_messages(home, DETECTION)
    link = home / "my_msgs" / "msg" / "Detection.msg"
    link.unlink()
    link.symlink_to(outside / "Detection.msg")
    result = compile_file(str(model))
    found = [(d.span.line, d.span.col, d.message) for d in result.diagnostics
             if d.code == "E315"]
    assert len(found) == 1 and found[0][:2] == (8, 16), result.diagnostics
    assert "leads outside the model's folder" in found[0][2]


def test_check_applies_the_runtimes_name_rules() -> None:
    from hfsmc.templates.python import hfsmc_ros2_wire as wire  # type: ignore[import-not-found]

    cases = ["scan", "/scan", "~/status", "~", "a/b", "a//b", "scan/", "2scan", "s__x", "~x",
             "", "sc-an", "/tb2/scan", "_x"]
    for ns in ("/", "/tb2", "tb2", "/a/b", "/a//b", "/2a"):
        for name in cases:
            try:
                ours: object = names.resolve_name(name, ns, "node")
            except names.NameError_ as e:
                ours = ("refused", str(e))
            try:
                theirs: object = wire.resolve_name(name, ns, "node")
            except wire.Ros2Error as e:
                theirs = ("refused", str(e))
            assert ours == theirs, (name, ns)


# ---------------------------------------------------------------------------
# built components on DDS (loopback), against the simulated ground robot


def test_a_component_drives_the_robot_until_the_scan_sees_the_wall(tmp_path: Path) -> None:
    component = build_component(tmp_path)
    with ros2_domain() as dom:
        run, truth = run_against_sim(tmp_path, ROOM + "robots: [{name: tb, x: 3, y: 2}]\n",
                                     dom, component, env={"ROS_DOMAIN_ID": str(dom)})
    assert run.returncode == 0, run.stderr
    assert "Stop: stopped 0.7" in run.stderr or "Stop: stopped 0.8" in run.stderr, run.stderr
    assert "stopped (final)" in run.stderr
    tb = truth["tb"]
    assert isinstance(tb, dict)
    # Stopped before the east wall (x = 6; the base's radius is 0.176 m), after driving.
    assert 4.6 < tb["pose"]["x"] < 5.4, tb
    assert tb["collisions"] == []


def test_the_configuration_changes_domain_namespace_and_topic_without_a_rebuild(
        tmp_path: Path) -> None:
    model = tmp_path / "model" / "stop_at_wall.yaml"
    model.parent.mkdir()
    # Built for another topic name, namespace and domain than the robot's.
    model.write_text(EXAMPLE.read_text().replace("topic: scan", "topic: laser")
                     .replace("namespace: /\n", "namespace: /other\n    domain: 3\n"))
    component = build_component(tmp_path, model)
    before = component.read_bytes(), (component.parent / "stop_at_wall.yaml").read_bytes()
    with ros2_domain() as dom:
        config = tmp_path / "robot_a.yaml"
        config.write_text(json.dumps({"interfaces": {"robot": {
            "domain": dom, "namespace": "/a", "subscribe": {"scan": {"topic": "scan"}}}}}))
        run, truth = run_against_sim(
            tmp_path, ROOM + "robots: [{name: a, x: 3, y: 1}, {name: b, x: 3, y: 3}]\n", dom,
            component, "--config", str(config), env={"ROS_DOMAIN_ID": "4"})
    assert run.returncode == 0, run.stderr
    assert "stopped (final)" in run.stderr
    a, b = truth["a"], truth["b"]
    assert isinstance(a, dict) and isinstance(b, dict)
    assert 4.6 < a["pose"]["x"] < 5.4 and a["collisions"] == []
    assert b["pose"]["x"] == pytest.approx(3.0, abs=1e-3)  # the other robot never moved
    assert (component.read_bytes(), (component.parent / "stop_at_wall.yaml").read_bytes()) \
        == before


@pytest.mark.parametrize(("setting", "said"), [
    ({"publish": {"cmd_vel": {"type": "std_msgs/msg/String"}}},
     "`publish.cmd_vel.type: std_msgs/msg/String` differs from the model's"),
    ({"distro": "humble"}, "`distro: humble` differs from the model's (jazzy)"),
    ({"subscribe": {"lidar": {"topic": "scan"}}}, "`subscribe` has no `lidar` in the model"),
    ({"url": "udpin:127.0.0.1:14550"}, "`url` is not a setting of a ros2 interface"),
])
def test_the_configuration_may_not_change_what_needs_a_rebuild(
        tmp_path: Path, setting: dict[str, object], said: str) -> None:
    component = build_component(tmp_path)
    config = tmp_path / "bad.yaml"
    config.write_text(json.dumps({"interfaces": {"robot": setting}}))
    run = subprocess.run([sys.executable, str(component), "--config", str(config),
                          "--until", "1s"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2, run.stderr
    assert said in run.stderr and "Traceback" not in run.stderr
    assert len(run.stderr.strip().splitlines()) == 1, run.stderr


def test_a_message_of_the_wrong_type_is_reported_at_the_snippets_line(tmp_path: Path) -> None:
    model = tmp_path / "wrong.yaml"
    model.write_text(
        "hfsm: 1\nname: wrong\nimports:\n  - from geometry_msgs.msg import Twist, Vector3\n"
        "interfaces:\n  robot:\n    type: ros2\n    publish:\n"
        "      cmd_vel: {topic: cmd_vel, type: geometry_msgs/msg/Twist}\n"
        "initial: A\nstates:\n  A:\n    entry: |\n      log('publishing')\n"
        "      robot.publish('cmd_vel', Vector3(x=1.0))\n    transitions: [{to: B, after: 1s}]\n"
        "  B: {final: true}\n")
    component = build_component(tmp_path, model)
    with ros2_domain() as dom:
        run = subprocess.run([sys.executable, str(component), "--until", "5s"],
                             capture_output=True, text=True, timeout=60,
                             env={**os.environ, "ROS_DOMAIN_ID": str(dom)})
    assert run.returncode == 1, run.stderr
    assert f"{model}:15:7: error: TypeError: robot.publish('cmd_vel', ...): a " \
           "geometry_msgs/msg/Twist is expected, not geometry_msgs/msg/Vector3" in run.stderr
