"""Where a diagnostic is inside the snippet it is about, for the code editors' gutters
(docs/editor.md): the engine's positions are the file's; the page shows a snippet's value
alone (a block scalar without its indentation, a quoted one without its quotes)."""

from __future__ import annotations

from typing import Any

from hfsmc.edit.references import Index
from hfsmc.frontend.yaml_ranges import Node, YamlTree

STATE_FIELDS = ("entry", "during", "exit")
EDGE_FIELDS = ("when", "after", "do", "to", "name")


def place(text: str, items: list[dict[str, Any]]) -> None:
    """Give each item of ``items`` (the page's diagnostics: ``state``, ``transition``,
    ``line``, ``col``) that falls inside one of its element's snippets ``field`` (its key)
    and ``at`` ([line, col], 1-based, in the snippet's value)."""
    wanted = [d for d in items if not d.get("other") and d.get("state")]
    if not wanted:
        return
    try:
        tree = YamlTree(text)
        index = Index(tree)
    except Exception:  # a text YAML cannot read: no element to place a problem in
        return
    for d in wanted:
        el = index.elements.get(d["state"])
        if el is None:
            continue
        i = d.get("transition")
        base = (*el.doc_path, "transitions", i) if isinstance(i, int) else tuple(el.doc_path)
        fields = EDGE_FIELDS if isinstance(i, int) else STATE_FIELDS
        off = tree.offset(int(d["line"]) - 1, int(d["col"]) - 1)
        for key in fields:
            node = tree.find((*base, key))
            if node is None or node.kind != "scalar" or not node.start <= off <= node.end + 1:
                continue
            at = _inside(tree, node, off)
            if at is not None:
                d["field"], d["at"] = key, list(at)
            break


def _inside(tree: YamlTree, node: Node, off: int) -> tuple[int, int] | None:
    """(line, col), 1-based, of the file's offset ``off`` in the value of ``node``."""
    line, col = tree.line_of(off), tree.col_of(off)
    first = tree.line_of(node.start)
    if node.style in ("|", ">"):
        if line <= first:  # on the indicator's line: the snippet's start
            return 1, 1
        indent = _indent(tree, first + 1, line)
        return line - first, max(col - indent, 0) + 1
    start_col = tree.col_of(node.start) + (1 if node.style in ('"', "'") else 0)
    if line == first:
        return 1, max(col - start_col, 0) + 1
    # a plain or quoted scalar folded over lines: its later lines are joined with spaces
    return line - first + 1, 1


def _indent(tree: YamlTree, first: int, upto: int) -> int:
    """A block scalar's indentation: that of its first line that is not blank."""
    for n in range(first, upto + 1):
        start = tree.line_starts[n]
        end = tree.line_starts[n + 1] if n + 1 < len(tree.line_starts) else len(tree.text)
        body = tree.text[start:end].rstrip("\r\n")
        if body.strip():
            return len(body) - len(body.lstrip(" "))
    return 0
