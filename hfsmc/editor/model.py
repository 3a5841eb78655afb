"""What the editor's page is told about the model being edited: its structure (every
automaton's states, each state's snippets and transitions), the diagnostics keyed by the
state or transition they are in, and where each state is drawn (``NAME.layout.yaml``
beside the model, else Graphviz's layout)."""

from __future__ import annotations

import os
import re
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from hfsmc.edit.references import Index
from hfsmc.edit.session import EditSession
from hfsmc.editor.forms import settings
from hfsmc.errors import Diagnostics
from hfsmc.frontend import is_xml, load
from hfsmc.frontend.yaml_ranges import YamlTree
from hfsmc.fsutil import write_atomic

SNIPPETS = ("entry", "during", "exit")
EDGE_KEYS = ("name", "to", "when", "after", "do")
SCALE = 72.0  # Graphviz's points per inch
MAX_LAYOUT_BYTES = 1 << 20


def _text(v: Any) -> str | None:
    if v is None:
        return None
    if isinstance(v, bool):
        return "true" if v else "false"
    return str(v)


def structure(session: EditSession) -> dict[str, Any]:
    """Every automaton (``""`` the root) with its states, and every state by its path."""
    try:
        data = load(session.path, Diagnostics(), session.text).data
    except Exception:  # a text the front end cannot read: its diagnostics say why
        data = None
    automata: dict[str, Any] = {}
    states: dict[str, Any] = {}
    if isinstance(data, dict):
        _walk(data, "", automata, states)
    return {"automata": automata, "states": states, "settings": settings(data),
            "language": data.get("language", "python") if isinstance(data, dict) else "python"}


def _walk(body: dict[str, Any], owner: str, automata: dict[str, Any],
          states: dict[str, Any]) -> None:
    kids: dict[Any, Any] = body["states"] if isinstance(body.get("states"), dict) else {}
    regions: dict[Any, Any] = body["regions"] if isinstance(body.get("regions"), dict) else {}
    automata[owner] = {"states": [str(k) for k in kids] or [str(k) for k in regions],
                       "initial": _text(body.get("initial")), "regions": bool(regions)}
    prefix = owner + "/" if owner else ""
    for kind, group in (("state", kids), ("region", regions)):
        for name, sub in group.items():
            sub = sub if isinstance(sub, dict) else {}
            path = prefix + str(name)
            trans: list[Any] = sub["transitions"] if isinstance(sub.get("transitions"), list) \
                else []
            inner = isinstance(sub.get("states"), dict) or isinstance(sub.get("regions"), dict)
            states[path] = {
                "name": str(name), "kind": kind, "parent": owner, "composite": inner,
                "use": _text(sub.get("use")), "final": sub.get("final") is True,
                "regions": isinstance(sub.get("regions"), dict),
                **{k: _text(sub.get(k)) for k in SNIPPETS},
                "transitions": [{k: _text(t.get(k)) for k in EDGE_KEYS} if isinstance(t, dict)
                                else {} for t in trans]}
            if inner:
                _walk(sub, path, automata, states)


def diagnostics(session: EditSession) -> list[dict[str, Any]]:
    """The session's diagnostics, each with the element it is in: ``state`` (a path,
    ``""`` the root) and, inside a transition, ``transition`` (its index)."""
    ranges: list[tuple[int, int, str, int | None]] = []
    if not is_xml(session.text):
        try:
            tree = YamlTree(session.text)
            index = Index(tree)
        except Exception:
            tree = None
        if tree is not None:
            for el in index.elements.values():
                ranges.append((el.key.start, max(el.node.end, el.key.end), el.path, None))
                node = tree.find((*el.doc_path, "transitions"))
                if node is not None and node.kind == "seq":
                    for n, t in enumerate(node.items):
                        ranges.append((t.start, t.end, el.path, n))
    starts = [0, *(m.end() for m in re.finditer(r"\r\n|\r|\n", session.text))]
    here = os.path.normpath(session.path)
    out: list[dict[str, Any]] = []
    for d in session.diagnostics:
        item: dict[str, Any] = {**d.as_dict(), "state": "", "transition": None}
        if os.path.normpath(d.span.file) != here:
            item["other"] = True
        else:
            off = starts[min(max(d.span.line, 1), len(starts)) - 1] + d.span.col - 1
            best: tuple[int, str, int | None] | None = None
            for start, end, path, i in ranges:
                if start <= off <= end and (best is None or end - start < best[0]):
                    best = (end - start, path, i)
            if best is not None:
                item["state"], item["transition"] = best[1], best[2]
        out.append(item)
    return out


