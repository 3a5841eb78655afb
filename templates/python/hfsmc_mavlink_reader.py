"""The receiving side of the ``mavlink`` interface (hfsmc_mavlink.py), copied beside a
component with it, and mixed into its ``Vehicle``.

One daemon thread (``_run``; in lockstep, the automaton's thread through
``lockstep_sync``, which counts the simulator's datagrams in, then calls ``_drain`` and
``_timed``) reads the socket and keeps the latest telemetry as immutable values (a float
or a tuple, replaced whole, so that readers need no lock), watches the heartbeat, sends
ours, matches COMMAND_ACKs to the commands waiting for them (``Pending``: resent once
halfway to the deadline, as MAVProxy does with ``confirmation`` + 1) and logs each
outcome once on stderr. The mission protocol's messages and its resends go to
hfsmc_mission_upload.py (``_upload_message``, ``_upload_tick``). What the automaton
sends, and when it asks, is hfsmc_mavlink's.
"""

from __future__ import annotations

import contextlib
import select
import threading
import time
from dataclasses import dataclass
from typing import Any

from pymavlink import mavutil

try:  # beside the component, or in the hfsmc package
    from . import hfsmc_mavlink_link as _link
    from . import hfsmc_px4 as _px4
except ImportError:
    import hfsmc_mavlink_link as _link  # type: ignore[import-not-found, no-redef]
    import hfsmc_px4 as _px4  # type: ignore[import-not-found, no-redef]

_MAV: Any = mavutil.mavlink

LINK_TIMEOUT_S = 2.0  # no heartbeat for that long: the link is lost (docs/interfaces.md)
GCS_HEARTBEAT_S = 1.0  # our own heartbeat, so the vehicle sees a ground station
POLL_S = 0.05  # longest wait of the reader: bounds ack deadlines and close()
DATAGRAM_WAIT_S = 10.0  # lockstep: the simulator's datagrams, counted, are that late at most
PREARM_CHECK = 0x10000000  # SYS_STATUS sensor bit PX4 sets healthy once it would arm
RESULTS = _px4.RESULTS = {0: "accepted", 1: "temporarily_rejected", 2: "denied", 3: "unsupported",
           4: "failed", 5: "in_progress", 6: "cancelled"}  # MAV_RESULT
IN_PROGRESS = 5


@dataclass(slots=True)
class Pending:
    """A command waiting for its COMMAND_ACK."""

    name: str  # the key of last_ack(): arm, disarm, takeoff, land, rtl, set_mode, ...
    label: str  # as logged: `set_mode GUIDED`
    command: int
    params: tuple[float, ...]  # the seven of COMMAND_LONG
    deadline: float
    resend_at: float | None  # None once resent (or in progress)
    quiet: bool  # log only a failure (message rates)


