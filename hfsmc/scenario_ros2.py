"""A scenario's ROS 2 topics (docs/testing.md, "`ros2` interfaces"): messages by field
values or replayed from a recorded topic, and expectations on the messages published.

What a scenario writes under a ``ros2`` interface is read with its positions
(:class:`Written`, :class:`RecordedTopic`) before the model is known; once it is,
:class:`Topics` checks it against the interface's declaration and the message
definitions (the distro's and the model's own ``.msg`` files, hfsmc/ros2/definitions.py)
and turns each message into CDR with rosbags, as ROS 2 writes it. Every mistake is a
diagnostic at its place: an unknown field (E190, with a did-you-mean), a value of the
wrong type or out of its type's range (E191), a name the interface does not subscribe
or publish (E195), a type other than the declared one and a recorded topic of another
type (E195), a recording that cannot be read (E198).
"""

from __future__ import annotations

import base64
import itertools
import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hfsmc.errors import Diagnostics, Span, did_you_mean
from hfsmc.frontend.source import Document, PathKey
from hfsmc.ir import Interface, Model, Ros2Topic
from hfsmc.ros2.definitions import Field, FieldType, MessageSet, ros2_type_name

# A topic's recorded form: `scan: {recorded: run.mcap, topic: /scan, from: 2s}`.
RECORDED_KEYS = ("recorded", "topic", "from")
# A run of equal items in a list of numbers, strings or booleans: `{repeat: .inf, times: 170}`.
REPEAT_KEYS = ("repeat", "times")
# Comparisons a published message's field may be held to, besides equality.
MATCHERS = ("above", "below", "not")
MAX_REPEAT = 1_000_000  # items one `repeat` may make (a scan has hundreds)

_FLOAT32_MAX = 3.4028234663852886e38
_INT_RANGES = {
    "byte": (0, 0xFF), "char": (0, 0xFF), "uint8": (0, 0xFF), "int8": (-0x80, 0x7F),
    "uint16": (0, 0xFFFF), "int16": (-0x8000, 0x7FFF), "uint32": (0, 0xFFFF_FFFF),
    "int32": (-0x8000_0000, 0x7FFF_FFFF), "uint64": (0, 2**64 - 1),
    "int64": (-(2**63), 2**63 - 1),
}
_NUMPY = {"bool": "bool", "byte": "uint8", "char": "uint8", "int8": "int8", "uint8": "uint8",
          "int16": "int16", "uint16": "uint16", "int32": "int32", "uint32": "uint32",
          "int64": "int64", "uint64": "uint64", "float32": "float32", "float64": "float64"}


@dataclass(frozen=True, slots=True)
class Written:
    """A value as the scenario writes it: a scalar, or a ``dict[str, Written]`` / a
    ``list[Written]``, each part with its position."""

    value: Any
    span: Span
    key_span: Span


@dataclass(frozen=True, slots=True)
class RecordedTopic:
    """A subscription's messages replayed from a recording (MCAP: hfsmc's ``--record`` or a
    rosbag2), from ``from_us`` of the recording on, delivered from the entry's time."""

    file: str  # resolved, inside the scenario's folder
    topic: str | None  # the channel; None: the subscription's resolved topic name
    from_us: int
    span: Span  # the `recorded` value
    key_span: Span


def written(doc: Document, path: PathKey) -> Written:
    """The value at ``path`` of ``doc`` with the positions of all its parts."""
    value = _value_at(doc, path)
    if isinstance(value, dict):
        inner: Any = {str(k): written(doc, (*path, k)) for k in value}
    elif isinstance(value, list):
        inner = [written(doc, (*path, i)) for i in range(len(value))]
    else:
        inner = value
    return Written(inner, doc.span(path), doc.key_span(path))


def _value_at(doc: Document, path: PathKey) -> Any:
    v = doc.data
    for k in path:
        v = v[k]
    return v


