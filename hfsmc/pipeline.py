"""The pipeline from a model file to a checked IR: load, validate, build, lower."""

from __future__ import annotations

import gc
import os
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field

from hfsmc.errors import Diagnostic, Diagnostics, HfsmcError
from hfsmc.frontend import load, schema
from hfsmc.frontend.source import Document, split_lines
from hfsmc.ir import Model
from hfsmc.ir_builder import build_ir
from hfsmc.lower import lower
from hfsmc.uses import UseLoader

# Errors inside snippet code (syntax, names, parameters assigned, imports, C++ keywords and
# brackets, active() paths, interface methods): the model's structure is sound, so it can still be drawn and a
# legacy file converted; check and build refuse it.
SNIPPET_CODES = frozenset({"E140", "E141", "E142", "E143", "E145", "E146", "E147", "E148",
                           "E149"})


@dataclass
class Result:
    """What compiling one file gave: the model (None when it has errors) and why."""

    path: str
    model: Model | None
    diagnostics: list[Diagnostic]
    lines: list[str] = field(default_factory=list)
    document: Document | None = None
    notes: list[str] = field(default_factory=list)  # said once, not problems of the model
    # The lowered model even when its snippets have errors (None when the structure has any).
    structure: Model | None = None
    # The lines of the files it uses (`use`), by the name their diagnostics give.
    used: dict[str, list[str]] = field(default_factory=dict)

    @property
    def sources(self) -> dict[str, list[str]]:
        """The lines of every file its diagnostics may point into."""
        return {**self.used, self.path: self.lines}

    @property
    def ok(self) -> bool:
        return self.model is not None and not any(d.severity == "error" for d in self.diagnostics)

    @property
    def errors_only_in_snippets(self) -> bool:
        """The model has errors, and all of them are inside snippet code."""
        errors = [d.code for d in self.diagnostics if d.severity == "error"]
        return self.structure is not None and bool(errors) and set(errors) <= SNIPPET_CODES


@contextmanager
def _no_cyclic_gc() -> Iterator[None]:
    """Pause Python's cyclic garbage collector.

    Loading a model makes millions of small objects that all stay alive until
    the end; the collector's repeated passes over them cost about a third of
    the check's time and grow faster than the model.  Reference counting
    still frees everything; the collector resumes afterwards.
    """
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


@contextmanager
def _collect_new_cycles() -> Iterator[None]:
    """Inside :func:`_no_cyclic_gc`: the collector back on for new objects only.

    The snippet checks (ast, pyflakes) leave cyclic garbage that reference
    counting cannot free: kept until the end, it was most of the 3 GiB peak of
    a 100,000-state check.  What is loaded so far is frozen (moved out of the
    collector's sight), so collections do not rescan it; it thaws after.
    """
    if gc.isenabled():
        yield
        return
    gc.freeze()
    gc.enable()
    try:
        yield
    finally:
        gc.disable()
        gc.unfreeze()


def compile_file(path: str, text: str | None = None, cxx: bool = False,
                 texts: Mapping[str, str] | None = None) -> Result:
    """Every diagnostic of one model file; the model when it has no errors.

    With ``cxx``, a C++ model without other errors is also compiled by g++
    (``-fsyntax-only``, see hfsmc/cxxcheck.py), as ``hfsmc check`` does.  With ``texts``
    (normalised path -> text: a recording's sources, ``path`` among them), nothing is
    read from the disk."""
    if texts is not None:
        text = texts[os.path.normpath(path)]
    with _no_cyclic_gc():
        result = _compile(path, text, texts)
    if cxx and result.ok and result.model is not None and result.model.language == "cpp":
        from hfsmc.cxxcheck import check_cpp

        found = check_cpp(result.model)
        if found.diagnostics:
            diags = Diagnostics(list(result.diagnostics))
            diags.extend(found.diagnostics)
            result.diagnostics = diags.sorted()
            if diags.has_errors:
                result.model = None
        if found.note:
            result.notes.append(f"{path}: {found.note}")
    return result


def _compile(path: str, text: str | None, texts: Mapping[str, str] | None) -> Result:
    diags = Diagnostics()
    doc: Document | None = None
    uses = UseLoader(path, texts)
    try:
        doc = load(path, diags, text)
        if not diags.has_errors:
            schema.validate(doc, diags)
        if diags.has_errors:
            return Result(path, None, diags.sorted(), doc.lines, doc)
        model = build_ir(doc, diags, uses)
        with _collect_new_cycles():
            model = lower(model, diags)
        uses.finish(diags)
    except HfsmcError as e:
        diags.extend(e.diagnostics)
        return Result(path, None, diags.sorted(), doc.lines if doc else _lines(path, text), doc,
                      used=uses.sources)
    return Result(path, None if diags.has_errors else model, diags.sorted(), doc.lines, doc,
                  structure=model, used=uses.sources)


def _lines(path: str, text: str | None) -> list[str]:
    if text is not None:
        return split_lines(text)
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return split_lines(f.read(1 << 20))
    except OSError:
        return []
