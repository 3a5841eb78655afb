"""A ``ros2`` interface as the live views show it (schemas/monitor.md, minor version 3).

Copied beside every generated Python component and imported by ``hfsmc view``: standard
library only. The monitor and ``--display`` call ``ros2_message`` about 4 times a second
with what the interface's node holds (``Ros2Node.views()``, never the instant's
snapshot), and ``scan_message`` for a LaserScan subscription's new scan (only for viewers
that asked for scans). ``Rates`` turns the counts into rates over the last seconds, and
``ros2_rows`` a ``ros2`` message into the terminal view's rows (``hfsmc_view``).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

if __package__:
    from .hfsmc_viewstate import clean
else:  # copied beside the generated component, where the modules are top level
    from hfsmc_viewstate import clean  # type: ignore[import-not-found, no-redef]

RATE_WINDOW_S = 2.0  # a rate is the messages of about the last 2 s per second
ODOMETRY = "nav_msgs/msg/Odometry"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
MAX_RAYS = 1440  # a scan with more rays is sent every k-th ray (a view needs no more)
STALE_S = 2.0  # a topic whose latest message is older is shown yellow


class Rates:
    """Per key, messages per second over about the last RATE_WINDOW_S seconds."""

    def __init__(self, window: float = RATE_WINDOW_S) -> None:
        self.window = window
        self._seen: dict[str, deque[tuple[float, int]]] = {}

    def rate(self, key: str, now: float, count: int) -> float | None:
        """The rate of ``key`` whose total is ``count`` at ``now`` (monotonic seconds);
        None until two counts some time apart are known."""
        seen = self._seen.setdefault(key, deque())
        if seen and count < seen[-1][1]:  # counted again from 0 (a new node): start over
            seen.clear()
        seen.append((now, count))
        while len(seen) > 2 and now - seen[1][0] >= self.window:
            seen.popleft()
        t0, c0 = seen[0]
        if now - t0 < 0.2:
            return None
        return round((count - c0) / (now - t0), 1)


def _num(x: object, digits: int = 3) -> float | None:
    try:
        f = float(x)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return None
    return round(f, digits) if math.isfinite(f) else None


def yaw_of(q: Any) -> float:
    """The heading (rad, about z) of a quaternion with x, y, z, w."""
    x, y, z, w = float(q.x), float(q.y), float(q.z), float(q.w)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def pose_of(msg: Any) -> dict[str, Any] | None:
    """An Odometry's pose in its frame: x, y (m), yaw (rad), speed (m/s), turn (rad/s)."""
    try:
        p, tw = msg.pose.pose, msg.twist.twist
        pose = {"x": _num(p.position.x), "y": _num(p.position.y),
                "yaw": _num(yaw_of(p.orientation), 4), "v": _num(tw.linear.x),
                "w": _num(tw.angular.z), "frame": str(msg.header.frame_id)[:64]}
    except (AttributeError, TypeError, ValueError):
        return None
    return pose if pose["x"] is not None and pose["y"] is not None else None


def ros2_message(name: str, t_ms: int, views: dict[str, Any], rates: Rates, now: float
                 ) -> dict[str, Any]:
    """A ``ros2`` message: the node and each topic's rate, age, count and matched
    endpoints; an odometry subscription's latest pose."""
    subs = []
    for n, s in views["subscriptions"].items():
        entry = {"name": n, "topic": s["topic"], "type": s["type"],
                 "rate": rates.rate(f"s/{n}", now, int(s["count"])), "age": _num(s["age"]),
                 "count": int(s["count"]), "publishers": int(s["publishers"]),
                 "dropped": int(s["dropped"])}
        if s["type"] == ODOMETRY and s["msg"] is not None:
            pose = pose_of(s["msg"])
            if pose is not None:
                entry["pose"] = pose
        subs.append(entry)
    pubs = [{"name": n, "topic": p["topic"], "type": p["type"], "count": int(p["count"]),
             "rate": rates.rate(f"p/{n}", now, int(p["count"])),
             "subscribers": int(p["subscribers"])}
            for n, p in views["publications"].items()]
    return {"type": "ros2", "t": t_ms, "name": name, "node": views["node"],
            "namespace": views["namespace"], "domain": int(views["domain"]),
            "distro": views["distro"], "subscriptions": subs, "publications": pubs}


def scans_of(views: dict[str, Any]) -> dict[str, tuple[int, Any]]:
    """The LaserScan subscriptions that have a scan: name -> (count, latest message)."""
    return {n: (int(s["count"]), s["msg"]) for n, s in views["subscriptions"].items()
            if s["type"] == LASER_SCAN and s["msg"] is not None}


