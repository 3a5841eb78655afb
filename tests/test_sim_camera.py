"""The simulator's downward camera: rendering, the MJPEG stream, following another vehicle,
and the example worlds (docs/worlds.md, examples/). Real sockets on 127.0.0.1, every wait bounded."""

from __future__ import annotations

import contextlib
import io
import itertools
import math
import re
import selectors
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from pymavlink import mavutil

from hfsmc.sim.camera import MIN_ALTITUDE, OUTSIDE, CameraFeed, Renderer, bgr, footprint
from hfsmc.sim.follow import _Follower, run_follow
from hfsmc.sim.mjpeg import MjpegServer
from hfsmc.sim.world import World, WorldClock, WorldError, load_world, parse_world
from tests.conftest import ROOT
from tests.support import free_port, wait_until

GREEN = (0, 200, 0)
RED = (220, 20, 20)
BLUE = (0, 60, 230)
CAP_PARAMS = [cv2.CAP_PROP_OPEN_TIMEOUT_MSEC, 3000, cv2.CAP_PROP_READ_TIMEOUT_MSEC, 3000]


def world(**data: Any) -> World:
    return parse_world({"seed": 3, **data}, "test.yaml")


def disc(name: str, color: tuple[int, int, int], north: float, east: float,
         radius: float = 1.0) -> dict[str, Any]:
    return {"name": name, "color": list(color), "radius": radius, "path": [[north, east]]}


def blob(img: np.ndarray, rgb: tuple[int, int, int], tol: int = 40) -> tuple[int, float, float]:
    """(pixel count, mean u, mean v) of the pixels within ``tol`` of colour ``rgb``."""
    diff = np.abs(img.astype(np.int32) - np.array(bgr(rgb), dtype=np.int32)).max(axis=2)
    vs, us = np.nonzero(diff <= tol)
    if len(us) == 0:
        return (0, math.nan, math.nan)
    return (len(us), float(us.mean()), float(vs.mean()))


def focal(w: World) -> float:
    return (w.camera.width / 2) / math.tan(math.radians(w.camera.hfov_deg) / 2)


def centre(w: World) -> tuple[float, float]:
    return ((w.camera.width - 1) / 2, (w.camera.height - 1) / 2)


# --- rendering -------------------------------------------------------------------------------

def test_render_is_deterministic_and_shaped() -> None:
    w = world(road={"points": [[0, 0], [30, 10]]}, victims=[{"north": 1, "east": 2}],
              objects=[{"name": "g", "color": list(GREEN), "path": [[0, 0], [20, 0]]}],
              camera={"width": 160, "height": 120})
    a = Renderer(w).render(3.0, 1.0, 0.5, -4.0, 0.3)
    b = Renderer(w).render(3.0, 1.0, 0.5, -4.0, 0.3)
    assert a.shape == (120, 160, 3) and a.dtype == np.uint8
    assert a.tobytes() == b.tobytes()
    assert Renderer(w).render(9.0, 1.0, 0.5, -4.0, 0.3).tobytes() != a.tobytes()  # it moved
    other_seed = Renderer(parse_world({"seed": 4, "camera": {"width": 160, "height": 120}}))
    assert other_seed.render(0, 0, 0, -4, 0).tobytes() != Renderer(
        world(camera={"width": 160, "height": 120})).render(0, 0, 0, -4, 0).tobytes()


def test_an_object_under_the_vehicle_is_at_the_centre_in_its_colour() -> None:
    w = world(objects=[disc("g", GREEN, 10, -5)])
    img = Renderer(w).render(0.0, 10.0, -5.0, -4.0, 0.7)
    n, u, v = blob(img, GREEN, tol=0)
    cu, cv = centre(w)
    assert n > 0 and abs(u - cu) < 0.5 and abs(v - cv) < 0.5
    assert tuple(img[120, 160]) == bgr(GREEN)


