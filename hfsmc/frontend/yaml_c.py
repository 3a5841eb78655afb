"""The fast YAML path: libyaml's C parser (through PyYAML's C extension) read event
by event into the same :class:`Document` the ruamel.yaml path builds.

``hfsmc check``, ``build`` and ``diagram`` read models here; ruamel.yaml's
round-trip loader stays for ``convert``'s in-place edits and for every document
this path does not take as it is:

* a syntax error, a duplicate key, a key that is not a plain string, a `<<`
  merge key, a tag, an anchor or an alias on a snippet or a key, an alias to
  an anchor not closed yet, a `%` directive, a second document, an empty
  value, a value that cannot be constructed, nesting deeper than
  :data:`MAX_C_DEPTH`, more than ``MAX_NODES`` values or :data:`MAX_ALIASED`
  through aliases, a
  tab, a BOM after the start, NEL/LS/PS characters (line breaks for libyaml):
  :func:`load_c` returns a reason and :func:`hfsmc.frontend.yaml.load_yaml`
  parses the text again with ruamel.yaml, so its diagnostics (positions, the words of
  :mod:`hfsmc.frontend.yaml_syntax`, the tag and anchor checks of
  :mod:`hfsmc.frontend.yaml_traps`, the alias-bomb bound) are the only ones;
* PyYAML missing, or built without libyaml: every document.

An alias gives a copy of its anchor's data, with the anchored node's positions
under the alias's path, as ruamel.yaml's tree (where the alias is the anchored
node) gives them to the walker.  Scalars resolve as ruamel.yaml resolves them
in YAML 1.2 (its own table of implicit resolvers), and a value other than a string is constructed by
ruamel.yaml's round-trip constructor, so both paths give the same values,
positions and YAML 1.1 notes (``tests/test_frontend_c.py`` compares them on
every example and every invalid model).
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.nodes import ScalarNode as RuamelScalarNode
from ruamel.yaml.tag import Tag

from hfsmc.errors import Span
from hfsmc.frontend.source import MAX_NODES, YAML11_BOOLS, Document, PathKey
from hfsmc.frontend.yaml_traps import snippet_kind
from hfsmc.frontend.yaml_values import record_value, scalar

try:
    from yaml import (
        AliasEvent,
        MappingEndEvent,
        MappingStartEvent,
        ScalarEvent,
        SequenceEndEvent,
        SequenceStartEvent,
        StreamEndEvent,
        YAMLError,
    )
    from yaml._yaml import CParser
except ImportError:  # PyYAML missing, or built without libyaml
    AVAILABLE = False
else:
    AVAILABLE = True

# Deeper documents go to ruamel.yaml, whose recursion decides where E006 is said.
MAX_C_DEPTH = 100
# Values copied for aliases before the document goes to ruamel.yaml, whose check of the
# expansion counts without copying (an alias bomb costs it nothing).
MAX_ALIASED = 200_000

# Tags a plain scalar may resolve to here; the others (`<<` merge, `=`) go to ruamel.
_CONSTRUCTED = frozenset("tag:yaml.org,2002:" + t for t in ("int", "float", "bool", "null", "timestamp"))
# Characters libyaml reads otherwise than ruamel.yaml: NEL, LS and PS break lines (YAML
# 1.1); tabs and a BOM are accepted in places ruamel refuses; a directive may switch the
# YAML version.
_UNSURE = re.compile("[\t\x85\u2028\u2029\ufeff]|^%", re.MULTILINE)


class _Resolver:
    """ruamel.yaml's YAML 1.2 implicit resolution of plain scalars, and its constructor."""

    def __init__(self) -> None:
        y = YAML(typ="rt")
        y.preserve_quotes = True
        self.table: dict[str, list[tuple[str, re.Pattern[str]]]] = {
            k: [(str(t), rx) for t, rx in v] for k, v in y.resolver.versioned_resolver.items()
            if k is not None}
        self.constructor = y.constructor

    def plain(self, value: str) -> Any:
        """The value of a plain scalar (a str, or ruamel's int, float, bool, None, date)."""
        for tag, rx in self.table.get(value[:1], ()):
            if rx.match(value):
                if tag not in _CONSTRUCTED:
                    raise _Fallback(f"a plain scalar resolved to {tag}")
                node = RuamelScalarNode(Tag(suffix=tag), value)
                try:
                    return self.constructor.construct_object(node, deep=True)
                except Exception:
                    raise _Fallback("a value that cannot be constructed") from None
                finally:
                    self.constructor.constructed_objects.pop(node, None)  # not kept for good
        return value


