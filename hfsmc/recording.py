"""Reading a recording (a component's ``--record FILE``): schemas/recording.md.

The file is read as a stream, record after record, so that a recording the
component could not close (a crash, ``kill -9``) gives everything up to its
last complete record: the mcap package's stream readers raise ``EndOfFile``,
``struct.error`` or ``UnicodeDecodeError`` where the file is cut
(schemas/recording.md, "Cuts"), which here mean "the recording ends here".
Anything else wrong with the file is a :class:`RecordingError`, said in one line.
"""

from __future__ import annotations

import base64
import binascii
import json
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

VERSION = "1"  # the recording version this hfsmc reads


class RecordingError(Exception):
    """The file is not a recording hfsmc can replay (the message says why, in one line)."""


@dataclass(frozen=True, slots=True)
class Snapshot:
    """What one interface presented to the automaton at one instant."""

    t: int  # us since start
    interface: str
    values: Mapping[str, Any]  # the message's fields but `t`, as written (non-finite: strings)


@dataclass(frozen=True, slots=True)
class Frame:
    """A camera frame a snippet obtained (the first time): the JPEG the camera sent or a
    PNG of its pixels, and the CRC-32 of those pixels (None in a recording without it)."""

    t: int
    interface: str
    count: int
    data: bytes
    format: str  # jpeg or png
    crc32: int | None


@dataclass(frozen=True, slots=True)
class Command:
    t: int
    interface: str
    call: str
    args: tuple[Any, ...]

    def text(self) -> str:
        return f"{self.interface}.{self.call}({', '.join(json.dumps(a) for a in self.args)})"


@dataclass(frozen=True, slots=True)
class Skip:
    t: int
    automaton: str  # "" for the root
    deadline: int
    missed: int


@dataclass(frozen=True, slots=True)
class Signal:
    t: int
    reason: str
    ticks: int


@dataclass(frozen=True, slots=True)
class TraceRecord:
    t_us: int  # the instant it belongs to, in us (the line's own `t` is in ms)
    line: str  # exactly as `--trace` writes it
    record: Mapping[str, Any]


@dataclass(frozen=True, slots=True)
class Recording:
    path: str
    run: Mapping[str, str]  # the `hfsmc.run` metadata
    parameters: Mapping[str, Any]  # name: value in force
    interfaces: Mapping[str, Mapping[str, Any]]  # name: {"type", "url", "options"}
    sources: tuple[tuple[str, str], ...]  # (path relative to the model's folder, text)
    snapshots: tuple[Snapshot, ...]
    frames: tuple[Frame, ...]
    commands: tuple[Command, ...]
    skips: tuple[Skip, ...]
    signals: tuple[Signal, ...]
    trace: tuple[TraceRecord, ...]
    cut: bool  # the component did not close the file: it ends at its last complete record
    end_us: int  # the last instant recorded, in us since start

    @property
    def component(self) -> str:
        return self.run.get("component", "")

    @property
    def language(self) -> str:
        return self.run.get("language", "")

    @property
    def model_hash(self) -> str:
        return self.run.get("model_hash", "")

    @property
    def until_us(self) -> int | None:
        return _int_or_none(self.run.get("until_us", ""))

    @property
    def time_limit_us(self) -> int | None:
        return _int_or_none(self.run.get("time_limit_us", ""))

    @property
    def stop(self) -> Mapping[str, Any] | None:
        """The trace's `stop` record, if the recording has it."""
        last = self.trace[-1].record if self.trace else None
        return last if last is not None and last.get("ev") == "stop" else None


def _int_or_none(text: str) -> int | None:
    try:
        return int(text) if text else None
    except ValueError:
        return None


_REQUIRED = ("hfsmc.run", "hfsmc.parameters", "hfsmc.interfaces", "hfsmc.sources")
_LANGUAGES = ("python", "cpp")


def read_recording(path: str | Path) -> Recording:
    """Read ``path``; raise :class:`RecordingError` when it cannot be replayed."""
    from mcap.exceptions import EndOfFile, InvalidMagic, McapError
    from mcap.records import Channel, Footer, Message, Metadata
    from mcap.stream_reader import CRCValidationError, StreamReader

    metadata: dict[str, dict[str, str]] = {}
    channels: dict[int, str] = {}
    reader: _Messages | None = None  # made at the first message: the metadata come first
    cut = False
    closed = False
    try:
        with open(path, "rb") as f:
            try:
                for record in StreamReader(f, validate_crcs=True).records:
                    if isinstance(record, Metadata):
                        metadata.setdefault(record.name, dict(record.metadata))
                    elif isinstance(record, Channel):
                        channels[record.id] = record.topic
                    elif isinstance(record, Message):
                        topic = channels.get(record.channel_id)
                        if topic is None:
                            raise RecordingError(f"corrupted: a message of channel "
                                                 f"{record.channel_id}, which was never declared")
                        reader = reader or _Messages(metadata)
                        reader.add(topic, record.log_time, record.data)
                    elif isinstance(record, Footer):
                        closed = True
            except InvalidMagic:
                raise RecordingError("not an MCAP file (a recording is written by a "
                                     "component's --record FILE)") from None
            except CRCValidationError:
                raise RecordingError("corrupted: its data does not match its checksum") from None
            except (EndOfFile, struct.error, UnicodeDecodeError):
                cut = True
            except (McapError, ValueError, KeyError, MemoryError) as e:
                raise RecordingError(f"corrupted: {e}") from None
    except OSError as e:
        raise RecordingError(f"cannot read it: {e.strerror}") from None
    if not closed:
        cut = True
    if not metadata and reader is None:
        if cut:
            raise RecordingError("the recording ends before its metadata (cut at the start: "
                                 "nothing to replay)")
        raise RecordingError("not a recording: an MCAP file without hfsmc's metadata")
    return (reader or _Messages(metadata)).recording(str(path), cut)


