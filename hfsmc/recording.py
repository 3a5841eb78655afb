"""Reading a recording (a component's ``--record FILE``): schemas/recording.md.

The file is read as a stream, record after record, so that a recording the
component could not close (a crash, ``kill -9``) gives everything up to its
last complete record: the mcap package's stream readers raise ``EndOfFile``,
``struct.error`` or ``UnicodeDecodeError`` where the file is cut
(schemas/recording.md, "Cuts"), which here mean "the recording ends here".
Anything else wrong with the file is a :class:`RecordingError`, said in one line.

A recording is data from someone else (docs/recording.md, "Trust"): everything read is
bounded before it is held (a record's size, what compressed chunks inflate to, how deep a
JSON value nests, numbers), names and paths are checked, and the model's hash must be the
one its sources give.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import io
import json
import os
import re
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

VERSION = "1"  # the recording version this hfsmc reads

# Bounds on what a file may make hfsmc hold (docs/recording.md, "Trust").
MAX_RECORD_BYTES = 64 << 20  # one MCAP record (a frame of a 4K camera is about 30 MB)
MAX_INFLATED_BYTES = 256 << 20  # what compressed chunks inflate to, at least ...
INFLATION = 16  # ... or this many times the file's size
MAX_MESSAGE_BYTES = 1 << 20  # a message that is not a frame (a snapshot is under 1 KB)
MAX_DEPTH = 16  # how deep a JSON value of a message or the metadata nests
MAX_INT = (1 << 62) - 1  # times (us), counts, ticks
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_ROS_TYPE = re.compile(r"[A-Za-z][A-Za-z0-9_]*/msg/[A-Za-z][A-Za-z0-9_]*")
_ROS_TOPIC = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+")
_ROLES = ("subscription", "publication")
_HASH = re.compile(r"sha256:[0-9a-f]{64}")


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
class Topic:
    """A channel of raw messages a driver keeps of its own (a ``ros2`` interface's topic:
    the CDR of each sample, schemas/recording.md)."""

    interface: str
    role: str  # subscription or publication
    name: str  # the subscription's or publication's name in the model
    topic: str  # the resolved ROS name: /tb2/scan
    type: str  # pkg/msg/Name
    definition: str  # the `ros2msg` schema: the message's definition and its nested types'


@dataclass(frozen=True, slots=True)
class Sample:
    """One message of a :class:`Topic`: at the instant ``t`` (us), its CDR bytes."""

    t: int
    topic: int  # its index in Recording.topics
    data: bytes


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
    topics: tuple[Topic, ...] = ()  # raw channels (ros2 topics), in order of declaration
    samples: tuple[Sample, ...] = ()  # their messages, in file order
    start_ns: int = 0  # the run's start (unix ns): a message's log time is start + t

    @property
    def component(self) -> str:
        return self.run.get("component", "")

    @property
    def language(self) -> str:
        return self.run.get("language", "")

    @property
    def model_hash(self) -> str:
        """The model's hash: checked on reading to be the one its sources give."""
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


def sources_hash(sources: tuple[tuple[str, str], ...]) -> str:
    """``sha256:`` and the hex digest of each path and text, NUL after each (the hash a
    component records as `model_hash`; hfsmc/model_sources.py)."""
    h = hashlib.sha256()
    for path, text in sources:
        h.update(path.encode() + b"\0" + text.encode() + b"\0")
    return "sha256:" + h.hexdigest()


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
    from mcap.stream_reader import CRCValidationError

    try:
        with open(path, "rb") as f:
            size = _size(f)
            stream = _Stream(f, size)
            try:
                stream.read()
            except InvalidMagic:
                raise RecordingError("not an MCAP file (a recording is written by a "
                                     "component's --record FILE)") from None
            except CRCValidationError:
                raise RecordingError("corrupted: its data does not match its checksum") from None
            except (EndOfFile, struct.error, UnicodeDecodeError):
                stream.cut = True
            except RecursionError:
                raise RecordingError("corrupted: a value nests too deeply") from None
            except (McapError, ValueError, KeyError, IndexError, MemoryError, OverflowError,
                    EOFError) as e:
                raise RecordingError(f"corrupted: {_said(e)}") from None
    except OSError as e:
        raise RecordingError(f"cannot read it: {e.strerror or e}") from None
    if not stream.closed:
        stream.cut = True
    if not stream.metadata and stream.messages is None:
        if stream.cut:
            raise RecordingError("the recording ends before its metadata (cut at the start: "
                                 "nothing to replay)")
        raise RecordingError("not a recording: an MCAP file without hfsmc's metadata")
    return (stream.messages or _Messages(stream.metadata)).recording(str(path), stream.cut)


