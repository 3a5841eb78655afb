"""XML front end: hfsm version-1 documents (docs/model.md, XML) into the neutral Document.

Four steps, each of which may stop with positioned diagnostics:

1. refuse what could make a parser fetch or expand anything (DOCTYPE, entity
   declarations and references, XInclude), before lxml sees the text;
2. parse with a locked-down lxml parser (syntax errors keep lxml's line:col);
3. validate against ``schemas/hfsm.xsd`` and turn every XSD error into a
   diagnostic at the element or attribute it is about;
4. convert the tree into the YAML-shaped data the YAML front end would give
   for the same model, with a span for every value and every key.

lxml only knows each element's line, so columns come from the source text:
``XmlSource`` blanks out comments, CDATA and processing instructions, after
which the n-th start tag in the text is the n-th element of the tree.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import cache
from typing import Any

from lxml import etree

from hfsmc.errors import Diagnostic, Diagnostics, ParseError, SchemaError, Span, did_you_mean, fail
from hfsmc.frontend.source import Document, PathKey
from hfsmc.frontend.xmlsource import (
    Element,
    XmlIndex,
    XmlSource,
    clean_text,
    parse_safely,
    refuse_after_parse,
    refuse_declarations,
    safe_parser,
    written_name,
)
from hfsmc.resources import schema_file

_XS = "{http://www.w3.org/2001/XMLSchema}"
_LEGACY = ("VisualStates", "VisualHFSM")  # docs/legacy.md: read by the legacy front end
_ROOT_TYPE = "hfsm"  # the XSD's type of the root element
_MAX_XSD_ROUNDS = 20  # re-validations after dropping unexpected elements (see _validate)


def load_xml(file: str, text: str, diags: Diagnostics) -> Document:
    """Parse, check and convert an XML model; see the module docstring.

    Raises :class:`ParseError` (E002 syntax, E004 forbidden construct, E005
    not an hfsm document, E006 too deep or too big) or :class:`SchemaError`
    (every XSD violation); duplicate names go to ``diags``.
    """
    src = XmlSource(file, text)
    doc = Document(file, "xml", src.lines())
    refuse_declarations(src)
    root = parse_safely(src)
    index = XmlIndex(src, root)
    refuse_after_parse(root, index)
    legacy = _check_root(root, index, diags)
    if legacy is not None:
        return legacy
    problems = _validate(root, index)
    if problems:
        raise SchemaError(problems)
    doc.data = _Converter(doc, index, diags).model(root)
    return doc


def _check_root(root: Element, index: XmlIndex, diags: Diagnostics) -> Document | None:
    """None for an hfsm document; a legacy one is read by its own front end (docs/legacy.md)."""
    name = etree.QName(root)
    if name.namespace is None and name.localname == "hfsm":
        return None
    if name.localname == "hfsm":
        fail(ParseError, "E005", f"the `<hfsm>` element takes no namespace (it is in "
             f"`{name.namespace}`)", index.span(root), "drop the xmlns attribute")
    if name.namespace is None and name.localname in _LEGACY:
        from hfsmc.frontend.legacy import load_legacy

        return load_legacy(root, index, diags)
    fail(ParseError, "E005", f"not an hfsm model: the root element is `<{written_name(root)}>`",
         index.span(root), 'an hfsm XML model starts with <hfsm version="1" name="...">')


# ---------------------------------------------------------------------------
# XSD validation


@dataclass(frozen=True, slots=True)
class _Type:
    """What the XSD allows in an element of one complex type."""

    children: dict[str, str]  # element name -> its type
    attributes: dict[str, str]  # attribute name -> its type


@dataclass(frozen=True, slots=True)
class _Grammar:
    schema: etree.XMLSchema
    types: dict[str, _Type]
    enums: dict[str, tuple[str, ...]]  # simple type -> allowed values

    def type_of(self, el: Element) -> _Type | None:
        """The complex type of ``el``, found from the root down."""
        chain = [*reversed(list(el.iterancestors())), el]
        name: str | None = _ROOT_TYPE
        for child in chain[1:]:
            t = self.types.get(name or "")
            name = t.children.get(str(child.tag)) if t else None
        return self.types.get(name or "")


@cache
def _grammar() -> _Grammar:
    """The parsed XSD, and the names it allows where (for "did you mean")."""
    tree = etree.fromstring(schema_file("hfsm.xsd").read_bytes(), safe_parser())
    types: dict[str, _Type] = {}
    for ct in tree.iterfind(f"{_XS}complexType"):
        children = {str(e.get("name")): str(e.get("type")) for e in ct.iter(f"{_XS}element")}
        attrs = {str(a.get("name")): str(a.get("type")) for a in ct.iter(f"{_XS}attribute")}
        types[str(ct.get("name"))] = _Type(children, attrs)
    enums = {str(st.get("name")): tuple(str(e.get("value")) for e in st.iter(f"{_XS}enumeration"))
             for st in tree.iterfind(f"{_XS}simpleType")}
    return _Grammar(etree.XMLSchema(tree), types, enums)


def _validate(root: Element, index: XmlIndex) -> list[Diagnostic]:
    """Every XSD violation of the document.

    libxml2 stops checking an element's children at the first unexpected
    one, so unexpected elements are dropped and the tree validated again
    until nothing new turns up.  The tree is only used further when valid.
    """
    grammar = _grammar()
    out: list[Diagnostic] = []
    seen: set[tuple[Span, str, str]] = set()
    for _ in range(_MAX_XSD_ROUNDS):
        if grammar.schema.validate(root):
            break
        stray: list[Element] = []
        log: Any = grammar.schema.error_log  # iterable, though lxml-stubs do not say so
        for entry in log:
            el = _element_at(root, entry.path)
            d = _diagnose(entry.message, el, index, grammar)
            if (d.span, d.code, d.message) not in seen:
                seen.add((d.span, d.code, d.message))
                out.append(d)
            if "This element is not expected" in entry.message and el is not root:
                stray.append(el)
        if not stray:
            break
        for el in stray:
            parent = el.getparent()
            if parent is not None:
                parent.remove(el)
    return out


def _element_at(root: Element, path: str | None) -> Element:
    try:
        found = root.getroottree().xpath(path) if path else []
    except etree.XPathError:
        found = []
    return found[0] if isinstance(found, list) and found and isinstance(found[0], Element) else root


_XSD_MESSAGE = re.compile(r"^Element '([^']*)'(?:, attribute '([^']*)')?: (.*)$", re.S)
_EXPECTED = re.compile(r"Expected is (?:one of )?\( ([^)]*) \)")


def _diagnose(message: str, el: Element, index: XmlIndex, grammar: _Grammar) -> Diagnostic:
    m = _XSD_MESSAGE.match(message.strip())
    attr, what = (m.group(2), m.group(3)) if m else (None, message.strip())
    tag = written_name(el)
    if attr is not None:
        return _attribute_problem(el, attr, what, index, grammar)
    if "This element is not expected" in what:
        return _unknown_element(el, index, grammar)
    if "is required but missing" in what:
        missing = re.search(r"attribute '([^']*)'", what)
        name = missing.group(1) if missing else "?"
        states = [c.get("name", "?") for c in el if c.tag == "state"]
        notes = (f"its states: {', '.join(states)}",) if name == "initial" and states else ()
        return Diagnostic("E102", f"missing required attribute `{name}` of `<{tag}>`",
                          index.span(el), "error", notes)
    if "Missing child element" in what:
        names = _EXPECTED.search(what)
        wanted = " or ".join(f"`<{n.strip()}>`" for n in names.group(1).split(",")) if names \
            else "a child element"
        return Diagnostic("E102", f"`<{tag}>` needs at least one {wanted}", index.span(el))
    if "Element content is not allowed" in what:
        child = next(iter(el), el)
        return Diagnostic("E101", f"`<{tag}>` holds text, not elements", index.span(child),
                          "error", ("write < as &lt; and & as &amp;, or put the code in "
                                    "<![CDATA[ ... ]]>",))
    if "Character content other than whitespace" in what:
        return Diagnostic("E101", f"`<{tag}>` holds elements, not text", index.span(el))
    return Diagnostic("E103", f"`<{tag}>`: {what.rstrip('.')}", index.span(el))


def _unknown_element(el: Element, index: XmlIndex, grammar: _Grammar) -> Diagnostic:
    parent = el.getparent()
    ptype = grammar.type_of(parent) if parent is not None else None
    allowed = list(ptype.children) if ptype else []
    pname = written_name(parent) if parent is not None else "?"
    note = did_you_mean(written_name(el), allowed)
    notes = (note,) if note else (f"allowed in `<{pname}>`: {', '.join(allowed) or 'nothing'}",)
    return Diagnostic("E100", f"unknown element `<{written_name(el)}>` in `<{pname}>`", index.span(el),
                      "error", notes)


def _attribute_problem(el: Element, attr: str, what: str, index: XmlIndex,
                       grammar: _Grammar) -> Diagnostic:
    value = el.get(attr, "")
    attr = index.written(el, attr)
    key_span, value_span = index.attribute(el, attr)
    etype = grammar.type_of(el)
    allowed = etype.attributes if etype else {}
    if "is not allowed" in what and "value" not in what:
        note = did_you_mean(attr, allowed)
        notes = (note,) if note else (f"allowed on `<{written_name(el)}>`: {', '.join(allowed)}",)
        return Diagnostic("E100", f"unknown attribute `{attr}` of `<{written_name(el)}>`", key_span,
                          "error", notes)
    kind = allowed.get(attr, "")
    if kind == "identifier":
        return Diagnostic("E120", f"`{value}` is not an identifier (letters, digits and _, not "
                          "starting with a digit)", value_span)
    if kind == "duration":
        return Diagnostic("E110", f"`{value}` is not a duration: write 250ms, 2s, 1.5s or 2m "
                          "(a bare number means milliseconds)", value_span)
    if kind == "flag":
        return Diagnostic("E101", f"`{attr}` must be true or false, not {value!r}", value_span)
    if kind == "version":
        return Diagnostic("E104", f"unsupported format version {value}: this hfsmc reads "
                          "version 1", value_span)
    choices = grammar.enums.get(kind)
    if choices:
        note = did_you_mean(value, choices)
        return Diagnostic("E103", f"`{attr}` must be one of {', '.join(choices)}; not {value!r}",
                          value_span, "error", (note,) if note else ())
    if not value:
        return Diagnostic("E103", f"`{attr}` must not be empty", value_span)
    return Diagnostic("E103", f"`{attr}`: {what.rstrip('.')}", value_span)


# ---------------------------------------------------------------------------
# conversion to the neutral data

# Elements that stand for one mapping key: a second one is a duplicate key.
_SINGLE = frozenset({"description", "functions", "on_shutdown", "automaton", "entry", "during",
                     "exit", "when", "do"})


def _number(text: str) -> int | str:
    """An integer attribute (a domain id, a QoS depth); other text stays text, for the
    schema to say what it must be."""
    stripped = text.strip()
    return int(stripped) if re.fullmatch(r"[+-]?\d{1,12}", stripped) else text


def _flag(value: str) -> bool:
    return value == "true"  # the XSD allows only true and false


class _Converter:
    """The valid tree as the YAML front end's data, with spans."""

    def __init__(self, doc: Document, index: XmlIndex, diags: Diagnostics) -> None:
        self.doc = doc
        self.index = index
        self.diags = diags

    def model(self, root: Element) -> dict[str, Any]:
        d: dict[str, Any] = {}
        self.doc.spans[()] = self.index.span(root)
        self.attr(root, (), d, "version", "hfsm", int)
        self.attr(root, (), d, "name")
        self.attr(root, (), d, "language")
        for child in self.children(root):
            tag = child.tag
            if tag == "import":
                imports = d.setdefault("imports", [])
                self.first_key(child, ("imports",))
                imports.append(self.text(child, ("imports", len(imports))))
            elif tag in ("interface", "parameter", "variable"):
                self.declaration(child, d, str(tag))
            elif tag == "automaton":
                self.automaton(child, (), d)
            else:
                d[str(tag)] = self.text(child, (str(tag),))
        if "states" not in d:
            self.diags.error("E102", "missing required element `<automaton>` in `<hfsm>`",
                             self.index.span(root), "the root sub-automaton, with the states")
        return d

    # -- helpers -------------------------------------------------------------
    def children(self, el: Element) -> Iterator[Element]:
        """Child elements; a second singleton (two `<entry>`) is reported and skipped."""
        seen: dict[str, Element] = {}
        for child in el.iterchildren(etree.Element):
            tag = str(child.tag)
            if tag in _SINGLE and tag in seen:
                line = self.index.span(seen[tag]).line
                self.diags.error("E003", f"`<{tag}>` is given twice in this `<{el.tag}>`",
                                 self.index.span(child), f"the first is on line {line}")
                continue
            seen[tag] = child
            yield child

    def put(self, d: dict[str, Any], path: PathKey, value: Any, key: Span, span: Span) -> None:
        d[str(path[-1])] = value
        self.doc.key_spans[path] = key
        self.doc.spans[path] = span

    def attr(self, el: Element, path: PathKey, d: dict[str, Any], name: str,
             key: str | None = None, convert: Callable[[str], Any] = str) -> None:
        value = el.get(name)
        if value is not None:
            key_span, value_span = self.index.attribute(el, name)
            self.put(d, (*path, key or name), convert(value), key_span, value_span)

    def first_key(self, el: Element, path: PathKey) -> None:
        """Position of a list or mapping made of repeated elements: its first one."""
        if path not in self.doc.spans:
            self.doc.spans[path] = self.doc.key_spans[path] = self.index.span(el)

    def text(self, el: Element, path: PathKey) -> str:
        """A text element's content, positioned at its first character."""
        raw = el.text or ""
        if el.get("verbatim") == "true":
            text, first, margin = raw, 0, 0
        else:
            text, first, margin = clean_text(raw)
        self.doc.key_spans[path] = self.index.span(el)
        self.doc.spans[path] = self.index.text(el, first)
        self.doc.cont_cols[path] = 1 + margin
        if self.index.has_reference(el, len(raw)):
            # `&gt;` is 4 columns for 1 character: columns are no longer linear
            self.doc.segments[path] = self.char_positions(el, raw, text, first, margin)
        return text

    def char_positions(self, el: Element, raw: str, text: str, first: int,
                       margin: int) -> tuple[tuple[int, int, int], ...]:
        """(offset in text, line, col) of every character of ``text``."""
        out: list[tuple[int, int, int]] = []
        offset, raw_start = 0, first
        raw_lines = raw[first:].split("\n")
        for k, line in enumerate(text.split("\n")):
            raw_line = raw_lines[k] if k < len(raw_lines) else ""
            skip = 0 if k == 0 else min(margin, len(raw_line) - len(raw_line.lstrip(" \t")))
            for c in range(len(line) + 1):
                span = self.index.text(el, raw_start + skip + c)
                out.append((offset + c, span.line, span.col))
            offset += len(line) + 1
            raw_start += len(raw_line) + 1
        return tuple(out)

    def named(self, el: Element, path: PathKey, group: dict[str, Any],
              kind: str) -> tuple[dict[str, Any], PathKey] | None:
        """A new entry of a mapping keyed by the element's `name` (None if a duplicate)."""
        name = el.get("name", "")
        if name in group:
            _, value_span = self.index.attribute(el, "name")
            self.diags.error("E121", f"duplicate {kind} name `{name}`", value_span,
                             f"the first `{name}` is on line {self.doc.key_span((*path, name)).line}")
            return None
        item: dict[str, Any] = {}
        self.put(group, (*path, name), item, self.index.span(el), self.index.span(el))
        return item, (*path, name)

    # -- declarations ----------------------------------------------------------
    def declaration(self, el: Element, d: dict[str, Any], tag: str) -> None:
        key = f"{tag}s"
        self.first_key(el, (key,))
        found = self.named(el, (key,), d.setdefault(key, {}), tag)
        if found is None:
            return
        item, path = found
        for name in ("type", "url", "python", "cpp", "default", "init", "description", "node",
                     "namespace", "distro"):
            self.attr(el, path, item, name)
        self.attr(el, path, item, "domain", convert=_number)
        if tag == "interface":
            self.attr(el, path, item, "introspection", convert=_flag)
            self.ros2_children(el, path, item)
        for option in el.iterchildren("option"):
            self.first_key(option, (*path, "options"))
            opt = self.named(option, (*path, "options"), item.setdefault("options", {}), "option")
            if opt is not None:
                _, opath = opt
                _, value_span = self.index.attribute(option, "value")
                self.put(item["options"], opath, option.get("value", ""), self.index.span(option),
                         value_span)

    def ros2_children(self, el: Element, path: PathKey, item: dict[str, Any]) -> None:
        """A ros2 interface's `<subscribe>`, `<publish>` and `<message>` (docs/ros2.md)."""
        for child in el.iterchildren("subscribe", "publish"):
            key = str(child.tag)
            self.first_key(child, (*path, key))
            found = self.named(child, (*path, key), item.setdefault(key, {}), key)
            if found is None:
                continue
            entry, epath = found
            for name in ("topic", "type"):
                self.attr(child, epath, entry, name)
            if child.get("qos") is not None:
                self.attr(child, epath, entry, "qos")
            elif any(child.get(k) is not None for k in ("reliability", "durability", "depth")):
                qos: dict[str, Any] = {}
                self.put(entry, (*epath, "qos"), qos, self.index.span(child),
                         self.index.span(child))
                for name in ("reliability", "durability"):
                    self.attr(child, (*epath, "qos"), qos, name)
                self.attr(child, (*epath, "qos"), qos, "depth", convert=_number)
        for child in el.iterchildren("action", "service"):
            key = f"{child.tag}s"
            self.first_key(child, (*path, key))
            found = self.named(child, (*path, key), item.setdefault(key, {}), str(child.tag))
            if found is None:
                continue
            entry, epath = found
            if child.get("ros_name") is not None:
                _, span = self.index.attribute(child, "ros_name")
                self.put(entry, (*epath, "name"), child.get("ros_name"), span, span)
            for name in ("type", "timeout"):
                self.attr(child, epath, entry, name)
        for child in el.iterchildren("message"):
            messages = item.setdefault("messages", [])
            self.first_key(child, (*path, "messages"))
            _, value_span = self.index.attribute(child, "file")
            self.put_item(messages, (*path, "messages", len(messages)), child.get("file", ""),
                          self.index.span(child), value_span)

    def put_item(self, items: list[Any], path: PathKey, value: Any, key: Span,
                 span: Span) -> None:
        items.append(value)
        self.doc.key_spans[path] = key
        self.doc.spans[path] = span

    # -- states ----------------------------------------------------------------
    def automaton(self, el: Element, path: PathKey, d: dict[str, Any]) -> None:
        for name in ("period", "initial", "on_interrupt", "interrupt_timeout", "time_limit"):
            self.attr(el, path, d, name)
        self.attr(el, path, d, "history", convert=_flag)
        states: dict[str, Any] = {}
        self.put(d, (*path, "states"), states, self.index.span(el), self.index.span(el))
        for child in self.children(el):
            if child.tag == "description":  # a region's, as YAML's region may have
                d["description"] = self.text(child, (*path, "description"))
            else:
                self.state(child, (*path, "states"), states)

    def state(self, el: Element, path: PathKey, states: dict[str, Any]) -> None:
        found = self.named(el, path, states, "state")
        if found is None:
            return
        sd, sp = found
        self.attr(el, sp, sd, "final", convert=_flag)
        self.attr(el, sp, sd, "use")
        for child in self.children(el):
            tag = str(child.tag)
            if tag == "with":
                self.binding(child, sp, sd)
            elif tag == "transition":
                self.transition(child, sp, sd)
            elif tag == "automaton":
                self.automaton(child, sp, sd)
            elif tag == "region":
                self.region(child, sp, sd)
            else:
                sd[tag] = self.text(child, (*sp, tag))

    def region(self, el: Element, path: PathKey, sd: dict[str, Any]) -> None:
        """A `<region>` as an entry of the state's `regions` mapping, as YAML writes it.

        A `<region>` beside an `<automaton>` (E160) or alone (E161) is left to the IR
        builder, which reports it at the first `<region>`, where YAML's `regions` key is.
        """
        rpath: PathKey = (*path, "regions")
        self.first_key(el, rpath)
        found = self.named(el, rpath, sd.setdefault("regions", {}), "region")
        if found is not None:
            rd, rp = found
            self.automaton(el, rp, rd)

    def binding(self, el: Element, path: PathKey, sd: dict[str, Any]) -> None:
        """A `<with name=... value=...>` as an entry of YAML's `with` mapping; its text is
        converted by the used parameter's type when the used file is read."""
        wpath: PathKey = (*path, "with")
        self.first_key(el, wpath)
        group = sd.setdefault("with", {})
        name = el.get("name", "")
        if name in group:
            _, value_span = self.index.attribute(el, "name")
            self.diags.error("E121", f"`with` binds `{name}` twice", value_span,
                             f"the first is on line {self.doc.key_span((*wpath, name)).line}")
            return
        _, value_span = self.index.attribute(el, "value")
        self.put(group, (*wpath, name), el.get("value", ""), self.index.span(el), value_span)

    def transition(self, el: Element, path: PathKey, sd: dict[str, Any]) -> None:
        self.first_key(el, (*path, "transitions"))
        items = sd.setdefault("transitions", [])
        tp: PathKey = (*path, "transitions", len(items))
        td: dict[str, Any] = {}
        items.append(td)
        self.doc.spans[tp] = self.index.span(el)
        for name in ("name", "to", "after"):
            self.attr(el, tp, td, name)
        for child in self.children(el):
            td[str(child.tag)] = self.text(child, (*tp, str(child.tag)))
