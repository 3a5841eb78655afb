"""The model's operations on a YAML text (states, regions, transitions, fields,
parameters, variables, interfaces, imports; rename; wrap; copy and paste), each
turned into :class:`TextEdit` s by :mod:`hfsmc.edit.yaml_splice`.

Elements are named by their model path (`Mission/FollowGreen`, a region's name
included: `Mission/Watch/Ok`; "" is the root).  An edit that leaves the model
invalid is still made (SPEC 8.1): the session's check says what is wrong."""

from __future__ import annotations

import re
from typing import Any

import yaml

from hfsmc.edit import yaml_splice as splice
from hfsmc.edit.references import Element, Index
from hfsmc.edit.text import EditError, TextEdit, apply_edits, insert_into
from hfsmc.edit.yaml_splice import Splicer
from hfsmc.frontend.source import PathKey

IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
SECTIONS = {"parameter": "parameters", "variable": "variables", "interface": "interfaces"}


def _ident(name: str, what: str) -> None:
    if not IDENT.match(name):
        raise EditError(f"`{name}` is not a valid {what} name (letters, digits, `_`; not a digit first)")


class YamlOps:
    """Operations on one YAML text; each returns the edits that make it."""

    def __init__(self, text: str, index: Index | None = None) -> None:
        """``index``: one already built for this text (the language server keeps one)."""
        self.sp = Splicer(text, index.tree if index is not None else None)
        self.index = index if index is not None and index.tree is self.sp.tree else Index(self.sp.tree)

    @property
    def text(self) -> str:
        return self.sp.text

    # ----- finding elements

    def element(self, path: str) -> Element:
        el = self.index.elements.get(path)
        if el is None:
            raise EditError(f"no state or region `{path}` in this model")
        return el

    def automaton(self, path: str) -> PathKey:
        """The Document path of the sub-automaton owner at ``path`` ("" the root)."""
        return () if not path else self.element(path).doc_path

    def _writable(self, el: Element) -> None:
        shared = self.sp.tree.shared(el.doc_path)
        if shared is not None:
            raise EditError(f"`{el.path}` is written once under the anchor &{shared.value} and "
                            f"shared through *{shared.value}: edit it at the anchor")
        parts = el.path.split("/")
        for i in range(1, len(parts)):
            up = self.index.elements.get("/".join(parts[:i]))
            if up is not None and up.use is not None:
                raise EditError(f"`{el.path}` is in {up.use} (used by `{up.path}`): read-only here, "
                                "edit that file")

    # ----- states and regions

    def add_state(self, parent: str, name: str, body: dict[str, Any] | None = None,
                  index: int | None = None) -> list[TextEdit]:
        """A new state ``name`` in ``parent``'s sub-automaton (or region); the first
        state of a sub-automaton becomes its `initial`."""
        _ident(name, "state")
        owner = self.automaton(parent)
        node = self.sp.tree.find(owner)
        states = node.get("states") if node is not None else None
        if parent and self.index.elements[parent].kind == "state" and node is not None \
                and node.get("regions") is not None:
            raise EditError(f"`{parent}` has regions: add the state to one of them")
        edits = splice.add_entry(self.sp, (*owner, "states"), name, body or {}, index)
        if (states is None or (states.kind == "map" and not states.keys)) and \
                (node is None or node.get("initial") is None):
            edits = self._also(edits, lambda sp: _set_initial(sp, owner, name))
        return edits

    def _also(self, first: list[TextEdit], more: Any) -> list[TextEdit]:
        """Edits made after ``first``, expressed against the original text (the two
        touch different places): computed on the text with ``first`` applied and
        mapped back."""
        mid = apply_edits(self.text, first)
        second = more(Splicer(mid))
        return _compose(self.text, first, second)

    def delete_state(self, path: str) -> list[TextEdit]:
        el = self.element(path)
        self._writable(el)
        return splice.delete(self.sp, el.doc_path)

    def move_state(self, path: str, index: int) -> list[TextEdit]:
        """Move a state (or a region) to position ``index`` among its siblings."""
        el = self.element(path)
        self._writable(el)
        return splice.move(self.sp, el.doc_path, index)

    def rename(self, path: str, new: str) -> list[TextEdit]:
        """Rename a state or a region, and every reference to it in this file."""
        _ident(new, "state")
        el = self.element(path)
        self._writable(el)
        parent_path = path.rsplit("/", 1)[0] if "/" in path else ""
        new_path = (parent_path + "/" if parent_path else "") + new
        if new_path in self.index.elements and new != path.rsplit("/", 1)[-1]:
            raise EditError(f"`{new_path}` already exists")
        # states shared through an alias are renamed in every copy
        copies = {e.path for e in self.index.elements.values() if e.key is el.key}
        edits: dict[tuple[int, int], TextEdit] = {}
        for target in copies:
            for r in self.index.references("state", target):
                edits[(r.start, r.end)] = TextEdit(r.start, r.end, new)
        key = el.key
        quoted = key.style in ("'", '"')
        edits[(key.start, key.end)] = TextEdit(key.start, key.end, f"{key.style}{new}{key.style}"
                                               if quoted else new)
        return sorted(edits.values(), key=lambda e: e.start)

    def add_region(self, state: str, name: str, body: dict[str, Any] | None = None,
                   index: int | None = None) -> list[TextEdit]:
        _ident(name, "region")
        el = self.element(state)
        self._writable(el)
        return splice.add_entry(self.sp, (*el.doc_path, "regions"), name, body or {"states": {}},
                                index)

    # ----- transitions

    def _transitions(self, state: str) -> PathKey:
        el = self.element(state)
        self._writable(el)
        return (*el.doc_path, "transitions")

    def add_transition(self, state: str, transition: dict[str, Any],
                       index: int | None = None) -> list[TextEdit]:
        return splice.add_item(self.sp, self._transitions(state), transition, index)

    def delete_transition(self, state: str, i: int) -> list[TextEdit]:
        return splice.delete(self.sp, (*self._transitions(state), i))

    def move_transition(self, state: str, i: int, index: int) -> list[TextEdit]:
        return splice.move(self.sp, (*self._transitions(state), i), index)

    # ----- fields

    def set_field(self, path: PathKey, value: Any) -> list[TextEdit]:
        """Set (None: clear) the value at a Document path, snippets included."""
        return splice.set_value(self.sp, path, value)

    def set_state_field(self, state: str, key: str, value: Any) -> list[TextEdit]:
        if state:
            el = self.element(state)
            self._writable(el)
            return self.set_field((*el.doc_path, key), value)
        return self.set_field((key,), value)

    def add_declaration(self, kind: str, name: str, spec: Any) -> list[TextEdit]:
        """Add a parameter, a variable or an interface."""
        _ident(name, kind)
        return splice.add_entry(self.sp, (SECTIONS[kind],), name, spec)

    def remove_declaration(self, kind: str, name: str) -> list[TextEdit]:
        return splice.delete(self.sp, (SECTIONS[kind], name))

    def rename_declaration(self, kind: str, name: str, new: str) -> list[TextEdit]:
        """Rename a parameter, a variable or an interface, and its uses in snippets
        (and a parameter's `$NAME` in `with`)."""
        _ident(new, kind)
        if new in self.index.names and new != name:
            raise EditError(f"`{new}` is already a {self.index.names[new]}")
        if self.index.definition(kind, name) is None:
            raise EditError(f"no {kind} `{name}` in this model")
        return sorted((TextEdit(r.start, r.end, new) for r in self.index.references(kind, name)),
                      key=lambda e: e.start)

    def add_import(self, line: str, index: int | None = None) -> list[TextEdit]:
        return splice.add_item(self.sp, ("imports",), line, index)

    def remove_import(self, line: str) -> list[TextEdit]:
        node = self.sp.tree.find(("imports",))
        items = [] if node is None or node.kind != "seq" else [x.value for x in node.items]
        if line not in items:
            raise EditError(f"no import `{line}`")
        return splice.delete(self.sp, ("imports", items.index(line)))

    # ----- wrap, copy, paste

    def copy_state(self, path: str) -> str:
        """The state as YAML text (`Name:` and its body, at indentation 0)."""
        el = self.element(path)
        parent = self.sp.tree.find(el.doc_path[:-1])
        assert parent is not None
        i = parent.key_index(el.key.value)
        assert i is not None
        if parent.flow:
            return self.text[el.key.start:el.node.end] + "\n"
        s, e = self.sp.entry_range(parent, i)
        return _dedent(self.text[s:e])

    def paste_state(self, parent: str, text: str, index: int | None = None) -> tuple[list[TextEdit], str]:
        """Paste a state copied by :meth:`copy_state` into ``parent``; a name taken among
        the siblings gets a number (`Track2`).  Returns the edits and the name."""
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as e:
            raise EditError(f"the pasted text is not YAML: {str(e).splitlines()[0]}") from None
        if not isinstance(data, dict) or len(data) != 1:
            raise EditError("the pasted text is not one state (`Name:` and its body)")
        (name,) = data
        name = str(name)
        siblings = {p.rsplit("/", 1)[-1] for p in self.index.elements
                    if (p.rsplit("/", 1)[0] == parent and "/" in p) or (not parent and "/" not in p)}
        new, n = name, 2
        while new in siblings:
            new, n = f"{name}{n}", n + 1
        owner = self.automaton(parent)
        states = self.sp.tree.find((*owner, "states"))
        if states is None or states.kind != "map" or states.flow or not states.keys:
            edits = self.add_state(parent, new, data[name], index)
            return edits, new
        col = self.sp.col(states.keys[0].start)
        body = _dedent(text)
        if new != name:
            body = re.sub(rf"^{re.escape(name)}(?=\s*:)", new, body, count=1)
        lines = "".join(((" " * col + ln) if ln.strip() else ln) for ln in body.splitlines(True))
        lines = lines.rstrip("\r\n").replace("\n", self.sp.nl) if self.sp.nl != "\n" else \
            lines.rstrip("\n")
        return splice._insert_block(self.sp, states, len(states.keys) if index is None else index,
                                    lines), new

    def wrap_states(self, parent: str, names: list[str], new: str) -> list[TextEdit]:
        """Move sibling states ``names`` of ``parent`` into a new composite state ``new``
        (its `initial` the first of them), where the first of them was.  Transitions of
        other siblings to them now go to ``new``; theirs to states left outside stay as
        written and are diagnosed."""
        _ident(new, "state")
        if not names:
            raise EditError("no states to wrap")
        prefix = parent + "/" if parent else ""
        els = [self.element(prefix + n) for n in names]
        for el in els:
            self._writable(el)
        if prefix + new in self.index.elements and new not in names:
            raise EditError(f"`{prefix + new}` already exists")
        owner = self.automaton(parent)
        states = self.sp.tree.find((*owner, "states"))
        assert states is not None
        order = [k.value for k in states.keys]
        wrapped = sorted(names, key=order.index)
        edits: list[TextEdit] = []
        inside = set(wrapped)
        for r in self.index.refs:
            if r.kind == "state" and r.via in ("to", "initial", "on_interrupt") and not r.definition:
                tgt = r.target
                if tgt.startswith(prefix) and tgt[len(prefix):] in inside:
                    src_path = _ref_owner(r.path)
                    if src_path is None or src_path not in {(*owner, "states", n) for n in inside}:
                        edits.append(TextEdit(r.start, r.end, new))
        # Literal `active("P/A/...")` paths through a wrapped state gain the new level.
        moved = {prefix + n for n in inside}
        inserts = sorted({(r.start, new + "/") for r in self.index.refs
                          if r.kind == "state" and r.via == "active" and r.target in moved})
        if states.flow:
            raise EditError("the states are written in flow style: wrap is for block mappings")
        col = self.sp.col(states.keys[0].start)
        step = self.sp.step
        chunks = []
        for n in wrapped:
            i = states.key_index(n)
            assert i is not None
            s, e = self.sp.entry_range(states, i)
            chunk, _ = insert_into(self.text[s:e], s, inserts)
            inserts = [i for i in inserts if not s <= i[0] < e]
            if not chunk.endswith(("\n", "\r")):
                chunk += self.sp.nl
            chunks.append(chunk)
            if n != wrapped[0]:
                edits.append(TextEdit(s, e, ""))
        pad = " " * (col + step)
        inner = "".join("".join(pad[:2 * step] + ln if ln.strip() else ln
                                for ln in c.splitlines(True)) for c in chunks)
        nl = self.sp.nl
        head = f"{' ' * col}{new}:{nl}{pad}initial: {wrapped[0]}{nl}{pad}states:{nl}"
        first = states.key_index(wrapped[0])
        assert first is not None
        s, e = self.sp.entry_range(states, first)
        edits.append(TextEdit(s, e, head + inner))
        edits += [TextEdit(off, off, text) for off, text in inserts]
        # `initial` of the parent pointed at a wrapped state: the references loop rewrote it
        return sorted(edits, key=lambda x: (x.start, x.end))