def _size(f: Any) -> int:
    try:
        return os.fstat(f.fileno()).st_size
    except (OSError, AttributeError):
        return 0


def _said(e: BaseException) -> str:
    """An exception of the mcap reader in a few words, on one line."""
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= 160 else text[:157] + "..."


class _Stream:
    """The records of one file, read with the mcap package's stream reader; chunks are
    inflated here, within bounds, before the package splits them into records."""

    def __init__(self, f: Any, size: int) -> None:
        self.f = f
        self.total = self.inflate_budget = max(MAX_INFLATED_BYTES, INFLATION * size)
        self.metadata: dict[str, dict[str, str]] = {}
        self.channels: dict[int, str] = {}
        self.schemas: dict[int, tuple[str, str, bytes]] = {}  # id -> name, encoding, data
        self.raw: dict[int, Topic | None] = {}  # a raw channel's id -> its topic (None: not ours)
        self.messages: _Messages | None = None  # made at the first message: metadata first
        self.cut = False
        self.closed = False

    def read(self) -> None:
        from mcap.records import Chunk
        from mcap.stream_reader import StreamReader, breakup_chunk

        reader = StreamReader(self.f, emit_chunks=True, validate_crcs=True,
                              record_size_limit=MAX_RECORD_BYTES)
        for record in reader.records:
            if isinstance(record, Chunk):
                plain = Chunk(compression="", data=self._inflate(record),
                              message_end_time=record.message_end_time,
                              message_start_time=record.message_start_time,
                              uncompressed_crc=record.uncompressed_crc,
                              uncompressed_size=record.uncompressed_size)
                for inner in breakup_chunk(plain, validate_crc=True):
                    self._record(inner)
            else:
                self._record(record)

    def _inflate(self, chunk: Any) -> bytes:
        """A chunk's records, inflated: never more than it says, nor past the budget."""
        claimed = int(chunk.uncompressed_size)
        if claimed > MAX_RECORD_BYTES:
            raise RecordingError(f"too large: a chunk would inflate to {claimed} bytes (hfsmc "
                                 f"reads chunks of {MAX_RECORD_BYTES >> 20} MiB at most)")
        if claimed > self.inflate_budget:
            raise RecordingError(f"too large: its chunks would inflate past "
                                 f"{self.total >> 20} MiB (hfsmc reads {INFLATION} times the "
                                 f"file's size, or {MAX_INFLATED_BYTES >> 20} MiB, at most)")
        self.inflate_budget -= claimed
        if chunk.compression == "":
            data = bytes(chunk.data)
        elif chunk.compression == "zstd":
            import zstandard

            parts = []
            left = claimed + 1
            with zstandard.ZstdDecompressor().stream_reader(io.BytesIO(chunk.data),
                                                            read_across_frames=True) as r:
                while left > 0 and (part := r.read(min(left, 1 << 20))):
                    parts.append(part)
                    left -= len(part)
            data = b"".join(parts)
        elif chunk.compression == "lz4":
            import lz4.frame  # type: ignore[import-untyped]

            data = lz4.frame.LZ4FrameDecompressor().decompress(chunk.data, max_length=claimed + 1)
        else:
            raise RecordingError(f"corrupted: a chunk compressed with unknown "
                                 f"`{chunk.compression[:20]}` (zstd, lz4 or none)")
        if len(data) != claimed:
            more = "more" if len(data) > claimed else "fewer"
            raise RecordingError(f"corrupted: a chunk inflates to {more} bytes than the "
                                 f"{claimed} it says")
        return data

    def _record(self, record: Any) -> None:
        from mcap.records import Channel, Footer, Message, Metadata, Schema

        if isinstance(record, Metadata):
            self.metadata.setdefault(record.name, dict(record.metadata))
        elif isinstance(record, Schema):
            self.schemas.setdefault(record.id, (record.name, record.encoding, record.data))
        elif isinstance(record, Channel):
            self.channels[record.id] = record.topic
            if record.message_encoding != "json":
                self.raw[record.id] = _raw_topic(record, self.schemas)
        elif isinstance(record, Message):
            topic = self.channels.get(record.channel_id)
            if topic is None:
                raise RecordingError(f"corrupted: a message of channel {record.channel_id}, "
                                     "which was never declared")
            self.messages = self.messages or _Messages(self.metadata)
            if record.channel_id in self.raw:
                self.messages.add_raw(self.raw[record.channel_id], record.log_time, record.data)
            else:
                self.messages.add(topic, record.log_time, record.data)
        elif isinstance(record, Footer):
            self.closed = True


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
            raise RecordingError(f"recording version `{_short(version)}`: this hfsmc reads "
                                 f"version {VERSION} (a newer hfsmc wrote it?)")
        if run.get("language") not in _LANGUAGES:
            raise RecordingError(f"unknown component language `{_short(run.get('language', ''))}`"
                                 " in its metadata")
        try:
            self.start_ns = int(run.get("start_unix_ns", ""))
        except ValueError:
            raise RecordingError("its metadata has no start time (start_unix_ns)") from None
        self.parameters = {_name(k, "parameter"): _json(v, f"parameter `{k}`")
                           for k, v in metadata["hfsmc.parameters"].items()}
        self.interfaces = {_name(k, "interface"): _json(v, f"interface `{k}`")
                           for k, v in metadata["hfsmc.interfaces"].items()}
        self.sources = tuple(metadata["hfsmc.sources"].items())
        _check_sources(self.sources, run.get("model_hash", ""))
        self.snapshots: list[Snapshot] = []
        self.frames: list[Frame] = []
        self.commands: list[Command] = []
        self.skips: list[Skip] = []
        self.signals: list[Signal] = []
        self.trace: list[TraceRecord] = []
        self.topics: dict[Topic, int] = {}
        self.samples: list[Sample] = []
        self.end = 0

    def add_raw(self, topic: Topic | None, log_time: int, data: bytes) -> None:
        """A message of a raw channel (a ros2 topic's CDR); one of a channel that is not
        hfsmc's (another tool added it) is left out."""
        if topic is None:
            return
        t = (log_time - self.start_ns) // 1000
        if not 0 <= t <= MAX_INT:
            raise RecordingError(f"corrupted: a {_short(topic.topic)} message logged at "
                                 f"{log_time} ns, before the run's start or too late")
        self.end = max(self.end, t)
        index = self.topics.setdefault(topic, len(self.topics))
        self.samples.append(Sample(t, index, bytes(data)))

    def add(self, topic: str, log_time: int, data: bytes) -> None:
        t = (log_time - self.start_ns) // 1000
        if not 0 <= t <= MAX_INT:
            raise RecordingError(f"corrupted: a {_short(topic)} message logged at "
                                 f"{log_time} ns, before the run's start or too late")
        self.end = max(self.end, t)
        if len(data) > MAX_MESSAGE_BYTES and not topic.startswith("/hfsmc/frame/"):
            raise RecordingError(f"corrupted: a {_short(topic)} message of {len(data)} bytes "
                                 f"(at most {MAX_MESSAGE_BYTES} are read)")
        if topic == "/hfsmc/trace":
            line = data.decode("utf-8", "replace").rstrip("\n")
            self.trace.append(TraceRecord(t, line, _object(line.encode(), topic)))
            return
        body = _object(data, topic)
        name = topic.rsplit("/", 1)[1]
        if topic.startswith(("/hfsmc/interface/", "/hfsmc/frame/", "/hfsmc/command/")):
            _name(name, "interface")
        try:
            if topic.startswith("/hfsmc/interface/"):
                values = {k: v for k, v in body.items() if k != "t"}
                self.snapshots.append(Snapshot(_int(body["t"]), name, values))
            elif topic.startswith("/hfsmc/frame/"):
                crc = body.get("crc32")
                self.frames.append(Frame(t, name, _int(body["count"]),
                                         base64.b64decode(body["data"], validate=True),
                                         _format(body.get("format", "png")),
                                         None if crc is None else _int(crc)))
            elif topic.startswith("/hfsmc/command/"):
                args = body.get("args", ())
                if not isinstance(args, list | tuple):
                    raise TypeError("args")
                self.commands.append(Command(_int(body["t"]), name, str(body["call"]),
                                             tuple(args)))
            elif topic == "/hfsmc/skip":
                self.skips.append(Skip(_int(body["t"]), str(body["automaton"]),
                                       _int(body["deadline"]), _int(body["missed"])))
            elif topic == "/hfsmc/signal":
                self.signals.append(Signal(_int(body["t"]), str(body["reason"]),
                                           _int(body["ticks"])))
            # other topics: written by a newer component, not needed to replay
        except (KeyError, TypeError, ValueError, binascii.Error) as e:
            raise RecordingError(f"corrupted: a {_short(topic)} message at {t / 1e6:.3f} s "
                                 f"lacks or garbles {_said(e)}") from None

    def recording(self, path: str, cut: bool) -> Recording:
        return Recording(path, self.run, self.parameters, self.interfaces, self.sources,
                         tuple(self.snapshots), tuple(self.frames), tuple(self.commands),
                         tuple(self.skips), tuple(self.signals), tuple(self.trace), cut,
                         self.end, tuple(self.topics), tuple(self.samples), self.start_ns)