def recorded_topic(doc: Document, path: PathKey, folder: Path, diags: Diagnostics,
                   duration: Any) -> RecordedTopic | None:
    """`{recorded: FILE, topic: /scan, from: 2s}` read and its file confined to ``folder``
    (E198); ``duration(value, path, what)`` reads a time as the scenario's reader does."""
    m = _value_at(doc, path)
    ok = True
    for k in m:
        if k not in RECORDED_KEYS:
            note = did_you_mean(str(k), RECORDED_KEYS)
            diags.error("E190", f"unknown key `{k}` in a recorded topic", doc.key_span((*path, k)),
                        *([note] if note else []), f"a recorded topic takes: {', '.join(RECORDED_KEYS)}")
            ok = False
    file = m["recorded"]
    fspan = doc.span((*path, "recorded"))
    if not isinstance(file, str) or not file:
        diags.error("E191", "`recorded` must be an MCAP file (relative to the scenario's folder)",
                    fspan)
        return None
    where = (folder / file).resolve()
    if os.path.isabs(file) or not where.is_relative_to(folder.resolve()):
        diags.error("E198", f"the recording `{file}` is outside the scenario's folder (a "
                    "scenario reads only files beside it or below)", fspan)
        return None
    if not where.is_file():
        diags.error("E198", f"the recording `{file}` does not exist (read relative to the "
                    "scenario's folder)", fspan)
        return None
    topic = m.get("topic")
    if topic is not None and (not isinstance(topic, str) or not topic.startswith("/")):
        diags.error("E191", "`topic` must be the recorded channel's topic name (`/scan`)",
                    doc.span((*path, "topic")))
        ok = False
    start = 0
    if "from" in m:
        got = duration(m["from"], (*path, "from"), "`from`")
        ok = ok and got is not None
        start = got or 0
    if not ok:
        return None
    return RecordedTopic(_display(where), topic, start, fspan, doc.key_span(path))


def _display(file: Path) -> str:
    absolute = Path(os.path.abspath(file))
    if absolute.is_relative_to(Path.cwd()):
        return str(absolute.relative_to(Path.cwd()))
    return str(absolute)


# ---------------------------------------------------------------------------
# the model's side: what each ros2 interface subscribes and publishes, its messages


