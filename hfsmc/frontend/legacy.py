"""Legacy VisualStates and VisualHFSM files as version-1 models (SPEC 2.7).

A legacy file is told by its root element (``<VisualStates>``, ``<VisualHFSM>``)
and read in two steps:

1. a reader per format (:mod:`.legacy_visualstates`, :mod:`.legacy_visualhfsm`)
   walks the tree, direct children only, and turns it into a small neutral
   form (:class:`Legacy`: levels of states, namespaces, interfaces), reporting
   everything broken with its position;
2. :class:`~.legacy_map.Assembler` maps that form, the same way for both
   formats, onto the version-1 data a YAML model gives (names from
   :mod:`.legacy_names`, code rewritten by :mod:`.legacy_code`), with a span
   for every value and key and the segments of every code text, so that the
   ordinary pipeline (schema, builder, passes, back ends) runs unchanged and
   every diagnostic or traceback lands in the legacy file.

What the mapping did is written to ``Document.notes`` (the ``convert`` report);
what matters to a user is a warning (W205-W208).  The decisions are listed in
``docs/legacy.md``.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from lxml import etree

from hfsmc.errors import Diagnostics, Span
from hfsmc.frontend.legacy_code import (
    Mapped,
    Pos,
    Ref,
    edit,
)
from hfsmc.frontend.source import Document
from hfsmc.frontend.xmlsource import Element, XmlIndex, written_name
from hfsmc.ir import DEFAULT_ROOT_PERIOD_MS

DEFAULT_PERIOD_MS = DEFAULT_ROOT_PERIOD_MS
_ENTITIES = {"&lt;": "<", "&gt;": ">", "&amp;": "&", "&quot;": '"', "&apos;": "'"}
_ESCAPED = re.compile("|".join(_ENTITIES))


def load_legacy(root: Element, index: XmlIndex, diags: Diagnostics) -> Document:
    """The version-1 model of a ``<VisualStates>`` or ``<VisualHFSM>`` document."""
    kind = etree.QName(root).localname
    doc = Document(index.src.file, "visualstates" if kind == "VisualStates" else "visualhfsm",
                   index.src.lines())
    doc.spans[()] = index.span(root)
    doc.data = {}
    reader = Reader(doc, index, diags, kind)
    if kind == "VisualStates" and root.find("state") is None \
            and root.find("SubAutomata") is not None:
        # VisualStates' C++ editor (2016-2017) saved VisualHFSM 5's layout under this root
        from hfsmc.frontend.legacy_visualhfsm import read
    elif kind == "VisualStates":
        from hfsmc.frontend.legacy_visualstates import read
    else:
        from hfsmc.frontend.legacy_visualhfsm3 import is_visualhfsm3
        if is_visualhfsm3(root):
            from hfsmc.frontend.legacy_visualhfsm3 import read
        else:
            from hfsmc.frontend.legacy_visualhfsm import read
    legacy = read(reader, root)
    if legacy is not None and not diags.has_errors:
        from hfsmc.frontend.legacy_map import Assembler

        doc.data = Assembler(reader, legacy).model()
    return doc


# ---------------------------------------------------------------------------
# the neutral form the readers produce


@dataclass(eq=False)
class Member:
    """A variable, function or interface of a legacy namespace."""

    name: str  # as the legacy code names it
    kind: str  # variable | function | interface | init (defined by a statement) | implicit
    span: Span
    value: Any = None  # a variable's value (data for the model's `variables`)
    value_span: Span | None = None
    final: str = ""  # its name in the model


@dataclass(eq=False)
class Space:
    """A namespace: the global one (``self.globalNamespace``, VisualHFSM's automaton)
    or the local one of a VisualStates level (``self.namespace``)."""

    owner: str  # the owning state's name ("" for the global namespace): prefix of renamed members
    where: str  # for messages
    span: Span
    functions: list[Mapped] = field(default_factory=list)
    variables: list[Mapped] = field(default_factory=list)
    members: dict[str, Member] = field(default_factory=dict)
    inits: list[Mapped] = field(default_factory=list)  # statements that run at load
    ctx: Context | None = None  # how its own functions name things


@dataclass(eq=False)
class Context:
    """Where each kind of reference looks a name up, in order (see legacy_code.Ref)."""

    scopes: dict[str, tuple[Space, ...]]
    state: bool = False  # the code of a state or transition (not a namespace's functions)

    def find(self, ref: Ref) -> Member | None:
        for space in self.scopes.get(ref.scope, ()):
            member = space.members.get(ref.name)
            if member is not None:
                return member
        return None


@dataclass(eq=False)
class Interface:
    candidates: tuple[str, ...]  # the names code may use for it, preferred first
    type: str  # ros_topic | ice
    url: str | None
    options: dict[str, str]
    span: Span
    what: str  # "ROS topic `/odom`" (for messages)
    msg_import: tuple[str, Span] | None = None  # the ROS message type's import
    member: Member | None = None


@dataclass(eq=False)
class Transition:
    span: Span
    name: str | None
    target: LState
    target_span: Span
    after_ms: int | None = None
    after_span: Span | None = None
    cond: Mapped | None = None
    cond_is_body: bool = False  # VisualStates: the body of a function returning a bool
    code: Mapped | None = None


@dataclass(eq=False)
class LState:
    uid: str  # the legacy id
    written: str  # the name as written
    span: Span  # of the name
    code: Mapped | None
    ctx: Context
    transitions: list[Transition] = field(default_factory=list)
    child: Level | None = None
    name: str = ""  # its name in the model


@dataclass(eq=False)
class Level:
    """A sub-automaton: a VisualStates state's children, or a VisualHFSM SubAutomata."""

    span: Span
    states: list[LState] = field(default_factory=list)
    initial: LState | None = None
    initial_span: Span | None = None
    period_ms: int | None = None  # None: the parent's
    period_span: Span | None = None


@dataclass(eq=False)
class Legacy:
    root: Level
    spaces: list[Space]  # the global namespace first
    interfaces: list[Interface]
    libraries: list[tuple[str, Span]]
    history: bool  # what re-entering a composite state does in the legacy tool
    implicit_imports: tuple[str, ...]  # modules the legacy tool's generated code imported
    dropped: list[tuple[Span, str]] = field(default_factory=list)  # for the report
    language: str | None = None  # the code's language when the format fixes it
    language_why: str = ""
    ros_dependencies: list[tuple[str, Span]] = field(default_factory=list)  # ROS packages


# ---------------------------------------------------------------------------
# reading elements, with positions and diagnostics


def _char_offsets(text: str, start: int, n: int) -> list[int]:
    """Source offsets of the first ``n`` content characters from ``start``, and of the end
    (CDATA markers, comments and PIs take none; a reference or a CRLF takes one)."""
    out: list[int] = []
    i, cdata = start, False
    size = len(text)
    while len(out) < n and i < size:
        if cdata and text.startswith("]]>", i):
            cdata, i = False, i + 3
        elif not cdata and text.startswith("<![CDATA[", i):
            cdata, i = True, i + 9
        elif not cdata and text.startswith(("<!--", "<?"), i):
            end = text.find("-->" if text[i + 1] == "!" else "?>", i)
            i = size if end < 0 else end + (3 if text[i + 1] == "!" else 2)
        else:
            out.append(i)
            if not cdata and text[i] == "&":
                end = text.find(";", i)
                i = size if end < 0 else end + 1
            else:
                i += 2 if text.startswith("\r\n", i) else 1
    while len(out) <= n:
        out.append(min(i, size))
    return out


class Reader:
    """Element access for the format readers: positions, texts, numbers, diagnostics."""

    def __init__(self, doc: Document, index: XmlIndex, diags: Diagnostics, kind: str) -> None:
        self.doc = doc
        self.index = index
        self.diags = diags
        self.kind = kind
        self.notes = doc.notes
        self.unescaped = False

    def span(self, el: Element) -> Span:
        return self.index.span(el)

    def pos(self, span: Span) -> Pos:
        return span.line, span.col

    def to_span(self, pos: Pos) -> Span:
        return Span(self.doc.file, pos[0], pos[1])

    def error(self, code: str, message: str, span: Span, *notes: str) -> None:
        self.diags.error(code, message, span, *notes)

    def warn(self, code: str, message: str, span: Span, *notes: str) -> None:
        self.diags.warning(code, message, span, *notes)

    def note(self, span: Span, message: str) -> None:
        self.notes.append((span, message))

    def children(self, el: Element, single: Iterable[str], multi: Iterable[str] = (),
                 ignore: Iterable[str] = ("posx", "posy")) -> dict[str, list[Element]]:
        """Direct child elements by tag; a repeated single one is E003, an unknown one W207."""
        single, multi, ignore = set(single), set(multi), set(ignore)
        out: dict[str, list[Element]] = {}
        for child in el.iterchildren(etree.Element):
            tag = str(child.tag)
            if tag in ignore:
                continue
            if tag in single and tag in out:
                self.error("E003", f"`<{tag}>` is given twice in this `<{written_name(el)}>`",
                           self.span(child), f"the first is on line {self.span(out[tag][0]).line}")
            elif tag in single or tag in multi:
                out.setdefault(tag, []).append(child)
            else:
                self.warn("W207", f"`<{written_name(child)}>` in `<{written_name(el)}>` is not part "
                          f"of the {self.kind} format: not carried over", self.span(child))
        return out

    def first(self, groups: dict[str, list[Element]], tag: str) -> Element | None:
        found = groups.get(tag)
        return found[0] if found else None

    def required(self, groups: dict[str, list[Element]], tag: str, parent: Element,
                 what: str) -> Element | None:
        el = self.first(groups, tag)
        if el is None:
            self.error("E102", f"{what} has no `<{tag}>`", self.span(parent))
        return el

    def text(self, el: Element) -> Mapped:
        """The element's text, each character at its place in the file."""
        stray = next(el.iterchildren(etree.Element), None)
        if stray is not None:
            self.error("E101", f"`<{written_name(el)}>` holds text, not elements",
                       self.span(stray))
        raw = el.text or ""
        start = self.index.tag(el).content
        if start is None:
            return Mapped.synth("", self.pos(self.span(el)))
        src = self.index.src
        offsets = _char_offsets(src.text, start, len(raw))
        return self._unescape(Mapped(raw, tuple(self.pos(src.span(o)) for o in offsets)))

    def _unescape(self, m: Mapped) -> Mapped:
        """Text escaped twice (``&amp;lt;`` in the file, ``&lt;`` once read): VisualStates'
        editor saved some files so, and unescaped the code again when it read them."""
        found = list(_ESCAPED.finditer(m.text))
        if not found:
            return m
        edits = [(e.start(), e.end(), Mapped(_ENTITIES[e.group()], (m.pos[e.start()],
                                                                     m.pos[e.end()])))
                 for e in found]
        if not self.unescaped:
            self.unescaped = True
            self.note(self.to_span(m.at(found[0].start())),
                      f"code escaped twice (`{found[0].group()}` once read): unescaped again, "
                      "as VisualStates did")
        return edit(m, edits)

    def value(self, el: Element) -> tuple[str, Span]:
        """The element's text, stripped, and where it starts."""
        m = self.text(el).strip()
        return m.text, self.to_span(m.start) if m.text else self.span(el)

    def attr(self, el: Element, name: str) -> tuple[str | None, Span]:
        value = el.get(name)
        return value, self.index.attribute(el, name)[1]

    def flag(self, el: Element, name: str) -> bool:
        """``initial="True"`` (VisualStates) or ``"true"`` (VisualHFSM)."""
        value, span = self.attr(el, name)
        if value is None:
            return False
        if value.strip().lower() in ("true", "false"):
            return value.strip().lower() == "true"
        self.error("E103", f"`{name}` must be True or False, not {value!r}", span)
        return False

    def milliseconds(self, el: Element, what: str, code: str = "E110") -> tuple[int | None, Span]:
        """A whole number of milliseconds written in the element, or a positioned error."""
        text, span = self.value(el)
        try:
            number = float(text)
        except ValueError:
            number = None
        if number is None or number != number or abs(number) > 3.2e10:
            self.error(code, f"{what} `{text}` is not a number of milliseconds", span)
            return None, span
        if number < 0 or number != int(number):
            self.error("E111", f"{what} `{text}` must be a whole, positive number of "
                       "milliseconds", span)
            return None, span
        return int(number), span