def _raw_topic(channel: Any, schemas: Mapping[int, tuple[str, str, bytes]]) -> Topic | None:
    """The topic of a raw channel hfsmc wrote (a ros2 topic: ``cdr`` messages, a ``ros2msg``
    schema, hfsmc's metadata), checked; None for a channel of another kind or tool."""
    meta = dict(channel.metadata)
    name = meta.get("hfsmc.interface")
    if channel.message_encoding != "cdr" or name is None:
        return None
    roles = [r for r in _ROLES if f"hfsmc.{r}" in meta]
    where = f"channel {_short(channel.topic)}"
    if len(roles) != 1:
        raise RecordingError(f"corrupted: {where} is neither one subscription nor one "
                             "publication")
    schema = schemas.get(channel.schema_id)
    if schema is None or schema[1] != "ros2msg":
        raise RecordingError(f"corrupted: {where} has no ros2msg schema")
    if not _ROS_TYPE.fullmatch(schema[0]):
        raise RecordingError(f"corrupted: {where}'s type `{_short(schema[0])}` is not "
                             "pkg/msg/Name")
    if not _ROS_TOPIC.fullmatch(channel.topic):
        raise RecordingError(f"corrupted: {where} is not a ROS 2 topic name")
    try:
        text = schema[2].decode("utf-8")
    except UnicodeDecodeError:
        raise RecordingError(f"corrupted: {where}'s message definition is not UTF-8") from None
    return Topic(_name(name, "interface"), roles[0], _name(meta[f"hfsmc.{roles[0]}"], roles[0]),
                 channel.topic, schema[0], text)