class Topics:
    """One model's ros2 interfaces: checks a scenario's messages and makes their CDR."""

    def __init__(self, model: Model) -> None:
        from hfsmc.ros2files import model_distro, msg_files, ros2_interfaces

        self.interfaces: dict[str, Interface] = {i.name: i for i in ros2_interfaces(model.interfaces)}
        self.distro = model_distro(model.interfaces)
        self.files = msg_files(model.interfaces)
        self._set: MessageSet | None = None
        self._store: Any = None
        self.encoded: dict[int, bytes] = {}
        self._recordings: dict[tuple[str, str | None, str], list[tuple[int, str, bytes]]] = {}

    def messages(self) -> MessageSet:
        if self._set is None:
            from hfsmc.ros2.definitions import message_set

            uses = [(t.type, t.type_span) for i in self.interfaces.values() if i.ros2
                    for t in (*i.ros2.subscribe, *i.ros2.publish)]
            rpcs = [(r.type, r.type_span) for i in self.interfaces.values() if i.ros2
                    for r in (*i.ros2.actions, *i.ros2.services)]
            self._set = message_set(self.distro, uses, self.files, rpcs)
        return self._set

    def store(self) -> Any:
        if self._store is None:
            from hfsmc.ros2.definitions import rosbags_store

            self._store = rosbags_store(self.distro, self.files)
        return self._store

    def subscription(self, iface: str, name: str) -> Ros2Topic | None:
        i = self.interfaces[iface].ros2
        assert i is not None
        return next((t for t in i.subscribe if t.name == name), None)

    def publication(self, iface: str, name: str) -> Ros2Topic | None:
        i = self.interfaces[iface].ros2
        assert i is not None
        return next((t for t in i.publish if t.name == name), None)

    def resolved(self, iface: str, t: Ros2Topic) -> str:
        from hfsmc.ros2.names import resolve_name

        s = self.interfaces[iface].ros2
        assert s is not None
        return resolve_name(t.topic, s.namespace or "/", s.node or iface)

    def names(self, iface: str, role: str) -> list[str]:
        s = self.interfaces[iface].ros2
        assert s is not None
        return [t.name for t in (s.subscribe if role == "subscribe" else s.publish)]

    def rpc_names(self, iface: str) -> list[str]:
        s = self.interfaces[iface].ros2
        assert s is not None
        return [r.name for r in (*s.actions, *s.services)]

    # -- a scenario's parts against the model

    def check_settings(self, iface: str, settings: Any, diags: Diagnostics) -> None:
        """An entry's settings under the ros2 interface ``iface``: each a subscription's
        message (by values, or recorded) or the entry's `rate`."""
        subs, pubs = self.names(iface, "subscribe"), self.names(iface, "publish")
        for s in settings:
            if s.field == "rate" and not isinstance(s.value, (Written, RecordedTopic)):
                continue
            t = self.subscription(iface, s.field)
            if t is None or not isinstance(s.value, (Written, RecordedTopic)):
                if s.field in pubs:
                    diags.error("E195", f"`{s.field}` is a publication of `{iface}`: the model "
                                f"publishes it (expect it: `published: {iface}.{s.field}`)",
                                s.key_span, f"its subscriptions: {', '.join(subs) or 'none'}")
                elif t is None:
                    note = did_you_mean(s.field, subs)
                    diags.error("E195", f"the ros2 interface `{iface}` subscribes to no `{s.field}`",
                                s.key_span, *([note] if note else []),
                                f"it takes its subscriptions ({', '.join(subs) or 'none'}), each a "
                                "message, and `rate`; its actions and services, each a server "
                                f"({', '.join(self.rpc_names(iface)) or 'none'})")
                else:
                    diags.error("E191", f"`{s.field}` is a {t.type}: a mapping of its fields, or "
                                "`{recorded: FILE}`", s.span)
                continue
            if isinstance(s.value, Written):
                self.build(s.value, t.type, diags)
            else:
                self.recorded(iface, t, s.value, diags)


    def recorded(self, iface: str, t: Ros2Topic, r: RecordedTopic, diags: Diagnostics
                  ) -> list[tuple[int, bytes]]:
        """The messages of a recorded topic from its `from` on: (time after it in us, CDR),
        each checked to be of the subscription's type and to decode as it."""
        from hfsmc.recording import RecordingError, raw_channel

        key = (r.file, r.topic, self.resolved(iface, t) if r.topic is None else r.topic)
        try:
            found = self._recordings[key]
        except KeyError:
            try:
                found = raw_channel(r.file, key[2])
            except RecordingError as e:
                diags.error("E198", f"the recording `{r.file}`: {e}", r.span)
                return []
            self._recordings[key] = found
        want = ros2_type_name(t.type)
        out = []
        for n, (us, kind, data) in enumerate(found, 1):
            if ros2_type_name(kind) != want:
                diags.error("E195", f"the recorded topic {key[2]} is a {kind}; `{iface}.{t.name}` "
                            f"is a {want}", r.span, "record the same type, or name another channel "
                            "with `topic:`")
                return []
            if us < r.from_us:
                continue
            try:
                self.decode(data, want)
            except Exception as e:  # bytes rosbags cannot read: any of its errors
                diags.error("E198", f"the recording `{r.file}`: message {n} of {key[2]} is no "
                            f"{want} ({type(e).__name__})", r.span)
                return []
            out.append((us - r.from_us, data))
        if not out:
            diags.error("E193", f"the recording `{r.file}` has no message of {key[2]} at or after "
                        f"{r.from_us / 1e6:g} s", r.span)
        return out


    def check_published(self, subject: str, span: Span, msg_type: str | None,
                         fields: Written | None, diags: Diagnostics) -> None:
        iface, name = subject.split(".")
        t = self.publication(iface, name)
        if t is None:
            pubs, subs = self.names(iface, "publish"), self.names(iface, "subscribe")
            note = did_you_mean(name, pubs)
            said = (f"`{name}` is a subscription of `{iface}`, not a publication" if name in subs
                    else f"the ros2 interface `{iface}` publishes no `{name}`")
            diags.error("E195", said, span, *([note] if note else []),
                        f"its publications: {', '.join(pubs) or 'none'}")
            return
        if msg_type is not None and ros2_type_name(msg_type) != ros2_type_name(t.type):
            diags.error("E195", f"`{subject}` is declared a {ros2_type_name(t.type)}, not "
                        f"{msg_type}", span)
            return
        if fields is not None:
            check_matchers(fields, self, t.type, diags)

    # -- messages by field values

    def build(self, w: Written, type_name: str, diags: Diagnostics) -> Any:
        """The rosbags message of type ``type_name`` that ``w`` writes (fields left out
        take their defaults); None with diagnostics when it does not fit."""
        return self._message(w, ros2_type_name(type_name), diags)

    def cdr(self, message: Any, type_name: str) -> bytes:
        return bytes(self.store().serialize_cdr(message, ros2_type_name(type_name)))

    def decode(self, data: bytes, type_name: str) -> Any:
        return self.store().deserialize_cdr(data, ros2_type_name(type_name))

    def _message(self, w: Written | None, name: str, diags: Diagnostics) -> Any:
        desc = self.messages().get(name)
        given: dict[str, Written] = {}
        if w is not None:
            if not isinstance(w.value, dict):
                diags.error("E191", f"a {name} is a mapping of its fields, not {_kind(w.value)}",
                            w.span, _fields_note(desc.fields))
                return None
            given = w.value
        names = [f.name for f in desc.fields]
        ok = True
        for k, v in given.items():
            if k not in names:
                note = did_you_mean(k, names)
                diags.error("E190", f"{name} has no field `{k}`", v.key_span,
                            *([note] if note else []), _fields_note(desc.fields))
                ok = False
        values = {}
        for f in desc.fields:
            if f.name == "structure_needs_at_least_one_member":
                values[f.name] = 0
                continue
            v = self._field(f, given.get(f.name), name, diags)
            ok = ok and v is not _BAD
            values[f.name] = v
        if not ok:
            return _BAD
        return self.store().types[name](**values)

    def _field(self, f: Field, w: Written | None, owner: str, diags: Diagnostics) -> Any:
        t = f.type
        what = f"`{f.name}` ({_type_words(t)})"
        if t.array == "none":
            if w is None:
                return self._default(f)
            return self._one(t, w, what, diags)
        if w is None:
            return self._array(t, [self._one(t, None, what, diags) for _ in range(t.size)]
                               if t.array == "fixed" and f.default is None else
                               list(f.default if isinstance(f.default, tuple) else ()))
        items = self._items(w, what, t, diags)
        if items is None:
            return _BAD
        if t.array == "fixed" and len(items) != t.size:
            diags.error("E191", f"{what} has exactly {t.size} items, not {len(items)}", w.span)
            return _BAD
        if t.array == "bounded" and len(items) > t.size:
            diags.error("E191", f"{what} has at most {t.size} items, not {len(items)}", w.span)
            return _BAD
        out = [self._one(t, item, what, diags) for item in items]
        if any(v is _BAD for v in out):
            return _BAD
        return self._array(t, out)

    def _items(self, w: Written, what: str, t: FieldType, diags: Diagnostics) -> list[Written] | None:
        if not isinstance(w.value, list):
            diags.error("E191", f"{what} must be a list, not {_kind(w.value)}", w.span)
            return None
        out: list[Written] = []
        for item in w.value:
            v = item.value
            if t.kind != "nested" and isinstance(v, dict):
                n = _repeat(item, what, diags)
                if n is None:
                    return None
                out.extend([v["repeat"]] * n)
            else:
                out.append(item)
            if len(out) > MAX_REPEAT:
                diags.error("E193", f"{what}: more than {MAX_REPEAT} items", item.span)
                return None
        return out

    def _array(self, t: FieldType, items: list[Any]) -> Any:
        if t.kind == "primitive":
            import numpy as np

            return np.array(items, dtype=_NUMPY[t.name])
        return items

    def _default(self, f: Field) -> Any:
        if f.default is not None:
            return f.default
        return self._one(f.type, None, "", Diagnostics())

    def _one(self, t: FieldType, w: Written | None, what: str, diags: Diagnostics) -> Any:
        """One item of type ``t`` (its zero when ``w`` is None)."""
        if t.kind == "nested":
            return self._message(w, t.name, diags)
        if t.kind in ("string", "wstring"):
            if w is None:
                return ""
            if not isinstance(w.value, str):
                diags.error("E191", f"{what} must be a string, not {_kind(w.value)}", w.span)
                return _BAD
            if t.string_bound and len(w.value.encode("utf-8")) > t.string_bound:
                diags.error("E191", f"{what} holds {t.string_bound} bytes at most", w.span)
                return _BAD
            return w.value
        return _primitive(t.name, w, what, diags)


