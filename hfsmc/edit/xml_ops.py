"""The operations of :class:`hfsmc.edit.yaml_ops.YamlOps` on an XML model's text, its
formatting kept (SPEC 8.1): every element's exact range comes from
:mod:`hfsmc.edit.xml_tree`, new elements are written by :mod:`hfsmc.edit.xml_render` in
the file's style, and an element taken away or moved goes with its lines and the comment
lines right above it at its indentation.

Elements are named as in YAML: `Mission/FollowGreen`, a region's name included; ""
is the root.  A field is named by the YAML form's key (`entry`, `period`, `final`,
`initial`); on an XML model it is an attribute or a child element, wherever the XML
form keeps it (a state's `initial` and `period` are its `<automaton>`'s)."""

from __future__ import annotations

import re
import textwrap
from typing import Any

import yaml

from hfsmc.edit.references import Ref
from hfsmc.edit.text import EditError, TextEdit, insert_into, line_end, line_start, newline_of
from hfsmc.edit.xml_render import AUTOMATON_ATTRS, ROOT_AUTOMATON_ATTRS, STATE_ATTRS, Style
from hfsmc.edit.xml_tree import DECLARATIONS, TEXTS, XElement, XmlNames, parse
from hfsmc.frontend.source import PathKey

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_COMMENT_LINE = re.compile(r"[ \t]*<!--.*-->[ \t]*\Z")
_ROOT_ORDER = ("description", "import", "interface", "parameter", "variable", "functions",
               "on_shutdown", "automaton")


def _ident(name: str, what: str) -> None:
    if not _IDENT.match(name):
        raise EditError(f"`{name}` is not a valid {what} name (letters, digits, `_`; not a digit first)")


