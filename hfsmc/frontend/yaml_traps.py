"""YAML tags, anchors and aliases that eat a snippet's `!`, `&&` or `*`.

:class:`PropertyScan` follows the parser's events as the document loads
(:class:`WatchedParser` hands them over) and refuses a tag, an anchor or an
alias at the start of a code snippet (``when: !drone.armed() && ...`` is a
tag, an anchor and a condition that lost both: E105), and any tag hfsmc does
not define (E106).  docs/quoting.md explains.  Syntax errors are put in words
by :mod:`hfsmc.frontend.yaml_syntax`.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ruamel.yaml.events import (
    AliasEvent,
    CollectionEndEvent,
    MappingStartEvent,
    NodeEvent,
    ScalarEvent,
    SequenceStartEvent,
)
from ruamel.yaml.parser import RoundTripParser

from hfsmc.errors import Diagnostic, Span
from hfsmc.frontend.source import PathKey

# Keys whose value is code in the model's language (docs/quoting.md).
STATE_SNIPPETS = frozenset({"entry", "during", "exit"})
TRANSITION_SNIPPETS = frozenset({"when", "do"})
ROOT_SNIPPETS = frozenset({"functions", "on_shutdown"})
SNIPPET_KEYS = STATE_SNIPPETS | TRANSITION_SNIPPETS | ROOT_SNIPPETS | {"init"}

# Tags of YAML's core schema: they only say what a plain value already is.
_CORE = "tag:yaml.org,2002:"
ALLOWED_TAGS = frozenset({"!", *(_CORE + t for t in ("str", "int", "float", "bool", "null", "seq", "map"))})

# A tag, an anchor or an alias can start a value only after a space or a flow indicator.
_PROPERTY = re.compile(r"(?:^|[\s\[\]{},])[!&*]", re.MULTILINE)


def may_have_properties(text: str) -> bool:
    """Cheap test: could the document hold a tag, an anchor or an alias at all?"""
    return _PROPERTY.search(text) is not None


def snippet_kind(path: PathKey) -> str | None:
    """The snippet key ``path`` ends in, when the value there is code; else None.

    ``init`` counts (it is code only in a C++ model: the caller decides).
    """
    if not path or not isinstance(path[-1], str):
        return None
    key = path[-1]
    if len(path) == 1:
        return key if key in ROOT_SNIPPETS else None
    if len(path) >= 3 and path[-3] == "states" and key in STATE_SNIPPETS:
        return key
    if len(path) >= 4 and path[-3] == "transitions" and isinstance(path[-2], int) \
            and key in TRANSITION_SNIPPETS:
        return key
    if len(path) == 3 and path[0] == "variables" and key == "init":
        return key
    return None


@dataclass
class _Frame:
    path: PathKey
    is_map: bool
    flow: bool
    key: str | int = "?"
    expect_key: bool = True
    index: int = 0


@dataclass
class PropertyScan:
    """E105 for a tag, anchor or alias on a snippet; E106 for a tag hfsmc does not define.

    Fed the parser's events one by one (:class:`WatchedParser` does it while the
    document loads, so the text is parsed once); :meth:`found` gives the result.
    """

    file: str
    lines: list[str]
    errors: list[Diagnostic] = field(default_factory=list)
    cpp_inits: list[Diagnostic] = field(default_factory=list)
    language: str | None = None
    stack: list[_Frame] = field(default_factory=list)

    def feed(self, ev: Any) -> None:
        stack = self.stack
        if isinstance(ev, CollectionEndEvent):
            if stack:
                stack.pop()
            _advance(stack)
            return
        if not isinstance(ev, NodeEvent):
            return
        path = _node_path(stack)
        _check_node(self, ev, path, stack[-1].flow if stack else False)
        if isinstance(ev, (MappingStartEvent, SequenceStartEvent)):
            here = path if path is not None else (*stack[-1].path, "?")
            if path is None:  # a mapping or list used as a key
                stack[-1].key = "?"
            stack.append(_Frame(here, isinstance(ev, MappingStartEvent), bool(ev.flow_style)))
            return
        if path is None and isinstance(ev, ScalarEvent):
            stack[-1].key = ev.value
        elif path == ("language",) and isinstance(ev, ScalarEvent):
            self.language = ev.value
        _advance(stack)

    def found(self) -> list[Diagnostic]:
        return self.errors + (self.cpp_inits if self.language == "cpp" else [])


class WatchedParser(RoundTripParser):
    """ruamel's round-trip parser, showing each event it hands out to ``watch``."""

    watch: Callable[[Any], None] | None = None

    def get_event(self) -> Any:
        ev = super().get_event()
        if self.watch is not None:
            self.watch(ev)
        return ev


