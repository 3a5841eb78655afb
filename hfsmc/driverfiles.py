"""A user's driver files (``type: driver``), read while the model is built (docs/drivers.md).

The model names them relative to its own folder (``python: drivers/gadget.py``,
``cpp: drivers/gadget.hpp``); a driver is code, so a path that leaves the model's
folder (``..``, an absolute path, a link pointing out) is refused, as `use` files are
read only from where the model says. The text is kept in the IR: the build copies it
from there, and a recording carries it with the model's sources. The declaration is
read without running anything (hfsmc/drivers.py) and checked against the interface's
options.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from typing import Any

from hfsmc.drivers import (
    DeclarationError,
    Driver,
    disagreement,
    read_cpp_driver,
    read_python_driver,
)
from hfsmc.errors import Diagnostics, HfsmcError, Span
from hfsmc.frontend import read_text
from hfsmc.ir import DriverFile

_SUFFIX = {"python": (".py",), "cpp": (".hpp", ".h", ".hh", ".hxx")}


def driver_files(model_file: str, spec: Mapping[str, Any], language: str,
                 spans: Mapping[str, Span], texts: Mapping[str, str] | None,
                 diags: Diagnostics) -> tuple[DriverFile | None, DriverFile | None, Driver | None]:
    """The Python and C++ files of a ``type: driver`` interface and the declaration of the
    one the model's language runs; errors E185-E189 with their positions."""
    found: dict[str, DriverFile] = {}
    decl: dict[str, Driver] = {}
    for lang in ("python", "cpp"):
        written = spec.get(lang)
        if written is None:
            continue
        f = _read(model_file, str(written), lang, spans[lang], texts, diags)
        if f is None:
            continue
        found[lang] = f
        try:
            decl[lang] = (read_python_driver if lang == "python" else read_cpp_driver)(f.text)
        except DeclarationError as e:
            diags.error("E186", f"driver `{f.written}`: {e.message}",
                        Span(f.path, e.line, e.col), f"used from {spans[lang]}")
    where = spans["type"]
    if language not in found and not any(d.code in ("E185", "E186") for d in diags.items
                                         if d.span.file in (model_file, *(f.path for f in found.values()))):
        diags.error("E187", f"a `type: driver` interface of a {language} model names its "
                    f"{'Python' if language == 'python' else 'C++'} driver with "
                    f"`{language}: FILE`", where)
    if "python" in decl and "cpp" in decl:
        why = disagreement(decl["python"], decl["cpp"])
        if why is not None:
            diags.error("E189", f"the Python and C++ drivers disagree: {why}", where,
                        "one description: both declare the same kind, methods and snapshot")
    d = decl.get(language)
    if d is not None:
        _check_options(spec, d, spans, diags)
    return found.get("python"), found.get("cpp"), d


def confined(model_file: str, written: str) -> str:
    """The path of a file the model names relative to its own folder; ValueError saying
    why when it leaves that folder as written (absolute, ``~``, ``..``). A link that
    leads out is found by :func:`leads_out` once the file exists."""
    home = os.path.dirname(model_file) or "."
    if (os.path.isabs(written) or written.startswith("~")
            or os.path.normpath(written).split(os.sep)[0] == ".."):
        raise ValueError("is outside the model's folder")
    return os.path.normpath(os.path.join(home, written))


def leads_out(model_file: str, path: str) -> str | None:
    """Where ``path`` really leads when a link takes it out of the model's folder."""
    home = os.path.dirname(model_file) or "."
    real, root = os.path.realpath(path), os.path.realpath(home)
    return None if os.path.commonpath([real, root]) == root else real


def _read(model_file: str, written: str, lang: str, span: Span,
          texts: Mapping[str, str] | None, diags: Diagnostics) -> DriverFile | None:
    try:
        path = confined(model_file, written)
    except ValueError:
        diags.error("E185", f"driver `{written}` is outside the model's folder: a driver is "
                    "code, and is read only from the model's folder and below", span)
        return None
    if not written.endswith(_SUFFIX[lang]):
        diags.error("E185", f"driver `{written}`: a {lang} driver is a "
                    f"{' or '.join(_SUFFIX[lang])} file", span)
        return None
    if texts is not None:
        text = texts.get(path)
        if text is None:
            diags.error("E185", f"driver `{written}` is not in the recording", span)
            return None
        return DriverFile(written, path, text, span)
    real = leads_out(model_file, path)
    if real is not None:
        diags.error("E185", f"driver `{written}` leads outside the model's folder "
                    f"(to {real}): a driver is read only from the model's folder", span)
        return None
    if not os.path.isfile(path):
        diags.error("E185", f"driver `{written}` does not exist (looked for {path})", span)
        return None
    try:
        return DriverFile(written, path, read_text(path), span)
    except HfsmcError as e:
        why = e.diagnostics[0].message if e.diagnostics else "cannot be read"
        diags.error("E185", f"driver `{written}` cannot be read: {why}", span)
        return None


def _check_options(spec: Mapping[str, Any], d: Driver, spans: Mapping[str, Span],
                   diags: Diagnostics) -> None:
    known = dict(d.options)
    for key in spec.get("options") or {}:
        if str(key) not in known:
            listed = ", ".join(known) or "none"
            diags.error("E186", f"the {d.type} driver has no option `{key}` (its options: "
                        f"{listed})", spans.get(f"options.{key}", spans["type"]))
