"""``--playback DIR``: the component's interfaces fed from a script instead of the world.

Copied beside every generated Python component; the runtime imports it only for
``--playback``, which `hfsmc replay` and `hfsmc test` use. ``DIR/inputs.jsonl`` holds
the snapshots of the interfaces over time, the ticks a real clock skipped and the
signals acted on (schemas/recording.md, "Playback"); the fakes keep the real
interfaces' names and types, so a model runs unchanged; every command a snippet sends
is appended to ``DIR/commands.jsonl`` and goes nowhere else.

A script that starts with a ``recorded`` entry is a recorded run (`hfsmc replay`): it
holds each interface's snapshot at every instant of that run, and says which values it
lacks (a camera frame no snippet read then). A query it cannot answer (such a frame, any
value at an instant the recorded run did not have, an interface it does not hold) is
answered with the "nothing yet" value, and the first one is written to
``DIR/unanswered.jsonl``: from there on the run is no evidence of what the model would
have done (the C++ runtime does the same, templates/cpp/hfsmc/playback.hpp).
"""

from __future__ import annotations

import json
import os
import sys
import zlib
from typing import IO, Any

from hfsmc_record import plain  # type: ignore[import-not-found]  # beside the component

_FLOATS = {"heartbeat_age", "altitude", "yaw", "age"}
CAMERA_FIELDS = ("count", "age", "frame", "crc32")  # what a camera's script may give
_TRIPLES = {"position", "velocity", "location", "home"}


class PlaybackError(Exception):
    """A playback folder that cannot be read: said on one line with file:line."""


def _number(value: Any) -> float:
    if isinstance(value, str) and value in ("nan", "inf", "-inf"):
        return float(value)
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    raise ValueError(f"`{value}` is not a number")


def _normal(field: str, value: Any) -> Any:
    """A snapshot field as the real interface returns it."""
    if field in _FLOATS:
        return _number(value)
    if field in _TRIPLES:
        if not isinstance(value, list) or len(value) != 3:
            raise ValueError(f"`{field}` must be a list of three numbers")
        return (_number(value[0]), _number(value[1]), _number(value[2]))
    if field in ("battery", "type", "count", "crc32"):
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"`{field}` must be an integer")
        return value
    if field == "mission":
        if not (isinstance(value, list) and len(value) == 2 and all(
                isinstance(x, int) and not isinstance(x, bool) for x in value)):
            raise ValueError("`mission` must be [current, total] (two integers)")
        return (value[0], value[1])
    if field in ("ready", "armed", "vehicle", "fence_breached"):
        if not isinstance(value, bool):
            raise ValueError(f"`{field}` must be true or false")
        return value
    if field in ("mode", "status_text", "battery_failsafe", "failsafe") and \
            not isinstance(value, str):
        raise ValueError(f"`{field}` must be a string")
    if field == "acks" and not (isinstance(value, dict)
                                and all(isinstance(v, str) for v in value.values())):
        raise ValueError("`acks` must map commands to outcomes")
    return value


