"""The simulator's world: ground, road, victims and moving coloured objects (docs/worlds.md).

Coordinates are local NED metres from the home point (the take-off point):
``north``, ``east``, and ``down`` (negative above the ground). A world file is
YAML; every key is optional and has a default, so ``{}`` is a valid world::

    name: follow_colors
    seed: 7                       # same seed, same flight (textures, noise)
    home: {lat: -35.363261, lon: 149.165230, alt: 584.0}
    ground: {size: 160, color: [70, 130, 60], texture: 0.25}
    road: {width: 5, color: [85, 85, 85], points: [[0, 0], [40, 0], [70, 25]]}
    accident: {north: 70, east: 25, radius: 12}
    victims: [{north: 64, east: 30}, {north: 75, east: 18}]
    objects:
      - {name: green, color: [0, 200, 0], radius: 1.2, speed: 0.8,
         path: [[8, 0], [30, 0]], start: 0, loop: false}
    camera: {width: 320, height: 240, hfov_deg: 80, fps: 15}
    vehicle: {max_speed: 5, max_accel: 2.5, max_climb: 2, battery_wh: 60, hover_w: 180}

Colours are RGB. An object moves along its path (``[north, east]`` points)
at ``speed`` m/s from ``start`` seconds after the simulator starts; at the end
it stops, or with ``loop: true`` goes back along the path and again.

Unknown keys, wrong types and values out of range raise ``WorldError`` naming
the file and the key. ``docs/worlds.md`` describes every key and the camera.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML

Point = tuple[float, float]  # north, east (m)
RGB = tuple[int, int, int]


class WorldError(Exception):
    """A world file that cannot be used: the message names the file and the key."""


@dataclass(frozen=True, slots=True)
class Home:
    lat: float = -35.363261
    lon: float = 149.165230
    alt: float = 584.0


@dataclass(frozen=True, slots=True)
class Ground:
    size: float = 160.0  # metres, a square centred on home
    color: RGB = (70, 130, 60)
    texture: float = 0.25  # 0: flat colour; 1: strong grass-like noise


@dataclass(frozen=True, slots=True)
class Road:
    width: float = 5.0
    color: RGB = (85, 85, 85)
    points: tuple[Point, ...] = ()


@dataclass(frozen=True, slots=True)
class Area:
    north: float
    east: float
    radius: float


@dataclass(frozen=True, slots=True)
class Victim:
    north: float
    east: float
    radius: float = 0.6
    color: RGB = (230, 200, 40)


@dataclass(frozen=True, slots=True)
class MovingObject:
    name: str
    color: RGB
    radius: float = 1.2
    speed: float = 0.8
    path: tuple[Point, ...] = ()
    start: float = 0.0
    loop: bool = False

    def position(self, t: float) -> Point:
        """Where the object is ``t`` seconds after the simulator started."""
        if not self.path:
            return (0.0, 0.0)
        if len(self.path) == 1:
            return self.path[0]
        legs = list(zip(self.path, self.path[1:], strict=False))
        lengths = [math.dist(a, b) for a, b in legs]
        total = sum(lengths)
        s = max(t - self.start, 0.0) * self.speed
        if total <= 0:
            return self.path[0]
        if self.loop:
            s %= 2 * total
            if s > total:
                s = 2 * total - s
        s = min(s, total)
        for (a, b), n in zip(legs, lengths, strict=False):
            if s <= n and n > 0:
                f = s / n
                return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))
            s -= n
        return self.path[-1]


@dataclass(frozen=True, slots=True)
class Camera:
    width: int = 320
    height: int = 240
    hfov_deg: float = 80.0
    fps: float = 15.0


@dataclass(frozen=True, slots=True)
class Vehicle:
    max_speed: float = 5.0  # m/s horizontal
    max_accel: float = 2.5  # m/s²
    max_climb: float = 2.0  # m/s vertical
    battery_wh: float = 60.0
    hover_w: float = 180.0  # power drawn in flight


@dataclass(frozen=True, slots=True)
class World:
    name: str = "world"
    seed: int = 1
    home: Home = field(default_factory=Home)
    ground: Ground = field(default_factory=Ground)
    road: Road = field(default_factory=Road)
    accident: Area | None = None
    victims: tuple[Victim, ...] = ()
    objects: tuple[MovingObject, ...] = ()
    camera: Camera = field(default_factory=Camera)
    vehicle: Vehicle = field(default_factory=Vehicle)
    file: str = "<default>"


WORLD_CLOCKS = ("start", "armed", "takeoff")
TAKEOFF_HEIGHT = 0.3  # m above the ground: the vehicle has left it


class WorldClock:
    """When the world's time (its objects' motion) starts: when the simulator starts
    (``start``), or when the vehicle first arms (``armed``) or first leaves the ground
    (``takeoff``); until then the world's time is 0 and every object waits."""

    def __init__(self, start: str = "start") -> None:
        if start not in WORLD_CLOCKS:
            raise ValueError(f"world clock {start!r}: expected one of {', '.join(WORLD_CLOCKS)}")
        self.start = start
        self.zero: float | None = 0.0 if start == "start" else None

    def update(self, t: float, armed: bool, height: float) -> bool:
        """Note the vehicle's state at ``t`` (seconds on the caller's clock); True when
        this starts the world's clock."""
        if self.zero is not None:
            return False
        if armed and (self.start == "armed" or height > TAKEOFF_HEIGHT):
            self.zero = t
            return True
        return False

    def time(self, t: float) -> float:
        """The world's time at ``t`` on the caller's clock."""
        return 0.0 if self.zero is None else max(0.0, t - self.zero)


