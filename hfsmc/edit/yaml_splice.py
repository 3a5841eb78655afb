"""Structural changes of a YAML text as splices: set, add, delete, move and rename
entries of mappings and lists, each touching only the text it changes.

Every function takes a :class:`Splicer` (the text and its :class:`YamlTree`) and
returns :class:`TextEdit` s against that text.  An entry of a block mapping or list
is its lines, with the comment lines right above it at its indentation (they travel
with it when it moves and go when it goes); an entry of a flow collection is its text
and one separating comma."""

from __future__ import annotations

import re
from typing import Any

from hfsmc.edit import yaml_render as render
from hfsmc.edit.text import EditError, TextEdit, after_break, line_end, line_start, newline_of
from hfsmc.frontend.source import PathKey
from hfsmc.frontend.yaml_ranges import Node, YamlTree

_COMMENT_LINE = re.compile(r"[ ]*#")


class Splicer:
    """A YAML text, its tree, its line break and indentation step."""

    def __init__(self, text: str, tree: YamlTree | None = None) -> None:
        self.text = text
        self.tree = tree if tree is not None and tree.text == text else YamlTree(text)
        self.nl = newline_of(text)
        self.step = self._step()

    def _step(self) -> int:
        root = self.tree.root
        if root is None or root.kind != "map":
            return 2
        for k, v in zip(root.keys, root.items, strict=True):
            if v.kind == "map" and not v.flow and v.keys:
                d = self.col(v.keys[0].start) - self.col(k.start)
                if d > 0:
                    return d
        return 2

    def col(self, off: int) -> int:
        return off - line_start(self.text, off)

    def node(self, path: PathKey) -> Node:
        shared = self.tree.shared(path)
        if shared is not None:
            target = shared.target
            where = f" (line {self.tree.line_of(target.start) + 1})" if target is not None else ""
            raise EditError(f"{_show(path)} is written once under the anchor &{shared.value}{where} "
                            f"and shared through *{shared.value}: edit it there")
        node = self.tree.find(path)
        if node is None:
            raise EditError(f"{_show(path)}: no such element")
        return node

    def in_flow(self, path: PathKey) -> bool:
        """Whether the value at ``path`` sits inside a flow collection."""
        node = self.tree.root
        for k in path:
            if node is None:
                return False
            if node.kind in ("map", "seq") and node.flow:
                return True
            node = node.get(k)
        return False

    # ----- ranges of entries

    def _lead(self, start: int, col: int) -> int:
        """``start`` (a line start) moved up over the comment lines right above it at
        indentation ``col``."""
        text = self.text
        while start > 0:
            prev = line_start(text, start - 1)
            line = text[prev:start].rstrip("\r\n")
            if _COMMENT_LINE.match(line) and len(line) - len(line.lstrip(" ")) == col:
                start = prev
            else:
                break
        return start

    def entry_range(self, parent: Node, i: int) -> tuple[int, int]:
        """The text of entry ``i`` of ``parent`` (see the module's docstring)."""
        text = self.text
        if parent.kind == "map":
            first, last = parent.keys[i].start, max(parent.keys[i].end, parent.items[i].end)
        else:
            first, last = self._dash(parent.items[i]), parent.items[i].end
        if parent.flow:
            n = len(parent.items)
            starts = [k.start for k in parent.keys] if parent.kind == "map" else \
                [x.start for x in parent.items]
            ends = [max(k.end, v.end) for k, v in zip(parent.keys, parent.items, strict=True)] \
                if parent.kind == "map" else [x.end for x in parent.items]
            if n == 1:
                return starts[0], ends[0]
            if i < n - 1:
                return starts[i], starts[i + 1]
            return ends[i - 1], ends[i]
        ls = line_start(text, first)
        if text[ls:first].strip():
            # the entry starts after other text on its line (`- to: X`): it ends where the
            # next entry starts
            if parent.kind == "map" and i + 1 < len(parent.keys):
                return first, parent.keys[i + 1].start
            raise EditError("this entry shares its line with its list's dash: edit the list item")
        start = self._lead(ls, first - ls)
        end = after_break(text, line_end(text, last))
        return start, end

    def _dash(self, item: Node) -> int:
        j = item.start - 1
        while j >= 0 and self.text[j] in " \t":
            j -= 1
        return j if j >= 0 and self.text[j] == "-" else item.start

    def entry_text(self, parent: Node, i: int) -> str:
        s, e = self.entry_range(parent, i)
        return self.text[s:e]

    def colon_after(self, key: Node) -> int:
        """The offset just after the `:` that follows ``key``."""
        j = self.text.find(":", key.end)
        if j < 0:
            raise EditError("malformed mapping entry")
        return j + 1


def _show(path: PathKey) -> str:
    return "/".join(str(p) for p in path) or "the document"


def _container(sp: Splicer, path: PathKey) -> Node:
    node = sp.node(path)
    if node.kind not in ("map", "seq"):
        raise EditError(f"{_show(path)} is not a mapping or a list")
    return node