class Playback:
    """The script of one run, read whole at start."""

    def __init__(self, folder: str) -> None:
        self.folder = folder
        self.snapshots: dict[str, list[tuple[int, dict[str, Any], frozenset[str]]]] = {}
        self.recorded = False  # a recorded run: a snapshot of every interface at each instant
        self.t = 0
        self.unanswered: dict[str, Any] | None = None  # the first query it could not answer
        self.skips: dict[tuple[int, str], tuple[int, int]] = {}
        self.signals: list[tuple[int, int, str]] = []  # (ticks, t, reason)
        self.fakes: dict[str, Any] = {}
        self.place: dict[str, int] = {}
        # the entries as written, and the first that a built-in driver's fields refuse
        self.raw: dict[str, list[tuple[int, dict[str, Any], frozenset[str]]]] = {}
        self.bad: dict[str, str] = {}
        self.images: dict[str, tuple[str, Any]] = {}  # per interface, its frame's file and image
        self.warned: set[str] = set()  # interfaces whose frames decode to other pixels here
        path = self.path = os.path.join(folder, "inputs.jsonl")
        self.line = 0
        try:
            with open(path, encoding="utf-8") as f:
                lines = f.read().splitlines()
        except OSError as e:
            raise PlaybackError(f"{path}: cannot read: {e.strerror}") from None
        except UnicodeDecodeError:
            raise PlaybackError(f"{path}: not UTF-8 text") from None
        last = -1
        for n, line in enumerate(lines, 1):
            self.line = n
            if not line.strip():
                continue
            try:
                entry = json.loads(line)
                t = entry["t"]
                if isinstance(t, bool) or not isinstance(t, int) or t < 0:
                    raise ValueError("`t` must be a whole number of microseconds, >= 0")
                if t < last:
                    raise ValueError(f"`t` {t} goes back in time (the line before: {last})")
                last = t
                self._entry(entry, t)
            except (ValueError, KeyError, TypeError) as e:
                what = f"missing {e}" if isinstance(e, KeyError) else str(e)
                raise PlaybackError(f"{path}:{n}: {what}") from None
        self.signals.sort()
        try:
            self.commands: IO[str] = open(os.path.join(folder, "commands.jsonl"), "w",  # noqa: SIM115
                                          encoding="ascii")
        except OSError as e:
            raise PlaybackError(f"{folder}/commands.jsonl: cannot write: {e.strerror}") from None

    def _entry(self, entry: dict[str, Any], t: int) -> None:
        kind = entry["kind"]
        if kind == "snapshot":
            values = entry["values"]
            if not isinstance(values, dict):
                raise ValueError("`values` must be a mapping")
            frame = values.get("frame")
            if frame is not None and not os.path.isfile(os.path.join(self.folder, str(frame))):
                raise ValueError(f"frame `{frame}` is not a file in {self.folder}")
            missing = entry.get("unrecorded", [])
            if not isinstance(missing, list) or not all(isinstance(m, str) for m in missing):
                raise ValueError("`unrecorded` must be a list of field names")
            name = str(entry["interface"])
            self.raw.setdefault(name, []).append((t, values, frozenset(missing)))
            try:  # the built-in drivers' fields; a user driver's fake converts its own
                self.snapshots.setdefault(name, []).append(
                    (t, {k: v if k == "frame" else _normal(k, v) for k, v in values.items()},
                     frozenset(missing)))
            except ValueError as e:
                self.bad.setdefault(name, f"{self.path}:{self.line}: {e}")
        elif kind == "skip":
            self.skips[(t, str(entry["automaton"]))] = (int(entry["deadline"]), int(entry["missed"]))
        elif kind == "signal":
            self.signals.append((int(entry["ticks"]), t, str(entry["reason"])))
        elif kind == "recorded":
            self.recorded = True
        else:
            raise ValueError(f"unknown kind `{kind}` (snapshot, skip, signal, recorded)")

    def fake(self, name: str, kind: str, settings: dict[str, Any] | None = None) -> Any:
        """The fake of interface ``name`` (None for a kind that has none); ``settings``:
        a ``ros2`` interface's (node, namespace, subscribe, publish), as its ``connect``."""
        fake: Any
        if kind == "ros2":
            import hfsmc_ros2_playback  # type: ignore[import-not-found]  # beside the component
            try:
                fake, rows = hfsmc_ros2_playback.fake(name, settings or {}, self,
                                                      self.raw.get(name, []))
            except ValueError as e:
                raise PlaybackError(f"{self.path}: {e}") from None
            self.snapshots[name] = rows
            self.fakes[name] = fake
            self.place[name] = 0
            return fake
        if name in self.bad and kind in ("mavlink", "camera"):
            raise PlaybackError(self.bad[name])
        # the built-in drivers' own fakes (hfsmc_driver.Driver.fake), as a user driver's
        if kind == "mavlink":
            import hfsmc_mavlink  # type: ignore[import-not-found]  # beside the component
            fake = hfsmc_mavlink.VehicleQueries.fake(name, None, {}, self)
        elif kind == "camera":
            import hfsmc_camera  # type: ignore[import-not-found]  # beside the component
            fake = hfsmc_camera.Camera.fake(name, None, {}, self)
            self.snapshots[name] = [(t, {k: v for k, v in values.items() if k in CAMERA_FIELDS},
                                     lacks) for t, values, lacks in self.snapshots.get(name, [])]
        else:
            return None
        self.fakes[name] = fake
        self.place[name] = 0
        return fake

    def adopt(self, name: str, fake: Any) -> Any:
        """A user driver's fake (hfsmc_driver.Driver.fake), fed like the built-in ones from
        the entries as written (its ``apply`` converts and checks them)."""
        self.snapshots[name] = self.raw.get(name, [])
        fields = getattr(type(fake), "SNAPSHOT", {})
        frames = ("frame", "crc32") if getattr(type(fake), "FRAMES", "") else ()
        for t, values, _ in self.snapshots[name]:  # a field it lacks: said at start
            odd = [k for k in values if k not in fields and k not in frames]
            if odd:
                raise PlaybackError(f"{self.path}: t={t}: the {getattr(fake, 'KIND', '')} "
                                    f"interface `{name}` has no snapshot field `{odd[0]}` "
                                    f"(fields: {', '.join(fields)})")
        self.fakes[name] = fake
        self.place[name] = 0
        return fake

    def image(self, name: str, file: str, crc: Any, count: Any) -> Any:
        """The image a script names for a driver's frame (FRAMES, hfsmc_driver.Driver), read
        once while it is the frame of the moment; said once when its pixels are not those
        of the recorded run (``crc``: their CRC-32 there)."""
        held = self.images.get(name)
        if held is not None and held[0] == file:
            return held[1]
        import cv2  # a driver with frames has it
        path = os.path.join(self.folder, file)
        img = cv2.imread(path, cv2.IMREAD_COLOR)
        if img is None:
            raise PlaybackError(f"{path}: cannot read the frame (a PNG or JPEG file)")
        if crc is not None and zlib.crc32(img.tobytes()) != crc and name not in self.warned:
            self.warned.add(name)
            sys.stderr.write(
                f"{name}: frame {count} ({file}) decodes to other pixels here than in the "
                "recorded run (another JPEG decoder): from there on this run does not "
                "compute on the recorded pixels\n")
        self.images[name] = (file, img)  # the frame of the moment: the previous one goes
        return img

    def advance(self, t_us: int) -> None:
        """Apply every entry up to ``t_us`` to the fakes (before they take a snapshot), and
        tell each what the script holds of it at this instant."""
        self.t = t_us
        for name, fake in self.fakes.items():
            rows = self.snapshots.get(name, ())
            k = self.place[name]
            while k < len(rows) and rows[k][0] <= t_us:
                fake.apply(rows[k][1])
                k += 1
            self.place[name] = k
            last = rows[k - 1] if k > 0 else None
            if not self.recorded:
                fake.lacks = None
            elif last is None:
                fake.lacks = "interface"  # the recording holds nothing of it
            elif last[0] != t_us:
                fake.lacks = "instant"  # the recorded run had no instant then
            else:
                fake.lacks = last[2] or None

    def asked(self, name: str, query: str, reason: str, count: int | None) -> None:
        """A query the script cannot answer: the first one goes to DIR/unanswered.jsonl."""
        if self.unanswered is not None:
            return
        self.unanswered = {"t": self.t, "interface": name, "query": query, "reason": reason}
        if count is not None:
            self.unanswered["count"] = count
        try:
            with open(os.path.join(self.folder, "unanswered.jsonl"), "w", encoding="ascii") as f:
                f.write(json.dumps(self.unanswered, separators=(",", ":")) + "\n")
        except OSError as e:
            sys.stderr.write(f"playback: cannot write {self.folder}/unanswered.jsonl: "
                             f"{e.strerror}\n")

    def command(self, t_us: int, name: str, call: str, args: list[Any]) -> None:
        self.commands.write(json.dumps({"t": t_us, "interface": name, "call": call,
                                        "args": plain(args)},
                                       separators=(",", ":")) + "\n")

    def close(self) -> None:
        self.commands.close()
