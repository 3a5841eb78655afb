"""The language server's answers, computed from an :class:`Analysis` (no protocol here
beyond lsprotocol's types)."""

from __future__ import annotations

import json
import os
import re
from collections.abc import Sequence
from functools import cache
from pathlib import Path
from typing import Any

from lsprotocol import types

from hfsmc.drivers import driver
from hfsmc.edit.library import model_files, names_of, rename_in_users
from hfsmc.edit.references import Index, Names, Ref
from hfsmc.edit.text import EditError, apply_edits
from hfsmc.edit.xml_ops import XmlOps
from hfsmc.edit.xml_tree import XmlNames
from hfsmc.edit.yaml_ops import YamlOps
from hfsmc.errors import CODES
from hfsmc.frontend.yaml_ranges import YamlTree
from hfsmc.lsp import xml_features
from hfsmc.lsp.analysis import Analysis
from hfsmc.lsp.positions import Lines
from hfsmc.resources import schema_file

HELPERS = {"log": "log(msg): write a log line", "elapsed": "elapsed(): seconds since the state was entered",
           "now": "now(): seconds since the component started", "done": "done(): the sub-automaton is in a final state",
           "active": 'active("A/B"): that state is active now', "shutdown": "shutdown(): ask for a graceful stop",
           "yaw_of": "yaw_of(q): the heading (rad) of a quaternion",
           "euler_from_quaternion": "euler_from_quaternion(q): roll, pitch and yaw (rad) of a quaternion"}
_STATE_VALUE = re.compile(r"(?:^|[{,\s])(?:to|initial|on_interrupt)\s*(?::\s*[\"']?|=\s*[\"'])(\w*)$")
_ACTIVE_OPEN = re.compile(r"""active\(\s*(?:\\?["']|&quot;|&apos;)([\w/]*)$""")
_ATTRIBUTE = re.compile(r"\b([A-Za-z_]\w*)\.(\w*)$")
_DOLLAR = re.compile(r"\$(\w*)$")
_KEY_START = re.compile(r"^(\s*)(?:-\s+)?([A-Za-z_]\w*)?$")


def uri_of(path: str) -> str:
    return Path(path).resolve().as_uri()


# ----- definition and references

def definition(a: Analysis, offset: int) -> types.Location | None:
    if a.index is None:
        return None
    ref = a.index.at(offset)
    if ref is None:
        return None
    if ref.kind == "file":
        target = Path(a.path).parent / ref.target
        return types.Location(uri_of(str(target)), types.Range(types.Position(0, 0), types.Position(0, 0)))
    d = a.index.definition(ref.kind, ref.target)
    if d is not None:
        return types.Location(uri_of(a.path), a.lines.range(d.start, d.end))
    if ref.kind == "state":
        return _in_used_file(a, a.index, ref.target)
    return None


def _in_used_file(a: Analysis, index: Names, target: str) -> types.Location | None:
    """A state path that goes into a `use`d file: its definition there."""
    parts = target.split("/")
    for i in range(len(parts) - 1, 0, -1):
        el = index.elements.get("/".join(parts[:i]))
        if el is not None and el.use is not None:
            used = Path(a.path).parent / el.use
            try:
                text = used.read_text("utf-8")
            except (OSError, ValueError):
                return None
            other = names_of(text)
            if other is None:
                return None
            d = other.definition("state", "/".join(parts[i:]))
            if d is None:
                return None
            return types.Location(uri_of(str(used)), Lines(text).range(d.start, d.end))
    return None


def references(a: Analysis, offset: int, declaration: bool) -> list[types.Location]:
    if a.index is None:
        return []
    ref = a.index.at(offset)
    if ref is None:
        return []
    uri = uri_of(a.path)
    return [types.Location(uri, a.lines.range(r.start, r.end))
            for r in a.index.references(ref.kind, ref.target) if declaration or not r.definition]


def rename(a: Analysis, offset: int, new: str, roots: Sequence[str] = ()
           ) -> tuple[types.WorkspaceEdit, str | None]:
    """The edits of a rename of the name under ``offset`` (raises EditError), and what
    could not be renamed (read-only models that use this one).  A state renamed in a
    library is renamed in the `active()` paths of the models that use it, in those of the
    folders ``roots`` (the workspace's) that hold the library."""
    if a.index is None or not a.parsed:
        raise EditError("the document does not parse: fix it before renaming")
    ref = a.index.at(offset)
    if ref is None or ref.kind == "file":
        raise EditError("no state, region, parameter, variable or interface here")
    ops: YamlOps | XmlOps = XmlOps(a.text, a.index) if isinstance(a.index, XmlNames) else \
        YamlOps(a.text, a.index if isinstance(a.index, Index) else None)
    users = None
    if ref.kind in ("state", "region"):
        if ref.target not in a.index.elements:
            raise EditError(f"`{ref.target}` is not defined in this file (a used file's states "
                            "are read-only here: rename it in that file)")
        edits = ops.rename(ref.target, new)
        users = rename_in_users(Path(a.path), ref.target, new, _models_beside(a.path, roots))
    else:
        edits = ops.rename_declaration(ref.kind, ref.target, new)
    apply_edits(a.text, edits)  # refuses overlapping edits before the client sees them
    changes = {uri_of(a.path): [types.TextEdit(a.lines.range(e.start, e.end), e.new) for e in edits]}
    if users is None:
        return types.WorkspaceEdit(changes=changes), None
    for f, more in users.edits.items():
        lines = Lines(users.texts[f])
        changes[uri_of(f)] = [types.TextEdit(lines.range(e.start, e.end), e.new) for e in more]
    return types.WorkspaceEdit(changes=changes), users.message()


