"""Robots that work together (docs/ros2.md): examples/patrol_pair's two components, each its
own process, split the waypoints over /patrol/claims and drive to them with navigate_to_pose
in one `hfsmc sim --robot diffdrive` world; judged on the simulator's truth. Real time: the
simulator's lockstep has one component, and the pair is two."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from tests.cppbuild import Superbuild
from tests.ros2_support import ros2_domain
from tests.support import ROOT, hfsmc, interrupt, stop_processes

EXAMPLE = ROOT / "examples" / "patrol_pair"
CPP_MODEL = EXAMPLE / "robot_cpp.yaml"
# Which twin drives which robot: one Python component and one C++ (robot_cpp.yaml), as the
# example is meant to run.
PAIR = {"r1": "python", "r2": "cpp"}
NEAR_M = 0.15  # a trail sample this near a point is at it
LIMIT_S = 120  # the pair's run is bounded (it takes about 20 s, 35 s with a robot killed)


def points() -> list[tuple[float, float]]:
    """The waypoints, from the model's default (the test reads what the robots read)."""
    text = (EXAMPLE / "robot.yaml").read_text()
    found = re.search(r'waypoints: \{type: str, default: "([^"]+)"', text)
    assert found is not None
    return [(float(x), float(y)) for x, y in (p.split(",") for p in found[1].split(";"))]


def visits(trail: list[list[float]], p: tuple[float, float]) -> int:
    """How many times a robot's trail came to ``p``: runs of samples within NEAR_M of it."""
    count, inside = 0, False
    for _, x, y, _ in trail:
        now = math.hypot(x - p[0], y - p[1]) <= NEAR_M
        count += now and not inside
        inside = now
    return count


@pytest.fixture(scope="module")
def components(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[str]]:
    """The command that runs each robot's component, built once (the C++ twin in a
    Superbuild, Release as a robot runs it, its runtime from the suite's compiler cache)."""
    out = tmp_path_factory.mktemp("patrol")
    r = hfsmc("build", str(EXAMPLE / "robot.yaml"), "-o", str(out / "python"))
    assert r.returncode == 0, r.stderr
    made = {"python": [sys.executable, str(out / "python" / "robot.py")],
            "cpp": [str(Superbuild(out / "cpp", [CPP_MODEL], build_type="Release")
                        .executable(CPP_MODEL))]}
    return {name: made[lang] for name, lang in PAIR.items()}


def run_pair(tmp: Path, components: dict[str, list[str]], kill: str | None = None
             ) -> tuple[dict[str, Any], dict[str, str], dict[str, int]]:
    """Both components against the simulator until they stop (bounded); with ``kill``, that
    robot's component is killed (SIGKILL) while it pauses at its first point. The robots'
    truth, each component's stderr and exit status."""
    truth = tmp / "truth.json"
    procs: list[subprocess.Popen[bytes]] = []
    errs = {name: tmp / f"{name}.err" for name in PAIR}
    with ros2_domain() as dom:
        env = {"ROS_DOMAIN_ID": str(dom), "PATH": "/usr/bin:/bin",
               "CYCLONEDDS_URI": os.environ["CYCLONEDDS_URI"]}
        sim = subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                                "--world", str(EXAMPLE / "world.yaml"), "--domain", str(dom),
                                "--truth", str(truth)],
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        try:
            for name, command in components.items():
                with errs[name].open("wb") as err:
                    procs.append(subprocess.Popen(
                        [*command, "--config", str(EXAMPLE / f"{name}.yaml"),
                         "--until", f"{LIMIT_S}s"],
                        stdout=subprocess.DEVNULL, stderr=err, env=env))
            end = time.monotonic() + LIMIT_S + 30
            if kill is not None:
                victim = procs[list(PAIR).index(kill)]
                while "reached point" not in errs[kill].read_text() and time.monotonic() < end:
                    time.sleep(0.05)
                victim.send_signal(signal.SIGKILL)
            for p in procs:
                p.wait(timeout=max(1.0, end - time.monotonic()))
        finally:
            stop_processes(procs)
            status = interrupt(sim, timeout=30)
            assert sim.stderr is not None
            sim_err = sim.stderr.read().decode()
            sim.stderr.close()
    assert status == 0, sim_err
    robots = json.loads(truth.read_text())["robots"]
    return (robots, {n: errs[n].read_text() for n in PAIR},
            {n: p.returncode for n, p in zip(PAIR, procs, strict=True)})


def reached(err: str) -> list[int]:
    """The points a component said it reached, in order."""
    return [int(i) for i in re.findall(r"reached point (\d+) ", err)]


def test_the_pair_splits_the_points_and_visits_each_once(tmp_path: Path,
                                                         components: dict[str, list[str]]
                                                         ) -> None:
    robots, errs, codes = run_pair(tmp_path, components)
    for name in PAIR:
        assert codes[name] == 0, errs[name]
        assert "stopped (final)" in errs[name] and "Done: every point reached" in errs[name], \
            errs[name]
        assert robots[name]["collisions"] == [], robots[name]["collisions"]
        assert "Traceback" not in errs[name]
    pts = points()
    for i, p in enumerate(pts):  # by truth: each point visited once, by one robot
        assert sum(visits(robots[n]["trail"], p) for n in PAIR) == 1, (i, p)
    said = {n: reached(errs[n]) for n in PAIR}
    assert sorted(said["r1"] + said["r2"]) == list(range(len(pts))), said
    # Nearest first from each start: r1 takes the south row, r2 the north one.
    assert said == {"r1": [2, 3, 5], "r2": [4, 1, 0]}, said
    for n in PAIR:
        assert all(visits(robots[n]["trail"], pts[i]) == 1 for i in said[n]), n


def test_a_killed_robots_points_are_taken_over_after_its_silence(
        tmp_path: Path, components: dict[str, list[str]]) -> None:
    robots, errs, codes = run_pair(tmp_path, components, kill="r2")
    assert codes["r2"] == -signal.SIGKILL
    assert reached(errs["r2"]) == [4]  # killed while it paused at its first point
    assert re.search(r"claims point 1 ", errs["r2"]), errs["r2"]  # its next, never reached
    assert codes["r1"] == 0, errs["r1"]
    assert "Done: every point reached" in errs["r1"], errs["r1"]
    took = re.search(r"r2 silent for 3 s: takes over points \[1\]", errs["r1"])
    assert took is not None, errs["r1"]
    assert sorted(reached(errs["r1"])) == [0, 1, 2, 3, 5], errs["r1"]
    pts = points()
    for i, p in enumerate(pts):  # by truth: every point visited once, the rest by r1
        by = [n for n in PAIR for _ in range(visits(robots[n]["trail"], p))]
        assert by == (["r2"] if i == 4 else ["r1"]), (i, by)
    for n in PAIR:
        assert robots[n]["collisions"] == [], robots[n]["collisions"]
