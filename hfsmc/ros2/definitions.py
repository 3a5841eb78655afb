"""ROS 2 message definitions: a distro's standard messages and a model's own ``.msg`` files,
as one neutral, frozen description that the Python and the C++ generators walk
(docs/ros2.md, "Message types").

The definitions of a distro come from rosbags' stores (``rosbags.typesys.stores``), never
from a hand-written copy; so do the RIHS01 type hashes (rosbags computes them as ROS 2
does). The stores drop the default values that a few standard ``.msg`` files give
(``geometry_msgs/Quaternion``'s ``w 1``): :data:`STANDARD_DEFAULTS` puts them back, each
with the upstream line it comes from. A model's own ``.msg``, ``.srv`` and ``.action``
files are read line by line (hfsmc/ros2/msgfiles.py), so that a line that does not parse
is reported at that line; their services and actions join the shipped ones.

Only the closure of the types a model uses is described (:func:`message_set`): a model
that subscribes to ``nav_msgs/msg/Odometry`` gets Odometry, Header, Time, PoseWithCovariance,
Pose, Point, Quaternion, TwistWithCovariance, Twist and Vector3, dependencies first.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

from hfsmc.errors import CheckError, Diagnostic, Diagnostics, Span, did_you_mean
from hfsmc.ros2 import services
from hfsmc.ros2.msgfiles import INTEGER_RANGES as INTEGER_RANGES
from hfsmc.ros2.msgfiles import MsgFile as MsgFile
from hfsmc.ros2.msgfiles import OwnFile, read_file
from hfsmc.ros2.msgfiles import Scalar as Scalar
from hfsmc.ros2.msgfiles import Value as Value

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

DISTROS = ("humble", "jazzy")
DEFAULT_DISTRO = "jazzy"

Kind = Literal["primitive", "string", "wstring", "nested"]
ArrayKind = Literal["none", "fixed", "bounded", "unbounded"]

# The primitive types of ROS 2's .msg syntax and their CDR size (= alignment) in bytes.
# `byte` is IDL's octet, `char` IDL's uint8 (ROS 2's .msg-to-IDL mapping).
PRIMITIVE_SIZES: dict[str, int] = {
    "bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
    "int32": 4, "uint32": 4, "int64": 8, "uint64": 8, "float32": 4, "float64": 8,
}

# Defaults that ROS 2's standard .msg files give and rosbags' stores drop (its parse trees
# keep no defaults). Each is the upstream line, per distro: (type, field) -> value.
STANDARD_DEFAULTS: dict[str, dict[tuple[str, str], Scalar]] = {
    "humble": {
        ("geometry_msgs/msg/Quaternion", "w"): 1.0,  # Quaternion.msg: `float64 w 1`
    },
    "jazzy": {
        ("geometry_msgs/msg/Quaternion", "w"): 1.0,  # Quaternion.msg: `float64 w 1`
        ("sensor_msgs/msg/NavSatStatus", "status"): -2,  # `int8 status -2 # STATUS_UNKNOWN`
    },
}

_TYPE_NAME = re.compile(r"^([A-Za-z0-9_]+)/(?:(msg)/)?([A-Za-z0-9_]+)$")


@dataclass(frozen=True, slots=True)
class FieldType:
    """The type of a field. ``name``: the primitive (``float64``), ``string``/``wstring``,
    or the nested message (``geometry_msgs/msg/Vector3``). ``string_bound``: N of
    ``string<=N`` (0: unbounded). ``array``: none, fixed ``T[N]``, bounded ``T[<=N]``,
    unbounded ``T[]``; ``size`` is N (0 for none and unbounded)."""

    kind: Kind
    name: str
    string_bound: int = 0
    array: ArrayKind = "none"
    size: int = 0


@dataclass(frozen=True, slots=True)
class Field:
    """A field; ``default`` is the value the ``.msg`` gives (a tuple for an array), or
    None for the zero of its type (0, 0.0, false, "", empty, the nested default)."""

    name: str
    type: FieldType
    default: Value | None = None


@dataclass(frozen=True, slots=True)
class Constant:
    """A constant (``uint8 OK=0``); ``type`` is a primitive or ``string``."""

    name: str
    type: str
    value: Scalar


@dataclass(frozen=True, slots=True)
class Message:
    """One message type. ``origin``: the distro (``jazzy``) or the ``.msg`` file it comes
    from; ``type_hash``: its RIHS01 hash; ``ros2msg``: its definition with those of its
    nested types, as rosbag2 and MCAP's ``ros2msg`` schemas write it."""

    name: str
    fields: tuple[Field, ...]
    constants: tuple[Constant, ...]
    type_hash: str
    origin: str
    ros2msg: str

    @property
    def package(self) -> str:
        return self.name.split("/")[0]

    @property
    def short(self) -> str:
        return self.name.split("/")[-1]

    @property
    def module(self) -> str:
        """Its Python module's path: ``geometry_msgs/msg``, ``std_srvs/srv``,
        ``nav2_msgs/action`` (a service's or an action's messages live beside it)."""
        return self.name.rsplit("/", 1)[0]

    @property
    def dds_type_name(self) -> str:
        """The DDS type name ROS 2 gives it: ``geometry_msgs::msg::dds_::Twist_``,
        ``std_srvs::srv::dds_::Trigger_Request_``."""
        return f"{self.module.replace('/', '::')}::dds_::{self.short}_"