def delete(sp: Splicer, path: PathKey) -> list[TextEdit]:
    """Remove the entry at ``path`` (a mapping's key or a list's item)."""
    parent = _container(sp, path[:-1])
    sp.node(path)
    i = parent.key_index(str(path[-1])) if parent.kind == "map" else path[-1]
    assert isinstance(i, int)
    s, e = sp.entry_range(parent, i)
    edits = [TextEdit(s, e, "")]
    owner = sp.tree.find_key(path[:-1]) if len(path) >= 2 else None
    if not parent.flow and len(parent.items) == 1 and owner is not None:
        # the last entry of a block collection: it becomes `{}` or `[]`
        at = sp.colon_after(owner)
        if at <= s:
            edits.insert(0, TextEdit(at, at, " {}" if parent.kind == "map" else " []"))
    if e == len(sp.text) and not sp.text[s:e].endswith(("\n", "\r")) and s > 0:
        edits[-1] = TextEdit(s - len(sp.nl) if sp.text[s - 1] in "\r\n" else s, e, "")
    return edits


def set_value(sp: Splicer, path: PathKey, value: Any, hint: str | None = None) -> list[TextEdit]:
    """Set the value at ``path``, adding its key (and missing mappings above it) when absent."""
    if value is None:
        return delete(sp, path) if sp.tree.find(path) is not None else []
    node = sp.tree.find(path)
    if node is None:
        if sp.tree.find(path[:-1]) is None and len(path) > 1 and isinstance(path[-1], str):
            return set_value(sp, path[:-1], {path[-1]: value}, hint)
        parent = _container(sp, path[:-1])
        if parent.kind == "seq":
            raise EditError(f"{_show(path)}: no such list item")
        return add_entry(sp, path[:-1], str(path[-1]), value, hint=hint)
    sp.node(path)  # refuses a path through an alias
    flow = sp.in_flow(path)
    if node.kind == "scalar" and not isinstance(value, (dict, list)):
        style = node.style if hint is None else hint
        indent = _content_indent(sp, node, path)
        new = render.scalar(value, style, flow, indent, sp.nl)
        if not node.value and not node.style and node.start == node.end:
            return [TextEdit(node.start, node.end, (" " if sp.text[node.start - 1:node.start] == ":"
                                                    else "") + new)]
        return [TextEdit(node.start, node.end, new)]
    if flow or (node.flow and not isinstance(value, (dict, list))) or \
            (node.flow and render.fits_flow(value)):
        if not isinstance(value, (dict, list)):
            return [TextEdit(node.start, node.end, render.scalar(value, hint or "", flow, 0, sp.nl))]
        return [TextEdit(node.start, node.end, render.flow(value, hint or ""))]
    key = sp.tree.find_key(path)
    if key is None:  # a list item
        col = sp.col(node.start)
        if isinstance(value, dict) and render.fits_flow(value):
            return [TextEdit(node.start, node.end, render.flow(value, hint or ""))]
        body = render.block(value, col, sp.step, sp.nl, hint or "") if isinstance(value, (dict, list)) \
            and value else render.flow(value)
        return [TextEdit(node.start, node.end, body[col:] if body.startswith(" " * col) else body)]
    at = sp.colon_after(key)
    return [TextEdit(at, max(at, node.end), render.after_key(
        value, sp.col(key.start), sp.step, sp.nl, hint or "", prefer_flow=node.flow))]


def _content_indent(sp: Splicer, node: Node, path: PathKey) -> int:
    """The indentation of a block scalar's content (new or kept)."""
    if node.style in ("|", ">"):
        first = after_break(sp.text, line_end(sp.text, node.start))
        line = sp.text[first:line_end(sp.text, first)]
        if line.strip():
            return len(line) - len(line.lstrip(" "))
    key = sp.tree.find_key(path)
    return (sp.col(key.start) if key is not None else sp.col(node.start)) + sp.step


def _prefer_flow(parent: Node) -> bool:
    """Whether a mapping's values are written in flow style (most of them that are
    collections)."""
    kinds = [v.flow for v in parent.items if v.kind in ("map", "seq") and v.items]
    return bool(kinds) and sum(kinds) * 2 > len(kinds)


def sibling_hint(sp: Splicer, parent: Node) -> str:
    """The quoting the text around uses for scalars that need it (`'` or `"`)."""
    seen = [v.style for v in parent.items if v.kind == "scalar" and v.style in ("'", '"')]
    if not seen:
        return ""
    return max(set(seen), key=seen.count)


