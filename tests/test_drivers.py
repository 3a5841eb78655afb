"""The drone and camera interfaces of Python components (docs/interfaces.md), on loopback:
a fake ArduPilot-like vehicle written here with pymavlink, a tiny MJPEG server,
and a generated component flying the fake."""

from __future__ import annotations

import contextlib
import http.server
import importlib
import json
import math
import re
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from pymavlink import mavutil

from tests.conftest import ROOT
from tests.support import Live, Worker, free_port, simulator, wait_until

hfsmc_mavlink = importlib.import_module("hfsmc.templates.python.hfsmc_mavlink")
hfsmc_camera = importlib.import_module("hfsmc.templates.python.hfsmc_camera")
MAV = mavutil.mavlink

pytestmark = pytest.mark.timeout(60)

GUIDED, LAND, RTL, STABILIZE = 4, 9, 6, 0  # ArduCopter custom modes
READY_FLAGS = MAV.EKF_ATTITUDE | MAV.EKF_VELOCITY_HORIZ | MAV.EKF_POS_HORIZ_ABS


# -- a fake vehicle ------------------------------------------------------------------------
class FakeVehicle(Worker):
    """ArduPilot Copter as a ground station sees it, reduced: it sends to the
    component's port (udpout), heartbeats and telemetry, answers COMMAND_LONG
    with COMMAND_ACK the way Copter would (or as `answers` says: a MAV_RESULT,
    or None for silence), climbs and lands, and records what it receives."""

    def __init__(self, port: int, *, heartbeat_s: float = 1.0, gps_fix: int = 3,
                 ekf_flags: int = READY_FLAGS, ready_after: float | None = None) -> None:
        self.conn: Any = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}",
                                                    source_system=1, source_component=1)
        self.heartbeat_s = heartbeat_s
        self.heartbeats = True
        self.gps_fix = gps_fix
        self.ekf_flags = ekf_flags
        self.ready_after = ready_after  # s after the first word from the component: READY_FLAGS
        self.answers: dict[int, int | None] = {}
        self.received: list[tuple[float, Any]] = []
        self.mode = STABILIZE
        self.armed = False
        self.north = self.east = 0.0
        self.alt = 0.0
        self.target_alt = 0.0
        self.battery = 87
        self.start_worker()

    def close(self) -> None:
        self.stop_worker(timeout=2)
        self.conn.close()

    def messages(self, kind: str) -> list[Any]:
        with self._lock:
            return [m for _, m in self.received if m.get_type() == kind]

    def commands(self, command: int | None = None) -> list[Any]:
        return [m for m in self.messages("COMMAND_LONG") if command in (None, m.command)]

    def _run(self) -> None:
        next_heartbeat = next_telemetry = 0.0
        last = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            self._fly(now - last)
            last = now
            while (m := self.conn.recv_msg()) is not None:
                if self.ready_after is not None and not self.received:
                    threading.Timer(self.ready_after, setattr, (self, "ekf_flags", READY_FLAGS)).start()
                with self._lock:
                    self.received.append((now, m))
                if m.get_type() == "COMMAND_LONG":
                    self._answer(m)
            if self.heartbeats and now >= next_heartbeat:
                next_heartbeat = now + self.heartbeat_s
                self.send_heartbeat()
            if now >= next_telemetry:
                next_telemetry = now + 0.05
                self._telemetry()
            time.sleep(0.005)

    def send_heartbeat(self) -> None:
        base = MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (
            MAV.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        self.conn.mav.heartbeat_send(MAV.MAV_TYPE_QUADROTOR, MAV.MAV_AUTOPILOT_ARDUPILOTMEGA,
                                     base, self.mode, MAV.MAV_STATE_STANDBY)

    def _telemetry(self) -> None:
        mav = self.conn.mav
        ms = int(time.monotonic() * 1000) & 0xFFFFFFFF
        mav.local_position_ned_send(ms, self.north, self.east, -self.alt, 0.5, -0.25, 0.125)
        mav.global_position_int_send(ms, 0, 0, 0, int(self.alt * 1000), 0, 0, 0, 0)
        mav.attitude_send(ms, 0.0, 0.0, 1.25, 0.0, 0.0, 0.0)
        mav.sys_status_send(0, 0, 0, 0, 12000, 0, self.battery, 0, 0, 0, 0, 0, 0)
        mav.gps_raw_int_send(ms * 1000, self.gps_fix, 0, 0, 0, 0, 0, 0, 0, 10)
        mav.ekf_status_report_send(self.ekf_flags, 0, 0, 0, 0, 0)

    def _fly(self, dt: float) -> None:
        step = 2.5 * dt
        self.alt = min(self.alt + step, self.target_alt) if self.alt < self.target_alt else max(
            self.alt - step, self.target_alt)
        if self.mode == LAND and self.alt <= 0.0:
            self.armed = False

    def _answer(self, m: Any) -> None:
        result = self.answers[m.command] if m.command in self.answers else self._obey(m)
        if result is not None:
            self.conn.mav.command_ack_send(m.command, result)

    def _obey(self, m: Any) -> int:
        ok, failed = int(MAV.MAV_RESULT_ACCEPTED), int(MAV.MAV_RESULT_FAILED)
        if m.command == MAV.MAV_CMD_DO_SET_MODE:
            self.mode = int(m.param2)
        elif m.command == MAV.MAV_CMD_COMPONENT_ARM_DISARM:
            if m.param1 == 0 and self.alt > 0.1:
                return failed
            self.armed = m.param1 == 1
        elif m.command == MAV.MAV_CMD_NAV_TAKEOFF:
            if not self.armed or self.mode != GUIDED:
                return failed
            self.target_alt = m.param7
        elif m.command == MAV.MAV_CMD_NAV_LAND:
            self.mode, self.target_alt = LAND, 0.0
        elif m.command == MAV.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            self.mode = RTL
        return ok


@pytest.fixture
def link() -> Iterator[tuple[Any, FakeVehicle]]:
    """A vehicle interface connected to a fake vehicle."""
    port = free_port(socket.SOCK_DGRAM)
    drone = Live(hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {}))
    fake = FakeVehicle(port)
    try:
        assert wait_until(drone.connected, 5)
        yield drone, fake
    finally:
        fake.close()
        drone.close()