class XmlOps:
    """Operations on one XML text; each returns the edits that make it."""

    def __init__(self, text: str, index: XmlNames | None = None) -> None:
        self.text = text
        self.index = index if index is not None and index.text == text else XmlNames(text)
        self.root = self.index.root
        self.style = self._style()

    def _style(self) -> Style:
        text = self.text
        kids = self.root.children
        step = "  "
        if kids:
            d = self._col(kids[0].start) - self._col(self.root.start)
            if d > 0:
                step = text[line_start(text, kids[0].start):kids[0].start][-d:]
        quotes = [text[s - 1] for el in _walk(self.root) for s, _, _ in el.attrs.values()]
        quote = "'" if quotes.count("'") > quotes.count('"') else '"'
        return Style(step, quote, "<![CDATA[" in text, newline_of(text))

    # ----- text positions

    def _col(self, off: int) -> int:
        return off - line_start(self.text, off)

    def _pad(self, el: XElement) -> str:
        """The indentation of an element's line (when it starts the line)."""
        pad = self.text[line_start(self.text, el.start):el.start]
        return pad if not pad.strip() else ""

    def _lines(self, el: XElement) -> tuple[int, int]:
        """An element's text with its indentation, the line break after it and the comment
        lines right above it at its indentation."""
        text = self.text
        s = line_start(text, el.start)
        if text[s:el.start].strip():
            return el.start, el.end
        pad = text[s:el.start]
        while s > 0:
            prev = line_start(text, s - 1)
            line = text[prev:s].rstrip("\r\n")
            if _COMMENT_LINE.match(line) and line[:len(pad)] == pad and line[len(pad):len(pad) + 1] == "<":
                s = prev
            else:
                break
        e = el.end
        rest = text[e:line_end(text, e)]
        if not rest.strip():
            e = line_end(text, e)
            e += 2 if text.startswith("\r\n", e) else 1 if e < len(text) else 0
        return s, e

    def _child_pad(self, parent: XElement) -> str:
        for c in parent.children:
            if self._pad(c):
                return self._pad(c)
        return self._pad(parent) + self.style.step

    def _insert(self, parent: XElement, before: XElement | None, block: str) -> list[TextEdit]:
        """Insert ``block`` (whole lines at the children's indentation, no final break) as a
        child of ``parent``, before ``before`` (None: after its last child)."""
        nl = self.style.nl
        if before is not None:
            s, _ = self._lines(before)
            if s == before.start and self._pad(before) == "":  # shares its line with others
                return [TextEdit(s, s, block.strip() + " ")]
            return [TextEdit(s, s, block + nl)]
        if parent.empty:
            head = self.text[parent.start:parent.open_end - 2].rstrip()
            return [TextEdit(parent.start, parent.end,
                             f"{head}>{nl}{block}{nl}{self._pad(parent)}</{parent.tag}>")]
        if parent.children:
            last = parent.children[-1]
            _, e = self._lines(last)
            if e > last.end:
                return [TextEdit(e, e, block + nl)]
            return [TextEdit(last.end, last.end, nl + block)]
        # text or nothing inside: the close tag goes on its own line after the block
        at = parent.close_start
        lead = self.text[line_start(self.text, at):at]
        if not lead.strip():
            return [TextEdit(line_start(self.text, at), line_start(self.text, at), block + nl)]
        return [TextEdit(at, at, nl + block + nl + self._pad(parent))]

    def _move(self, el: XElement, sibs: list[XElement], index: int) -> list[TextEdit]:
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

    def _delete(self, el: XElement) -> list[TextEdit]:
        return [TextEdit(*self._lines(el), "")]

    # ----- finding elements

    def element(self, path: str) -> XElement:
        el = self.index.xml.get(path)
        if el is None:
            raise EditError(f"no state or region `{path}` in this model")
        return el

    def _owner(self, path: str) -> XElement:
        """The element holding the states of ``path`` ("" the root): an `<automaton>` or a
        `<region>`; raises EditError when a state has none."""
        if not path:
            autos = self.root.kids("automaton")
            if not autos:
                raise EditError("the model has no <automaton>")
            return autos[0]
        el = self.element(path)
        if el.tag == "region":
            return el
        autos = el.kids("automaton")
        if not autos:
            raise EditError(f"`{path}` has no sub-automaton")
        return autos[0]

    def _state_el(self, state: str) -> XElement:
        return self.element(state) if state else self.root

    # ----- states and regions

    def add_state(self, parent: str, name: str, body: dict[str, Any] | None = None,
                  index: int | None = None) -> list[TextEdit]:
        """A new state in ``parent``'s sub-automaton (or region); the first state of a
        sub-automaton becomes its `initial` (a state without one gets one)."""
        _ident(name, "state")
        prefix = parent + "/" if parent else ""
        if prefix + name in self.index.elements:
            raise EditError(f"`{prefix + name}` already exists")
        holder = self._state_el(parent)
        if parent and holder.tag == "state" and holder.kids("region"):
            raise EditError(f"`{parent}` has regions: add the state to one of them")
        autos = [holder] if holder.tag == "region" else holder.kids("automaton")
        if not autos:
            pad = self._child_pad(holder)
            block = self.style.automaton("automaton", [], {"initial": name, "states": {name: body}}, pad)
            return self._insert(holder, None, block)
        auto = autos[0]
        sibs = auto.kids("state")
        pad = self._child_pad(auto)
        block = self.style.state(name, body, pad)
        index = len(sibs) if index is None else max(0, min(index, len(sibs)))
        edits = self._insert(auto, sibs[index] if index < len(sibs) else None, block)
        if not sibs and "initial" not in auto.attrs:
            edits.append(self._add_attr(auto, "initial", name))
        return sorted(edits, key=lambda e: e.start)

    def delete_state(self, path: str) -> list[TextEdit]:
        """Delete a state or a region, with its lines."""
        return self._delete(self.element(path))

    def move_state(self, path: str, index: int) -> list[TextEdit]:
        """Move a state (or a region) to position ``index`` among its siblings."""
        el = self.element(path)
        assert el.parent is not None
        return self._move(el, el.parent.kids(el.tag), index)

    def rename(self, path: str, new: str) -> list[TextEdit]:
        """Rename a state or a region, and every reference to it in this file."""
        _ident(new, "state")
        self.element(path)
        parent = path.rsplit("/", 1)[0] if "/" in path else ""
        new_path = (parent + "/" if parent else "") + new
        if new_path in self.index.elements and new != path.rsplit("/", 1)[-1]:
            raise EditError(f"`{new_path}` already exists")
        return _replace(self.index.references("state", path), new)

    def add_region(self, state: str, name: str, body: dict[str, Any] | None = None,
                   index: int | None = None) -> list[TextEdit]:
        _ident(name, "region")
        el = self.element(state)
        if el.tag != "state":
            raise EditError(f"`{state}` is a region: regions belong to a state")
        if f"{state}/{name}" in self.index.elements:
            raise EditError(f"`{state}/{name}` already exists")
        regions = el.kids("region")
        pad = self._child_pad(el)
        block = self.style.automaton("region", [("name", name)], body or {}, pad)
        index = len(regions) if index is None else max(0, min(index, len(regions)))
        return self._insert(el, regions[index] if index < len(regions) else None, block)

    # ----- transitions

    def _transitions(self, state: str) -> tuple[XElement, list[XElement]]:
        el = self.element(state)
        if el.tag != "state":
            raise EditError(f"`{state}` is a region: transitions belong to states")
        return el, el.kids("transition")

    def _transition(self, state: str, i: int) -> XElement:
        _, ts = self._transitions(state)
        if not 0 <= i < len(ts):
            raise EditError(f"`{state}` has no transition {i}")
        return ts[i]

    def add_transition(self, state: str, transition: dict[str, Any],
                       index: int | None = None) -> list[TextEdit]:
        el, ts = self._transitions(state)
        block = self.style.transition(transition, self._child_pad(el))
        index = len(ts) if index is None else max(0, min(index, len(ts)))
        if index < len(ts):
            return self._insert(el, ts[index], block)
        if ts:  # after the last transition, before a sub-automaton written after them
            _, e = self._lines(ts[-1])
            later = [c for c in el.children if c.start > ts[-1].start]
            if later and e > ts[-1].end:
                return [TextEdit(e, e, block + self.style.nl)]
        return self._insert(el, None, block)

    def delete_transition(self, state: str, i: int) -> list[TextEdit]:
        return self._delete(self._transition(state, i))

    def move_transition(self, state: str, i: int, index: int) -> list[TextEdit]:
        t = self._transition(state, i)
        return self._move(t, self._transitions(state)[1], index)

    # ----- fields

    def set_state_field(self, state: str, key: str, value: Any) -> list[TextEdit]:
        """Set (None: clear) a field of a state, a region or the root ("")."""
        el = self._state_el(state)
        if not state:
            if key in ROOT_AUTOMATON_ATTRS:
                return self._set_attr(self._owner(""), key, value)
            if key in ("name", "language", "version", "hfsm"):
                return self._set_attr(self.root, "version" if key == "hfsm" else key, value)
            if key == "imports":
                return self._set_list(self.root, "import", value)
            if key in ("description", "functions", "on_shutdown") and not el.kids(key) \
                    and value is not None:
                return self._root_insert(key, lambda pad: self.style.text(key, str(value), pad))
            return self._set_on(el, key, value)
        if el.tag == "state" and key in AUTOMATON_ATTRS:
            return self._set_attr(self._owner(state), key, value)
        if key == "transitions":
            return self._set_list(el, "transition", value)
        return self._set_on(el, key, value)

    def set_field(self, path: PathKey, value: Any) -> list[TextEdit]:
        """Set (None: clear) the value at a YAML Document path (`states/A/transitions/0/when`,
        `parameters/speed/default`, `imports/1`)."""
        if not path:
            raise EditError("the document itself cannot be set")
        head = path[0]
        if head in DECLARATIONS.values() and len(path) >= 2:
            kind = next(k for k, v in DECLARATIONS.items() if v == head)
            el = self._declaration(kind, str(path[1]))
            if len(path) == 2:
                if value is None:
                    return self._delete(el)
                raise EditError("set a declaration's fields one by one")
            if len(path) == 4 and path[2] == "options":
                opt = next((o for o in el.kids("option") if o.attr("name") == path[3]), None)
                if value is None:
                    return self._delete(opt) if opt is not None else []
                if opt is not None:
                    return self._set_attr(opt, "value", value)
                return self._insert(el, None, f"{self._child_pad(el)}<option"
                                    f"{self.style.attr('name', path[3])}{self.style.attr('value', value)}/>")
            if len(path) != 3 or isinstance(value, (dict, list)):
                raise EditError(f"{'/'.join(map(str, path))}: not a field of this XML model")
            return self._set_attr(el, str(path[2]), value)  # every field of one is an attribute
        if head == "imports" and len(path) == 2 and isinstance(path[1], int):
            imps = self.root.kids("import")
            if not 0 <= path[1] < len(imps):
                raise EditError(f"no import {path[1]}")
            return self._delete(imps[path[1]]) if value is None else self._set_text(imps[path[1]], value)
        state, rest = _split(path)
        if len(rest) == 1:
            return self.set_state_field(state, str(rest[0]), value)
        if len(rest) == 3 and rest[0] == "transitions" and isinstance(rest[1], int):
            t = self._transition(state, rest[1])
            if value is None and rest[2] == "to":
                raise EditError("a transition needs its `to`: delete the transition instead")
            return self._set_on(t, str(rest[2]), value)
        if len(rest) == 2 and rest[0] == "transitions" and isinstance(rest[1], int):
            t = self._transition(state, rest[1])
            if value is None:
                return self._delete(t)
            return [TextEdit(*self._lines(t), self.style.transition(value, self._pad(t)) + self.style.nl)]
        raise EditError(f"{'/'.join(map(str, path))}: not a field of this XML model")

    def _set_on(self, el: XElement, key: str, value: Any) -> list[TextEdit]:
        """A field of ``el``: a text child (`entry`, `when`, `description`) or an attribute."""
        if key in TEXTS:
            kids = el.kids(key)
            if value is None:
                return self._delete(kids[0]) if kids else []
            if kids:
                return self._set_text(kids[0], value)
            block = self.style.text(key, str(value), self._child_pad(el))
            first = next((c for c in el.children if c.tag not in (*TEXTS, "with")), None) \
                if key in ("entry", "during", "exit", "description") else None
            return self._insert(el, first, block)
        if key in ("states", "regions", "with", "options", "transitions") or isinstance(value, dict):
            raise EditError(f"`{key}` is made of elements: use the operations on them")
        if el.tag == "state" and key not in ("name", *STATE_ATTRS):
            raise EditError(f"a state has no `{key}` attribute in XML")
        return self._set_attr(el, key, value)

    def _set_text(self, el: XElement, value: Any) -> list[TextEdit]:
        new = self.style.text(el.tag, str(value), self._pad(el))
        if not self._pad(el):
            new = new.strip()
        return [TextEdit(el.start, el.end, new.lstrip(" \t"))]

    def _set_attr(self, el: XElement, key: str, value: Any) -> list[TextEdit]:
        if value is None:
            if key not in el.attrs:
                return []
            s, e, _ = el.attrs[key]
            a = self.text.rfind(key, el.start, s)
            while a > el.start and self.text[a - 1] in " \t\r\n":
                a -= 1
            return [TextEdit(a, e + 1, "")]
        if key in el.attrs:
            s, e, _ = el.attrs[key]
            return [TextEdit(s, e, self.style.attr(key, value)[len(key) + 3:-1])]
        return [self._add_attr(el, key, value)]

    def _add_attr(self, el: XElement, key: str, value: Any) -> TextEdit:
        at = el.open_end - (2 if self.text[el.open_end - 2:el.open_end] == "/>" else 1)
        while self.text[at - 1] in " \t\r\n":
            at -= 1
        return TextEdit(at, at, self.style.attr(key, value))

    def _set_list(self, el: XElement, tag: str, value: Any) -> list[TextEdit]:
        """Replace every ``tag`` child of ``el`` with ``value``'s items."""
        if value is not None and not isinstance(value, list):
            raise EditError(f"`{tag}s` is a list")
        old = el.kids(tag)
        pad = self._child_pad(el)
        new = [self.style.transition(v, pad) if tag == "transition" else self.style.text(tag, v, pad)
               for v in value or []]
        if not old:
            return self._insert(el, None, self.style.nl.join(new)) if new else []
        edits = [TextEdit(*self._lines(o), "") for o in old[1:]]
        s, e = self._lines(old[0])
        edits.append(TextEdit(s, e, "".join(n + self.style.nl for n in new)))
        return sorted(edits, key=lambda x: x.start)

    # ----- declarations and imports

    def _declaration(self, kind: str, name: str) -> XElement:
        el = next((d for d in self.root.kids(kind) if d.attr("name") == name), None)
        if el is None:
            raise EditError(f"no {kind} `{name}` in this model")
        return el

    def _root_insert(self, tag: str, block_of: Any, index: int | None = None) -> list[TextEdit]:
        """Insert a child of `<hfsm>` after its siblings of ``tag`` (at ``index`` among them),
        or where the XML form's order puts it."""
        same = self.root.kids(tag)
        pad = self._child_pad(self.root)
        block = block_of(pad)
        if same and index is not None and index < len(same):
            return self._insert(self.root, same[max(index, 0)], block)
        order = _ROOT_ORDER.index(tag)
        later = [c for c in self.root.children if c.tag in _ROOT_ORDER and
                 _ROOT_ORDER.index(c.tag) > order and (not same or c.start > same[-1].start)]
        return self._insert(self.root, later[0] if later else None, block)

    def add_declaration(self, kind: str, name: str, spec: Any) -> list[TextEdit]:
        """Add a parameter, a variable or an interface."""
        _ident(name, kind)
        if kind not in DECLARATIONS:
            raise EditError(f"no declarations of kind `{kind}`")
        if any(d.attr("name") == name for d in self.root.kids(kind)):
            raise EditError(f"{DECLARATIONS[kind]}/{name} already exists")
        return self._root_insert(kind, lambda pad: self.style.declaration(kind, name, spec, pad))

    def remove_declaration(self, kind: str, name: str) -> list[TextEdit]:
        return self._delete(self._declaration(kind, name))

    def rename_declaration(self, kind: str, name: str, new: str) -> list[TextEdit]:
        """Rename a parameter, a variable or an interface, and its uses in snippets
        (and a parameter's `$NAME` in `<with>`)."""
        _ident(new, kind)
        if new in self.index.names and new != name:
            raise EditError(f"`{new}` is already a {self.index.names[new]}")
        if self.index.definition(kind, name) is None:
            raise EditError(f"no {kind} `{name}` in this model")
        return _replace(self.index.references(kind, name), new)

    def add_import(self, line: str, index: int | None = None) -> list[TextEdit]:
        return self._root_insert("import", lambda pad: self.style.text("import", line, pad), index)

    def remove_import(self, line: str) -> list[TextEdit]:
        for el in self.root.kids("import"):
            if _text_of(self.text, el) == line:
                return self._delete(el)
        raise EditError(f"no import `{line}`")

    # ----- wrap, copy, paste

    def copy_state(self, path: str) -> str:
        """The state as XML text (its element and the comment lines above it, at
        indentation 0)."""
        el = self.element(path)
        s, e = self._lines(el)
        return _dedent_lines(self.text[s:e], self._pad(el))

    def paste_state(self, parent: str, text: str, index: int | None = None) -> tuple[list[TextEdit], str]:
        """Paste a state copied by :meth:`copy_state` (XML) or by ``YamlOps.copy_state``
        (YAML) into ``parent``; a name taken among the siblings gets a number (`Track2`).
        Returns the edits and the name."""
        prefix = parent + "/" if parent else ""
        if not text.lstrip().startswith("<"):
            try:
                data = yaml.safe_load(text)
            except yaml.YAMLError as e:
                raise EditError(f"the pasted text is not XML or YAML: {str(e).splitlines()[0]}") from None
            if not isinstance(data, dict) or len(data) != 1:
                raise EditError("the pasted text is not one state (`Name:` and its body)")
            ((name, body),) = data.items()
            new = _free(prefix, str(name), self.index.elements)
            return self.add_state(parent, new, body, index), new
        try:
            states = [c for c in parse(text).children if c.tag == "state"]
        except EditError as e:
            raise EditError(f"the pasted text is not one state: {e}") from None
        if len(states) != 1 or "name" not in states[0].attrs:
            raise EditError("the pasted text is not one <state name=...> element")
        st = states[0]
        name = st.attr("name") or ""
        new = _free(prefix, name, self.index.elements)
        ns, ne, _ = st.attrs["name"]
        body = text[:ns] + new + text[ne:]
        holder = self._state_el(parent)
        if holder.tag == "state" and not holder.kids("automaton"):
            if holder.kids("region"):
                raise EditError(f"`{parent}` has regions: paste the state into one of them")
            return self._paste_new_automaton(holder, new, body), new
        auto = self._owner(parent) if parent else self._owner("")
        sibs = auto.kids("state")
        block = _indent_lines(_dedent_lines(body, ""), self._child_pad(auto), self.style.nl)
        index = len(sibs) if index is None else max(0, min(index, len(sibs)))
        return self._insert(auto, sibs[index] if index < len(sibs) else None, block), new

    def _paste_new_automaton(self, holder: XElement, name: str, body: str) -> list[TextEdit]:
        pad = self._child_pad(holder)
        inner = _indent_lines(_dedent_lines(body, ""), pad + self.style.step, self.style.nl)
        block = self.style.nl.join([f"{pad}<automaton{self.style.attr('initial', name)}>", inner,
                                    f"{pad}</automaton>"])
        return self._insert(holder, None, block)

    def wrap_states(self, parent: str, names: list[str], new: str) -> list[TextEdit]:
        """Move sibling states ``names`` of ``parent`` into a new composite state ``new``
        (its `initial` the first of them), where the first of them was.  Transitions of the
        other siblings to them (and `initial`, `on_interrupt`) now name ``new``; theirs to
        states left outside stay as written and are diagnosed."""
        _ident(new, "state")
        if not names:
            raise EditError("no states to wrap")
        prefix = parent + "/" if parent else ""
        els = [self.element(prefix + n) for n in names]
        if prefix + new in self.index.elements and new not in names:
            raise EditError(f"`{prefix + new}` already exists")
        auto = self._owner(parent)
        if any(el.parent is not auto for el in els):
            raise EditError("only states of one sub-automaton can be wrapped together")
        order = auto.kids("state")
        wrapped = sorted(els, key=order.index)
        inside = {f"{prefix}{w.attr('name')}" for w in wrapped}
        edits: list[TextEdit] = []
        for r in self.index.refs:
            if r.kind == "state" and r.via in ("to", "initial", "on_interrupt") and \
                    r.target in inside and not _within(r, wrapped):
                edits.append(TextEdit(r.start, r.end, new))
        # Literal `active("P/A/...")` paths through a wrapped state gain the new level.
        inserts = sorted({(r.start, new + "/") for r in self.index.refs
                          if r.kind == "state" and r.via == "active" and r.target in inside})
        first = wrapped[0]
        pad = self._pad(first)
        if not pad:
            raise EditError("the states share their lines: wrap is for states on lines of their own")
        step = self.style.step
        chunks = []
        for w in wrapped:
            s, e = self._lines(w)
            chunk, keep = insert_into(self.text[s:e], s, inserts, _verbatim_ranges(w, s))
            inserts = [i for i in inserts if not s <= i[0] < e]
            if not chunk.endswith(("\n", "\r")):
                chunk += self.style.nl
            chunks.append(_reindent(chunk, step * 2, keep))
            if w is not first:
                edits.append(TextEdit(s, e, ""))
        nl = self.style.nl
        head = (f"{pad}<state{self.style.attr('name', new)}>{nl}{pad}{step}<automaton"
                f"{self.style.attr('initial', first.attr('name'))}>{nl}")
        tail = f"{pad}{step}</automaton>{nl}{pad}</state>{nl}"
        s, e = self._lines(first)
        edits.append(TextEdit(s, e, head + "".join(chunks) + tail))
        edits += [TextEdit(off, off, text) for off, text in inserts]
        return sorted(edits, key=lambda x: (x.start, x.end))