@pytest.mark.parametrize(("yaw_deg", "du", "dv"), [
    (0, 0, -1),     # heading north: north is up
    (90, -1, 0),    # heading east: north is on the left
    (-90, 1, 0),    # heading west: north is on the right
    (180, 0, 1),    # heading south: north is down
])
def test_yaw_turns_the_view(yaw_deg: float, du: int, dv: int) -> None:
    w = world(objects=[disc("r", RED, 2, 0, radius=0.3)])
    img = Renderer(w).render(0.0, 0.0, 0.0, -5.0, math.radians(yaw_deg))
    n, u, v = blob(img, RED, tol=0)
    offset = focal(w) * 2 / 5  # 2 m away seen from 5 m up, in pixels
    cu, cv = centre(w)
    assert n > 0
    assert abs(u - (cu + du * offset)) < 1 and abs(v - (cv + dv * offset)) < 1


def test_the_right_of_the_image_is_the_right_of_the_vehicle() -> None:
    w = world(objects=[disc("b", BLUE, 0, 2, radius=0.5)])  # east of the vehicle
    _, u, v = blob(Renderer(w).render(0, 0, 0, -5, 0), BLUE, tol=0)
    assert u > centre(w)[0] + 50 and abs(v - centre(w)[1]) < 1


def test_altitude_scales_the_view() -> None:
    w = world(objects=[disc("g", GREEN, 0, 0, radius=0.5)])
    r = Renderer(w)
    areas = {h: blob(r.render(0, 0, 0, -h, 0), GREEN, tol=0)[0] for h in (2.0, 4.0, 8.0)}
    expected = {h: math.pi * (0.5 * focal(w) / h) ** 2 for h in areas}
    for h in areas:
        assert areas[h] == pytest.approx(expected[h], rel=0.08)
    assert footprint(w, 4.0) == pytest.approx((2 * 4 * math.tan(math.radians(40)),
                                               2 * 4 * math.tan(math.radians(40)) * 0.75))


def test_on_the_ground_the_camera_sees_from_its_minimum_height() -> None:
    w = world(objects=[disc("g", GREEN, 0, 0)])
    r = Renderer(w)
    low = r.render(0, 0, 0, -MIN_ALTITUDE, 0).tobytes()
    assert r.render(0, 0, 0, 0.0, 0).tobytes() == low
    assert r.render(0, 0, 0, 0.3, 0).tobytes() == low  # below the ground: as on it


def grey(img: np.ndarray) -> np.ndarray:
    """Where the picture is road-like: low saturation, not dark."""
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    return (hsv[:, :, 1] < 40) & (hsv[:, :, 2] > 50)


def test_the_road_is_where_it_should_be() -> None:
    w = world(road={"width": 4, "points": [[0, -50], [0, 50]]})  # along east, through home
    r = Renderer(w)
    half = 4 / 2 * focal(w) / 5  # half the road's width in pixels from 5 m up
    cu, cv = centre(w)
    across = r.render(0, 0, 0, -5, 0)  # heading north: the road runs left-right
    rows = grey(across).mean(axis=1)
    assert rows[round(cv)] > 0.99 and rows[round(cv - half + 3)] > 0.99
    assert rows[round(cv - half - 3)] < 0.01 and rows[round(cv + half + 3)] < 0.01
    along = r.render(0, 0, 0, -5, math.pi / 2)  # heading east: the road runs up-down
    cols = grey(along).mean(axis=0)
    assert cols[round(cu)] > 0.99 and cols[round(cu + half + 3)] < 0.01
    assert not grey(r.render(0, 20, 0, -5, 0)).any()  # 20 m north: grass only
    # A bend: from home north 10 m, then east; seen from above the corner, heading north.
    bend = Renderer(world(road={"width": 2, "points": [[0, 0], [10, 0], [10, 20]]}))
    g = grey(bend.render(0, 10, 0, -6, 0))
    assert g[round(cv), round(cu)] and g[-1, round(cu)] and g[round(cv), -1]
    assert not g[0, 0] and not g[-1, -1] and not g[0, -1]