@dataclass(frozen=True, slots=True)
class MessageSet:
    """The messages a model uses, with everything they contain, dependencies first."""

    distro: str
    messages: tuple[Message, ...]
    services: tuple[str, ...] = ()  # `pkg/srv/Name`: their messages are among `messages`
    actions: tuple[str, ...] = ()  # `pkg/action/Name`

    def get(self, name: str) -> Message:
        for msg in self.messages:
            if msg.name == name:
                return msg
        raise KeyError(name)

    def __iter__(self) -> Iterator[Message]:
        return iter(self.messages)

    def packages(self) -> tuple[str, ...]:
        return tuple(sorted({m.package for m in self.messages}))

    def modules(self) -> tuple[str, ...]:
        """``pkg/msg``, ``pkg/srv``, ``pkg/action``: one Python module each."""
        return tuple(sorted({m.module for m in self.messages}))


def ros2_type_name(name: str) -> str:
    """ROS 2's full name of a message type: ``geometry_msgs/Twist`` (ROS 1) and
    ``geometry_msgs/msg/Twist`` both give the latter; anything else comes back as it is."""
    m = _TYPE_NAME.match(name.strip())
    return f"{m[1]}/msg/{m[3]}" if m else name


@functools.cache
def typestore(distro: str) -> Typestore:
    """rosbags' type store of a distro (``humble``, ``jazzy``)."""
    from rosbags.typesys import Stores, get_typestore

    if distro not in DISTROS:
        raise ValueError(f"unknown ROS 2 distro `{distro}` (known: {', '.join(DISTROS)})")
    store = get_typestore(Stores.ROS2_HUMBLE if distro == "humble" else Stores.ROS2_JAZZY)
    services.register(store, distro)
    return store


def standard_types(distro: str) -> tuple[str, ...]:
    """Every message type of the distro's standard packages, sorted."""
    return tuple(sorted(n for n in typestore(distro).fielddefs if "/msg/" in n))


def message_set(distro: str, uses: Iterable[tuple[str, Span]],
                msg_files: Iterable[MsgFile] = (),
                interfaces: Iterable[tuple[str, Span]] = ()) -> MessageSet:
    """The messages ``uses`` (type names, ROS 1 or ROS 2 style, each with where the model
    names it) need, from the distro and the model's ``msg_files``. Raises CheckError with
    every problem found: an unknown type (with a did-you-mean), a ``.msg`` line that does
    not parse, a ``.msg`` naming a type that does not exist."""
    diags = Diagnostics()
    store = _store_with(distro, tuple(msg_files), diags)
    known = store.known
    roots: list[str] = []
    for name, span in uses:
        full = ros2_type_name(name)
        if full in known:
            roots.append(full)
            continue
        notes = [n for n in (did_you_mean(full, known),) if n]
        diags.error("E310", f"unknown ROS 2 message type `{name}` (distro {distro})", span, *notes)
    srvs, acts = _interface_roots(distro, store.own_interfaces, interfaces, roots, diags)
    if diags.has_errors:
        raise CheckError(diags.sorted())
    return MessageSet(distro, tuple(store.describe(n) for n in _closure(store, roots)),
                      srvs, acts)


