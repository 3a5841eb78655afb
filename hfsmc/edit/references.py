"""Every name a YAML model defines and every place that refers to it, as text ranges.

States (their keys; `initial`, `to`, `on_interrupt`, the segments of literal
`active("A/B")` paths), regions, parameters (keys, `$NAME` in `with`, names in
snippets), variables and interfaces (keys, names in snippets) and `use` files.
The language server's definition, references and rename, and the engine's rename,
read this one index.

Names in snippets are found by a scan that skips string literals and comments (an
f-string's `{...}` parts are code and are scanned); a name spelled inside `eval()` text
or built at run time is not seen.
"""

from __future__ import annotations

import gc
import re
from collections.abc import Iterator
from dataclasses import dataclass

from hfsmc.frontend.source import PathKey
from hfsmc.frontend.yaml_ranges import Node, YamlTree

STATE_SNIPPETS = ("entry", "during", "exit")
TRANSITION_SNIPPETS = ("when", "do")
ROOT_SNIPPETS = ("functions", "on_shutdown")

ACTIVE = re.compile(r"""\bactive\(\s*(\\?["'])([A-Za-z0-9_/]*)\1\s*\)""")
_TOKEN = re.compile(r"""(?P<pre>[rRbBuUfF]{0,2})(?P<q>"(?:\\.|[^"\\\n])*"|'(?:\\.|[^'\\\n])*')"""
                    r"""|(?P<c>#[^\n]*|//[^\n]*)|(?P<id>[A-Za-z_][A-Za-z0-9_]*)""")
_FIELD = re.compile(r"\{([^{}]*)\}")
_DOLLAR = re.compile(r"(?<!\$)\$([A-Za-z_][A-Za-z0-9_]*)")


@dataclass(frozen=True, slots=True)
class Ref:
    """A name at ``start:end`` of the text: its definition, or a reference to it."""

    kind: str  # "state" | "region" | "parameter" | "variable" | "interface" | "file"
    target: str  # a state's or region's path (`Mission/Watch/Ok`), a name, a file as written
    start: int
    end: int
    definition: bool = False
    via: str = ""  # key, initial, to, on_interrupt, active, with, snippet, use
    path: PathKey = ()  # the Document path of the value or key holding it


@dataclass
class Element:
    """A state or a region: its path in the model and in the document."""

    kind: str  # "state" | "region"
    path: str
    doc_path: PathKey
    node: Node
    key: Node
    use: str | None = None  # a state whose sub-automaton comes from another file


class Names:
    """Definitions and references of one model text, YAML's or XML's: the questions the
    language server and the renames ask."""

    refs: list[Ref]
    elements: dict[str, Element]
    names: dict[str, str]  # parameter/variable/interface name -> kind
    types: dict[str, str]  # interface name -> its type (`mavlink`, ...)

    def at(self, offset: int) -> Ref | None:
        """The name under ``offset`` (its end included, as a cursor after a word)."""
        best = None
        for r in self.refs:
            if r.start <= offset <= r.end and (best is None or r.end - r.start < best.end - best.start):
                best = r
        return best

    def definition(self, kind: str, target: str) -> Ref | None:
        kinds = ("state", "region") if kind in ("state", "region") else (kind,)
        return next((r for r in self.refs if r.definition and r.kind in kinds and r.target == target),
                    None)

    def references(self, kind: str, target: str) -> Iterator[Ref]:
        kinds = ("state", "region") if kind in ("state", "region") else (kind,)
        seen: set[tuple[int, int]] = set()
        for r in self.refs:
            if r.kind in kinds and r.target == target and (r.start, r.end) not in seen:
                seen.add((r.start, r.end))
                yield r

    def snippet_names(self, text: str, start: int, end: int, dpath: PathKey,
                      code: str | None = None) -> None:
        """The parameters, variables and interfaces named in snippet text ``text[start:end]``
        (read as ``code`` when given: the same text, entities read, at the same offsets)."""
        if not self.names:
            return
        raw = text[start:end] if code is None else code
        for s, name in identifiers(raw):
            kind = self.names.get(name)
            if kind is not None and not (s > 0 and raw[s - 1] == "&"):  # XML's &lt;
                self.refs.append(Ref(kind, name, start + s, start + s + len(name), False, "snippet",
                                     dpath))