def test_outside_the_ground_is_dark_and_plain() -> None:
    w = world(ground={"size": 40})
    img = Renderer(w).render(0, 20, 0, -5, 0)  # over the north edge, heading north
    cv = round(centre(w)[1])
    assert (img[: cv - 2] == OUTSIDE).all()
    assert not (img[cv + 2:] == OUTSIDE).all(axis=2).any()


def test_victims_are_figures_in_their_colour() -> None:
    yellow = (230, 200, 40)
    w = world(victims=[{"north": 2, "east": 0}, {"north": -30, "east": 0}])
    img = Renderer(w).render(0, 0, 0, -5, 0)
    n, u, v = blob(img, yellow, tol=0)
    cu, cv = centre(w)
    r_px = 0.6 * focal(w) / 5
    assert 0.8 * math.pi * r_px * 0.45 * r_px < n < 1.2 * math.pi * r_px * 0.45 * r_px
    assert abs(u - cu) < r_px and abs(v - (cv - 2 * focal(w) / 5)) < r_px


def test_texture_changes_brightness_not_colour() -> None:
    flat = Renderer(world(ground={"texture": 0.0})).render(0, 0, 0, -4, 0)
    assert (np.abs(flat.astype(int) - np.array(bgr((70, 130, 60)))) <= 1).all()
    rough = Renderer(world(ground={"texture": 0.5})).render(0, 0, 0, -4, 0)
    hsv = cv2.cvtColor(rough, cv2.COLOR_BGR2HSV)
    assert hsv[:, :, 2].std() > 4
    ground_hue = cv2.cvtColor(np.array([[bgr((70, 130, 60))]], dtype=np.uint8),
                              cv2.COLOR_BGR2HSV)[0, 0, 0]
    assert (np.abs(hsv[:, :, 0].astype(int) - int(ground_hue)) <= 3).mean() > 0.99


def test_frames_along_a_flight_over_monitor_area() -> None:
    """Descending and turning over the road (what a frame costs is bench/vision.py's figure,
    5 ms its target): every frame is drawn, whole, and the same when drawn again."""
    w = load_world(ROOT / "examples/monitor_area/world.yaml")
    poses = [(i / 15, 40 + i * 0.3, i * 0.2, -6 - i * 0.05, i * 0.05) for i in range(60)]
    r = Renderer(w)
    frames = [r.render(*p) for p in poses]
    assert all(f.shape == (w.camera.height, w.camera.width, 3) and f.dtype == np.uint8
               for f in frames)
    assert len({f.tobytes() for f in frames}) == len(frames)  # it moved at every frame
    assert all(r.render(*p).tobytes() == f.tobytes() for p, f in zip(poses[::10], frames[::10],
                                                                      strict=True))
    assert grey(frames[0]).any()  # over the road at the start


def test_world_values_are_checked() -> None:
    with pytest.raises(WorldError, match=r"w\.yaml: camera\.width: expected a whole number"):
        parse_world({"camera": {"width": 320.5}}, "w.yaml")
    with pytest.raises(WorldError, match=r"w\.yaml: camera\.hfov_deg: must be between 1 and 170"):
        parse_world({"camera": {"hfov_deg": 200}}, "w.yaml")
    with pytest.raises(WorldError, match=r"w\.yaml: objects\[0\]\.path"):
        parse_world({"objects": [{"name": "g", "color": [0, 1, 2]}]}, "w.yaml")
    with pytest.raises(WorldError, match=r"w\.yaml: seed"):
        parse_world({"seed": "x"}, "w.yaml")


# --- the MJPEG stream ------------------------------------------------------------------------

@pytest.fixture
def feed() -> Iterator[CameraFeed]:
    w = world(objects=[disc("g", GREEN, 0, 0, radius=1.5)])
    f = CameraFeed(w, lambda: (0.0, 0.0, 0.0, -4.0, 0.0), port=0)
    f.start()
    try:
        yield f
    finally:
        f.stop()