def _models_beside(path: str, roots: Sequence[str]) -> list[Path]:
    """The model files of the workspace folders that hold ``path`` (none for a file
    outside the workspace)."""
    p = Path(path).resolve()
    out: dict[Path, None] = {}
    for r in roots:
        if p.is_relative_to(Path(r).resolve()):
            out.update(dict.fromkeys(model_files(Path(r))))
    return list(out)


# ----- symbols

def symbols(a: Analysis) -> list[types.DocumentSymbol]:
    if a.index is None:
        return []
    by_path: dict[str, types.DocumentSymbol] = {}
    roots: list[types.DocumentSymbol] = []
    for path, el in a.index.elements.items():  # parents first, siblings in text order
        end = max(el.node.end, el.key.end)
        if end < el.key.start:
            end = el.key.end
        sym = types.DocumentSymbol(
            name=path.rsplit("/", 1)[-1], detail=("region" if el.kind == "region" else
                                                 f"use {el.use}" if el.use else path),
            kind=types.SymbolKind.Namespace if el.kind == "region" else types.SymbolKind.Class,
            range=a.lines.range(el.key.start, end), selection_range=a.lines.range(el.key.start, el.key.end),
            children=[])
        parent = by_path.get(path.rsplit("/", 1)[0]) if "/" in path else None
        if parent is not None and isinstance(parent.children, list):
            parent.children.append(sym)
        else:
            roots.append(sym)
        by_path[path] = sym
    return roots


# ----- completion

@cache
def _schema() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(Path(str(schema_file("hfsm.schema.json"))).read_text("utf-8"))
    return data


def keys_of(context: str) -> dict[str, str]:
    """The keys allowed in a mapping of ``context`` (root, state, transition, region,
    parameter, interface) with their documentation."""
    s = _schema()
    props = s["properties"] if context == "root" else s["$defs"].get(context, {}).get("properties", {})
    return {k: v.get("description", "") for k, v in props.items()}


def context_of(path: tuple[Any, ...]) -> str | None:
    if not path:
        return "root"
    if len(path) >= 2 and path[-2] == "states":
        return "state"
    if len(path) >= 2 and path[-2] == "transitions":
        return "transition"
    if len(path) >= 2 and path[-2] == "regions":
        return "region"
    if len(path) == 2 and path[0] in ("parameters", "interfaces"):
        return str(path[0])[:-1]
    return None


def _mapping_at(tree: YamlTree, offset: int, indent: int) -> tuple[Any, ...] | None:
    """The path of the block mapping whose keys sit at column ``indent`` around ``offset``."""
    best: tuple[int, tuple[Any, ...]] | None = None
    for path, node in tree.walk():
        if node.kind == "map" and node.keys and not node.flow and tree.col_of(node.keys[0].start) == indent \
                and node.keys[0].start <= offset and (best is None or node.keys[0].start > best[0]):
            best = (node.keys[0].start, path)
    return best[1] if best else None


def completion(a: Analysis, offset: int) -> list[types.CompletionItem]:
    pos = a.lines.position(offset)
    line = a.lines.line(pos.line)
    before = line[:offset - a.lines.offset(types.Position(pos.line, 0))]
    index = a.index
    items: list[types.CompletionItem] = []
    if index is None:
        return items
    m = _ACTIVE_OPEN.search(before)
    if m:
        return [types.CompletionItem(p, kind=types.CompletionItemKind.Reference)
                for p in sorted(index.elements)]
    m = _STATE_VALUE.search(before)
    if m:
        here = _element_at(a, offset)
        parent = here.rsplit("/", 1)[0] if here and "/" in here else ""
        if before.rstrip().endswith("initial:") or "initial" in before.split(":")[0]:
            parent = here or ""
        names = sorted({p.rsplit("/", 1)[-1] for p in index.elements
                        if (p.rsplit("/", 1)[0] if "/" in p else "") == parent})
        return [types.CompletionItem(n, kind=types.CompletionItemKind.EnumMember) for n in names]
    m = _DOLLAR.search(before)
    if m:
        return [types.CompletionItem(n, kind=types.CompletionItemKind.Constant)
                for n, k in sorted(index.names.items()) if k == "parameter"]
    m = _ATTRIBUTE.search(before)
    if m and index.names.get(m.group(1)) == "interface":
        kind = index.types.get(m.group(1))
        drv = driver(kind) if kind is not None else None
        if drv is not None:
            return [types.CompletionItem(x.name, kind=types.CompletionItemKind.Method,
                                         detail=x.signature(), documentation=x.doc)
                    for x in drv.methods.values()]
        return items
    if isinstance(index, XmlNames):
        markup = xml_features.completion(a.text, offset)
        if markup is not None:
            return markup
    m = _KEY_START.match(before)
    if m and a.tree is not None:
        path = _mapping_at(a.tree, offset, len(m.group(1)))
        ctx = context_of(path) if path is not None else ("root" if not m.group(1) else None)
        if ctx is not None:
            node = a.tree.find(path or ())
            present = {k.value for k in node.keys} if node is not None and node.kind == "map" else set()
            return [types.CompletionItem(k, kind=types.CompletionItemKind.Property, documentation=doc,
                                         insert_text=k + ": ")
                    for k, doc in keys_of(ctx).items() if k not in present]
    # inside code: the names a snippet sees
    items += [types.CompletionItem(n, kind=types.CompletionItemKind.Variable, detail=k)
              for n, k in sorted(index.names.items())]
    items += [types.CompletionItem(n, kind=types.CompletionItemKind.Function, detail=d)
              for n, d in HELPERS.items()]
    return items


