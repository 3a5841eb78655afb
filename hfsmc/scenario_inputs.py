"""A scenario's scripted inputs become a playback folder (schemas/recording.md, "Playback").

The entries of a scenario are evaluated on a time grid (the models' instants:
:func:`hfsmc.scenario.grid_us`) plus every entry's own start and end, and each
interface's snapshot is written to ``inputs.jsonl`` whenever one of its values
changes.  At a time where several entries set a value, the one that started
last wins (the later in the file at equal starts); a span (``from``/``to``)
holds its values until ``to`` and then gives way to what held before, except a
ramp, which keeps its end value.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hfsmc.errors import Diagnostics
from hfsmc.scenario import Entry, Scenario, ScenarioError, Setting
from hfsmc.scenario_driver import Ramp, driver_value
from hfsmc.scenario_ros2 import Topics, topic_rows
from hfsmc.scenario_rpc import server_rows

DEFAULT_RATE = 10.0  # frames per second of a scripted camera


@dataclass(frozen=True, slots=True)
class _Source:
    entry: Entry
    setting: Setting
    order: int  # position in the file

    def applies(self, t: int) -> bool:
        e = self.entry
        if t < e.start_us:
            return False
        return e.end_us is None or t < e.end_us or isinstance(self.setting.value, Ramp)

    @property
    def rank(self) -> tuple[int, int]:
        return (self.entry.start_us, self.order)


def _winner(sources: list[_Source], t: int) -> _Source | None:
    best: _Source | None = None
    for s in sources:
        if s.applies(t) and (best is None or s.rank > best.rank):
            best = s
    return best


def _ramp(r: Ramp, e: Entry, t: int) -> Any:
    assert e.end_us is not None
    f = min(1.0, (t - e.start_us) / (e.end_us - e.start_us))
    if isinstance(r.start, tuple) and isinstance(r.end, tuple):
        return [a + (b - a) * f for a, b in zip(r.start, r.end, strict=True)]
    assert isinstance(r.start, float) and isinstance(r.end, float)
    return r.start + (r.end - r.start) * f


def _value(src: _Source, t: int) -> Any:
    v = src.setting.value
    if isinstance(v, Ramp):
        return _ramp(v, src.entry, t)
    if isinstance(v, tuple):
        return list(v)
    return v


# A vehicle never heard (schemas/recording.md): what a field goes back to when no entry sets it.
NEVER_HEARD: dict[str, Any] = {
    "heartbeat_age": math.inf, "ready": False, "armed": False, "vehicle": False, "mode": "",
    "type": 0, "position": [math.nan] * 3, "velocity": [math.nan] * 3, "altitude": math.nan,
    "yaw": math.nan, "battery": -1, "location": [math.nan] * 3, "home": [math.nan] * 3,
    "status_text": "", "battery_failsafe": "", "mission": [0, 0], "fence_breached": False,
    "failsafe": "",
}


class _Mavlink:
    """A mavlink interface's snapshot fields over time."""

    def __init__(self, sources: list[_Source]) -> None:
        self.fields: dict[str, list[_Source]] = {}
        for s in sources:
            f = s.setting.field
            if f == "connected":
                self.fields.setdefault("heartbeat_age", []).append(s)
                if s.setting.value is True:
                    self.fields.setdefault("vehicle", []).append(s)
            elif f == "acks":
                assert isinstance(s.setting.value, tuple)
                for cmd, outcome in s.setting.value:
                    one = Setting(f"acks.{cmd}", outcome, s.setting.span, s.setting.key_span)
                    self.fields.setdefault(one.field, []).append(_Source(s.entry, one, s.order))
            else:
                self.fields.setdefault(f, []).append(s)

    def at(self, t: int) -> dict[str, Any]:
        out: dict[str, Any] = {}
        acks: dict[str, Any] = {}
        for name, sources in self.fields.items():
            w = _winner(sources, t)
            if w is None:  # set before, or later: the value of a vehicle never heard
                if not name.startswith("acks."):
                    out[name] = NEVER_HEARD[name]
                continue
            value: Any
            if w.setting.field == "connected":
                value = 0.0 if name == "heartbeat_age" and w.setting.value else (
                    True if name == "vehicle" else (t - w.entry.start_us) / 1e6)
            else:
                value = _value(w, t)
            if name.startswith("acks."):
                acks[name[5:]] = value
            else:
                out[name] = value
        if any(name.startswith("acks.") for name in self.fields):
            out["acks"] = dict(sorted(acks.items()))
        return out