def add_entry(sp: Splicer, map_path: PathKey, key: str, value: Any, index: int | None = None,
              hint: str | None = None) -> list[TextEdit]:
    """Add ``key: value`` to the mapping at ``map_path`` (created when absent), at
    ``index`` among its entries (default: last)."""
    node = sp.tree.find(map_path)
    if node is None or (node.kind == "scalar" and not node.value and not node.style):
        if node is None and not map_path:
            raise EditError("the document is empty")
        if node is None:
            return set_value(sp, map_path, {key: value}, hint)
        return set_value(sp, map_path, {key: value}, hint)
    node = sp.node(map_path)
    if node.kind != "map":
        raise EditError(f"{_show(map_path)} is not a mapping")
    if node.key_index(key) is not None:
        raise EditError(f"{_show((*map_path, key))} already exists")
    h = hint if hint is not None else sibling_hint(sp, node)
    n = len(node.keys)
    index = n if index is None else max(0, min(index, n))
    if node.flow:
        item = f"{render.flow({key: value}, h)[1:-1]}"
        if n == 0:
            return [TextEdit(node.start + 1, node.end - 1, item)]
        if index < n:
            return [TextEdit(node.keys[index].start, node.keys[index].start, item + ", ")]
        end = max(node.keys[-1].end, node.items[-1].end)
        return [TextEdit(end, end, ", " + item)]
    col = sp.col(node.keys[0].start)
    return _insert_block(sp, node, index, _block_entry(sp, key, value, col, h, _prefer_flow(node)))


def _block_entry(sp: Splicer, key: str, value: Any, col: int, hint: str, prefer_flow: bool) -> str:
    return " " * col + render.key(key) + ":" + render.after_key(
        value, col, sp.step, sp.nl, hint, prefer_flow=prefer_flow)


def _insert_block(sp: Splicer, node: Node, index: int, lines: str) -> list[TextEdit]:
    """Insert whole ``lines`` (no final break) as entry ``index`` of a block collection."""
    n = len(node.items)
    if index < n:
        s, _ = sp.entry_range(node, index)
        return [TextEdit(s, s, lines + sp.nl)]
    _, e = sp.entry_range(node, n - 1)
    if e == len(sp.text) and not sp.text.endswith(("\n", "\r")):
        return [TextEdit(e, e, sp.nl + lines)]
    return [TextEdit(e, e, lines + sp.nl)]


def add_item(sp: Splicer, seq_path: PathKey, value: Any, index: int | None = None,
             hint: str | None = None) -> list[TextEdit]:
    """Add ``value`` to the list at ``seq_path`` (created when absent) at ``index``."""
    node = sp.tree.find(seq_path)
    if node is None or (node.kind == "scalar" and not node.value and not node.style):
        return set_value(sp, seq_path, [value], hint)
    node = sp.node(seq_path)
    if node.kind != "seq":
        raise EditError(f"{_show(seq_path)} is not a list")
    n = len(node.items)
    index = n if index is None else max(0, min(index, n))
    h = hint if hint is not None else ""
    if node.flow:
        item = render.flow(value, h)
        if n == 0:
            return [TextEdit(node.start + 1, node.end - 1, item)]
        if index < n:
            return [TextEdit(node.items[index].start, node.items[index].start, item + ", ")]
        return [TextEdit(node.items[-1].end, node.items[-1].end, ", " + item)]
    col = sp.col(sp._dash(node.items[0]))
    lines = render.block([value], col, sp.step, sp.nl, h)
    return _insert_block(sp, node, index, lines)


def move(sp: Splicer, path: PathKey, index: int) -> list[TextEdit]:
    """Move the entry at ``path`` to position ``index`` among its siblings."""
    parent = _container(sp, path[:-1])
    sp.node(path)
    i = parent.key_index(str(path[-1])) if parent.kind == "map" else path[-1]
    assert isinstance(i, int)
    n = len(parent.items)
    index = max(0, min(index, n - 1))
    if index == i:
        return []
    if parent.flow:
        if parent.kind == "map":
            starts = [k.start for k in parent.keys]
        else:
            starts = [x.start for x in parent.items]
        ends = [x.end for x in parent.items]
        item = sp.text[starts[i]:ends[i]]
        s, e = sp.entry_range(parent, i)
        if index < i:
            return [TextEdit(starts[index], starts[index], item + ", "), TextEdit(s, e, "")]
        return [TextEdit(s, e, ""), TextEdit(ends[index], ends[index], ", " + item)]
    s, e = sp.entry_range(parent, i)
    block = sp.text[s:e]
    if not block.endswith(("\n", "\r")):
        # the last line of the file, without a line break
        block += sp.nl
        edits = [TextEdit(s - len(sp.nl), e, "")]
    else:
        edits = [TextEdit(s, e, "")]
    if index < i:
        at, _ = sp.entry_range(parent, index)
        return [TextEdit(at, at, block), *edits]
    _, at = sp.entry_range(parent, index)
    if at == len(sp.text) and not sp.text.endswith(("\n", "\r")):
        return [*edits, TextEdit(at, at, sp.nl + block.rstrip("\r\n"))]
    return [*edits, TextEdit(at, at, block)]


def rename_key(sp: Splicer, path: PathKey, new: str) -> list[TextEdit]:
    """Give the entry at ``path`` the key ``new`` (its quoting kept where it can be)."""
    sp.node(path)
    key = sp.tree.find_key(path)
    if key is None:
        raise EditError(f"{_show(path)} has no key")
    parent = sp.tree.find(path[:-1])
    assert parent is not None
    if parent.key_index(new) is not None and new != path[-1]:
        raise EditError(f"{_show(path[:-1])}/{new} already exists")
    text = render.scalar(new, key.style, sp.in_flow(path), 0, sp.nl) if key.style \
        else render.flow(new)
    return [TextEdit(key.start, key.end, text)]
