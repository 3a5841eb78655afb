"""ROS 2 message definitions: a distro's standard messages and a model's own ``.msg`` files,
as one neutral, frozen description that the Python and the C++ generators walk
(docs/ros2.md, "Message types").

The definitions of a distro come from rosbags' stores (``rosbags.typesys.stores``), never
from a hand-written copy; so do the RIHS01 type hashes (rosbags computes them as ROS 2
does). The stores drop the default values that a few standard ``.msg`` files give
(``geometry_msgs/Quaternion``'s ``w 1``): :data:`STANDARD_DEFAULTS` puts them back, each
with the upstream line it comes from. A model's own ``.msg`` files are read line by line
with rosbags' parser, so that a line that does not parse is reported at that line.

Only the closure of the types a model uses is described (:func:`message_set`): a model
that subscribes to ``nav_msgs/msg/Odometry`` gets Odometry, Header, Time, PoseWithCovariance,
Pose, Point, Quaternion, TwistWithCovariance, Twist and Vector3, dependencies first.
"""

from __future__ import annotations

import functools
import keyword
import re
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from hfsmc.errors import CheckError, Diagnostic, Diagnostics, Span, did_you_mean
from hfsmc.ros2 import services

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

DISTROS = ("humble", "jazzy")
DEFAULT_DISTRO = "jazzy"

Kind = Literal["primitive", "string", "wstring", "nested"]
ArrayKind = Literal["none", "fixed", "bounded", "unbounded"]
Scalar = bool | int | float | str
Value = Scalar | tuple[Scalar, ...]

