"""`hfsmc sim --camera-only --follow URL`: the simulated camera on another MAVLink vehicle.

The vehicle (ArduPilot SITL, say) is heard on a pymavlink URL such as
``udpin:127.0.0.1:14551``; its LOCAL_POSITION_NED and ATTITUDE (yaw) are the
camera's pose. Once the vehicle has been heard, the streams are asked for at
20 Hz with SET_MESSAGE_INTERVAL, as a ground station would, and again while
they do not come. The world's clock (its objects' motion) starts when the vehicle
first arms (by default: a real autopilot may take a minute to be ready), when it
first leaves the ground, or when the follower starts (``world_clock``).
"""

from __future__ import annotations

import contextlib
import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from types import FrameType
from typing import Any, TextIO

from pymavlink import mavutil

from hfsmc.sim.camera import CameraFeed, Pose
from hfsmc.sim.world import World, WorldClock

RATE_HZ = 20.0  # pose messages asked of the vehicle
ASK_AGAIN = 3.0  # seconds without a pose before asking again
MSG_ATTITUDE = 30
MSG_LOCAL_POSITION_NED = 32


class _Follower:
    """The other vehicle's latest pose, written by the MAVLink loop, read by the camera."""

    def __init__(self, clock: WorldClock | None = None,
                 say: Callable[[str], None] = lambda text: None) -> None:
        self._lock = threading.Lock()
        self._t0 = time.monotonic()
        self.clock = clock or WorldClock("armed")
        self.say = say
        self.armed = False
        self.north = self.east = self.down = self.yaw = 0.0
        self.system: int | None = None  # the vehicle's system id once heard
        self.last_position = -math.inf
        self.last_ask = -math.inf

    def pose(self) -> Pose:
        with self._lock:
            t = self.clock.time(time.monotonic() - self._t0)
            return (t, self.north, self.east, self.down, self.yaw)

    def handle(self, msg: Any) -> None:
        kind = msg.get_type()
        src = msg.get_srcSystem()
        if kind == "HEARTBEAT":
            if self.system is None and msg.autopilot != mavutil.mavlink.MAV_AUTOPILOT_INVALID:
                self.system = src
            if src == self.system:
                self.armed = bool(msg.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                self._clock()
            return
        if self.system is not None and src != self.system:
            return  # a ground station or another vehicle on the same link
        with self._lock:
            if kind == "LOCAL_POSITION_NED":
                self.north, self.east, self.down = float(msg.x), float(msg.y), float(msg.z)
                self.last_position = time.monotonic()
            elif kind == "ATTITUDE":
                self.yaw = float(msg.yaw)
        if kind == "LOCAL_POSITION_NED":
            self._clock()

    def _clock(self) -> None:
        with self._lock:
            started = self.clock.update(time.monotonic() - self._t0, self.armed, -self.down)
        if started:
            self.say(f"the world's clock starts (vehicle {self.clock.start})")


def _ask_for_pose(conn: Any, system: int) -> None:
    interval_us = int(1e6 / RATE_HZ)
    for msg_id in (MSG_LOCAL_POSITION_NED, MSG_ATTITUDE):
        conn.mav.command_long_send(system, 0, mavutil.mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                   msg_id, interval_us, 0, 0, 0, 0, 0)


def run_follow(world: World, mavlink_url: str, port: int = 8554, host: str = "127.0.0.1",
               stop: threading.Event | None = None, out: TextIO | None = None,
               world_clock: str = "armed") -> int:
    """Serve ``world``'s camera from the pose of the vehicle heard on ``mavlink_url`` until
    SIGINT or SIGTERM (or ``stop`` is set); 0 then, 1 when the link or the port cannot open.
    The world's objects start moving at ``world_clock`` (``armed``, ``takeoff``, ``start``).

    Prints the stream's URL on ``out`` (stdout) once serving.
    """
    out = out or sys.stdout
    stop = stop or threading.Event()
    try:
        conn = mavutil.mavlink_connection(mavlink_url, source_system=255,
                                          source_component=mavutil.mavlink.MAV_COMP_ID_CAMERA)
    except Exception as e:  # pymavlink raises whatever its transport raises
        print(f"hfsmc sim: cannot open the MAVLink link {mavlink_url}: {e}", file=sys.stderr)
        return 1
    follower = _Follower(WorldClock(world_clock), say=lambda text: print(
        f"hfsmc sim: {text}", file=sys.stderr, flush=True))
    feed = CameraFeed(world, follower.pose, host=host, port=port)
    try:
        url = feed.start()
    except OSError as e:
        conn.close()
        print(f"hfsmc sim: cannot serve the camera on {host}:{port}: {e}", file=sys.stderr)
        return 1
    restore = _on_signals(stop)
    try:
        print(f"hfsmc sim: camera {url} following {mavlink_url}", file=out, flush=True)
        _listen(conn, follower, stop)
    finally:
        restore()
        feed.stop()
        conn.close()
    return 0


def _listen(conn: Any, follower: _Follower, stop: threading.Event) -> None:
    while not stop.is_set():
        try:
            msg = conn.recv_match(type=["HEARTBEAT", "LOCAL_POSITION_NED", "ATTITUDE"],
                                  blocking=True, timeout=0.2)
        except OSError:
            msg = None  # a datagram that could not be read: the next one may
            time.sleep(0.05)
        if msg is not None:
            follower.handle(msg)
        now = time.monotonic()
        # Asked once when the vehicle is first heard (its default rates may be low), then
        # again while its pose does not come.
        if follower.system is not None and now - follower.last_ask > ASK_AGAIN and (
                follower.last_ask == -math.inf or now - follower.last_position > ASK_AGAIN):
            follower.last_ask = now
            with contextlib.suppress(OSError):  # not reachable yet: asked again later
                _ask_for_pose(conn, follower.system)


def _on_signals(stop: threading.Event) -> Callable[[], None]:
    """SIGINT and SIGTERM set ``stop`` (in the main thread only, where Python allows it);
    returns what puts the previous handlers back."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None

    def handler(signum: int, frame: FrameType | None) -> None:
        stop.set()
    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}

    def restore() -> None:
        for s, h in previous.items():
            signal.signal(s, h)

    return restore
