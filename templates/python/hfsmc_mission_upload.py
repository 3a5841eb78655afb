"""Missions and the geofence of the ``mavlink`` interface (docs/interfaces.md, "Missions"):
copied beside a component with hfsmc_mavlink.py, the same on ArduPilot and PX4.

- ``upload_mission(points, end)``: latitude, longitude, altitude above home and an
  optional heading per point, sent with the MISSION_ITEM_INT protocol (MISSION_COUNT, the
  vehicle asks for each item with MISSION_REQUEST_INT, MISSION_ACK ends it). A message
  the vehicle does not answer within ``RETRY_S`` is sent again, ``RETRIES`` times, then
  the upload has failed (``timeout``). ArduPilot's item 0 is home; ArduPilot Copter
  ignores a waypoint's yaw, so a heading is a CONDITION_YAW item before the waypoint;
  PX4 takes it in the waypoint (param 4). ``end``: ``hold`` (stay at the last point),
  ``land`` (NAV_LAND at the last point) or ``rtl`` (NAV_RETURN_TO_LAUNCH).
- ``mission_progress()``: (the index of the point being flown to, the number of points),
  from MISSION_CURRENT and MISSION_ITEM_REACHED; (n, n) once the last point is reached.
- ``upload_fence(vertices)``: one inclusion polygon (MAV_MISSION_TYPE_FENCE);
  ``enable_fence(on)``: ArduPilot's DO_FENCE_ENABLE; on PX4 a fence is on once uploaded
  (GF_ACTION says what a breach does), so nothing is sent. ``fence_breached()``:
  FENCE_STATUS.breach_status.
- Each upload's outcome is ``last_ack("upload_mission")`` / ``last_ack("upload_fence")``,
  in last_ack's words (MAV_MISSION_RESULT's name said on stderr).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

try:  # beside the component, or in the hfsmc package
    from . import hfsmc_mission as _mission
except ImportError:
    import hfsmc_mission as _mission  # type: ignore[import-not-found, no-redef]

MISSION, FENCE = 0, 1  # MAV_MISSION_TYPE
RETRY_S = 2.0  # a message the vehicle does not answer is sent again after this
RETRIES = 5  # ... this many times, then the upload has failed (timeout)
MAX_POINTS = 10000  # more is a bug in the model, refused before anything is sent
AUTOPILOT_PX4 = 12
ENDS = ("hold", "land", "rtl")
NAV_WAYPOINT, NAV_RTL, NAV_LAND, CONDITION_YAW = 16, 20, 21, 115
FENCE_POLYGON = 5001  # MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
FRAME_GLOBAL, FRAME_MISSION, FRAME_RELATIVE_INT = 0, 2, 6
MISSION_STATE_COMPLETE = 5
RESULTS = ["accepted", "error", "unsupported_frame", "unsupported", "no_space", "invalid",
           "invalid_param1", "invalid_param2", "invalid_param3", "invalid_param4",
           "invalid_param5_x", "invalid_param6_y", "invalid_param7", "invalid_sequence",
           "denied", "operation_cancelled"]  # MAV_MISSION_RESULT
# ... as last_ack says them (its outcomes are the same for every command)
OUTCOMES = {"accepted": "accepted", "denied": "denied", "unsupported": "unsupported",
            "unsupported_frame": "unsupported", "operation_cancelled": "cancelled"}
NAMES = {MISSION: "upload_mission", FENCE: "upload_fence"}

# an item: (frame, command, p1, p2, p3, p4, x, y, z); user: the point's index or -1
Item = tuple[int, int, float, float, float, float, int, int, float]


def mission_items(vehicle: str, points: Any, end: str, px4: bool,
                  home: tuple[float, float, float]) -> tuple[list[Item], list[int]]:
    """The items of a mission and, for each, the index of the point it flies to (-1: none);
    ValueError naming the point at fault."""
    if end not in ENDS:
        raise ValueError(f"{vehicle}: upload_mission end `{end}` is not hold, land or rtl")
    pts = _sequence(vehicle, "upload_mission", points)
    items: list[Item] = []
    users: list[int] = []
    if not px4:  # ArduPilot's item 0 is home (it writes its own there)
        ok = not math.isnan(home[0])
        items.append((FRAME_GLOBAL, NAV_WAYPOINT, 0.0, 0.0, 0.0, 0.0,
                      round(home[0] * 1e7) if ok else 0, round(home[1] * 1e7) if ok else 0,
                      home[2] if ok else 0.0))
        users.append(-1)
    last = (0.0, 0.0)
    for i, p in enumerate(pts):
        if not isinstance(p, (list, tuple)) or len(p) not in (3, 4):
            raise ValueError(f"{vehicle}: upload_mission point {i} is (lat, lon, alt) or "
                             f"(lat, lon, alt, heading), not {p!r}")
        try:
            la, lo, al = _mission.checked_location(vehicle, *p[:3])
            h = _mission.checked_heading(vehicle, p[3] if len(p) == 4 else None)
        except ValueError as e:
            raise ValueError(f"{e} (upload_mission point {i})") from None
        deg = math.nan if h is None else math.degrees(h) % 360.0
        if h is not None and not px4:
            items.append((FRAME_MISSION, CONDITION_YAW, deg, 0.0, 0.0, 0.0, 0, 0, 0.0))
            users.append(-1)
        items.append((FRAME_RELATIVE_INT, NAV_WAYPOINT, 0.0, 0.0, 0.0,
                      deg if px4 else 0.0, round(la * 1e7), round(lo * 1e7), al))
        users.append(i)
        last = (la, lo)
    if end == "land" and pts:
        items.append((FRAME_RELATIVE_INT, NAV_LAND, 0.0, 0.0, 0.0, math.nan,
                      round(last[0] * 1e7), round(last[1] * 1e7), 0.0))
        users.append(-1)
    elif end == "rtl":
        items.append((FRAME_MISSION, NAV_RTL, 0.0, 0.0, 0.0, 0.0, 0, 0, 0.0))
        users.append(-1)
    return items, users


def plain(points: Any) -> list[list[float | None]]:
    """Points as recorded (checked already): lists of floats, a heading None when none."""
    return [[None if x is None else float(x) for x in p] for p in points]


def fence_items(vehicle: str, vertices: Any) -> list[Item]:
    """One inclusion polygon's items; an empty list clears the fence."""
    pts = _sequence(vehicle, "upload_fence", vertices)
    if 0 < len(pts) < 3:
        raise ValueError(f"{vehicle}: upload_fence needs at least 3 vertices, not {len(pts)}")
    items: list[Item] = []
    for i, p in enumerate(pts):
        if not isinstance(p, (list, tuple)) or len(p) != 2:
            raise ValueError(f"{vehicle}: upload_fence vertex {i} is (lat, lon), not {p!r}")
        try:
            la, lo, _ = _mission.checked_location(vehicle, p[0], p[1], 0.0)
        except ValueError as e:
            raise ValueError(f"{e} (upload_fence vertex {i})") from None
        items.append((FRAME_RELATIVE_INT, FENCE_POLYGON, float(len(pts)), 0.0, 0.0, 0.0,
                      round(la * 1e7), round(lo * 1e7), 0.0))
    return items