_BAD = object()  # a value that did not fit (its diagnostic is given)


def _primitive(base: str, w: Written | None, what: str, diags: Diagnostics) -> Any:
    if base == "bool":
        if w is None:
            return False
        if isinstance(w.value, bool):
            return w.value
        diags.error("E191", f"{what} must be true or false, not {_kind(w.value)}", w.span)
        return _BAD
    if base.startswith("float"):
        if w is None:
            return 0.0
        v = w.value
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            diags.error("E191", f"{what} must be a number (.inf and .nan too), not {_kind(v)}",
                        w.span)
            return _BAD
        if base == "float32" and math.isfinite(v) and abs(v) > _FLOAT32_MAX:
            diags.error("E191", f"{what}: {v} is out of a float32's range", w.span)
            return _BAD
        return float(v)
    if w is None:
        return 0
    v = w.value
    if isinstance(v, bool) or not isinstance(v, int):
        diags.error("E191", f"{what} must be an integer, not {_kind(v)}", w.span)
        return _BAD
    lo, hi = _INT_RANGES[base]
    if not lo <= v <= hi:
        diags.error("E191", f"{what}: {v} is out of range ({lo}..{hi})", w.span)
        return _BAD
    return v


def _repeat(item: Written, what: str, diags: Diagnostics) -> int | None:
    v = item.value
    odd = [k for k in v if k not in REPEAT_KEYS]
    if odd or "repeat" not in v or "times" not in v:
        diags.error("E191", f"an item of {what} is a value, or `{{repeat: VALUE, times: N}}`",
                    v[odd[0]].key_span if odd else item.span)
        return None
    n = v["times"].value
    if isinstance(n, bool) or not isinstance(n, int) or not 0 <= n <= MAX_REPEAT:
        diags.error("E191", f"`times` must be a whole number (0..{MAX_REPEAT})", v["times"].span)
        return None
    return n