def capture(url: str) -> Any:
    return cv2.VideoCapture(url, cv2.CAP_FFMPEG, CAP_PARAMS)


def read_frames(cap: Any, n: int, within: float = 5.0) -> list[np.ndarray]:
    frames: list[np.ndarray] = []
    deadline = time.monotonic() + within
    while len(frames) < n and time.monotonic() < deadline:
        ok, frame = cap.read()
        if not ok:
            break
        frames.append(frame)
    return frames


def is_green_at_centre(frame: np.ndarray) -> bool:
    b, g, r = (int(c) for c in frame[120, 160])
    return g > 150 and b < 60 and r < 60


def http_get(url: str) -> tuple[int, str, bytes]:
    try:
        with urllib.request.urlopen(url, timeout=3) as resp:
            return resp.status, resp.headers.get("Content-Type", ""), resp.read()
    except urllib.error.HTTPError as e:
        e.close()
        return e.code, "", b""


def test_opencv_reads_the_stream_with_several_clients(feed: CameraFeed) -> None:
    assert feed.url == f"http://127.0.0.1:{feed.port}/bottom.mjpg"
    caps = [capture(feed.url) for _ in range(3)]
    try:
        assert all(c.isOpened() for c in caps)
        # A client that goes away mid-stream, and one that never reads: the others go on.
        rude = socket.create_connection(("127.0.0.1", feed.port), timeout=2)
        rude.sendall(b"GET /bottom.mjpg HTTP/1.0\r\n\r\n")
        rude.recv(100)
        rude.close()
        idle = socket.create_connection(("127.0.0.1", feed.port), timeout=2)
        idle.sendall(b"GET /bottom.mjpg HTTP/1.0\r\n\r\n")
        for c in caps:
            frames = read_frames(c, 8)
            assert len(frames) == 8
            assert frames[-1].shape == (240, 320, 3) and is_green_at_centre(frames[-1])
        idle.close()
    finally:
        for c in caps:
            c.release()


def test_the_stream_runs_at_the_cameras_rate(feed: CameraFeed) -> None:
    with socket.create_connection(("127.0.0.1", feed.port), timeout=3) as s:
        s.sendall(f"GET /bottom.mjpg HTTP/1.1\r\nHost: 127.0.0.1:{feed.port}\r\n\r\n".encode())
        data = b""
        t0 = time.monotonic()
        while time.monotonic() - t0 < 1.5:
            data += s.recv(65536)
        head = data.split(b"\r\n\r\n", 1)[0].decode()
    assert head.startswith("HTTP/1.0 200")
    assert "multipart/x-mixed-replace; boundary=hfsmcframe" in head
    parts = data.count(b"--hfsmcframe\r\nContent-Type: image/jpeg\r\nContent-Length: ")
    assert 15 * 1.5 - 6 <= parts <= 15 * 1.5 + 3


def test_pause_drops_the_stream_and_a_reader_reconnects(feed: CameraFeed) -> None:
    cap = capture(feed.url)
    try:
        assert len(read_frames(cap, 3)) == 3
        feed.pause(True)
        assert feed.paused
        t0 = time.monotonic()
        assert len(read_frames(cap, 100, within=3.0)) < 100  # the stream ended
        assert time.monotonic() - t0 < 3.0
        cap.release()
        again = capture(feed.url)
        assert not again.isOpened()  # refused while dropped
        again.release()
        assert http_get(feed.url)[0] == 503
        assert http_get(feed.url.replace("bottom.mjpg", "snapshot.jpg"))[0] == 503
        feed.pause(False)
        cap = capture(feed.url)
        assert cap.isOpened()
        frames = read_frames(cap, 3)
        assert len(frames) == 3 and is_green_at_centre(frames[-1])
    finally:
        cap.release()