@dataclass
class Layout:
    """Positions the user gave states (``NAME.layout.yaml`` beside the model), and
    Graphviz's for the others (kept per automaton until its states or arrows change)."""

    path: Path
    given: dict[str, list[float]] = field(default_factory=dict)
    cache: dict[str, tuple[Any, dict[str, list[float]]]] = field(default_factory=dict)
    problem: str | None = None

    @classmethod
    def beside(cls, model: Path) -> Layout:
        path = model.with_name(model.name.rsplit(".", 1)[0] + ".layout.yaml")
        layout = cls(path)
        if path.is_symlink():
            layout.problem = f"{path.name} is a symbolic link: not read, positions laid out again"
        elif path.exists():
            try:
                if path.stat().st_size > MAX_LAYOUT_BYTES:
                    raise ValueError("larger than 1 MiB")
                raw = yaml.safe_load(path.read_text("utf-8")) or {}
                for k, v in (raw.get("states") or {}).items():
                    layout.given[str(k)] = [float(v["x"]), float(v["y"])]
            except (OSError, ValueError, TypeError, KeyError, AttributeError,
                    yaml.YAMLError) as e:
                layout.problem = f"{path.name}: not read ({str(e).splitlines()[0]}): positions " \
                                 "laid out again"
                layout.given = {}
        return layout

    def move(self, state: str, x: float, y: float) -> None:
        self.given[state] = [round(x, 1), round(y, 1)]
        self.write()

    def renamed(self, old: str, new: str) -> None:
        moved = {(new + k[len(old):] if k == old or k.startswith(old + "/") else k): v
                 for k, v in self.given.items()}
        if moved != self.given:
            self.given = moved
            self.write()

    def write(self) -> None:
        if self.path.is_symlink():
            raise OSError(f"{self.path.name} is a symbolic link: positions not written")
        body = {"states": {k: {"x": v[0], "y": v[1]} for k, v in sorted(self.given.items())}}
        text = ("# Where `hfsmc edit` draws the states of the model beside this file "
                "(docs/editor.md).\n" + yaml.safe_dump(body, sort_keys=False))
        write_atomic(self.path, text)

    def positions(self, shape: dict[str, Any]) -> dict[str, list[float]]:
        """Every state's position (its centre, in the canvas's pixels)."""
        out: dict[str, list[float]] = {}
        for owner, auto in shape["automata"].items():
            names = auto["states"]
            prefix = owner + "/" if owner else ""
            edges = sorted({(n, t["to"]) for n in names
                            for t in shape["states"].get(prefix + n, {}).get("transitions", [])
                            if t.get("to") in names})
            key = (tuple(names), tuple(edges))
            if owner not in self.cache or self.cache[owner][0] != key:
                self.cache[owner] = (key, _dot(names, edges))
            auto_pos = self.cache[owner][1]
            for n in names:
                out[prefix + n] = self.given.get(prefix + n) or auto_pos.get(n, [80.0, 80.0])
        return out


def _dot(names: list[str], edges: list[tuple[str, str]]) -> dict[str, list[float]]:
    """Graphviz's positions of a flat graph (``dot -Tplain``), top-down, in pixels."""
    if not names:
        return {}
    lines = ["digraph g { rankdir=TB; nodesep=0.9; ranksep=0.9; node [shape=box, width=1.6, "
             "height=0.7, fixedsize=true];"]
    lines += [f'"{n}";' for n in names]
    lines += [f'"{a}" -> "{b}";' for a, b in edges]
    lines.append("}")
    try:
        plain = subprocess.run(["dot", "-Tplain"], input="\n".join(lines), capture_output=True,
                               text=True, timeout=20, check=True).stdout
    except (OSError, subprocess.SubprocessError):
        return {n: [120.0 + 200.0 * (i % 4), 90.0 + 130.0 * (i // 4)]
                for i, n in enumerate(names)}
    height = 0.0
    out: dict[str, list[float]] = {}
    for line in plain.splitlines():
        part = line.split()
        if part and part[0] == "graph":
            height = float(part[3])
        elif part and part[0] == "node":
            out[part[1].strip('"')] = [round(float(part[2]) * SCALE + 40, 1),
                                       round((height - float(part[3])) * SCALE + 40, 1)]
    return out
