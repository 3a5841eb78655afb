"""What the language server knows of one document: `check`'s diagnostics for its
text, and (for YAML) its tree and reference index, built when a request needs them,
from the last text that parsed (a document mid-typing keeps its last good symbols)."""

from __future__ import annotations

import re
import threading
from dataclasses import dataclass, field

from lsprotocol import types

from hfsmc.edit.library import names_of
from hfsmc.edit.references import Index, Names
from hfsmc.errors import Diagnostic
from hfsmc.frontend import is_xml
from hfsmc.frontend.yaml_ranges import YamlTree
from hfsmc.frontend.yaml_syntax import COLON_IN_VALUE
from hfsmc.lsp.positions import Lines
from hfsmc.pipeline import compile_file

_MODEL = re.compile(r"^hfsm[ \t]*:", re.MULTILINE)
_DID_YOU_MEAN = re.compile(r"did you mean `([^`]+)`\?")
_WORD = re.compile(r"[\w$./\"'-]*")
# Codes that say the text is not YAML (or XML) at all: its tree is the last good one.
SYNTAX = frozenset({"E001", "E002", "E003", "E006"})


def is_model(text: str) -> bool:
    """A YAML document with a top-level `hfsm:` key, or an XML one (the others are left alone)."""
    if is_xml(text):
        return "<hfsm" in text[:4096]
    return _MODEL.search(text) is not None


@dataclass
class Source:
    """A text that parses, and its tree and index once built (shared by the analyses
    of later texts that do not parse)."""

    text: str
    _index: Names | None = None
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def index(self) -> Names | None:
        with self._lock:
            if self._index is None:
                self._index = names_of(self.text)
            return self._index


@dataclass
class Analysis:
    """One version of a document, checked."""

    path: str
    text: str
    lines: Lines
    diagnostics: list[Diagnostic] = field(default_factory=list)
    source: Source | None = None  # this text, or the last one that parsed

    @property
    def parsed(self) -> bool:
        return self.source is not None and self.source.text == self.text

    @property
    def index(self) -> Names | None:
        return self.source.index() if self.source is not None else None

    @property
    def tree(self) -> YamlTree | None:
        """The YAML tree (None for XML)."""
        index = self.index
        return index.tree if isinstance(index, Index) else None

    @property
    def xml(self) -> bool:
        return is_xml(self.text)

    def for_text(self, text: str) -> Analysis:
        """This analysis read against newer ``text`` (completion reads the line as typed,
        the tree as last checked)."""
        return Analysis(self.path, text, Lines(text), self.diagnostics, self.source)


def analyse(path: str, text: str, last: Analysis | None, cxx: bool = False) -> Analysis:
    """Check ``text`` (as ``hfsmc check`` does; g++ on C++ snippets only with ``cxx``)."""
    a = Analysis(path, text, Lines(text))
    a.diagnostics = compile_file(path, text, cxx=cxx).diagnostics
    broken = any(d.code in SYNTAX and d.span.file == path for d in a.diagnostics)
    if not broken:
        a.source = Source(text)
    elif last is not None:
        a.source = last.source
    return a


def lsp_diagnostics(a: Analysis) -> dict[str, list[types.Diagnostic]]:
    """The diagnostics by file (this one and the files it uses), as LSP gives them."""
    out: dict[str, list[types.Diagnostic]] = {}
    for d in a.diagnostics:
        same = d.span.file == a.path
        lines = a.lines if same else _other_lines(d.span.file)
        start = lines.span_position(d.span.line, d.span.col)
        off = lines.offset(start)
        m = _WORD.match(lines.text, off)
        end = lines.position(m.end() if m and m.end() > off else off)
        if end.line != start.line:
            end = types.Position(start.line, start.character)
        data: dict[str, object] = {}
        fix = next((m.group(1) for m in map(_DID_YOU_MEAN.search, (d.message, *d.notes)) if m), None)
        if fix is not None:
            data["replace"] = fix
        if d.message == COLON_IN_VALUE:
            data["quote"] = True
        message = d.message + "".join(f"\nnote: {n}" for n in d.notes)
        out.setdefault(d.span.file, []).append(types.Diagnostic(
            range=types.Range(start, end), message=message, code=d.code, source="hfsmc",
            severity=types.DiagnosticSeverity.Error if d.severity == "error"
            else types.DiagnosticSeverity.Warning, data=data or None))
    return out


def _other_lines(path: str) -> Lines:
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return Lines(f.read())
    except OSError:
        return Lines("")
