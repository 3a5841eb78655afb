"""``hfsmc convert``: YAML ↔ XML (and legacy XML → version 1).

YAML is written with ruamel.yaml's round-trip dumper.  When the output YAML
file already exists and holds a model, it is edited in place: unchanged keys
keep their comments and their layout, changed values are replaced, removed
keys are dropped and new keys added.
"""

from __future__ import annotations

import io
import os
import re
from pathlib import Path
from typing import Any

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.error import YAMLError
from ruamel.yaml.scalarstring import LiteralScalarString

from hfsmc.compiler import Result, compile_file
from hfsmc.durations import parse_us
from hfsmc.emit.data import model_to_data
from hfsmc.errors import Diagnostic, UsageError
from hfsmc.fsutil import write_atomic
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
    """The type a variable written as this bare literal has (the builder's inference)."""
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


def convert_model(result: Result, out: Path) -> list[str]:
    """Write ``result``'s model to ``out`` in the format its suffix names; report lines."""
    model = result.model
    assert model is not None
    suffix = out.suffix.lower()
    if suffix in (".yaml", ".yml"):
        existing = None
        if out.exists():
            try:
                existing = out.read_text("utf-8")
            except (OSError, UnicodeDecodeError):
                existing = None
        text = to_yaml(model, existing, out)
        how = "edited in place" if existing is not None else "wrote"
    elif suffix == ".xml":
        from hfsmc.emit.xml import to_xml

        doc = result.document
        text = to_xml(model, yaml_comments(result.lines) if doc is not None and
                      doc.format == "yaml" else ())
        how = "wrote"
    else:
        raise UsageError(f"{out}: the output's name must end in .yaml, .yml or .xml")
    write_atomic(out, text)
    n_states = sum(1 for _ in model.states())
    n_trans = sum(len(s.transitions) for s in model.states())
    return [*legacy_report(result), f"{how} {out}: {n_states} states, {n_trans} transitions"]


_BLOCK_START = re.compile(r"(?:^|[:-][ \t])[ \t]*[|>][0-9+-]*[ \t]*$")


def yaml_comments(lines: list[str]) -> list[tuple[int, str]]:
    """(line, text) of each comment of a YAML file, for the XML writer.

    Lines inside block scalars (`|`, `>`) are code or text, not comments; the
    editor hint on the first line is left out (the XML names its own schema).
    The comments above the first key (the file's header) get line 0: they go
    before the first element.
    """
    out: list[tuple[int, str]] = []
    block: int | None = None  # indentation of the key that opened a block scalar
    header = True
    for n, line in enumerate(lines, 1):
        body = line.rstrip("\r\n")
        stripped = body.lstrip(" ")
        indent = len(body) - len(stripped)
        if block is not None:
            if not stripped.strip() or indent > block:
                continue
            block = None
        cut = 0 if stripped.startswith("#") else _comment_start(body)
        if cut is not None:
            text = body[indent + 1 if cut == 0 else cut + 1:].strip()
            if text and not (n == 1 and text.startswith("yaml-language-server:")):
                out.append((0 if header and cut == 0 else n, text))
        if cut != 0 and stripped.strip():
            header = False
        if _BLOCK_START.search(body if cut is None else body[:indent if cut == 0 else cut]):
            block = indent
    return out


def _comment_start(line: str) -> int | None:
    """Index of the `#` that starts a comment after some YAML on ``line``, if any."""
    quote = ""
    for k, ch in enumerate(line):
        if quote:
            if ch == quote and (quote == "'" or line[k - 1] != "\\"):
                quote = ""
        elif ch in "'\"" and (k == 0 or line[k - 1] in " \t:[{,-"):
            quote = ch
        elif ch == "#" and k > 0 and line[k - 1] in " \t":
            return k
    return None


# Problems in the code of a legacy file (a name the file never imported, a syntax error):
# `convert` still writes the model and reports them as warnings, so that the user fixes
# them in the new file; `check` and `build` stay strict (docs/legacy.md).
def compile_for_convert(path: str, strict: bool = False) -> Result:
    """``path`` compiled for ``convert``: as ``check`` does, except that a legacy file whose
    only errors are in its code gives its model, those errors reported as W220."""
    result = compile_file(path)
    doc = result.document
    if strict or doc is None or doc.format not in ("visualstates", "visualhfsm") \
            or not result.errors_only_in_snippets:
        return result
    kept = [d if d.severity != "error" else Diagnostic(
        "W220", f"{d.message} ({d.code}: the converted model keeps it; fix it there)", d.span,
        "warning", d.notes) for d in result.diagnostics]
    return Result(path, result.structure, kept, result.lines, doc, result.notes)


def legacy_report(result: Result) -> list[str]:
    """What the import of a legacy file mapped, and how (SPEC 2.7); nothing for other files."""
    doc = result.document
    if doc is None or not doc.notes:
        return []
    kind = {"visualstates": "VisualStates", "visualhfsm": "VisualHFSM"}.get(doc.format, doc.format)
    return [f"{result.path}: {kind} file read as a version-1 model:",
            *(f"  {span}: {message}" for span, message in doc.notes)]