def _type_words(t: FieldType) -> str:
    base = t.name + (f"<={t.string_bound}" if t.string_bound else "")
    return {"none": base, "fixed": f"{base}[{t.size}]", "bounded": f"{base}[<={t.size}]",
            "unbounded": f"{base}[]"}[t.array]


def _fields_note(fields: tuple[Field, ...]) -> str:
    shown = [f"{f.name} ({_type_words(f.type)})" for f in fields
             if f.name != "structure_needs_at_least_one_member"]
    return f"its fields: {', '.join(shown) or 'none'}"


def _kind(v: Any) -> str:
    return {dict: "a mapping", list: "a list", str: "a string", bool: "a boolean", int: "a number",
            float: "a number", type(None): "null"}.get(type(v), type(v).__name__)


# ---------------------------------------------------------------------------
# a published message against the fields an expectation writes


def matches(msg: Any, w: Written) -> bool:
    """Whether the rosbags message ``msg`` has the fields ``w`` writes (numbers within a
    millionth, `{above: X}`, `{below: X}`, `{not: X}`; strings and booleans exactly)."""
    return all(_same(getattr(msg, k), sub) for k, sub in w.value.items())


def _same(got: Any, w: Written) -> bool:
    want = w.value
    if hasattr(got, "__dataclass_fields__"):
        return matches(got, w)
    if isinstance(want, list):
        items = list(got.tolist() if hasattr(got, "tolist") else got)
        flat: list[Written] = []
        for item in want:
            if isinstance(item.value, dict) and "repeat" in item.value and not hasattr(
                    items[0] if items else None, "__dataclass_fields__"):
                flat.extend([item.value["repeat"]] * int(item.value["times"].value))
            else:
                flat.append(item)
        return len(flat) == len(items) and all(_same(g, x) for g, x in zip(items, flat, strict=True))
    if isinstance(want, dict):  # a comparison
        x = float(next(iter(want.values())).value)
        op = next(iter(want))
        g = float(got)
        return {"above": g > x, "below": g < x, "not": not _close(g, x)}[op]
    if isinstance(want, (bool, str)) or isinstance(got, (bool, str)):
        return bool(want == got)
    return _close(float(got), float(want))