def _node_path(stack: list[_Frame]) -> PathKey | None:
    """Path of the node an event starts; None for a mapping key."""
    if not stack:
        return ()
    top = stack[-1]
    if top.is_map:
        return None if top.expect_key else (*top.path, top.key)
    return (*top.path, top.index)


def _advance(stack: list[_Frame]) -> None:
    """A node of the innermost collection is complete."""
    if not stack:
        return
    top = stack[-1]
    if top.is_map:
        top.expect_key = not top.expect_key
    else:
        top.index += 1


def _check_node(scan: PropertyScan, ev: NodeEvent, path: PathKey | None, flow: bool) -> None:
    tag = getattr(ev, "tag", None)
    tag = str(tag) if tag is not None else None
    anchor = ev.anchor
    mark = ev.start_mark
    col = mark.column
    if tag is not None and anchor is not None:  # the mark is on the anchor; the tag may come first
        written = "!!" + tag[len(_CORE):] if tag.startswith(_CORE) else tag
        at = scan.lines[mark.line].rfind(written, 0, col) if mark.line < len(scan.lines) else -1
        col = at if at >= 0 else col
    span = Span(scan.file, mark.line + 1, col + 1)
    kind = snippet_kind(path) if path is not None else None
    if kind is not None and (tag is not None or anchor is not None):
        d = _snippet_diagnostic(scan, ev, kind, span, flow)
        (scan.cpp_inits if kind == "init" else scan.errors).append(d)
        if kind != "init":
            return
    if tag is not None and tag not in ALLOWED_TAGS:
        shown = "!!" + tag[len(_CORE):] if tag.startswith(_CORE) else tag
        scan.errors.append(Diagnostic(
            "E106", f"YAML tag `{shown}`: hfsmc defines no tags", span, "error",
            ("remove the tag, or quote the value if the `!` belongs to it (docs/quoting.md)",)))


def _snippet_diagnostic(scan: PropertyScan, ev: NodeEvent, kind: str, span: Span, flow: bool) -> Diagnostic:
    tag = getattr(ev, "tag", None)
    parts: list[str] = []
    if tag is not None:
        parts.append(f"`{_source_word(scan.lines, span)}` as a tag")
    if isinstance(ev, AliasEvent):
        parts.append(f"`*{ev.anchor}` as an alias of an anchor")
    elif ev.anchor is not None:
        parts.append(f"`&{ev.anchor}` as an anchor")
    what = " and ".join(parts)
    if isinstance(ev, ScalarEvent) and ev.style:  # quoted or a block: the code is intact
        return Diagnostic("E105", f"YAML reads {what}: hfsmc takes no tags, anchors or aliases "
                          f"on code snippets; remove it from this `{kind}`", span, "error",
                          ("docs/quoting.md says which snippets need quotes",))
    message = f"YAML reads {what}, not as code: quote the whole `{kind}` value"
    notes: list[str] = []
    if isinstance(ev, ScalarEvent):
        left = f"as `{ev.value}`" if ev.value.strip() else "empty"
        notes.append(f"the snippet would be left {left}")
    raw = _rest_of_line(scan.lines, span)
    if raw and not flow:
        notes.append(f"write: {kind}: {quoted(raw)}   (docs/quoting.md)")
    else:
        notes.append("docs/quoting.md says which snippets need quotes")
    return Diagnostic("E105", message, span, "error", tuple(notes))


def _source_word(lines: list[str], span: Span) -> str:
    """The tag as written (`!drone.armed()`), from the source line."""
    rest = _rest_of_line(lines, span)
    return rest.split()[0] if rest else "!"


def quoted(value: str) -> str:
    """``value`` as a YAML quoted scalar that reads back as itself."""
    if "'" not in value or ('"' in value or "\\" in value):
        return "'" + value.replace("'", "''") + "'"
    return '"' + value + '"'


def _rest_of_line(lines: list[str], span: Span) -> str:
    if not 1 <= span.line <= len(lines):
        return ""
    return lines[span.line - 1][span.col - 1:].rstrip()