def _sequence(vehicle: str, call: str, points: Any) -> list[Any]:
    if isinstance(points, (str, bytes)) or not hasattr(points, "__len__"):
        raise ValueError(f"{vehicle}: {call} takes a list of points, not {points!r}")
    pts = list(points)
    if len(pts) > MAX_POINTS:
        raise ValueError(f"{vehicle}: {call}: {len(pts)} points, more than {MAX_POINTS}")
    return pts


def inside(point: tuple[float, float], polygon: list[tuple[float, float]]) -> bool:
    """A (lat, lon) inside a polygon of (lat, lon) (ray casting on a local flat earth)."""
    xy = [_mission.offset(point[0], point[1], la, lo) for la, lo in polygon]
    result = False
    for i in range(len(xy)):
        (an, ae), (bn, be) = xy[i], xy[(i + 1) % len(xy)]
        if (ae > 0) != (be > 0) and an - ae * (bn - an) / (be - ae) > 0:
            result = not result
    return result


@dataclass(slots=True)
class Upload:
    """One upload in flight."""

    kind: int
    items: list[Item]
    users: list[int]
    sent_at: float
    last: int = -1  # the item sent last; -1: MISSION_COUNT
    retries: int = 0
    polygon: list[tuple[float, float]] = field(default_factory=list)


