"""A model's data written over an existing YAML text as minimal edits (``hfsmc convert``
onto an existing YAML file, SPEC 8.1): what did not change keeps its bytes, a changed
value is replaced where it is written, a removed key goes with its lines, a new key
takes its siblings' style.  Spellings that mean the same (`5000ms` for `5s`, a bare
`0.0` for `{type: float, init: 0.0}`) are kept."""

from __future__ import annotations

from typing import Any

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
        edits = _diff(sp, (), old, new)
        if not edits:
            return text
        text = apply_edits(text, edits)
    raise EditError("the merge did not settle")



def _diff(sp: Splicer, path: PathKey, old: Any, new: Any) -> list[TextEdit] | None:
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
