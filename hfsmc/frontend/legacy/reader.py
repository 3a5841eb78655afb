"""Element access for the format readers: positions, texts, numbers, diagnostics."""

from __future__ import annotations

import re
from collections.abc import Iterable

from lxml import etree

from hfsmc.errors import Diagnostics, Span
from hfsmc.frontend.legacy.code import Mapped, Pos, edit
from hfsmc.frontend.source import Document
from hfsmc.frontend.xmlsource import Element, XmlIndex, written_name

_ENTITIES = {"&lt;": "<", "&gt;": ">", "&amp;": "&", "&quot;": '"', "&apos;": "'"}
_ESCAPED = re.compile("|".join(_ENTITIES))


def norm_id(uid: str) -> str:
    """An id as the legacy tools compared ids: as a number when it is one."""
    text = uid.strip()
    return str(int(text)) if re.fullmatch(r"[+-]?\d{1,30}", text) else text


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


