"""`hfsmc sim --robot diffdrive` on real DDS: a ROS 2 peer (tests/ros2/ground_peer.py, the
components' own runtime in another process) drives the robot and reads what it publishes."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from support import ROOT, ros2_domain

PEER = ROOT / "tests" / "ros2" / "ground_peer.py"


def sim(tmp: Path, world: str, domain: int, *args: str) -> subprocess.Popen[bytes]:
    w = tmp / "world.yaml"
    w.write_text(world)
    return subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                             "--world", str(w), "--domain", str(domain),
                             "--truth", str(tmp / "truth.json"), *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def peer(domain: int, namespace: str, seconds: float, linear: float,
         angular: float = 0.0) -> dict[str, Any]:
    out = subprocess.run([sys.executable, str(PEER), str(domain), namespace, str(seconds),
                          str(linear), str(angular)], capture_output=True, text=True,
                         timeout=seconds + 30, check=True)
    return json.loads(out.stdout)


def stop(proc: subprocess.Popen[bytes]) -> str:
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    return err.decode()


ROOM = "walls: [[[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]]]\n"


def test_a_peer_drives_the_robot_and_reads_odom_scan_and_clock(tmp_path: Path) -> None:
    dom = ros2_domain(1)
    proc = sim(tmp_path, ROOM + "robots: [{name: tb, x: 1, y: 2}]\n", dom)
    try:
        got = peer(dom, "/", 4.0, 0.3)
    finally:
        err = stop(proc)
    assert "1 diffdrive robot(s) (tb in /)" in err
    truth = json.loads((tmp_path / "truth.json").read_text())["robots"]["tb"]
    assert got["sim_subscribers"] == 1
    odom = got["odom"]
    assert (odom["frame"], odom["child"]) == ("odom", "base_footprint")
    assert 0.6 < odom["x"] <= truth["pose"]["x"] - 1 + 1e-6  # forward, in the start's frame
    assert abs(odom["y"]) < 1e-6 and abs(odom["yaw"]) < 1e-6
    scan = got["scan"]
    assert (scan["n"], scan["frame"], scan["angle_min"]) == (360, "base_scan", -math.pi)
    assert 0.5 < scan["ahead"] < 5 - odom["x"] + 0.1  # the east wall, 5 m ahead at the start
    assert got["counts"]["odom"] > 5 * got["counts"]["scan"] > 0  # 50 Hz and 10 Hz
    assert got["clock"] == pytest.approx(got["counts"]["clock"] * 0.02, abs=0.5)
    assert truth["collisions"] == []


def test_the_bumper_is_pressed_at_a_wall_and_the_truth_counts_it(tmp_path: Path) -> None:
    dom = ros2_domain(2)
    proc = sim(tmp_path, ROOM + "robots: [{name: tb, x: 5.3, y: 2}]\n", dom)
    try:
        got = peer(dom, "/", 3.0, 0.3)
    finally:
        stop(proc)
    assert got["bumps"][:1] == [[1, 1]]  # CENTER, PRESSED
    truth = json.loads((tmp_path / "truth.json").read_text())["robots"]["tb"]
    assert len(truth["collisions"]) == 1
    assert truth["pose"]["x"] == pytest.approx(6 - 0.176, abs=2e-3)


def test_robots_in_their_namespaces_obey_their_own_cmd_vel(tmp_path: Path) -> None:
    dom = ros2_domain(3)
    proc = sim(tmp_path, ROOM + "robots: [{name: a, x: 1, y: 1}, {name: b, x: 1, y: 3}]\n", dom)
    try:
        got = peer(dom, "/a", 3.0, 0.3)
    finally:
        err = stop(proc)
    assert "a in /a, b in /b" in err
    assert got["odom"]["frame"] == "a/odom"
    robots = json.loads((tmp_path / "truth.json").read_text())["robots"]
    assert robots["a"]["travelled"] > 0.5
    assert robots["b"]["travelled"] == 0.0


@pytest.mark.parametrize(("args", "said"), [
    (["--domain", "233"], "--domain: domain 233 is out of range"),
    (["--world", "bad"], r"world\.yaml:1:8: rays: must be between 8 and 4096"),
])
def test_bad_settings_exit_2_with_one_line(tmp_path: Path, args: list[str], said: str) -> None:
    world = "laser: {rays: 3}\n" if "bad" in args else ROOM
    args = [a for a in args if a != "bad" and a != "--world"]
    proc = sim(tmp_path, world, ros2_domain(4), *args)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2
    lines = err.decode().strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hfsmc: error: "), lines
    import re
    assert re.search(said, lines[0]), lines


def test_a_timed_run_ends_by_itself_with_its_truth(tmp_path: Path) -> None:
    proc = sim(tmp_path, ROOM + "robots: [{x: 1, y: 1}]\n", ros2_domain(5), "--duration", "1")
    proc.communicate(timeout=60)
    assert proc.returncode == 0
    assert json.loads((tmp_path / "truth.json").read_text())["time"] == 1.0
    assert os.path.getsize(tmp_path / "truth.json") > 0