def _close(a: float, b: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-9)


def check_matchers(w: Written, topics: Topics, type_name: str, diags: Diagnostics) -> None:
    """An expectation's `fields`: each a field of the type, of its kind (E190, E191)."""
    desc = topics.messages().get(ros2_type_name(type_name))
    if not isinstance(w.value, dict):
        diags.error("E191", f"`fields` is a mapping of {type_name}'s fields, not "
                    f"{_kind(w.value)}", w.span)
        return
    names = {f.name: f for f in desc.fields}
    for k, v in w.value.items():
        f = names.get(k)
        if f is None:
            note = did_you_mean(k, names)
            diags.error("E190", f"{desc.name} has no field `{k}`", v.key_span,
                        *([note] if note else []), _fields_note(desc.fields))
            continue
        t = f.type
        if t.kind == "nested" and t.array == "none":
            check_matchers(v, topics, t.name, diags)
        elif isinstance(v.value, dict) and t.array == "none":
            ops = list(v.value)
            if len(ops) != 1 or ops[0] not in MATCHERS:
                diags.error("E191", f"`{k}`: a value, or one comparison: "
                            f"{', '.join(f'{{{m}: X}}' for m in MATCHERS)}", v.span)
            elif t.kind != "primitive" or t.name == "bool":
                diags.error("E191", f"`{k}` ({_type_words(t)}) is not a number to compare",
                            v.span)
            else:
                _primitive("float64", v.value[ops[0]], f"`{k}.{ops[0]}`", diags)
        else:  # a value as an input would give it: its checks are those of a message's
            topics._field(f, v, desc.name, diags)


def describe(msg: Any, prefix: str = "") -> str:
    """A message's fields that are not zero or empty, nested ones dotted: `linear.x=0.4`."""
    out = []
    for name in getattr(msg, "__dataclass_fields__", {}):
        if name == "__msgtype__":
            continue
        v = getattr(msg, name)
        if hasattr(v, "__dataclass_fields__"):
            inner = describe(v, f"{prefix}{name}.")
            if inner:
                out.append(inner)
        elif hasattr(v, "tolist"):
            if len(v):
                items = v.tolist()
                out.append(f"{prefix}{name}=[{len(items)} items]" if len(items) > 6
                           else f"{prefix}{name}={items}")
        elif isinstance(v, list):
            if v:
                out.append(f"{prefix}{name}=[{len(v)} items]")
        elif v:
            out.append(f"{prefix}{name}={v!r}")
    return ", ".join(out)


