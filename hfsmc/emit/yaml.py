"""The YAML writer: a model as a version-1 YAML file (``hfsmc convert``).

YAML is written with ruamel.yaml's round-trip dumper.  When the output YAML
file already exists and holds a model, it is edited in place: unchanged keys
keep their comments and their layout, changed values are replaced, removed
keys are dropped and new keys added.
"""

from __future__ import annotations

import io
import os
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import YAMLError
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


def _merge(old: Any, new: Any) -> Any:
    """``new`` written over ``old``, keeping what of ``old`` (comments, style) still holds."""
    if isinstance(old, CommentedMap) and isinstance(new, dict):
        for k in [k for k in old if k not in new]:
            del old[k]
        for k, v in new.items():
            old[k] = _merge(old[k], v) if k in old else _styled(v)
        return old
    if isinstance(old, CommentedSeq) and isinstance(new, list) and len(old) == len(new):
        for i, v in enumerate(new):
            old[i] = _merge(old[i], v)
        return old
    if not isinstance(new, (dict, list)) and _same(old, new):
        return old
    if _same_variable(old, new) or _same_variable(new, old):
        return old
    if _bare_type(old) is not None and _typed(new) and _bare_type(old) == new["type"] \
            == _bare_type(new["init"]):
        return _styled(new["init"])  # `v: 0.0` edited to 0.5 stays in the short form
    return _styled(new)


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


def to_yaml(model: Model, existing: str | None = None, out: Path | None = None) -> str:
    """The model as YAML; over ``existing`` YAML text when given (comments kept)."""
    data = model_to_data(model)
    y = _yaml()
    doc: Any = None
    if existing is not None:
        try:
            doc = y.load(existing)
        except YAMLError:
            doc = None
    buf = io.StringIO()
    if isinstance(doc, CommentedMap):
        if "language" not in doc and data["language"] == "python":
            del data["language"]  # the default, which the user left out
        y.dump(_merge(doc, data), buf)
        return buf.getvalue()
    y.dump(_styled(data), buf)
    return (schema_line(out) if out is not None else "") + buf.getvalue()