# -- the mavlink interface ------------------------------------------------------------------
def test_before_any_vehicle_everything_answers_at_once(capsys: pytest.CaptureFixture[str]) -> None:
    drone = Live(hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{free_port(socket.SOCK_DGRAM)}", {}))
    try:
        assert not drone.connected() and not drone.ready() and not drone.armed()
        assert drone.heartbeat_age() == math.inf
        assert drone.mode() == ""
        assert all(math.isnan(x) for x in (*drone.position(), *drone.velocity(),
                                            drone.altitude(), drone.yaw()))
        assert drone.battery() == -1
        assert drone.last_ack("arm") == ""
        drone.arm()
        drone.set_velocity(1, 0, 0, 0)  # a stream of targets: nothing to send to, nothing said
        assert drone.last_ack("arm") == "not_sent"
        assert capsys.readouterr().err == "drone: arm: not sent, no vehicle yet (no heartbeat)\n"
    finally:
        drone.close()


def test_connects_requests_rates_and_reads_telemetry(link: tuple[Any, FakeVehicle],
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    drone, fake = link
    assert wait_until(lambda: not math.isnan(drone.yaw()), 2)
    assert drone.heartbeat_age() < 1.5
    assert drone.mode() == "STABILIZE" and not drone.armed()
    assert drone.position() == (0.0, 0.0, 0.0)
    assert drone.velocity() == (0.5, -0.25, 0.125)
    assert drone.yaw() == 1.25 and drone.battery() == 87 and drone.altitude() == 0.0
    assert wait_until(lambda: len(fake.commands(MAV.MAV_CMD_SET_MESSAGE_INTERVAL)) == 8, 2)
    intervals = {int(m.param1): m.param2 for m in fake.commands(MAV.MAV_CMD_SET_MESSAGE_INTERVAL)}
    fast = (MAV.MAVLINK_MSG_ID_LOCAL_POSITION_NED, MAV.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
            MAV.MAVLINK_MSG_ID_ATTITUDE)
    slow = (MAV.MAVLINK_MSG_ID_SYS_STATUS, MAV.MAVLINK_MSG_ID_GPS_RAW_INT,
            MAV.MAVLINK_MSG_ID_EKF_STATUS_REPORT, MAV.MAVLINK_MSG_ID_BATTERY_STATUS,
            MAV.MAVLINK_MSG_ID_HOME_POSITION)
    assert set(intervals) == {*fast, *slow}
    assert all(0 < intervals[i] <= 100_000 for i in fast)  # 10 Hz or more, in microseconds
    assert all(intervals[i] > 100_000 for i in slow)
    assert all((m.target_system, m.target_component) == (1, 1) for m in fake.commands())
    assert wait_until(lambda: fake.messages("HEARTBEAT"), 2)  # a ground station's heartbeat
    hb = fake.messages("HEARTBEAT")[0]
    assert (hb.type, hb.autopilot) == (MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID)
    time.sleep(0.2)
    assert "set_message_interval" not in capsys.readouterr().err  # accepted: nothing to say


def test_ready_follows_gps_and_ekf_as_arducopter_does(link: tuple[Any, FakeVehicle]) -> None:
    drone, fake = link
    fake.gps_fix, fake.ekf_flags = 1, MAV.EKF_ATTITUDE
    assert wait_until(lambda: not drone.ready(), 2)
    fake.gps_fix = 3
    time.sleep(0.3)
    assert not drone.ready()  # a 3D fix, but no absolute position in the EKF yet
    fake.ekf_flags = MAV.EKF_ATTITUDE | MAV.EKF_PRED_POS_HORIZ_ABS
    assert wait_until(drone.ready, 2)  # disarmed: a predicted absolute position will do
    fake.armed = True
    fake.send_heartbeat()
    assert wait_until(lambda: drone.armed() and not drone.ready(), 2)  # armed: it will not
    fake.ekf_flags = READY_FLAGS
    assert wait_until(drone.ready, 2)
    fake.ekf_flags = READY_FLAGS | MAV.EKF_CONST_POS_MODE
    assert wait_until(lambda: not drone.ready(), 2)


def test_each_command_sends_the_right_packet(link: tuple[Any, FakeVehicle],
                                             capsys: pytest.CaptureFixture[str]) -> None:
    drone, fake = link
    drone.set_mode("guided")
    drone.arm()
    drone.takeoff(3.0)
    assert wait_until(lambda: drone.last_ack("takeoff") == "accepted", 2)
    drone.land()
    drone.rtl()
    assert wait_until(lambda: drone.last_ack("rtl") == "accepted", 2)
    fake.alt = fake.target_alt = 0.0
    drone.disarm()
    assert wait_until(lambda: drone.last_ack("disarm") == "accepted", 2)
    sent = [(m.command, m.confirmation, m.param1, m.param2, m.param7) for m in fake.commands()
            if m.command != MAV.MAV_CMD_SET_MESSAGE_INTERVAL]
    assert sent == [
        (MAV.MAV_CMD_DO_SET_MODE, 0, MAV.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, GUIDED, 0),
        (MAV.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0),
        (MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 3.0),
        (MAV.MAV_CMD_NAV_LAND, 0, 0, 0, 0),
        (MAV.MAV_CMD_NAV_RETURN_TO_LAUNCH, 0, 0, 0, 0),
        (MAV.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 0, 0),
    ]
    assert all((m.target_system, m.target_component) == (1, 1) for m in fake.commands())
    assert [line for line in capsys.readouterr().err.splitlines() if "vehicle 1/1" not in line] == [
        "drone: set_mode GUIDED accepted", "drone: arm accepted", "drone: takeoff accepted",
        "drone: land accepted", "drone: rtl accepted", "drone: disarm accepted"]
    assert [drone.last_ack(c) for c in ("set_mode", "arm", "land")] == ["accepted"] * 3
    assert wait_until(lambda: drone.mode() == "RTL", 2)
    with pytest.raises(ValueError, match="unknown mode `HOVER`"):
        drone.set_mode("HOVER")


def _bits(mask: int) -> set[int]:
    return {i for i in range(16) if mask >> i & 1}


def test_velocity_goto_and_hold_targets(link: tuple[Any, FakeVehicle]) -> None:
    drone, fake = link
    drone.set_velocity(1.5, -2.0, -0.5, 0.25)
    drone.goto(4.0, -5.0, 6.0)
    drone.hold()
    assert wait_until(lambda: len(fake.messages("SET_POSITION_TARGET_LOCAL_NED")) == 3, 2)
    velocity, goto, hold = fake.messages("SET_POSITION_TARGET_LOCAL_NED")
    for m in (velocity, goto, hold):
        assert (m.target_system, m.target_component) == (1, 1)
    # Body frame; ignore x y z (bits 0-2), acceleration (6-8) and yaw (10); use vx vy vz yaw_rate.
    assert velocity.coordinate_frame == MAV.MAV_FRAME_BODY_OFFSET_NED == 9
    assert velocity.type_mask == 0x05C7 == 0b0000_0101_1100_0111
    assert _bits(velocity.type_mask) == {0, 1, 2, 6, 7, 8, 10}
    assert (velocity.vx, velocity.vy, velocity.vz, velocity.yaw_rate) == (1.5, -2.0, -0.5, 0.25)
    # Local NED from the EKF origin; use x y z only (ArduPilot's "use position", 0x0DF8).
    assert goto.coordinate_frame == MAV.MAV_FRAME_LOCAL_NED == 1
    assert goto.type_mask == 0x0DF8 and _bits(goto.type_mask) == {3, 4, 5, 6, 7, 8, 10, 11}
    assert (goto.x, goto.y, goto.z) == (4.0, -5.0, -6.0)
    # Hold: a zero velocity target.
    assert (hold.coordinate_frame, hold.type_mask) == (9, 0x05C7)
    assert (hold.vx, hold.vy, hold.vz, hold.yaw_rate) == (0.0, 0.0, 0.0, 0.0)


def test_refusal_and_silence_are_logged_once(link: tuple[Any, FakeVehicle],
                                             capsys: pytest.CaptureFixture[str]) -> None:
    drone, fake = link
    capsys.readouterr()
    drone.takeoff(2.0)  # not armed, not GUIDED: Copter says FAILED
    fake.answers[MAV.MAV_CMD_COMPONENT_ARM_DISARM] = MAV.MAV_RESULT_DENIED
    drone.arm()
    fake.answers[MAV.MAV_CMD_NAV_LAND] = None  # no answer at all
    sent = time.monotonic()
    drone.land()
    assert drone.last_ack("land") == "pending"
    assert wait_until(lambda: drone.last_ack("land") == "timeout", 4)
    assert 2.9 <= time.monotonic() - sent <= 3.6
    lands = [(t, m) for t, m in fake.received
             if m.get_type() == "COMMAND_LONG" and m.command == MAV.MAV_CMD_NAV_LAND]
    assert [m.confirmation for _, m in lands] == [0, 1]  # resent once, as MAVProxy does
    assert lands[1][0] - lands[0][0] >= 1.2 and lands[1][0] - lands[0][0] <= 2.0
    time.sleep(0.3)
    assert capsys.readouterr().err.splitlines() == [
        "drone: takeoff FAILED", "drone: arm DENIED", "drone: land: no acknowledgement in 3 s"]
    assert (drone.last_ack("takeoff"), drone.last_ack("arm")) == ("failed", "denied")


def test_in_progress_waits_for_the_final_answer(link: tuple[Any, FakeVehicle],
                                                capsys: pytest.CaptureFixture[str]) -> None:
    drone, fake = link
    capsys.readouterr()
    fake.answers[MAV.MAV_CMD_NAV_TAKEOFF] = MAV.MAV_RESULT_IN_PROGRESS
    drone.takeoff(1.0)
    time.sleep(2.0)  # past the resend point: in progress means no resend
    assert drone.last_ack("takeoff") == "pending"
    assert len(fake.commands(MAV.MAV_CMD_NAV_TAKEOFF)) == 1
    fake.conn.mav.command_ack_send(MAV.MAV_CMD_NAV_TAKEOFF, MAV.MAV_RESULT_ACCEPTED)
    assert wait_until(lambda: drone.last_ack("takeoff") == "accepted", 2)
    assert capsys.readouterr().err == "drone: takeoff accepted\n"


def test_lost_link_is_seen_within_two_and_a_half_seconds(
        link: tuple[Any, FakeVehicle], capsys: pytest.CaptureFixture[str]) -> None:
    drone, fake = link
    capsys.readouterr()
    fake.heartbeats = False
    stopped = time.monotonic()
    assert wait_until(lambda: not drone.connected(), 3)
    assert time.monotonic() - stopped <= 2.5
    assert drone.heartbeat_age() >= 2.0
    assert wait_until(lambda: "link lost" in capsys.readouterr().err, 1)
    fake.heartbeats = True
    assert wait_until(drone.connected, 2)
    assert wait_until(lambda: "drone: link back" in capsys.readouterr().err, 1)


def test_garbage_datagrams_do_not_break_the_reader(link: tuple[Any, FakeVehicle]) -> None:
    drone, fake = link
    port = int(drone.url.rsplit(":", 1)[1])
    rng = np.random.default_rng(7)
    good = MAV.MAVLink_heartbeat_message(2, 3, 0, 0, 0, 3).pack(MAV.MAVLink(None, 1, 1))
    bad_crc = good[:-1] + bytes([good[-1] ^ 0xFF])
    junk = [b"", b"\xfe", b"\xfd\x00\x00", good[:5], bad_crc, b"hello\n" * 100,
            bytes(60000), *(rng.integers(0, 256, n, dtype=np.uint8).tobytes()
                            for n in (1, 7, 17, 280, 1500, 9000))]
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        for _ in range(20):
            for datagram in junk:
                s.sendto(datagram, ("127.0.0.1", port))
    fake.north = 3.0
    assert wait_until(lambda: drone.position()[0] == 3.0, 2)
    drone.arm()
    assert wait_until(lambda: drone.last_ack("arm") == "accepted", 2)
    assert drone.connected() and drone._thread.is_alive()


def test_queries_and_commands_never_touch_the_socket(link: tuple[Any, FakeVehicle]) -> None:
    drone, fake = link
    readers: set[int | None] = set()
    recv = drone._conn.recv

    def spy(*args: Any) -> Any:
        readers.add(threading.get_ident())
        return recv(*args)

    drone._conn.recv = spy
    fake.heartbeats = False
    fake.answers = dict.fromkeys(range(1000))  # silent from now on
    time.sleep(0.2)
    worst = 0.0
    for _ in range(50):
        for call in (drone.connected, drone.ready, drone.heartbeat_age, drone.armed, drone.mode,
                     drone.position, drone.altitude, drone.velocity, drone.yaw, drone.battery,
                     lambda: drone.last_ack("arm"), drone.hold, lambda: drone.goto(1, 2, 3),
                     lambda: drone.set_velocity(1, 0, 0, 0), drone.arm, drone.land):
            start = time.perf_counter()
            call()
            worst = max(worst, time.perf_counter() - start)
    assert worst < 0.05  # a sanity bound; the real guarantee is the next line
    assert readers == {drone._thread.ident}


def test_gcs_heartbeats_do_not_count_as_the_vehicle() -> None:
    port = free_port(socket.SOCK_DGRAM)
    drone = Live(hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {}))
    gcs: Any = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=255)
    try:
        for _ in range(5):
            gcs.mav.heartbeat_send(MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            time.sleep(0.05)
        assert not drone.connected() and drone.mode() == ""
    finally:
        gcs.close()
        drone.close()


def test_close_frees_the_port_and_a_taken_port_is_said(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port(socket.SOCK_DGRAM)
    drone = Live(hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {"rate": "50"}))
    drone.close()
    assert not drone._thread.is_alive()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as held:
        held.bind(("127.0.0.1", port))  # free again
        with pytest.raises(SystemExit) as stop:
            hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {})
        assert stop.value.code == 1
    assert capsys.readouterr().err.startswith(f"drone: cannot open udpin:127.0.0.1:{port}: ")


