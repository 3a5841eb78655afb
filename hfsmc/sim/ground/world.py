"""A ground robot's world: walls, boxes, robots and their sensors (docs/worlds.md, "Ground robots").

Metres and the world frame of REP 103 (x forward, y left, z up); angles in degrees in the
file, radians inside. Every key has a default but ``walls`` or ``boxes`` give the robot
something to meet::

    name: room
    seed: 3                        # same seed, same laser noise, same run
    walls: [[[0, 0], [8, 0], [8, 6], [0, 6], [0, 0]]]   # polylines
    boxes: [{x: 3, y: 2, length: 0.6, width: 0.4, yaw_deg: 30}]
    robots: [{name: tb2, x: 1, y: 1, yaw_deg: 0}]
    laser: {rays: 360, range_min: 0.12, range_max: 3.5, rate: 10, noise: 0.01, x: 0.0}
    base: {radius: 0.176, max_speed: 0.7, max_turn: 3.14, accel: 1.0, turn_accel: 3.0,
           cmd_timeout: 0.5}
    odom: {rate: 50}
    coverage: {cell: 0.25}

A world that cannot be used raises ``WorldError`` as ``file:line:col: message``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq

from hfsmc.sim.world import WorldError

Point = tuple[float, float]
NAMESPACE = re.compile(r"^(/[A-Za-z][A-Za-z0-9_]*)*/?$")
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")


@dataclass(frozen=True, slots=True)
class Box:
    x: float
    y: float
    length: float = 0.5
    width: float = 0.5
    yaw_deg: float = 0.0


@dataclass(frozen=True, slots=True)
class RobotStart:
    name: str = "robot"
    namespace: str = ""  # "" until resolved: "/" for a lone robot, else "/NAME"
    x: float = 0.0
    y: float = 0.0
    yaw_deg: float = 0.0


@dataclass(frozen=True, slots=True)
class Laser:
    rays: int = 360
    range_min: float = 0.12
    range_max: float = 3.5
    rate: float = 10.0  # scans per second
    noise: float = 0.01  # standard deviation of each range, metres
    x: float = 0.0  # where it sits ahead of the base's centre, metres


@dataclass(frozen=True, slots=True)
class Base:
    radius: float = 0.176  # Kobuki: 352 mm across
    max_speed: float = 0.7  # m/s
    max_turn: float = 3.14  # rad/s
    accel: float = 1.0  # m/s²
    turn_accel: float = 3.0  # rad/s²
    cmd_timeout: float = 0.5  # s without cmd_vel before the base stops


@dataclass(frozen=True, slots=True)
class Odom:
    rate: float = 50.0


@dataclass(frozen=True, slots=True)
class Coverage:
    cell: float = 0.25  # side of a coverage cell, metres


@dataclass(frozen=True, slots=True)
class GroundWorld:
    name: str = "world"
    seed: int = 1
    walls: tuple[tuple[Point, ...], ...] = ()
    boxes: tuple[Box, ...] = ()
    robots: tuple[RobotStart, ...] = (RobotStart(namespace="/"),)
    laser: Laser = field(default_factory=Laser)
    base: Base = field(default_factory=Base)
    odom: Odom = field(default_factory=Odom)
    coverage: Coverage = field(default_factory=Coverage)
    file: str = "<world>"

    def bounds(self) -> tuple[float, float, float, float]:
        """min x, min y, max x, max y of the walls and boxes (the robots' starts if none)."""
        xs = [p[0] for w in self.walls for p in w] + [b.x for b in self.boxes]
        ys = [p[1] for w in self.walls for p in w] + [b.y for b in self.boxes]
        xs += [r.x for r in self.robots]
        ys += [r.y for r in self.robots]
        return min(xs), min(ys), max(xs), max(ys)


class _Reader:
    """Reads the round-trip tree, so that every error says file:line:col."""

    def __init__(self, file: str) -> None:
        self.file = file

    def fail(self, node: Any, key: Any, message: str) -> WorldError:
        line, col = 0, 0
        if isinstance(node, CommentedMap) and key in node:
            line, col = node.lc.value(key)
        elif isinstance(node, CommentedSeq) and isinstance(key, int) and key < len(node):
            line, col = node.lc.item(key)
        elif hasattr(node, "lc"):
            line, col = node.lc.line, node.lc.col
        return WorldError(f"{self.file}:{line + 1}:{col + 1}: {message}")

    def number(self, node: Any, key: Any, low: float = -math.inf, high: float = math.inf,
               whole: bool = False) -> float:
        v = node[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or (whole and not isinstance(v, int)):
            raise self.fail(node, key, f"{key}: expected {'a whole number' if whole else 'a number'}, "
                                       f"not {v!r}")
        if not low <= v <= high:
            bound = f"at least {low:g}" if high == math.inf else f"between {low:g} and {high:g}"
            raise self.fail(node, key, f"{key}: must be {bound}, not {v:g}")
        return v

    def point(self, seq: Any, i: int) -> Point:
        p = seq[i]
        if (not isinstance(p, list) or len(p) != 2
                or not all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in p)):
            raise self.fail(seq, i, f"a point is [x, y] in metres, not {p!r}")
        return float(p[0]), float(p[1])

    def section(self, cls: type, node: Any, key: str,
                limits: dict[str, tuple[float, float]] | None = None) -> Any:
        data = node.get(key) if isinstance(node, dict) else None
        if data is None:
            return cls()
        if not isinstance(data, CommentedMap):
            raise self.fail(node, key, f"{key}: expected a mapping")
        known = {f.name: f for f in fields(cls)}
        values: dict[str, Any] = {}
        for k in data:
            if k not in known:
                raise self.fail(data, k, f"unknown key `{k}` in {key} (keys: {', '.join(known)})")
            kind = known[k].type
            if kind == "str":
                if not isinstance(data[k], str):
                    raise self.fail(data, k, f"{k}: expected a string")
                values[k] = data[k]
            else:
                low, high = (limits or {}).get(k, (-math.inf, math.inf))
                values[k] = self.number(data, k, low, high, whole=kind == "int")
                if kind == "float":
                    values[k] = float(values[k])
        try:
            return cls(**values)
        except TypeError:
            need = [f.name for f in fields(cls) if f.name not in values]
            raise self.fail(node, key, f"{key} needs {', '.join(need)}") from None


POSITIVE = (1e-6, math.inf)


def parse_ground_world(data: Any, file: str = "<world>") -> GroundWorld:
    """A GroundWorld from the round-trip tree of a world file."""
    r = _Reader(file)
    if data is None:
        data = CommentedMap()
    if not isinstance(data, CommentedMap):
        raise WorldError(f"{file}:1:1: a world is a mapping")
    known = {f.name for f in fields(GroundWorld)} - {"file"}
    for k in data:
        if k not in known:
            raise r.fail(data, k, f"unknown key `{k}` (keys: {', '.join(sorted(known))})")
    seed = int(r.number(data, "seed", 0, 2**63 - 1, whole=True)) if "seed" in data else 1
    walls = []
    for i, w in enumerate(data.get("walls") or ()):
        if not isinstance(w, CommentedSeq) or len(w) < 2:
            raise r.fail(data["walls"], i, "a wall is a list of at least two [x, y] points")
        walls.append(tuple(r.point(w, j) for j in range(len(w))))
    boxes = [_box(r, data["boxes"], i) for i in range(len(data.get("boxes") or ()))]
    robots = _robots(r, data)
    world = GroundWorld(
        name=str(data.get("name", Path(file).stem)), seed=seed, walls=tuple(walls),
        boxes=tuple(boxes), robots=robots,
        laser=r.section(Laser, data, "laser", {
            "rays": (8, 4096), "range_min": (0.0, 100.0), "range_max": (0.1, 100.0),
            "rate": (0.5, 100.0), "noise": (0.0, 1.0), "x": (-1.0, 1.0)}),
        base=r.section(Base, data, "base", {
            "radius": (0.02, 2.0), "max_speed": POSITIVE, "max_turn": POSITIVE,
            "accel": POSITIVE, "turn_accel": POSITIVE, "cmd_timeout": (0.05, 10.0)}),
        odom=r.section(Odom, data, "odom", {"rate": (1.0, 200.0)}),
        coverage=r.section(Coverage, data, "coverage", {"cell": (0.05, 5.0)}),
        file=file)
    if world.laser.range_min >= world.laser.range_max:
        raise r.fail(data["laser"], "range_min", "laser.range_min must be below range_max")
    return world


def _box(r: _Reader, seq: Any, i: int) -> Box:
    b = seq[i]
    if not isinstance(b, CommentedMap):
        raise r.fail(seq, i, "a box is a mapping {x, y, length, width, yaw_deg}")
    for k in ("x", "y"):
        if k not in b:
            raise r.fail(seq, i, f"a box needs `{k}`")
    box: Box = r.section(Box, _holder("box", b, seq, i), "box",
                         {"length": POSITIVE, "width": POSITIVE})
    return box


def _robots(r: _Reader, data: Any) -> tuple[RobotStart, ...]:
    seq = data.get("robots")
    if seq is None:
        return (RobotStart(namespace="/"),)
    if not isinstance(seq, CommentedSeq) or not seq:
        raise r.fail(data, "robots", "robots: a list of at least one robot")
    out: list[RobotStart] = []
    for i, item in enumerate(seq):
        if not isinstance(item, CommentedMap):
            raise r.fail(seq, i, "a robot is a mapping {name, namespace, x, y, yaw_deg}")
        robot = r.section(RobotStart, _holder("robot", item, seq, i), "robot")
        if not NAME.match(robot.name):
            raise r.fail(item, "name", f"a robot's name is a ROS name ([A-Za-z][A-Za-z0-9_]*), "
                                       f"not {robot.name!r}")
        ns = robot.namespace or ("/" if len(seq) == 1 else f"/{robot.name}")
        if not NAMESPACE.match(ns) or not ns.startswith("/"):
            raise r.fail(item, "namespace", f"a namespace is absolute, like /tb2, not {ns!r}")
        ns = ns.rstrip("/") or "/"
        if any(o.name == robot.name or o.namespace == ns for o in out):
            raise r.fail(seq, i, f"two robots named {robot.name!r} or in namespace {ns}")
        out.append(RobotStart(robot.name, ns, robot.x, robot.y, robot.yaw_deg))
    return tuple(out)


def _holder(key: str, item: Any, seq: Any, i: int) -> CommentedMap:
    """A one-key mapping around a list's item, so that ``section`` reads it with its position."""
    holder = CommentedMap()
    holder[key] = item
    line, col = seq.lc.item(i)
    holder.lc.data = {key: [line, col, line, col]}
    return holder


def load_ground_world(path: str | Path) -> GroundWorld:
    """Read a ground world file."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise WorldError(f"{path}: cannot read the world: {e}") from None
    try:
        data = YAML(typ="rt").load(text)
    except Exception as e:  # ruamel's errors carry their own position
        raise WorldError(f"{path}: {e}") from None
    return parse_ground_world(data, str(path))