_resolver: _Resolver | None = None


class _Fallback(Exception):
    """This document is for ruamel.yaml (the message says why)."""


def load_c(doc: Document, text: str) -> str | None:
    """Fill ``doc`` (data and positions) from ``text`` with libyaml.

    Returns None when done, or why the document must go to ruamel.yaml instead
    (``doc`` is then left as it was).
    """
    if not AVAILABLE:
        return "PyYAML with libyaml is not installed"
    if _UNSURE.search(text):
        return "a directive, a tab, a BOM or a NEL/LS/PS character"
    global _resolver
    if _resolver is None:
        _resolver = _Resolver()
    work = Document(doc.file, doc.format, doc.lines)
    try:
        data = _read(work, text, _resolver)
    except _Fallback as e:
        return str(e)
    except YAMLError:
        return "libyaml found an error"
    doc.data = data
    doc.spans.update(work.spans)
    doc.spans[()] = Span(doc.file, 1, 1)
    doc.key_spans.update(work.key_spans)
    doc.segments.update(work.segments)
    doc.cont_cols.update(work.cont_cols)
    doc.yaml11.update(work.yaml11)
    return None


def _read(doc: Document, text: str, resolver: _Resolver) -> Any:
    """The document's data from libyaml's events, positions recorded in ``doc``.

    A frame of ``stack`` is [container, path, is_map, key, anchor] (key None: a
    mapping's key comes next; anchor: the name and :func:`_marks` of an anchored
    collection); the bottom frame holds the root in a one-slot list.
    """
    file = doc.file
    lines = doc.lines
    nlines = len(lines)
    spans = doc.spans
    key_spans = doc.key_spans
    plain = resolver.plain
    anchors: dict[str, _Anchor | None] = {}  # None: still open (an alias to it is recursive)
    parser = CParser(text)
    try:
        get: Callable[[], Any] = parser.get_event  # events are read by their type
        get()  # StreamStartEvent
        ev = get()
        if type(ev) is StreamEndEvent:
            return None
        if ev.version is not None or ev.tags:  # DocumentStartEvent
            raise _Fallback("a directive")
        root: list[Any] = [None]
        stack: list[list[Any]] = [[root, (), False, None, None]]
        nodes = aliased = 0
        while True:
            ev = get()
            t = type(ev)
            top = stack[-1]
            if t is MappingEndEvent or t is SequenceEndEvent:
                stack.pop()
                if top[4] is not None:
                    name, start = top[4]
                    anchors[name] = _Anchor(top[1], top[0], nodes - start[0] + 1,
                                            _since(doc, start))
                continue
            if t is AliasEvent:
                alias = ev.anchor
            elif t is ScalarEvent or t is MappingStartEvent or t is SequenceStartEvent:
                alias = None
                if ev.tag is not None:
                    raise _Fallback("a tag")
            elif len(stack) == 1:
                break  # DocumentEndEvent
            else:
                raise _Fallback(f"an unexpected {t.__name__}")
            mark = ev.start_mark
            line = mark.line
            col = mark.column
            container = top[0]
            is_map = top[2]
            if is_map and top[3] is None:  # a mapping's key
                if t is not ScalarEvent or ev.anchor is not None:
                    raise _Fallback("an alias, an anchor, a mapping or a list as a key")
                key = ev.value
                if not ev.style:
                    key = plain(key)
                    if type(key) is not str:
                        raise _Fallback("a key that is not a string")
                if key in container:
                    raise _Fallback("a duplicate key")
                top[3] = key
                key_spans[(*top[1], key)] = Span(file, line + 1, col + 1)
                continue
            nodes += 1
            if nodes >= MAX_NODES:
                raise _Fallback("too many values")
            if is_map:
                slot = top[3]
                top[3] = None
                path: PathKey = (*top[1], slot)
            elif len(stack) > 1:
                slot = len(container)
                path = (*top[1], slot)
            else:
                path = ()
            out: Any
            anchor = None
            if alias is not None or ev.anchor is not None:
                if snippet_kind(path) is not None:
                    raise _Fallback("an anchor or an alias on a snippet")
                if alias is not None:
                    target = anchors.get(alias)
                    if target is None:
                        raise _Fallback("an alias to an anchor not closed yet")
                    nodes += target.nodes - 1
                    aliased += target.nodes
                    if nodes >= MAX_NODES or aliased > MAX_ALIASED:
                        raise _Fallback("too many values through aliases")
                    out = _copy(target.data)
                    target.replay(doc, path)
                else:
                    anchor = (ev.anchor, _marks(doc, nodes))
                    anchors[ev.anchor] = None
            if alias is not None:
                pass
            elif t is ScalarEvent:
                style = ev.style
                value = ev.value
                if not style:
                    if not value:  # ruamel places it at the next token, or where a comment is
                        raise _Fallback("an empty value")
                    value = plain(value)
                    out = value if type(value) is str else scalar(value)
                else:
                    out = value
                if not path:
                    pass
                elif not style and type(value) is str and value not in YAML11_BOOLS \
                        and (line >= nlines or lines[line].startswith(value, col)):
                    spans[path] = Span(file, line + 1, col + 1)
                else:
                    record_value(doc, path, value, style, line, col)
                if anchor is not None:
                    anchors[anchor[0]] = _Anchor(path, out, 1, _since(doc, anchor[1]))
            else:
                if len(stack) > MAX_C_DEPTH:
                    raise _Fallback("deep nesting")
                if path:
                    spans[path] = Span(file, line + 1, col + 1)
                is_map = t is MappingStartEvent
                out = {} if is_map else []
                stack.append([out, path, is_map, None, anchor])
            if top[2]:
                container[slot] = out
            elif container is root:
                root[0] = out
            else:
                container.append(out)
        if type(get()) is not StreamEndEvent:
            raise _Fallback("more than one document")
        return root[0]
    finally:
        parser.dispose()


