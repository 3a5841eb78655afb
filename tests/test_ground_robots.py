"""Ground robots driven for real: the examples and VisualStates' kobuki_bump_and_go, built,
run against `hfsmc sim --robot diffdrive` over ROS 2 in lockstep (120 s of driving in a few
seconds), judged on the simulator's truth (docs/worlds.md, "Ground robots")."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.ros2_support import ros2_domain
from tests.support import ROOT, free_port, hfsmc

CORPUS = ROOT / "tests" / "legacy" / "corpus" / "visualstates"
# bump_and_go's first 120 s in examples/bump_and_go/world.yaml covered 0.29 of the room;
# a change that makes it wander much less (or stall) falls below this.
COVERAGE_BOUND = 0.2


def drive(tmp: Path, component: Path, world: Path, seconds: int,
          config: Path | None = None, *more: str) -> tuple[dict[str, Any], str, str]:
    """Run a built component (Python, or a C++ executable) against the simulator in
    lockstep: the robot's truth, the component's trace (JSON lines) and its stderr."""
    command = [sys.executable, str(component)] if component.suffix == ".py" else [str(component)]
    port = free_port()
    truth = tmp / "truth.json"
    with ros2_domain() as dom:
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                                "--world", str(world), "--domain", str(dom), "--truth", str(truth),
                                "--lockstep", str(port)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            run = subprocess.run([*command, "--clock", f"sim:{port}",
                                  "--until", f"{seconds}s", "--trace", str(tmp / "trace.jsonl"),
                                  *(["--config", str(config)] if config else []), *more],
                                 capture_output=True, text=True, timeout=300,
                                 env={"ROS_DOMAIN_ID": str(dom), "PATH": "/usr/bin:/bin",
                                      "CYCLONEDDS_URI": os.environ["CYCLONEDDS_URI"]})
        finally:
            try:
                _, err = sim.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                sim.kill()
                _, err = sim.communicate()
    assert run.returncode == 0, run.stderr
    assert sim.returncode == 0, err
    robots = json.loads(truth.read_text())["robots"]
    [robot] = robots.values()
    return robot, (tmp / "trace.jsonl").read_text(), run.stderr


@pytest.fixture(scope="module")
def bump_and_go(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bump_and_go")
    r = hfsmc("build", "examples/bump_and_go/bump_and_go.yaml", "-o", str(out / "c"))
    assert r.returncode == 0, r.stderr
    return out / "c" / "bump_and_go.py"


def test_bump_and_go_drives_two_minutes_without_a_collision(tmp_path: Path,
                                                            bump_and_go: Path) -> None:
    world = ROOT / "examples" / "bump_and_go" / "world.yaml"
    robot, trace, err = drive(tmp_path, bump_and_go, world, 120)
    assert robot["collisions"] == [], robot["collisions"]
    assert robot["coverage"] >= COVERAGE_BOUND, robot["coverage"]
    assert robot["travelled"] > 20
    turns = err.count("Turn: turning to")
    assert turns >= 3, err  # it met obstacles and turned away from each
    stop = json.loads(trace.splitlines()[-1])
    assert (stop["ev"], stop["reason"], stop["t"]) == ("stop", "until", 120_000), stop


def test_bump_and_go_is_the_same_every_run_in_lockstep(tmp_path: Path,
                                                       bump_and_go: Path) -> None:
    world = ROOT / "examples" / "bump_and_go" / "world.yaml"
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = drive(tmp_path / "a", bump_and_go, world, 30)
    second = drive(tmp_path / "b", bump_and_go, world, 30)
    assert first[0] == second[0]  # the truth: poses, trail, coverage
    assert first[1] == second[1]  # the trace, byte for byte


def test_visualstates_kobuki_bump_and_go_drives_again(tmp_path: Path) -> None:
    """The corpus file, converted: its topics are a ros2 interface, tf's euler is the helper.
    Its laser must sit at the front (the file's threshold is 0.1 m, less than the base's
    radius), and its scan topic is /laser/scan: renamed in NAME.yaml, without a rebuild."""
    model = tmp_path / "kobuki_bump_and_go.yaml"
    r = hfsmc("convert", str(CORPUS / "kobuki_bump_and_go.xml"), "-o", str(model))
    assert r.returncode == 0, r.stderr
    r = hfsmc("build", str(model), "-o", str(tmp_path / "c"))
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "c" / "kobuki_bump_and_go.yaml").read_text()
    config = json.loads("\n".join(ln for ln in text.splitlines() if not ln.startswith("#")))
    subs = config["interfaces"]["ros"]["subscribe"]
    subs["turtlebotROS_laser_scan"]["topic"] = "/scan"
    (tmp_path / "robot.yaml").write_text(json.dumps(config))
    world = tmp_path / "world.yaml"
    world.write_text("walls: [[[0, 0], [5, 0], [5, 4], [0, 4], [0, 0]]]\n"
                     "robots: [{name: kobuki, x: 2, y: 2}]\nlaser: {x: 0.15}\n")
    robot, trace, _ = drive(tmp_path, tmp_path / "c" / "kobuki_bump_and_go.py", world, 60,
                            tmp_path / "robot.yaml")
    fired = [json.loads(line) for line in trace.splitlines()]
    entered = [r["state"] for r in fired if r.get("ev") == "enter"]
    # It meets the wall (the file backs off only on contact), backs off, turns, goes on.
    assert robot["collisions"], "it never reached a wall"
    first_bump = robot["collisions"][0]["t"]
    after = [p for p in robot["trail"] if p[0] > first_bump + 5]
    assert after and max(abs(p[1] - after[0][1]) + abs(p[2] - after[0][2]) for p in after) > 0.5
    cycle = [s.rpartition("/")[2] for s in entered]
    assert "GetBack" in cycle and "Rotate" in cycle
    assert cycle.count("Go") >= 2, cycle


def test_wall_follower_goes_round_the_room_without_a_collision(
        tmp_path: Path) -> None:
    r = hfsmc("build", "examples/wall_follower/wall_follower.yaml", "-o", str(tmp_path / "c"))
    assert r.returncode == 0, r.stderr
    world = ROOT / "examples" / "wall_follower" / "world.yaml"
    robot, _, err = drive(tmp_path, tmp_path / "c" / "wall_follower.py", world, 120)
    assert robot["collisions"] == [], robot["collisions"]
    # Its first 120 s went once round the L-shaped room (0.38 of it covered): the east end,
    # the north wing and the west wall all reached.
    xs = [p[1] for p in robot["trail"]]
    ys = [p[2] for p in robot["trail"]]
    assert max(xs) > 7 and max(ys) > 5 and min(xs) < 1, robot["trail"]
    assert robot["coverage"] >= 0.3, robot["coverage"]
    assert err.count("turning left") >= 4, err


def test_no_usable_network_is_one_line_and_exit_2(bump_and_go: Path) -> None:
    uri = ("<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"nosuch0\"/>"
           "</Interfaces></General></Domain></CycloneDDS>")
    run = subprocess.run([sys.executable, str(bump_and_go), "--until", "1s"], capture_output=True,
                         text=True, timeout=60, env={"PATH": "/usr/bin:/bin",
                                                     "CYCLONEDDS_URI": uri})
    assert run.returncode == 2
    ours = [ln for ln in run.stderr.splitlines() if ln.startswith("robot: ")]
    assert ours == ["robot: ros2: cannot join ROS 2 domain 0: Cyclone DDS found no usable "
                    "network interface (CYCLONEDDS_URI is set: look at its network settings)"]
    assert "Traceback" not in run.stderr


@pytest.fixture(scope="module")
def bump_and_go_cpp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from tests.cppbuild import Superbuild

    model = ROOT / "examples" / "bump_and_go_cpp" / "bump_and_go_cpp.yaml"
    sb = Superbuild(tmp_path_factory.mktemp("bump_and_go_cpp"), [model], build_type="Release")
    sb.build()
    return sb.executable(model)


def test_bump_and_go_cpp_drives_as_its_python_twin_and_replays_across(
        tmp_path: Path, bump_and_go: Path, bump_and_go_cpp: Path) -> None:
    """The C++ twin: 120 s without a collision, above the Python bound; it draws its random
    headings as Python's random.Random(seed), so the two runs are the same (truth and trace);
    each recording replays identical with the other twin (docs/ros2.md, "Recordings")."""
    world = ROOT / "examples" / "bump_and_go" / "world.yaml"
    runs = {}
    for lang, component in (("cpp", bump_and_go_cpp), ("python", bump_and_go)):
        (tmp_path / lang).mkdir()
        runs[lang] = drive(tmp_path / lang, component, world, 120, None,
                           "--record", str(tmp_path / lang / "run.mcap"))
    robot, trace, err = runs["cpp"]
    assert robot["collisions"] == [], robot["collisions"]
    assert robot["coverage"] >= COVERAGE_BOUND, robot["coverage"]
    assert err.count("Turn: turning to") >= 3, err
    assert robot == runs["python"][0]  # poses, trail, coverage: the same run
    assert trace.replace('"name":"bump_and_go_cpp"', '"name":"bump_and_go"') == runs["python"][1]
    for recorded, model, label in (
            ("cpp", "examples/bump_and_go/bump_and_go.yaml", "(cpp -> python)"),
            ("python", "examples/bump_and_go_cpp/bump_and_go_cpp.yaml", "(python -> cpp)")):
        done = hfsmc("replay", str(tmp_path / recorded / "run.mcap"), "--model", model,
                     timeout=600)
        assert done.returncode == 0, done.stdout + done.stderr
        found = re.search(rf"{re.escape(label)}: identical: (\d+) trace records, (\d+) commands, "
                          r"0-120\.000 s", done.stdout)
        assert found is not None, done.stdout
        assert int(found[2]) > 2000  # every publish of 120 s at 20 Hz, compared by its bytes
