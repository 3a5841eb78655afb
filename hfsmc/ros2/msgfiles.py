"""A model's own ROS 2 interface files, read line by line (docs/ros2.md, "Message types"
and "Services and actions"): ``PKG/msg/Name.msg``, ``PKG/srv/Name.srv`` and
``PKG/action/Name.action``, laid out as in a ROS 2 package (the package is the folder
above ``msg/``, ``srv/`` or ``action/``; the file name is the type's name).

A ``.srv`` is two parts (request, response) and an ``.action`` three (goal, result,
feedback), separated by a line ``---``; each part is a ``.msg``. Every line is parsed on its
own with rosbags' message parser, so that a line that does not parse, a name that breaks
ROS 2's rules or a default that does not fit its type is reported at that line of the file.
"""

from __future__ import annotations

import keyword
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from hfsmc.errors import Diagnostics, Span

FileKind = Literal["msg", "srv", "action"]
Scalar = bool | int | float | str
Value = Scalar | tuple[Scalar, ...]

INTEGER_RANGES: dict[str, tuple[int, int]] = {
    "byte": (0, 0xFF), "char": (0, 0xFF), "uint8": (0, 0xFF), "int8": (-0x80, 0x7F),
    "uint16": (0, 0xFFFF), "int16": (-0x8000, 0x7FFF), "uint32": (0, 0xFFFF_FFFF),
    "int32": (-0x8000_0000, 0x7FFF_FFFF), "uint64": (0, 2**64 - 1), "int64": (-(2**63), 2**63 - 1),
}
# The parts of each kind of file, in the order of its `---`-separated sections (rosidl's).
PARTS: dict[FileKind, tuple[str, ...]] = {
    "msg": ("",), "srv": ("Request", "Response"), "action": ("Goal", "Result", "Feedback"),
}
_WHAT = {"msg": "a message", "srv": "a service", "action": "an action"}

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


@dataclass(frozen=True, slots=True)
class MsgFile:
    """A model's own ``.msg``, ``.srv`` or ``.action`` file: where it is, and how to name
    it in an error."""

    path: Path
    shown: str


@dataclass(frozen=True, slots=True)
class Part:
    """One message of a model's file: ``pkg/msg/Name`` (a ``.msg``), ``pkg/srv/Name_Request``,
    ``pkg/action/Name_Goal``... ``text``: its ``.msg`` text (the section of the file)."""

    name: str
    text: str
    refs: tuple[tuple[int, str], ...]  # (line in the file, nested type) as written, normalised
    defaults: dict[str, Value]


@dataclass(frozen=True, slots=True)
class OwnFile:
    """A model's own file, parsed: ``name`` is ``pkg/msg/Name``, ``pkg/srv/Name`` or
    ``pkg/action/Name``; ``parts`` its messages, in the file's order."""

    file: MsgFile
    kind: FileKind
    name: str
    text: str
    parts: tuple[Part, ...]


def read_file(f: MsgFile, diags: Diagnostics) -> OwnFile | None:
    """Read one of a model's files, line by line; None (with diagnostics) when it is wrong."""
    start = len(diags)
    where = Span(f.shown, 1, 1)
    kind = f.path.suffix.lstrip(".")
    if kind not in PARTS or f.path.parent.name != kind:
        diags.error("E311", "a message file is `PACKAGE/msg/Name.msg`, a service "
                    "`PACKAGE/srv/Name.srv`, an action `PACKAGE/action/Name.action`", where)
        return None
    package, short = f.path.parent.parent.name, f.path.stem
    if not _PACKAGE.match(package):
        diags.error("E311", f"package `{package}` (the folder above {kind}/) is not a ROS 2 "
                    "package name (lower case, digits, single underscores)", where)
    if not _MESSAGE.match(short):
        diags.error("E311", f"{_WHAT[kind].split()[1]} name `{short}` is not CamelCase "
                    "(`Detection`)", where)
    try:
        text = f.path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        diags.error("E311", f"cannot read the {_WHAT[kind].split()[1]} file: {exc}", where)
        return None
    fkind: FileKind = "msg" if kind == "msg" else "srv" if kind == "srv" else "action"
    sections = _sections(f, fkind, text, diags)
    parts = []
    for part, (first, lines) in zip(PARTS[fkind], sections, strict=False):
        suffix = f"_{part}" if part else ""
        parts.append(_read_part(f, f"{package}/{kind}/{short}{suffix}",
                                f"{package}/msg/{short}{suffix}", first, lines, diags))
    if len(diags) > start:
        return None
    return OwnFile(f, fkind, f"{package}/{kind}/{short}", text, tuple(parts))


def _sections(f: MsgFile, kind: FileKind, text: str, diags: Diagnostics
              ) -> list[tuple[int, list[str]]]:
    """The file's ``---``-separated sections: (the line number of its first line, its
    lines). A wrong number of sections is E311 at the separator too many, or at the end."""
    lines = text.splitlines()
    out: list[tuple[int, list[str]]] = [(1, [])]
    names = PARTS[kind]
    for no, line in enumerate(lines, 1):
        if line.strip() != "---":
            out[-1][1].append(line)
            continue
        if len(out) == len(names):
            what = ("a message file has no `---` line (that separates the parts of a .srv "
                    "or an .action)" if kind == "msg" else
                    f"{_WHAT[kind]} file has {len(names)} parts ({', '.join(names).lower()}) "
                    f"separated by {len(names) - 1} `---` line{'s' if len(names) > 2 else ''}: "
                    "this one is too many")
            diags.error("E311", what, Span(f.shown, no, len(line) - len(line.lstrip()) + 1))
            return out
        out.append((no + 1, []))
    if len(out) < len(names):
        diags.error("E311", f"{_WHAT[kind]} file has {len(names)} parts "
                    f"({', '.join(names).lower()}) separated by `---` lines: this one has "
                    f"{len(out)}", Span(f.shown, max(len(lines), 1), 1))
    return out


def _read_part(f: MsgFile, name: str, parse_as: str, first: int, lines: list[str],
               diags: Diagnostics) -> Part:
    """One message's lines (``first``: the file's line number of the first), each parsed
    on its own; a nested type's short name is of the file's package (``parse_as``)."""
    from rosbags.typesys.base import Constant as RConstant
    from rosbags.typesys.msg import MSGParser

    refs: list[tuple[int, str]] = []
    defaults: dict[str, Value] = {}
    names: set[str] = set()
    for no, line in enumerate(lines, first):
        span = Span(f.shown, no, len(line) - len(line.lstrip()) + 1)
        try:
            msgs = MSGParser(f"MSG: {parse_as}\n{line}\n").specification()
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
    return Part(name, "\n".join(lines) + "\n", tuple(refs), defaults)


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