def test_snapshot_and_unknown_paths(feed: CameraFeed) -> None:
    base = f"http://127.0.0.1:{feed.port}"
    status, ctype, body = http_get(base + "/snapshot.jpg")
    assert status == 200 and ctype == "image/jpeg"
    img = cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None
    assert img.shape == (240, 320, 3) and is_green_at_centre(img)
    last = feed.frame()
    assert last is not None and last.shape == (240, 320, 3)
    assert http_get(base + "/nothing")[0] == 404
    assert http_get(base + "/")[0] == 404
    assert http_get(base + "/bottom.mjpg.old")[0] == 404


def test_stop_closes_everything_within_a_second() -> None:
    w = world()
    f = CameraFeed(w, lambda: (0.0, 0.0, 0.0, -4.0, 0.0), port=0)
    url = f.start()
    port = f.port
    cap = capture(url)
    idle = socket.create_connection(("127.0.0.1", port), timeout=2)  # never sends a request
    stuck = socket.create_connection(("127.0.0.1", port), timeout=2)  # never reads
    stuck.sendall(b"GET /bottom.mjpg HTTP/1.0\r\n\r\n")
    try:
        assert len(read_frames(cap, 2)) == 2
        t0 = time.monotonic()
        f.stop()
        assert time.monotonic() - t0 < 1.0
        assert len(read_frames(cap, 100, within=3.0)) < 100
        with pytest.raises(OSError):
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
        assert idle.recv(10) == b""  # cut too
    finally:
        cap.release()
        idle.close()
        stuck.close()


def test_a_failing_pose_skips_frames_without_stopping_the_camera() -> None:
    calls = {"n": 0}

    def pose() -> tuple[float, float, float, float, float]:
        calls["n"] += 1
        if calls["n"] < 4:
            raise RuntimeError("no pose yet")
        return (0.0, 0.0, 0.0, -4.0, 0.0)

    with CameraFeed(world(), pose, port=0) as f:
        deadline = time.monotonic() + 3
        while f.frame() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert f.frame() is not None


def test_the_server_alone_and_a_busy_port() -> None:
    s = MjpegServer(port=0)
    s.start()
    try:
        assert http_get(s.url("/snapshot.jpg"))[0] == 503  # nothing published yet
        s.publish(b"\xff\xd8fake\xff\xd9")
        assert http_get(s.url("/snapshot.jpg"))[2] == b"\xff\xd8fake\xff\xd9"
        with pytest.raises(OSError):
            CameraFeed(world(), lambda: (0.0, 0.0, 0.0, -4.0, 0.0), port=s.port).start()
    finally:
        s.stop()


def ask(port: int, host: str | None) -> tuple[int, dict[str, str], bytes]:
    """GET /snapshot.jpg with the ``Host`` given (none at all for None, as HTTP/1.0 allows)."""
    with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
        s.sendall(b"GET /snapshot.jpg HTTP/1.0\r\n" + (f"Host: {host}\r\n".encode() if host is not None
                                                        else b"") + b"\r\n")
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    head, _, body = data.partition(b"\r\n\r\n")
    lines = head.decode().split("\r\n")
    headers = dict(line.split(": ", 1) for line in lines[1:])
    return int(lines[0].split()[1]), headers, body


