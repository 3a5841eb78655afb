"""`hfsmc sim --robot diffdrive` on real DDS: a ROS 2 peer (tests/ros2/ground_peer.py, the
components' own runtime in another process) drives the robot and reads what it publishes."""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from tests.ros2_support import ros2_domain
from tests.support import ROOT, free_port

PEER = ROOT / "tests" / "ros2" / "ground_peer.py"
ROOM = "walls: [[[0, 0], [6, 0], [6, 4], [0, 4], [0, 0]]]\n"


def sim(tmp: Path, world: str, domain: int, *args: str) -> subprocess.Popen[bytes]:
    w = tmp / "world.yaml"
    w.write_text(world)
    return subprocess.Popen([sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive",
                             "--world", str(w), "--domain", str(domain),
                             "--truth", str(tmp / "truth.json"), *args],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def drive(tmp: Path, world: str, namespace: str, seconds: float, linear: float
          ) -> tuple[dict[str, Any], str, dict[str, Any]]:
    """Start the simulator, let the peer drive for ``seconds``, stop: what the peer got,
    what the simulator said, and the truth per robot."""
    with ros2_domain() as dom:
        proc = sim(tmp, world, dom)
        try:
            out = subprocess.run([sys.executable, str(PEER), str(dom), namespace, str(seconds),
                                  str(linear), "0"], capture_output=True, text=True,
                                 timeout=seconds + 60, check=True, cwd=ROOT)
        finally:
            proc.send_signal(signal.SIGINT)
            try:
                _, err = proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()  # never left behind
                _, err = proc.communicate()
    assert proc.returncode == 0, err
    truth = json.loads((tmp / "truth.json").read_text())["robots"]
    return json.loads(out.stdout), err.decode(), truth


def test_a_peer_drives_the_robot_and_reads_odom_scan_and_clock(tmp_path: Path) -> None:
    world = ROOM + "laser: {range_max: 8}\nrobots: [{name: tb, x: 1, y: 2}]\n"
    got, err, robots = drive(tmp_path, world, "/", 4.0, 0.3)
    assert "1 diffdrive robot(s) (tb in /)" in err
    truth = robots["tb"]
    assert got["sim_subscribers"] == 1
    odom = got["odom"]
    assert (odom["frame"], odom["child"]) == ("odom", "base_footprint")
    assert 0.6 < odom["x"] <= truth["pose"]["x"] - 1 + 1e-6  # forward, in the start's frame
    assert abs(odom["y"]) < 1e-6 and abs(odom["yaw"]) < 1e-6
    scan = got["scan"]
    assert (scan["n"], scan["frame"]) == (360, "base_scan")
    assert scan["angle_min"] == pytest.approx(-math.pi)  # a float32
    assert 5 - odom["x"] - 0.3 < scan["ahead"] < 5 - odom["x"] + 0.3  # the east wall ahead
    assert got["counts"]["odom"] > 4 * got["counts"]["scan"] > 0  # 50 Hz and 10 Hz
    assert got["clock"] == pytest.approx(got["counts"]["clock"] * 0.02, abs=0.5)
    assert truth["collisions"] == []


def test_the_bumper_is_pressed_at_a_wall_and_the_truth_counts_it(tmp_path: Path) -> None:
    # 0.32 m from the wall: reached within 2 s of the first cmd_vel, the peer sends for 5 s
    got, _, robots = drive(tmp_path, ROOM + "robots: [{name: tb, x: 5.5, y: 2}]\n", "/", 5.0, 0.3)
    assert got["bumps"][:1] == [[1, 1]]  # CENTER, PRESSED
    assert len(robots["tb"]["collisions"]) == 1
    assert robots["tb"]["pose"]["x"] == pytest.approx(6 - 0.176, abs=2e-3)


def test_robots_in_their_namespaces_obey_their_own_cmd_vel(tmp_path: Path) -> None:
    got, err, robots = drive(tmp_path, ROOM + "robots: [{name: a, x: 1, y: 1}, "
                             "{name: b, x: 1, y: 3}]\n", "/a", 3.0, 0.3)
    assert "a in /a, b in /b" in err
    assert got["odom"]["frame"] == "a/odom"
    assert robots["a"]["travelled"] > 0.5
    assert robots["b"]["travelled"] == 0.0


@pytest.mark.parametrize(("world", "args", "said"), [
    (ROOM, ["--domain", "233"], r"--domain: domain 233 is out of range"),
    ("name: x\nlaser: {rays: 3}\n", [], r"world\.yaml:2:15: rays: must be between 8 and 4096"),
    ("name: x\n", ["--seed", "x"], r"argument --seed: invalid int value"),
])
def test_bad_settings_exit_2_with_one_line(tmp_path: Path, world: str, args: list[str],
                                          said: str) -> None:
    proc = sim(tmp_path, world, 0, *args)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2
    lines = [ln for ln in err.decode().splitlines() if "error:" in ln]
    assert len(lines) == 1 and re.search(said, lines[0]), err


def test_a_timed_run_ends_by_itself_with_its_truth(tmp_path: Path) -> None:
    with ros2_domain() as dom:
        proc = sim(tmp_path, ROOM + "robots: [{x: 1, y: 1}]\n", dom, "--duration", "1")
        proc.communicate(timeout=60)
    assert proc.returncode == 0
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert truth["time"] == 1.0 and truth["robots"]["robot"]["travelled"] == 0.0


def out_failed(out: subprocess.CompletedProcess[str] | None) -> bool:
    """Whether the peer did not finish well (then the simulator still waits: stop it)."""
    return out is None or out.returncode != 0


def lockstep_run(tmp: Path, world: str) -> tuple[list[dict[str, Any]], dict[str, Any]]:
    """A 6 s drive in lockstep: what the peer held each second, and the truth."""
    port = free_port()
    with ros2_domain() as dom:
        proc = sim(tmp, world, dom, "--lockstep", str(port))
        try:
            out = subprocess.run([sys.executable, str(ROOT / "tests" / "ros2" /
                                                      "ground_lockstep_peer.py"),
                                  str(dom), str(port), "6", "0.4", "0.3"],
                                 capture_output=True, text=True, timeout=120, cwd=ROOT)
        finally:
            if proc.poll() is None and out_failed(locals().get("out")):
                proc.send_signal(signal.SIGINT)
            try:
                _, err = proc.communicate(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()  # never left behind
                _, err = proc.communicate()
        assert out.returncode == 0, out.stderr
    assert proc.returncode == 0, err
    assert b"lockstep: component peer connected" in err
    return ([json.loads(line) for line in out.stdout.splitlines()],
            json.loads((tmp / "truth.json").read_text()))


def test_lockstep_holds_every_sample_and_is_the_same_every_run(tmp_path: Path) -> None:
    world = ROOM + "seed: 9\nrobots: [{name: tb, x: 1, y: 1}]\n"
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first, truth_a = lockstep_run(tmp_path / "a", world)
    second, truth_b = lockstep_run(tmp_path / "b", world)
    assert first == second and truth_a == truth_b
    assert [r["t"] for r in first] == [1_000_000 * i for i in range(1, 7)]
    assert [r["odom"] for r in first] == [50 * i for i in range(1, 7)]  # none lost, none late
    assert truth_a["robots"]["tb"]["travelled"] > 1.5
