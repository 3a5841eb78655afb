"""C++ components with a ``ros2`` interface (docs/ros2-cpp.md), built by ``hfsmc build -t
cpp`` and run on real DDS (loopback, a leased domain id): the Python and the C++ twin of
one model exchange messages both ways on humble and on jazzy, a C++ component drives
``hfsmc sim --robot diffdrive`` in real time and in lockstep (``--clock sim:PORT``, the
same run twice), NAME.yaml changes what it may and refuses the rest, and check finds a
wrong field (g++, at the model's line), a message of a type the interface does not
publish, and an undeclared name."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from hfsmc.pipeline import compile_file
from tests.cppbuild import Superbuild
from tests.ros2_support import ros2_domain
from tests.support import ROOT, free_port, hfsmc, interrupt

MODELS = ROOT / "tests" / "ros2" / "models"
STOP_AT_WALL = ROOT / "examples" / "stop_at_wall_cpp" / "stop_at_wall_cpp.yaml"
ROOM = "walls: [[[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]]]\nlaser: {range_max: 8}\n"
ENV = dict(os.environ)  # DDS on loopback (tests/conftest.py)


def twin(folder: Path, name: str, distro: str) -> Path:
    """The pingpong model ``name`` for ``distro`` (the distro is the model's: a rebuild)."""
    text = (MODELS / name / f"{name}.yaml").read_text()
    out = folder / f"{name}_{distro}" / f"{name}_{distro}.yaml"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(text.replace("    node: pingpong\n", f"    node: pingpong\n    distro: {distro}\n")
                   .replace(f"name: {name}\n", f"name: {name}_{distro}\n"))
    return out


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> tuple[Superbuild, dict[str, Path]]:
    """The C++ twins of both distros and stop_at_wall_cpp, in one CMake project."""
    base = tmp_path_factory.mktemp("ros2cpp")
    models = {d: twin(base / "models", "pingpong_cpp", d) for d in ("humble", "jazzy")}
    sb = Superbuild(base / "build", [*models.values(), STOP_AT_WALL], build_type="Release")
    sb.build()
    return sb, models


def crossed(config: Path, me: str, other: str, domain: int) -> Path:
    """A copy of a component's NAME.yaml whose node and topics are its own: it publishes
    /ME_to_OTHER and reads OTHER_to_ME (relative: resolved against the namespace)."""
    import yaml

    data = yaml.safe_load(config.read_text())
    link = data["interfaces"]["link"]
    link["node"], link["domain"] = f"node_{me}", domain
    link["subscribe"]["inbox"]["topic"] = f"{other}_to_{me}"
    link["publish"]["outbox"]["topic"] = f"/{me}_to_{other}"
    out = config.parent / f"{me}.yaml"
    out.write_text(json.dumps(data))
    return out


@pytest.mark.parametrize("distro", ["humble", "jazzy"])
def test_the_python_and_cpp_twins_exchange_messages_both_ways(
        built: tuple[Superbuild, dict[str, Path]], tmp_path: Path, distro: str) -> None:
    sb, models = built
    exe = sb.executable(models[distro])
    py_model = twin(tmp_path, "pingpong", distro)
    result = hfsmc("build", str(py_model), "-o", str(tmp_path / "py"))
    assert result.returncode == 0, result.stderr
    with ros2_domain() as dom:
        cpp_config = crossed(sb.folder(models[distro]) / f"pingpong_cpp_{distro}.yaml", "a", "b",
                             dom)
        py_config = crossed(tmp_path / "py" / f"pingpong_{distro}.yaml", "b", "a", dom)
        cpp = subprocess.Popen([str(exe), "--config", str(cpp_config), "--until", "30s"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        try:
            py = subprocess.run([sys.executable, str(tmp_path / "py" / f"pingpong_{distro}.py"),
                                 "--config", str(py_config), "--until", "30s"],
                                capture_output=True, text=True, timeout=60, env=ENV)
            _, cpp_err = cpp.communicate(timeout=60)
        finally:
            if cpp.poll() is None:
                cpp.kill()
                cpp.communicate()
    for name, status, err in (("C++", cpp.returncode, cpp_err), ("Python", py.returncode,
                                                                   py.stderr)):
        assert status == 0, f"{name}: {err}"
        assert "stopped (final)" in err, f"{name}: {err}"
        # The first five numbers the twin sent, each read in its own instant, in order.
        got = [ln.split("got ")[1].split(" ")[0] for ln in err.splitlines() if ": got " in ln]
        assert got == ["0", "1", "2", "3", "4"], f"{name}: {err}"
        assert "from 1 publisher(s)" in err


def run_on_sim(tmp: Path, exe: Path, domain: int, *args: str,
               sim_args: tuple[str, ...] = ()) -> tuple[subprocess.CompletedProcess[str],
                                                        dict[str, Any], str]:
    """The ground robot `tb` at (3, 2) facing the east wall; the component until it stops."""
    (tmp / "world.yaml").write_text(ROOM + "seed: 5\nrobots: [{name: tb, x: 3, y: 2}]\n")
    sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                            "--world", str(tmp / "world.yaml"), "--domain", str(domain),
                            "--truth", str(tmp / "truth.json"), *sim_args],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV)
    try:
        run = subprocess.run([str(exe), "--until", "40s", *args], capture_output=True,
                             text=True, timeout=120, env={**ENV, "ROS_DOMAIN_ID": str(domain)})
    finally:
        status = sim.wait(timeout=30) if sim_args else interrupt(sim, timeout=30)
        assert sim.stderr is not None
        err = sim.stderr.read().decode()
        sim.stderr.close()
    assert status == 0, err
    truth = json.loads((tmp / "truth.json").read_text())["robots"]["tb"]
    assert isinstance(truth, dict)
    return run, truth, err


def test_a_cpp_component_drives_the_ground_robot_to_the_wall(
        built: tuple[Superbuild, dict[str, Path]], tmp_path: Path) -> None:
    sb, _ = built
    with ros2_domain() as dom:
        run, truth, _ = run_on_sim(tmp_path, sb.executable(STOP_AT_WALL), dom)
    assert run.returncode == 0, run.stderr
    assert "Stop: stopped 0.7" in run.stderr or "Stop: stopped 0.8" in run.stderr, run.stderr
    assert "stopped (final)" in run.stderr
    assert 4.6 < truth["pose"]["x"] < 5.4, truth  # the east wall is at x = 6
    assert truth["collisions"] == []


def test_in_lockstep_the_cpp_component_holds_every_sample_and_runs_the_same_twice(
        built: tuple[Superbuild, dict[str, Path]], tmp_path: Path) -> None:
    sb, _ = built
    runs = []
    for k in range(2):
        (tmp_path / str(k)).mkdir()
        port = free_port()
        with ros2_domain() as dom:
            run, truth, err = run_on_sim(tmp_path / str(k), sb.executable(STOP_AT_WALL), dom,
                                         "--clock", f"sim:{port}",
                                         sim_args=("--lockstep", str(port)))
        assert run.returncode == 0, run.stderr
        assert "lockstep: component stop_at_wall_cpp connected" in err, err
        assert "did not" not in err + run.stderr, err + run.stderr  # matched, nothing late
        lines = [ln for ln in run.stderr.splitlines() if "waiting for the simulator" not in ln]
        runs.append(("\n".join(lines), truth))
    assert runs[0] == runs[1]
    said, truth = runs[0]
    # A scan every 100 ms of simulated time, each held before the instant that follows it:
    # the stop comes at the same instant and after the same number of scans every run.
    found = re.search(r"\[ *(\d+\.\d+)\] Stop: stopped 0\.[78]\d m from the wall, (\d+) scans read",
                      said)
    assert found is not None, said
    # One scan per 100 ms of simulated time from 0 on, every one of them held.
    assert int(found[2]) == round(float(found[1]) * 10), said
    assert 4.6 < truth["pose"]["x"] < 5.4 and truth["collisions"] == []


@pytest.mark.parametrize(("setting", "said"), [
    ({"domain": 300}, "domain `300` is not a ROS 2 domain id (0 to 232)"),
    ({"distro": "humble"}, "`distro: humble` differs from the model's (jazzy)"),
    ({"subscribe": {"lidar": {"topic": "scan"}}}, "`subscribe` has no `lidar` in the model"),
    ({"publish": {"cmd_vel": {"type": "std_msgs/msg/String"}}},
     "`publish.cmd_vel.type: std_msgs/msg/String` differs from the model's"),
    ({"subscribe": {"scan": {"topic": "a__b"}}}, "'__' is kept by ROS 2"),
    ({"subscribe": {"scan": {"qos": "fast"}}}, "unknown QoS profile 'fast'"),
    ({"url": "udpin:127.0.0.1:14550"}, "`url` is not a setting of a ros2 interface"),
])
def test_the_configuration_may_not_change_what_needs_a_rebuild(
        built: tuple[Superbuild, dict[str, Path]], tmp_path: Path, setting: dict[str, object],
        said: str) -> None:
    sb, _ = built
    config = tmp_path / "bad.yaml"
    config.write_text(json.dumps({"interfaces": {"robot": setting}}))
    run = subprocess.run([str(sb.executable(STOP_AT_WALL)), "--config", str(config),
                          "--until", "1s"], capture_output=True, text=True, timeout=60, env=ENV)
    assert run.returncode == 2, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("stop_at_wall_cpp: robot: ros2: "), lines
    assert said in lines[0]


def test_a_domain_id_out_of_range_stops_the_component_at_start(
        built: tuple[Superbuild, dict[str, Path]]) -> None:
    sb, _ = built
    run = subprocess.run([str(sb.executable(STOP_AT_WALL)), "--until", "1s"],
                         capture_output=True, text=True, timeout=60,
                         env={**ENV, "ROS_DOMAIN_ID": "999"})
    assert run.returncode == 2
    assert run.stderr.strip() == ("stop_at_wall_cpp: robot: ros2: domain id 999 out of range "
                                  "(0 to 232)")


@pytest.mark.parametrize(("old", "new", "found"), [
    ("go.linear.x = speed;", "go.linear.xx = speed;",
     r"stop_at_wall_cpp\.yaml:{line}:17: error\[E144\]: 'struct geometry_msgs::msg::Vector3' has "
     r"no member named 'xx'"),
    ('robot.publish("cmd_vel", go);', 'robot.publish("cmd_vel", go.linear);',
     r"stop_at_wall_cpp\.yaml:{line}:35: error\[E144\]: cannot convert "
     r"'geometry_msgs::msg::Vector3' to 'const geometry_msgs::msg::Twist&'"),
    ('robot.publish("cmd_vel", go);', 'robot.publish("cmd_vl", go);',
     r"stop_at_wall_cpp\.yaml:{line}:21: error\[E148\]: `robot\.publish`: `cmd_vl` is not one of "
     r"the interface's `publish` \(cmd_vel\)"),
    ('robot.count("scan")', 'robot.count("cmd_vel")',
     r"stop_at_wall_cpp\.yaml:{line}:\d+: error\[E148\]: `robot\.count`: `cmd_vel` is not one of "
     r"the interface's `subscribe` \(scan, odom\)"),
])
def test_check_finds_a_wrong_field_type_or_name_at_the_models_line(
        tmp_path: Path, old: str, new: str, found: str) -> None:
    text = STOP_AT_WALL.read_text()
    assert old in text
    line = text[:text.index(old)].count("\n") + 1  # where the example has it
    found = found.replace("{line}", str(line))
    model = tmp_path / "stop_at_wall_cpp.yaml"
    model.write_text(text.replace(old, new))
    result = hfsmc("check", str(model), cwd=tmp_path)
    assert result.returncode == 1
    assert any(re.search(found, ln) for ln in result.stderr.splitlines()), \
        result.stderr


def test_the_example_checks_clean() -> None:
    result = compile_file(str(STOP_AT_WALL.relative_to(ROOT)), cxx=True)
    assert result.ok, result.diagnostics