_Marks = tuple[int, int, int, int, int, int]
_TABLES = ("spans", "key_spans", "segments", "cont_cols", "yaml11")


def _marks(doc: Document, nodes: int) -> _Marks:
    """The node count and the size of each position table, where an anchored node starts."""
    return (nodes, len(doc.spans), len(doc.key_spans), len(doc.segments), len(doc.cont_cols),
            len(doc.yaml11))


def _since(doc: Document, start: _Marks) -> list[list[tuple[PathKey, Any]]]:
    """The entries each position table got since ``start`` (tables keep insertion order)."""
    out = []
    for name, n in zip(_TABLES, start[1:], strict=True):
        table: dict[PathKey, Any] = getattr(doc, name)
        new = len(table) - n
        out.append(list(itertools.islice(reversed(table.items()), new))[::-1] if new else [])
    return out


@dataclass
class _Anchor:
    """An anchored node: its path, its data and the positions recorded under it."""

    path: PathKey
    data: Any
    nodes: int
    entries: list[list[tuple[PathKey, Any]]]

    def replay(self, doc: Document, at: PathKey) -> None:
        """Record the anchored node's positions again for an alias at ``at``, as
        ruamel.yaml's tree (the alias is the anchored node itself) gives them."""
        cut = len(self.path)
        for name, entries in zip(_TABLES, self.entries, strict=True):
            table: dict[PathKey, Any] = getattr(doc, name)
            for path, value in entries:
                table[(*at, *path[cut:])] = value


def _copy(data: Any) -> Any:
    if type(data) is dict:
        return {k: _copy(v) for k, v in data.items()}
    if type(data) is list:
        return [_copy(v) for v in data]
    return data


def resolves_to_str(value: str) -> bool:
    """Whether ``value`` written as a plain scalar reads back as a string (YAML 1.2, as
    hfsmc reads it): what an editor checks before it writes a string unquoted."""
    global _resolver
    if _resolver is None:
        _resolver = _Resolver()
    try:
        return type(_resolver.plain(value)) is str
    except _Fallback:
        return False