class Index(Names):
    """The definitions and references of one YAML text."""

    def __init__(self, tree: YamlTree) -> None:
        was = gc.isenabled()
        gc.disable()  # many small objects that stay: see hfsmc/pipeline.py
        try:
            self._build(tree)
        finally:
            if was:
                gc.enable()

    def _build(self, tree: YamlTree) -> None:
        self.tree = tree
        self.refs: list[Ref] = []
        self.elements: dict[str, Element] = {}
        self.names = {}
        self.types = {}
        root = tree.root
        if root is None or root.kind != "map":
            return
        for section, kind in (("parameters", "parameter"), ("variables", "variable"),
                              ("interfaces", "interface")):
            sec = root.get(section)
            if sec is not None and sec.kind == "map":
                for k, v in zip(sec.keys, sec.items, strict=True):
                    self.names.setdefault(k.value, kind)
                    t = v.get("type") if kind == "interface" else None
                    if t is not None and t.kind == "scalar":
                        self.types[k.value] = t.value
                    self.refs.append(Ref(kind, k.value, k.start, k.end, True, "key", (section, k.value)))
        self._automaton(root, "", (), is_root=True)
        oi = root.get("on_interrupt")
        if oi is not None and oi.kind == "scalar":
            self._name_ref("state", oi.value, oi, ("on_interrupt",), "on_interrupt")
        for key in ROOT_SNIPPETS:
            self._snippet(root.get(key), "", (key,))

    # ----- walking

    def _automaton(self, node: Node, prefix: str, dpath: PathKey, is_root: bool = False) -> None:
        states = node.get("states")
        initial = node.get("initial")
        if initial is not None and initial.kind == "scalar":
            self._name_ref("state", prefix + initial.value, initial, (*dpath, "initial"), "initial")
        if states is None or states.kind not in ("map", "alias"):
            return
        target = states.target if states.kind == "alias" else states
        if target is None or target.kind != "map":
            return
        for k, v in zip(target.keys, target.items, strict=True):
            self._state(prefix, k, v, (*dpath, "states", k.value))

    def _state(self, prefix: str, key: Node, node: Node, dpath: PathKey) -> None:
        path = prefix + key.value
        if node.kind == "alias" and node.target is not None:
            node = node.target
        use = node.get("use") if node.kind == "map" else None
        self.elements.setdefault(path, Element("state", path, dpath, node, key,
                                               use.value if use is not None else None))
        self.refs.append(Ref("state", path, key.start, key.end, True, "key", dpath))
        if node.kind != "map":
            return
        for s in STATE_SNIPPETS:
            self._snippet(node.get(s), prefix, (*dpath, s))
        if use is not None and use.kind == "scalar":
            self.refs.append(Ref("file", use.value, use.start, use.end, False, "use", (*dpath, "use")))
        with_ = node.get("with")
        if with_ is not None and with_.kind == "map":
            for k, v in zip(with_.keys, with_.items, strict=True):
                if v.kind == "scalar":
                    for m in _DOLLAR.finditer(v.value):
                        at = self.tree.text.find("$" + m.group(1), v.start, v.end + 1)
                        if at >= 0:
                            self.refs.append(Ref("parameter", m.group(1), at + 1, at + 1 + len(m.group(1)),
                                                 False, "with", (*dpath, "with", k.value)))
        trans = node.get("transitions")
        if trans is not None and trans.kind == "seq":
            for i, t in enumerate(trans.items):
                if t.kind != "map":
                    continue
                to = t.get("to")
                if to is not None and to.kind == "scalar":
                    self._name_ref("state", prefix + to.value, to, (*dpath, "transitions", i, "to"), "to")
                for s in TRANSITION_SNIPPETS:
                    self._snippet(t.get(s), prefix, (*dpath, "transitions", i, s))
        self._automaton(node, path + "/", dpath)
        regions = node.get("regions")
        if regions is not None and regions.kind == "map":
            for k, v in zip(regions.keys, regions.items, strict=True):
                rpath = path + "/" + k.value
                rdpath = (*dpath, "regions", k.value)
                self.elements.setdefault(rpath, Element("region", rpath, rdpath, v, k))
                self.refs.append(Ref("region", rpath, k.start, k.end, True, "key", rdpath))
                if v.kind == "map":
                    self._automaton(v, rpath + "/", rdpath)

    def _name_ref(self, kind: str, target: str, node: Node, dpath: PathKey, via: str) -> None:
        start, end = _name_range(self.tree.text, node)
        self.refs.append(Ref(kind, target, start, end, False, via, dpath))

    def _snippet(self, node: Node | None, prefix: str, dpath: PathKey) -> None:
        if node is None or node.kind != "scalar":
            return
        text = self.tree.text
        raw = text[node.start:node.end]
        for m in ACTIVE.finditer(raw):
            pos = node.start + m.start(2)
            walked = ""
            for seg in m.group(2).split("/"):
                if seg:
                    walked = f"{walked}/{seg}" if walked else seg
                    self.refs.append(Ref("state", walked, pos, pos + len(seg), False, "active", dpath))
                pos += len(seg) + 1
        self.snippet_names(text, node.start, node.end, dpath)


def _name_range(text: str, node: Node) -> tuple[int, int]:
    """The range of a scalar's name inside its quotes."""
    if node.style in ("'", '"') and node.end - node.start >= 2:
        return node.start + 1, node.end - 1
    return node.start, node.end


def identifiers(raw: str) -> Iterator[tuple[int, str]]:
    """(offset, name) of every identifier of snippet text, strings and comments skipped,
    attribute names (`x.name`) too."""
    for m in _TOKEN.finditer(raw):
        if m.group("id"):
            s = m.start("id")
            if s > 0 and raw[s - 1] == ".":
                continue
            yield s, m.group("id")
        elif m.group("q") and "f" in m.group("pre").lower():
            base = m.start("q")
            for f in _FIELD.finditer(m.group("q")):
                for s, name in identifiers(f.group(1)):
                    yield base + f.start(1) + s, name
