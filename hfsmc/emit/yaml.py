"""The YAML writer: a model as a version-1 YAML file (``hfsmc convert``).

A new YAML file is written with ruamel.yaml's dumper.  An existing one is never
dumped again: ``hfsmc convert`` edits it through the edit engine
(hfsmc/edit/merge.py), which changes only the text of what changed.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.scalarstring import LiteralScalarString

from hfsmc.durations import parse_us
from hfsmc.emit.data import model_to_data
from hfsmc.ir import Model
from hfsmc.resources import schema_file


def _yaml() -> YAML:
    y = YAML(typ="rt")
    y.preserve_quotes = True
    y.width = 100
    y.indent(mapping=2, sequence=4, offset=2)
    return y


def _styled(v: Any) -> Any:
    """Plain data with multi-line strings as `|` blocks."""
    if isinstance(v, dict):
        m = CommentedMap()
        for k, x in v.items():
            m[k] = _styled(x)
        return m
    if isinstance(v, list):
        return CommentedSeq(_styled(x) for x in v)
    if isinstance(v, str) and "\n" in v.rstrip("\n"):
        return LiteralScalarString(v if v.endswith("\n") else v + "\n")
    return v


def same_spelling(old: Any, new: Any) -> bool:
    """Whether the text's value ``old`` already says ``new`` (an editor keeps it)."""
    if isinstance(old, (dict, list)) or isinstance(new, (dict, list)):
        return bool(old == new) or _same_variable(old, new) or _same_variable(new, old)
    return _same(old, new)


def short_form(old: Any, new: Any) -> Any:
    """What to write for ``new`` where the text has ``old``: a variable written bare
    (`v: 0.0`) and edited to 0.5 stays in the short form."""
    if _bare_type(old) is not None and _typed(new) and _bare_type(old) == new["type"] \
            == _bare_type(new["init"]):
        return new["init"]
    return new


def _bare_type(value: Any) -> str | None:
    """The type a variable written as this bare literal has (the IR builder's inference)."""
    kind = {bool: "bool", int: "int", float: "float", str: "str", list: "list"}
    return next((k for t, k in kind.items() if isinstance(value, t)), None)


def _typed(value: Any) -> bool:
    return isinstance(value, dict) and set(value) == {"type", "init"}


def _same_variable(bare: Any, typed: Any) -> bool:
    """Whether a variable written bare (`v: 0.0`) means the ``{type, init}`` form written
    for it (an XML variable always names its type): the user's short form is kept."""
    return _typed(typed) and _bare_type(bare) == typed["type"] and bool(bare == typed["init"])


def _same(old: Any, new: Any) -> bool:
    """Whether the user's spelling ``old`` means ``new`` (`5000ms` is `5s`, `true` is `True`)."""
    if isinstance(old, bool) or isinstance(new, bool):
        return old is new or (isinstance(old, bool) and new == str(old))
    if old == new:
        return True
    us = parse_us(new)
    return us is not None and isinstance(old, (str, int)) and parse_us(old) == us


def schema_line(out: Path) -> str:
    """The editor hint naming the installed schema, relative to ``out``'s folder."""
    schema = Path(str(schema_file("hfsm.schema.json"))).resolve()
    rel = os.path.relpath(schema, out.resolve().parent)
    return f"# yaml-language-server: $schema={rel}\n"


def to_yaml(model: Model, out: Path | None = None) -> str:
    """The model as a new YAML file (an existing one is edited by hfsmc/edit/merge.py)."""
    data = model_to_data(model)
    buf = io.StringIO()
    _yaml().dump(_styled(data), buf)
    return (schema_line(out) if out is not None else "") + buf.getvalue()
