"""Safe XML reading with positions, shared by the XML front ends.

lxml only knows each element's line, so columns come from the source text:
:class:`XmlSource` blanks out comments, CDATA and processing instructions,
after which the n-th start tag in the text is the n-th element of the tree.
Before lxml sees the text, anything that could make a parser fetch or expand
something (DOCTYPE, entity declarations and references, XInclude) is refused.
"""

from __future__ import annotations

import re
import textwrap
from bisect import bisect_right
from dataclasses import dataclass
from typing import Any

from lxml import etree

from hfsmc.errors import ParseError, Span, fail
from hfsmc.frontend.source import MAX_NODES

Element = etree._Element

_XINCLUDE = ("http://www.w3.org/2001/XInclude", "http://www.w3.org/2003/XInclude")


def safe_parser() -> etree.XMLParser:
    """A parser that never loads, fetches or expands anything."""
    return etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False,
                           dtd_validation=False, huge_tree=False, remove_comments=True,
                           remove_pis=True, encoding="utf-8")


# ---------------------------------------------------------------------------
# the source text


_HIDDEN = re.compile(r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>", re.S)
_BREAK = re.compile(r"\r\n?|\n")  # XML's line breaks (not str.splitlines()'s many)


def _blank(m: re.Match[str]) -> str:
    return re.sub(r"[^\r\n]", " ", m.group())


class XmlSource:
    """The text, offset → line:col, and a copy with comments, CDATA and PIs blanked."""

    def __init__(self, file: str, text: str) -> None:
        self.file = file
        self.text = text
        self.starts = [0, *(m.end() for m in _BREAK.finditer(text))]
        self.masked = _HIDDEN.sub(_blank, text)  # same length, so offsets agree

    def span(self, offset: int) -> Span:
        i = bisect_right(self.starts, offset) - 1
        return Span(self.file, i + 1, offset - self.starts[i] + 1)

    def lines(self) -> list[str]:
        return _BREAK.split(self.text)


# ---------------------------------------------------------------------------
# refusing what could fetch or expand


_DECLARATION = re.compile(r"<!(DOCTYPE|ENTITY|ELEMENT|ATTLIST|NOTATION)\b", re.I)
_ENTITY_REF = re.compile(r"&([^#\s;&<>\"']+);")
_PREDEFINED = {"amp", "lt", "gt", "quot", "apos"}


def refuse_declarations(src: XmlSource) -> None:
    """E004 for a DTD or a named entity, found in the text before any parsing."""
    m = _DECLARATION.search(src.masked)
    if m:
        fail(ParseError, "E004", f"`<!{m.group(1)}` is not allowed: hfsm files take no DTD, so "
             "nothing is ever fetched or expanded", src.span(m.start()))
    for m in _ENTITY_REF.finditer(src.masked):
        if m.group(1) not in _PREDEFINED:
            fail(ParseError, "E004", f"entity reference `&{m.group(1)};` is not allowed",
                 src.span(m.start()), "only &amp; &lt; &gt; &quot; &apos; and character "
                 "references such as &#233; (or CDATA for code)")


_LIBXML_POS = re.compile(r", line \d+, column \d+$")


def parse_safely(src: XmlSource) -> Element:
    try:
        return etree.fromstring(src.text.encode("utf-8", "surrogatepass"), safe_parser())
    except etree.XMLSyntaxError as e:
        line, col = e.position if e.position else (e.lineno or 1, 1)
        span = Span(src.file, max(line, 1), max(col, 1))
        msg = _LIBXML_POS.sub("", str(e.msg or "malformed XML"))
        if "Excessive depth" in msg:
            fail(ParseError, "E006", "the document nests deeper than 256 elements", span)
        fail(ParseError, "E002", msg, span)


def refuse_after_parse(root: Element, index: XmlIndex) -> None:
    """Belt and braces: a DTD the text scan missed, entity nodes, XInclude."""
    info: Any = root.getroottree().docinfo  # lxml-stubs lack DocInfo.doctype
    if info.doctype or info.internalDTD is not None or info.externalDTD is not None:
        fail(ParseError, "E004", "a DTD is not allowed in hfsm files", index.span(root))
    count = 0
    for node in root.iter():
        count += 1
        if isinstance(node, etree._Entity):
            fail(ParseError, "E004", "entity references are not allowed",
                 Span(index.src.file, element_line(node), 1))
        if isinstance(node.tag, str) and etree.QName(node).namespace in _XINCLUDE:
            fail(ParseError, "E004", "XInclude is not allowed: an hfsm file is self-contained",
                 index.span(node))
    if count > MAX_NODES:
        fail(ParseError, "E006", f"the document has more than {MAX_NODES} elements",
             index.span(root))


def element_line(el: Element) -> int:
    line = el.sourceline
    return line if isinstance(line, int) and line > 0 else 1


def written_name(el: Element) -> str:
    """An element's name as written (prefix:local)."""
    q = etree.QName(el)
    return f"{el.prefix}:{q.localname}" if el.prefix else q.localname


# ---------------------------------------------------------------------------
# positions


_START_TAG = re.compile(r"<([^\s/>!?][^\s/>]*)")
_ATTRIBUTE = re.compile(r"\s+([^\s=/>]+)\s*=\s*(?:\"([^\"]*)\"|'([^']*)')")
_TAG_END = re.compile(r"\s*(/?)>")


@dataclass(frozen=True, slots=True)
class _Tag:
    attributes: dict[str, tuple[int, int]]  # name -> offsets of the name and of the value
    content: int | None  # offset just after `>`; None for an empty-element tag


class XmlIndex:
    """Source offsets of every element, attribute and element content."""

    def __init__(self, src: XmlSource, root: Element) -> None:
        self.src = src
        self.offsets: dict[Element, int] = {}
        self.tags: dict[Element, _Tag] = {}
        starts = _START_TAG.finditer(src.masked)
        for el, m in zip(root.iter(etree.Element), starts, strict=False):
            if m.group(1).rpartition(":")[2] != etree.QName(el).localname:
                break  # cannot happen for a well-formed file; keep lxml's line numbers
            self.offsets[el] = m.start()

    def span(self, el: Element) -> Span:
        off = self.offsets.get(el)
        if off is None:
            return Span(self.src.file, element_line(el), 1)
        return self.src.span(off)

    def tag(self, el: Element) -> _Tag:
        found = self.tags.get(el)
        if found is None:
            found = self.tags[el] = self._scan(el)
        return found

    def _scan(self, el: Element) -> _Tag:
        off = self.offsets.get(el)
        if off is None:
            return _Tag({}, None)
        text = self.src.masked
        m = _START_TAG.match(text, off)
        i = m.end() if m else off
        attributes: dict[str, tuple[int, int]] = {}
        while (a := _ATTRIBUTE.match(text, i)) is not None:
            value = a.start(2) if a.group(2) is not None else a.start(3)
            attributes[a.group(1)] = (a.start(1), value)
            i = a.end()
        end = _TAG_END.match(text, i)
        return _Tag(attributes, end.end() if end and not end.group(1) else None)

    def written(self, el: Element, name: str) -> str:
        """An attribute's name as written: `xml:lang` for lxml's `{...}lang`."""
        if not name.startswith("{"):
            return name
        local = name.rpartition("}")[2]
        return next((n for n in self.tag(el).attributes if n.rpartition(":")[2] == local), local)

    def attribute(self, el: Element, name: str) -> tuple[Span, Span]:
        """Spans of an attribute's name and of its value's first character."""
        offs = self.tag(el).attributes.get(name)
        if offs is None:
            s = self.span(el)
            return s, s
        return self.src.span(offs[0]), self.src.span(offs[1])

    def text(self, el: Element, n: int) -> Span:
        """Span of character ``n`` of the element's text content."""
        start = self.tag(el).content
        if start is None:
            return self.span(el)
        return self.src.span(_text_offset(self.src.text, start, n))


    def has_reference(self, el: Element, n: int) -> bool:
        """Whether the element's first ``n`` text characters hold an entity or character reference."""
        start = self.tag(el).content
        if start is None:
            return False
        end = _text_offset(self.src.text, start, n)
        return "&" in self.src.masked[start:end]


def _after(text: str, marker: str, i: int) -> int:
    j = text.find(marker, i)
    return len(text) if j < 0 else j + len(marker)


def _text_offset(text: str, start: int, n: int) -> int:
    """Source offset of the n-th character of the content starting at ``start``.

    CDATA markers, comments and PIs take no characters of the content; an
    entity or character reference takes one, as does a CRLF.
    """
    i, cdata = start, False
    while i < len(text):
        if cdata and text.startswith("]]>", i):
            cdata, i = False, i + 3
            continue
        if not cdata and text.startswith("<![CDATA[", i):
            cdata, i = True, i + 9
            continue
        if not cdata and text.startswith(("<!--", "<?"), i):
            i = _after(text, "-->" if text[i + 1] == "!" else "?>", i)
            continue
        if n == 0:
            return i
        n -= 1
        if not cdata and text[i] == "&":
            i = _after(text, ";", i)
        else:
            i += 2 if text.startswith("\r\n", i) else 1
    return min(i, len(text))


def clean_text(raw: str) -> tuple[str, int, int]:
    """Element text as the model means it: ``(text, first, margin)``.

    A blank first line (the rest of the start tag's line) and the indentation
    before the closing tag are dropped and the rest is dedented, so that code
    written indented inside XML is ordinary code.  ``first`` is the index in
    ``raw`` of the text's first character, ``margin`` the indentation removed.
    Writers use this to check that a text reads back unchanged.
    """
    if not raw.strip(" \t\n"):
        return "", 0, 0  # only layout: an empty element
    start = 0
    nl = raw.find("\n")
    if nl >= 0 and not raw[:nl].strip(" \t"):
        start = nl + 1
    body = raw[start:]
    last = body.rfind("\n")
    if last >= 0 and not body[last + 1:].strip(" \t"):
        body = body[:last + 1]
    text = textwrap.dedent(body)
    margin = _margin(body, text)
    first_line = body.split("\n", 1)[0]
    indent = len(first_line) - len(first_line.lstrip(" \t"))
    return text, start + min(indent, margin), margin


def _margin(body: str, text: str) -> int:
    """The indentation dedent removed (lines correspond one to one)."""
    for before, after in zip(body.split("\n"), text.split("\n"), strict=False):
        if before.strip(" \t"):
            return len(before) - len(after)
    return 0
