"""A model's data written over an existing YAML text as minimal edits (``hfsmc convert``
onto an existing YAML file, SPEC 8.1): what did not change keeps its bytes, a changed
value is replaced where it is written, a removed key goes with its lines, a new key
takes its siblings' style.  Spellings that mean the same (`5000ms` for `5s`, a bare
`0.0` for `{type: float, init: 0.0}`) are kept."""

from __future__ import annotations

from typing import Any

from hfsmc.edit import yaml_render as render
from hfsmc.edit import yaml_splice as splice
from hfsmc.edit.text import EditError, TextEdit, apply_edits
from hfsmc.edit.yaml_splice import Splicer
from hfsmc.emit.yaml import same_spelling, short_form
from hfsmc.errors import Diagnostics
from hfsmc.frontend.source import PathKey
from hfsmc.frontend.yaml import load_yaml

MAX_STEPS = 100_000


def merge_into(text: str, new: dict[str, Any]) -> str:
    """``text`` edited until its data is ``new``."""
    for _ in range(MAX_STEPS):
        old = load_yaml("<merge>", text, Diagnostics()).data
        sp = Splicer(text)
        try:
            edits = _diff(sp, (), old, new)
        except _Shared as e:
            # a value written once under an anchor and shared through an alias differs in
            # this copy only: the alias is replaced by the copy's own value
            edits = _unshare(sp, e.path, new)
        if not edits:
            return text
        text = apply_edits(text, edits)
    raise EditError("the merge did not settle")



class _Shared(Exception):
    def __init__(self, path: PathKey) -> None:
        self.path = path


def _unshare(sp: Splicer, path: PathKey, new: Any) -> list[TextEdit]:
    for i in range(len(path) + 1):
        node = sp.tree.root
        for k in path[:i]:
            node = node.get(k) if node is not None else None
        if node is not None and node.kind == "alias":
            value = new
            for k in path[:i]:
                value = value[k]
            flow = sp.in_flow(path[:i])
            text = render.flow(value) if flow or render.fits_flow(value) else \
                render.after_key(value, sp.col(_key_start(sp, path[:i])), sp.step, sp.nl)
            if not flow and not render.fits_flow(value):
                colon = sp.colon_after(sp.tree.find_key(path[:i]))  # type: ignore[arg-type]
                return [TextEdit(colon, node.end, text)]
            return [TextEdit(node.start, node.end, text)]
    raise EditError(f"{'/'.join(map(str, path))}: cannot be edited")


def _key_start(sp: Splicer, path: PathKey) -> int:
    key = sp.tree.find_key(path)
    if key is None:
        raise EditError("an alias in a list")
    return key.start


def _diff(sp: Splicer, path: PathKey, old: Any, new: Any) -> list[TextEdit] | None:
    if sp.tree.shared(path) is not None and old != new:
        raise _Shared(path)
    if isinstance(old, dict) and isinstance(new, dict):
        for k in old:
            if k not in new:
                return splice.delete(sp, (*path, k))
        keys = list(old)
        for i, (k, v) in enumerate(new.items()):
            if k not in old:
                before = [x for x in list(new)[:i] if x in old]
                index = keys.index(before[-1]) + 1 if before else 0
                return splice.add_entry(sp, path, k, v, index)
            d = _diff(sp, (*path, k), old[k], v)
            if d:
                return d
        return None
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        for i, (a, b) in enumerate(zip(old, new, strict=True)):
            d = _diff(sp, (*path, i), a, b)
            if d:
                return d
        return None
    if same_spelling(old, new):
        return None
    new = short_form(old, new)
    if same_spelling(old, new):
        return None
    return splice.set_value(sp, path, new)
