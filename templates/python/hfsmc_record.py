"""``--record FILE``: what entered the automaton from outside, as an MCAP recording.

Copied beside every generated Python component; the runtime imports it only for
``--record``, and the recorder needs the ``mcap`` package then (the component says so at
start when it is missing); ``plain`` alone, which a playback uses too, needs nothing. What is written is in schemas/recording.md; why, in
docs/recording.md. Records go straight to the file (no chunks, no compression),
handed to the operating system once per instant: a component killed mid-run leaves
a recording that replays up to its last complete instant.
"""

from __future__ import annotations

import base64
import contextlib
import json
import math
import sys
import time
import zlib
from collections.abc import Callable
from typing import IO, Any

RECORDING_VERSION = "1"

_SCHEMAS: dict[str, dict[str, Any]] = {
    "hfsmc.mavlink.Snapshot": {
        "title": "What the automaton saw of a vehicle during one instant",
        "type": "object", "properties": {
            "t": {"type": "integer", "description": "the instant, us since start"},
            "heartbeat_age": {"type": ["number", "string"]}, "ready": {"type": "boolean"},
            "armed": {"type": "boolean"}, "mode": {"type": "string"},
            "position": {"type": "array", "items": {"type": ["number", "string"]}},
            "altitude": {"type": ["number", "string"]},
            "velocity": {"type": "array", "items": {"type": ["number", "string"]}},
            "yaw": {"type": ["number", "string"]}, "battery": {"type": "integer"},
            "acks": {"type": "object", "additionalProperties": {"type": "string"}},
            "vehicle": {"type": "boolean"}, "type": {"type": "integer"}}},
    "hfsmc.camera.Snapshot": {
        "title": "What the automaton saw of a camera during one instant",
        "type": "object", "properties": {
            "t": {"type": "integer"}, "count": {"type": "integer"},
            "age": {"type": ["number", "string"]}}},
    "foxglove.CompressedImage": {
        "title": "foxglove.CompressedImage", "type": "object", "properties": {
            "timestamp": {"type": "object", "properties": {
                "sec": {"type": "integer"}, "nsec": {"type": "integer"}}},
            "frame_id": {"type": "string"},
            "data": {"type": "string", "contentEncoding": "base64"},
            "format": {"type": "string"},
            "count": {"type": "integer", "description": "the camera's frame number"},
            "crc32": {"type": "integer", "description": "CRC-32 of the decoded BGR pixels"}}},
    "hfsmc.ros2.Snapshot": {
        "title": "What the automaton saw of its ROS 2 topics during one instant",
        "type": "object", "properties": {
            "t": {"type": "integer"},
            "subscriptions": {"type": "object", "additionalProperties": {
                "type": "object", "properties": {
                    "count": {"type": "integer", "description": "samples arrived since start"},
                    "age": {"type": ["number", "string"], "description": "s; inf: none yet"},
                    "publishers": {"type": "integer"}, "dropped": {"type": "integer"}}}},
            "subscribers": {"type": "object", "additionalProperties": {"type": "integer"}},
            "goals": {"type": "object", "description": "per action, its latest goal",
                      "additionalProperties": {"type": "object", "properties": {
                          "status": {"type": "string"},
                          "feedback": {"type": ["string", "null"], "contentEncoding": "base64",
                                       "description": "CDR; only in the instant it changed"},
                          "result": {"type": ["string", "null"], "contentEncoding": "base64",
                                     "description": "CDR; only in the instant it changed"}}}},
            "calls": {"type": "object", "description": "per service, its latest call",
                      "additionalProperties": {"type": "object", "properties": {
                          "status": {"type": "string"},
                          "response": {"type": ["string", "null"], "contentEncoding": "base64",
                                       "description": "CDR; only in the instant it changed"}}}}}},
    "hfsmc.Command": {
        "title": "A command a snippet sent to an interface", "type": "object", "properties": {
            "t": {"type": "integer"}, "call": {"type": "string"}, "args": {"type": "array"}}},
    "hfsmc.Skip": {
        "title": "Ticks a sub-automaton missed, skipped by the real clock", "type": "object",
        "properties": {"t": {"type": "integer"}, "automaton": {"type": "string"},
                       "deadline": {"type": "integer"}, "missed": {"type": "integer"}}},
    "hfsmc.Signal": {
        "title": "A signal the automaton acted on", "type": "object", "properties": {
            "t": {"type": "integer"}, "reason": {"type": "string"},
            "ticks": {"type": "integer"}}},
    "hfsmc.TraceRecord": {
        "title": "A trace record (as --trace writes it; t in ms)", "type": "object",
        "properties": {"t": {"type": "integer"}, "ev": {"type": "string"}}},
}