def test_bad_options_are_said_and_replaced(capsys: pytest.CaptureFixture[str]) -> None:
    drone = Live(hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{free_port(socket.SOCK_DGRAM)}",
                                  {"rate": "fast", "colour": "red"}))
    drone.close()
    assert capsys.readouterr().err.splitlines() == [
        "drone: option rate: `fast` is not a positive number, 20 used",
        "drone: unknown option `colour` ignored (options: rate, ack_timeout, source_system, autopilot)"]


# -- the camera interface -------------------------------------------------------------------
class MjpegServer:
    """MJPEG over HTTP on 127.0.0.1 (multipart/x-mixed-replace), 320x240 at 25 fps."""

    def __init__(self, port: int) -> None:
        server = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                n = 0
                while not server.stopping.is_set():
                    img = np.zeros((240, 320, 3), np.uint8)
                    img[:, :, 1] = 50 + n % 200
                    jpeg = cv2.imencode(".jpg", img)[1].tobytes()
                    try:
                        self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\n"
                                         b"Content-Length: %d\r\n\r\n%s\r\n" % (len(jpeg), jpeg))
                        self.wfile.flush()
                    except OSError:
                        return
                    n += 1
                    server.stopping.wait(0.04)

            def log_message(self, format: str, *args: Any) -> None:
                pass

        self.stopping = threading.Event()
        self.http = http.server.ThreadingHTTPServer(("127.0.0.1", port), Handler)
        self.http.daemon_threads = True
        self.thread = threading.Thread(target=self.http.serve_forever, args=(0.05,), daemon=True)
        self.thread.start()

    def close(self) -> None:
        self.stopping.set()
        self.http.shutdown()
        self.http.server_close()
        self.thread.join(timeout=2)