def b64(data: bytes) -> str:
    return base64.b64encode(data).decode("ascii")



# ---------------------------------------------------------------------------
# the playback: each message at its time


def topic_rows(entries: Any, until_us: int, topics: Topics) -> list[dict[str, Any]]:
    """The playback entries (schemas/recording.md, "Playback") of the scenario's ros2
    messages: one per interface and time a message arrives, with its CDR and the
    subscription's count. Per subscription, the entry that started last holds (a span
    gives way at its end to what held before); a message by values is sent when its
    entry begins to hold (again), and at the entry's `rate` while it holds; a recorded
    topic's messages come at their recorded spacing from the entry's start."""
    ordered = [(order, e) for order, e in enumerate(entries) if e.interface in topics.interfaces]
    sources: dict[tuple[str, str], list[tuple[int, Any, Any]]] = {}
    for order, e in ordered:
        for s in e.settings:  # (an action's or a service's server: hfsmc/scenario_rpc.py)
            if isinstance(s.value, (Written, RecordedTopic)) and \
                    topics.subscription(e.interface, s.field) is not None:
                sources.setdefault((e.interface, s.field), []).append((order, e, s))
    arrivals: list[tuple[int, int, str, str, bytes]] = []  # t, order, interface, name, cdr
    for (iface, name), srcs in sources.items():
        t = topics.subscription(iface, name)
        assert t is not None
        points = sorted({0, *(e.start_us for _, e, _ in srcs),
                         *(e.end_us for _, e, _ in srcs if e.end_us is not None)})
        points = [p for p in points if p <= until_us] + [until_us + 1]
        previous = None
        for a, b in itertools.pairwise(points):
            live = [x for x in srcs if x[1].start_us <= a and (x[1].end_us is None or a < x[1].end_us)]
            if not live:
                previous = None
                continue
            order, e, s = max(live, key=lambda x: (x[1].start_us, x[0]))
            for at, data in _sends(topics, iface, t, e, s, a, b, previous is not s):
                arrivals.append((at, order, iface, name, data))
            previous = s
    arrivals.sort(key=lambda x: (x[0], x[1]))
    rows: dict[tuple[int, str], dict[str, Any]] = {}
    counts: dict[tuple[str, str], int] = {}
    for at, _, iface, name, data in arrivals:
        n = counts[(iface, name)] = counts.get((iface, name), 0) + 1
        row = rows.setdefault((at, iface), {"t": at, "kind": "snapshot", "interface": iface,
                                            "values": {"subscriptions": {}}})
        row["values"]["subscriptions"][name] = {"cdr": b64(data), "count": n}
    return list(rows.values())


def _sends(topics: Topics, iface: str, t: Ros2Topic, e: Any, s: Any, a: int, b: int,
           fresh: bool) -> list[tuple[int, bytes]]:
    """The messages the source ``s`` (of entry ``e``), holding over [a, b), sends: (time,
    CDR)."""
    if isinstance(s.value, RecordedTopic):
        return [(e.start_us + us, data)
                for us, data in topics.recorded(iface, t, s.value, Diagnostics())
                if a <= e.start_us + us < b]
    if id(s) not in topics.encoded:
        topics.encoded[id(s)] = topics.cdr(topics.build(s.value, t.type, Diagnostics()), t.type)
    data = topics.encoded[id(s)]
    rate = next((x.value for x in e.settings if x.field == "rate"
                 and isinstance(x.value, float)), None)
    out = [a] if fresh else []
    if rate is not None:
        period = 1e6 / rate
        k = max(0, math.ceil((a - e.start_us) / period))
        while (at := e.start_us + round(k * period)) < b:
            if at != a or not fresh:
                out.append(at)
            k += 1
    return [(at, data) for at in out]
