"""An XML model's elements with their exact ranges (start tag to end tag, every
attribute value), and the names it defines and refers to (:class:`XmlNames`, the XML
twin of :class:`hfsmc.edit.references.Index`).

lxml's ``sourceline`` gives a line, not a range, so a small tokenizer reads the text:
comments, CDATA and processing instructions are skipped whole, so a tag written inside
them is not taken for one."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

from hfsmc.edit.references import Element, Names, Ref
from hfsmc.edit.text import EditError
from hfsmc.frontend.source import PathKey
from hfsmc.frontend.yaml_ranges import Node

_TAG = re.compile(r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>|<!DOCTYPE[^>]*>"
                  r"|<(/?)([A-Za-z_][\w.:-]*)((?:\s+[^\s=/>]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*)\s*(/?)>",
                  re.DOTALL)
_ATTR = re.compile(r"([^\s=/>]+)\s*=\s*(\"([^\"]*)\"|'([^']*)')")
# active("A/B") in code, its quotes written as they are or as &quot; / &apos;
ACTIVE = re.compile(r"""\bactive\(\s*(["']|&quot;|&apos;)([A-Za-z0-9_/]*)\1\s*\)""")
_DOLLAR = re.compile(r"(?<!\$)\$([A-Za-z_][A-Za-z0-9_]*)")
SNIPPETS = ("entry", "during", "exit", "when", "do", "functions", "on_shutdown")
TEXTS = (*SNIPPETS, "description", "import")
DECLARATIONS = {"parameter": "parameters", "variable": "variables", "interface": "interfaces"}


@dataclass(eq=False)
class XElement:
    """One element as written."""

    tag: str
    start: int  # `<` of the start tag
    open_end: int  # after the start tag's `>`
    end: int = 0  # after the end tag's `>` (the start tag's for an empty element)
    close_start: int = 0  # `<` of the end tag (== end for an empty element)
    attrs: dict[str, tuple[int, int, str]] = field(default_factory=dict)  # value's range, raw value
    children: list[XElement] = field(default_factory=list)
    parent: XElement | None = None

    def kids(self, *tags: str) -> list[XElement]:
        return [c for c in self.children if c.tag in tags]

    def attr(self, name: str) -> str | None:
        a = self.attrs.get(name)
        return a[2] if a else None

    @property
    def empty(self) -> bool:
        return self.end == self.open_end


def parse(text: str) -> XElement:
    """The elements of ``text`` with their ranges (raises EditError when tags do not match)."""
    root = XElement("#document", 0, 0, len(text), len(text))
    stack = [root]
    for m in _TAG.finditer(text):
        if m.group(2) is None:
            continue
        closing, tag, attrs, empty = m.group(1), m.group(2), m.group(3), m.group(4)
        if closing:
            if len(stack) < 2 or stack[-1].tag != tag:
                raise EditError(f"unbalanced </{tag}> at offset {m.start()}")
            el = stack.pop()
            el.close_start, el.end = m.start(), m.end()
            continue
        el = XElement(tag, m.start(), m.end(), parent=stack[-1])
        base = m.start(3)
        for a in _ATTR.finditer(attrs):
            g = 3 if a.group(3) is not None else 4
            el.attrs[a.group(1)] = (base + a.start(g), base + a.end(g), a.group(g))
        stack[-1].children.append(el)
        if empty:
            el.end = el.close_start = m.end()
        else:
            stack.append(el)
    if len(stack) != 1:
        raise EditError(f"<{stack[-1].tag}> is never closed")
    return root


class XmlNames(Names):
    """The states, regions, declarations and references of an XML model's text."""

    def __init__(self, text: str) -> None:
        self.text = text
        doc = parse(text)
        hfsm = doc.kids("hfsm")
        if not hfsm:
            raise EditError("not an hfsm XML model")
        self.root = hfsm[0]
        self.refs: list[Ref] = []
        self.elements: dict[str, Element] = {}
        self.names: dict[str, str] = {}
        self.types: dict[str, str] = {}
        self.xml: dict[str, XElement] = {}  # state or region path -> its element
        for el in self.root.children:
            kind = el.tag
            if kind in DECLARATIONS and "name" in el.attrs:
                s, e, name = el.attrs["name"]
                self.names.setdefault(name, kind)
                if kind == "interface" and el.attr("type"):
                    self.types[name] = el.attr("type") or ""
                self.refs.append(Ref(kind, name, s, e, True, "key", (DECLARATIONS[kind], name)))
        autos = self.root.kids("automaton")
        for auto in autos[:1]:
            self._automaton(auto, "", ())
            if "on_interrupt" in auto.attrs:
                self._attr_ref(auto, "on_interrupt", "", ("on_interrupt",))
        for el in self.root.kids("functions", "on_shutdown"):
            self._snippet(el, "", (el.tag,))

    def _attr_ref(self, el: XElement, name: str, prefix: str, dpath: PathKey) -> None:
        s, e, value = el.attrs[name]
        self.refs.append(Ref("state", prefix + value, s, e, False, name, dpath))

    def _automaton(self, auto: XElement, prefix: str, dpath: PathKey) -> None:
        if "initial" in auto.attrs:
            self._attr_ref(auto, "initial", prefix, (*dpath, "initial"))
        for st in auto.kids("state"):
            self._state(st, prefix, (*dpath, "states", st.attr("name") or ""))

    def _state(self, st: XElement, prefix: str, dpath: PathKey) -> None:
        name = st.attr("name") or ""
        path = prefix + name
        self._define("state", path, st, dpath, st.attr("use"))
        if "use" in st.attrs:
            s, e, value = st.attrs["use"]
            self.refs.append(Ref("file", value, s, e, False, "use", (*dpath, "use")))
        for i, t in enumerate(st.kids("transition")):
            tpath = (*dpath, "transitions", i)
            if "to" in t.attrs:
                self._attr_ref(t, "to", prefix, (*tpath, "to"))
            for sn in t.kids("when", "do"):
                self._snippet(sn, prefix, (*tpath, sn.tag))
        for sn in st.kids("entry", "during", "exit"):
            self._snippet(sn, prefix, (*dpath, sn.tag))
        for w in st.kids("with"):
            if "value" in w.attrs:
                s, _, value = w.attrs["value"]
                for m in _DOLLAR.finditer(value):
                    self.refs.append(Ref("parameter", m.group(1), s + m.start(1), s + m.end(1), False,
                                         "with", (*dpath, "with", w.attr("name") or "")))
        for sub in st.kids("automaton")[:1]:
            self._automaton(sub, path + "/", dpath)
        for reg in st.kids("region"):
            rname = reg.attr("name") or ""
            rdpath = (*dpath, "regions", rname)
            self._define("region", path + "/" + rname, reg, rdpath, None)
            self._automaton(reg, path + "/" + rname + "/", rdpath)

    def _define(self, kind: str, path: str, el: XElement, dpath: PathKey, use: str | None) -> None:
        s, e, name = el.attrs.get("name", (el.start + 1, el.start + 1 + len(el.tag), ""))
        key = Node("scalar", s, e, "", name)
        self.elements.setdefault(path, Element(kind, path, dpath, Node("map", el.start, el.end, "block"),
                                               key, use))
        self.xml.setdefault(path, el)
        self.refs.append(Ref(kind, path, s, e, True, "key", dpath))

    def _snippet(self, el: XElement, prefix: str, dpath: PathKey) -> None:
        if el.empty:
            return
        for m in ACTIVE.finditer(self.text, el.open_end, el.close_start):
            pos = m.start(2)
            walked = ""
            for seg in m.group(2).split("/"):
                if seg:
                    walked = f"{walked}/{seg}" if walked else seg
                    self.refs.append(Ref("state", walked, pos, pos + len(seg), False, "active", dpath))
                pos += len(seg) + 1
        self.snippet_names(self.text, el.open_end, el.close_start, dpath,
                           _as_code(self.text[el.open_end:el.close_start]))


_ENTITY = re.compile(r"<!\[CDATA\[.*?\]\]>|&(quot|apos|amp|lt|gt);", re.S)


def _as_code(text: str) -> str:
    """Snippet ``text`` with its entities outside CDATA read as the code they stand for, at
    the same offsets: `&quot;a&quot;` becomes `     "a     "`, so that a string written
    with entities is a string when names are searched."""
    def same_length(m: re.Match[str]) -> str:
        if m.group(1) is None:  # a CDATA section: its text is the code as written
            return m.group(0)
        return " " * (len(m.group(0)) - 1) + {"quot": '"', "apos": "'"}.get(m.group(1), " ")
    return _ENTITY.sub(same_length, text)
