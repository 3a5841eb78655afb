"""``--playback DIR``: the component's interfaces fed from a script instead of the world.

Copied beside every generated Python component; the runtime imports it only for
``--playback``, which `hfsmc replay` and `hfsmc test` use. ``DIR/inputs.jsonl`` holds
the snapshots of the interfaces over time, the ticks a real clock skipped and the
signals acted on (schemas/recording.md, "Playback"); the fakes keep the real
interfaces' names and types, so a model runs unchanged; every command a snippet sends
is appended to ``DIR/commands.jsonl`` and goes nowhere else.
"""

from __future__ import annotations

import json
import os
import sys
import zlib
from typing import IO, Any

from hfsmc_record import plain  # type: ignore[import-not-found]  # beside the component

_FLOATS = {"heartbeat_age", "altitude", "yaw", "age"}
_TRIPLES = {"position", "velocity"}


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
    if field in ("ready", "armed", "vehicle"):
        if not isinstance(value, bool):
            raise ValueError(f"`{field}` must be true or false")
        return value
    if field == "mode" and not isinstance(value, str):
        raise ValueError("`mode` must be a string")
    if field == "acks" and not (isinstance(value, dict)
                                and all(isinstance(v, str) for v in value.values())):
        raise ValueError("`acks` must map commands to outcomes")
    return value


class Playback:
    """The script of one run, read whole at start."""

    def __init__(self, folder: str) -> None:
        self.folder = folder
        self.snapshots: dict[str, list[tuple[int, dict[str, Any]]]] = {}
        self.skips: dict[tuple[int, str], tuple[int, int]] = {}
        self.signals: list[tuple[int, int, str]] = []  # (ticks, t, reason)
        self.fakes: dict[str, Any] = {}
        self.place: dict[str, int] = {}
        path = os.path.join(folder, "inputs.jsonl")
        try:
            with open(path, encoding="utf-8") as f:
                lines = f.read().splitlines()
        except OSError as e:
            raise PlaybackError(f"{path}: cannot read: {e.strerror}") from None
        except UnicodeDecodeError:
            raise PlaybackError(f"{path}: not UTF-8 text") from None
        last = -1
        for n, line in enumerate(lines, 1):
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
            self.snapshots.setdefault(str(entry["interface"]), []).append(
                (t, {k: v if k == "frame" else _normal(k, v) for k, v in values.items()}))
        elif kind == "skip":
            self.skips[(t, str(entry["automaton"]))] = (int(entry["deadline"]), int(entry["missed"]))
        elif kind == "signal":
            self.signals.append((int(entry["ticks"]), t, str(entry["reason"])))
        else:
            raise ValueError(f"unknown kind `{kind}` (snapshot, skip, signal)")

    def fake(self, name: str, kind: str) -> Any:
        """The fake of interface ``name`` (None for a kind that has none)."""
        fake: Any
        if kind == "mavlink":
            import hfsmc_mavlink  # type: ignore[import-not-found]  # beside the component
            fake = fake_vehicle(name, hfsmc_mavlink)
        elif kind == "camera":
            import hfsmc_camera  # type: ignore[import-not-found]  # beside the component
            fake = fake_camera(name, hfsmc_camera, self.folder)
        else:
            return None
        self.fakes[name] = fake
        self.place[name] = 0
        return fake

    def advance(self, t_us: int) -> None:
        """Apply every entry up to ``t_us`` to the fakes (before they take a snapshot)."""
        for name, fake in self.fakes.items():
            rows = self.snapshots.get(name, ())
            k = self.place[name]
            while k < len(rows) and rows[k][0] <= t_us:
                fake.apply(rows[k][1])
                k += 1
            self.place[name] = k

    def command(self, t_us: int, name: str, call: str, args: list[Any]) -> None:
        self.commands.write(json.dumps({"t": t_us, "interface": name, "call": call,
                                        "args": plain(args)},
                                       separators=(",", ":")) + "\n")

    def close(self) -> None:
        self.commands.close()


def fake_vehicle(name: str, module: Any) -> Any:
    """A vehicle whose snapshot comes from the script; it sends nothing."""

    class Fake(module.VehicleQueries):  # type: ignore[misc]
        def __init__(self) -> None:
            self.name = name
            self.on_command = None
            self.state: dict[str, Any] = dict(module.NEVER_HEARD)
            self._snap = self.state

        def __repr__(self) -> str:
            return f"<mavlink {name} (playback)>"

        def close(self) -> None:
            """Nothing to stop (the real one's reader thread and socket)."""

        def apply(self, values: dict[str, Any]) -> None:
            self.state = {**self.state, **values}

        def snapshot(self) -> dict[str, Any]:
            self._snap = self.state
            return self._snap

    return Fake()


def fake_camera(name: str, module: Any, folder: str) -> Any:
    """A camera whose frames are PNG files named by the script."""
    import cv2

    class Fake(module.CameraQueries):  # type: ignore[misc]
        def __init__(self) -> None:
            self.name = name
            self.on_frame = None
            self.state: dict[str, Any] = {**module.NO_FRAME, "frame": None}
            self._snap = module.NO_FRAME
            self._frame = None
            self._jpeg = None  # frames come as files; a recording of this run writes PNGs
            self._seen = None
            self.images: dict[str, Any] = {}
            self.warned = False

        def __repr__(self) -> str:
            return f"<camera {name} (playback)>"

        def close(self) -> None:
            """Nothing to stop (the real one's grabber)."""

        def apply(self, values: dict[str, Any]) -> None:
            self.state = {**self.state, **values}

        def snapshot(self) -> dict[str, Any]:
            file = self.state.get("frame")
            self._frame = None if file is None else self._image(str(file), self.state)
            snap: dict[str, Any] = {"count": self.state["count"], "age": self.state["age"]}
            self._snap = snap
            return snap

        def _image(self, file: str, state: dict[str, Any]) -> Any:
            img = self.images.get(file)
            if img is None:
                path = os.path.join(folder, file)
                img = cv2.imread(path, cv2.IMREAD_COLOR)
                if img is None:
                    raise PlaybackError(f"{path}: cannot read the frame (a PNG or JPEG file)")
                crc = state.get("crc32")
                if crc is not None and zlib.crc32(img.tobytes()) != crc and not self.warned:
                    self.warned = True
                    sys.stderr.write(
                        f"{name}: frame {state['count']} ({file}) decodes to other pixels here "
                        "than in the recorded run (another JPEG decoder): from there on this "
                        "run does not compute on the recorded pixels\n")
                self.images = {file: img}  # the frame of the moment: the previous one goes
            return img

    return Fake()