def _rgb(v: Any, where: str) -> RGB:
    if (not isinstance(v, (list, tuple)) or len(v) != 3
            or not all(isinstance(c, int) and 0 <= c <= 255 for c in v)):
        raise WorldError(f"{where}: a colour is [R, G, B] with 0..255 each, not {v!r}")
    return (v[0], v[1], v[2])


def _name(v: Any, where: str) -> str:
    if not isinstance(v, (str, int)) or isinstance(v, bool) or not str(v):
        raise WorldError(f"{where}: a name is a non-empty string, not {v!r}")
    return str(v)


def _points(v: Any, where: str) -> tuple[Point, ...]:
    if not isinstance(v, (list, tuple)):
        raise WorldError(f"{where}: a path is a list of [north, east] points")
    out = []
    for p in v:
        if (not isinstance(p, (list, tuple)) or len(p) != 2
                or not all(isinstance(c, (int, float)) for c in p)):
            raise WorldError(f"{where}: a point is [north, east] in metres, not {p!r}")
        out.append((float(p[0]), float(p[1])))
    return tuple(out)


def _value(v: Any, kind: Any, where: str) -> Any:
    """A plain value checked against its field's type (annotations are strings here)."""
    if kind in ("float", float) and isinstance(v, (int, float)) and not isinstance(v, bool):
        return float(v)
    if kind in ("int", int) and isinstance(v, int) and not isinstance(v, bool):
        return v
    if kind in ("bool", bool) and isinstance(v, bool):
        return v
    if kind in ("str", str) and isinstance(v, str):
        return v
    names = {"float": "a number", "int": "a whole number", "bool": "true or false",
             "str": "a string"}
    raise WorldError(f"{where}: expected {names.get(str(kind), str(kind))}, not {v!r}")


def _section(cls: type, data: Any, where: str, converters: dict[str, Any] | None = None) -> Any:
    if data is None:
        return cls()
    if not isinstance(data, dict):
        raise WorldError(f"{where}: expected a mapping")
    fields_ = {f.name: f for f in dataclasses.fields(cls)}
    known = set(fields_)
    unknown = sorted(set(data) - known)
    if unknown:
        raise WorldError(f"{where}: unknown key `{unknown[0]}` (keys: {', '.join(sorted(known))})")
    values = {}
    for k, v in data.items():
        conv = (converters or {}).get(k)
        values[k] = conv(v, f"{where}.{k}") if conv is not None else \
            _value(v, fields_[k].type, f"{where}.{k}")
    try:
        return cls(**values)
    except TypeError as e:
        raise WorldError(f"{where}: {e}") from None