def _interface_roots(distro: str, own: tuple[str, ...], interfaces: Iterable[tuple[str, Span]],
                     roots: list[str], diags: Diagnostics
                     ) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The services and actions named (E316 for one neither hfsmc nor the model's files
    have), their messages added to ``roots``; an action brings the cancel service and
    status topic."""
    known = sorted({*services.shipped(distro), *own})
    srvs: set[str] = set()
    acts: set[str] = set()
    for name, span in interfaces:
        if name not in known:
            kind = services.kind_of(name) or "srv"
            same = [k for k in known if services.kind_of(k) == kind]
            notes = [n for n in (did_you_mean(name, same),) if n]
            diags.error("E316", f"unknown ROS 2 {'action' if kind == 'action' else 'service'}"
                        f" type `{name}` (distro {distro}; known: {', '.join(same)})",
                        span, *notes)
            continue
        (acts if services.kind_of(name) == "action" else srvs).add(name)
        roots += services.parts(name)
    if acts:
        srvs.add(services.CANCEL_SERVICE)
        roots += [*services.parts(services.CANCEL_SERVICE), services.STATUS_MESSAGE]
    return tuple(sorted(srvs)), tuple(sorted(acts))


def rosbags_store(distro: str, msg_files: Iterable[MsgFile] = ()) -> Any:
    """rosbags' type store of the distro with the model's own types registered (to read
    and write CDR and rosbags as rosbags does). Raises CheckError as message_set does."""
    diags = Diagnostics()
    return _store_with(distro, tuple(msg_files), diags).rosbags


# ---------------------------------------------------------------------------
# the store: a distro and a model's own types


@dataclass(frozen=True, slots=True)
class _Store:
    distro: str
    rosbags: Any  # a rosbags Typestore: the distro's, plus the model's own types
    defaults: dict[tuple[str, str], Value]  # (type, field) -> the .msg's default
    origins: dict[str, str]  # type -> the model's file it comes from (none for the distro's)
    own_interfaces: tuple[str, ...] = ()  # the model's services and actions: pkg/srv/Name

    @property
    def known(self) -> tuple[str, ...]:
        return tuple(sorted(n for n in self.rosbags.fielddefs if "/msg/" in n))

    def describe(self, name: str) -> Message:
        consts, fields = self.rosbags.fielddefs[name]
        if not fields:  # ROS 2 gives an empty message one byte (rosbags' stores do so too)
            fields = [("structure_needs_at_least_one_member", _UINT8)]
        return Message(
            name=name,
            fields=tuple(Field(f, _field_type(desc), self.defaults.get((name, f)))
                         for f, desc in fields),
            constants=tuple(Constant(c, t, v) for c, t, v in consts),
            type_hash=self.rosbags.hash_rihs01(name),
            origin=self.origins.get(name, self.distro),
            ros2msg=_msgdef(self.rosbags, name),
        )


def _msgdef(store: Any, name: str) -> str:
    """The ``ros2msg`` definition (a recording's schema). rosbags writes none for a
    message that holds a service's or an action's part (``_SendGoal_Request`` holds
    ``_Goal``): those are not recorded as topics yet, and get an empty one."""
    try:
        return str(store.generate_msgdef(name, ros_version=2)[0])
    except AssertionError:
        return ""


_UINT8 = (1, ("uint8", 0))  # rosbags' description of a uint8 field (Nodetype.BASE)


def _store_with(distro: str, msg_files: tuple[MsgFile, ...], diags: Diagnostics) -> _Store:
    from rosbags.typesys import Stores, get_typestore

    base = typestore(distro)
    defaults: dict[tuple[str, str], Value] = dict(STANDARD_DEFAULTS[distro])
    if not msg_files:
        return _Store(distro, base, defaults, {})
    store = get_typestore(Stores.ROS2_HUMBLE if distro == "humble" else Stores.ROS2_JAZZY)
    services.register(store, distro)
    parsed = [p for f in msg_files if (p := read_file(f, diags)) is not None]
    _check_own(distro, base, parsed, diags)
    if diags.has_errors:
        raise CheckError(diags.sorted())
    from rosbags.typesys import get_types_from_msg

    origins: dict[str, str] = {}
    for p in parsed:
        if p.kind == "msg":
            store.register(get_types_from_msg(p.text, p.name))
        else:  # a service's or an action's messages, as rosidl derives them
            store.register(services.types_of(p.name, p.text))
            origins.update({n: p.file.shown for n in services.parts(p.name)})
        for part in p.parts:
            defaults.update({(part.name, f): v for f, v in part.defaults.items()})
        origins[p.name] = p.file.shown
    return _Store(distro, store, defaults, origins,
                  tuple(sorted(p.name for p in parsed if p.kind != "msg")))


def _check_own(distro: str, base: Any, parsed: list[OwnFile], diags: Diagnostics) -> None:
    """E311 for a model's type named like a standard one or like another of its files,
    and for a nested type (a field's) that neither the distro nor the model has."""
    shipped = services.shipped(distro)
    seen: dict[str, OwnFile] = {}
    for p in parsed:
        at = Span(p.file.shown, 1, 1)
        if p.name in base.fielddefs or p.name in shipped:
            kind = {"msg": "message", "srv": "service", "action": "action"}[p.kind]
            diags.error("E311", f"`{p.name}` is a standard {kind} of {distro}: give the "
                        "package another name", at)
        if p.name in seen:
            diags.error("E311", f"`{p.name}` is also defined by {seen[p.name].file.shown}", at)
        seen.setdefault(p.name, p)
    known = {n for n in base.fielddefs if "/msg/" in n} | {
        p.name for p in parsed if p.kind == "msg"}
    for p in parsed:
        for part in p.parts:
            for line, ref in part.refs:
                if ref not in known:
                    notes = [n for n in (did_you_mean(ref, known),) if n]
                    diags.error("E311", f"unknown message type `{ref}`",
                                Span(p.file.shown, line, 1), *notes)


def _closure(store: _Store, roots: list[str]) -> list[str]:
    """The roots and every type they contain, each after the types it contains."""
    order: list[str] = []
    done: set[str] = set()

    def visit(name: str, path: tuple[str, ...]) -> None:
        if name in done:
            return
        if name in path:  # ROS 2 has no recursive types (rosidl refuses them too)
            cycle = " -> ".join((*path[path.index(name):], name))
            raise CheckError([Diagnostic("E311", f"message types contain each other: {cycle}",
                                         Span(store.origins.get(name, name), 1, 1))])
        for _, desc in store.rosbags.fielddefs[name][1]:
            ft = _field_type(desc)
            if ft.kind == "nested":
                visit(ft.name, (*path, name))
        done.add(name)
        order.append(name)

    for root in sorted(set(roots)):
        visit(root, ())
    return order


def _field_type(desc: Any) -> FieldType:
    """rosbags' field description -> ours."""
    from rosbags.interfaces import Nodetype

    array: ArrayKind = "none"
    size = 0
    if desc[0] == Nodetype.ARRAY:
        array, size = "fixed", int(desc[1][1])
        desc = desc[1][0]
    elif desc[0] == Nodetype.SEQUENCE:
        size = int(desc[1][1])
        array = "bounded" if size else "unbounded"
        desc = desc[1][0]
    if desc[0] == Nodetype.NAME:
        return FieldType("nested", str(desc[1]), 0, array, size)
    base, bound = desc[1]
    if base in ("string", "wstring"):
        return FieldType(base, base, int(bound), array, size)
    return FieldType("primitive", str(base), 0, array, size)