def _walk(el: XElement) -> list[XElement]:
    out, stack = [], [el]
    while stack:
        x = stack.pop()
        out.append(x)
        stack.extend(x.children)
    return out


def _replace(refs: Any, new: str) -> list[TextEdit]:
    edits = {(r.start, r.end): TextEdit(r.start, r.end, new) for r in refs}
    return sorted(edits.values(), key=lambda e: e.start)


def _split(path: PathKey) -> tuple[str, PathKey]:
    """A Document path as the state (or region) path it is in and the rest."""
    parts: list[str] = []
    i = 0
    while i + 1 < len(path) and path[i] in ("states", "regions") and i + 2 <= len(path) - 1:
        parts.append(str(path[i + 1]))
        i += 2
    return "/".join(parts), path[i:]


def _free(prefix: str, name: str, taken: Any) -> str:
    new, n = name, 2
    while prefix + new in taken:
        new, n = f"{name}{n}", n + 1
    return new


def _text_of(text: str, el: XElement) -> str:
    from html import unescape

    raw = text[el.open_end:el.close_start]
    raw = re.sub(r"<!\[CDATA\[(.*?)\]\]>", lambda m: m.group(1).replace("&", "&amp;").replace("<", "&lt;"),
                 raw, flags=re.S)
    return unescape(raw).strip()


def _within(r: Ref, wrapped: list[XElement]) -> bool:
    return any(w.start <= r.start < w.end for w in wrapped)


def _verbatim_ranges(el: XElement, base: int) -> list[tuple[int, int]]:
    """Contents of `verbatim="true"` elements under ``el``, as offsets from ``base``."""
    return [(x.open_end - base, x.close_start - base) for x in _walk(el) if x.attr("verbatim") == "true"]


def _reindent(chunk: str, more: str, keep: list[tuple[int, int]]) -> str:
    """Every line of ``chunk`` with ``more`` indentation, but lines that start inside ``keep``."""
    out, pos = [], 0
    for ln in chunk.splitlines(True):
        inside = any(s < pos <= e for s, e in keep)
        out.append(ln if inside or not ln.strip() else more + ln)
        pos += len(ln)
    return "".join(out)


def _dedent_lines(text: str, pad: str) -> str:
    return textwrap.dedent(text) if not pad else "".join(
        ln[len(pad):] if ln.startswith(pad) else ln for ln in text.splitlines(True))


def _indent_lines(text: str, pad: str, nl: str) -> str:
    lines = text.rstrip("\r\n").splitlines()
    return nl.join(pad + ln if ln.strip() else ln for ln in lines)