class UploadVehicle:
    """The live side, mixed into hfsmc_mavlink.Vehicle (its attributes are the vehicle's)."""

    _conn: Any
    _lock: Any
    _target: tuple[int, int] | None
    _acks: dict[str, str]
    _px4: bool
    now: Any
    _say: Any
    _command: Any

    def _upload_init(self) -> None:
        self._uploads: dict[int, Upload] = {}
        self._users: list[int] = []  # the mission uploaded: each item's point (-1: none)
        self._progress = (0, 0)
        self._breached = False
        self._fence: list[tuple[float, float]] = []  # the fence the vehicle accepted
        self._fence_on = False

    def _upload(self, kind: int, items: list[Item], users: list[int]) -> None:
        name = NAMES[kind]
        if self._target is None:
            self._acks[name] = "not_sent"
            self._say(f"{name}: not sent, no vehicle yet (no heartbeat)")
            return
        up = Upload(kind, items, users, self.now())
        if kind == FENCE:
            up.polygon = [(x / 1e7, y / 1e7) for _, _, _, _, _, _, x, y, _ in items]
        if kind in self._uploads:
            self._say(f"{name}: a new upload replaces the one under way")
        self._uploads[kind] = up
        self._acks[name] = "pending"
        self._say(f"{name}: {len(items)} items")
        self._send_count(up)

    def _send_count(self, up: Upload) -> None:
        target = self._target
        if target is not None:
            with self._lock:
                self._conn.mav.mission_count_send(target[0], target[1], len(up.items), up.kind)

    def _send_item(self, up: Upload, seq: int) -> None:
        target = self._target
        if target is None:
            return
        frame, command, p1, p2, p3, p4, x, y, z = up.items[seq]
        with self._lock:
            self._conn.mav.mission_item_int_send(target[0], target[1], seq, frame, command, 0, 1,
                                                 p1, p2, p3, p4, x, y, z, up.kind)

    def _fence_enable(self, on: bool) -> None:
        if not self._px4:
            self._fence_on = on
            self._command("enable_fence", f"enable_fence {int(on)}", 207, 1.0 if on else 0.0)
            return
        if on:
            ok = self._acks.get("upload_fence") == "accepted" and bool(self._fence)
            self._acks["enable_fence"] = "accepted" if ok else "failed"
            self._fence_on = ok
            self._say("enable_fence: PX4's fence is on once uploaded (GF_ACTION says what a "
                      "breach does): nothing sent" if ok else
                      "enable_fence FAILED: no fence uploaded to PX4")
        else:
            self._acks["enable_fence"] = "unsupported"
            self._say("enable_fence 0 UNSUPPORTED: PX4 cannot turn its fence off; upload an "
                      "empty fence (upload_fence([])) to remove it")

    def _upload_message(self, kind: str, msg: Any) -> bool:
        """The mission protocol's messages and FENCE_STATUS; True when it was one."""
        if kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
            up = self._uploads.get(int(getattr(msg, "mission_type", 0)))
            if up is not None and 0 <= msg.seq < len(up.items):
                up.last, up.retries, up.sent_at = int(msg.seq), 0, self.now()
                self._send_item(up, up.last)
        elif kind == "MISSION_ACK":
            self._upload_done(int(getattr(msg, "mission_type", 0)), int(msg.type))
        elif kind == "MISSION_CURRENT":
            self._on_current(int(msg.seq), int(getattr(msg, "total", 0)),
                             int(getattr(msg, "mission_state", 0)))
        elif kind == "MISSION_ITEM_REACHED":
            users = self._users
            if 0 <= msg.seq < len(users) and users[msg.seq] >= 0:
                self._progress = (max(self._progress[0], users[msg.seq] + 1), self._progress[1])
        elif kind == "FENCE_STATUS":
            breached = bool(msg.breach_status)
            if breached and not self._breached:
                self._say("fence breached")
            self._breached = breached
        else:
            return False
        return True

    def _on_current(self, seq: int, total: int, state: int) -> None:
        users = self._users
        if not users:  # a mission this driver did not upload: the vehicle's numbering
            offset = 0 if self._px4 else 1
            self._progress = (max(0, seq - offset), max(0, total - offset))
            return
        points = sum(1 for u in users if u >= 0)
        if state == MISSION_STATE_COMPLETE:
            self._progress = (points, points)
            return
        ahead = [u for u in users[max(0, seq):] if u >= 0]
        self._progress = (ahead[0] if ahead else points, points)

    def _upload_done(self, kind: int, result: int) -> None:
        up = self._uploads.pop(kind, None)
        if up is None:
            return
        word = RESULTS[result] if 0 <= result < len(RESULTS) else f"result_{result}"
        name = NAMES[kind]
        self._acks[name] = OUTCOMES.get(word, "failed")
        if word == "accepted":
            self._say(f"{name} accepted ({len(up.items)} items)")
            if kind == MISSION:
                self._users = up.users
                self._progress = (0, sum(1 for u in up.users if u >= 0))
            else:
                self._fence = up.polygon
        else:
            self._say(f"{name} {word.upper()}" + (f" (at item {up.last})" if up.last >= 0
                                                   else ""))

    def _upload_tick(self, now: float) -> None:
        """Resend what the vehicle did not answer; give up after RETRIES."""
        for kind, up in list(self._uploads.items()):
            if now - up.sent_at < RETRY_S:
                continue
            if up.retries >= RETRIES:
                del self._uploads[kind]
                self._acks[NAMES[kind]] = "timeout"
                self._say(f"{NAMES[kind]}: no answer after {RETRIES} resends")
                continue
            up.retries += 1
            up.sent_at = now
            if up.last < 0:
                self._send_count(up)
            else:
                self._send_item(up, up.last)

    def _fence_check(self, lat: float, lon: float) -> None:
        """A goto_location outside the fence the vehicle holds: said, as the autopilot
        will answer it (ArduPilot ignores the target, PX4 flies it and breaches)."""
        if len(self._fence) >= 3 and (self._fence_on or self._px4) and \
                not inside((lat, lon), self._fence):
            what = ("PX4 will fly it and breach the fence" if self._px4 else
                    "ArduPilot ignores it (the vehicle keeps its previous target)")
            self._say(f"goto_location {lat:.7f}, {lon:.7f} is outside the fence: {what}")

    def _upload_snapshot(self) -> dict[str, Any]:
        return {"mission": self._progress, "fence_breached": self._breached}