class _Messages:
    """The messages of a recording, sorted by kind as they are read."""

    def __init__(self, metadata: dict[str, dict[str, str]]) -> None:
        missing = [name for name in _REQUIRED if name not in metadata]
        if missing:
            raise RecordingError(f"not an hfsmc recording, or cut before its metadata: no "
                                 f"{', '.join(missing)} metadata")
        self.run = run = metadata["hfsmc.run"]
        version = run.get("recording", "")
        if version != VERSION:
            raise RecordingError(f"recording version `{version}`: this hfsmc reads version "
                                 f"{VERSION} (a newer hfsmc wrote it?)")
        if run.get("language") not in _LANGUAGES:
            raise RecordingError(f"unknown component language `{run.get('language', '')}` "
                                 "in its metadata")
        try:
            self.start_ns = int(run.get("start_unix_ns", ""))
        except ValueError:
            raise RecordingError("its metadata has no start time (start_unix_ns)") from None
        self.parameters = {k: _json(v, f"parameter `{k}`")
                           for k, v in metadata["hfsmc.parameters"].items()}
        self.interfaces = {k: _json(v, f"interface `{k}`")
                           for k, v in metadata["hfsmc.interfaces"].items()}
        self.sources = tuple(metadata["hfsmc.sources"].items())
        if not self.sources:
            raise RecordingError("its metadata holds no model source (hfsmc.sources)")
        self.snapshots: list[Snapshot] = []
        self.frames: list[Frame] = []
        self.commands: list[Command] = []
        self.skips: list[Skip] = []
        self.signals: list[Signal] = []
        self.trace: list[TraceRecord] = []
        self.end = 0

    def add(self, topic: str, log_time: int, data: bytes) -> None:
        t = (log_time - self.start_ns) // 1000
        self.end = max(self.end, t)
        if topic == "/hfsmc/trace":
            line = data.decode("utf-8", "replace").rstrip("\n")
            self.trace.append(TraceRecord(t, line, _object(line.encode(), topic)))
            return
        body = _object(data, topic)
        name = topic.rsplit("/", 1)[1]
        try:
            if topic.startswith("/hfsmc/interface/"):
                values = {k: v for k, v in body.items() if k != "t"}
                self.snapshots.append(Snapshot(int(body["t"]), name, values))
            elif topic.startswith("/hfsmc/frame/"):
                crc = body.get("crc32")
                self.frames.append(Frame(t, name, int(body["count"]),
                                         base64.b64decode(body["data"], validate=True),
                                         str(body.get("format", "png")),
                                         None if crc is None else int(crc)))
            elif topic.startswith("/hfsmc/command/"):
                self.commands.append(Command(int(body["t"]), name, str(body["call"]),
                                             tuple(body.get("args", ()))))
            elif topic == "/hfsmc/skip":
                self.skips.append(Skip(int(body["t"]), str(body["automaton"]),
                                       int(body["deadline"]), int(body["missed"])))
            elif topic == "/hfsmc/signal":
                self.signals.append(Signal(int(body["t"]), str(body["reason"]),
                                           int(body["ticks"])))
            # other topics: written by a newer component, not needed to replay
        except (KeyError, TypeError, ValueError, binascii.Error) as e:
            raise RecordingError(f"corrupted: a {topic} message at {t / 1e6:.3f} s lacks "
                                 f"or garbles {e}") from None

    def recording(self, path: str, cut: bool) -> Recording:
        return Recording(path, self.run, self.parameters, self.interfaces, self.sources,
                         tuple(self.snapshots), tuple(self.frames), tuple(self.commands),
                         tuple(self.skips), tuple(self.signals), tuple(self.trace), cut,
                         self.end)


def _json(text: str, what: str) -> Any:
    try:
        return json.loads(text)
    except ValueError:
        raise RecordingError(f"corrupted: the metadata of {what} is not JSON") from None


def _object(data: bytes, topic: str) -> dict[str, Any]:
    try:
        body = json.loads(data)
    except ValueError:
        body = None
    if not isinstance(body, dict):
        raise RecordingError(f"corrupted: a {topic} message is not a JSON object")
    return body
