"""The web view's side of a ``ros2`` interface (docs/web.md, "ROS 2 topics and the map").

The monitor's ``ros2`` and ``scan`` messages (schemas/monitor.md, minor version 3) are
checked member by member here before any page sees them; the odometry's trail is kept
here, so that a late page draws the whole path; and a world file's walls and boxes
(``hfsmc view --web --world WORLD.yaml``, read by the command into plain data) are put in
the odom frame of the robot whose namespace is the interface's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

TRAIL_POINTS = 4000  # the trail keeps this many points, the oldest dropped first
TRAIL_STEP_M = 0.02  # a pose nearer than this to the trail's last point adds nothing
MAX_RAYS = 1440  # as the monitor sends at most
MAX_TOPICS = 64  # subscriptions or publications of one interface shown


def _text(x: object, limit: int = 200) -> str:
    return str(x)[:limit] if x is not None else ""


def _int(x: object) -> int:
    return x if isinstance(x, int) and not isinstance(x, bool) and x >= 0 else 0


def _float(x: object) -> float | None:
    if isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x):
        return float(x)
    return None


def _pose(p: object) -> dict[str, Any] | None:
    if not isinstance(p, dict):
        return None
    x, y = _float(p.get("x")), _float(p.get("y"))
    if x is None or y is None:
        return None
    return {"x": x, "y": y, "yaw": _float(p.get("yaw")), "v": _float(p.get("v")),
            "w": _float(p.get("w")), "frame": _text(p.get("frame"), 64)}


def ros2_record(msg: dict[str, Any]) -> dict[str, Any]:
    """A monitor ``ros2`` message as the pages get it: the known members, checked."""
    subs, pubs = msg.get("subscriptions"), msg.get("publications")
    out_subs = []
    for s in subs[:MAX_TOPICS] if isinstance(subs, list) else ():
        if not isinstance(s, dict):
            continue
        entry: dict[str, Any] = {"name": _text(s.get("name"), 80), "topic": _text(s.get("topic")),
                 "type": _text(s.get("type"), 120), "rate": _float(s.get("rate")),
                 "age": _float(s.get("age")), "count": _int(s.get("count")),
                 "publishers": _int(s.get("publishers")), "dropped": _int(s.get("dropped"))}
        pose = _pose(s.get("pose"))
        if pose is not None:
            entry["pose"] = pose
        out_subs.append(entry)
    out_pubs = [{"name": _text(p.get("name"), 80), "topic": _text(p.get("topic")),
                 "type": _text(p.get("type"), 120), "rate": _float(p.get("rate")),
                 "count": _int(p.get("count")), "subscribers": _int(p.get("subscribers"))}
                for p in (pubs[:MAX_TOPICS] if isinstance(pubs, list) else ())
                if isinstance(p, dict)]
    return {"type": "ros2", "name": _text(msg.get("name"), 80), "t": _int(msg.get("t")),
            "node": _text(msg.get("node"), 120), "namespace": _text(msg.get("namespace"), 120),
            "domain": _int(msg.get("domain")), "distro": _text(msg.get("distro"), 20),
            "subscriptions": out_subs, "publications": out_pubs}


def scan_record(msg: dict[str, Any]) -> dict[str, Any] | None:
    """A monitor ``scan`` message as the pages get it; None when it cannot be drawn."""
    ranges = msg.get("ranges")
    a0, da = _float(msg.get("angle_min")), _float(msg.get("angle_increment"))
    if not isinstance(ranges, list) or len(ranges) > MAX_RAYS or a0 is None or da is None:
        return None
    out = {"type": "scan", "name": _text(msg.get("name"), 80), "t": _int(msg.get("t")),
           "subscription": _text(msg.get("subscription"), 80),
           "frame": _text(msg.get("frame"), 64), "angle_min": a0, "angle_increment": da,
           "ranges": [_float(r) for r in ranges]}
    pose = _pose(msg.get("pose"))
    if pose is not None:
        out["pose"] = pose
    return out


def odometry(rec: dict[str, Any]) -> dict[str, Any] | None:
    """The pose of the interface's first odometry subscription that has one."""
    for s in rec["subscriptions"]:
        if "pose" in s:
            pose: dict[str, Any] = s["pose"]
            return pose
    return None


class Trail:
    """The odometry's path, a point every TRAIL_STEP_M at most, the latest TRAIL_POINTS."""

    def __init__(self) -> None:
        self.points: list[list[float]] = []

    def add(self, x: float, y: float) -> bool:
        """Whether the point was kept."""
        if self.points:
            px, py = self.points[-1]
            if math.hypot(x - px, y - py) < TRAIL_STEP_M:
                return False
        self.points.append([round(x, 3), round(y, 3)])
        if len(self.points) > TRAIL_POINTS:
            del self.points[:len(self.points) - TRAIL_POINTS]
        return True


@dataclass(frozen=True)
class WorldMap:
    """A ground world's walls, boxes and robots' starts, in the world frame (plain data,
    read from the world file by ``hfsmc view``)."""

    file: str
    walls: tuple[tuple[tuple[float, float], ...], ...]
    boxes: tuple[tuple[float, float, float, float, float], ...]  # x, y, length, width, yaw_deg
    robots: tuple[tuple[str, str, float, float, float], ...]  # name, namespace, x, y, yaw_deg


def _corners(x: float, y: float, length: float, width: float, yaw_deg: float
             ) -> list[tuple[float, float]]:
    c, s = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    return [(x + c * dx - s * dy, y + s * dx + c * dy)
            for dx, dy in ((length / 2, width / 2), (-length / 2, width / 2),
                           (-length / 2, -width / 2), (length / 2, -width / 2))]


def world_message(world: WorldMap, name: str, namespace: str) -> dict[str, Any]:
    """The world drawn in the odom frame of the interface ``name`` (namespace
    ``namespace``): the odom frame starts where the robot of that namespace starts in the
    world file, facing its ``yaw_deg`` (what ``hfsmc sim`` does), so a world point p is
    R(-yaw0)·(p - start). With no robot of that namespace, the world's first robot's start
    is taken, and ``note`` says so."""
    ns = "/" + namespace.strip("/") if namespace.strip("/") else "/"
    robot = next((r for r in world.robots if r[1] == ns), None)
    note = None
    if robot is None:
        robot = world.robots[0] if world.robots else ("robot", "/", 0.0, 0.0, 0.0)
        note = (f"no robot of namespace {ns} in {world.file}: drawn from {robot[0]}'s start "
                f"({robot[1]})")
    _, _, x0, y0, yaw0 = robot
    c, s = math.cos(math.radians(yaw0)), math.sin(math.radians(yaw0))

    def odom(p: tuple[float, float]) -> list[float]:
        dx, dy = p[0] - x0, p[1] - y0
        return [round(c * dx + s * dy, 3), round(-s * dx + c * dy, 3)]

    return {"type": "world", "name": name, "file": world.file, "robot": robot[0],
            "start": {"x": x0, "y": y0, "yaw_deg": yaw0}, "note": note,
            "walls": [[odom(p) for p in wall] for wall in world.walls],
            "boxes": [[odom(p) for p in _corners(*b)] for b in world.boxes]}
