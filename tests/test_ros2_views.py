"""A ros2 interface in the live views (docs/web.md "ROS 2 topics and the map",
schemas/monitor.md minor version 3): the monitor's ros2 and scan messages, the terminal
view's rows and the web view's map, against a real bump_and_go driving in the real
ground-robot simulator."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from hfsmc.templates.python.hfsmc_ros2view import Rates  # type: ignore[import-not-found]
from hfsmc.templates.python.hfsmc_view import ros2_rows  # type: ignore[import-not-found]

from hfsmc.web.ros2 import Trail, WorldMap, world_message
from tests.ros2_support import ros2_domain
from tests.support import WEB_URL, Client, Process, Tmux, needs_browser, screenshot

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "bump_and_go"
START = (1.0, 1.0)  # tb2's start in examples/bump_and_go/world.yaml (yaw 0)


# -- pure parts ------------------------------------------------------------------------------
MESSAGE: dict[str, Any] = {
    "type": "ros2", "t": 1000, "name": "robot", "node": "bump", "namespace": "/tb2", "domain": 7,
    "distro": "jazzy",
    "subscriptions": [
        {"name": "scan", "topic": "/tb2/scan", "type": "sensor_msgs/msg/LaserScan", "rate": 10.0,
         "age": 0.04, "count": 12, "publishers": 1, "dropped": 0},
        {"name": "odom", "topic": "/tb2/odom", "type": "nav_msgs/msg/Odometry", "rate": None,
         "age": None, "count": 0, "publishers": 1, "dropped": 0},
        {"name": "bumper", "topic": "/tb2/events/bumper", "type": "x/msg/B", "rate": 0.0,
         "age": 5.5, "count": 3, "publishers": 1, "dropped": 2}],
    "publications": [{"name": "cmd_vel", "topic": "/tb2/cmd_vel", "type": "geometry_msgs/msg/Twist",
                      "count": 40, "rate": 20.0, "subscribers": 0}]}


def test_the_terminal_view_s_rows_of_a_ros2_interface() -> None:
    rows = ros2_rows(MESSAGE)
    assert [("  ".join(c for c in cells if c), style) for cells, style in rows] == [
        ("ros2 robot  /tb2/bump  domain 7  jazzy", "bold"),
        ("<- scan  /tb2/scan  10.0 Hz  0.04 s ago  n 12  1 pub", ""),
        ("<- odom  /tb2/odom  – Hz  never  n 0  1 pub", "red"),  # nothing yet: red
        ("<- bumper  /tb2/events/bumper  0.0 Hz  5.50 s ago  n 3  1 pub  2 dropped", "red"),
        ("-> cmd_vel  /tb2/cmd_vel  20.0 Hz  n 40  0 sub", "red"),  # nobody listens: red
    ]
    stale = {**MESSAGE, "subscriptions": [{**MESSAGE["subscriptions"][0], "age": 2.5}]}
    assert ros2_rows(stale)[1][1] == "yellow"  # older than 2 s
    # A name that would drive the terminal is shown cleaned.
    evil = {**MESSAGE, "name": "r\x1b[2J", "subscriptions": [], "publications": []}
    assert ros2_rows(evil)[0][0][0] == "ros2 r?[2J"


def test_rates_are_counted_over_the_last_seconds() -> None:
    r = Rates(window=2.0)
    assert r.rate("a", 100.0, 0) is None  # one count: no rate yet
    assert r.rate("a", 100.5, 5) == 10.0
    for k in range(1, 13):  # then 50 a second for 3 s
        got = r.rate("a", 100.5 + k * 0.25, 5 + k * 12)
    assert got == 48.0  # the first 10 Hz half second has left the window
    assert r.rate("a", 104.0, 3) is None  # counted from 0 again (a new node): starts over


def test_the_world_is_drawn_in_the_odom_frame_of_the_robot_of_its_namespace() -> None:
    world = WorldMap("w.yaml", walls=(((0.0, 0.0), (4.0, 0.0)),), boxes=((2.0, 3.0, 1.0, 0.5, 0.0),),
                     robots=(("a", "/a", 1.0, 1.0, 90.0), ("b", "/b", 0.0, 0.0, 0.0)))
    msg = world_message(world, "robot", "/a/")
    # a faces +y from (1, 1): the wall from (0, 0) to (4, 0) is 1 m behind it (odom x -1),
    # from its left (odom y +1) across to its right.
    assert msg["walls"] == [[[-1.0, 1.0], [-1.0, -3.0]]] and msg["note"] is None
    assert msg["robot"] == "a"
    corners = msg["boxes"][0]
    assert sorted(corners) == sorted([[2.25, -0.5], [2.25, -1.5], [1.75, -1.5], [1.75, -0.5]])
    other = world_message(world, "robot", "/c")
    assert other["robot"] == "a" and "no robot of namespace /c" in other["note"]
    assert world_message(world, "robot", "b")["walls"] == [[[0.0, 0.0], [4.0, 0.0]]]


def test_the_trail_keeps_a_point_every_2_cm_and_the_latest_points() -> None:
    t = Trail()
    assert t.add(0, 0) and not t.add(0.01, 0) and t.add(0.03, 0)
    for k in range(5000):
        t.add(k * 0.1, 0)
    assert len(t.points) == 4000 and t.points[-1] == [499.9, 0.0]


# -- the real thing: bump_and_go in the simulator --------------------------------------------
class Run:
    """The simulator, bump_and_go with --monitor, and their files."""

    def __init__(self, tmp: Path, domain: int) -> None:
        self.tmp = tmp
        self.domain = domain
        self.procs: list[subprocess.Popen[bytes]] = []
        out = subprocess.run([sys.executable, "-m", "hfsmc", "build",
                              str(EXAMPLE / "bump_and_go.yaml"), "-o", str(tmp / "bg")],
                             capture_output=True, text=True, timeout=120, cwd=ROOT)
        assert out.returncode == 0, out.stderr
        self.truth = tmp / "truth.json"
        self.start("sim", [sys.executable, "-m", "hfsmc", "sim", "--robot", "diffdrive", "--world",
                           str(EXAMPLE / "world.yaml"), "--domain", str(domain), "--truth",
                           str(self.truth)])
        self.start("component", [sys.executable, str(tmp / "bg" / "bump_and_go.py"), "--monitor",
                                 "0", "--until", "600s"])
        deadline = time.monotonic() + 20
        while not (m := re.search(r"monitor: listening on 127\.0\.0\.1:(\d+)",
                                  (tmp / "component.err").read_text())):
            assert time.monotonic() < deadline, (tmp / "component.err").read_text()
            time.sleep(0.05)
        self.port = int(m.group(1))

    def start(self, name: str, args: list[str]) -> None:
        with open(self.tmp / f"{name}.err", "w") as err:
            self.procs.append(subprocess.Popen(
                args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err,
                cwd=self.tmp, env={**_env(), "ROS_DOMAIN_ID": str(self.domain)}))

    def stop(self) -> None:
        for p in reversed(self.procs):
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
            try:
                p.wait(15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)

    def odom_truth(self) -> tuple[float, float]:
        """Where the simulator says the robot is, in its odom frame (the start at 0, 0)."""
        pose = json.loads(self.truth.read_text())["robots"]["tb2"]["pose"]
        return pose["x"] - START[0], pose["y"] - START[1]


def _env() -> dict[str, str]:
    return dict(os.environ)


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Run]:
    tmp = tmp_path_factory.mktemp("ros2views")
    with ros2_domain() as dom:
        r = Run(tmp, dom)
        try:
            yield r
        finally:
            r.stop()
    shutil.rmtree(tmp, ignore_errors=True)


def _ros2(c: Client, ok: Callable[[dict[str, Any]], bool], timeout: float = 30) -> dict[str, Any]:
    deadline = time.monotonic() + timeout
    while True:
        msg = c.message()
        assert msg is not None and time.monotonic() < deadline, msg
        if msg["type"] == "ros2" and ok(msg):
            return msg


def test_the_monitor_sends_the_topics_to_every_viewer_and_scans_to_those_that_ask(run: Run) -> None:
    c = Client(run.port)  # every message checked against schemas/monitor.schema.json
    try:
        hello = c.message()
        assert hello is not None and hello["minor"] == 4
        assert hello["feeds"] == {"vehicle": [], "camera": [], "ros2": ["robot"], "driver": []}

        def settled(m: dict[str, Any]) -> bool:
            subs = {s["name"]: s for s in m["subscriptions"]}
            return all(s["rate"] is not None and s["count"] > 20 for s in subs.values())

        msg = _ros2(c, settled)
        assert (msg["node"], msg["namespace"], msg["domain"]) == ("bump_and_go", "/", run.domain)
        subs = {s["name"]: s for s in msg["subscriptions"]}
        assert subs["scan"]["topic"] == "/scan" and subs["odom"]["type"] == "nav_msgs/msg/Odometry"
        # The simulator's rates (10 Hz scans, 50 Hz odometry), give or take a loaded machine.
        assert 5 < subs["scan"]["rate"] < 15 and 25 < subs["odom"]["rate"] < 75, subs
        assert all(s["publishers"] == 1 and s["dropped"] == 0 for s in subs.values())
        assert subs["odom"]["pose"]["frame"] == "odom" and "pose" not in subs["scan"]
        (pub,) = msg["publications"]
        assert pub["name"] == "cmd_vel" and pub["subscribers"] == 1 and pub["count"] > 0
        assert 10 < pub["rate"] < 30  # a Twist every 50 ms period
        # No scans to a viewer that did not ask: the ros2 messages keep coming without them.
        kinds = {m["type"] for m in [c.message() or {} for _ in range(12)]}
        assert "scan" not in kinds and "ros2" in kinds
        c.sock.sendall(b'{"type":"subscribe","scans":true}\n')
        deadline = time.monotonic() + 10
        while (m := c.message()) is not None and m["type"] != "scan":
            assert time.monotonic() < deadline
        assert m is not None and m["name"] == "robot" and m["subscription"] == "scan"
        assert len(m["ranges"]) == 360 and m["frame"] == "base_scan"
        assert m["pose"]["frame"] == "odom"  # where the robot was when it was taken
        # In the room of 8 m by 6 m with a range of 3.5 m, some rays see a wall.
        assert any(r is not None for r in m["ranges"])
        c.sock.sendall(b'{"type":"subscribe","scans":false}\n')
        time.sleep(0.5)
        late = [c.message() or {} for _ in range(12)]
        assert "scan" not in {x.get("type") for x in late[4:]}
    finally:
        c.close()


def test_the_terminal_view_shows_the_topics(run: Run, tmux: Callable[..., Tmux],
                                            tmp_path: Path) -> None:
    t = tmux(f"{sys.executable} -m hfsmc view {run.port}", ROOT)
    rows = (r"ros2 robot\s+/bump_and_go\s+domain \d+\s+jazzy",
            r"<- scan\s+/scan\s+\d+\.\d Hz\s+\d\.\d\d s ago\s+n \d+\s+1 pub",
            r"<- odom\s+/odom\s+\d+\.\d Hz\s+\d\.\d\d s ago\s+n \d+\s+1 pub",
            r"-> cmd_vel\s+/cmd_vel\s+\d+\.\d Hz\s+n \d+\s+1 sub")
    screen = t.wait(lambda s: all(re.search(r, s) for r in rows), timeout=30)
    assert "bump_and_go" in screen and re.search(r"● (Go|Back|Turn)", screen), screen
    folder = Path(os.environ.get("HFSMC_SCREENSHOTS") or tmp_path)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "view-bump_and_go.txt").write_text(screen)


MAP_JS = """
const c = document.querySelector('#hv-ros2 canvas.hv-map');
return {
  status: document.body.dataset.status,
  panel: !document.getElementById('hv-ros2').hidden,
  map: c && !c.hidden ? Object.assign({}, c.dataset) : null,
  rows: [...document.querySelectorAll('#hv-ros2 .hv-topics tr')].map((t) => t.innerText),
  head: (document.querySelector('#hv-ros2 .hv-ros2-node') || {}).textContent,
  caption: (document.querySelector('#hv-ros2 .hv-map-caption') || {}).textContent,
};
"""


@needs_browser
def test_the_web_view_draws_the_robot_on_its_map(run: Run, browsers: Callable[..., Any],
                                                  tmp_path: Path) -> None:
    web = Process([sys.executable, "-m", "hfsmc", "view", "--web", "0", f"127.0.0.1:{run.port}",
                   "--model", str(EXAMPLE / "bump_and_go.yaml"), "--world",
                   str(EXAMPLE / "world.yaml")], tmp_path, "web")
    try:
        url = web.wait_for(WEB_URL, where="out").group(1)
        driver = browsers()
        driver.set_window_size(1280, 800)
        driver.get(url)
        deadline = time.monotonic() + 60
        while True:
            s = driver.execute_script(MAP_JS)
            m = s["map"]
            # Driven a while: a trail, the latest scan, what past scans saw, the world's walls.
            if m and int(m["trail"]) > 40 and int(m["scan"]) > 30 and int(m["hits"]) > 300:
                break
            assert time.monotonic() < deadline, (s, web.err_path.read_text())
            time.sleep(0.2)
        assert s["status"] == "connected" and s["panel"], s
        assert m["walls"] == "4", m  # the room's closed polyline: 4 segments
        assert re.fullmatch(r"robot · node /bump_and_go · domain \d+ · jazzy", s["head"]), s
        assert [r.split("\t")[0] for r in s["rows"]] == ["← scan", "← odom", "→ cmd_vel"], s
        assert all(re.search(r"\d+\.\d Hz", r) for r in s["rows"]), s
        assert "walls of world.yaml (tb2's start at the origin)" in s["caption"], s
        # The map's pose is the simulator's, in the odom frame (the truth is rewritten every
        # simulated second: the robot moves at most 0.7 m/s meanwhile).
        tx, ty = run.odom_truth()
        assert math.hypot(float(m["x"]) - tx, float(m["y"]) - ty) < 1.0, (m, tx, ty)
        screenshot(driver, "web-ground-robot", tmp_path)
    finally:
        web.kill(signal.SIGINT)


def test_world_needs_the_web_view_and_a_good_file(tmp_path: Path) -> None:
    def view(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "hfsmc", "view", *args], capture_output=True,
                              text=True, timeout=60, cwd=ROOT)

    out = view("8765", "--world", str(EXAMPLE / "world.yaml"))
    assert (out.returncode, out.stderr) == (
        2, "hfsmc: error: --world is for the web view of a running component (--web [HOST:]PORT "
           "and the component's [HOST:]PORT)\n")
    bad = tmp_path / "world.yaml"
    bad.write_text("walls: [[[0, 0], [1, 0]]]\nboxes: [{x: 1, length: -2}]\n")
    port = socket.socket()
    port.bind(("127.0.0.1", 0))
    try:
        out = view("--web", "0", f"127.0.0.1:{port.getsockname()[1]}", "--world", str(bad))
    finally:
        port.close()
    assert out.returncode == 1 and out.stderr.startswith(f"hfsmc: error: --world: {bad}:2:"), out.stderr
    assert out.stderr.count("\n") == 1 and "Traceback" not in out.stderr