Pose = tuple[float, float, float, float]  # north, east, down (m), yaw (rad)
Render = Callable[[str, int, Pose], str]  # (world file, t us, pose) -> the PNG's name


class _Camera:
    """A camera interface's frames: each image entry delivers its picture at `rate`; a world
    entry, the simulator's view of that world from the vehicle's scripted pose."""

    def __init__(self, sources: list[_Source], frames: dict[str, str],
                 render: Render | None, pose: Callable[[], Pose | None]) -> None:
        self.images = [s for s in sources if s.setting.field in ("image", "world")]
        self.rates = [s for s in sources if s.setting.field == "rate"]
        self.frames = frames  # image path -> its PNG's name in the folder
        self.render = render
        self.pose = pose
        self.count = 0
        self.last: int | None = None
        self.frame: str | None = None
        self.prev: int | None = None

    def _period(self, t: int) -> float:
        w = _winner(self.rates, t)
        rate = float(w.setting.value) if w is not None else DEFAULT_RATE
        return 1e6 / rate

    def at(self, t: int) -> dict[str, Any]:
        w = _winner(self.images, t)
        if w is not None and isinstance(w.setting.value, str):
            start, period = w.entry.start_us, self._period(t)

            def upto(x: int | None) -> int:
                return 0 if x is None or x < start else math.floor((x - start) / period) + 1

            n = upto(t) - upto(self.prev)
            if n > 0:
                latest = start + round((upto(t) - 1) * period)
                if w.setting.field == "image":
                    picture: str | None = self.frames[w.setting.value]
                else:  # rendered where the vehicle is; nothing while its pose is unknown
                    pose = self.pose()
                    picture = None if pose is None or self.render is None \
                        else self.render(w.setting.value, latest, pose)
                if picture is not None:
                    self.count += n
                    self.last = latest
                    self.frame = picture
        self.prev = t
        if self.last is None:
            return {}
        return {"count": self.count, "age": (t - self.last) / 1e6, "frame": self.frame}


class _Driver:
    """A user driver's snapshot fields over time: each the value of the entry that holds
    it, else its declared "nothing yet" value."""

    def __init__(self, sources: list[_Source], defaults: dict[str, Any]) -> None:
        self.defaults = defaults
        self.fields: dict[str, list[_Source]] = {}
        for s in sources:
            assert s.setting.raw is not None
            value = driver_value(defaults[s.setting.field], s.setting.raw, s.setting.spanned,
                                 s.setting.field, Diagnostics())
            one = Setting(s.setting.field, value, s.setting.span, s.setting.key_span)
            self.fields.setdefault(one.field, []).append(_Source(s.entry, one, s.order))

    def at(self, t: int) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for name, sources in self.fields.items():
            w = _winner(sources, t)
            out[name] = self.defaults[name] if w is None else _value(w, t)
        return out


def _times(sc: Scenario, step: int) -> list[int]:
    times = set(range(0, sc.until_us + 1, step))
    for e in sc.inputs:
        times.add(e.start_us)
        if e.end_us is not None and e.end_us <= sc.until_us:
            times.add(e.end_us)
    return sorted(t for t in times if t <= sc.until_us)


def _json(v: Any) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if isinstance(v, list):
        return [_json(x) for x in v]
    if isinstance(v, dict):
        return {k: _json(x) for k, x in v.items()}
    return v