def test_the_camera_answers_loopback_names_only_and_a_bounded_number_of_clients() -> None:
    """DNS rebinding: a page under another name pointed at 127.0.0.1 is refused; pages of other
    origins may not embed the frames; the 17th connection at once is told 503 and closed."""
    from hfsmc.sim.mjpeg import MAX_CLIENTS

    s = MjpegServer(port=0)
    s.start()
    held: list[socket.socket] = []
    try:
        s.publish(b"\xff\xd8fake\xff\xd9")
        for host in (f"127.0.0.1:{s.port}", f"localhost:{s.port}", "[::1]", None):
            status, headers, body = ask(s.port, host)
            assert (status, body) == (200, b"\xff\xd8fake\xff\xd9"), host
            assert headers["Cross-Origin-Resource-Policy"] == "same-origin"
            assert headers["X-Content-Type-Options"] == "nosniff"
        for host in (f"rebind.test:{s.port}", "127.0.0.1.nip.io", "a b", ""):
            status, _, body = ask(s.port, host)
            assert status == 403 and b"not a name this camera answers to" in body, host
        # Streams held open (every one reading) fill the slots; one more is refused at once.
        for _ in range(MAX_CLIENTS):
            c = socket.create_connection(("127.0.0.1", s.port), timeout=3)
            c.sendall(f"GET /bottom.mjpg HTTP/1.0\r\nHost: 127.0.0.1:{s.port}\r\n\r\n".encode())
            assert c.recv(12) == b"HTTP/1.0 200"
            held.append(c)
        status, _, body = ask(s.port, f"127.0.0.1:{s.port}")
        assert (status, body) == (503, b"too many camera clients at once\n")
        held.pop().close()  # its thread sees it gone at the next frame

        def served() -> bool:
            s.publish(b"\xff\xd8fake\xff\xd9")
            return ask(s.port, f"127.0.0.1:{s.port}")[0] == 200

        assert wait_until(served, 5, step=0.1)
    finally:
        for c in held:
            c.close()
        s.stop()


# --- following another vehicle ---------------------------------------------------------------

class FakeVehicle:
    """Plays a MAVLink vehicle: heartbeats, LOCAL_POSITION_NED and ATTITUDE at 20 Hz."""

    def __init__(self, port: int) -> None:
        self.conn = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1,
                                               source_component=1)
        self.pose = (0.0, 0.0, -4.0, 0.0)  # north, east, down, yaw
        self.asked: set[int] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        mav = self.conn.mav
        t0 = time.monotonic()
        i = 0
        while not self._stop.wait(0.05):
            ms = int((time.monotonic() - t0) * 1000)
            if i % 10 == 0:
                mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_QUADROTOR,
                                   mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 4)
            n, e, d, yaw = self.pose
            mav.local_position_ned_send(ms, n, e, d, 0, 0, 0)
            mav.attitude_send(ms, 0, 0, yaw, 0, 0, 0)
            i += 1
            while (msg := self.conn.recv_match(type="COMMAND_LONG", blocking=False)) is not None:
                if msg.command == mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
                    self.asked.add(int(msg.param1))

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2)
        self.conn.close()


def read_line(proc: subprocess.Popen[str], within: float) -> str:
    assert proc.stdout is not None
    with selectors.DefaultSelector() as sel:
        sel.register(proc.stdout, selectors.EVENT_READ)
        if not sel.select(within):
            return ""
    return proc.stdout.readline()


def wait_for(cond: Any, within: float) -> bool:
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.1)
    return bool(cond())


