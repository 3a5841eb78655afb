"""The neutral form the front ends hand to the IR builder (hfsmc/ir_builder.py).

A :class:`Document` is the model as plain data (dicts, lists, str, int, float,
bool, None) shaped like the YAML format, plus the source position of every
value and every mapping key, addressed by its path from the root
(``("states", "Follow", "transitions", 0, "when")``).  The JSON Schema
validator and the IR builder only ever see this form, so YAML, XML and legacy
files share one validation and one IR builder.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Literal

from hfsmc.errors import Span

PathKey = tuple[str | int, ...]
Format = Literal["yaml", "xml", "visualstates", "visualhfsm"]

# Limits enforced by every front end (docs/limits in the README).
MAX_FILE_BYTES = 50 * 1024 * 1024
MAX_DEPTH = 400  # nesting of YAML/XML containers (about 130 levels of states)
MAX_NODES = 5_000_000  # values after alias expansion

# Spellings YAML 1.1 reads as booleans and YAML 1.2 (what hfsmc reads) as strings.
YAML11_BOOLS: dict[str, bool] = {
    w: b in ("yes", "on", "y")
    for b in ("yes", "no", "on", "off", "y", "n") for w in (b, b.capitalize(), b.upper())}

_BREAK = re.compile(r"\r\n|\r|\n")


def split_lines(text: str) -> list[str]:
    """Lines as YAML and XML count them (CR, LF, CRLF): unlike str.splitlines(),
    form feeds, U+2028 and the like do not end a line."""
    lines = _BREAK.split(text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


@dataclass
class Document:
    file: str
    format: Format
    lines: list[str]
    data: Any = None
    spans: dict[PathKey, Span] = field(default_factory=dict)
    key_spans: dict[PathKey, Span] = field(default_factory=dict)
    # Column (1-based) where the 2nd and later lines of a multi-line string start.
    cont_cols: dict[PathKey, int] = field(default_factory=dict)
    # For folded (`>`) and multi-line plain scalars, whose line breaks became spaces:
    # (offset in the value, line, col) where each source line's text starts.
    segments: dict[PathKey, tuple[tuple[int, int, int], ...]] = field(default_factory=dict)
    # What a legacy import mapped and how (`hfsmc convert` prints it as its report).
    notes: list[tuple[Span, str]] = field(default_factory=list)
    # Plain YAML scalars that a YAML 1.1 reader reads differently (`no`, `010`): their text.
    yaml11: dict[PathKey, str] = field(default_factory=dict)
    # The text read (a recording keeps it: hfsmc/model_sources.py).
    text: str = ""

    def span(self, path: PathKey) -> Span:
        """Position of the value at ``path``, or of its nearest ancestor."""
        p = tuple(path)
        while p:
            s = self.spans.get(p)
            if s is not None:
                return s
            p = p[:-1]
        return self.spans.get((), Span(self.file, 1, 1))

    def key_span(self, path: PathKey) -> Span:
        """Position of the key that names ``path`` (falls back to its value)."""
        s = self.key_spans.get(tuple(path))
        return s if s is not None else self.span(path)

    def cont_col(self, path: PathKey) -> int:
        c = self.cont_cols.get(tuple(path))
        return c if c is not None else self.span(path).col