def _check_sources(sources: tuple[tuple[str, str], ...], digest: str) -> None:
    """The sources' paths are relative paths, and the recorded hash is theirs."""
    if not sources:
        raise RecordingError("its metadata holds no model source (hfsmc.sources)")
    for path, _ in sources:
        parts = path.split("/")
        if (not path or path.startswith("/") or "\\" in path or "\0" in path
                or any(p in ("", ".") for p in parts) or ".." in parts[len(parts) - 1:]):
            raise RecordingError(f"corrupted: a model source's path `{_short(path)}` is not a "
                                 "relative file path")
    if "/" in sources[0][0] or sources[0][0].startswith(".."):
        raise RecordingError(f"corrupted: the model file `{_short(sources[0][0])}` is not a "
                             "file name")
    if not _HASH.fullmatch(digest):
        raise RecordingError(f"corrupted: its model hash `{_short(digest)}` is not sha256: "
                             "and 64 hex digits")
    if sources_hash(sources) != digest:
        raise RecordingError("corrupted: its model hash is not the hash of the model sources "
                             "it holds (the sources or the hash were changed)")


def _short(text: str) -> str:
    text = text.encode("unicode_escape").decode("ascii")
    return text if len(text) <= 40 else text[:37] + "..."


def _name(name: str, what: str) -> str:
    if not _NAME.fullmatch(name):
        raise RecordingError(f"corrupted: {what} name `{_short(name)}` is not a name")
    return name


def _int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_INT:
        raise ValueError(f"a whole number from 0 to {MAX_INT} (`{_short(str(value))}`)")
    return value


def _format(value: Any) -> str:
    if value not in ("png", "jpeg"):
        raise ValueError(f"the frame format (png or jpeg, not `{_short(str(value))}`)")
    return str(value)


def _loads(data: str | bytes) -> Any:
    """JSON, no deeper than MAX_DEPTH, its whole numbers within +-MAX_INT (what both
    components read back); ValueError otherwise."""
    try:
        value = json.loads(data)
    except RecursionError:
        raise ValueError("nested too deeply") from None
    todo = [(value, 0)]
    while todo:
        v, depth = todo.pop()
        if depth > MAX_DEPTH:
            raise ValueError("nested too deeply")
        if isinstance(v, int) and not isinstance(v, bool) and abs(v) > MAX_INT:
            raise ValueError("holds a number out of range")
        if isinstance(v, dict):
            todo.extend((x, depth + 1) for x in v.values())
        elif isinstance(v, list):
            todo.extend((x, depth + 1) for x in v)
    return value