FOLLOW = ("import sys; from hfsmc.sim.follow import run_follow; "
          "from hfsmc.sim.world import load_world; "
          "sys.exit(run_follow(load_world(sys.argv[1]), sys.argv[2], 0))")


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_the_camera_follows_another_vehicle(tmp_path: Path, sig: int) -> None:
    world_file = tmp_path / "world.yaml"
    world_file.write_text("objects:\n  - {name: r, color: [220, 20, 20], radius: 0.5,"
                          " path: [[10, 5]]}\n")
    port = free_port(socket.SOCK_DGRAM)
    vehicle = FakeVehicle(port)
    with open(tmp_path / "stderr", "w") as err:
        proc = subprocess.Popen([sys.executable, "-c", FOLLOW, str(world_file),
                                 f"udpin:127.0.0.1:{port}"], cwd=ROOT, text=True,
                                stdout=subprocess.PIPE, stderr=err)
    try:
        line = read_line(proc, 20)
        assert "camera http://127.0.0.1:" in line, (tmp_path / "stderr").read_text()
        url = line.split("camera ", 1)[1].split()[0]
        snap = url.replace("bottom.mjpg", "snapshot.jpg")

        def red_at(du: int, dv: int) -> bool:
            status, _, body = http_get(snap)
            if status != 200:
                return False
            img = cv2.imdecode(np.frombuffer(body, np.uint8), cv2.IMREAD_COLOR)
            if img is None:
                return False
            n, u, v = blob(img, RED, tol=60)
            return n > 20 and abs(u - (159.5 + du)) < 3 and abs(v - (119.5 + dv)) < 3

        vehicle.pose = (10.0, 5.0, -4.0, 0.0)  # right over the red disc
        assert wait_for(lambda: red_at(0, 0), 10)
        offset = round((160 / math.tan(math.radians(40))) * 1 / 4)  # 1 m seen from 4 m up
        vehicle.pose = (9.0, 5.0, -4.0, 0.0)  # 1 m south of it, heading north: red is ahead
        assert wait_for(lambda: red_at(0, -offset), 5)
        vehicle.pose = (9.0, 5.0, -4.0, math.pi / 2)  # heading east: red is on the left
        assert wait_for(lambda: red_at(-offset, 0), 5)
        assert wait_for(lambda: {30, 32} <= vehicle.asked, 5)  # it asked for the pose streams
        cap = capture(url)
        assert cap.isOpened() and len(read_frames(cap, 3)) == 3
        proc.send_signal(sig)
        assert proc.wait(timeout=5) == 0
        assert len(read_frames(cap, 100, within=3.0)) < 100
        cap.release()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(5)
        vehicle.close()
        assert proc.stdout is not None
        proc.stdout.close()


# pymavlink leaves the socket of a link it failed to open to the garbage collector.
@pytest.mark.filterwarnings("ignore::ResourceWarning")
def test_follow_stops_on_its_event_and_reports_a_bad_link(tmp_path: Path) -> None:
    stop = threading.Event()
    out = tmp_path / "out.txt"
    result: list[int] = []
    with open(out, "w") as f:
        t = threading.Thread(target=lambda: result.append(
            run_follow(world(), f"udpin:127.0.0.1:{free_port(socket.SOCK_DGRAM)}", 0, stop=stop, out=f)))
        t.start()
        assert wait_for(lambda: "camera http://" in out.read_text(), 10)
        stop.set()
        t.join(5)
    assert result == [0]
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        assert run_follow(world(), "udpin:256.1.1.1:14551", 0, stop=stop) == 1
    assert "cannot open the MAVLink link udpin:256.1.1.1:14551" in err.getvalue()


def test_the_world_clock_starts_at_start_arming_or_take_off() -> None:
    start, armed, takeoff = WorldClock("start"), WorldClock("armed"), WorldClock("takeoff")
    assert start.time(5.0) == 5.0 and not start.update(5.0, True, 3.0)
    assert not armed.update(40.0, False, 0.0) and armed.time(40.0) == 0.0
    assert armed.update(41.0, True, 0.0) and armed.time(51.0) == 10.0
    assert not armed.update(60.0, False, 0.0) and armed.time(61.0) == 20.0  # once started, runs
    assert not takeoff.update(41.0, True, 0.1) and takeoff.time(43.0) == 0.0  # still on the ground
    assert takeoff.update(44.0, True, 0.4) and takeoff.time(45.5) == 1.5
    with pytest.raises(ValueError):
        WorldClock("boot")


def test_the_follower_starts_the_world_clock_when_the_vehicle_arms() -> None:
    """With a real autopilot ready a minute after its start, the objects wait for it."""
    said: list[str] = []
    follower = _Follower(WorldClock("armed"), say=said.append)
    ml = mavutil.mavlink
    disarmed = ml.MAVLink_heartbeat_message(2, 3, ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, 4, 3, 3)
    armed = ml.MAVLink_heartbeat_message(
        2, 3, ml.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | ml.MAV_MODE_FLAG_SAFETY_ARMED, 4, 4, 3)
    follower.handle(disarmed)
    follower.handle(ml.MAVLink_local_position_ned_message(0, 1.0, 2.0, -0.05, 0, 0, 0))
    assert follower.clock.zero is None and follower.pose()[0] == 0.0 and said == []
    follower.handle(armed)
    assert follower.clock.zero is not None and said == ["the world's clock starts (vehicle armed)"]
    follower.handle(armed)
    assert len(said) == 1
    assert follower.pose()[1:4] == (1.0, 2.0, -0.05)