def odometry_of(views: dict[str, Any]) -> Any:
    """The latest message of the interface's first odometry subscription, or None."""
    return next((s["msg"] for s in views["subscriptions"].values()
                 if s["type"] == ODOMETRY and s["msg"] is not None), None)


def _stamp(msg: Any) -> float:
    return float(msg.header.stamp.sec) + float(msg.header.stamp.nanosec) * 1e-9


def pose_at(odom: Any, scan: Any) -> dict[str, Any] | None:
    """The odometry's pose taken back (or on) to the scan's stamp with its own twist, so
    that a scan is drawn where the robot was when it was taken: turning at 1 rad/s, a scan
    50 ms older than the odometry would otherwise be drawn 3 degrees off. Stamps more than
    1 s apart (a publisher without a clock) are taken as equal."""
    pose = pose_of(odom)
    if pose is None:
        return None
    try:
        dt = _stamp(odom) - _stamp(scan)
    except (AttributeError, TypeError, ValueError):
        dt = 0.0
    if not math.isfinite(dt) or abs(dt) > 1.0:
        dt = 0.0
    yaw, v, w = pose["yaw"] or 0.0, pose["v"] or 0.0, pose["w"] or 0.0
    back = yaw - w * dt
    mid = (yaw + back) / 2
    pose.update(x=_num(pose["x"] - v * math.cos(mid) * dt),
                y=_num(pose["y"] - v * math.sin(mid) * dt), yaw=_num(back, 4))
    return pose


def scan_message(name: str, subscription: str, t_ms: int, msg: Any, odom: Any = None
                 ) -> dict[str, Any] | None:
    """A ``scan`` message: a LaserScan's ranges (m, to the mm; null where there is no
    return: out of range, inf, NaN), every k-th ray when it has more than MAX_RAYS; with
    the odometry ``odom``, the pose the scan was taken from (``pose_at``)."""
    try:
        ranges = list(msg.ranges)
        lo, hi = float(msg.range_min), float(msg.range_max)
        step = max(1, math.ceil(len(ranges) / MAX_RAYS))
        kept = [_num(r) if math.isfinite(r) and lo <= r <= hi else None
                for r in (float(x) for x in ranges[::step])]
        out = {"type": "scan", "t": t_ms, "name": name, "subscription": subscription,
               "frame": str(msg.header.frame_id)[:64], "angle_min": _num(msg.angle_min, 5),
               "angle_increment": _num(float(msg.angle_increment) * step, 6),
               "range_min": _num(lo), "range_max": _num(hi), "ranges": kept}
    except (AttributeError, TypeError, ValueError):
        return None
    pose = pose_at(odom, msg) if odom is not None else None
    if pose is not None:
        out["pose"] = pose
    return out if out["angle_min"] is not None and out["angle_increment"] is not None else None


def _rate(x: object) -> str:
    return f"{x:.1f} Hz" if isinstance(x, int | float) and not isinstance(x, bool) else "– Hz"


def ros2_rows(msg: dict[str, Any]) -> list[tuple[list[str], str]]:
    """A ``ros2`` message as the terminal view's rows: (cells, style), the node first,
    then ``<-`` per subscription (rate, age, count, matched publishers, dropped) and ``->``
    per publication (rate, count, matched subscribers). Red: a subscription that never got
    a message or has no publisher, a publication nobody subscribes to, dropped samples;
    yellow: a message older than STALE_S."""
    ns = clean(msg.get("namespace") or "/")
    node = f"{ns.rstrip('/')}/{clean(msg.get('node'))}"
    rows = [([f"ros2 {clean(msg.get('name'))}", node, f"domain {clean(msg.get('domain'))}",
              clean(msg.get("distro")), "", ""], "bold")]
    for s in msg.get("subscriptions", ()):
        age = s.get("age")
        style = ""
        if not s.get("count") or not s.get("publishers"):
            style = "red"
        elif isinstance(age, int | float) and age > STALE_S:
            style = "yellow"
        seen = f"{age:.2f} s ago" if isinstance(age, int | float) else "never"
        extra = f"  {s['dropped']} dropped" if s.get("dropped") else ""
        rows.append(([f"<- {clean(s.get('name'))}", clean(s.get("topic")), _rate(s.get("rate")),
                      seen, f"n {clean(s.get('count'))}",
                      f"{clean(s.get('publishers'))} pub{extra}"],
                     "red" if extra else style))
    for p in msg.get("publications", ()):
        rows.append(([f"-> {clean(p.get('name'))}", clean(p.get("topic")), _rate(p.get("rate")),
                      "", f"n {clean(p.get('count'))}", f"{clean(p.get('subscribers'))} sub"],
                     "" if p.get("subscribers") else "red"))
    return rows