def plain(value: Any) -> Any:
    """JSON-ready: tuples as lists, non-finite floats as "nan", "inf", "-inf"."""
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    return value


def _json(value: Any) -> str:
    return json.dumps(value, separators=(",", ":"))


class Recorder:
    """One recording. Every method is called from the automaton's thread."""

    def __init__(self, path: str, run: dict[str, str], parameters: dict[str, Any],
                 interfaces: dict[str, dict[str, Any]], sources: tuple[tuple[str, str], ...]
                 ) -> None:
        from mcap.writer import CompressionType, Writer  # ImportError: the runtime says so

        self.path = path
        self.broken = False
        self.out: IO[bytes] = open(path, "wb", buffering=1 << 20)  # noqa: SIM115
        self.start_ns = time.time_ns()
        self.w = Writer(self.out, use_chunking=False, compression=CompressionType.NONE,
                        enable_data_crcs=True)
        self.w.start(profile="", library="hfsmc")
        self.w.add_metadata("hfsmc.run", {"recording": RECORDING_VERSION, **run,
                                          "start_unix_ns": str(self.start_ns)})
        self.w.add_metadata("hfsmc.parameters", {k: _json(plain(v)) for k, v in parameters.items()})
        self.w.add_metadata("hfsmc.interfaces", {k: _json(v) for k, v in interfaces.items()})
        self.w.add_metadata("hfsmc.sources", dict(sources))
        self.schemas: dict[str, int] = {}
        self.channels: dict[str, int] = {}
        # drivers with channels of their own: name -> (driver, key -> channel spec)
        self.own: dict[str, tuple[Any, dict[str, dict[str, Any]]]] = {}
        self.own_ids: dict[tuple[str, str], int] = {}  # (interface, key) -> channel id
        self.own_last: dict[tuple[str, str], int] = {}  # (interface, key) -> last count written
        self.out.flush()

    def _channel(self, topic: str, schema: str) -> int:
        c = self.channels.get(topic)
        if c is None:
            s = self.schemas.get(schema)
            if s is None:
                s = self.schemas[schema] = self.w.register_schema(
                    schema, "jsonschema", json.dumps(_SCHEMAS[schema]).encode())
            c = self.channels[topic] = self.w.register_channel(topic, "json", s)
        return c

    def _write(self, topic: str, schema: str, t_us: int, message: dict[str, Any]) -> None:
        if self.broken:
            return
        at = self.start_ns + t_us * 1000
        self._io(lambda: self.w.add_message(self._channel(topic, schema), at,
                                            _json(message).encode(), at))

    def attach(self, name: str, iface: Any, clock: Callable[[], int]) -> None:
        """A driver with channels of its own (docs/drivers.md): ``own_channels()`` says
        them (key -> topic, schema name, schema encoding and data, message encoding,
        metadata), ``recorded(values)`` splits each snapshot into its JSON part and raw
        parts (key -> (count, bytes), written when the count is new); a ``ros2``
        interface's publishes (``on_publish(name, data)``) are commands, recorded with
        their bytes (base64) and on their own channel too."""
        if not callable(getattr(type(iface), "own_channels", None)):
            return
        self.own[name] = (iface, iface.own_channels())
        if hasattr(iface, "on_publish"):
            def published(pub: str, data: bytes) -> None:
                t = clock()
                self.command(t, name, "publish", [pub, base64.b64encode(data).decode("ascii")])
                self.raw(t, name, f"publication/{pub}", data)
            iface.on_publish = published

    def _own_channel(self, name: str, key: str) -> int:
        c = self.own_ids.get((name, key))
        if c is None:
            spec = self.own[name][1][key]
            schema = (spec["schema_encoding"], spec["schema"])
            s = self.schemas.get("\0".join(schema))
            if s is None:
                s = self.schemas["\0".join(schema)] = self.w.register_schema(
                    spec["schema"], spec["schema_encoding"], spec["schema_data"])
            c = self.own_ids[(name, key)] = self.w.register_channel(
                spec["topic"], spec["encoding"], s, dict(spec.get("metadata") or {}))
        return c

    def raw(self, t_us: int, name: str, key: str, data: bytes) -> None:
        """Bytes on a driver's own channel ``key``, logged at the instant ``t_us``."""
        if self.broken:
            return
        at = self.start_ns + t_us * 1000
        self._io(lambda: self.w.add_message(self._own_channel(name, key), at, data, at))

    def declare(self, kind: str, schema: dict[str, Any]) -> None:
        """The snapshot schema of a user's driver (hfsmc_driver.Driver.snapshot_schema)."""
        _SCHEMAS.setdefault(f"hfsmc.{kind}.Snapshot", schema)

    def snapshot(self, t_us: int, name: str, kind: str, values: dict[str, Any]) -> None:
        own = self.own.get(name)
        raw: dict[str, tuple[int, bytes]] = {}
        if own is not None:
            values, raw = own[0].recorded(values)
        self._write(f"/hfsmc/interface/{name}", f"hfsmc.{kind}.Snapshot", t_us,
                    {"t": t_us, **plain(values)})
        for key, (count, data) in raw.items():  # a new sample: its bytes, once
            if self.own_last.get((name, key)) != count:
                self.own_last[(name, key)] = count
                self.raw(t_us, name, key, data)

    def frame(self, t_us: int, name: str, count: int, image: Any, jpeg: Any) -> None:
        """Frame ``count`` of camera ``name``: its JPEG as the camera sent it, else a PNG
        of its pixels; lossless either way, with the CRC-32 of the pixels (BGR rows)."""
        if jpeg is not None:
            data, kind = jpeg.tobytes(), "jpeg"
        else:
            import cv2  # the camera interface has it
            ok, png = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, 1])
            if not ok:
                return
            data, kind = png.tobytes(), "png"
        at = self.start_ns + t_us * 1000
        self._write(f"/hfsmc/frame/{name}", "foxglove.CompressedImage", t_us, {
            "timestamp": {"sec": at // 1_000_000_000, "nsec": at % 1_000_000_000},
            "frame_id": name, "format": kind, "data": base64.b64encode(data).decode("ascii"),
            "count": count, "crc32": zlib.crc32(image.tobytes())})

    def command(self, t_us: int, name: str, call: str, args: list[Any]) -> None:
        self._write(f"/hfsmc/command/{name}", "hfsmc.Command", t_us,
                    {"t": t_us, "call": call, "args": plain(args)})

    def skip(self, t_us: int, automaton: str, deadline: int, missed: int) -> None:
        self._write("/hfsmc/skip", "hfsmc.Skip", t_us,
                    {"t": t_us, "automaton": automaton, "deadline": deadline, "missed": missed})

    def signal(self, t_us: int, reason: str, ticks: int) -> None:
        self._write("/hfsmc/signal", "hfsmc.Signal", t_us,
                    {"t": t_us, "reason": reason, "ticks": ticks})

    def trace(self, t_us: int, record: dict[str, Any]) -> None:
        self._write("/hfsmc/trace", "hfsmc.TraceRecord", t_us, record)

    def flush(self) -> None:
        """The end of an instant: what is written so far is in the file."""
        if not self.broken:
            self._io(self.out.flush)

    def close(self) -> None:
        if not self.broken:
            self._io(self.w.finish)
        with contextlib.suppress(OSError):
            self.out.close()

    def _io(self, fn: Callable[[], object]) -> None:
        try:
            fn()
        except (OSError, ValueError) as e:
            self.broken = True
            sys.stderr.write(f"record: cannot write to {self.path}: {e}; "
                             "the component goes on without its recording\n")