def test_world_clock_option_is_in_the_help() -> None:
    r = subprocess.run([sys.executable, "-m", "hfsmc", "sim", "--help"], cwd=ROOT,
                       capture_output=True, text=True, timeout=30)
    assert r.returncode == 0 and "--world-clock WHEN" in r.stdout and "takeoff" in r.stdout


# --- the example worlds ----------------------------------------------------------------------

# The drone's worlds; a ground robot's (walls, robots) are tests/test_ground_sim.py's.
WORLDS = sorted(p for p in (ROOT / "examples").glob("*/world.yaml")
                if not re.search(r"^(walls|robots):", p.read_text(), re.M))


def test_the_example_worlds_are_there() -> None:
    assert {p.parent.name for p in WORLDS} >= {"follow_colors", "monitor_area"}


@pytest.mark.parametrize("path", WORLDS, ids=lambda p: p.parent.name)
def test_an_example_world_loads_and_renders(path: Path) -> None:
    w = load_world(path)
    assert w.name == path.parent.name
    img = Renderer(w).render(0, 0, 0, -4, 0)
    assert img.shape == (w.camera.height, w.camera.width, 3)


def test_follow_colors_shows_the_next_colour_while_following_the_current_one() -> None:
    w = load_world(ROOT / "examples/follow_colors/world.yaml")
    r = Renderer(w)
    objs = {o.name: o for o in w.objects}
    order = ["green1", "blue", "green2", "red"]
    assert list(objs) == order
    # Airborne over home, green 1 is in view (partly at least) at 3-5 m before it moves.
    for h in (3.0, 5.0):
        assert blob(r.render(objs["green1"].start, 0, 0, -h, 0), objs["green1"].color)[0] > 100
    for cur, nxt in itertools.pairwise(order):
        a, b = objs[cur], objs[nxt]
        end = a.start + sum(math.dist(p, q) for p, q in itertools.pairwise(a.path)) / a.speed
        assert b.start >= end  # the next one waits for the current one
        n, e = a.position(end)
        for h in (3.0, 4.0, 5.0):
            img = r.render(end, n, e, -h, 0)
            assert blob(img, b.color)[0] > 100, (cur, nxt, h)
        # ...and is not in view while the current one is still far from the end of its path.
        n, e = a.position(end - 10)
        assert blob(r.render(end - 10, n, e, -5, 0), b.color)[0] == 0, (cur, nxt)
    red = objs["red"]
    total = red.start + sum(math.dist(p, q) for p, q in itertools.pairwise(red.path)) / red.speed
    assert 120 <= total <= 180
    pts = [p for o in w.objects for p in o.path] + [(0.0, 0.0)]
    assert max(math.dist(p, q) for p in pts for q in pts) <= 120


def test_monitor_area_has_a_road_to_an_accident_with_five_victims() -> None:
    w = load_world(ROOT / "examples/monitor_area/world.yaml")
    pts = w.road.points
    assert pts[0] == (0.0, 0.0) and len(pts) >= 3
    length = sum(math.dist(p, q) for p, q in itertools.pairwise(pts))
    assert 60 <= length <= 90
    assert w.accident is not None and not w.objects
    acc = (w.accident.north, w.accident.east)
    assert math.dist(pts[-1], acc) <= 5
    assert len(w.victims) == 5
    assert all(math.dist((v.north, v.east), acc) <= 12 for v in w.victims)
    r = Renderer(w)
    assert grey(r.render(0, 0, 0, -8, 0))[119, 159]  # home is on the road
    yellow = w.victims[0].color
    assert blob(r.render(0, acc[0], acc[1], -15, 0), yellow, tol=30)[0] > 100
