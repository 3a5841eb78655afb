"""``hfsmc export rosbag RECORDING DIR``: a recording's ROS 2 topics as a rosbag2.

The topics a ``ros2`` interface recorded (its subscriptions' samples and its publishes,
each the CDR bytes that went over the wire; schemas/recording.md) are written, as they
are, into a rosbag2 with MCAP storage, by ``rosbags`` (docs/ros2.md, "Recordings"):
``ros2 bag info/play`` and ``rosbags`` read it. A message's time is the instant the
automaton saw it (a subscription's sample) or sent it (a publish): the recording's log
time. Each topic's type comes with the definition the recording holds (its ``ros2msg``
schema), so the bag does not depend on the distro installed where it is read.

A recording is data from someone else: it is read within hfsmc's bounds
(hfsmc/recording.py), its definitions are parsed (never run) by rosbags, and each
sample is checked to be a message of its type before anything is written.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hfsmc.recording import Recording, Topic, read_recording

ROSBAG_VERSION: Literal[9] = 9  # rosbag2's metadata version of Jazzy (type hashes); Humble reads 8


class ExportError(Exception):
    """Why the export could not be made, in one line."""


@dataclass(frozen=True, slots=True)
class Exported:
    folder: str
    topics: tuple[tuple[str, str, int], ...]  # (topic, type, messages)
    start_ns: int
    end_ns: int


def export_rosbag(recording: str, folder: str) -> Exported:
    """Write ``recording``'s ROS 2 topics into the rosbag2 ``folder`` (absent or empty).
    Raises RecordingError (the file) or ExportError (the rest), each one line."""
    _check_folder(folder)
    rec = read_recording(recording)
    if not rec.samples:
        raise ExportError("it holds no ROS 2 topic (a component with a ros2 interface, "
                          "run with --record, writes them)")
    store, hashes = _types(rec)
    _check_samples(rec, store)
    from rosbags.rosbag2 import StoragePlugin, Writer, WriterError

    if os.path.isdir(folder):
        os.rmdir(folder)  # empty (checked): rosbags makes the folder itself
    counts: dict[int, int] = {}
    try:
        with Writer(folder, version=ROSBAG_VERSION, storage_plugin=StoragePlugin.MCAP) as w:
            conns: dict[tuple[str, str], Any] = {}
            by_topic: dict[int, Any] = {}
            for i, t in enumerate(rec.topics):
                key = (t.topic, t.type)
                if key not in conns:  # a topic subscribed and published: one connection
                    conns[key] = w.add_connection(t.topic, t.type, msgdef=t.definition,
                                                  rihs01=hashes[t.type])
                by_topic[i] = conns[key]
            for s in rec.samples:
                w.write(by_topic[s.topic], rec.start_ns + s.t * 1000, s.data)
                counts[id(by_topic[s.topic])] = counts.get(id(by_topic[s.topic]), 0) + 1
            listed = tuple((c.topic, c.msgtype, counts.get(id(c), 0)) for c in conns.values())
    except (WriterError, OSError) as e:
        raise ExportError(f"cannot write {folder}: {e}") from None
    times = [rec.start_ns + s.t * 1000 for s in rec.samples]
    return Exported(folder, listed, min(times), max(times))


def _check_folder(folder: str) -> None:
    """DIR is new, or an empty folder: an export never writes over anything."""
    if os.path.lexists(folder) and not os.path.isdir(folder):
        raise ExportError(f"{folder} exists and is not a folder")
    if os.path.isdir(folder) and os.listdir(folder):
        raise ExportError(f"{folder} is not empty (an export writes a new rosbag folder, "
                          "never into another's)")
    parent = Path(folder).resolve().parent
    if not parent.is_dir():
        raise ExportError(f"{parent} does not exist")


def _types(rec: Recording) -> tuple[Any, dict[str, str]]:
    """rosbags' type store of the recorded definitions, and each type's RIHS01 hash."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    hashes: dict[str, str] = {}
    for t in rec.topics:
        try:
            types = get_types_from_msg(t.definition, t.type)
            known = {n: store.fielddefs[n] for n in types if n in store.fielddefs}
            clash = [n for n, d in known.items() if d != types[n]]
            if clash:
                raise ExportError(f"topic {t.topic}: the recording defines `{clash[0]}` "
                                  "twice, differently")
            store.register(types)
            hashes[t.type] = store.hash_rihs01(t.type)
        except ExportError:
            raise
        except Exception as e:  # rosbags' parser and type system refuse a definition
            raise ExportError(f"topic {t.topic}: its definition of {t.type} does not "
                              f"parse: {_one_line(e)}") from None
    return store, hashes


def _check_samples(rec: Recording, store: Any) -> None:
    """Every sample is a message of its topic's type (rosbags decodes it)."""
    for s in rec.samples:
        t: Topic = rec.topics[s.topic]
        try:
            store.deserialize_cdr(s.data, t.type)
        except Exception as e:  # rosbags raises many kinds on bytes that are no message
            raise ExportError(f"a {t.topic} sample at {s.t / 1e6:.3f} s is no {t.type}: "
                              f"{_one_line(e)}") from None


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= 160 else text[:157] + "..."