@contextlib.contextmanager
def mjpeg(port: int) -> Iterator[MjpegServer]:
    server = MjpegServer(port)
    try:
        yield server
    finally:
        server.close()


def test_camera_serves_the_latest_frame(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port(socket.SOCK_STREAM)
    with mjpeg(port):
        camera = Live(hfsmc_camera.connect("camera", f"http://127.0.0.1:{port}/bottom.mjpg", {}))
        small = Live(hfsmc_camera.connect("small", f"http://127.0.0.1:{port}/bottom.mjpg",
                                     {"size": "160x120"}))
        try:
            assert wait_until(lambda: camera.frame() is not None and small.frame() is not None, 10)
            frame = camera.frame()
            assert frame.shape == (240, 320, 3) and frame.dtype == np.uint8
            assert 40 < frame[120, 160, 1] < 255 and frame[120, 160, 0] < 10  # green, BGR
            assert small.frame().shape == (120, 160, 3)
            assert 0 <= camera.age() < 0.5 and camera.ok()
            seen = camera.count()
            assert wait_until(lambda: camera.count() >= seen + 5, 2)
        finally:
            camera.close()
            small.close()
    assert capsys.readouterr().err == ""


def test_camera_reconnects_when_the_stream_comes_back(capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port(socket.SOCK_STREAM)
    camera = Live(hfsmc_camera.connect("camera", f"http://127.0.0.1:{port}/bottom.mjpg", {}))
    try:
        time.sleep(0.3)  # nobody serves yet
        assert camera.frame() is None and camera.age() == math.inf and not camera.ok()
        with mjpeg(port):
            assert wait_until(camera.ok, 5)  # reconnected within the 2 s backoff
        dropped = time.monotonic()
        assert wait_until(lambda: not camera.ok(), 4)
        last = camera.frame()
        worst = 0.0
        for _ in range(200):  # the stream is down: still no wait
            start = time.perf_counter()
            camera.frame(), camera.age(), camera.ok()
            worst = max(worst, time.perf_counter() - start)
        assert worst < 0.05 and camera.frame() is last and camera.age() >= 1.0
        time.sleep(max(0.0, 1.5 - (time.monotonic() - dropped)))
        with mjpeg(port):
            seen = camera.count()
            assert wait_until(lambda: camera.count() > seen, 5)
            assert camera.ok()
            camera.close()
    finally:
        camera.close()
    url = f"http://127.0.0.1:{port}/bottom.mjpg"
    assert capsys.readouterr().err.splitlines() == [
        f"camera: stream not available at {url}: reconnecting",
        f"camera: stream back at {url}",
        f"camera: stream lost at {url}: reconnecting",
        f"camera: stream back at {url}"]


def test_camera_plays_a_file_at_its_rate_and_loops(tmp_path: Path) -> None:
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter.fourcc(*"MJPG"), 20.0, (64, 48))
    for i in range(6):
        writer.write(np.full((48, 64, 3), (0, 0, 40 * i), np.uint8))
    writer.release()
    camera = Live(hfsmc_camera.connect("camera", str(video), {"size": "32x24"}))
    try:
        assert wait_until(lambda: camera.count() >= 1, 5)
        assert camera.frame().shape == (24, 32, 3)
        assert wait_until(lambda: camera.count() > 6, 3)  # looped
        time.sleep(0.5)
        assert camera.count() < 30  # about 20 fps, not as fast as decoding goes
    finally:
        camera.close()


def test_camera_without_a_device_and_bad_size(capsys: pytest.CaptureFixture[str]) -> None:
    camera = Live(hfsmc_camera.connect("camera", "63", {"size": "big"}))
    try:
        time.sleep(0.3)
        assert camera.frame() is None and not camera.ok()
    finally:
        camera.close()
    assert capsys.readouterr().err.splitlines() == [
        "camera: option size: `big` is not WxH (320x240): frames kept as they come",
        "camera: stream not available at 63: reconnecting"]


# -- a generated component flying the fake ---------------------------------------------------
PROBE = """\
hfsm: 1
name: takeoff_probe
language: python
interfaces:
  drone: {{type: mavlink, url: "udpin:127.0.0.1:{port}"}}
period: 50ms
initial: WaitReady
states:
  WaitReady:
    transitions:
      - {{to: Guided, when: drone.ready()}}
  Guided:
    entry: |
      log(f"ready, mode {{drone.mode()}}, battery {{drone.battery()}} %")
      drone.set_mode("GUIDED")
    transitions:
      - {{to: Arm, when: drone.mode() == "GUIDED"}}
  Arm:
    entry: drone.arm()
    transitions:
      - {{to: TakeOff, when: drone.armed()}}
  TakeOff:
    entry: |
      drone.takeoff(2.0)
      log(f"taking off from {{drone.altitude():.1f}} m")
    transitions:
      - {{to: Up, when: drone.altitude() >= 2.0}}
  Up:
    entry: log(f"up at {{drone.altitude():.1f}} m, ack {{drone.last_ack('takeoff')}}")
    final: true
"""


def build_probe(tmp_path: Path, port: int) -> Path:
    model = tmp_path / "takeoff_probe.yaml"
    model.write_text(PROBE.format(port=port))
    out = tmp_path / "probe"
    r = subprocess.run([sys.executable, "-m", "hfsmc", "build", "-t", "python", str(model),
                        "-o", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (out / "hfsmc_mavlink.py").read_bytes() == (
        ROOT / "templates/python/hfsmc_mavlink.py").read_bytes()
    return out / "takeoff_probe.py"


def test_generated_component_waits_for_ready_then_takes_off(tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    main = build_probe(tmp_path, port)
    fake = FakeVehicle(port, heartbeat_s=0.5, ekf_flags=MAV.EKF_ATTITUDE, ready_after=1.0)
    try:
        started = time.monotonic()
        run = subprocess.run([sys.executable, str(main), "--clock", "real", "--until", "5s",
                              "--trace", "-"], capture_output=True, text=True, timeout=30,
                             stdin=subprocess.DEVNULL)
        took = time.monotonic() - started
    finally:
        fake.close()
    assert run.returncode == 0, run.stderr
    records = [json.loads(line) for line in run.stdout.splitlines()]
    assert [r["state"] for r in records if r["ev"] == "enter"] == [
        "WaitReady", "Guided", "Arm", "TakeOff", "Up"]
    assert records[-1]["ev"] == "stop" and records[-1]["reason"] == "final"
    ready_at = next(r["t"] for r in records if r["ev"] == "enter" and r["state"] == "Guided")
    assert ready_at >= 1000  # the EKF had no absolute position for a second
    logs = [(r["state"], r["msg"]) for r in records if r["ev"] == "log"]
    # It stops at its final state with the vehicle armed: said loudly, in the trace too.
    warning = ("drone: WARNING: ARMED in GUIDED at 2.0 m as the component stops: "
               "nothing lands the vehicle now")
    assert logs == [("Guided", "ready, mode STABILIZE, battery 87 %"),
                    ("TakeOff", "taking off from 0.0 m"), ("Up", "up at 2.0 m, ack accepted"),
                    ("", warning)]
    assert f"takeoff_probe: {warning}\n" in run.stderr
    commands = [(m.command, m.param1, m.param2, m.param7) for m in fake.commands()
                if m.command != MAV.MAV_CMD_SET_MESSAGE_INTERVAL]
    assert commands == [(MAV.MAV_CMD_DO_SET_MODE, 1, GUIDED, 0),
                        (MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1, 0, 0),
                        (MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 2.0)]
    assert run.stderr.startswith(f"drone: vehicle 1/1 on udpin:127.0.0.1:{port}, mode STABILIZE\n")
    for line in ("drone: set_mode GUIDED accepted", "drone: arm accepted",
                 "drone: takeoff accepted"):
        assert line in run.stderr.splitlines(), run.stderr
    assert took < 8  # stopped at the final state, the reader closed at exit


# -- against the simulator -------------------------------------------------------------------
def test_takeoff_to_three_metres_and_land_in_the_simulator(tmp_path: Path,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    port = free_port(socket.SOCK_DGRAM)
    truth = tmp_path / "truth.json"
    drone = Live(hfsmc_mavlink.connect("drone", f"udpin:127.0.0.1:{port}", {}))
    try:
        with simulator(tmp_path, port, "--no-camera", "--truth", str(truth)):
            assert wait_until(drone.connected, 10)
            assert wait_until(drone.ready, 10)
            drone.arm()  # in STABILIZE: refused, as the vehicle only arms in GUIDED
            assert wait_until(lambda: drone.last_ack("arm") in ("failed", "denied"), 5)
            assert not drone.armed()
            drone.set_mode("GUIDED")
            assert wait_until(lambda: drone.mode() == "GUIDED", 5)
            drone.arm()
            assert wait_until(drone.armed, 5)
            drone.takeoff(3.0)
            assert wait_until(lambda: drone.altitude() > 2.8, 15)
            time.sleep(1.0)
            assert 2.7 < drone.altitude() < 3.3 and abs(drone.position()[2] + 3.0) < 0.4
            warning = drone.warning_at_stop()
            assert warning is not None and re.fullmatch(
                r"WARNING: ARMED in GUIDED at (2\.9|3\.0|3\.1) m "
                r"as the component stops: nothing lands the vehicle now", warning), warning
            drone.land()
            assert wait_until(lambda: not drone.armed(), 25, step=0.1)  # landed, disarmed by itself
            assert drone.mode() == "LAND" and drone.altitude() < 0.3
            assert drone.warning_at_stop() is None
    finally:
        drone.close()
    said = capsys.readouterr().err.splitlines()
    for line in ("drone: set_mode GUIDED accepted", "drone: arm accepted",
                 "drone: takeoff accepted", "drone: land accepted"):
        assert line in said, said
    assert any(line.startswith("drone: arm FAILED") or line.startswith("drone: arm DENIED")
               for line in said), said
    final = json.loads(truth.read_text())
    assert final["armed"] is False and final["landed"] is True
    assert 2.7 < final["track"]["max_altitude"] < 3.4
    assert (final["track"]["takeoffs"], final["track"]["landings"]) == (1, 1)
