"""The sending side of the ``mavlink`` interface (hfsmc_mavlink.py), copied beside a
component with it and mixed into its ``Vehicle``: a COMMAND_LONG waiting for its
acknowledgement (hfsmc_mavlink_reader.py matches it), a local position target, the
message rates asked of the vehicle, and the driver's lines on stderr. What a snippet
calls, and what it sends then, is hfsmc_mavlink's.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from typing import Any

from pymavlink import mavutil

try:  # beside the component, or in the hfsmc package
    from . import hfsmc_mavlink_reader as _reader
except ImportError:
    import hfsmc_mavlink_reader as _reader  # type: ignore[import-not-found, no-redef]

_MAV: Any = mavutil.mavlink

FAST_RATE_HZ = 20.0  # position, velocity, attitude (option `rate`)
SLOW_RATE_HZ = 2.0  # battery, GPS, EKF status
HOME_RATE_HZ = 1.0  # HOME_POSITION (it moves only when the autopilot sets a new home)


class Sender:
    """The sending of hfsmc_mavlink.Vehicle, which mixes it in (its attributes are the
    vehicle's: ``_conn``, ``_lock``, ``_target``, ``_pending``...)."""

    name: str
    _conn: Any
    _lock: threading.Lock
    _target: tuple[int, int] | None
    _pending: list[_reader.Pending]
    _acks: dict[str, str]
    _ack_timeout: float
    _rate: float
    _start: float
    _px4: bool
    _offboard: Any
    now: Any
    _px4_command: Any
    _send_global: Any

    def _command(self, name: str, label: str, command: int, *params: float,
                 quiet: bool = False) -> None:
        p = tuple(float(x) for x in params) + (0.0,) * (7 - len(params))
        target = self._target
        if name in ("set_mode", "land", "rtl", "takeoff"):
            self._offboard.lost = False  # the model acts on it
        if self._px4 and target is not None:
            adjusted = self._px4_command(name, command, p)
            if adjusted is None:
                return
            p = adjusted
        with self._lock:
            if target is not None:
                self._conn.mav.command_long_send(target[0], target[1], command, 0, *p)
                now = self.now()
                self._pending.append(_reader.Pending(name, label, command, p,
                                                      now + self._ack_timeout,
                                                      now + self._ack_timeout / 2, quiet))
            if not quiet:
                self._acks[name] = "pending" if target is not None else "not_sent"
        if target is None:
            self._say(f"{label}: not sent, no vehicle yet (no heartbeat)")

    def _send_setpoint(self, kind: str, *args: Any) -> None:
        """The PX4 stream's resend of a target (Offboard.send)."""
        if kind == "global":
            self._send_global(*args)
        else:
            self._send_target(*args)

    def _send_target(self, frame: int, mask: int, pos: tuple[float, float, float],
                     vel: tuple[float, float, float], yaw_rate: float, yaw: float = 0.0) -> None:
        target = self._target
        if target is None:
            return  # a target is a stream, repeated each tick: nothing to say about one
        boot_ms = int((self.now() - self._start) * 1000) & 0xFFFFFFFF
        with self._lock:
            self._conn.mav.set_position_target_local_ned_send(
                boot_ms, target[0], target[1], frame, mask,
                float(pos[0]), float(pos[1]), float(pos[2]),
                float(vel[0]), float(vel[1]), float(vel[2]),
                0.0, 0.0, 0.0, float(yaw), float(yaw_rate))

    def _request_rates(self) -> None:
        fast = 1e6 / max(self._rate, 0.1)
        slow = 1e6 / SLOW_RATE_HZ
        for message, interval in (("LOCAL_POSITION_NED", fast), ("GLOBAL_POSITION_INT", fast),
                                  ("ATTITUDE", fast), ("SYS_STATUS", slow),
                                  ("GPS_RAW_INT", slow), ("BATTERY_STATUS", slow),
                                  ("HOME_POSITION", 1e6 / HOME_RATE_HZ),
                                  *(() if self._px4 else (("EKF_STATUS_REPORT", slow),))):
            self._command("set_message_interval", f"set_message_interval {message}",
                          _MAV.MAV_CMD_SET_MESSAGE_INTERVAL,
                          getattr(_MAV, f"MAVLINK_MSG_ID_{message}"), round(interval),
                          quiet=True)

    def _say(self, text: str) -> None:
        with contextlib.suppress(ValueError, OSError):  # stderr closed at exit: nothing to tell
            sys.stderr.write(f"{self.name}: {text}\n")
            sys.stderr.flush()
