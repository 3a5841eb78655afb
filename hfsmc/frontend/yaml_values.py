"""Where a YAML value's content starts, and its plain-data form: shared by the
ruamel.yaml path (:mod:`hfsmc.frontend.yaml`) and the libyaml path
(:mod:`hfsmc.frontend.yaml_c`), so both record the same positions."""

from __future__ import annotations

import datetime
import re
from typing import Any

from ruamel.yaml.scalarint import ScalarInt

from hfsmc.errors import Span
from hfsmc.frontend.source import YAML11_BOOLS, Document, PathKey

_LEADING_ZERO = re.compile(r"[-+]?0[0-9]+(?![0-9.eE_:])")


def record_value(doc: Document, path: PathKey, value: Any, style: str | None, line: int, col: int) -> None:
    """Position of the first character of a value's content.

    ``style`` is the scalar's: None or "" for plain, `"` or `'` quoted, `|` or `>` a
    block; ``line`` and ``col`` (0-based) are where the parser's node starts.
    """
    lines = doc.lines
    plain_str = not style and type(value) is str
    if plain_str and value in YAML11_BOOLS:
        doc.yaml11[path] = value
    elif type(value) is ScalarInt and line < len(lines):
        m = _LEADING_ZERO.match(lines[line], col)
        if m is not None:
            doc.yaml11[path] = m.group(0)
    if plain_str and line < len(lines) and lines[line][col:col + len(value)] != value:
        # a plain scalar folded over several lines
        doc.segments[path] = segments(lines, value, line, col)
    if style == "|" or style == ">":
        # The mark is on the `|`/`>` indicator; the content starts on the next
        # non-blank line, at the block's indentation.
        ln = line + 1
        while ln < len(lines) and not lines[ln].strip():
            ln += 1
        indent = len(lines[ln]) - len(lines[ln].lstrip(" ")) if ln < len(lines) else col
        doc.spans[path] = Span(doc.file, ln + 1, indent + 1)
        doc.cont_cols[path] = indent + 1
        if style == ">":
            doc.segments[path] = segments(lines, str(value), ln, indent)
        return
    if style == '"' or style == "'":
        col += 1
    doc.spans[path] = Span(doc.file, line + 1, col + 1)


def segments(lines: list[str], text: str, line: int, col: int) -> tuple[tuple[int, int, int], ...]:
    """Where each source line of a folded scalar starts in its value.

    Folding turns line breaks into spaces but keeps each line's text, so every
    source line is found verbatim, in order.  Stops at the first line that is
    not (a comment, a closing bracket): positions after it fall back to the
    plain line arithmetic of :class:`hfsmc.ir.Code`.
    """
    segs: list[tuple[int, int, int]] = []
    pos, end, ln = 0, len(text.rstrip()), line
    while ln < len(lines) and pos < end:
        src = lines[ln]
        start = col if ln == line else len(src) - len(src.lstrip(" "))
        chunk = src[start:].rstrip()
        if chunk:
            idx = text.find(chunk, pos)
            if idx < 0:
                break
            segs.append((idx, ln + 1, start + 1))
            pos = idx + len(chunk)
        ln += 1
    return tuple(segs)


def scalar(v: Any) -> Any:
    """A scalar as plain data (ruamel's int, float and string types to Python's)."""
    if v is None or isinstance(v, bool):
        return v
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        return float(v)
    if isinstance(v, str):
        return str(v)
    if isinstance(v, (datetime.date, datetime.datetime)):
        return v.isoformat()
    if isinstance(v, bytes):
        return v.decode("latin-1")
    # tagged scalars and anything exotic: keep their text
    return str(getattr(v, "value", v))