def _element_at(a: Analysis, offset: int) -> str | None:
    assert a.index is not None
    best: tuple[int, str] | None = None
    for path, el in a.index.elements.items():
        if el.key.start <= offset <= max(el.node.end, el.key.end) and (
                best is None or el.key.start > best[0]):
            best = (el.key.start, path)
    return best[1] if best else None


# ----- hover

def hover(a: Analysis, offset: int, diagnostics: list[types.Diagnostic]) -> types.Hover | None:
    pos = a.lines.position(offset)
    for d in diagnostics:
        r = d.range
        if r.start.line == pos.line and r.start.character <= pos.character <= max(r.end.character,
                                                                                r.start.character + 1):
            code = str(d.code)
            return types.Hover(types.MarkupContent(types.MarkupKind.Markdown,
                                                   f"**{code}**: {CODES.get(code, '')}\n\n{d.message}"))
    if isinstance(a.index, XmlNames):
        found = xml_features.hover(a.text, offset)
        if found is not None:
            word, s, e = found
            return types.Hover(types.MarkupContent(types.MarkupKind.Markdown, word),
                               range=a.lines.range(s, e))
    for path, node in a.tree.walk() if a.tree is not None else ():
        if node.kind != "map":
            continue
        for k in node.keys:
            if k.start <= offset <= k.end:
                ctx = context_of(path)
                doc = keys_of(ctx).get(k.value, "") if ctx else ""
                if doc:
                    return types.Hover(types.MarkupContent(types.MarkupKind.Markdown, f"`{k.value}`: {doc}"),
                                       range=a.lines.range(k.start, k.end))
    if a.index is not None:
        ref = a.index.at(offset)
        if ref is not None:
            return types.Hover(types.MarkupContent(types.MarkupKind.Markdown, _describe(ref)))
    return None


def _describe(ref: Ref) -> str:
    return f"{ref.kind} `{ref.target}`"


# ----- code actions

def code_actions(a: Analysis, uri: str,
                 diagnostics: Sequence[types.Diagnostic]) -> list[types.CodeAction]:
    out: list[types.CodeAction] = []
    for d in diagnostics:
        data = d.data if isinstance(d.data, dict) else {}
        if "replace" in data:
            start = a.lines.offset(d.range.start)
            end = a.lines.offset(d.range.end)
            word = re.match(r"[\w$./]*", a.text[start:end])
            end = start + (word.end() if word else 0)
            new = str(data["replace"])
            out.append(types.CodeAction(
                title=f"Replace with `{new}`", kind=types.CodeActionKind.QuickFix, diagnostics=[d],
                is_preferred=True, edit=types.WorkspaceEdit(changes={uri: [
                    types.TextEdit(a.lines.range(start, end), new)]})))
        if data.get("quote"):
            fix = _quote_fix(a, d)
            if fix is not None:
                out.append(types.CodeAction(title="Quote the value", kind=types.CodeActionKind.QuickFix,
                                            diagnostics=[d], is_preferred=True,
                                            edit=types.WorkspaceEdit(changes={uri: [fix]})))
    return out


def _quote_fix(a: Analysis, d: types.Diagnostic) -> types.TextEdit | None:
    """The plain value with an unquoted `: ` on the diagnostic's line, double-quoted."""
    line = a.lines.line(d.range.start.line)
    m = re.match(r"^(\s*(?:-\s+)?[^\s#'\"{}\[\],:][^#:]*?\s*:\s+)([^\s#'\"|>{\[&*!].*?)(\s+#.*)?$", line)
    if m is None:
        return None
    value = m.group(2)
    quoted = json.dumps(value, ensure_ascii=False)
    base = a.lines.offset(types.Position(d.range.start.line, 0))
    s = base + len(m.group(1))
    return types.TextEdit(a.lines.range(s, s + len(value)), quoted)


def same_file(a: str, b: str) -> bool:
    return os.path.normcase(os.path.abspath(a)) == os.path.normcase(os.path.abspath(b))