def snapshots(sc: Scenario, types: dict[str, str], step: int, frames: dict[str, str],
              render: Render | None = None, drivers: dict[str, dict[str, Any]] | None = None
              ) -> Iterator[dict[str, Any]]:
    """The playback entries of ``sc``'s inputs, in time order: one per interface and time at
    which one of its values changed, with the values that changed. ``drivers``: each user
    driver interface's snapshot fields and their "nothing yet" values."""
    drivers = drivers or {}
    by_iface: dict[str, list[_Source]] = {}
    for order, e in enumerate(sc.inputs):
        if types.get(e.interface) == "ros2":  # its messages: hfsmc/scenario_ros2.py
            continue
        for s in e.settings:
            by_iface.setdefault(e.interface, []).append(_Source(e, s, order))
    # vehicles first: a camera that renders a world takes the pose of the first one at that time
    names = sorted(by_iface, key=lambda n: types[n] == "camera")
    vehicle = next((n for n in names if types[n] == "mavlink"), None)
    # what the fakes start with: a value is written when it differs
    heard = {k: _json(v) for k, v in NEVER_HEARD.items()} | {"acks": {}}
    shown = {name: dict(heard) if types[name] == "mavlink" else
             {k: _json(v) for k, v in drivers.get(name, {}).items()} for name in names}

    def pose() -> Pose | None:
        values = shown.get(vehicle or "", {})
        position, yaw = values.get("position"), values.get("yaw")
        if not isinstance(position, list) or not all(isinstance(x, float) for x in position):
            return None
        return (position[0], position[1], position[2], yaw if isinstance(yaw, float) else 0.0)

    makers: dict[str, _Mavlink | _Camera | _Driver] = {}
    for name in names:
        sources = by_iface[name]
        makers[name] = _Camera(sources, frames, render, pose) if types[name] == "camera" \
            else _Driver(sources, drivers[name]) if types[name] == "driver" else _Mavlink(sources)
    for t in _times(sc, step):
        for name, maker in makers.items():
            now = {k: _json(v) for k, v in maker.at(t).items()}
            changed = {k: v for k, v in now.items() if shown[name].get(k, _UNSET) != v}
            if isinstance(maker, _Camera) and "count" in changed:
                changed["frame"] = now["frame"]  # a new frame: name its picture with it
            if changed:
                shown[name].update(changed)
                yield {"t": t, "kind": "snapshot", "interface": name, "values": changed}


_UNSET = object()


def write_playback(sc: Scenario, types: dict[str, str], step: int, folder: Path,
                   topics: Topics | None = None,
                   drivers: dict[str, dict[str, Any]] | None = None) -> int:
    """Write ``folder/inputs.jsonl`` and the camera pictures (PNG); the number of entries.
    ``topics``: the model's ros2 interfaces, whose messages join the snapshots in time;
    ``drivers``: its user driver interfaces' snapshot fields (:func:`snapshots`)."""
    folder.mkdir(parents=True, exist_ok=True)
    frames = _write_frames(sc, types, folder)
    items = list(snapshots(sc, types, step, frames, _renderer(sc, folder), drivers))
    if topics is not None:
        items = sorted(items + topic_rows(sc.inputs, sc.until_us, topics)
                       + server_rows(sc.inputs, sc.until_us, topics), key=lambda i: i["t"])
    with open(folder / "inputs.jsonl", "w", encoding="utf-8") as f:
        for item in items:
            f.write(json.dumps(item, separators=(",", ":")) + "\n")
    return len(items)


def _write_frames(sc: Scenario, types: dict[str, str], folder: Path) -> dict[str, str]:
    """Each image the scenario names, read with OpenCV and written once as BGR PNG."""
    images = list(dict.fromkeys(
        s.value for e in sc.inputs if types.get(e.interface) == "camera"
        for s in e.settings if s.field == "image" and isinstance(s.value, str)))
    if not images:
        return {}
    import cv2

    diags = Diagnostics()
    out: dict[str, str] = {}
    for k, path in enumerate(images, 1):
        picture = cv2.imread(path, cv2.IMREAD_COLOR)
        if picture is None:
            span = next(s.span for e in sc.inputs for s in e.settings if s.value == path)
            diags.error("E198", f"`{path}` is not an image OpenCV can read (PNG, JPEG...)", span)
            continue
        name = f"frame{k}.png"
        if not cv2.imwrite(str(folder / name), picture):
            raise OSError(f"cannot write {folder / name}")
        out[path] = name
    if diags.has_errors:
        raise ScenarioError(diags.sorted())
    return out


def _renderer(sc: Scenario, folder: Path) -> Render | None:
    """Draws the worlds the scenario names (hfsmc/sim's camera), one PNG per frame."""
    worlds = {s.value: s.span for e in sc.inputs for s in e.settings
              if s.field == "world" and isinstance(s.value, str)}
    if not worlds:
        return None
    import cv2

    from hfsmc.sim.camera import Renderer
    from hfsmc.sim.world import WorldError, load_world

    renderers: dict[str, Renderer] = {}
    diags = Diagnostics()
    for path, span in worlds.items():
        try:
            renderers[path] = Renderer(load_world(path))
        except WorldError as e:
            diags.error("E198", f"the world cannot be read: {e}", span)
    if diags.has_errors:
        raise ScenarioError(diags.sorted())
    made = [0]

    def render(world: str, t: int, pose: Pose) -> str:
        north, east, down, yaw = pose
        made[0] += 1
        name = f"world{made[0]}.png"
        picture = renderers[world].render(t / 1e6, north, east, down, yaw)
        if not cv2.imwrite(str(folder / name), picture):
            raise OSError(f"cannot write {folder / name}")
        return name

    return render