# The primitive types of ROS 2's .msg syntax and their CDR size (= alignment) in bytes.
# `byte` is IDL's octet, `char` IDL's uint8 (ROS 2's .msg-to-IDL mapping).
PRIMITIVE_SIZES: dict[str, int] = {
    "bool": 1, "byte": 1, "char": 1, "int8": 1, "uint8": 1, "int16": 2, "uint16": 2,
    "int32": 4, "uint32": 4, "int64": 8, "uint64": 8, "float32": 4, "float64": 8,
}
INTEGER_RANGES: dict[str, tuple[int, int]] = {
    "byte": (0, 0xFF), "char": (0, 0xFF), "uint8": (0, 0xFF), "int8": (-0x80, 0x7F),
    "uint16": (0, 0xFFFF), "int16": (-0x8000, 0x7FFF), "uint32": (0, 0xFFFF_FFFF),
    "int32": (-0x8000_0000, 0x7FFF_FFFF), "uint64": (0, 2**64 - 1), "int64": (-(2**63), 2**63 - 1),
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

# Field names the generated Python or C++ could not carry (ROS 2 packages avoid them too).
_CPP_KEYWORDS = """
    alignas alignof and and_eq asm auto bitand bitor bool break case catch char char8_t
    char16_t char32_t class compl concept const consteval constexpr constinit const_cast
    continue co_await co_return co_yield decltype default delete do double dynamic_cast
    else enum explicit export extern false float for friend goto if inline int long mutable
    namespace new noexcept not not_eq nullptr operator or or_eq private protected public
    register reinterpret_cast requires return short signed sizeof static static_assert
    static_cast struct switch template this thread_local throw true try typedef typeid
    typename union unsigned using virtual void volatile wchar_t while xor xor_eq"""
_RESERVED = frozenset(keyword.kwlist) | frozenset(_CPP_KEYWORDS.split())
_PACKAGE = re.compile(r"^[a-z](?:[a-z0-9]|_(?!_))*(?<!_)$")
_MESSAGE = re.compile(r"^[A-Z][A-Za-z0-9]*$")
_FIELD = re.compile(r"^[a-z](?:[a-z0-9]|_(?!_))*(?<!_)$")
_CONSTANT = re.compile(r"^[A-Z](?:[A-Z0-9]|_(?!_))*(?<!_)$")
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


@dataclass(frozen=True, slots=True)
class MsgFile:
    """A model's own ``.msg`` file: where it is, and how to name it in an error."""

    path: Path
    shown: str


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
    srvs, acts = _interface_roots(distro, interfaces, roots, diags)
    if diags.has_errors:
        raise CheckError(diags.sorted())
    return MessageSet(distro, tuple(store.describe(n) for n in _closure(store, roots)),
                      srvs, acts)


def _interface_roots(distro: str, interfaces: Iterable[tuple[str, Span]], roots: list[str],
                     diags: Diagnostics) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The services and actions named (E316 for one hfsmc does not have), their
    messages added to ``roots``; an action brings the cancel service and status topic."""
    known = services.shipped(distro)
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
    origins: dict[str, str]  # type -> the .msg file it comes from (none for the distro's)

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
    parsed = [p for f in msg_files if (p := _read_msg(f, diags)) is not None]
    own = {p.name: p for p in parsed}
    known = set(base.fielddefs) | set(own)
    for p in parsed:
        if p.name in base.fielddefs:
            diags.error("E311", f"`{p.name}` is a standard message of {distro}: give the "
                        "package another name", Span(p.file.shown, 1, 1))
        for line, ref in p.refs:
            if ref not in known:
                notes = [n for n in (did_you_mean(ref, known),) if n]
                diags.error("E311", f"unknown message type `{ref}`", Span(p.file.shown, line, 1),
                            *notes)
    if diags.has_errors:
        raise CheckError(diags.sorted())
    from rosbags.typesys import get_types_from_msg

    for p in parsed:
        store.register(get_types_from_msg(p.text, p.name))
        defaults.update({(p.name, f): v for f, v in p.defaults.items()})
    return _Store(distro, store, defaults, {p.name: p.file.shown for p in parsed})


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


# ---------------------------------------------------------------------------
# a model's own .msg files


@dataclass(frozen=True, slots=True)
class _Parsed:
    file: MsgFile
    name: str
    text: str
    refs: tuple[tuple[int, str], ...]  # (line, nested type) as written, normalised
    defaults: dict[str, Value]


def _read_msg(f: MsgFile, diags: Diagnostics) -> _Parsed | None:
    """Read one ``.msg`` file, line by line; None (with diagnostics) when it is wrong."""
    from rosbags.typesys.base import Constant as RConstant
    from rosbags.typesys.msg import MSGParser

    start = len(diags)
    where = Span(f.shown, 1, 1)
    if f.path.suffix != ".msg" or f.path.parent.name != "msg":
        diags.error("E311", "a message file is `PACKAGE/msg/Name.msg`", where)
        return None
    package, short = f.path.parent.parent.name, f.path.stem
    if not _PACKAGE.match(package):
        diags.error("E311", f"package `{package}` (the folder above msg/) is not a ROS 2 "
                    "package name (lower case, digits, single underscores)", where)
    if not _MESSAGE.match(short):
        diags.error("E311", f"message name `{short}` is not CamelCase (`Detection`)", where)
    try:
        text = f.path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        diags.error("E311", f"cannot read the message file: {exc}", where)
        return None
    name = f"{package}/msg/{short}"
    refs: list[tuple[int, str]] = []
    defaults: dict[str, Value] = {}
    names: set[str] = set()
    for no, line in enumerate(text.splitlines(), 1):
        span = Span(f.shown, no, len(line) - len(line.lstrip()) + 1)
        try:
            msgs = MSGParser(f"MSG: {name}\n{line}\n").specification()
        except Exception:  # rosbags raises TypesysError (and a few others on odd input)
            diags.error("E311", "not a ROS 2 .msg line: `TYPE NAME [DEFAULT]` or "
                        "`TYPE NAME=VALUE`", span)
            continue
        items: list[Any] = [*msgs[0].constants, *msgs[0].fields]
        for item in items:
            if item.name in names:
                diags.error("E311", f"`{item.name}` is defined twice", span)
            names.add(item.name)
            if isinstance(item, RConstant):
                if not _CONSTANT.match(item.name):
                    diags.error("E311", f"constant `{item.name}` is not UPPER_CASE", span)
                _check_value(str(item.typ.value), item.value, span, diags)
            else:
                _read_field(item, no, span, diags, refs, defaults)
    if len(diags) > start:
        return None
    return _Parsed(f, name, text, tuple(refs), defaults)


def _read_field(item: Any, no: int, span: Span, diags: Diagnostics,
                refs: list[tuple[int, str]], defaults: dict[str, Value]) -> None:
    """One field line: its name, the nested type it names, its default."""
    from rosbags.typesys.base import BaseType, Cardinality

    if not _FIELD.match(item.name):
        diags.error("E311", f"field `{item.name}` is not lower_case (ROS 2 field names)", span)
    elif item.name in _RESERVED:
        diags.error("E311", f"field `{item.name}` is a keyword of Python or C++: the generated "
                    "messages could not have it", span)
    ref = item.typ.ref
    if not isinstance(ref, BaseType):
        if ref.name.rsplit("/", 1)[-1] == "wstring":
            diags.error("E311", "`wstring` is not supported yet (docs/ros2.md)", span)
        else:
            refs.append((no, ref.name))
        if item.value is not None:
            diags.error("E311", "a nested message has no default value", span)
        return
    if item.value is None:
        return
    base = str(ref.name.value)
    if item.typ.cardinality == Cardinality.SCALAR:
        _check_value(base, item.value, span, diags)
        bound = int(item.typ.str_size)
        if bound and isinstance(item.value, str) and len(item.value) > bound:
            diags.error("E311", f"the default is longer than string<={bound}", span)
        defaults[item.name] = item.value
    elif not isinstance(item.value, list):
        diags.error("E311", "an array's default is a list: `[1, 2]`", span)
    else:
        _check_array_default(item.typ, base, item.value, span, diags)
        defaults[item.name] = tuple(item.value)


def _check_array_default(typ: Any, base: str, value: list[Scalar], span: Span,
                         diags: Diagnostics) -> None:
    from rosbags.typesys.base import Cardinality

    n = int(typ.size)
    if typ.cardinality == Cardinality.ARRAY and len(value) != n:
        diags.error("E311", f"the default has {len(value)} values for an array of {n}", span)
    elif typ.cardinality == Cardinality.SEQUENCE and n and len(value) > n:
        diags.error("E311", f"the default has {len(value)} values for at most {n}", span)
    for v in value:
        _check_value(base, v, span, diags)


def _check_value(base: str, value: Any, span: Span, diags: Diagnostics) -> None:
    """A default or constant value fits its type."""
    if base in INTEGER_RANGES:
        lo, hi = INTEGER_RANGES[base]
        if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
            diags.error("E311", f"`{value}` is not a value of type {base} ({lo}..{hi})", span)
    elif base == "bool":
        if not isinstance(value, bool):
            diags.error("E311", f"`{value}` is not a bool (true or false)", span)
    elif base in ("float32", "float64"):
        if isinstance(value, bool) or not isinstance(value, int | float):
            diags.error("E311", f"`{value}` is not a number", span)
    elif not isinstance(value, str):
        diags.error("E311", f"`{value}` is not a string (quote it)", span)