def _set_initial(sp: Splicer, owner: PathKey, name: str) -> list[TextEdit]:
    """`initial: name` in the mapping at ``owner``, before its `states`."""
    node = sp.tree.find(owner)
    at = node.key_index("states") if node is not None and node.kind == "map" else None
    return splice.add_entry(sp, owner, "initial", name, at)


def _ref_owner(path: PathKey) -> PathKey | None:
    """The Document path of the state whose transition holds the reference at ``path``."""
    if "transitions" in path:
        i = len(path) - 1 - path[::-1].index("transitions")
        return path[:i]
    return None


def _dedent(text: str) -> str:
    lines = text.splitlines(True)
    cols = [len(ln) - len(ln.lstrip(" ")) for ln in lines if ln.strip()]
    cut = min(cols, default=0)
    return "".join(ln[cut:] if ln.strip() else ln for ln in lines)


def _compose(text: str, first: list[TextEdit], second: list[TextEdit]) -> list[TextEdit]:
    """Edits against ``text`` doing ``first`` then ``second`` (made on the result of
    ``first``), when ``second`` touches no text ``first`` inserted."""
    out: list[TextEdit] = []
    for e in second:
        s, t = _back(first, e.start), _back(first, e.end)
        if s is None or t is None:
            raise EditError("edits overlap")
        out.append(TextEdit(s, t, e.new))
    out += first  # at one offset, what the second inserted goes before the first's text
    return sorted(out, key=lambda x: (x.start, x.end))


def _back(first: list[TextEdit], pos: int) -> int | None:
    """The offset in the original text of ``pos`` in the edited one."""
    shift = 0
    for f in sorted(first, key=lambda x: x.start):
        new_start = f.start + shift
        new_end = new_start + len(f.new)
        if pos <= new_start:
            break
        if pos <= new_end and len(f.new):
            if pos == new_end:
                shift += len(f.new) - (f.end - f.start)
                continue
            return None
        shift += len(f.new) - (f.end - f.start)
    return pos - shift