def _at_least(where: str, value: float, low: float, high: float = math.inf) -> None:
    if not low <= value <= high:
        bound = f"at least {low:g}" if high == math.inf else f"between {low:g} and {high:g}"
        raise WorldError(f"{where}: must be {bound}, not {value:g}")


def _check(w: World) -> None:
    """Values the simulator cannot use, named by file and key."""
    f = w.file
    _at_least(f"{f}: ground.size", w.ground.size, 1.0)
    _at_least(f"{f}: ground.texture", w.ground.texture, 0.0, 1.0)
    _at_least(f"{f}: road.width", w.road.width, 0.0)
    if w.accident is not None:
        _at_least(f"{f}: accident.radius", w.accident.radius, 0.0)
    for i, v in enumerate(w.victims):
        _at_least(f"{f}: victims[{i}].radius", v.radius, 0.05)
    for i, o in enumerate(w.objects):
        _at_least(f"{f}: objects[{i}].radius", o.radius, 0.05)
        _at_least(f"{f}: objects[{i}].speed", o.speed, 0.0)
        _at_least(f"{f}: objects[{i}].start", o.start, 0.0)
        if not o.path:
            raise WorldError(f"{f}: objects[{i}].path: an object needs at least one point")
    _at_least(f"{f}: camera.width", w.camera.width, 16, 4096)
    _at_least(f"{f}: camera.height", w.camera.height, 16, 4096)
    _at_least(f"{f}: camera.hfov_deg", w.camera.hfov_deg, 1.0, 170.0)
    _at_least(f"{f}: camera.fps", w.camera.fps, 0.5, 120.0)
    for name in ("max_speed", "max_accel", "max_climb", "battery_wh"):
        _at_least(f"{f}: vehicle.{name}", getattr(w.vehicle, name), 0.01)
    _at_least(f"{f}: vehicle.hover_w", w.vehicle.hover_w, 0.0)


def parse_world(data: Any, file: str = "<world>") -> World:
    """A World from the plain data of a world file."""
    if data is None:
        data = {}
    if not isinstance(data, dict):
        raise WorldError(f"{file}: a world is a mapping")
    known = {f.name for f in dataclasses.fields(World)} - {"file"}
    unknown = sorted(set(data) - known)
    if unknown:
        raise WorldError(f"{file}: unknown key `{unknown[0]}` (keys: {', '.join(sorted(known))})")
    color = {"color": _rgb}
    victims = tuple(_section(Victim, v, f"{file}: victims[{i}]", color)
                    for i, v in enumerate(data.get("victims") or ()))
    objects = tuple(_section(MovingObject, o, f"{file}: objects[{i}]",
                             {"color": _rgb, "path": _points, "name": _name})
                    for i, o in enumerate(data.get("objects") or ()))
    accident = data.get("accident")
    seed = data.get("seed", 1)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise WorldError(f"{file}: seed: expected a whole number, not {seed!r}")
    world = World(
        name=str(data.get("name", Path(file).stem)),
        seed=seed,
        home=_section(Home, data.get("home"), f"{file}: home"),
        ground=_section(Ground, data.get("ground"), f"{file}: ground", color),
        road=_section(Road, data.get("road"), f"{file}: road", {**color, "points": _points}),
        accident=None if accident is None else _section(Area, accident, f"{file}: accident"),
        victims=victims,
        objects=objects,
        camera=_section(Camera, data.get("camera"), f"{file}: camera"),
        vehicle=_section(Vehicle, data.get("vehicle"), f"{file}: vehicle"),
        file=file,
    )
    _check(world)
    return world


def load_world(path: str | Path | None) -> World:
    """Read a world file (None: the default, empty world)."""
    if path is None:
        return World()
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        raise WorldError(f"{path}: cannot read the world: {e}") from None
    try:
        data = YAML(typ="safe").load(text)
    except Exception as e:  # ruamel's errors carry their own position
        raise WorldError(f"{path}: {e}") from None
    return parse_world(data, str(path))