def _json(text: str, what: str) -> Any:
    try:
        return _loads(text)
    except ValueError as e:
        why = ("nests too deeply" if "nested" in str(e) else
               "holds a number out of range" if "range" in str(e) else "is not JSON")
        raise RecordingError(f"corrupted: the metadata of {_short(what)} {why}") from None


def _object(data: bytes, topic: str) -> dict[str, Any]:
    try:
        body = _loads(data)
    except ValueError as e:
        if "nested" in str(e):
            raise RecordingError(f"corrupted: a {_short(topic)} message nests too deeply "
                                 f"(more than {MAX_DEPTH} levels)") from None
        if "range" in str(e):
            raise RecordingError(f"corrupted: a {_short(topic)} message holds a whole number "
                                 f"out of range (more than {MAX_INT} in size)") from None
        body = None
    if not isinstance(body, dict):
        raise RecordingError(f"corrupted: a {_short(topic)} message is not a JSON object")
    return body


# ---------------------------------------------------------------------------
# one ROS 2 topic of any MCAP file (a scenario's recorded topic: docs/testing.md)


def raw_channel(path: str | Path, topic: str) -> list[tuple[int, str, bytes]]:
    """The messages of the CDR channel named ``topic`` in an MCAP file (hfsmc's recording or
    a rosbag2): (time since the file's first message in us, its ``ros2msg`` type, the
    bytes), in order; read within the bounds of :func:`read_recording`. Of an hfsmc
    recording that has it both subscribed and published, the subscription's. Raises
    :class:`RecordingError` (no such channel: it names the CDR channels there are)."""
    from mcap.exceptions import InvalidMagic, McapError

    try:
        with open(path, "rb") as f:
            stream = _Channels(f, _size(f), topic)
            try:
                stream.read()
            except InvalidMagic:
                raise RecordingError("not an MCAP file (a recording or a rosbag2 in MCAP "
                                     "storage)") from None
            except (McapError, ValueError, KeyError, IndexError, MemoryError, OverflowError,
                    EOFError, struct.error, UnicodeDecodeError, RecursionError) as e:
                raise RecordingError(f"cannot be read: {_said(e)}") from None
    except OSError as e:
        raise RecordingError(f"cannot read it: {e.strerror or e}") from None
    wanted = [c for c, (name, _, _) in stream.cdr.items() if name == topic]
    if not wanted:
        there = sorted({name for name, _, _ in stream.cdr.values()})
        raise RecordingError(f"no CDR channel `{_short(topic)}` in it (its ROS 2 topics: "
                             f"{', '.join(there) or 'none'})")
    wanted.sort(key=lambda c: stream.cdr[c][2] != "subscription")
    channel = wanted[0]
    schema = stream.types.get(channel, "")
    start = stream.first if stream.first is not None else 0
    return [((t - start) // 1000, schema, data) for c, t, data in stream.found if c == channel]


class _Channels(_Stream):
    """Every CDR channel of a file, and the messages of those named ``topic``."""

    def __init__(self, f: Any, size: int, topic: str) -> None:
        super().__init__(f, size)
        self.topic = topic
        self.cdr: dict[int, tuple[str, str, str]] = {}  # id -> topic, type, hfsmc role
        self.types: dict[int, str] = {}
        self.found: list[tuple[int, int, bytes]] = []
        self.first: int | None = None

    def _record(self, record: Any) -> None:
        from mcap.records import Channel, Message, Schema

        if isinstance(record, Schema):
            self.schemas.setdefault(record.id, (record.name, record.encoding, record.data))
        elif isinstance(record, Channel):
            schema = self.schemas.get(record.schema_id)
            if record.message_encoding == "cdr" and schema is not None:
                meta = dict(record.metadata)
                role = next((r for r in _ROLES if f"hfsmc.{r}" in meta), "")
                self.cdr[record.id] = (record.topic, schema[0], role)
                self.types[record.id] = schema[0]
        elif isinstance(record, Message):
            t = int(record.log_time)
            self.first = t if self.first is None else min(self.first, t)
            name = self.cdr.get(record.channel_id, ("",))[0]
            if name == self.topic:
                if len(record.data) > MAX_RECORD_BYTES:
                    raise RecordingError("a message is too large")
                self.found.append((record.channel_id, t, bytes(record.data)))