class Reader:
    """The reader of hfsmc_mavlink.Vehicle, which mixes it in (its attributes are the
    vehicle's: ``_conn``, ``_lock``, ``_target``, ``_pending``, ``_say``...)."""

    _conn: Any
    _lock: threading.Lock
    _stop: threading.Event
    _pending: list[Pending]
    _acks: dict[str, str]
    _answered: dict[int, tuple[str, str, bool, float]]
    _ack_timeout: float
    _target: tuple[int, int] | None
    _heartbeat_at: float | None
    _heartbeat: tuple[int, int, int, int]
    _next_heartbeat: float
    _lost: bool
    _position: tuple[float, float, float]
    _velocity: tuple[float, float, float]
    _relative_alt: float | None
    _home_amsl: float | None
    _yaw: float
    _battery: int
    _gps_fix: int
    _ekf_flags: int
    _prearm: bool
    _px4: bool
    _autopilot: str
    _duplicates: _link.Duplicates
    _counted: _link.Counted | None
    name: str
    url: str | None
    now: Any
    _say: Any
    _mode_name: Any
    _request_rates: Any
    _mission_message: Any
    _upload_message: Any
    _upload_tick: Any
    _late_ack: Any
    _px4_tick: Any

    def _run(self) -> None:
        while not self._stop.is_set():
            fd = self._conn.fd
            if fd is None:  # a link select cannot watch: poll it
                self._stop.wait(POLL_S)
                self._drain()
            else:
                try:
                    readable, _, _ = select.select([fd], [], [], POLL_S)
                except (OSError, ValueError):  # closed under us
                    return
                if readable:
                    self._drain()
            self._timed(time.monotonic())

    def _timed(self, now: float) -> None:
        """The reader's timed work: our heartbeat, resends and deadlines, the link's watch."""
        if now >= self._next_heartbeat:
            self._next_heartbeat = now + GCS_HEARTBEAT_S
            with self._lock:
                self._conn.mav.heartbeat_send(_MAV.MAV_TYPE_GCS,
                                              _MAV.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        self._expire(now)
        self._upload_tick(now)
        self._watch_link()
        if self._px4:
            self._px4_tick(now)

    def _drain(self) -> None:
        """Handle every datagram waiting; a bad one is dropped, never raised."""
        for _ in range(1000):  # bounded, so a flood cannot starve the deadlines
            try:
                with self._lock:
                    msg = self._conn.recv_msg()
            except Exception:  # garbage pymavlink could not digest
                continue
            if msg is None:
                return
            try:
                self._handle(msg)
            except (AttributeError, TypeError, ValueError):  # a malformed field
                continue

    def _handle(self, msg: Any) -> None:
        kind = msg.get_type()
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self._duplicates.seen(self.now(), source, bytes(msg.get_msgbuf())):
            return
        if kind == "HEARTBEAT":
            self._on_heartbeat(msg, source)
            return
        if self._target is None or source[0] != self._target[0]:
            return
        if self._mission_message(kind, msg) or self._upload_message(kind, msg):
            return
        if kind == "LOCAL_POSITION_NED":
            self._position = (float(msg.x), float(msg.y), float(msg.z))
            self._velocity = (float(msg.vx), float(msg.vy), float(msg.vz))
        elif kind == "GLOBAL_POSITION_INT":
            self._relative_alt = msg.relative_alt / 1000.0
            if msg.lat or msg.lon:
                self._home_amsl = (msg.alt - msg.relative_alt) / 1000.0
        elif kind == "ATTITUDE":
            self._yaw = float(msg.yaw)
        elif kind == "SYS_STATUS":
            self._battery = int(msg.battery_remaining)
            self._prearm = bool(msg.onboard_control_sensors_health & PREARM_CHECK)
        elif kind == "GPS_RAW_INT":
            self._gps_fix = int(msg.fix_type)
        elif kind == "EKF_STATUS_REPORT":
            self._ekf_flags = int(msg.flags)
        elif kind == "COMMAND_ACK":
            self._on_ack(msg)

    def _on_heartbeat(self, msg: Any, source: tuple[int, int]) -> None:
        if msg.autopilot == _MAV.MAV_AUTOPILOT_INVALID or msg.type == _MAV.MAV_TYPE_GCS:
            return  # a ground station, a camera, a gimbal: not the vehicle
        if self._target is not None and source != self._target:
            return
        first = self._target is None
        self._target = source
        if first and self._autopilot == "auto":
            self._px4 = msg.autopilot == _px4.AUTOPILOT_PX4
        self._heartbeat = (int(msg.type), int(msg.autopilot), int(msg.base_mode),
                           int(msg.custom_mode))
        self._heartbeat_at = self.now()
        if first:
            mode = self._mode_name(self._heartbeat)
            kind = "PX4 " if self._px4 else ""
            self._say(f"{kind}vehicle {source[0]}/{source[1]} on {self.url}, mode {mode}")
            self._request_rates()
        elif self._lost:
            self._lost = False
            self._say("link back")
            self._request_rates()  # the vehicle may have restarted

    def _on_ack(self, msg: Any) -> None:
        """The oldest command of that id waiting gets the answer (acks come in order)."""
        with self._lock:
            p = next((p for p in self._pending if p.command == msg.command), None)
            if p is None:
                self._late_ack(msg)
                return
            if msg.result == IN_PROGRESS:  # keep waiting for the final word, without resending
                p.deadline = self.now() + self._ack_timeout
                p.resend_at = None
                return
            self._pending.remove(p)
            result = RESULTS.get(int(msg.result), f"result_{msg.result}")
            self._answered[p.command] = (p.name, p.label, p.quiet, self.now() + self._ack_timeout)
            if not p.quiet:
                self._acks[p.name] = result
        if p.quiet and result == "accepted":
            return
        self._say(f"{p.label} {result if result == 'accepted' else result.upper()}")

    def _expire(self, now: float) -> None:
        """Resend a command once halfway to its deadline; give up at the deadline."""
        expired: list[Pending] = []
        with self._lock:
            target = self._target
            for p in list(self._pending):
                if now >= p.deadline:
                    self._pending.remove(p)
                    expired.append(p)
                    if not p.quiet:
                        self._acks[p.name] = "timeout"
                elif p.resend_at is not None and now >= p.resend_at and target is not None:
                    p.resend_at = None
                    self._conn.mav.command_long_send(target[0], target[1], p.command, 1, *p.params)
        for p in expired:
            self._say(f"{p.label}: no acknowledgement in {self._ack_timeout:g} s")

    def _watch_link(self) -> None:
        at = self._heartbeat_at
        if not self._lost and at is not None and self.now() - at >= LINK_TIMEOUT_S:
            self._lost = True
            self._gps_fix = 0  # whatever answers next says afresh whether it is ready
            self._ekf_flags = 0
            self._say(f"link lost: no heartbeat for {LINK_TIMEOUT_S:g} s")

    # -- lockstep (--clock sim): the automaton's thread reads, no reader thread ------
    def _count_datagrams(self) -> None:
        """Lockstep: count what goes through pymavlink's UDP socket, both ways."""
        conn = self._conn
        if not isinstance(conn, mavutil.mavudp):
            self._say(f"--clock sim needs a UDP link (udpin: or udpout:), not {self.url}")
            raise SystemExit(1)
        self._counted = _link.Counted(conn)

    def lockstep_sent(self) -> int:
        """Lockstep: the datagrams sent so far."""
        return self._counted.sent if self._counted is not None else 0

    def lockstep_sync(self, t_us: int, step: dict[str, Any]) -> str | None:
        """Lockstep, before the instant at ``t_us``: read until the simulator's ``sent``
        datagrams have come, then do the reader's timed work; why not, or None."""
        want = int(step["sent"])
        end = time.monotonic() + DATAGRAM_WAIT_S
        fd = self._conn.fd
        while True:
            self._drain()
            received = self._counted.received if self._counted is not None else 0
            if received >= want:
                break
            left = end - time.monotonic()
            if left <= 0:
                return (f"{self.name}: {want - received} of the simulator's datagrams did "
                        f"not come in {DATAGRAM_WAIT_S:g} s (is {self.url} the simulator's link?)")
            with contextlib.suppress(InterruptedError):
                select.select([fd], [], [], min(left, POLL_S))
        self._timed(self.now())
        return None
