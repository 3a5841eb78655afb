"""Operations on an XML model's text, its formatting kept: a small tokenizer gives every
element's exact range (start tag to end tag) and every attribute value's range, which
lxml's ``sourceline`` alone does not.

Done for XML: rename of a state or region (its `name`, sibling transitions' `to`, the
automaton's `initial`, the root's `on_interrupt`, literal `active()` paths), delete,
move among siblings, add a state, set or clear an attribute (`period`, `initial`,
`history`, `final`, ...) or a snippet (`entry`, `during`, `exit`).  The other
operations say they are for YAML (docs/editing.md)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from html import escape

from hfsmc.edit.text import EditError, TextEdit, line_start

_TAG = re.compile(r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>|<!DOCTYPE[^>]*>"
                  r"|<(/?)([A-Za-z_][\w.:-]*)((?:\s+[^\s=/>]+\s*=\s*(?:\"[^\"]*\"|'[^']*'))*)\s*(/?)>",
                  re.DOTALL)
_ATTR = re.compile(r"([^\s=/>]+)\s*=\s*(\"([^\"]*)\"|'([^']*)')")
_ACTIVE = re.compile(r"""\bactive\(\s*(["']|&quot;)([A-Za-z0-9_/]*)\1\s*\)""")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
SNIPPETS = ("entry", "during", "exit", "when", "do", "functions", "on_shutdown")


@dataclass(eq=False)
class Element:
    tag: str
    start: int  # `<` of the start tag
    open_end: int  # after the start tag's `>`
    end: int = 0  # after the end tag's `>` (the start tag's for an empty element)
    close_start: int = 0  # `<` of the end tag (== end for an empty element)
    attrs: dict[str, tuple[int, int, str]] = field(default_factory=dict)  # value's range, value
    children: list[Element] = field(default_factory=list)

    def kids(self, tag: str) -> list[Element]:
        return [c for c in self.children if c.tag == tag]

    def attr(self, name: str) -> str | None:
        a = self.attrs.get(name)
        return a[2] if a else None


def parse(text: str) -> Element:
    """The elements of ``text`` with their ranges (raises EditError when tags do not match)."""
    root = Element("#document", 0, 0, len(text), len(text))
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
        el = Element(tag, m.start(), m.end())
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


class XmlOps:
    """The operations of :class:`hfsmc.edit.yaml_ops.YamlOps` that XML has."""

    def __init__(self, text: str) -> None:
        self.text = text
        doc = parse(text)
        hfsm = doc.kids("hfsm")
        if not hfsm:
            raise EditError("not an hfsm XML model")
        self.root = hfsm[0]
        self.elements: dict[str, tuple[Element, Element]] = {}  # path -> (element, its automaton)
        for auto in self.root.kids("automaton"):
            self._walk(auto, "")

    def _walk(self, auto: Element, prefix: str) -> None:
        for st in auto.kids("state"):
            name = st.attr("name") or ""
            path = prefix + name
            self.elements[path] = (st, auto)
            for sub in st.kids("automaton"):
                self._walk(sub, path + "/")
            for reg in st.kids("region"):
                rpath = path + "/" + (reg.attr("name") or "")
                self.elements[rpath] = (reg, auto)
                self._walk(reg, rpath + "/")

    def element(self, path: str) -> tuple[Element, Element]:
        if path not in self.elements:
            raise EditError(f"no state or region `{path}` in this model")
        return self.elements[path]

    def _snippets(self) -> list[Element]:
        out: list[Element] = []
        stack = [self.root]
        while stack:
            el = stack.pop()
            if el.tag in SNIPPETS:
                out.append(el)
            stack.extend(el.children)
        return out

    def rename(self, path: str, new: str) -> list[TextEdit]:
        if not _IDENT.match(new):
            raise EditError(f"`{new}` is not a valid state name (letters, digits, `_`; not a digit first)")
        el, auto = self.element(path)
        old = el.attr("name") or ""
        parent = path.rsplit("/", 1)[0] if "/" in path else ""
        if (parent + "/" if parent else "") + new in self.elements and new != old:
            raise EditError(f"`{(parent + '/' if parent else '') + new}` already exists")
        edits = [_set_attr_value(el, "name", new)]
        if el.tag == "state":
            if auto.attr("initial") == old:
                edits.append(_set_attr_value(auto, "initial", new))
            if not parent and auto.attr("on_interrupt") == old:
                edits.append(_set_attr_value(auto, "on_interrupt", new))
            for sib in auto.kids("state"):
                for t in sib.kids("transition"):
                    if t.attr("to") == old:
                        edits.append(_set_attr_value(t, "to", new))
        depth = path.count("/")
        for sn in self._snippets():
            body = self.text[sn.open_end:sn.close_start]
            for m in _ACTIVE.finditer(body):
                segs = m.group(2).split("/")
                if len(segs) > depth and "/".join(segs[:depth + 1]) == path:
                    off = sn.open_end + m.start(2) + sum(len(s) + 1 for s in segs[:depth])
                    edits.append(TextEdit(off, off + len(old), new))
        return sorted(edits, key=lambda e: e.start)

    def delete_state(self, path: str) -> list[TextEdit]:
        el, _ = self.element(path)
        return [TextEdit(*self._lines(el), "")]

    def _lines(self, el: Element) -> tuple[int, int]:
        """An element's text with the indentation before it and the line break after it."""
        s = line_start(self.text, el.start)
        if self.text[s:el.start].strip():
            s = el.start
        e = el.end
        if self.text.startswith("\r\n", e):
            e += 2
        elif self.text[e:e + 1] == "\n":
            e += 1
        return s, e

    def move_state(self, path: str, index: int) -> list[TextEdit]:
        el, auto = self.element(path)
        sibs = auto.kids(el.tag)
        i = sibs.index(el)
        index = max(0, min(index, len(sibs) - 1))
        if index == i:
            return []
        s, e = self._lines(el)
        chunk = self.text[s:e]
        if index < i:
            at, _ = self._lines(sibs[index])
            return [TextEdit(at, at, chunk), TextEdit(s, e, "")]
        _, at = self._lines(sibs[index])
        return [TextEdit(s, e, ""), TextEdit(at, at, chunk)]

    def add_state(self, parent: str, name: str, body: dict[str, object] | None = None,
                  index: int | None = None) -> list[TextEdit]:
        if not _IDENT.match(name):
            raise EditError(f"`{name}` is not a valid state name (letters, digits, `_`; not a digit first)")
        if parent:
            el, _ = self.element(parent)
            autos = el.kids("automaton") if el.tag == "state" else [el]
            if not autos:
                raise EditError(f"`{parent}` has no sub-automaton: add one in YAML or write it")
            auto = autos[0]
        else:
            auto = self.root.kids("automaton")[0]
        attrs = "".join(f' {k}="{escape(str(v).lower() if isinstance(v, bool) else str(v))}"'
                        for k, v in (body or {}).items() if not isinstance(v, (dict, list)))
        sibs = auto.kids("state")
        if not sibs:
            raise EditError("the automaton has no state to take the layout from")
        index = len(sibs) if index is None else max(0, min(index, len(sibs)))
        ref = sibs[min(index, len(sibs) - 1)]
        pad = self.text[line_start(self.text, ref.start):ref.start]
        line = f'{pad}<state name="{name}"{attrs}/>\n'
        if index < len(sibs):
            at, _ = self._lines(sibs[index])
            return [TextEdit(at, at, line)]
        _, at = self._lines(sibs[-1])
        return [TextEdit(at, at, line)]

    def set_state_field(self, state: str, key: str, value: object) -> list[TextEdit]:
        el = self.element(state)[0] if state else self.root
        if key in SNIPPETS:
            kids = el.kids(key)
            if value is None:
                return [TextEdit(*self._lines(kids[0]), "")] if kids else []
            text = escape(str(value), quote=False)
            if kids:
                return [TextEdit(kids[0].open_end, kids[0].close_start, text)]
            pad = self.text[line_start(self.text, el.start):el.start] + "  "
            if el.end == el.open_end:  # an empty element: open it
                head = self.text[el.start:el.open_end - 2].rstrip()
                return [TextEdit(el.start, el.end, f"{head}>\n{pad}<{key}>{text}</{key}>\n"
                                 f"{pad[:-2]}</{el.tag}>")]
            return [TextEdit(el.open_end, el.open_end, f"\n{pad}<{key}>{text}</{key}>")]
        target = el if state else (self.root.kids("automaton") or [self.root])[0] \
            if key in ("period", "initial", "on_interrupt", "interrupt_timeout") else el
        if value is None:
            if key not in target.attrs:
                return []
            s, e, _ = target.attrs[key]
            a = self.text.rfind(key, target.start, s)
            while a > target.start and self.text[a - 1] in " \t\n":
                a -= 1
            return [TextEdit(a, e + 1, "")]
        v = str(value).lower() if isinstance(value, bool) else str(value)
        if key in target.attrs:
            return [_set_attr_value(target, key, v)]
        at = target.open_end - (2 if self.text[target.open_end - 2:target.open_end] == "/>" else 1)
        while self.text[at - 1] in " \t":
            at -= 1
        return [TextEdit(at, at, f' {key}="{escape(v)}"')]


def _set_attr_value(el: Element, name: str, value: str) -> TextEdit:
    s, e, _ = el.attrs[name]
    return TextEdit(s, e, escape(value))
