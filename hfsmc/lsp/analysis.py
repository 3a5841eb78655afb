"""What the language server knows of one document: `check`'s diagnostics for its
text, and (for YAML) its tree and reference index, the last good ones kept while
the text does not parse (a document mid-typing)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import yaml
from lsprotocol import types

from hfsmc.edit.references import Index
from hfsmc.errors import Diagnostic
from hfsmc.frontend import is_xml
from hfsmc.frontend.yaml_ranges import YamlTree
from hfsmc.frontend.yaml_syntax import COLON_IN_VALUE
from hfsmc.lsp.positions import Lines
from hfsmc.pipeline import compile_file

_MODEL = re.compile(r"^hfsm[ \t]*:", re.MULTILINE)
_DID_YOU_MEAN = re.compile(r"did you mean `([^`]+)`\?")
_WORD = re.compile(r"[\w$./\"'-]*")


def is_model(text: str) -> bool:
    """A YAML document with a top-level `hfsm:` key, or an XML one (the others are left alone)."""
    if is_xml(text):
        return "<hfsm" in text[:4096]
    return _MODEL.search(text) is not None


@dataclass
class Analysis:
    """One version of a document, checked."""

    path: str
    text: str
    lines: Lines
    diagnostics: list[Diagnostic] = field(default_factory=list)
    tree: YamlTree | None = None
    index: Index | None = None
    parsed: bool = False  # the tree is this text's (not the last good one)


def analyse(path: str, text: str, last: Analysis | None, cxx: bool = False) -> Analysis:
    """Check ``text`` (as ``hfsmc check`` does; g++ on C++ snippets only with ``cxx``)."""
    a = Analysis(path, text, Lines(text))
    a.diagnostics = compile_file(path, text, cxx=cxx).diagnostics
    if not is_xml(text):
        try:
            a.tree = YamlTree(text)
            a.index = Index(a.tree)
            a.parsed = True
        except yaml.YAMLError:
            if last is not None:
                a.tree, a.index = last.tree, last.index
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
