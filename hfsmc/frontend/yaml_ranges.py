"""Where every value and key of a YAML model starts AND ends in its text.

The loading path (:mod:`hfsmc.frontend.yaml_c`, :mod:`hfsmc.frontend.yaml`) records only
where things start, which is all a diagnostic needs and keeps ``hfsmc check`` fast.
An edit needs the whole range of what it replaces (SPEC 8.1: a text splice at known
positions), and the style it was written in: this module reads the text again,
event by event with libyaml's C parser (PyYAML's pure-Python parser where libyaml is
missing or refuses the text), into a small tree of :class:`Node`, addressed by the same
paths as :class:`hfsmc.frontend.source.Document`.

Offsets are indices into the Python string (characters, not bytes).
"""

from __future__ import annotations

import gc
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import yaml

from hfsmc.frontend.source import PathKey

try:
    from yaml._yaml import CParser
except ImportError:  # PyYAML without libyaml
    HAVE_C = False
else:
    HAVE_C = True

_BREAK = re.compile(r"\r\n|\r|\n")


@dataclass(slots=True, eq=False)
class Node:
    """One value as written: a mapping, a list, a scalar or an alias."""

    kind: str  # "map" | "seq" | "scalar" | "alias"
    start: int
    end: int  # just after the last character of the value (a block scalar: its last non-blank)
    style: str  # scalar: "" plain, '"', "'", "|", ">"; map and seq: "flow" or "block"
    value: str = ""  # a scalar's value; an alias's anchor name
    anchor: str | None = None
    keys: list[Node] = field(default_factory=list)  # a mapping's keys
    items: list[Node] = field(default_factory=list)  # a mapping's values, a list's items
    target: Node | None = None  # what an alias names

    def key_index(self, key: str) -> int | None:
        for i, k in enumerate(self.keys):
            if k.value == key:
                return i
        return None

    def get(self, key: str | int) -> Node | None:
        node = self.target if self.kind == "alias" and self.target is not None else self
        if node.kind == "map" and isinstance(key, str):
            i = node.key_index(key)
            return None if i is None else node.items[i]
        if node.kind == "seq" and isinstance(key, int) and 0 <= key < len(node.items):
            return node.items[key]
        return None

    @property
    def flow(self) -> bool:
        return self.style == "flow"


class YamlTree:
    """A YAML text's nodes with their ranges; :meth:`find` walks a Document path."""

    def __init__(self, text: str) -> None:
        self.text = text
        self.line_starts = [0] + [m.end() for m in _BREAK.finditer(text)]
        # Hundreds of thousands of small objects that all stay alive: the cyclic collector's
        # passes over them cost more than the read itself (as in hfsmc/pipeline.py).
        was = gc.isenabled()
        gc.disable()
        try:
            self.root: Node | None = _read(self, text)
        finally:
            if was:
                gc.enable()

    def offset(self, line: int, col: int) -> int:
        """The offset of a 0-based (line, column)."""
        if line >= len(self.line_starts):
            return len(self.text)
        return min(self.line_starts[line] + col, len(self.text))

    def line_of(self, offset: int) -> int:
        """The 0-based line holding ``offset``."""
        lo, hi = 0, len(self.line_starts) - 1
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if self.line_starts[mid] <= offset:
                lo = mid
            else:
                hi = mid - 1
        return lo

    def col_of(self, offset: int) -> int:
        return offset - self.line_starts[self.line_of(offset)]

    def find(self, path: PathKey) -> Node | None:
        """The node at ``path`` (through aliases: the anchored node), or None."""
        node = self.root
        for k in path:
            if node is None:
                return None
            node = node.get(k)
        if node is not None and node.kind == "alias":
            return node.target
        return node

    def shared(self, path: PathKey) -> Node | None:
        """The first alias on ``path`` (its text is written at the anchor), if any."""
        node = self.root
        for k in path:
            if node is None:
                return None
            if node.kind == "alias":
                return node
            node = node.get(k)
        return node if node is not None and node.kind == "alias" else None

    def find_key(self, path: PathKey) -> Node | None:
        """The key node naming ``path`` (a mapping's entry), or None."""
        if not path or not isinstance(path[-1], str):
            return None
        parent = self.find(path[:-1])
        if parent is None or parent.kind != "map":
            return None
        i = parent.key_index(path[-1])
        return None if i is None else parent.keys[i]

    def walk(self) -> Iterator[tuple[PathKey, Node]]:
        """Every (path, node) of the document, aliases not followed."""
        if self.root is None:
            return
        stack: list[tuple[PathKey, Node]] = [((), self.root)]
        while stack:
            path, node = stack.pop()
            yield path, node
            if node.kind == "map":
                stack.extend(((*path, k.value), v) for k, v in zip(node.keys, node.items, strict=True))
            elif node.kind == "seq":
                stack.extend(((*path, i), v) for i, v in enumerate(node.items))


def _events(text: str) -> list[Any]:
    if HAVE_C:
        parser = CParser(text)
        out: list[Any] = []
        try:
            while True:
                ev = parser.get_event()
                if ev is None:
                    return out
                out.append(ev)
                if isinstance(ev, yaml.StreamEndEvent):
                    return out
        except yaml.YAMLError:
            pass  # libyaml refused: the pure-Python parser, which says where it stops
        finally:
            parser.dispose()
    return list(yaml.parse(text, Loader=yaml.SafeLoader))


def _read(tree: YamlTree, text: str) -> Node | None:
    """The root node of ``text``'s first document (raises yaml.YAMLError when malformed)."""
    anchors: dict[str, Node] = {}
    stack: list[Node] = []
    root: Node | None = None
    off = tree.offset
    for ev in _events(text):
        if isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            kind = "map" if isinstance(ev, yaml.MappingStartEvent) else "seq"
            start = _at(off, ev.start_mark)
            node = Node(kind, start, start, "flow" if ev.flow_style else "block", anchor=ev.anchor)
            _attach(stack, node)
            if not stack and root is None:
                root = node
            stack.append(node)
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            node = stack.pop()
            if node.flow:
                node.end = _at(off, ev.end_mark)
            else:
                node.end = max((c.end for c in (*node.keys, *node.items)), default=node.start)
            if node.anchor:
                anchors[node.anchor] = node
        elif isinstance(ev, yaml.ScalarEvent):
            start = _at(off, ev.start_mark)
            end = _at(off, ev.end_mark)
            style = ev.style or ""
            if style in ("|", ">"):
                while end > start and text[end - 1] in " \t\r\n":
                    end -= 1
            node = Node("scalar", start, end, style, ev.value, anchor=ev.anchor)
            if ev.anchor:
                anchors[ev.anchor] = node
            if not stack:
                root = root or node
            else:
                _attach(stack, node)
        elif isinstance(ev, yaml.AliasEvent):
            start = _at(off, ev.start_mark)
            end = _at(off, ev.end_mark)
            name = ev.anchor or ""
            node = Node("alias", start, end, "", name, target=anchors.get(name))
            if stack:
                _attach(stack, node)
        elif isinstance(ev, yaml.DocumentEndEvent) and root is not None:
            break
    return root


def _at(off: Callable[[int, int], int], mark: Any) -> int:
    return off(mark.line, mark.column) if mark is not None else 0


def _attach(stack: list[Node], node: Node) -> None:
    if not stack:
        return
    parent = stack[-1]
    if parent.kind == "map" and len(parent.keys) == len(parent.items):
        parent.keys.append(node)
    else:
        parent.items.append(node)
